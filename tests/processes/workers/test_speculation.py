"""A speculating run (RunOptions.speculate): the physics steps on past its runs near the cloth net
before the net worker answers them, goes back where the net touched the ball, and still plays
the in-process match bit for bit."""
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.play.match import Match, point_row
from processes.supervisor import Supervisor
from tests import bots

SCENE = load_scene("match")
ONE_GAME = replace(SCENE, match=replace(SCENE.match, best_of=1))


def test_a_speculating_match_is_the_in_process_match_bit_for_bit(no_leftovers):
    """A whole game on the cloth net: the net touches the ball in it (so the physics goes back,
    and the AI with it: decisions taken back), and the state, the points and the events are the
    reference's all the same."""
    result = Supervisor(ONE_GAME, 200_000, "lockstep", seed=0, speculate=True, gate_ai_turns=True).run()
    reference = Match(ONE_GAME, seed=0)
    events: list = []
    reference.play(max_ticks=200_000, events_out=events)
    assert reference.over and result.ticks == reference.current_tick
    assert result.final.tobytes() == reference.state.record[0].tobytes()
    physics, ai = result.workers["physics"], result.workers["ai"]
    assert physics["net_rollbacks"] > 0 and physics["net_ticks_again"] > 0  # the go-back path ran
    assert ai["taken_back"] > 0  # and decisions made on states taken back were undone
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
    ({"crash_at_tick": 100}, "fault injection restarts workers"),
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
