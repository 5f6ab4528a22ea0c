"""The grid kernels: the CSR kernels' bits by index arithmetic, in place, for any row blocking and steps per call."""
import numpy as np
import pytest

from net_kernel import NetSim, NetSpec, build_topology, grid_spec, kernels, make_topology, reference
from net_kernel.kernels import grid_work
from tests.helpers.net import perturbed

STEPS = 7


def _state(topo, seed):
    """(2, 3, rows, cols) state of a perturbed, moving net, and the same as (n, 3) positions and velocities."""
    rows, cols = topo.spec.rows, topo.spec.cols
    pos, vel = perturbed(topo, seed=seed)
    state = np.zeros((2, 3, rows, cols))
    state[0] = pos.T.reshape(3, rows, cols)
    state[1] = vel.T.reshape(3, rows, cols)
    return state, pos, vel


def _grid_steps(mod, name, topo, state, steps, blocks=1):
    h = 0.5 * topo.h_max
    work = grid_work(topo.spec.rows, topo.spec.cols, blocks)
    inv_mass = topo.knot_inv_mass.reshape(topo.spec.rows, topo.spec.cols)
    getattr(mod, name)(state, inv_mass, topo.grid_params, 9.81, 5.0, h, steps, work)


def _csr_steps(topo, pos, vel, steps):
    work = np.zeros((kernels.STEP_WORK_ROWS, topo.n_springs))
    for _ in range(steps):
        out_pos, out_vel = np.empty_like(pos), np.empty_like(vel)
        kernels.step_knots_serial(pos, vel, topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring,
                                  topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, 9.81, 5.0,
                                  0.5 * topo.h_max, work, out_pos, out_vel)
        pos, vel = out_pos, out_vel
    return pos, vel


# The default fixing, free posts (border columns step), free table row (bottom row steps), and a
# net taller than kernels.grid.CHUNK_ROWS (the serial kernel's chunks meet inside it).
NETS = [grid_spec(24, 8), grid_spec(24, 8, fix_posts=False, fix_table=True), grid_spec(9, 5, fix_table=True),
        grid_spec(7, 2 * kernels.grid.CHUNK_ROWS + 5)]


@pytest.mark.parametrize("spec", NETS, ids=["hanging", "free_posts", "tied", "tall"])
def test_grid_equals_csr_bit_for_bit(spec):
    topo = build_topology(spec)
    state, pos, vel = _state(topo, seed=11)
    _grid_steps(kernels, "step_grid_serial", topo, state, STEPS)
    csr_pos, csr_vel = _csr_steps(topo, pos, vel, STEPS)
    # Exact: same spring expression on the same old state, same per-knot summation order (a
    # missing border spring adds +-0, which array_equal counts equal).
    assert np.array_equal(state[0].reshape(3, -1).T, csr_pos)
    assert np.array_equal(state[1].reshape(3, -1).T, csr_vel)


@pytest.mark.parametrize("spec", NETS[:2], ids=["hanging", "free_posts"])
def test_grid_equals_reference(spec):
    topo = build_topology(spec)
    state, _, _ = _state(topo, seed=12)
    twin = state.copy()
    _grid_steps(kernels, "step_grid_serial", topo, state, STEPS)
    _grid_steps(reference, "step_grid", topo, twin, STEPS)
    # The twin does the kernel's IEEE operations in its order (no FMA, no reassociation):
    # equal to the last bit, observed; 1e-15 m and m/s leave room for a platform's libm.
    np.testing.assert_allclose(state, twin, rtol=0, atol=1e-15)


@pytest.mark.parametrize("spec", [NETS[0], NETS[3]], ids=["hanging", "tall"])
def test_blocks_threads_and_steps_per_call_give_the_same_bits(spec):
    topo = build_topology(spec)
    rows, cols = spec.rows, spec.cols
    start, _, _ = _state(topo, seed=13)
    results = []
    # Blocks of one row (rows) and of uneven sizes (3) exercise every block border; on the tall net
    # the blocks also step in chunks (kernels.grid.CHUNK_ROWS) that end inside them.
    for name, blocks, calls in (("step_grid_serial", 1, 1), ("step_grid", 1, 1), ("step_grid", 3, 1),
                                ("step_grid", rows, 1), ("step_grid_serial", 3, STEPS)):
        state = start.copy()
        for _ in range(calls):
            work = grid_work(rows, cols, blocks)
            getattr(kernels, name)(state, topo.knot_inv_mass.reshape(rows, cols), topo.grid_params, 9.81, 5.0,
                                   0.5 * topo.h_max, STEPS // calls, work)
        results.append(state)
    for other in results[1:]:
        assert np.array_equal(other, results[0])  # exact: blocks recompute their border springs, no races


def test_zero_steps_leave_the_state_alone():
    topo = build_topology(grid_spec(12, 4))
    state, _, _ = _state(topo, seed=14)
    before = state.copy()
    _grid_steps(kernels, "step_grid", topo, state, 0)
    assert np.array_equal(state, before)


def test_netsim_picks_the_grid_kernels_and_matches_csr_through_an_impact():
    topo = build_topology(NetSpec(width=0.5, cols=51, knot_mass=NetSpec().knot_mass))
    sims = [NetSim(topo, 1e-3), NetSim(topo, 1e-3, grid=False)]
    assert sims[0].grid and not sims[1].grid
    balls = []
    for sim in sims:
        pos, vel = np.array([-0.1, 0.0, 0.08]), np.array([20.0, 0.0, 0.0])
        for _ in range(12):  # far, contact, far again: both the one-call and the per-substep path
            contact = sim.step(pos, vel, 0.02, 1 / 2.7e-3)
            pos = pos + vel * 1e-3 + contact.offset
            vel = vel + contact.impulse / 2.7e-3
        balls.append((pos, vel))
    assert balls[0][1][0] < 0  # the net threw the ball back
    assert np.array_equal(sims[0].knot_pos, sims[1].knot_pos)  # exact: the same bits as CSR
    assert np.array_equal(sims[0].knot_vel, sims[1].knot_vel)
    assert np.array_equal(balls[0][0], balls[1][0])
    # While the ball is away a tick is one kernel call plus the rest check, not one per substep.
    assert sims[0].kernel_calls < sims[1].kernel_calls


def test_grid_refused_where_it_does_not_apply():
    raw = make_topology(np.array([[0, 0, 0], [0, 0.01, 0], [0, 0.02, 0.0]]), np.full(3, 1e-3), [True, False, True],
                        [[0, 1], [1, 2]], [0.01, 0.01], [100.0, 100.0], [0.0, 0.0])
    assert raw.grid_params is None and not NetSim(raw, 1e-3).grid
    with pytest.raises(ValueError, match="grid=True needs a net built by build_topology"):
        NetSim(raw, 1e-3, grid=True)
    implicit = build_topology(grid_spec(12, 4, solver="implicit"))
    assert not NetSim(implicit, 1e-3).grid
    with pytest.raises(ValueError, match="semi-implicit"):
        NetSim(implicit, 1e-3, grid=True)


def test_class_parameters_are_every_spring_s():
    topo = build_topology(grid_spec(10, 5))
    table = {tuple(row) for row in topo.grid_params}
    springs = {tuple(row) for row in np.stack([topo.spring_k, topo.spring_c, topo.spring_rest], axis=1)}
    assert springs <= table  # every spring takes its class's exact values


def test_netsim_reference_backend_steps_the_grid_twin():
    topo = build_topology(grid_spec(24, 8))
    sims = [NetSim(topo, 1e-3), NetSim(topo, 1e-3, backend="reference")]
    pos, vel = perturbed(topo, seed=15)
    for sim in sims:
        assert sim.grid
        sim.knot_pos[:] = pos  # through the (n, 3) views into the grid state
        sim.knot_vel[:] = vel
        for _ in range(3):
            sim.step()
    # The twin repeats the kernel's operations in order: equal to the last bit, observed;
    # 1e-15 m and m/s leave room for a platform's libm.
    np.testing.assert_allclose(sims[0].knot_pos, sims[1].knot_pos, rtol=0, atol=1e-15)
    np.testing.assert_allclose(sims[0].knot_vel, sims[1].knot_vel, rtol=0, atol=1e-15)
    assert not np.array_equal(sims[0].knot_pos, pos)  # it moved
