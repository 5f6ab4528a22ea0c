"""Bat dynamics: forces and torques in, motion out (the arm holds the bat's weight)."""
import numpy as np
import pytest

from tests.helpers.scenes import make_scene, run_ticks


def test_constant_force_gives_the_semi_implicit_euler_kinematics():
    force, mass, ticks = 9.0, 0.18, 100
    scene = make_scene(["bats"], {"pos": [0.0, 0.0, 1.0]},
                       bats={"a": {"pos": [-1.5, 0.0, 0.2], "force": [force, 0.0, 0.0], "mass": mass}})
    state, _ = run_ticks(scene, ticks)
    h, a = scene.dt, force / mass
    assert state.bats["vel"][0][0] == pytest.approx(a * ticks * h, rel=1e-12)  # exact for velocity
    # Semi-implicit Euler: x_n = a h^2 n (n + 1) / 2, i.e. 1/2 a t^2 + 1/2 a h t.
    assert state.bats["pos"][0][0] == pytest.approx(-1.5 + a * h * h * ticks * (ticks + 1) / 2, rel=1e-12)
    np.testing.assert_array_equal(state.bats["pos"][0][1:], [0.0, 0.2])  # no weight: it does not sag


def test_spin_about_the_face_normal_is_exact_rotation():
    rate, ticks = 20.0, 250
    scene = make_scene(["bats"], {"pos": [0.0, 0.0, 1.0]},
                       bats={"a": {"pos": [-1.5, 0.0, 0.2], "normal": [1.0, 0.0, 0.0], "ang_vel": [rate, 0.0, 0.0]}})
    state, _ = run_ticks(scene, ticks)
    angle = rate * ticks * scene.dt
    # Start: z -> x (a quarter turn about y); then `angle` about world x.
    start = np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])
    turn = np.array([np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0])
    w1, x1, y1, z1 = turn
    w2, x2, y2, z2 = start
    expected = np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    np.testing.assert_allclose(state.bats["quat"][0], expected, atol=1e-12)  # round-off over 250 rotations
    np.testing.assert_allclose(state.bats["ang_vel"][0], [rate, 0.0, 0.0], atol=1e-12)  # torque-free, symmetric
