"""What bounds the grid net step on this machine: bare numba loops with the step's arithmetic and no more.

Run: `.venv/bin/python bench/net_floor.py [--cols 184 --rows 16] [--zmm]`. Each row is µs per net
step (CPU time of this thread, best of 5), next to kernels.step_grid_serial timed the same way,
with the register width its loop compiled to (net_kernel.assembly):
- roots: a root and a division per spring (float64, exact), and nothing else: the divider;
- springs: the grid kernel's spring arithmetic (kernels.grid._grid_line's: 12 loads, |L|, rate,
  scale, 3 stores) per spring, in plain contiguous loops of one row's length;
- springs without the divider: the same with 1/|L| from a float32 root and division and one
  float64 Newton step (what a divider-free spring would cost; no kernel rounds this way);
- knots: the knot pass (kernels.grid._knots's: 8 spring terms, velocity and position update) per
  knot and axis, one flat loop over the grid as the kernel's.
The step cannot be faster than springs + knots unless the loops overlap, which they do not (one
writes what the other reads). --zmm compiles everything for 512-bit vectors (LLVM prefers 256
bits on these CPUs: NUMBA_CPU_FEATURES with the host's features and -prefer-256-bit), to see
whether the wider registers pay.
"""
import argparse
import math
import os
import sys
import time

if __name__ == "__main__" and "--zmm" in sys.argv:  # before numba reads its configuration
    import llvmlite.binding as llvm

    os.environ["NUMBA_CPU_FEATURES"] = llvm.get_host_cpu_features().flatten() + ",-prefer-256-bit"

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from bench import net_costs as net_profile  # noqa: E402
from net_kernel import kernels  # noqa: E402
from net_kernel.assembly import vector_report  # noqa: E402
from net_kernel.topology import build_topology, grid_spec  # noqa: E402


@njit(cache=True, error_model="numpy")
def _knots(t, x, v, w, reps):
    n = w.shape[0] - 1
    for _ in range(reps):
        for k in range(3):
            a, b, c, hh, d, e, f8 = t[k], t[3 + k], t[6 + k], t[9 + k], t[12 + k], t[15 + k], t[18 + k]
            xr, vr = x[k], v[k]
            for q in range(1, n):
                f = -a[q - 1]
                f -= b[q]
                f -= c[q]
                f -= hh[q - 1]
                f += hh[q]
                f += d[q - 1]
                f += e[q]
                f += f8[q]
                wq, xi, vi = w[q], xr[q], vr[q]
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
    parser.add_argument("--zmm", action="store_true", help="compile for 512-bit vectors (read before numba loads)")
    args = parser.parse_args()
    topo = build_topology(grid_spec(args.cols, args.rows))
    cols, rows, n_springs = args.cols, args.rows, topo.n_springs
    rng = np.random.default_rng(0)
    length2 = 1e-4 * (1.0 + 0.01 * rng.random(n_springs))
    out = np.empty(n_springs)
    lines = math.ceil(n_springs / (cols - 1))
    per_spring = n_springs / (lines * (cols - 1))
    x = 0.01 * np.arange(cols + 1) + 1e-4 * rng.random((3, cols + 1))
    v = 1e-3 * rng.random((3, cols + 1))
    line_out = np.empty((3, cols - 1))
    t = 1e-3 * rng.random((21, rows * cols))
    xs, vs = rng.random((3, rows * cols)), 1e-3 * rng.random((3, rows * cols))
    w = np.full(rows * cols, 60.0)
    state = np.zeros((2, 3, rows, cols))
    state[0] = topo.knot_pos.T.reshape(3, rows, cols)
    work = kernels.grid_work(rows, cols)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    h = 0.5 * topo.h_max
    rows_out = {
        "roots (1/sqrt per spring)": (
            _best(lambda r: net_profile._divider_floor(length2, out, r), args.reps),  # noqa: SLF001
            vector_report(net_profile._divider_floor, (length2, out, 1))),  # noqa: SLF001
        "springs (the spring pass's loop)": (
            per_spring * _best(lambda r: net_profile._spring_floor(x, v, line_out, lines, r), args.reps),  # noqa: SLF001
            vector_report(net_profile._spring_floor, (x, v, line_out, lines, 1))),  # noqa: SLF001
        "springs without the divider": (
            per_spring * _best(lambda r: net_profile._spring_floor_no_divider(x, v, line_out, lines, r),  # noqa: SLF001
                               args.reps),
            vector_report(net_profile._spring_floor_no_divider, (x, v, line_out, lines, 1))),  # noqa: SLF001
        "knots (the knot pass's loop)": (_best(lambda r: _knots(t, xs, vs, w, r), args.reps),
                                         vector_report(_knots, (t, xs, vs, w, 1))),
        "step_grid_serial (the kernel)": (
            _best(lambda r: kernels.step_grid_serial(state, inv_mass, topo.grid_params, 9.81, 5.0, h, r, work),
                  args.reps),
            vector_report(net_profile._grid_springs, (state, inv_mass, topo.grid_params, work))),  # noqa: SLF001
    }
    print(f"net {cols} x {rows}: {topo.n_knots} knots, {n_springs} springs; µs per step, this thread's CPU time, "
          f"best of 5; {'512-bit vectors preferred' if args.zmm else 'the compiler default width'}")
    for name, (us, vectors) in rows_out.items():
        print(f"  {name:<36} {us:8.1f}   {vectors['width']} x{vectors['lanes']}")


if __name__ == "__main__":
    main()
