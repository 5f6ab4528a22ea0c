"""A bat stays where and as fast as an arm can take it, and never becomes non-finite unnoticed.

The bug these pin down (found by `pingpong stress`): a served player's valid input (|torque|
<= 50 N m, the wire's limit) left its bat spinning, the explicit gyroscopic term pumped the
spin up by sqrt(1 + (w_z h)^2) a tick until it overflowed, and the physics published NaN bats
for hundreds of snapshots: the finite guard covered the ball only.
"""
import numpy as np
import pytest

from engine.physics.bat import BAT_MAX_SPEED, BAT_MAX_SPIN, HALL_HI_X, HALL_HI_Z, HALL_LO_X
from engine.physics.world import SimulationError, build_model, initial_state, new_events, step
from tests.helpers.scenes import make_scene

BATS = {"a": {"pos": [-1.5, 0.0, 0.2]}, "b": {"pos": [1.5, 0.0, 0.2]}}
ROUND = 1e-12  # relative: the limit is applied by scaling, one rounding per component


def _world():
    scene = make_scene(["gravity", "bats"], {"pos": [0.0, 0.0, 0.5]}, bats=BATS)
    return build_model(scene), initial_state(scene), new_events()


def test_a_valid_torque_held_then_released_leaves_the_spin_bounded_and_finite():
    model, state, events = _world()
    inputs = np.zeros((2, 6))
    inputs[0, 3:6] = [30.0, 0.0, 40.0]  # 50 N m, the wire's largest; tilted to the face: gyroscopic pumping
    step(model, state, inputs, events)
    for _ in range(99):  # held for the gateway's input_hold_s (0.1 s) ...
        step(model, state, None, events)
    inputs[:] = 0.0
    step(model, state, inputs, events)  # ... then let go: before the fix NaN ~400 ticks later
    spins = []
    for _ in range(1000):
        step(model, state, None, events)
        spins.append(float(np.linalg.norm(state.bats["ang_vel"][0])))
    assert np.isfinite(state.bats.view("<f8")).all()
    assert max(spins) <= BAT_MAX_SPIN * (1 + ROUND)
    assert max(spins) == pytest.approx(BAT_MAX_SPIN, rel=ROUND)  # the limit did act (50 N m for 0.1 s is ~2e4 rad/s)
    np.testing.assert_allclose(np.linalg.norm(state.bats["quat"][0]), 1.0, atol=1e-12)  # renormalised each tick


def test_a_held_force_saturates_at_the_arm_speed_then_the_hall_wall_stops_the_bat():
    model, state, events = _world()
    inputs = np.zeros((2, 6))
    inputs[0, 0] = -500.0  # the wire's largest force: 2800 m/s^2 on 0.18 kg
    inputs[1, 2] = 500.0  # bat b pushed up, to the ceiling
    step(model, state, inputs, events)
    for _ in range(12):  # 13 ticks: 36 m/s unbounded
        step(model, state, None, events)
    assert float(np.linalg.norm(state.bats["vel"][0])) == pytest.approx(BAT_MAX_SPEED, rel=ROUND)
    for _ in range(400):  # 0.4 s at 35 m/s is 14 m: both reach their wall
        step(model, state, None, events)
    a, b = state.bats[0], state.bats[1]
    assert float(a["pos"][0]) == HALL_LO_X and float(a["vel"][0]) == 0.0  # stopped, not bounced
    assert a["pos"][1:].tolist() == [0.0, 0.2]
    assert float(b["pos"][2]) == HALL_HI_Z and float(b["vel"][2]) == 0.0
    assert b["pos"][:2].tolist() == [1.5, 0.0]
    inputs[0, 0] = 500.0  # pushed back, it leaves the wall
    step(model, state, inputs, events)
    assert HALL_LO_X < float(state.bats["pos"][0][0]) < HALL_HI_X


@pytest.mark.parametrize("field, column, quantity", [("ang_vel", 1, r"ang_vel\[y\]"), ("quat", 0, r"quat\[w\]"),
                                                     ("torque", 2, r"torque\[z\]")])
def test_a_non_finite_bat_record_is_refused_before_the_tick_naming_it(field, column, quantity):
    """Writers that go around step()'s inputs (a worker's mailbox, a restored record) cannot
    slip a NaN past the engine: it stops, names bat, quantity and tick, and changes nothing."""
    model, state, events = _world()
    step(model, state, None, events)
    state.bats[field][1][column] = np.nan
    before = (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes())
    with pytest.raises(SimulationError, match=rf"tick 1: bat b's {quantity} is nan before the tick; nothing was "
                                              r"stepped"):
        step(model, state, None, events)
    assert (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes()) == before


@pytest.mark.filterwarnings("ignore:overflow encountered in reduce:RuntimeWarning")  # the input check's sum
def test_an_input_too_large_for_the_arithmetic_is_named_after_the_kernel():
    """A finite torque of 1e308 N m overflows the frame rotation (inf - inf): the check after the
    kernel names the bat and the quantity instead of letting the NaN be published."""
    model, state, events = _world()
    inputs = np.zeros((2, 6))
    inputs[0, 3:6] = [1e308, 1e308, 1e308]
    with pytest.raises(SimulationError, match=r"ticks 0\.\.1: bat a's \w+\[[wxyz]\] became nan during the kernel"):
        step(model, state, inputs, events)
