"""Knot steps of a net on a regular grid (NetTopology.grid): step_knots' model and bits, fused row by row, in place."""
import math

import numpy as np
from numba import njit, prange

from net_kernel.kernels.table import TABLE_Z

# Structured grid: the same model and the same arithmetic as step_knots, for nets built on a
# regular grid (NetTopology.grid). Knot (r, c) finds its 8 springs by index arithmetic instead
# of the CSR lists, spring parameters come per class (GRID_CLASSES) instead of per spring, and
# the state is structure of arrays (knot_state below) so every loop runs along a row's
# contiguous columns and vectorises. Spring and knot work are fused row by row: the forces of
# the springs above row r go to a rolling scratch of a few rows, then row r's knots gather and
# step, so nothing of size n_springs goes to memory and back.
#
# In place, yet every spring sees the old state (springs act before knots move): row r is
# stepped only after the springs of rows r - 1, r and r + 1 that touch it were evaluated, and
# no spring evaluated later reads row r. Row blocks run in parallel: first every block
# evaluates the springs below its first row (the only ones that read a row another block
# steps), then all blocks step their rows. One buffer is half the memory traffic of two: no
# second buffer to stream out (and read for ownership) each step.
#
# Bits: a knot sums its springs in the CSR slot order of build_topology (down-left, down,
# down-right, left, right, up-left, up, up-right: increasing spring index), each spring's
# scale is the same expression as step_knots', so step_grid gives step_knots' bits (a missing
# spring at the border adds a +-0 term), for any number of blocks or threads.
#
# A spring's force is stored once as a vector t = scale (x_j - x_i) (force on its first knot
# i; -t on j): -t is exactly scale (x_i - x_j), so the sums keep step_knots' bits, and the
# knot pass adds 8 vectors instead of recomputing 8 differences and products.
#
# Loops: each writes one array (a scratch block or knot_state) so LLVM's runtime alias
# checks stay few enough to vectorise it: a knot pass that reads 19 arrays and writes 6 in
# one loop stays scalar.

# Spring classes of a grid net: rows of NetTopology.grid_params (k N/m, c N s/m, rest m).
GRID_MESH, GRID_VERTICAL, GRID_SHEAR, GRID_CORD, GRID_HEM = 0, 1, 2, 3, 4
GRID_CLASSES = 5
# Scratch rows of one row block (grid_work[block]), each (cols,): the row's horizontal
# springs' t (3 rows), two rolling bands of the springs between a row and the next
# (vertical, shear / and shear \ t: 9 rows each), and the band below the block's first row.
GRID_WORK_ROWS = 30
_H, _BAND, _EDGE = 0, 3, 21
_V, _D1, _D2 = 0, 3, 6  # offsets within a band


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_line(x, v, ri, rj, qi, qj, n, k, c, rest, work, row):
    """t = scale (x_j - x_i) of n springs from knots (ri, qi + q) to (rj, qj + q) into work[row : row + 3, q].

    The scale is step_knots' expression, same operations in the same order. Indices are
    unsigned: numba then skips the negative-index test, and LLVM sees plain strides and
    vectorises. Written out, not built from inline helpers: numba's IR inlining multiplied
    the grid kernels' compile time (and the runtime was no better).
    """
    for q in range(n):
        i = qi + q
        j = qj + q
        d0 = x[0, rj, j] - x[0, ri, i]
        d1 = x[1, rj, j] - x[1, ri, i]
        d2 = x[2, rj, j] - x[2, ri, i]
        e0 = v[0, rj, j] - v[0, ri, i]
        e1 = v[1, rj, j] - v[1, ri, i]
        e2 = v[2, rj, j] - v[2, ri, i]
        length2 = d0 * d0 + d1 * d1 + d2 * d2
        rate = e0 * d0 + e1 * d1 + e2 * d2
        length = math.sqrt(length2)
        inv_len = 1.0 / length
        scale = (k * (length - rest) + c * rate * inv_len) * inv_len
        work[row, q] = scale * d0
        work[row + 1, q] = scale * d1
        work[row + 2, q] = scale * d2


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_band(x, v, r, params, work, band):
    """t of the springs between rows r and r + 1 into the band at work[band : band + 9]."""
    cols = x.shape[2]
    u = np.uint64
    ri, rj, n, zero, one = u(r), u(r + 1), u(cols), u(0), u(1)
    k, c, rest = params[GRID_VERTICAL, 0], params[GRID_VERTICAL, 1], params[GRID_VERTICAL, 2]
    _grid_line(x, v, ri, rj, zero, zero, n, k, c, rest, work, band + _V)
    k, c, rest = params[GRID_SHEAR, 0], params[GRID_SHEAR, 1], params[GRID_SHEAR, 2]
    _grid_line(x, v, ri, rj, zero, one, n - one, k, c, rest, work, band + _D1)  # shear /: (r, q) to (r + 1, q + 1)
    _grid_line(x, v, ri, rj, one, zero, n - one, k, c, rest, work, band + _D2)  # shear \: (r, q + 1) to (r + 1, q)
    # No spring leaves the last column: zeros there are the border's missing terms.
    for row in range(band + _D1, band + _D2 + 3):
        work[row, cols - 1] = 0.0


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_row(x, v, r, params, work):
    """t of row r's horizontal springs (the top cord on the last row) into work[_H : _H + 3]."""
    cols = x.shape[2]
    kind = GRID_CORD if r == x.shape[1] - 1 else (GRID_HEM if r == 0 else GRID_MESH)
    u = np.uint64
    _grid_line(x, v, u(r), u(r), u(0), u(1), u(cols - 1), params[kind, 0], params[kind, 1], params[kind, 2], work, _H)
    for row in range(_H, _H + 3):
        work[row, cols - 1] = 0.0


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_border(state, knot_inv_mass, r, q, ql, down, up, work, gravity, drag, h):
    """Knot (r, q) on a border column stepped in place as _grid_update does; ql: the column of the
    springs to its left (the zeroed last column when q = 0)."""
    w = knot_inv_mass[r, q]
    for k in range(3):
        f = -work[down + _D1 + k, ql]
        f -= work[down + _V + k, q]
        f -= work[down + _D2 + k, q]
        f -= work[_H + k, ql]
        f += work[_H + k, q]
        f += work[up + _D2 + k, ql]
        f += work[up + _V + k, q]
        f += work[up + _D1 + k, q]
        g = gravity if k == 2 else 0.0
        xi = state[0, k, r, q]
        vi = state[1, k, r, q]
        nv = vi + h * (w * f - drag * vi - g)
        z = xi + h * nv
        if k == 2 and w != 0.0 and z < TABLE_Z:  # the playing surface (net_kernel/kernels/table.py)
            z = TABLE_Z
            nv = max(nv, 0.0)
        state[1, k, r, q] = vi if w == 0.0 else nv
        state[0, k, r, q] = xi if w == 0.0 else z


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_update(state, knot_inv_mass, r, down, up, work, gravity, drag, h):
    """Row r's symplectic Euler step in place: v' = v + h (w f - drag v - g), x' = x + h v'; fixed (w = 0) knots kept.

    The force f on knot (r, q) sums its springs' t in CSR slot order: -t of the springs of
    which it is the second knot (below-left, below, below-right, left), +t of the others
    (right, above-left, above, above-right).
    """
    cols = state.shape[3]
    last = cols - 1
    w_row = knot_inv_mass[r]
    for k in range(3):
        g = gravity if k == 2 else 0.0  # - 0.0 is exact: step_knots' bits on x and y
        x_row = state[0, k, r]
        v_row = state[1, k, r]
        below_left, below, below_right = work[down + _D1 + k], work[down + _V + k], work[down + _D2 + k]
        horizontal = work[_H + k]
        above_left, above, above_right = work[up + _D2 + k], work[up + _V + k], work[up + _D1 + k]
        for q in range(1, last):
            f = -below_left[q - 1]  # shear / from below-left
            f -= below[q]  # vertical from below
            f -= below_right[q]  # shear \ from below-right
            f -= horizontal[q - 1]  # horizontal, left
            f += horizontal[q]  # horizontal, right
            f += above_left[q - 1]  # shear \ to above-left
            f += above[q]  # vertical to above
            f += above_right[q]  # shear / to above-right
            w = w_row[q]
            xi = x_row[q]
            vi = v_row[q]
            # Fixed knots by a 0/1 factor, not a select: with `vi if w == 0.0 else nv` LLVM
            # sinks the force sum under the condition and loads the 8 terms with masked loads
            # (vmaskmovpd), a slower pass. Same bits: 1.0 * y is y, and vi + 0.0 * y is vi (a
            # -0.0 velocity becomes +0.0).
            free = 1.0 if w != 0.0 else 0.0
            nv = vi + free * (h * (w * f - drag * vi - g))
            v_row[q] = nv
            x_row[q] = xi + free * (h * nv)
        if k == 2:
            # The playing surface (net_kernel/kernels/table.py): fixed knots never start below it,
            # so only free ones are moved; a pass of its own keeps the force loop free of branches.
            for q in range(1, last):
                z = x_row[q]
                below = z < TABLE_Z
                x_row[q] = TABLE_Z if below else z
                v_row[q] = max(v_row[q], 0.0) if below else v_row[q]
    # Border columns: the springs missing to the left sit in the zeroed last column.
    _grid_border(state, knot_inv_mass, r, 0, last, down, up, work, gravity, drag, h)
    _grid_border(state, knot_inv_mass, r, last, last - 1, down, up, work, gravity, drag, h)


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_edge(state, params, grid_work, b, r0):
    """Block b's first phase: the band below its first row r0 into grid_work[b, _EDGE:] (none for r0 = 0)."""
    if r0 > 0:
        _grid_band(state[0], state[1], r0 - 1, params, grid_work[b], _EDGE)


@njit(cache=True, fastmath=False, error_model="numpy")
def _grid_block(state, knot_inv_mass, params, gravity, drag, h, grid_work, b, r0, r1):
    """Block b's second phase: step rows r0 .. r1 - 1 in place; the band above r1 - 1 is block b + 1's edge."""
    x = state[0]
    v = state[1]
    rows, cols = x.shape[1], x.shape[2]
    work = grid_work[b]
    for r in range(r0, r1):
        up = _BAND + 9 * (r % 2)
        down = _BAND + 9 * ((r + 1) % 2)
        if r == r0:
            for row in range(9):
                for q in range(cols):  # no springs below the bottom row; else this block's edge band
                    work[down + row, q] = 0.0 if r == 0 else work[_EDGE + row, q]
        if r == rows - 1 or r == r1 - 1:
            for row in range(9):
                for q in range(cols):  # none above the top row; else block b + 1's edge, evaluated before it moved row r1
                    work[up + row, q] = 0.0 if r == rows - 1 else grid_work[b + 1, _EDGE + row, q]
        else:
            _grid_band(x, v, r, params, work, up)
        _grid_row(x, v, r, params, work)
        _grid_update(state, knot_inv_mass, r, down, up, work, gravity, drag, h)


@njit(cache=True, parallel=True, fastmath=False, error_model="numpy")
def step_grid(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work):
    """n_steps semi-implicit Euler steps of a grid net in place, row blocks in parallel; step_knots' model and bits.

    Every spring is evaluated on the state at the step's start (springs act before knots
    move), though the state is updated in place (see the notes above). Row blocks (one per
    grid_work block) run in parallel in two phases a step and never write what another
    block reads in the same phase. Bit-for-bit the same for any number of blocks or threads.

    Args:
        knot_state: (2, 3, rows, cols), [position m | velocity m/s], axis, row, column; knot
            (r, c) is knot r * cols + c of the topology. Updated in place.
        knot_inv_mass: (rows, cols) 1/kg; 0 marks a fixed knot.
        grid_params: (GRID_CLASSES, 3) per spring class: k N/m, c N s/m, rest length m.
        gravity: m/s^2 along -z.
        drag: 1/s, linear air damping of free knots.
        h: s, the step; stable below NetTopology.h_max.
        n_steps: steps to take (>= 0).
        grid_work: (blocks, GRID_WORK_ROWS, cols) scratch, 1 <= blocks <= rows: that many row
            blocks step in parallel.
    """
    rows = knot_state.shape[2]
    blocks = grid_work.shape[0]
    for _ in range(n_steps):
        for b in prange(blocks):
            _grid_edge(knot_state, grid_params, grid_work, b, b * rows // blocks)
        for b in prange(blocks):
            _grid_block(knot_state, knot_inv_mass, grid_params, gravity, drag, h, grid_work, b, b * rows // blocks,
                        (b + 1) * rows // blocks)


@njit(cache=True, fastmath=False, error_model="numpy")
def step_grid_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work):
    """step_grid on one thread (the same blocks and phases in turn, same bits). Args as step_grid."""
    rows = knot_state.shape[2]
    blocks = grid_work.shape[0]
    for _ in range(n_steps):
        for b in range(blocks):
            _grid_edge(knot_state, grid_params, grid_work, b, b * rows // blocks)
        for b in range(blocks):
            _grid_block(knot_state, knot_inv_mass, grid_params, gravity, drag, h, grid_work, b, b * rows // blocks,
                        (b + 1) * rows // blocks)


@njit(cache=True, fastmath=False)
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


@njit(cache=True, fastmath=False, error_model="numpy")
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


@njit(inline="always")
def knot_checks(knot_state, box):
    """m/s, the largest knot speed of a grid net's state (knot_speed_max's arithmetic; a max does not
    depend on the order), or inf at the first knot whose position or velocity is not finite; the
    knots' box (2, 3) m into `box` (lo, hi corners), complete when the speed is finite."""
    rows = knot_state.shape[2]
    cols = knot_state.shape[3]
    x = knot_state[0]
    v = knot_state[1]
    top = 0.0
    for a in range(3):
        box[0, a] = math.inf
        box[1, a] = -math.inf
    for r in range(rows):
        for c in range(cols):
            s = v[0, r, c] * v[0, r, c] + v[1, r, c] * v[1, r, c] + v[2, r, c] * v[2, r, c]
            p = x[0, r, c] + x[1, r, c] + x[2, r, c]
            if not (s < math.inf and p - p == 0.0):
                return math.inf
            if s > top:
                top = s
            for a in range(3):
                box[0, a] = min(box[0, a], x[a, r, c])
                box[1, a] = max(box[1, a], x[a, r, c])
    return math.sqrt(top)


@njit(inline="always")
def in_reach(box, reach):
    """Does the box (2, 3) m lie within `reach` (2, 3) m (lo, hi corners)?"""
    for a in range(3):
        if box[0, a] < reach[0, a] or box[1, a] > reach[1, a]:
            return False
    return True
