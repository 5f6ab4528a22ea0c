"""A speculating run (RunOptions.speculate): the physics steps on past its runs near the cloth net
before the net worker answers them, goes back where the net touched the ball, and still plays
the in-process match bit for bit."""
import os
import signal
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.play.match import Match, point_row
from processes.supervisor import Supervisor, WorkerFailed, workers_for
from tests import bots

SCENE = load_scene("match")
ONE_GAME = replace(SCENE, match=replace(SCENE.match, best_of=1))


@pytest.mark.parametrize("slow_net_s", [0.0, 0.005])
def test_a_speculating_match_is_the_in_process_match_bit_for_bit(no_leftovers, slow_net_s):
    """A whole game on the cloth net, the state, the points and the events the reference's. The
    net touches the ball in it where the physics cannot tell in advance (the tape), so with a net
    that answers each run 5 ms late (fault injection: the physics is well past such a run by
    then) the physics goes back, and the AI forgets the decisions it made past the touch
    (taken_back: how many depends on how far the AI got, so it is reported, not asserted)."""
    result = Supervisor(ONE_GAME, 200_000, "lockstep", seed=0, speculate=True, gate_ai_turns=True,
                        crash_worker="net", slow_turn_s=slow_net_s).run()
    reference = Match(ONE_GAME, seed=0)
    events: list = []
    reference.play(max_ticks=200_000, events_out=events)
    assert reference.over and result.ticks == reference.current_tick
    assert result.final.tobytes() == reference.state.record[0].tobytes()
    if slow_net_s:
        physics = result.workers["physics"]
        assert physics["net_rollbacks"] > 0 and physics["net_ticks_again"] > 0  # the go-back path ran
    expected = np.array([point_row(p, 0) for p in reference.referee.points])
    fields = ["winner", "reason", "shots", "score_after"]
    np.testing.assert_array_equal(result.points[fields], expected[fields])
    assert result.events_total == len(events)
    tail = np.array(events[-len(result.events):])
    np.testing.assert_array_equal(result.events.view(np.uint8), tail.view(np.uint8))


@pytest.mark.parametrize("changes, refusal", [
    ({"mode": "realtime"}, "only a lockstep run speculates"),
    ({"trace": True}, "traces and replay frames"),
    ({"frame_every": 100}, "traces and replay frames"),
    ({"crash_at_tick": 100}, "a crash is injected to have the worker restarted"),
])
def test_a_run_that_cannot_be_taken_back_is_refused_before_it_starts(changes, refusal):
    with pytest.raises(ValueError, match=refusal):
        Supervisor(SCENE, 1000, **{"mode": "lockstep", **changes}, speculate=True)


def test_speculating_needs_a_cloth_net_and_players_whose_state_can_be_kept():
    with pytest.raises(ValueError, match="not a match with a cloth net"):
        Supervisor(load_scene("match_rigid"), 1000, speculate=True)
    with_bot = replace(SCENE, bats=(replace(SCENE.bats[0], skill=bots.spec("Spy")), SCENE.bats[1]))
    with pytest.raises(ValueError, match="a bot's own objects cannot be taken back"):
        Supervisor(with_bot, 1000, speculate=True)


@pytest.mark.parametrize("kind", ["net", "physics", "ai"])
def test_a_worker_that_dies_ends_a_speculating_run_saying_so(kind, no_leftovers):
    """No restart (a speculating run's trial has none): the run fails with a message that names
    the worker and the way to have it restarted, and leaves nothing behind."""
    supervisor = Supervisor(SCENE, 300_000, "lockstep", seed=0, speculate=True)
    row = workers_for(SCENE).index(kind)
    killed = []

    def progress(record):
        if not killed and int(record["world"]["tick"]) > 2000:
            killed.append(int(supervisor.arena["status"].array[row]["pid"]))
            os.kill(killed[0], signal.SIGKILL)

    with pytest.raises(WorkerFailed, match=f"{kind} worker died .*a speculating run restarts no worker"):
        supervisor.run(progress=progress)
    assert killed
