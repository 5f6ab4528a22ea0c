"""Knot steps of a net on a regular grid (NetTopology.grid): step_knots' model and bits, in flat loops, in place."""
import math

import numpy as np
from numba import njit, prange

from net_kernel.kernels.table import TABLE_Z

# Structured grid: the same model and the same arithmetic as step_knots, for nets built on a
# regular grid (NetTopology.grid). Knot (r, c) finds its 8 springs by index arithmetic instead
# of the CSR lists, spring parameters come per class (GRID_CLASSES) instead of per spring, and
# the state is structure of arrays (knot_state below). The rows are contiguous, so the grid is
# one flat array of rows x cols knots (knot q = r cols + c) and each spring class is one loop
# over it: from knot q to q + 1 (horizontal), q + cols (vertical), q + cols + 1 (shear /) or
# q + cols - 1 (shear \), then one loop per axis over the knots. A substep is a few long loops,
# not a few per row: the fixed cost of entering a vectorised loop (its runtime alias checks, its
# remainder) is paid per class, not again for every row of a net only a few rows high. The
# springs that join a row's end to the next row's start are computed with the rest and zeroed,
# which leaves a border knot's missing springs as zero terms.
#
# Scratch (grid_work): one flat line per class and axis. A spring's t is stored one knot right
# of its first knot: horizontal ones at q + 1, the bands between rows r and r + 1 one row
# further, at q + cols + 1 (shear \, from q to q + cols - 1, at q + cols). Knot q then finds
# its lower and left-hand terms at q and q + 1 and its upper ones at q + cols and q + cols + 1;
# the lines' first row (below the bottom row) and last (above the top row) stay zero.
#
# In place, yet every spring sees the old state (springs act before knots move). Serially the
# net goes in chunks of CHUNK_ROWS rows, each chunk's springs (its rows' horizontal springs and
# the bands to the row above) and then its knots: a chunk's springs read only its rows and the
# next chunk's first row, which has not moved yet, and its knots read the band below, which the
# chunk before evaluated before it moved anything. The chunks keep a large net's scratch in
# cache. In parallel, every row block first evaluates the band below its first row (the only
# springs that read a row another block steps), then all blocks step their rows in chunks, each
# leaving the band above its top row to the block above. One buffer is half the memory traffic
# of two: no second buffer to stream out (and read for ownership) each step.
#
# Bits: a knot sums its springs in the CSR slot order of build_topology (down-left, down,
# down-right, left, right, up-left, up, up-right: increasing spring index), each spring's
# scale is the same expression as step_knots', so step_grid gives step_knots' bits (a missing
# spring at the border adds a +-0 term), for any number of blocks, chunks or threads.
#
# A spring's force is stored once as a vector t = scale (x_j - x_i) (force on its first knot
# i; -t on j): -t is exactly scale (x_i - x_j), so the sums keep step_knots' bits, and the
# knot pass adds 8 vectors instead of recomputing 8 differences and products.
#
# Loops: each writes one array (a scratch line or knot_state) so LLVM's runtime alias
# checks stay few enough to vectorise it: a knot pass that reads 19 arrays and writes 6 in
# one loop stays scalar.

# Spring classes of a grid net: rows of NetTopology.grid_params (k N/m, c N s/m, rest m).
GRID_MESH, GRID_VERTICAL, GRID_SHEAR, GRID_CORD, GRID_HEM = 0, 1, 2, 3, 4
GRID_CLASSES = 5
# Lines of the scratch (grid_work[0]), 3 axes each: t of the horizontal, vertical, shear / and
# shear \ springs.
GRID_WORK_LINES = 12
_H, _V, _D1, _D2 = 0, 3, 6, 9
# Rows a serial step takes at a time (see above): the match's nets are one chunk.
CHUNK_ROWS = 16


def grid_work(rows: int, cols: int, blocks: int = 1) -> np.ndarray:
    """The grid kernels' scratch for a rows x cols net: (blocks, GRID_WORK_LINES, (rows + 1) cols + 1).

    Its first axis is the number of row blocks step_grid runs in parallel (1 <= blocks <= rows;
    any count gives the same bits); grid_work[0] holds the lines (each block writes its rows).
    """
    return np.zeros((blocks, GRID_WORK_LINES, (rows + 1) * cols + 1))


@njit(inline="always")
def _grid_line(x, v, lo, hi, off, k, c, rest, t, line, shift):
    """t = scale (x_j - x_i) of the springs from flat knot q to q + off, q in [lo, hi), into
    t[line : line + 3, q + shift].

    The scale is step_knots' expression, same operations in the same order. Indices are
    unsigned: numba then skips the negative-index test, and LLVM sees plain strides and
    vectorises.
    """
    u = np.uint64
    off, shift = u(off), u(shift)
    for q in range(u(lo), u(hi)):
        j = q + off
        d0 = x[0, j] - x[0, q]
        d1 = x[1, j] - x[1, q]
        d2 = x[2, j] - x[2, q]
        e0 = v[0, j] - v[0, q]
        e1 = v[1, j] - v[1, q]
        e2 = v[2, j] - v[2, q]
        length2 = d0 * d0 + d1 * d1 + d2 * d2
        rate = e0 * d0 + e1 * d1 + e2 * d2
        length = math.sqrt(length2)
        inv_len = 1.0 / length
        scale = (k * (length - rest) + c * rate * inv_len) * inv_len
        t[line, q + shift] = scale * d0
        t[line + 1, q + shift] = scale * d1
        t[line + 2, q + shift] = scale * d2


@njit(inline="always")
def _class_line(x, v, lo, hi, off, params, kind, t, line, shift):
    _grid_line(x, v, lo, hi, off, params[kind, 0], params[kind, 1], params[kind, 2], t, line, shift)


@njit(inline="always")
def _zero_wraps(t, line, first, last, cols):
    """Zero the t at t[line : line + 3, first + m cols] for first + m cols <= last: springs that
    join a row's end to the next row's start."""
    for a in range(line, line + 3):
        for slot in range(first, last + 1, cols):
            t[a, slot] = 0.0


@njit(inline="always")
def _horizontal(x, v, t, params, rows, cols, r0, r1):
    """t of the horizontal springs of rows r0 .. r1 - 1 (x, v: the state as (3, rows cols) flat
    knots): the hem on the bottom row, the top cord on the top row."""
    mesh0, mesh1 = max(r0, 1), min(r1, rows - 1)
    if r0 == 0 and rows > 1:
        _class_line(x, v, 0, cols, 1, params, GRID_HEM, t, _H, 1)
    if mesh0 < mesh1:
        _class_line(x, v, mesh0 * cols, mesh1 * cols, 1, params, GRID_MESH, t, _H, 1)
    if r1 == rows:
        _class_line(x, v, (rows - 1) * cols, rows * cols - 1, 1, params, GRID_CORD, t, _H, 1)
    _zero_wraps(t, _H, (r0 + 1) * cols, r1 * cols, cols)  # from (r, cols - 1) to (r + 1, 0)


@njit(inline="always")
def _bands(x, v, t, params, rows, cols, r0, r1):
    """t of the bands from rows r0 .. r1 - 1 to the row above (r1 <= rows - 1): vertical, shear / and \\."""
    if r0 < r1:
        lo, hi = r0 * cols, r1 * cols
        _class_line(x, v, lo, hi, cols, params, GRID_VERTICAL, t, _V, cols + 1)
        # the last band's spring from the grid's last knot would end past it: left out (zeroed below)
        _class_line(x, v, lo, hi - (r1 == rows - 1), cols + 1, params, GRID_SHEAR, t, _D1, cols + 1)
        _class_line(x, v, lo, hi, cols - 1, params, GRID_SHEAR, t, _D2, cols)
        _zero_wraps(t, _D1, (r0 + 2) * cols, (r1 + 1) * cols, cols)  # from (r, cols - 1) to (r + 2, 0)
        _zero_wraps(t, _D2, (r0 + 1) * cols, r1 * cols, cols)  # from (r, 0) to (r, cols - 1)


@njit(inline="always")
def _knots(x, v, w, t, cols, lo, hi, gravity, drag, h):
    """Flat knots lo .. hi - 1 stepped in place, axis by axis: v' = v + h (w f - drag v - g),
    x' = x + h v'; fixed (w = 0) knots kept.

    The force f on knot q sums its springs' t in CSR slot order: -t of the springs of which it
    is the second knot (below-left, below, below-right, left), +t of the others (right,
    above-left, above, above-right).
    """
    u = np.uint64
    one, up, up1 = u(1), u(cols), u(cols + 1)
    for a in range(3):
        g = gravity if a == 2 else 0.0  # - 0.0 is exact: step_knots' bits on x and y
        h_line, v_line, d1, d2 = _H + a, _V + a, _D1 + a, _D2 + a
        for q in range(u(lo), u(hi)):
            f = -t[d1, q]  # shear / from below-left
            f -= t[v_line, q + one]  # vertical from below
            f -= t[d2, q + one]  # shear \ from below-right
            f -= t[h_line, q]  # horizontal, left
            f += t[h_line, q + one]  # horizontal, right
            f += t[d2, q + up]  # shear \ to above-left
            f += t[v_line, q + up1]  # vertical to above
            f += t[d1, q + up1]  # shear / to above-right
            wq = w[q]
            xi = x[a, q]
            vi = v[a, q]
            # Fixed knots by a 0/1 factor, not a select: with `vi if w == 0.0 else nv` LLVM
            # sinks the force sum under the condition and loads the 8 terms with masked loads
            # (vmaskmovpd), a slower pass. Same bits: 1.0 * y is y, and vi + 0.0 * y is vi (a
            # -0.0 velocity becomes +0.0).
            free = 1.0 if wq != 0.0 else 0.0
            nv = vi + free * (h * (wq * f - drag * vi - g))
            v[a, q] = nv
            x[a, q] = xi + free * (h * nv)
        if a == 2:
            # The playing surface (net_kernel/kernels/table.py): fixed knots never start below it,
            # so only free ones are moved; a pass of its own keeps the force loop free of branches.
            for q in range(u(lo), u(hi)):
                z = x[2, q]
                below = z < TABLE_Z
                x[2, q] = TABLE_Z if below else z
                v[2, q] = max(v[2, q], 0.0) if below else v[2, q]


@njit(inline="always")
def _flat(knot_state, knot_inv_mass):
    """The state as flat knots: (3, n) positions, (3, n) velocities, (n,) inverse masses."""
    n = knot_state.shape[2] * knot_state.shape[3]
    return knot_state[0].reshape(3, n), knot_state[1].reshape(3, n), knot_inv_mass.reshape(n)


@njit(inline="always")
def _chunks(x, v, w, t, params, rows, cols, r0, r1, top, gravity, drag, h):
    """Rows r0 .. r1 - 1 stepped CHUNK_ROWS at a time, each chunk's springs then its knots; the
    bands from rows below `top` only (the one from row top, if any, is evaluated already)."""
    for c0 in range(r0, r1, CHUNK_ROWS):
        c1 = min(c0 + CHUNK_ROWS, r1)
        _horizontal(x, v, t, params, rows, cols, c0, c1)
        _bands(x, v, t, params, rows, cols, c0, min(c1, top))
        _knots(x, v, w, t, cols, c0 * cols, c1 * cols, gravity, drag, h)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _grid_edge(knot_state, knot_inv_mass, params, grid_work, r0):
    """step_grid's first phase for a row block from row r0 > 0: the band below it, evaluated before
    any block moves a knot (it reads row r0 - 1, which the block below steps)."""
    x, v, _ = _flat(knot_state, knot_inv_mass)
    _bands(x, v, grid_work[0], params, knot_state.shape[2], knot_state.shape[3], r0 - 1, r0)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _grid_block(knot_state, knot_inv_mass, params, grid_work, gravity, drag, h, r0, r1):
    """step_grid's second phase for the row block r0 .. r1 - 1: its rows in chunks, the band above
    its top row being the next block's edge (none above the net's top row)."""
    x, v, w = _flat(knot_state, knot_inv_mass)
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    _chunks(x, v, w, grid_work[0], params, rows, cols, r0, r1, r1 - 1, gravity, drag, h)


@njit(cache=True, parallel=True, fastmath=False, error_model="numpy")
def step_grid(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work):
    """n_steps semi-implicit Euler steps of a grid net in place, row blocks in parallel; step_knots' model and bits.

    Every spring is evaluated on the state at the step's start (springs act before knots
    move), though the state is updated in place (see the notes above): each block first
    evaluates the band below its first row (the only springs it shares with the block below),
    then steps its rows in chunks. Bit-for-bit the same for any number of blocks or threads.

    Args:
        knot_state: (2, 3, rows, cols), [position m | velocity m/s], axis, row, column; knot
            (r, c) is knot r * cols + c of the topology. Updated in place.
        knot_inv_mass: (rows, cols) 1/kg; 0 marks a fixed knot.
        grid_params: (GRID_CLASSES, 3) per spring class: k N/m, c N s/m, rest length m.
        gravity: m/s^2 along -z.
        drag: 1/s, linear air damping of free knots.
        h: s, the step; stable below NetTopology.h_max.
        n_steps: steps to take (>= 0).
        grid_work: grid_work(rows, cols, blocks): that many row blocks step in parallel.
    """
    rows = knot_state.shape[2]
    blocks = grid_work.shape[0]
    for _ in range(n_steps):
        for b in prange(1, blocks):
            _grid_edge(knot_state, knot_inv_mass, grid_params, grid_work, b * rows // blocks)
        for b in prange(blocks):
            _grid_block(knot_state, knot_inv_mass, grid_params, grid_work, gravity, drag, h, b * rows // blocks,
                        (b + 1) * rows // blocks)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work):
    """step_grid on one thread, chunk by chunk (CHUNK_ROWS; same bits). Args as step_grid (its blocks unused)."""
    x, v, w = _flat(knot_state, knot_inv_mass)
    t = grid_work[0]
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    for _ in range(n_steps):
        _chunks(x, v, w, t, grid_params, rows, cols, 0, rows, rows - 1, gravity, drag, h)


@njit(cache=True, fastmath=False, _nrt=False)
def grid_knots(knot_state, knot_pos, knot_vel):
    """A grid net's state as knots: knot_pos, knot_vel (n_knots, 3) m, m/s, written from knot_state
    (2, 3, rows, cols); knot (r, c) is knot r * cols + c. A plain copy (numpy's copy of the
    transposed view is a strided loop several times slower)."""
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    for r in range(rows):
        for c in range(cols):
            i = r * cols + c
            for a in range(3):
                knot_pos[i, a] = knot_state[0, a, r, c]
                knot_vel[i, a] = knot_state[1, a, r, c]


# step_grid_free's statuses: the net is still awake, fell asleep, went non-finite, left its reach.
FREE_AWAKE, FREE_ASLEEP, FREE_NOT_FINITE, FREE_OUT_OF_REACH = 0, 1, 2, 3


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid_free(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                   sleep_ticks, quiet_ticks, reach, box):
    """Up to `ticks` ticks of a grid net with no ball, each as NetSim.step takes one, on one thread.

    A tick: step_grid_serial's `substeps` steps; the largest knot speed (knot_speed_max's
    arithmetic; a max does not depend on the order); `quiet_ticks` counts ticks in a row below
    `sleep_speed`, and at `sleep_ticks` the net falls asleep (velocities zeroed); the knots' box.
    It stops after the tick the net falls asleep, goes non-finite or leaves `reach`. The same
    bits as NetSim.step called that many times without a ball, minus its per-tick Python.

    Args:
        knot_state, knot_inv_mass, grid_params, gravity, drag, h, grid_work: as step_grid.
        substeps: steps per tick. ticks: ticks to take (>= 0).
        sleep_speed: m/s. sleep_ticks: quiet ticks to fall asleep. quiet_ticks: the count so far.
        reach: (2, 3) m, lo and hi corners no knot may pass.
        box: (2, 3) m, written: the knots' box after the last tick taken.

    Returns:
        (ticks taken, quiet_ticks after them, FREE_* status).
    """
    return free_ticks(step_grid_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work,
                      ticks, sleep_speed, sleep_ticks, quiet_ticks, reach, box)


@njit(inline="always")
def free_ticks(step, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
               sleep_ticks, quiet_ticks, reach, box):
    """step_grid_free's ticks with `step` (a serial grid kernel of step_grid_serial's signature) for their steps."""
    v = knot_state[1]
    for t in range(ticks):
        step(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work)
        speed = knot_checks(knot_state, box)
        if speed == math.inf:
            return t + 1, quiet_ticks, FREE_NOT_FINITE
        quiet_ticks = quiet_ticks + 1 if speed < sleep_speed else 0
        if quiet_ticks >= sleep_ticks:
            v[:] = 0.0
        if not in_reach(box, reach):
            return t + 1, quiet_ticks, FREE_OUT_OF_REACH
        if quiet_ticks >= sleep_ticks:
            return t + 1, quiet_ticks, FREE_ASLEEP
    return ticks, quiet_ticks, FREE_AWAKE


_EXPONENT = np.uint64(0x7FF0000000000000)  # a float64 whose exponent bits are all set is inf or NaN


@njit(inline="always")
def knot_checks(knot_state, box):
    """m/s, the largest knot speed of a grid net's state (knot_speed_max's arithmetic; a max does not
    depend on the order), or inf if a knot's position or velocity is not finite; the knots' box
    (2, 3) m into `box` (lo, hi corners), complete when the speed is finite."""
    bits = knot_state.reshape(knot_state.size).view(np.uint64)
    nonfinite = False
    for i in range(bits.size):  # integer tests on the bits: a loop of vector compares
        nonfinite |= (bits[i] & _EXPONENT) == _EXPONENT
    if nonfinite:
        return math.inf
    n = knot_state.shape[2] * knot_state.shape[3]
    v = knot_state[1].reshape(3, n)
    top = 0.0
    for q in range(n):
        s = v[0, q] * v[0, q] + v[1, q] * v[1, q] + v[2, q] * v[2, q]
        top = max(top, s)
    x = knot_state[0].reshape(3, n)
    for a in range(3):
        lo, hi = math.inf, -math.inf
        for q in range(n):
            lo = min(lo, x[a, q])
            hi = max(hi, x[a, q])
        box[0, a] = lo
        box[1, a] = hi
    return math.sqrt(top)


@njit(inline="always")
def in_reach(box, reach):
    """Does the box (2, 3) m lie within `reach` (2, 3) m (lo, hi corners)?"""
    for a in range(3):
        if box[0, a] < reach[0, a] or box[1, a] > reach[1, a]:
            return False
    return True
