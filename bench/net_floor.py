"""What bounds the grid net step on this machine: bare numba loops with the step's arithmetic and no more.

Run: `.venv/bin/python bench/net_floor.py [--cols 184 --rows 16]`. Three floors, each in µs per
net step (CPU time of this thread, best of 5), next to kernels.step_grid_serial timed the same way:
- roots: a root and a division per spring (float64, exact), and nothing else;
- springs: the grid kernel's spring arithmetic (_grid_line's: 12 loads, |L|, rate, scale, 3 stores)
  per spring, in plain contiguous loops of one row's length;
- knots: the knot pass (_grid_update's: 8 spring terms, velocity and position update) per knot
  and axis.
The step cannot be faster than springs + knots unless the loops overlap, which they do not (one
writes what the other reads).
"""
import argparse
import math
import time

import numpy as np
from numba import njit

from net_kernel import kernels
from net_kernel.topology import build_topology, grid_spec


@njit(cache=True, error_model="numpy")
def _roots(length2, out, reps):
    for _ in range(reps):
        for i in range(length2.shape[0]):
            out[i] = 1.0 / math.sqrt(length2[i])


@njit(cache=True, error_model="numpy")
def _springs(x, v, out, lines, reps):
    n = out.shape[1]
    for _ in range(reps):
        for _ in range(lines):
            for q in range(n):
                d0 = x[0, q + 1] - x[0, q]
                d1 = x[1, q + 1] - x[1, q]
                d2 = x[2, q + 1] - x[2, q]
                e0 = v[0, q + 1] - v[0, q]
                e1 = v[1, q + 1] - v[1, q]
                e2 = v[2, q + 1] - v[2, q]
                length2 = d0 * d0 + d1 * d1 + d2 * d2
                rate = e0 * d0 + e1 * d1 + e2 * d2
                length = math.sqrt(length2)
                inv_len = 1.0 / length
                scale = (200.0 * (length - 0.01) + 0.1 * rate * inv_len) * inv_len
                out[0, q] = scale * d0
                out[1, q] = scale * d1
                out[2, q] = scale * d2


@njit(cache=True, error_model="numpy")
def _knots(t, x, v, w, reps):
    rows, cols = w.shape
    for _ in range(reps):
        for r in range(rows):
            for k in range(3):
                a, b, c, hh, d, e, f8 = t[k], t[3 + k], t[6 + k], t[9 + k], t[12 + k], t[15 + k], t[18 + k]
                xr, vr, wr = x[k, r], v[k, r], w[r]
                for q in range(1, cols - 1):
                    f = -a[q - 1]
                    f -= b[q]
                    f -= c[q]
                    f -= hh[q - 1]
                    f += hh[q]
                    f += d[q - 1]
                    f += e[q]
                    f += f8[q]
                    wq, xi, vi = wr[q], xr[q], vr[q]
                    free = 1.0 if wq != 0.0 else 0.0
                    nv = vi + free * (1e-5 * (wq * f - 5.0 * vi))
                    vr[q] = nv
                    xr[q] = xi + free * (1e-5 * nv)


def _best(call, reps):
    call(1)
    best = math.inf
    for _ in range(5):
        t0 = time.thread_time()
        call(reps)
        best = min(best, (time.thread_time() - t0) / reps)
    return best * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--cols", type=int, default=184)
    parser.add_argument("--rows", type=int, default=16)
    parser.add_argument("--reps", type=int, default=1000)
    args = parser.parse_args()
    topo = build_topology(grid_spec(args.cols, args.rows))
    cols, rows, n_springs = args.cols, args.rows, topo.n_springs
    rng = np.random.default_rng(0)
    length2 = 1e-4 * (1.0 + 0.01 * rng.random(n_springs))
    out = np.empty(n_springs)
    lines = math.ceil(n_springs / (cols - 1))
    x = rng.random((3, cols + 1))
    v = 1e-3 * rng.random((3, cols + 1))
    t = 1e-3 * rng.random((21, cols))
    xs, vs = rng.random((3, rows, cols)), 1e-3 * rng.random((3, rows, cols))
    w = np.full((rows, cols), 60.0)
    state = np.zeros((2, 3, rows, cols))
    state[0] = topo.knot_pos.T.reshape(3, rows, cols)
    work = np.zeros((1, kernels.GRID_WORK_ROWS, cols))
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    h = 0.5 * topo.h_max
    results = {
        "roots (1/sqrt per spring)": _best(lambda r: _roots(length2, out, r), args.reps),
        "springs (the spring pass's loop)": _best(lambda r: _springs(x, v, np.empty((3, cols - 1)), lines, r),
                                                  args.reps) * n_springs / (lines * (cols - 1)),
        "knots (the knot pass's loop)": _best(lambda r: _knots(t, xs, vs, w, r), args.reps),
        "step_grid_serial (the kernel)": _best(
            lambda r: kernels.step_grid_serial(state, inv_mass, topo.grid_params, 9.81, 5.0, h, r, work), args.reps),
    }
    print(f"net {cols} x {rows}: {topo.n_knots} knots, {n_springs} springs; µs per step, this thread's CPU time, "
          "best of 5")
    for name, us in results.items():
        print(f"  {name:<36} {us:8.1f}")


if __name__ == "__main__":
    main()
