"""The net step's costs: compile time, time per step, springs per second, bandwidth share.

Beside the kernels: the textbook per-spring scatter loop timed on the same net in the same run
(the ratios), the grid kernel's passes timed apart (grid_passes), and the vector width of each
kernel's loops (kernel_vectors, from numba's assembly).

Plain dicts out; bench/profile_net.py (`pingpong profile-net`) runs and formats them.

Kernel paths: "csr", the general per-knot gather over the CSR adjacency (kernels.step_knots,
one step a call), and "grid", the structured-grid kernel (kernels.step_grid, NetSim's path for
build_topology's nets), both float64 and the same bits; "grid32" and "grid32_fma", the grid
kernel in float32 on offsets from the built grid (kernels.step_grid32, NetSpec.kernel_precision
"float32", without and with kernel_fma). The grid paths are timed as NetSim calls them while the
ball is away: a 1 ms tick's substeps in one call (steps_per_call; fewer on big nets, where one
call would outlast a timed run).

Byte model of one step (the compulsory memory traffic, neighbours from cache):
  csr, per knot: spring pass reads knot_pos, knot_vel (48 B); knot pass reads knot_pos,
            knot_vel (48 B), knot_inv_mass (8 B), adj_start (8 B), writes out_pos,
            out_vel (48 B)                                                    -> 160 B
  csr, per spring: spring pass reads spring_ij (uint32, 8 B), writes |L|^2 and the rate
            (16 B), reads them back (16 B) with spring_rest, spring_k, spring_c (24 B),
            writes the scale (8 B); knot pass reads 2 slots of adj_knot, adj_spring
            (uint32, 16 B) and the scale twice (16 B)                           -> 104 B
  grid, per knot: reads position and velocity (48 B) and knot_inv_mass (8 B), writes
            them back in place (48 B)                                         -> 104 B
  grid, per spring: nothing (class parameters; a row's spring forces stay in a scratch
            of a few rows, in cache)                                            -> 0 B
  grid32, per knot: float32 offset and velocity read and written (24 + 24 B), the step's
            factors (16 B) and the table's offset (4 B); the float64 state's conversion
            in and out once a call is left out (amortised over the call's steps)  -> 68 B
  textbook scatter, per knot: the force zeroed (24 B), read and written by the spring
            loop (48 B), read by the knot loop (24 B); pos, vel read by both loops (96 B);
            knot_inv_mass (8 B); out_pos, out_vel written (48 B)               -> 248 B
  textbook scatter, per spring: spring_ij (8 B), rest, k, c (24 B)            -> 32 B
Write-allocate traffic is not counted, as it is not in the copy measurement
(bytes = 2 x size: one read, one write).
"""
import math
import os
import statistics
import time
from dataclasses import replace

import numba
import numpy as np
from numba import njit

from net_kernel import kernels, reference
from net_kernel.assembly import vector_report
from net_kernel.kernels import grid as grid_kernels
from net_kernel.kernels import grid32 as grid32_kernels
from net_kernel.sim import SAFETY, NetSim
from net_kernel.topology import FLOAT32, build_topology, grid_spec, resolution_spec

BYTES_PER_KNOT = 160
BYTES_PER_SPRING = 104
GRID_BYTES_PER_KNOT = 104
GRID_BYTES_PER_SPRING = 0
GRID32_BYTES_PER_KNOT = 68
TEXTBOOK_BYTES_PER_KNOT = 248
TEXTBOOK_BYTES_PER_SPRING = 32
PATHS = ("grid", "grid32", "grid32_fma", "csr")
GRID32_PATHS = {"grid32": kernels.GRID32_EXACT, "grid32_fma": kernels.GRID32_FMA}  # path: grid32_work's variant
# The textbook kernel (kernels.step_knots_scatter) is timed as a path of its own, serial, one
# step a call, on the same net in the same run: the baseline of the ratios.
TEXTBOOK = "scatter"
# The tick whose substeps the grid path takes in one call (the engine's match tick).
TICK_S = 1e-3
# The copy that sets this machine's bandwidth: large enough to leave every cache (256 MiB).
COPY_BYTES = 256 * 2**20
REPEATS = 5


def copy_bandwidth(n_bytes: int = COPY_BYTES, repeats: int = REPEATS) -> dict:
    """GB/s of a large numpy copy (read + write counted), median and spread of `repeats`."""
    src = np.ones(n_bytes // 8)
    dst = np.empty_like(src)
    np.copyto(dst, src)  # first touch: page faults out of the timing
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.copyto(dst, src)
        rates.append(2 * src.nbytes / (time.perf_counter() - t0) / 1e9)
    return {"gb_per_s": statistics.median(rates), "min": min(rates), "max": max(rates), "bytes": 2 * src.nbytes}


def moving_state(topo, seed=0):
    """A perturbed, moving state (so no branch is trivially skipped) and output buffers."""
    rng = np.random.default_rng(seed)
    free = (topo.knot_inv_mass > 0)[:, None]
    spacing = min(topo.spec.width / (topo.spec.cols - 1), topo.spec.height / (topo.spec.rows - 1))
    pos = topo.knot_pos + free * rng.normal(0.0, 0.01 * spacing, topo.knot_pos.shape)
    vel = free * rng.normal(0.0, 1e-3, topo.knot_pos.shape)
    return pos, vel, np.empty_like(pos), np.empty_like(vel)


def _substeps_per_tick(topo) -> int:
    """Substeps NetSim takes in one TICK_S tick (its step count; the profile's step size is 0.5 h_max)."""
    return max(1, math.ceil(TICK_S / (SAFETY * topo.h_max)))


def profile_backend(topo, backend: str, steps: int | None, parallel: bool = True, target_s: float = 1.0,
                    repeats: int = REPEATS, path: str = "csr", steps_per_call: int | None = None) -> dict:
    """Time `steps` semi-implicit steps of `topo` with one backend and path (median of `repeats` runs).

    Args:
        topo: the built net (a build_topology grid for path "grid").
        backend: "numba" or "reference".
        steps: steps per timed run; None sizes a run to about target_s / repeats.
        parallel: numba: the parallel kernel (else the serial twin of the same bits).
        target_s: s, rough total timing budget when steps is None.
        repeats: timed runs.
        path: "csr" (step_knots, one step a call), "grid" (step_grid) or a GRID32_PATHS one (step_grid32).
        steps_per_call: grid: steps per kernel call (None: a TICK_S tick's substeps, as
            NetSim calls it, or fewer if a call would outlast one timed run); csr: always 1.
    """
    if path not in PATHS + (TEXTBOOK,):
        raise ValueError(f"path {path!r} is not one of {', '.join(PATHS + (TEXTBOOK,))}")
    mod = kernels if backend == "numba" else reference
    pos, vel, out_pos, out_vel = moving_state(topo)
    h = 0.5 * topo.h_max
    grid = path == "grid" or path in GRID32_PATHS
    if grid:
        rows, cols = topo.spec.rows, topo.spec.cols
        state = np.zeros((2, 3, rows, cols))
        state[0] = pos.T.reshape(3, rows, cols)
        state[1] = vel.T.reshape(3, rows, cols)
        blocks = min(rows, max(1, numba.get_num_threads())) if parallel and backend == "numba" else 1
        inv_mass = topo.knot_inv_mass.reshape(rows, cols)
        if path == "grid":
            step = mod.step_grid if parallel else mod.step_grid_serial
            work = kernels.grid_work(rows, cols, blocks)
        else:
            step = mod.step_grid32 if parallel else mod.step_grid32_serial
            work = mod.grid32_work(topo.knot_pos.T.reshape(3, rows, cols).copy(), inv_mass, blocks, GRID32_PATHS[path])

        def call(n):
            step(state, inv_mass, topo.grid_params, topo.spec.gravity, topo.spec.air_damping, h, n, work)
    elif path == TEXTBOOK:
        step = mod.step_knots_scatter  # serial only: a scatter is a race under threads
        parallel = False
        args = (topo.knot_inv_mass, topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, topo.spec.gravity,
                topo.spec.air_damping, h, np.zeros_like(pos))
        buffers = [pos, vel, out_pos, out_vel]

        def call(n):  # one step a call, as the CSR kernel
            for _ in range(n):
                p, v, po, vo = buffers
                step(p, v, *args, po, vo)
                buffers[:] = po, vo, p, v
    else:
        step = mod.step_knots if parallel else mod.step_knots_serial
        args = (topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring, topo.spring_ij, topo.spring_rest,
                topo.spring_k, topo.spring_c, topo.spec.gravity, topo.spec.air_damping, h,
                np.zeros((kernels.STEP_WORK_ROWS, topo.n_springs)))
        buffers = [pos, vel, out_pos, out_vel]

        def call(n):  # the CSR kernel takes one step a call
            p, v, po, vo = buffers
            step(p, v, *args, po, vo)
            buffers[:] = po, vo, p, v
    t0 = time.perf_counter()
    call(1)  # compiles (or loads the cache) on the first call
    first_call = time.perf_counter() - t0
    # One step's time, the best of three (a shared machine's worst is noise, not the kernel).
    one = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        call(1)
        one = min(one, time.perf_counter() - t0)
    budget = target_s / repeats  # s, one timed run
    per_call = 1
    if grid:
        # A tick's substeps (NetSim's call), fewer where that would not fit one timed run
        # (a large net: hundreds of substeps a tick, each of them long).
        per_call = steps_per_call or max(1, min(_substeps_per_tick(topo), int(budget / max(one, 1e-7))))
        if steps is not None:
            per_call = min(per_call, steps)
    calls = max(1, (steps or per_call) // per_call)
    if steps is None:
        calls = max(1, min(100_000, int(budget / max(one * per_call, 1e-7))))
    call(per_call)  # warm: the first call of a new step count
    runs = []
    cpu_runs = []
    for _ in range(repeats):
        c0 = time.thread_time()
        t0 = time.perf_counter()
        for _ in range(calls):
            call(per_call)
        runs.append((time.perf_counter() - t0) / (calls * per_call))
        cpu_runs.append((time.thread_time() - c0) / (calls * per_call))
    per_step = statistics.median(runs)
    # One thread's CPU time: a serial kernel's cost on its core, steadier than wall time on a shared
    # machine (time spent waiting for a core is left out); not defined for the parallel kernel.
    cpu_per_step = statistics.median(cpu_runs) if not (parallel and backend == "numba") else None
    per_knot, per_spring = {"grid": (GRID_BYTES_PER_KNOT, GRID_BYTES_PER_SPRING),
                            "grid32": (GRID32_BYTES_PER_KNOT, GRID_BYTES_PER_SPRING),
                            "grid32_fma": (GRID32_BYTES_PER_KNOT, GRID_BYTES_PER_SPRING),
                            TEXTBOOK: (TEXTBOOK_BYTES_PER_KNOT, TEXTBOOK_BYTES_PER_SPRING)}.get(
                                path, (BYTES_PER_KNOT, BYTES_PER_SPRING))
    n_bytes = per_knot * topo.n_knots + per_spring * topo.n_springs
    return {
        "backend": backend,
        "path": path,
        "parallel": bool(parallel) if backend == "numba" else False,
        "compile_s": max(0.0, first_call - one) if backend == "numba" else 0.0,
        "steps": calls * per_call,
        "steps_per_call": per_call,
        "repeats": repeats,
        "us_per_step": per_step * 1e6,
        "us_per_step_min": min(runs) * 1e6,
        "us_per_step_max": max(runs) * 1e6,
        "cpu_us_per_step": None if cpu_per_step is None else cpu_per_step * 1e6,
        "msprings_per_s": topo.n_springs / per_step / 1e6,
        "bytes_per_step": n_bytes,
        "gb_per_s": n_bytes / per_step / 1e9,
    }


def profile_net(cols: int, rows: int, steps: int | None = None, backends=("numba", "reference"),
                target_s: float = 1.0, paths=PATHS) -> dict:
    """The whole profile: net size, copy bandwidth, and one entry per path and backend (numba: parallel and serial).

    Returns:
        {"cols", "rows", "knots", "springs", "h_s", "substeps_per_tick", "byte_model", "copy": {...},
        "threads", "threading_layer", "load_avg", "results": [...], "passes" (grid_passes, or None),
        "vectors" (kernel_vectors, or None)} where each result carries "copy_share" = its gb_per_s /
        the copy's gb_per_s (a net whose arrays fit in cache can exceed 100 %: the copy is sized to
        leave the caches) and, when numba is profiled, "textbook_ratio".
    """
    topo = build_topology(grid_spec(cols, rows))
    load_before = os.getloadavg()[0]
    copy = copy_bandwidth(n_bytes=min(COPY_BYTES, max(2**20, 64 * (BYTES_PER_KNOT * topo.n_knots
                                                                    + BYTES_PER_SPRING * topo.n_springs))))
    results = []
    for path in paths:
        for backend in backends:
            if backend == "reference" and path == "grid32_fma":
                continue  # the numpy twin fuses nothing: it is grid32's row
            variants = (True, False) if backend == "numba" else (False,)
            for parallel in variants:
                results.append(profile_backend(topo, backend, steps, parallel=parallel, target_s=target_s, path=path))
    textbook = None
    if "numba" in backends:
        textbook = profile_backend(topo, "numba", steps, parallel=False, target_s=target_s, path=TEXTBOOK)
        results.append(textbook)
        for r in results:
            # How many times faster than the textbook loop, by the stepping thread's CPU time
            # (wall time for the parallel kernels: their CPU time is spread over threads).
            mine = r["cpu_us_per_step"] if r["cpu_us_per_step"] is not None else r["us_per_step"]
            r["textbook_ratio"] = textbook["cpu_us_per_step"] / mine
    copy_again = copy_bandwidth(n_bytes=copy["bytes"] // 2)
    # Bandwidth is measured before and after the kernels; the share uses the better of the
    # two medians, since the machine is shared and the slower one saw more interference.
    copy_best = max(copy["gb_per_s"], copy_again["gb_per_s"])
    for r in results:
        r["copy_share"] = r["gb_per_s"] / copy_best
    return {
        "cols": cols,
        "rows": rows,
        "knots": topo.n_knots,
        "springs": topo.n_springs,
        "h_s": 0.5 * topo.h_max,
        "substeps_per_tick": _substeps_per_tick(topo),
        "byte_model": (f"grid: {GRID_BYTES_PER_KNOT} B per knot (position, velocity read and written; inv_mass), "
                       f"{GRID_BYTES_PER_SPRING} B per spring (class parameters, row scratch in cache); "
                       f"grid32: {GRID32_BYTES_PER_KNOT} B per knot (float32 offset, velocity read and written; step "
                       "factors; table offset), 0 B per spring; "
                       f"csr: {BYTES_PER_KNOT} B per knot (pos, vel read by both passes, written once; inv_mass; "
                       f"CSR start) + {BYTES_PER_SPRING} B per spring (ij, 2 slots as uint32; |L|^2, rate "
                       "out and in; rest, k, c; scale out and read twice; all f8); neighbours from cache"),
        "copy": {"gb_per_s": copy_best, "before": copy["gb_per_s"], "after": copy_again["gb_per_s"],
                 "bytes": copy["bytes"]},
        "threads": _threads(),
        "threading_layer": _layer(),
        # The machine may be shared: 1-minute load average before and after the kernels.
        "load_avg": [load_before, os.getloadavg()[0]],
        "results": results,
        "passes": grid_passes(topo, target_s=target_s) if "numba" in backends and "grid" in paths else None,
        "vectors": kernel_vectors(topo) if "numba" in backends else None,
        "awake_ticks": awake_tick_costs(target_s=target_s) if "numba" in backends and "grid" in paths else None,
    }


def _threads() -> int:
    return int(numba.get_num_threads())


def _layer() -> str:
    """numba's threading layer (known once a parallel kernel has run)."""
    try:
        return str(numba.threading_layer())
    except ValueError:
        return "not started"


# ---------------------------------------------------------------------------------------------
# The grid kernel taken apart: its two phases over a whole step (every spring class, then every
# knot), timed alone on the same state, beside the floor of the
# divider (a square root and a division per spring, float64, the springs' only long-latency
# operations) and the same passes on a net of as many knots in rows 8 times longer.


@njit(cache=True, error_model="numpy")
def _grid_springs(state, inv_mass, params, work):
    """Every spring of the grid (kernels.grid's chunk halves, all rows as one chunk)."""
    x, v, _ = grid_kernels._flat(state, inv_mass)  # noqa: SLF001
    rows, cols = state.shape[2], state.shape[3]
    grid_kernels._horizontal(x, v, work[0], params, rows, cols, 0, rows)  # noqa: SLF001
    grid_kernels._bands(x, v, work[0], params, rows, cols, 0, rows - 1)  # noqa: SLF001


@njit(cache=True, error_model="numpy")
def _grid_knots(state, inv_mass, work, h):
    """Every knot of the grid stepped from the springs' t in `work`."""
    x, v, w = grid_kernels._flat(state, inv_mass)  # noqa: SLF001
    grid_kernels._knots(x, v, w, work[0], state.shape[3], 0, w.shape[0], 9.81, 5.0, h)  # noqa: SLF001


@njit(cache=True, error_model="numpy")
def _pass_springs(state, inv_mass, params, work, reps):
    for _ in range(reps):
        _grid_springs(state, inv_mass, params, work)


@njit(cache=True, error_model="numpy")
def _pass_knots(state, inv_mass, work, h, reps):
    for _ in range(reps):
        _grid_knots(state, inv_mass, work, h)


@njit(cache=True, error_model="numpy")
def _divider_floor(length2, out, reps):
    for _ in range(reps):
        for s in range(length2.shape[0]):
            out[s] = 1.0 / math.sqrt(length2[s])


@njit(inline="always")
def _spring_t(d0, d1, d2, e0, e1, e2, length, inv_len, out, q):
    rate = e0 * d0 + e1 * d1 + e2 * d2
    scale = (200.0 * (length - 0.01) + 0.1 * rate * inv_len) * inv_len
    out[0, q] = scale * d0
    out[1, q] = scale * d1
    out[2, q] = scale * d2


@njit(cache=True, error_model="numpy")
def _spring_floor(x, v, out, lines, reps):
    """The grid's spring arithmetic (kernels.grid's _grid_line) over `lines` rows of out.shape[1]
    springs, nothing else."""
    n = out.shape[1]
    for _ in range(reps):
        for _ in range(lines):
            for q in range(n):
                d0, d1, d2 = x[0, q + 1] - x[0, q], x[1, q + 1] - x[1, q], x[2, q + 1] - x[2, q]
                length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                _spring_t(d0, d1, d2, v[0, q + 1] - v[0, q], v[1, q + 1] - v[1, q], v[2, q + 1] - v[2, q], length,
                          1.0 / length, out, q)


@njit(cache=True, error_model="numpy")
def _spring_floor_no_divider(x, v, out, lines, reps):
    """_spring_floor with 1/|L| from a float32 root and division refined by one float64 Newton step.

    Relative error ~1e-14: what a spring would cost without the float64 divider; for the floor
    only, no kernel rounds this way.
    """
    n = out.shape[1]
    for _ in range(reps):
        for _ in range(lines):
            for q in range(n):
                d0, d1, d2 = x[0, q + 1] - x[0, q], x[1, q + 1] - x[1, q], x[2, q + 1] - x[2, q]
                length2 = d0 * d0 + d1 * d1 + d2 * d2
                y = np.float64(np.float32(1.0) / np.sqrt(np.float32(length2)))
                inv_len = y * (1.5 - 0.5 * length2 * y * y)
                _spring_t(d0, d1, d2, v[0, q + 1] - v[0, q], v[1, q + 1] - v[1, q], v[2, q + 1] - v[2, q],
                          length2 * inv_len, inv_len, out, q)


def _best_us(call, target_s: float) -> float:
    """µs per call of call(reps), this thread's CPU time, the best of REPEATS runs sized to target_s."""
    call(1)  # compile or load
    t0 = time.thread_time()
    call(1)
    one = max(time.thread_time() - t0, 1e-7)
    reps = max(1, int(target_s / REPEATS / one))
    best = math.inf
    for _ in range(REPEATS):
        t0 = time.thread_time()
        call(reps)
        best = min(best, (time.thread_time() - t0) / reps)
    return best * 1e6


def _grid_case(topo, rows: int, cols: int):
    """A moving grid state of rows x cols knots with topo's spring classes, its masses and scratch."""
    rng = np.random.default_rng(0)
    state = np.zeros((2, 3, rows, cols))
    spacing = 0.01
    state[0, 1] = spacing * np.arange(cols)[None, :]
    state[0, 2] = spacing * np.arange(rows)[:, None]
    state[0] += rng.normal(0.0, 1e-4, state[0].shape)
    state[1] = rng.normal(0.0, 1e-3, state[1].shape)
    inv_mass = np.full((rows, cols), float(np.max(topo.knot_inv_mass)))
    inv_mass[0] = 0.0  # the table's row stays fixed, as in a built net
    return state, inv_mass, grid_kernels.grid_work(rows, cols)


def grid_passes(topo, target_s: float = 1.0) -> dict:
    """µs per step of each pass of step_grid_serial on `topo`'s grid, and of the divider's floor.

    Returns:
        {"rows", "cols", "passes": {name: (µs, springs or knots, unit)}, "long_rows": the same
        on rows 8 times longer and 8 times fewer (per spring or knot against "passes": what the
        short rows' per-loop overhead costs; None below 16 rows), "divider_floor_us" (a root and
        a division for each of the net's springs), "spring_floor_us" and
        "spring_floor_no_divider_us" (_spring_floor, _spring_floor_no_divider for as many springs),
        "step_us", "rest_us" (the step minus its passes: chunk set-up, calls)}.
    """
    rows, cols = topo.spec.rows, topo.spec.cols
    budget = target_s / 8

    def passes(n_rows, n_cols):
        state, inv_mass, work = _grid_case(topo, n_rows, n_cols)
        params, h = topo.grid_params, 0.5 * topo.h_max
        # name: (µs per step, how many springs or knots the pass handles, "spring" or "knot")
        return {
            "springs: one loop a class": (_best_us(lambda r: _pass_springs(state, inv_mass, params, work, r), budget),
                                          n_rows * (n_cols - 1) + (n_rows - 1) * (3 * n_cols - 2), "spring"),
            "knots: update": (_best_us(lambda r: _pass_knots(state, inv_mass, work, h, r), budget),
                              n_rows * n_cols, "knot"),
        }

    short = passes(rows, cols)
    long_rows = passes(max(2, rows // 8), cols * 8) if rows >= 16 else None
    state = np.zeros((2, 3, rows, cols))
    state[0] = topo.knot_pos.T.reshape(3, rows, cols)
    work = grid_kernels.grid_work(rows, cols)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    step_us = _best_us(lambda r: kernels.step_grid_serial(state, inv_mass, topo.grid_params, topo.spec.gravity,
                                                          topo.spec.air_damping, 0.5 * topo.h_max, r, work), budget)
    rng = np.random.default_rng(1)
    length2 = 1e-4 * (1.0 + 0.01 * rng.random(topo.n_springs))
    floor = _best_us(lambda r: _divider_floor(length2, np.empty_like(length2), r), budget)
    # The spring arithmetic alone on contiguous rows of the net's row length, scaled to its springs.
    x = 0.01 * np.arange(cols + 1) + 1e-4 * rng.random((3, cols + 1))
    v = 1e-3 * rng.random((3, cols + 1))
    lines = math.ceil(topo.n_springs / (cols - 1))
    per_spring = topo.n_springs / (lines * (cols - 1))
    springs = [per_spring * _best_us(lambda r, f=f: f(x, v, np.empty((3, cols - 1)), lines, r), budget)
               for f in (_spring_floor, _spring_floor_no_divider)]
    spent = sum(us for us, _, _ in short.values())
    return {"rows": rows, "cols": cols, "passes": short, "long_rows": long_rows, "divider_floor_us": floor,
            "spring_floor_us": springs[0], "spring_floor_no_divider_us": springs[1], "step_us": step_us,
            "rest_us": step_us - spent}


def kernel_vectors(topo) -> dict:
    """vector_report of each kernel's loops for `topo`'s arrays: the grid's spring and knot passes, csr, textbook."""
    rows, cols = topo.spec.rows, topo.spec.cols
    state = np.zeros((2, 3, rows, cols))
    work = grid_kernels.grid_work(rows, cols)
    inv_mass = topo.knot_inv_mass.reshape(rows, cols)
    net32 = kernels.grid32_work(topo.knot_pos.T.reshape(3, rows, cols).copy(), inv_mass, 1, kernels.GRID32_EXACT)
    pos, vel = topo.knot_pos.copy(), np.zeros_like(topo.knot_pos)
    h = 0.5 * topo.h_max
    csr = (pos, vel, topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring, topo.spring_ij,
           topo.spring_rest, topo.spring_k, topo.spring_c, 9.81, 5.0, h, np.zeros((kernels.STEP_WORK_ROWS,
                                                                                  topo.n_springs)),
           pos.copy(), vel.copy())
    textbook = (pos, vel, topo.knot_inv_mass, topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, 9.81, 5.0,
                h, pos.copy(), pos.copy(), vel.copy())
    return {
        "grid springs (_horizontal, _bands)": vector_report(_grid_springs, (state, inv_mass, topo.grid_params, work)),
        "grid knots (_knots)": vector_report(_grid_knots, (state, inv_mass, work, h)),
        "grid32 springs (_springs_exact)": vector_report(grid32_kernels._springs_exact, (  # noqa: SLF001
            net32, cols, 0, rows)),
        "grid32 knots (_knots_exact)": vector_report(grid32_kernels._knots_exact, (net32, 0, rows)),  # noqa: SLF001
        "csr (step_knots_serial)": vector_report(kernels.step_knots_serial, csr),
        "textbook scatter (step_knots_scatter)": vector_report(kernels.step_knots_scatter, textbook),
    }


# ---------------------------------------------------------------------------------------------
# The awake tick of the match's net (resolution_spec(85, 8)) with each grid kernel: NetSim.step
# with the ball away, as the net worker pays it (kernels and NetSim's Python).
AWAKE_KERNELS = {"float64": {}, "float32": {"kernel_precision": FLOAT32},
                 "float32 fma": {"kernel_precision": FLOAT32, "kernel_fma": True}}


def awake_tick_costs(cols: int = 85, rows: int = 8, target_s: float = 1.0, repeats: int = REPEATS) -> dict:
    """µs per awake NetSim tick (TICK_S, no ball) of resolution_spec(cols, rows) for each AWAKE_KERNELS option.

    The linear tail is off (tail_energy 0): the runs keep the net awake (wake() before every tick),
    and a net calm enough for the tail would otherwise leave it and enter it again every tick,
    which times the switch instead of the kernel. This thread's CPU time; the options interleaved run by run from the same perturbed state, the
    median of `repeats` runs each; "ratio": float64's µs over the option's, same run.
    """
    sims = {}
    for name, fields in AWAKE_KERNELS.items():
        spec = replace(resolution_spec(cols, rows), tail_energy=0.0, **fields)
        sim = NetSim(build_topology(spec), dt=TICK_S)
        pos, vel, _, _ = moving_state(sim.topo)
        sims[name] = (sim, pos, vel)
    runs = {name: [] for name in sims}
    for name, (sim, pos, vel) in sims.items():  # compile or load, and size the runs
        sim.knot_pos[:], sim.knot_vel[:] = pos, vel
        sim.step()
        t0 = time.thread_time()
        sim.step()
        one = max(time.thread_time() - t0, 1e-6)
    ticks = max(10, int(target_s / (len(sims) * repeats * one)))
    for _ in range(repeats):
        for name, (sim, pos, vel) in sims.items():
            sim.knot_pos[:], sim.knot_vel[:] = pos, vel
            t0 = time.thread_time()
            for _ in range(ticks):
                sim.wake()
                sim.step()
            runs[name].append((time.thread_time() - t0) / ticks)
    us = {name: statistics.median(r) * 1e6 for name, r in runs.items()}
    return {"cols": cols, "rows": rows, "ticks": ticks, "repeats": repeats, "substeps": sims["float64"][0].substeps,
            "us": us, "ratio": {name: us["float64"] / value for name, value in us.items()}}
