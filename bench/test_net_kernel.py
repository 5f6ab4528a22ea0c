"""pytest-benchmark suite of the net step: numba (parallel, serial) against the numpy twin, CSR and grid kernels.

Run with `make bench` (or `.venv/bin/python -m pytest bench/test_net_kernel.py --benchmark-enable`).
Each benchmark compiles (or loads numba's cache) and warms up before timing, so compile
time is never inside a round; extra_info carries springs per second.
"""
import numpy as np
import pytest

from net_kernel import kernels, reference
from net_kernel.topology import build_topology, grid_spec

SIZES = {"table_184x16": (184, 16), "grid_1000x1000": (1000, 1000)}
BACKENDS = {
    "numba_parallel": kernels.step_knots,
    "numba_serial": kernels.step_knots_serial,
    "reference": reference.step_knots,
}


@pytest.fixture(scope="module", params=sorted(SIZES))
def net(request):
    topo = build_topology(grid_spec(*SIZES[request.param]))
    rng = np.random.default_rng(0)
    free = (topo.knot_inv_mass > 0)[:, None]
    pos = topo.knot_pos + free * rng.normal(0.0, 1e-6, topo.knot_pos.shape)
    vel = free * rng.normal(0.0, 1e-3, topo.knot_pos.shape)
    return request.param, topo, pos, vel


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_net_step(benchmark, net, backend):
    name, topo, pos, vel = net
    step = BACKENDS[backend]
    out_pos, out_vel = np.empty_like(pos), np.empty_like(vel)
    args = (pos, vel, topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring, topo.spring_ij,
            topo.spring_rest, topo.spring_k, topo.spring_c, 9.81, 5.0, 0.5 * topo.h_max, np.zeros((kernels.STEP_WORK_ROWS, topo.n_springs)),
            out_pos, out_vel)
    step(*args)  # compile / load the cache, outside the timing
    step(*args)
    rounds = 3 if (backend == "reference" and name.startswith("grid")) else 20
    benchmark.pedantic(step, args=args, rounds=rounds, iterations=1, warmup_rounds=1)
    benchmark.extra_info["springs"] = topo.n_springs
    benchmark.extra_info["msprings_per_s"] = topo.n_springs / benchmark.stats.stats.median / 1e6
    assert np.all(np.isfinite(out_pos))


GRID_BACKENDS = {
    "grid_numba_parallel": kernels.step_grid,
    "grid_numba_serial": kernels.step_grid_serial,
    "grid_reference": reference.step_grid,
}
STEPS_PER_CALL = 25  # the default net's substeps in a 1 ms tick, taken in one call by NetSim


@pytest.mark.parametrize("backend", sorted(GRID_BACKENDS))
def test_net_step_grid(benchmark, net, backend):
    name, topo, pos, vel = net
    step = GRID_BACKENDS[backend]
    rows, cols = topo.spec.rows, topo.spec.cols
    state = np.zeros((2, 3, rows, cols))
    state[0] = pos.T.reshape(3, rows, cols)
    state[1] = vel.T.reshape(3, rows, cols)
    blocks = 2 if backend == "grid_numba_parallel" else 1
    steps = 1 if (backend == "grid_reference" and name.startswith("grid")) else STEPS_PER_CALL
    args = (state, topo.knot_inv_mass.reshape(rows, cols), topo.grid_params, 9.81, 5.0, 0.5 * topo.h_max, steps,
            kernels.grid_work(rows, cols, blocks))
    step(*args)  # compile / load the cache, outside the timing
    rounds = 3 if name.startswith("grid") else 20
    benchmark.pedantic(step, args=args, rounds=rounds, iterations=1, warmup_rounds=1)
    benchmark.extra_info["springs"] = topo.n_springs
    benchmark.extra_info["steps_per_call"] = steps
    benchmark.extra_info["msprings_per_s"] = steps * topo.n_springs / benchmark.stats.stats.median / 1e6
    assert np.all(np.isfinite(state))


COLLIDERS = {"full": kernels.collide_ball, "near": kernels.collide_ball_near}


@pytest.mark.parametrize("sweep", sorted(COLLIDERS))
def test_net_contact_sweep(benchmark, sweep):
    """One substep's contact sweep on the default net, the ball 3 cm in front of it (near, no contact)."""
    topo = build_topology(grid_spec(184, 16))
    pos, vel = topo.knot_pos.copy(), np.zeros_like(topo.knot_pos)
    args = (pos, vel, topo.knot_inv_mass, np.array([-0.03, 0.0, 0.08]), np.array([0.0, 2.0, 0.0]), 0.02, 1 / 2.7e-3,
            0.5e-3, 0.0, 0.5 * topo.h_max, 8, np.zeros(3), np.zeros(3))
    if sweep == "near":
        args = args + (np.zeros(topo.n_knots, dtype=np.int64),)
    collide = COLLIDERS[sweep]
    assert collide(*args) == kernels.NO_CONTACT  # compile / load the cache, outside the timing
    benchmark.pedantic(collide, args=args, rounds=200, iterations=1, warmup_rounds=5)
    benchmark.extra_info["knots"] = topo.n_knots
