"""Bots in the AI worker: lockstep matches with bots equal the in-process match bit for bit, and a
bot that fails (also one that never returns) costs the point, never the worker or the match."""
from pathlib import Path

import numpy as np
import pytest

from engine.physics.compiled import compile_scene
from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.scene import load_scene
from engine.play.match import Match, match_scene
from processes.supervisor import Supervisor, WorkerRefused, first_difference
from tests.helpers.commands import pingpong
from tests.waits import DEADLINE_S
from tests import bots

BASE = load_scene("match_rigid")
EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
BUDGET_S = 0.005
TICKS = 6000


def _reference(scene, seed: int, ticks: int):
    """The in-process match's states, tick by tick, to `ticks` or the match's end."""
    match = Match(scene, seed=seed, budget_s=BUDGET_S)
    trace = np.zeros(ticks + 1, physics_snapshot_dtype(len(scene.bats)))
    match.save(trace, 0)
    done = 0
    while done < ticks and not match.over:
        match.tick()
        done += 1
        match.save(trace, done)
    return match, trace[:done + 1]


def _same_run(result, trace) -> None:
    """The run's trace is the reference's, and it ended where the reference did."""
    assert result.ticks == len(trace) - 1
    assert first_difference(result.trace[:len(trace)], trace) is None


def test_the_example_bots_play_in_processes_as_in_process(no_leftovers):
    scene = match_scene(BASE, f"{EXAMPLES / 'attack.py'}:Attack", f"{EXAMPLES / 'block.py'}:Block", best_of=1)
    result = Supervisor(scene, TICKS, "lockstep", trace=True, seed=2, bot_budget_s=BUDGET_S).run()
    match, trace = _reference(scene, 2, TICKS)
    _same_run(result, trace)
    assert len(match.referee.points) > 0 and match.bot_errors == []
    assert result.workers["physics"]["bot_errors"] == []
    # a bot decides at every control tick: every one is a turn of the AI worker
    assert result.workers["physics"]["ai_turns"] == TICKS // compile_scene(scene).control_period


def test_a_raising_bot_in_the_worker_is_recorded_as_in_process(no_leftovers):
    scene = match_scene(BASE, bots.spec("Raises"), "pro", best_of=1)
    result = Supervisor(scene, TICKS, "lockstep", trace=True, seed=1, bot_budget_s=BUDGET_S).run()
    match, trace = _reference(scene, 1, TICKS)
    _same_run(result, trace)  # B wins the game on A's faults, one point a control tick
    assert match.referee.winner == 1
    assert result.workers["physics"]["bot_errors"] == match.bot_errors != []
    assert result.workers["ai"]["restarts"] == 0


def test_a_bot_that_never_returns_is_interrupted_and_the_match_goes_on(no_leftovers):
    # interrupted the same way in process (the wall-clock guard is the engine's): the same match
    scene = match_scene(BASE, bots.spec("Hangs"), "pro", best_of=1)
    result = Supervisor(scene, 3000, "lockstep", seed=1, bot_budget_s=BUDGET_S, trace=True).run()
    match, trace = _reference(scene, 1, 3000)
    _same_run(result, trace)
    assert result.workers["physics"]["bot_errors"] == match.bot_errors
    errors = result.workers["physics"]["bot_errors"]
    every = compile_scene(scene).control_period
    assert errors[0]["fault"] == "overran" and errors[0]["tick"] == (bots.FAIL_AT - 1) * every
    assert "interrupted" in errors[0]["detail"]
    assert result.ticks == 3000 or int(result.final["rally"]["winner"]) == 1  # it played on
    # the worker counts every failed decision, also one made after the match's last point was decided
    assert result.workers["ai"]["restarts"] == 0 and result.workers["ai"]["bot_faults"] >= len(errors)


def test_a_bot_stops_a_match_in_processes_when_told_to(no_leftovers):
    scene = match_scene(BASE, bots.spec("NotANumber"), "pro", best_of=1)
    result = Supervisor(scene, TICKS, "lockstep", seed=1, on_bot_error="stop", bot_budget_s=BUDGET_S).run()
    every = compile_scene(scene).control_period
    assert result.ticks == (bots.FAIL_AT - 1) * every + compile_scene(scene).decision_delay  # when the failed decision took effect
    assert result.workers["physics"]["stopped"].startswith(f"bot {bots.spec('NotANumber')} (player A) at tick")


def test_a_bot_whose_setup_raises_is_refused_in_one_line_as_in_process(no_leftovers):
    scene = match_scene(BASE, bots.spec("SetupFails"), "pro", best_of=1)
    with pytest.raises(ValueError) as in_process:
        Match(scene, seed=1)
    with pytest.raises(WorkerRefused) as in_workers:
        Supervisor(scene, TICKS, "lockstep", seed=1).run()
    assert str(in_workers.value) == str(in_process.value)  # the same words, no worker traceback
    assert "setup() raised RuntimeError: no table today" in str(in_workers.value)


@pytest.mark.parametrize("in_process", [False, True])
def test_a_match_a_bot_stopped_exits_non_zero_and_says_the_fault_once(in_process):
    args = ["match", "--scene", "match_rigid", "--a", bots.spec("Raises"), "--b", "pro", "--ticks", str(TICKS),
            "--on-bot-error", "stop", "--bot-budget-ms", "1000"] + (["--in-process"] if in_process else [])
    run = pingpong(*args)
    out, err = run.communicate(timeout=DEADLINE_S)
    assert run.returncode == 1, err  # the match did not end: a script must see that
    said = out + err
    assert said.count("no idea what to do") == 1, said
    assert "match stopped: bot" in out


def test_a_bot_no_interrupt_reaches_ends_an_in_process_match_with_one_line():
    run = pingpong("match", "--scene", "match_rigid", "--a", bots.spec("BlocksSignals"), "--b", "pro", "--ticks",
                   str(TICKS), "--in-process")
    out, err = run.communicate(timeout=DEADLINE_S)
    assert run.returncode == 3, err  # runtime.watchdog.ABANDONED_EXIT
    assert err.count("pingpong: bot BlocksSignals (bots.py) (player A) has not returned from act()") == 1, err
    assert "Traceback" not in err
