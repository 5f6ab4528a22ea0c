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
