"""Free ticks (NetSim.step_free): the same bits as stepping tick by tick without a ball, and the
net's reach (NET_REACH) checked on both paths."""
import numpy as np
import pytest

from net_kernel import NetSim, build_topology, grid_spec
from net_kernel.sim import NET_REACH


def _struck(backend):
    """A 40 x 8 net just struck: free knots moving at 0.3 m/s out of its plane."""
    topo = build_topology(grid_spec(40, 8))
    sim = NetSim(topo, dt=1e-3, backend=backend)
    sim.knot_vel[:, 0] = 0.3 * (topo.knot_inv_mass > 0)
    return sim


def _state(sim):
    return sim.knot_pos.copy(), sim.knot_vel.copy(), sim.sleeping, sim.quiet_ticks, sim.box.copy()


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_free_ticks_in_one_call_equal_tick_by_tick_through_falling_asleep(backend):
    by_tick, free = _struck(backend), _struck(backend)
    ticks = 0
    while not by_tick.sleeping:
        by_tick.step()
        ticks += 1
        assert ticks < 5000, "the struck net never fell asleep"
    free.step_free(ticks - 7)  # in two runs: the sleep count carries over from one to the next
    assert not free.sleeping
    free.step_free(1000)  # stops where it falls asleep
    for a, b in zip(_state(free), _state(by_tick)):
        assert np.array_equal(a, b)
    assert free.awake_ticks == by_tick.awake_ticks  # the ticks taken, counted alike on both paths
    calls = free.kernel_calls
    free.step_free(1000)  # asleep: nothing to do
    assert free.kernel_calls == calls and free.awake_ticks == by_tick.awake_ticks


def test_free_ticks_stop_with_the_net_awake_at_the_same_bits():
    by_tick, free = _struck("numba"), _struck("numba")
    for _ in range(50):
        by_tick.step()
    free.step_free(50)
    for a, b in zip(_state(free), _state(by_tick)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("free_ticks", [False, True])
def test_a_knot_beyond_the_nets_reach_is_an_error_naming_it(free_ticks):
    sim = _struck("numba")
    sim.knot_pos[:, 0] += NET_REACH + 0.01  # the whole net, posts and all, 16 cm out of its built plane
    with pytest.raises(FloatingPointError, match="NET_REACH"):
        sim.step_free(1) if free_ticks else sim.step()
