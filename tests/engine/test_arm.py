"""The arm: its PD law at rest and at its limits, and the idle arm's brake."""
import numpy as np

from engine.physics.dtypes import BAT_DTYPE
from engine.play.ai import SKILLS, BatAI
from engine.play.arm import (BAT_FLOATS, BRAKE_MAX_N, BRAKE_PER_S, CTL_D_ANGLE, CTL_HOLD, CTL_INERTIA, CTL_K_ANGLE,
                             CTL_KD, CTL_KP, CTL_MASS, CTL_MAX_FORCE, CTL_MAX_SPEED, CTL_MAX_TORQUE, CTL_NORMAL,
                             CTL_SIZE, bat_control, brake_force)

MASS = 0.18  # kg, engine.physics.equipment.BAT_MASS


def _arm(max_force=120.0, max_speed=18.0):
    ctl = np.zeros(CTL_SIZE)
    ctl[[CTL_MASS, CTL_INERTIA, CTL_KP, CTL_KD, CTL_K_ANGLE, CTL_D_ANGLE]] = (
        MASS, 2.5e-4, BatAI.KP, BatAI.KD, BatAI.K_ANGLE, BatAI.D_ANGLE)
    ctl[[CTL_MAX_FORCE, CTL_MAX_TORQUE, CTL_MAX_SPEED]] = max_force, 4.0, max_speed
    ctl[CTL_HOLD:CTL_HOLD + 3] = (1.77, 0.0, 0.15)
    ctl[CTL_NORMAL:CTL_NORMAL + 3] = (0.0, 0.0, 1.0)  # the face normal of the identity quaternion
    return ctl


def _bat(pos, vel):
    bat = np.zeros(1, BAT_DTYPE)
    bat["pos"][0], bat["vel"][0], bat["quat"][0] = pos, vel, (1.0, 0.0, 0.0, 0.0)
    return bat.view(np.float64).reshape(BAT_FLOATS)


def test_an_arm_at_its_hold_pose_at_rest_pushes_nothing():
    out = np.full(6, np.nan)
    bat_control(0.0, _bat((1.77, 0.0, 0.15), (0.0, 0.0, 0.0)), _arm(), out)
    np.testing.assert_array_equal(out, np.zeros(6))  # exact: every error term is 0.0


def test_the_arm_force_is_the_pd_law_clipped_at_its_limits():
    out = np.zeros(6)
    bat_control(0.0, _bat((1.77, 0.0, 0.14), (0.0, 0.0, 0.0)), _arm(), out)  # 1 cm low, at rest
    np.testing.assert_allclose(out[0:3], [0.0, 0.0, MASS * BatAI.KP * 0.01], rtol=1e-12)  # F = m kp e
    bat_control(0.0, _bat((1.77, 0.0, -0.85), (0.0, 0.0, 0.0)), _arm(max_force=50.0), out)  # 1 m low
    np.testing.assert_allclose(out[0:3], [0.0, 0.0, 50.0], rtol=1e-12)  # |F| clipped at max_force
    bat_control(0.0, _bat((1.77, 0.0, 0.15), (0.0, 20.0, 0.0)), _arm(), out)  # faster than max_speed
    np.testing.assert_allclose(out[0:3], [0.0, -120.0, 0.0], rtol=1e-12)  # brakes, -m kd v clipped at 120 N


def test_the_idle_brake_is_the_weakest_arms_damping():
    assert BRAKE_PER_S == BatAI.KD and BRAKE_MAX_N == SKILLS["novice"].max_force_n
    out = np.full(6, np.nan)
    np.testing.assert_allclose(brake_force(MASS, np.array([0.5, 0.0, 0.0]), out),
                               [-MASS * BRAKE_PER_S * 0.5, 0, 0, 0, 0, 0], rtol=1e-12)  # 5.4 N, under the clip
    np.testing.assert_allclose(brake_force(MASS, np.array([0.0, 3.0, -4.0]), out),
                               [0, -0.6 * BRAKE_MAX_N, 0.8 * BRAKE_MAX_N, 0, 0, 0], rtol=1e-12)  # clipped
