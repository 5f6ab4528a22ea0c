"""The numba kernels equal their numpy twins, and parallel runs repeat bit for bit."""
import numba
import numpy as np
import pytest

from net_kernel import kernels, reference
from net_kernel.kernels import KNOT_WORK_ROWS, NO_CONTACT, SPRING_WORK_COLS
from net_kernel.topology import NetSpec, build_topology
from tests.helpers.net import perturbed


def _step_args(topo, h):
    return (topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring, topo.spring_ij, topo.spring_rest,
            topo.spring_k, topo.spring_c, 9.81, 5.0, h, np.zeros((kernels.STEP_WORK_ROWS, topo.n_springs)))


@pytest.mark.parametrize("name", ["step_knots", "step_knots_serial"])
def test_step_equals_reference(small_topo, name):
    topo = small_topo
    pos, vel = perturbed(topo)
    outs = []
    for mod in (kernels, reference):
        p, v = pos.copy(), vel.copy()
        for _ in range(20):
            op, ov = np.empty_like(p), np.empty_like(v)
            getattr(mod, name)(p, v, *_step_args(topo, 0.5 * topo.h_max), op, ov)
            p, v = op, ov
        outs.append((p, v))
    # Same per-knot slot order in both; only the reference's vectorised products round
    # differently: 20 steps of 1e-16-relative errors stay far below 1e-12 m and 1e-9 m/s.
    np.testing.assert_allclose(outs[0][0], outs[1][0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(outs[0][1], outs[1][1], rtol=0, atol=1e-9)


def test_parallel_equals_serial_bit_for_bit(small_topo):
    topo = small_topo
    pos, vel = perturbed(topo, seed=1)
    results = []
    for step, threads in ((kernels.step_knots, 2), (kernels.step_knots, 1), (kernels.step_knots_serial, 1),
                          (kernels.step_knots, 2)):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        op, ov = np.empty_like(pos), np.empty_like(vel)
        step(pos, vel, *_step_args(topo, 0.5 * topo.h_max), op, ov)
        results.append((op, ov))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    for op, ov in results[1:]:
        assert np.array_equal(op, results[0][0]) and np.array_equal(ov, results[0][1])  # exact: a gather, no races


def test_implicit_equals_reference(small_topo):
    topo = small_topo
    pos, vel = perturbed(topo, seed=2)
    outs = []
    for mod in (kernels, reference):
        op, ov = np.empty_like(pos), np.empty_like(vel)
        iters = mod.step_knots_implicit(pos, vel, topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring,
                                        topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, 9.81, 5.0,
                                        20 * topo.h_max, 1e-12, 1000, np.zeros((KNOT_WORK_ROWS, topo.n_knots, 3)),
                                        np.zeros((topo.n_springs, SPRING_WORK_COLS)), op, ov)
        outs.append((op, ov, iters))
    scale = np.abs(outs[1][1]).max()
    # CG to a 1e-12 relative residual: both solutions agree to ~1e-10 of the velocity scale
    # (CG amplifies rounding by the system's condition number, ~1e2 here).
    np.testing.assert_allclose(outs[0][1], outs[1][1], rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(outs[0][0], outs[1][0], rtol=0, atol=1e-8 * scale * 20 * topo.h_max)
    assert abs(outs[0][2] - outs[1][2]) <= 2  # iteration counts differ only by rounding at the stop


def test_collide_equals_reference():
    topo = build_topology(NetSpec())  # the real mesh: 1 cm cells, finer than the ball
    results = []
    for mod in (kernels, reference):
        pos, vel = perturbed(topo, seed=3, vel_scale=0.01)
        impulse, end = np.zeros(3), np.zeros(3)
        toi = mod.collide_ball(pos, vel, topo.knot_inv_mass, np.array([-0.05, 0.0, 0.08]), np.array([30.0, 0.0, -1.0]),
                               0.02, 1 / 2.7e-3, 5e-4, 0.0, 2e-3, 8, impulse, end)
        results.append((toi, impulse, end, pos, vel))
    assert results[0][0] != NO_CONTACT
    assert results[0][0] == pytest.approx(results[1][0], abs=1e-12)  # same quadratic, different rounding
    for a, b in zip(results[0][1:], results[1][1:]):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)  # same sums in the same order, up to rounding


def test_speed_max_equals_reference_and_flags_nan(small_topo):
    pos, vel = perturbed(small_topo, seed=4)
    assert kernels.knot_speed_max(pos, vel) == pytest.approx(reference.knot_speed_max(pos, vel), rel=1e-15)
    vel[3, 1] = np.nan
    assert kernels.knot_speed_max(pos, vel) == np.inf == reference.knot_speed_max(pos, vel)


def _scatter(mod, topo, pos, vel, steps):
    for _ in range(steps):
        op, ov = np.empty_like(pos), np.empty_like(vel)
        mod.step_knots_scatter(pos, vel, topo.knot_inv_mass, topo.spring_ij, topo.spring_rest, topo.spring_k,
                               topo.spring_c, 9.81, 5.0, 0.5 * topo.h_max, np.empty_like(pos), op, ov)
        pos, vel = op, ov
    return pos, vel


def test_textbook_scatter_equals_its_twin_bit_for_bit(small_topo):
    pos, vel = perturbed(small_topo, seed=5)
    kernel, twin = _scatter(kernels, small_topo, pos, vel, 20), _scatter(reference, small_topo, pos, vel, 20)
    assert np.array_equal(kernel[0], twin[0]) and np.array_equal(kernel[1], twin[1])  # np.add.at: the loop's order


def test_textbook_scatter_steps_as_step_knots(small_topo):
    topo = small_topo
    pos, vel = perturbed(topo, seed=6)
    scatter = _scatter(kernels, topo, pos, vel, 20)
    p, v = pos, vel
    for _ in range(20):
        op, ov = np.empty_like(p), np.empty_like(v)
        kernels.step_knots_serial(p, v, *_step_args(topo, 0.5 * topo.h_max), op, ov)
        p, v = op, ov
    # The same model; only the order of each knot's sum (spring order against slot order) and
    # n = L/|L| against scale L round apart: the tolerances of test_step_equals_reference.
    np.testing.assert_allclose(scatter[0], p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scatter[1], v, rtol=0, atol=1e-9)
