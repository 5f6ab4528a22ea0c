"""A struck net's bound (NetSim.bound_box): it holds every knot through the ring-down, and a free
tick that leaves it is an error naming it."""
import numpy as np
import pytest

from engine.physics.scene import load_scene
from net_kernel import NetBoundError, NetSim, build_topology
from net_kernel.bound import BOUND_ENERGY_FACTOR
from net_kernel.sim import BALL_MASS, BALL_RADIUS

SPEC = load_scene("match").cloth  # the match's net: 85 x 8 knots, float32 grid kernels, the linear tail
DT = 1e-3


def _strike(speed: float, height: float) -> NetSim:
    """The match's net struck square in its middle by a ball at `speed` m/s, `height` m up; returned
    once the ball is out of its reach (gone through, over or back)."""
    sim = NetSim(build_topology(SPEC), DT)
    pos, vel = np.array([-0.1, 0.0, height]), np.array([speed, 0.0, 0.0])
    for _ in range(2000):
        contact = sim.step(pos, vel, BALL_RADIUS, 1.0 / BALL_MASS)
        pos = pos + vel * DT + contact.offset
        vel = vel + contact.impulse / BALL_MASS
        if abs(pos[0]) > 0.4:
            return sim
    raise AssertionError(f"a {speed} m/s ball is still within the net's reach after 2 s")


@pytest.mark.parametrize("speed, height", [(5.0, 0.08), (10.0, 0.03), (20.0, 0.12), (40.0, 0.08)])
def test_the_bound_holds_every_knot_through_the_ring_down(speed, height):
    sim = _strike(speed, height)
    assert not sim.sleeping and sim.tail is None  # still ringing: the case the bound is for
    bound = sim.bound_box().copy()
    assert np.all(bound[0] <= sim.box[0]) and np.all(sim.box[1] <= bound[1])
    for tick in range(4000):
        sim.step()  # no ball: every knot's place, tick by tick
        if sim.tail is not None or sim.sleeping:
            break
        # the box of the knots' positions at each tick lies inside (no tolerance: the bound is a bound)
        assert np.all(bound[0] <= sim.box[0]) and np.all(sim.box[1] <= bound[1]), (
            f"{speed} m/s: tick {tick} after the strike, knots span {sim.box.tolist()}, bound {bound.tolist()}")
    assert sim.tail is not None or sim.sleeping, "the struck net rang for 4 s"


def test_free_ticks_check_the_bound_and_say_so_when_a_knot_leaves_it():
    sim = _strike(10.0, 0.08)
    sim.bound_box()
    sim.step_free(200)  # the bound holds: nothing to say
    sim.bound = sim.box.copy()  # a bound that no moving knot keeps
    with pytest.raises(NetBoundError, match=f"BOUND_ENERGY_FACTOR = {BOUND_ENERGY_FACTOR}"):
        sim.step_free(1000)


def test_a_ball_near_the_net_ends_the_bound():
    sim = _strike(10.0, 0.08)
    sim.bound_box()
    sim.step(np.array([-0.05, 0.0, 0.08]), np.array([5.0, 0.0, 0.0]), BALL_RADIUS, 1.0 / BALL_MASS)
    assert sim.bound is None  # the ball may touch it: free ticks after check the reach only
