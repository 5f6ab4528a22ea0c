"""Free flight: identities and analytic trajectories."""
import numpy as np
import pytest

from engine.physics.integrators import METHODS
from tests.helpers.scenes import make_scene, run_ticks

G = 9.81
BALL = {"pos": [-1.0, 0.2, 0.5], "vel": [8.0, -1.0, 3.0], "spin": [0.0, 0.0, 0.0]}


@pytest.mark.parametrize("integrator", ["verlet", "rk4", "dopri5"])
def test_flight_without_drag_is_the_parabola(integrator):
    ticks = 500
    scene = make_scene(["gravity"], BALL, integrator=integrator)
    state, events = run_ticks(scene, ticks)
    t = ticks * scene.dt
    p0, v0 = np.array(BALL["pos"]), np.array(BALL["vel"])
    expected_pos = p0 + v0 * t + 0.5 * np.array([0.0, 0.0, -G]) * t * t
    expected_vel = v0 + np.array([0.0, 0.0, -G]) * t
    # Verlet and RK4 are exact on a quadratic; what is left is round-off over 500 steps.
    np.testing.assert_allclose(state.ball["pos"][0], expected_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.ball["vel"][0], expected_vel, rtol=0, atol=1e-12)
    assert events == []


@pytest.mark.parametrize("integrator", sorted(METHODS))
def test_no_force_is_uniform_motion(integrator):
    ball = dict(BALL, spin=[10.0, 20.0, 30.0])
    scene = make_scene([], ball, integrator=integrator)
    state, _ = run_ticks(scene, 200)
    expected = np.array(ball["pos"]) + np.array(ball["vel"]) * 200 * scene.dt
    np.testing.assert_allclose(state.ball["pos"][0], expected, rtol=0, atol=1e-13)  # round-off only
    np.testing.assert_array_equal(state.ball["vel"][0], ball["vel"])
    np.testing.assert_array_equal(state.ball["spin"][0], ball["spin"])


@pytest.mark.parametrize("integrator", sorted(METHODS))
def test_dt_zero_changes_nothing(integrator):
    scene = make_scene(["gravity", "drag", "magnus", "table", "net", "bats"],
                       dict(BALL, spin=[0.0, 100.0, 0.0]), integrator=integrator,
                       bats={"a": {"pos": [-1.5, 0.0, 0.2], "vel": [1.0, 0.0, 0.0], "ang_vel": [0.0, 0.0, 3.0]}})
    from engine.physics.world import build_model, initial_state, new_events, step

    model, state, events = build_model(scene), initial_state(scene), new_events()
    before = (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes())
    assert step(model, state, None, events, dt=0.0) == 0
    assert (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes()) == before
