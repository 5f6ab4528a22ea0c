"""The bot brain (processes.network.client.brain): any player of the bot API on a served match's
client, through the match's own seat: what it is shown, when it decides, how its faults are named."""
import numpy as np
import pytest

from engine.physics.compiled import compile_scene
from engine.physics.scene import load_scene, with_remote_players
from engine.physics.world import initial_state
from engine.play.arm import ARM_BRAKE, CTL_KIND
from processes.network import wire
from processes.network.client.brain import BotBrain
from processes.network.wire import Slot
from tests import bots

SCENE = with_remote_players(load_scene("match_rigid"), 2)
COMPILED = compile_scene(SCENE)


def _snapshot(tick: int, rally: int = 3):
    """A still state's snapshot at `tick`, rally `rally` (the wire's numbering, from 1)."""
    record = initial_state(SCENE).record[0].copy()
    record["world"]["tick"] = tick
    record["rally"]["rally"], record["rally"]["winner"] = rally - 1, -1
    return wire.decode(wire.snapshot_from_physics(record, seq=tick + 1))


def test_a_bot_decides_once_a_control_period_on_what_the_snapshot_shows():
    brain = BotBrain(SCENE, Slot.B, bots.spec("Spy"))
    period = COMPILED.control_period
    for tick in range(0, 3 * period):
        forces = brain.control(_snapshot(tick), SCENE.dt)
        assert forces.shape == (6,) and np.isfinite(forces).all()
    seen = brain.players[1].bot.seen
    assert [int(obs["tick"]) for obs in seen] == [0, period, 2 * period]
    snapshot = _snapshot(0)
    np.testing.assert_array_equal(seen[0]["own"]["pos"], snapshot["bat_pos"][1])  # B's own bat
    np.testing.assert_array_equal(seen[0]["other"]["pos"], snapshot["bat_pos"][0])
    assert int(seen[0]["rally"]) == 2 and brain.stats["decisions"] == 3 and brain.errors == []


def test_a_bots_fault_is_named_as_in_a_match_and_its_arm_brakes():
    brain = BotBrain(SCENE, Slot.A, bots.spec("Raises"))
    period, failed_at = COMPILED.control_period, (bots.FAIL_AT - 1) * COMPILED.control_period
    for tick in range(0, failed_at + COMPILED.decision_delay + 1):  # until the faulted plan is in effect
        brain.control(_snapshot(tick), SCENE.dt)
    first = brain.errors[0]
    assert (first.player, first.tick, first.fault) == (0, failed_at, "raised")
    assert "no idea what to do" in first.detail
    faults = COMPILED.decision_delay // period + 1  # every decision from the first failing one on
    assert len(brain.errors) == brain.stats["errors"] == brain.stats["faults"] == faults
    assert brain.arm[0, CTL_KIND] == ARM_BRAKE  # the idle arm's brake, as in a match


def test_a_bot_that_cannot_be_set_up_is_refused_by_name():
    with pytest.raises(ValueError, match="SetupFails"):
        BotBrain(SCENE, Slot.A, bots.spec("SetupFails"))
