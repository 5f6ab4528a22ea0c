"""Continuous collision detection: fast balls hit thin bodies, every impact in a tick is found."""
import numpy as np
import pytest

from engine.physics import equipment
from engine.physics.geometry import Body, disc_sdf
from engine.physics.world import build_model, initial_state, new_events, step
from tests.helpers.scenes import make_scene

R = equipment.BALL_RADIUS


def bat_gap(state, bat=0):
    """Gap between the ball and a bat's surface, m (negative = penetration)."""
    from engine.physics.bat import face_normal

    axis = np.zeros(3)
    face_normal(state.bats["quat"][bat], axis)
    return disc_sdf(state.ball["pos"][0], state.bats["pos"][bat], axis, equipment.BAT_RADIUS,
                    equipment.BAT_HALF_THICKNESS, np.zeros(3)) - R


def run_checked(scene, ticks, gap=None):
    model, state, events = build_model(scene), initial_state(scene), new_events()
    seen, min_gap = [], np.inf
    for _ in range(ticks):
        n = step(model, state, None, events)
        seen.extend(events[:n].copy())
        if gap is not None:
            min_gap = min(min_gap, gap(state))
    return state, seen, min_gap


@pytest.mark.parametrize("dt", [0.001, 0.005, 0.02])
@pytest.mark.parametrize("aim_y", [0.0, 0.07, 0.09])  # face centre, near the rim, the rounded rim
def test_40_m_per_s_ball_never_tunnels_through_the_bat(dt, aim_y):
    # 40 m/s covers 4 to 80 cm a tick; the bat is 14 mm thick.
    scene = make_scene(["bats"], {"pos": [0.5, aim_y, 0.3], "vel": [-40.0, 0.0, 0.0]}, dt=dt,
                       bats={"a": {"pos": [-1.0, 0.0, 0.3], "normal": [1.0, 0.0, 0.0]}})
    state, events, min_gap = run_checked(scene, int(round(0.1 / dt)), gap=bat_gap)
    assert [int(e["body"]) for e in events] == [Body.BAT_A]
    assert state.ball["vel"][0][0] > 0.0  # sent back
    assert min_gap > -1e-9  # never inside the bat (CONTACT_TOL keeps it outside)


def test_ball_passing_beside_the_bat_is_not_hit():
    scene = make_scene(["bats"], {"pos": [0.5, 0.2, 0.3], "vel": [-40.0, 0.0, 0.0]},
                       bats={"a": {"pos": [-1.0, 0.0, 0.3], "normal": [1.0, 0.0, 0.0]}})
    _, events, _ = run_checked(scene, 100)
    assert events == []


def test_40_m_per_s_ball_hits_the_table_end_not_through_it():
    # Aimed at the 25 mm thick end face of the table, 1 cm below the playing surface.
    scene = make_scene(["table"], {"pos": [2.5, 0.0, -0.01], "vel": [-40.0, 0.0, 0.0]}, dt=0.005)
    state, events, _ = run_checked(scene, 20)
    assert len(events) == 1 and int(events[0]["body"]) == Body.TABLE
    np.testing.assert_allclose(events[0]["normal"], [1.0, 0.0, 0.0], atol=1e-12)  # the end face
    assert state.ball["pos"][0][0] > equipment.TABLE_LENGTH / 2


def test_table_edge_deflects_along_the_edge_normal():
    # Just above the surface: the ball clips the rounded edge, whose normal points up and out.
    scene = make_scene(["table"], {"pos": [2.5, 0.0, 0.01], "vel": [-40.0, 0.0, 0.0]}, dt=0.005)
    _, events, _ = run_checked(scene, 20)
    assert len(events) == 1
    n = events[0]["normal"]
    assert n[0] > 0.0 and n[2] > 0.0 and abs(np.linalg.norm(n) - 1.0) < 1e-12


def test_table_corner():
    scene = make_scene(["table"], {"pos": [2.37, 1.7625, 1.0], "vel": [-20.0, -20.0, -20.0]}, dt=0.005)
    _, events, _ = run_checked(scene, 20)
    assert len(events) == 1
    np.testing.assert_allclose(events[0]["normal"], np.ones(3) / np.sqrt(3), atol=1e-3)  # corner's diagonal


def test_moving_bat_drives_a_resting_ball():
    # Head-on, frictionless, bat held (apparent restitution): v' = v_bat (1 + e).
    scene = make_scene(["bats"], {"pos": [0.0, 0.0, 0.3]}, dt=0.001,
                       bats={"a": {"pos": [-0.5, 0.0, 0.3], "normal": [1.0, 0.0, 0.0], "vel": [30.0, 0.0, 0.0]}})
    state, events, _ = run_checked(scene, 20)
    assert len(events) == 1
    expected = 30.0 * (1.0 + equipment.BAT_RESTITUTION)
    assert state.ball["vel"][0][0] == pytest.approx(expected, rel=1e-12)  # exact up to round-off


def test_two_impacts_in_one_tick_table_then_bat():
    # A 10 ms tick: the ball bounces off the table near A's end and meets A's bat in the same tick.
    scene = make_scene(["table", "bats"], {"pos": [-1.10, 0.0, 0.06], "vel": [-10.0, 0.0, -10.0]}, dt=0.01,
                       bats={"a": {"pos": [-1.22, 0.0, 0.06], "normal": [1.0, 0.0, 0.0]}})
    _, events, _ = run_checked(scene, 1)
    assert [int(e["body"]) for e in events] == [Body.TABLE, Body.BAT_A]
    assert events[0]["time"] < events[1]["time"] < 0.01


def test_net_stops_a_ball_driven_into_it():
    scene = make_scene(["net"], {"pos": [-0.5, 0.0, 0.07], "vel": [30.0, 0.0, 0.0]}, dt=0.005)
    state, events, _ = run_checked(scene, 40)
    assert [int(e["body"]) for e in events] == [Body.NET]
    assert state.ball["pos"][0][0] < 0.0  # stayed on A's side of the net
