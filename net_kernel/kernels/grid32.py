"""Knot steps of a grid net in float32 on offsets from its built grid: step_grid's model, 8 lanes a ymm register."""
import numpy as np
from numba import njit, prange

from net_kernel.kernels.grid import (
    _BAND,
    _D1,
    _D2,
    _EDGE,
    _H,
    _V,
    GRID_CLASSES,
    GRID_CORD,
    GRID_HEM,
    GRID_MESH,
    GRID_SHEAR,
    GRID_VERTICAL,
    GRID_WORK_ROWS,
    free_ticks,
)
from net_kernel.kernels.table import TABLE_Z

# step_grid's model and passes (net_kernel/kernels/grid.py: rows fused, in place, springs before
# knots, a knot's 8 springs summed in the same order), with the arithmetic in float32 on offsets
# o = x - R from the net's built grid R (build_topology's knot_pos: the plane x = 0, columns a
# apart along y, rows b apart along z). A spring's vector is then d = D + (o_j - o_i), D its
# class's constant (0, +-a, b, ...) rounded once from float64: no per-spring geometry to load.
# Float32 of absolute positions would round d, the difference of two ~1 m numbers, to ~0.1 µm;
# the offsets (a few mm: the rest shape's sag plus the motion) keep ~1e-10 m, and d itself
# (~1 cm) ~1e-9 m.
#
# Layout: knot (r, c) sits at column p = c + 1 of rows padded to W = P + 1 columns, P the
# smallest multiple of 8 above cols: column 0 and columns cols + 1 .. W - 1 are fixed pad knots
# at offset 0. Every loop runs over P columns, a whole number of vectors, and needs no border
# case: the springs that touch a pad are zeroed after each line (zeroed t, as step_grid's
# missing springs). A spring's t is stored one column right of its first knot (work[row, p + 1]),
# so a knot's left-hand terms are at p and its right-hand ones at p + 1, never at p - 1.
#
# The knot step per axis: v' = b v + (h w) f - h g [z], x' = x + s v', with per-knot factors
# recomputed each call from h (b = 1 - h drag, s = h for a free knot; b = 1, s = 0, h w = 0 for a
# fixed one, so it keeps its bits).
#
# The float64 state stays the master: a call converts it to float32 offsets on entry and back on
# exit (fixed knots keep their float64 bits), so NetSim, the contact sweep and snapshots see
# float64 positions as before; a call of n steps takes them all on the float32 state.
#
# Variants (net32's variant entry), each phase compiled apart because fastmath flags belong to a
# function:
#   GRID32_EXACT: IEEE float32, no fastmath; the numpy twin's bits (reference.step_grid32).
#   GRID32_FMA: multiply-adds fused (LLVM's flag contract over the whole phase, springs and knots).
# contract reorders no sum and assumes nothing about the values: a compiled kernel gives the same
# bits for the same input on any number of blocks or threads, so lockstep against in-process (the
# same compiled code on one machine) stays bit for bit. Which products LLVM fuses is its choice
# at compile time, so two machines (one without FMA) may differ in the last bits; the exact
# variant is IEEE throughout and differs nowhere.
# A reciprocal square root estimate with a Newton step (flags afn, arcp: vrsqrtps) in place of
# the root and the division is no option: the spring loop is bound by its loads and stores, not
# by the divider, and the estimate's table differs between CPUs.
GRID32_EXACT, GRID32_FMA = 0, 1
_FMA_FLAGS = {"contract"}
LANES = 8  # float32 lanes of a ymm register: the padded row is a multiple of it
# net32 entries (grid32_work)
_REF, _STATE, _KNOT, _MASS, _TABLE, _WORK, _CLASS, _VARIANT, _CALL = range(9)
# rows of net32[_KNOT]: the per-knot factors of the step (h w, b, h g, s)
_HW, _B, _HG, _S = range(4)
# columns of net32[_CLASS], per spring class: its built vector's y and z (x is 0: the built net
# lies in the plane x = 0), k, c and k rest (float32 of grid_params, set on each call's entry)
_DY, _DZ, _K, _C, _KREST = range(5)


@njit(cache=True)
def grid32_work(built, knot_inv_mass, blocks, variant):
    """The float32 kernels' constants and scratch for a grid net built as `built`.

    Args:
        built: (3, rows, cols) m, the built grid R (NetTopology.knot_pos as axis, row, column).
        knot_inv_mass: (rows, cols) 1/kg, as step_grid's.
        blocks: row blocks stepped in parallel (as step_grid's grid_work.shape[0]).
        variant: GRID32_* bits.

    Returns:
        net32, the last argument of the *32 kernels in place of grid_work: (R float64 (3, rows,
        cols), state float32 (2, 3, rows, W) [offset | velocity], per-knot step factors float32
        (4, rows, W), knot_inv_mass float32 (rows, W), the table's offset TABLE_Z - R_z float32
        (rows, W), scratch float32 (blocks, GRID_WORK_ROWS, W + 1), per-class constants float32
        (GRID_CLASSES, 5), variant, the (h, drag, gravity) float64 (3,) the step factors were made for).
    """
    rows, cols = built.shape[1], built.shape[2]
    width = (cols // LANES + 1) * LANES + 1
    inv_mass = np.zeros((rows, width), dtype=np.float32)
    table = np.full((rows, width), -np.inf, dtype=np.float32)
    for r in range(rows):
        for c in range(cols):
            inv_mass[r, c + 1] = np.float32(knot_inv_mass[r, c])
            table[r, c + 1] = np.float32(TABLE_Z - built[2, r, c])
    classes = np.zeros((GRID_CLASSES, 5), dtype=np.float32)
    across_y = built[1, 0, 1] - built[1, 0, 0]
    up_z = built[2, 1, 0] - built[2, 0, 0]
    for kind in (GRID_MESH, GRID_CORD, GRID_HEM):
        classes[kind, _DY] = np.float32(across_y)
    classes[GRID_VERTICAL, _DZ] = np.float32(up_z)
    classes[GRID_SHEAR, _DY] = np.float32(across_y)  # shear /; shear \ mirrors it
    classes[GRID_SHEAR, _DZ] = np.float32(up_z)
    return (built.copy(), np.zeros((2, 3, rows, width), dtype=np.float32),
            np.zeros((4, rows, width), dtype=np.float32), inv_mass, table,
            np.zeros((blocks, GRID_WORK_ROWS, width + 1), dtype=np.float32), classes, np.int64(variant),
            np.full(3, np.nan))


@njit(inline="always")
def _spring32(o, v, ri, rj, i, j, q, dy, dz, k, c, k_rest, work, row):
    """t = scale d of the spring from knot (ri, i) to (rj, j) into work[row : row + 3, q + 1], float32.

    scale = (k (|d| - rest) + c (e . d) / |d|) / |d| = k + (c (e . d) / |d| - k rest) / |d|:
    step_grid's spring-damper with one root and one division instead of a root and two.
    """
    d0 = o[0, rj, j] - o[0, ri, i]
    d1 = dy + (o[1, rj, j] - o[1, ri, i])
    d2 = dz + (o[2, rj, j] - o[2, ri, i])
    e0 = v[0, rj, j] - v[0, ri, i]
    e1 = v[1, rj, j] - v[1, ri, i]
    e2 = v[2, rj, j] - v[2, ri, i]
    length2 = d0 * d0 + d1 * d1 + d2 * d2
    rate = e0 * d0 + e1 * d1 + e2 * d2
    inv_len = np.float32(1.0) / np.sqrt(length2)
    scale = k + inv_len * (c * rate * inv_len - k_rest)
    work[row, q + 1] = scale * d0
    work[row + 1, q + 1] = scale * d1
    work[row + 2, q + 1] = scale * d2


@njit(inline="always")
def _line32(o, v, classes, ri, rj, qi, qj, kind, mirror, last, work, row):
    """t of the P springs from (ri, p + qi) to (rj, p + qj), p in [0, P), of class `kind` (its built
    vector's y negated when `mirror`: shear \\) into work[row : row + 3, p + 1];
    only p in [1, last] join two knots of the net, the others touch a pad and are zeroed."""
    width = o.shape[2] - 1
    u = np.uint64
    dy = -classes[kind, _DY] if mirror else classes[kind, _DY]
    dz, k, c, k_rest = classes[kind, _DZ], classes[kind, _K], classes[kind, _C], classes[kind, _KREST]
    ri, rj, qi, qj = u(ri), u(rj), u(qi), u(qj)
    for q in range(u(width)):
        _spring32(o, v, ri, rj, qi + q, qj + q, q, dy, dz, k, c, k_rest, work, row)
    for a in range(row, row + 3):
        work[a, 1] = 0.0  # p = 0: from the left pad
        for p in range(last + 1, width):
            work[a, p + 1] = 0.0


@njit(inline="always")
def _band32(o, v, classes, r, cols, work, band):
    """t of the springs between rows r and r + 1 into work[band : band + 9] (grid._grid_band's band)."""
    _line32(o, v, classes, r, r + 1, 0, 0, GRID_VERTICAL, False, cols, work, band + _V)
    # shear /: (r, p) to (r + 1, p + 1); shear \\: (r, p + 1) to (r + 1, p)
    _line32(o, v, classes, r, r + 1, 0, 1, GRID_SHEAR, False, cols - 1, work, band + _D1)
    _line32(o, v, classes, r, r + 1, 1, 0, GRID_SHEAR, True, cols - 1, work, band + _D2)


@njit(inline="always")
def _axis32(x_row, v_row, factors, r, below_left, below, below_right, horizontal, above_left, above, above_right,
            floor, vertical):
    """One axis of a row's knots stepped in place (step_grid's sum order); `vertical` (a constant bool):
    z, with gravity and the playing surface (net_kernel/kernels/table.py) at the offset `floor`, which
    pads and knots far above never reach."""
    hw, b, hg, s = factors[_HW, r], factors[_B, r], factors[_HG, r], factors[_S, r]
    for p in range(x_row.shape[0] - 1):
        f = above_right[p + 1] - below_left[p]
        f -= below[p + 1]
        f -= below_right[p + 1]
        f -= horizontal[p]
        f += horizontal[p + 1]
        f += above_left[p]
        f += above[p + 1]
        nv = b[p] * v_row[p] + hw[p] * f
        if vertical:
            nv -= hg[p]
            z = x_row[p] + s[p] * nv
            below_floor = z < floor[p]
            x_row[p] = floor[p] if below_floor else z
            v_row[p] = max(nv, np.float32(0.0)) if below_floor else nv
        else:
            v_row[p] = nv
            x_row[p] += s[p] * nv


@njit(inline="always")
def _update_row32(state, factors, table, r, down, up, work):
    """Row r's knots stepped in place, axis by axis."""
    for k in range(2):
        _axis32(state[0, k, r], state[1, k, r], factors, r, work[down + _D1 + k], work[down + _V + k],
                work[down + _D2 + k], work[_H + k], work[up + _D2 + k], work[up + _V + k], work[up + _D1 + k],
                table[r], False)
    _axis32(state[0, 2, r], state[1, 2, r], factors, r, work[down + _D1 + 2], work[down + _V + 2],
            work[down + _D2 + 2], work[_H + 2], work[up + _D2 + 2], work[up + _V + 2], work[up + _D1 + 2], table[r],
            True)


@njit(inline="always")
def _edge_body(net32, cols, b, r0):
    """Block b's first phase (grid._grid_edge): the band below its first row r0 (none for r0 = 0)."""
    if r0 > 0:
        state = net32[_STATE]
        _band32(state[0], state[1], net32[_CLASS], r0 - 1, cols, net32[_WORK][b], _EDGE)


@njit(inline="always")
def _block_body(net32, cols, b, r0, r1):
    """Block b's second phase (grid._grid_block): rows r0 .. r1 - 1 stepped in place."""
    state, factors, table, scratch, classes = net32[_STATE], net32[_KNOT], net32[_TABLE], net32[_WORK], net32[_CLASS]
    o, v = state[0], state[1]
    rows = state.shape[2]
    work = scratch[b]
    n = work.shape[1]
    for r in range(r0, r1):
        up = _BAND + 9 * (r % 2)
        down = _BAND + 9 * ((r + 1) % 2)
        if r == r0:
            for row in range(9):
                for p in range(n):  # no springs below the bottom row; else this block's edge band
                    work[down + row, p] = 0.0 if r == 0 else work[_EDGE + row, p]
        if r == rows - 1 or r == r1 - 1:
            for row in range(9):
                for p in range(n):  # none above the top row; else block b + 1's edge
                    work[up + row, p] = 0.0 if r == rows - 1 else scratch[b + 1, _EDGE + row, p]
        else:
            _band32(o, v, classes, r, cols, work, up)
        kind = GRID_CORD if r == rows - 1 else (GRID_HEM if r == 0 else GRID_MESH)
        _line32(o, v, classes, r, r, 0, 1, kind, False, cols - 1, work, _H)
        _update_row32(state, factors, table, r, down, up, work)


# Each phase compiled once per variant (its fastmath flags over the whole inlined phase); the
# serial and the parallel kernels call the same compiled phases, so they give the same bits.
@njit(cache=True, fastmath=False, error_model="numpy")
def _edge_exact(net32, cols, b, r0):
    _edge_body(net32, cols, b, r0)


@njit(cache=True, fastmath=_FMA_FLAGS, error_model="numpy")
def _edge_fma(net32, cols, b, r0):
    _edge_body(net32, cols, b, r0)


@njit(cache=True, fastmath=False, error_model="numpy")
def _block_exact(net32, cols, b, r0, r1):
    _block_body(net32, cols, b, r0, r1)


@njit(cache=True, fastmath=_FMA_FLAGS, error_model="numpy")
def _block_fma(net32, cols, b, r0, r1):
    _block_body(net32, cols, b, r0, r1)


@njit(inline="always")
def _edge32(net32, cols, b, r0):
    variant = net32[_VARIANT]
    if variant == GRID32_FMA:
        _edge_fma(net32, cols, b, r0)
    else:
        _edge_exact(net32, cols, b, r0)


@njit(inline="always")
def _block32(net32, cols, b, r0, r1):
    variant = net32[_VARIANT]
    if variant == GRID32_FMA:
        _block_fma(net32, cols, b, r0, r1)
    else:
        _block_exact(net32, cols, b, r0, r1)


@njit(cache=True, fastmath=False, error_model="numpy")
def _enter32(knot_state, grid_params, gravity, drag, h, net32):
    """The float64 state into net32's float32 offsets and velocities; the per-knot factors for (h, drag, gravity)
    (kept while those stay the same: the same bits as making them anew) and the class constants."""
    ref, state, factors, inv_mass, classes = net32[_REF], net32[_STATE], net32[_KNOT], net32[_MASS], net32[_CLASS]
    rows, cols = ref.shape[1], ref.shape[2]
    for a in range(3):
        for r in range(rows):
            x, v, ref_row = knot_state[0, a, r], knot_state[1, a, r], ref[a, r]
            o32, v32 = state[0, a, r], state[1, a, r]
            for c in range(cols):
                o32[c + 1] = np.float32(x[c] - ref_row[c])
                v32[c + 1] = np.float32(v[c])
    made = net32[_CALL]
    if not (made[0] == h and made[1] == drag and made[2] == gravity):  # NaN at first: always made once
        made[0], made[1], made[2] = h, drag, gravity
        step = np.float32(h)
        for r in range(rows):
            for p in range(inv_mass.shape[1]):
                free = inv_mass[r, p] != 0.0
                factors[_HW, r, p] = step * inv_mass[r, p]
                factors[_B, r, p] = np.float32(1.0) - step * np.float32(drag) if free else np.float32(1.0)
                factors[_HG, r, p] = step * np.float32(gravity) if free else np.float32(0.0)
                factors[_S, r, p] = step if free else np.float32(0.0)
    for kind in range(GRID_CLASSES):
        classes[kind, _K] = np.float32(grid_params[kind, 0])
        classes[kind, _C] = np.float32(grid_params[kind, 1])
        classes[kind, _KREST] = np.float32(grid_params[kind, 0]) * np.float32(grid_params[kind, 2])


@njit(cache=True, fastmath=False, error_model="numpy")
def _leave32(knot_state, knot_inv_mass, net32):
    """net32's float32 state back into the float64 state, free knots only (a fixed knot keeps its bits)."""
    ref, state = net32[_REF], net32[_STATE]
    rows, cols = ref.shape[1], ref.shape[2]
    for a in range(3):
        for r in range(rows):
            x, v, ref_row, w = knot_state[0, a, r], knot_state[1, a, r], ref[a, r], knot_inv_mass[r]
            o32, v32 = state[0, a, r], state[1, a, r]
            for c in range(cols):
                free = w[c] != 0.0
                x[c] = ref_row[c] + np.float64(o32[c + 1]) if free else x[c]
                v[c] = np.float64(v32[c + 1]) if free else v[c]


@njit(inline="always")
def _steps32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """step_grid32's body: its row blocks in parallel where the caller is parallel, in turn where not."""
    if n_steps <= 0:
        return
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    blocks = net32[_WORK].shape[0]
    _enter32(knot_state, grid_params, gravity, drag, h, net32)
    for _ in range(n_steps):
        for b in prange(blocks):
            _edge32(net32, cols, b, b * rows // blocks)
        for b in prange(blocks):
            _block32(net32, cols, b, b * rows // blocks, (b + 1) * rows // blocks)
    _leave32(knot_state, knot_inv_mass, net32)


# No parfor fusion: numba cannot see the first phase's writes through net32 (a tuple) and would
# fuse the two phases' loops into one, racing the edge bands it exists to order.
@njit(cache=True, parallel={"fusion": False}, fastmath=False, error_model="numpy")
def step_grid32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """n_steps of step_grid's model in float32 on offsets from the built grid, row blocks in parallel.

    The state goes to float32 offsets once on entry and back once on exit (see the notes above).
    Deterministic: blocks never write what another reads in a phase, every sum is a per-knot
    gather in a fixed order, no prange reduction, and no fastmath flag reorders a sum, so any
    number of blocks or threads gives the same bits.

    Args:
        knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps: as step_grid.
        net32: grid32_work's tuple for this net (its scratch blocks: the row blocks).
    """
    _steps32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32)


@njit(cache=True, fastmath=False, error_model="numpy")
def step_grid32_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """step_grid32 on one thread (the same blocks and phases in turn, same bits). Args as step_grid32."""
    _steps32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32)  # prange is range here


@njit(cache=True, fastmath=False, error_model="numpy")
def step_grid32_free(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                     sleep_ticks, quiet_ticks, reach, box):
    """step_grid_free with step_grid32_serial's steps (grid_work: grid32_work's tuple): the same bits as as many
    NetSim ticks of a float32 net without a ball. Args and returns as step_grid_free."""
    return free_ticks(step_grid32_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work,
                      ticks, sleep_speed, sleep_ticks, quiet_ticks, reach, box)
