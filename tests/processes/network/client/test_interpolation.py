"""A spectator's view, 100 ms behind: cubic Hermite positions and slerp turns between snapshots
(processes.network.client.interpolation), checked against constant-acceleration motion."""
import math

import numpy as np
import pytest

from processes.network import wire
from processes.network.client.interpolation import Interpolator, hermite, slerp

G = np.array([0.0, 0.0, -9.81])  # m/s^2
DT = 0.001  # s, the match scene's tick
SNAPSHOT_EVERY = 10  # ticks between snapshots: 100 Hz at that tick


def _analytic(t):
    """Ball in drag-free flight, bat A moving uniformly, bat B turning about z at 5 rad/s."""
    p0, v0 = np.array([-1.0, 0.1, 0.3]), np.array([7.0, -0.5, 2.0])
    ball_pos, ball_vel = p0 + v0 * t + 0.5 * G * t * t, v0 + G * t
    bat_pos = np.array([[-1.6 + 0.8 * t, 0.2, 0.1], [1.7, -0.3 * t, 0.2]])
    bat_vel = np.array([[0.8, 0.0, 0.0], [0.0, -0.3, 0.0]])
    half = 0.5 * 5.0 * t
    bat_quat = np.array([[1.0, 0.0, 0.0, 0.0], [math.cos(half), 0.0, 0.0, math.sin(half)]])
    return ball_pos, ball_vel, bat_pos, bat_vel, bat_quat


def _snapshot(tick, rally=0):
    ball_pos, ball_vel, bat_pos, bat_vel, bat_quat = _analytic(tick * DT)
    return wire.decode(wire.encode(
        wire.Kind.SNAPSHOT, tick=tick, ball_pos=ball_pos, ball_vel=ball_vel, ball_spin=np.zeros(3), bat_pos=bat_pos,
        bat_quat=bat_quat, bat_vel=bat_vel, bat_ang_vel=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 5.0]]),
        input_seq=np.zeros(2, np.uint64), rally=rally, score=np.zeros(2, np.uint16), games_won=np.zeros(2, np.uint8),
        phase=2, server=0, striker=0, winner=-1, realtime_factor=1.0))


def test_hermite_and_slerp_reproduce_constant_acceleration_and_uniform_turning():
    for t in (0.0, 0.0013, 0.0047, 0.01):
        a, b = _analytic(0.0), _analytic(0.01)
        got = hermite(0.0, a[0], a[1], 0.01, b[0], b[1], t)
        np.testing.assert_allclose(got, _analytic(t)[0], rtol=0, atol=1e-14)  # exact for a quadratic: round-off
        q = slerp(a[4][1], b[4][1], t / 0.01)
        np.testing.assert_allclose(q, _analytic(t)[4][1], rtol=0, atol=1e-12)  # uniform rotation: round-off
    linear = a[0] + (b[0] - a[0]) * 0.5
    assert np.linalg.norm(linear - _analytic(0.005)[0]) > 1e-4  # g (10 ms)^2 / 8 = 0.12 mm: linear would fail


def test_a_spectator_sees_the_motion_100_ms_behind_between_snapshots():
    view = Interpolator(DT, delay_s=0.1)
    assert view.sample(0.0) is None  # nothing received yet
    latency = 0.004  # s, each snapshot arrives 4 ms after its tick
    for tick in range(0, 400, SNAPSHOT_EVERY):
        view.push(_snapshot(tick), arrival=tick * DT + latency)
    wall = 0.39 + latency + 0.0003  # the clock says the server is at tick 390.3 now
    shown = view.sample(wall)
    assert shown["tick"] == pytest.approx(290.3, abs=1e-6)  # 100 ms behind (clock round-off)
    ball_pos, _, bat_pos, _, bat_quat = _analytic(shown["tick"] * DT)
    np.testing.assert_allclose(shown["ball_pos"], ball_pos, rtol=0, atol=1e-12)  # exact for constant g
    np.testing.assert_allclose(shown["bat_pos"], bat_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(shown["bat_quat"], bat_quat, rtol=0, atol=1e-9)  # slerp of a uniform turn
    assert shown["snapshot"].tick == 290
    late = _snapshot(120)
    view.push(late, arrival=wall)  # an old snapshot arriving late adds nothing, moves no clock forward
    assert view.counts["late_dropped"] == 1 and view.sample(wall)["tick"] == pytest.approx(290.3, abs=1e-6)
    newest = view.sample(wall + 1.0)  # the server fell silent: the view holds the newest snapshot
    assert newest["tick"] == 390.0 and view.counts["held_newest"] == 1


def test_a_toss_between_two_snapshots_is_shown_as_a_step_not_a_flight():
    view = Interpolator(DT, delay_s=0.0)
    view.push(_snapshot(0), arrival=0.0)
    view.push(_snapshot(10, rally=1), arrival=0.01)
    shown = view.at(5.0)
    assert shown["tick"] == 0.0 and view.counts["toss_steps"] == 1
