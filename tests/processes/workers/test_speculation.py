"""A speculating run (RunOptions.speculate): the physics steps on past its runs near the cloth net
before the net worker answers them, goes back where the net touched the ball, and still plays
the in-process match bit for bit, also with a worker killed and restarted in the middle of it."""
import os
import signal
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.play.match import Match, point_row
from processes.supervisor import Supervisor, workers_for
from tests import bots

SCENE = load_scene("match")
ONE_GAME = replace(SCENE, match=replace(SCENE.match, best_of=1))


@pytest.fixture(scope="module")
def reference() -> tuple[Match, list]:
    """The game in one process (seed 0): the match and its events."""
    match = Match(ONE_GAME, seed=0)
    events: list = []
    match.play(max_ticks=200_000, events_out=events)
    assert match.over
    return match, events


def assert_plays_the_reference(result, reference) -> None:
    """The run's ticks, state, points and events are the in-process game's, bit for bit."""
    match, events = reference
    assert result.ticks == match.current_tick
    assert result.final.tobytes() == match.state.record[0].tobytes()
    expected = np.array([point_row(p, 0) for p in match.referee.points])
    fields = ["winner", "reason", "shots", "score_after"]
    np.testing.assert_array_equal(result.points[fields], expected[fields])
    assert result.events_total == len(events)
    tail = np.array(events[-len(result.events):])
    np.testing.assert_array_equal(result.events.view(np.uint8), tail.view(np.uint8))


@pytest.mark.parametrize("slow_net_s", [0.0, 0.005])
def test_a_speculating_match_is_the_in_process_match_bit_for_bit(no_leftovers, reference, slow_net_s):
    """A whole game on the cloth net, the state, the points and the events the reference's. The
    net touches the ball in it where the physics cannot tell in advance (the tape), so with a net
    that answers each run 5 ms late (fault injection: the physics is well past such a run by
    then) the physics goes back, and the AI forgets the decisions it made past the touch
    (taken_back: how many depends on how far the AI got, so it is reported, not asserted)."""
    result = Supervisor(ONE_GAME, 200_000, "lockstep", seed=0, speculate=True, gate_ai_turns=True,
                        crash_worker="net", slow_turn_s=slow_net_s).run()
    if slow_net_s:
        physics = result.workers["physics"]
        assert physics["net_rollbacks"] > 0 and physics["net_ticks_again"] > 0  # the go-back path ran
    assert_plays_the_reference(result, reference)


@pytest.mark.parametrize("kind, crash_at", [("physics", 12_000), ("physics", 40_000), ("net", 20_000),
                                            ("ai", 30_000)])
def test_a_worker_killed_while_speculating_is_restarted_and_the_game_stays_exact(no_leftovers, reference, kind,
                                                                                 crash_at):
    """SIGKILLed at the hardest moment its loop has (fault injection): the physics with runs in
    flight, on guesses the net has not confirmed (the restarted one sends the net back to the
    snapshot it resumes from and takes back the AI's turns past it); the net with a run answered
    but not counted (the restarted one steps it again from its state after the run before); the
    AI after its first turn past the tick (the restarted one decides again from its state kept,
    leaving out the decisions taken back)."""
    result = Supervisor(ONE_GAME, 200_000, "lockstep", seed=0, speculate=True, gate_ai_turns=True,
                        crash_worker=kind, crash_at_tick=crash_at).run()
    assert result.workers[kind]["restarts"] == 1
    assert_plays_the_reference(result, reference)


def test_the_physics_killed_deep_in_its_guesses_is_restarted_and_the_game_stays_exact(no_leftovers, reference):
    """The net answers each run 5 ms late, so the physics is far ahead of it, with the AI deciding
    on its guesses, when it is SIGKILLed (from outside, wherever it is)."""
    supervisor = Supervisor(ONE_GAME, 200_000, "lockstep", seed=0, speculate=True, gate_ai_turns=True,
                            crash_worker="net", slow_turn_s=0.005)
    row = workers_for(ONE_GAME).index("physics")
    killed = []

    def progress(record):
        if not killed and int(record["world"]["tick"]) > 8000:
            killed.append(int(supervisor.arena["status"].array[row]["pid"]))
            os.kill(killed[0], signal.SIGKILL)

    result = supervisor.run(progress=progress)
    assert killed and result.workers["physics"]["restarts"] == 1
    assert_plays_the_reference(result, reference)


@pytest.mark.parametrize("changes, refusal", [
    ({"mode": "realtime"}, "only a lockstep run speculates"),
    ({"trace": True}, "traces and replay frames"),
    ({"frame_every": 100}, "traces and replay frames"),
])
def test_a_run_that_cannot_be_taken_back_is_refused_before_it_starts(changes, refusal):
    with pytest.raises(ValueError, match=refusal):
        Supervisor(SCENE, 1000, **{"mode": "lockstep", **changes}, speculate=True)


def test_a_run_speculates_by_default_wherever_it_can():
    assert Supervisor(SCENE, 1000).options.speculate
    assert not Supervisor(SCENE, 1000, speculate=False).options.speculate
    assert not Supervisor(SCENE, 1000, trace=True).options.speculate  # refused only when asked for
    assert not Supervisor(SCENE, 1000, "realtime").options.speculate
    assert not Supervisor(load_scene("match_rigid"), 1000).options.speculate


def test_speculating_needs_a_cloth_net_and_players_whose_state_can_be_kept():
    with pytest.raises(ValueError, match="not a match with a cloth net"):
        Supervisor(load_scene("match_rigid"), 1000, speculate=True)
    with_bot = replace(SCENE, bats=(replace(SCENE.bats[0], skill=bots.spec("Spy")), SCENE.bats[1]))
    with pytest.raises(ValueError, match="a bot's own objects cannot be taken back"):
        Supervisor(with_bot, 1000, speculate=True)
