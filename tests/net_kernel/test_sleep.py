"""A net at rest with the ball far sleeps and costs no kernel calls; the ball's approach wakes it."""
import numpy as np

from net_kernel import NetSim, build_topology, grid_spec


def _asleep():
    sim = NetSim(build_topology(grid_spec(40, 8)), dt=1e-3)
    for _ in range(3000):
        sim.step()
        if sim.sleeping:
            return sim
    raise AssertionError("the net never fell asleep")


def test_sleeping_net_costs_no_kernel_calls():
    sim = _asleep()
    calls = sim.kernel_calls
    pos = sim.knot_pos.copy()
    far_ball = np.array([-1.0, 0.0, 0.3])
    for _ in range(1000):
        contact = sim.step(far_ball, np.array([1.0, 0.0, 0.0]), 0.02)
        assert contact.toi == -1.0
    assert sim.kernel_calls == calls  # not one call in 1000 ticks
    assert np.array_equal(sim.knot_pos, pos)


def test_ball_close_wakes_the_net_and_contact_moves_it():
    sim = _asleep()
    calls = sim.kernel_calls
    target = sim.knot_pos[4 * 40 + 20]  # a free knot: this coarse mesh has gaps wider than the ball
    pos = np.array([-0.04, target[1], target[2]])
    vel = np.array([20.0, 0.0, 0.0])
    contact = sim.step(pos, vel, 0.02, 1 / 2.7e-3)
    assert not sim.sleeping
    assert sim.kernel_calls > calls
    assert contact.toi >= 0.0 and contact.impulse[0] < 0.0  # hit this tick, pushed back
    assert sim.knot_vel[:, 0].max() > 0.0  # the struck knots move away from the ball


def _fly(sim, ball, vel, ticks):
    """Step the net `ticks` ticks with the ball on a straight path; the kernel calls it took."""
    calls = sim.kernel_calls
    for _ in range(ticks):
        contact = sim.step(ball, vel, 0.02, 1 / 2.7e-3)
        assert contact.toi == -1.0 and not contact.impulse.any()
        ball = ball + vel * sim.dt
    return sim.kernel_calls - calls


def test_a_ball_skimming_over_a_sleeping_net_leaves_it_asleep_and_untouched():
    sim = _asleep()
    pos = sim.knot_pos.copy()
    top = float(sim.box[1, 2])  # the top cord's highest point
    # Level over the cord with 1 mm to spare at 10 m/s: the box test alone says far, no probe.
    skim = np.array([-0.05, 0.1, top + 0.02 + sim.knot_radius + 1e-3])
    assert _fly(sim, skim, np.array([10.0, 0.0, 0.0]), 10) == 0
    # Rising steeply across the cord, 24.7 mm from it at the closest (the line x - z' = -35 mm,
    # z' above the cord), more than the 20.5 mm reach: its path's box meets the net's, so the
    # frozen net is probed, but no knot is touched.
    rise = np.array([-0.03, 0.1, top + 0.005])
    assert _fly(sim, rise, np.array([20.0, 0.0, 20.0]), 3) >= 1
    assert sim.sleeping
    assert np.array_equal(sim.knot_pos, pos)  # not one knot moved


def test_a_ball_that_touches_the_top_cord_wakes_the_net():
    sim = _asleep()
    knot = sim.knot_pos[7 * 40 + 20]  # a top-cord knot (this coarse mesh has gaps wider than the ball)
    radius = 0.02
    ball = np.array([-0.015, knot[1], knot[2] + radius - 2e-3])  # 2 mm below grazing height
    contact = sim.step(ball, np.array([10.0, 0.0, 0.0]), radius, 1 / 2.7e-3)
    assert contact.toi >= 0.0
    assert not sim.sleeping
