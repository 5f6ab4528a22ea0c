"""Guards at the boundary and after each tick: bad numbers are refused, never propagated."""
import numpy as np
import pytest

from engine.world import SimulationError, build_model, initial_state, new_events, step
from tests.conftest import make_scene

BATS = {"a": {"pos": [-1.5, 0.0, 0.2]}, "b": {"pos": [1.5, 0.0, 0.2]}}


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_bat_input_is_refused_and_changes_nothing(bad):
    scene = make_scene(["gravity", "bats"], {"pos": [0.0, 0.0, 0.5]}, bats=BATS)
    model, state, events = build_model(scene), initial_state(scene), new_events()
    inputs = np.zeros((2, 6))
    inputs[1, 4] = bad
    before = (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes())
    with pytest.raises(ValueError, match=r"bat b torque\[1\] is .*; inputs must be finite"):
        step(model, state, inputs, events)
    assert (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes()) == before


def test_wrong_input_shape_is_refused():
    scene = make_scene(["bats"], {"pos": [0.0, 0.0, 0.5]}, bats=BATS)
    with pytest.raises(ValueError, match=r"shape \(2, 6\)"):
        step(build_model(scene), initial_state(scene), np.zeros((1, 6)), new_events())


def test_a_tick_that_would_go_non_finite_raises_and_keeps_the_state():
    scene = make_scene(["gravity", "drag"], {"pos": [0.0, 0.0, 0.5]})
    model, state, events = build_model(scene), initial_state(scene), new_events()
    state.ball["vel"][0] = [1e200, 0.0, 0.0]  # drag on this overflows to inf
    before = state.ball.tobytes()
    with pytest.raises(SimulationError, match=r"tick 0: the ball's (pos|vel)\[x\] would become non-finite"):
        step(model, state, None, events)
    assert state.ball.tobytes() == before
