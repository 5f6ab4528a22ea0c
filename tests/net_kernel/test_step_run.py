"""NetSim.step_run: a run of ticks with the ball is the same bits as step() tick by tick, up to the
first tick that touches the ball, and stops there."""
import numpy as np

from net_kernel import NO_CONTACT, NetSim, NetSpec, build_topology
from net_kernel.sim import BALL_MASS, BALL_RADIUS

DT = 1e-3
EVERYWHERE = np.array([-np.inf, -np.inf, -np.inf, np.inf, np.inf, np.inf])  # no tick is stepped free


def _net():
    return NetSim(build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass)), dt=DT)


def _straight_ball(speed: float, ticks: int) -> np.ndarray:
    """(ticks, 2, 3): a ball flying straight at the net's middle, each tick's start."""
    run = np.zeros((ticks, 2, 3))
    for j in range(ticks):
        run[j, 0] = (-0.2 + speed * DT * j, 0.0, 0.08)
        run[j, 1] = (speed, 0.0, 0.0)
    return run


def test_a_run_is_the_ticks_one_at_a_time_up_to_the_first_touch():
    run = _straight_ball(20.0, 40)  # reaches the net after ~9 ticks
    by_tick, by_run = _net(), _net()
    for j in range(len(run)):
        contact = by_tick.step(run[j, 0], run[j, 1], BALL_RADIUS, 1.0 / BALL_MASS)
        if contact.toi != NO_CONTACT:
            break
    touched_at = j
    expected = (contact.toi, contact.impulse.copy(), contact.offset.copy())
    taken, got = by_run.step_run(run, BALL_RADIUS, 1.0 / BALL_MASS, EVERYWHERE)
    assert 0 < touched_at < len(run) - 1  # the ball touched within the run, not at its last tick
    assert taken == touched_at + 1
    assert (got.toi, got.impulse.tolist(), got.offset.tolist()) == (expected[0], expected[1].tolist(),
                                                                     expected[2].tolist())
    assert np.array_equal(by_run.knot_pos, by_tick.knot_pos) and np.array_equal(by_run.knot_vel, by_tick.knot_vel)


def test_a_run_without_a_touch_steps_all_its_ticks():
    run = _straight_ball(10.0, 40)
    run[:, 0, 0] -= 0.6  # 0.8 m before the net at 10 m/s: 0.4 m closer after the 40 ticks
    by_tick, by_run = _net(), _net()
    for j in range(len(run)):
        assert by_tick.step(run[j, 0], run[j, 1], BALL_RADIUS, 1.0 / BALL_MASS).toi == NO_CONTACT
    taken, got = by_run.step_run(run, BALL_RADIUS, 1.0 / BALL_MASS, EVERYWHERE)
    assert (taken, got.toi) == (len(run), NO_CONTACT)
    assert np.array_equal(by_run.knot_pos, by_tick.knot_pos)


def test_a_sleeping_net_steps_free_the_ticks_with_the_ball_outside_the_box():
    sim = _net()
    for _ in range(3000):
        sim.step()
        if sim.sleeping:
            break
    assert sim.sleeping
    rest = sim.knot_pos.copy()
    # The ball passes right through where the net hangs, but the box says those ticks are free:
    # a sleeping net stepped free stays as it is (the engine only does so out of the net's reach).
    nowhere = np.array([5.0, 5.0, 5.0, 6.0, 6.0, 6.0])
    taken, got = sim.step_run(_straight_ball(20.0, 40), BALL_RADIUS, 1.0 / BALL_MASS, nowhere)
    assert (taken, got.toi, sim.sleeping) == (40, NO_CONTACT, True)
    assert np.array_equal(sim.knot_pos, rest)
