"""Knot steps of a grid net in float32 on offsets from its built grid: step_grid's model in flat loops over the grid."""
import numpy as np
from numba import njit, prange

from net_kernel.kernels.grid import (
    GRID_CLASSES,
    GRID_CORD,
    GRID_HEM,
    GRID_MESH,
    GRID_SHEAR,
    GRID_VERTICAL,
    free_ticks,
)
from net_kernel.kernels.table import TABLE_Z

# step_grid's model (net_kernel/kernels/grid.py: in place, springs before knots, a knot's 8
# springs summed in the same order), with the arithmetic in float32 on offsets
# o = x - R from the net's built grid R (build_topology's knot_pos: the plane x = 0, columns a
# apart along y, rows b apart along z). A spring's vector is then d = D + (o_j - o_i), D its
# class's constant (0, +-a, b, ...) rounded once from float64: no per-spring geometry to load.
# Float32 of absolute positions would round d, the difference of two ~1 m numbers, to ~0.1 µm;
# the offsets (a few mm: the rest shape's sag plus the motion) keep ~1e-10 m, and d itself
# (~1 cm) ~1e-9 m.
#
# Layout: knot (r, c) sits at column p = c + 1 of rows padded to W = P + 1 columns, P the
# smallest multiple of 8 above cols: column 0 and columns cols + 1 .. W - 1 are fixed pad knots
# at offset 0. The rows are contiguous, so the grid is one flat array of rows W knots (knot
# r W + p), and each spring class is one loop over it: from knot q to q + 1 (horizontal), q + W
# (vertical), q + W + 1 (shear /) or q + W - 1 (shear \\). A substep is then a few long loops
# (a pass per class, then a pass per axis over the knots), not a few per row, so the fixed cost
# of entering a vectorised loop (its runtime alias checks, its remainder) is paid per class and
# not again for every row of a net only a few rows high. The springs that touch a pad (or
# join the end of one row to the start of the next) are computed and then zeroed, as step_grid's
# missing springs. The scratch holds one flat line per class and axis: a spring's t is stored
# one knot right of its first knot, horizontal ones at q + 1, the others (the bands between
# rows r and r + 1) one row further, at q + W + 1 (shear \\: from q + 1 to q + W, at q + W + 1),
# so knot q finds its left-hand and lower terms at q and q + 1 and its upper ones at q + W and
# q + W + 1; the first row of the band lines (below the bottom row) and the last (above the top
# row) stay zero.
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
_REF, _STATE, _KNOT, _MASS, _TABLE, _WORK, _CLASS, _VARIANT, _CALL, _BLOCKS = range(10)
# lines of net32[_WORK], 3 axes each: t of the horizontal, vertical, shear / and shear \\ springs
_H, _V, _D1, _D2 = 0, 3, 6, 9
WORK32_LINES = 12
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
        blocks: row blocks stepped in parallel (1 <= blocks <= rows; any count gives the same bits).
        variant: GRID32_* bits.

    Returns:
        net32, the last argument of the *32 kernels in place of grid_work: (R float64 (3, rows,
        cols), state float32 (2, 3, rows, W) [offset | velocity], per-knot step factors float32
        (4, rows, W), knot_inv_mass float32 (rows, W), the table's offset TABLE_Z - R_z float32
        (rows, W), scratch float32 (WORK32_LINES, (rows + 1) W + 1), per-class constants float32
        (GRID_CLASSES, 5), variant, the (h, drag, gravity) float64 (3,) the step factors were made
        for, blocks).
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
            np.zeros((WORK32_LINES, (rows + 1) * width + 1), dtype=np.float32), classes, np.int64(variant),
            np.full(3, np.nan), np.int64(blocks))


@njit(inline="always")
def _line32(o, v, lo, hi, off, classes, kind, mirror, t, line, shift):
    """t of the springs of class `kind` from flat knot q to q + off, q in [lo, hi), into
    t[line : line + 3, q + shift], float32 (its built vector's y negated when `mirror`: shear \\).

    scale = (k (|d| - rest) + c (e . d) / |d|) / |d| = k + (c (e . d) / |d| - k rest) / |d|:
    step_grid's spring-damper with one root and one division instead of a root and two.
    Indices are unsigned: numba then skips the negative-index test, and LLVM vectorises.
    """
    u = np.uint64
    dy = -classes[kind, _DY] if mirror else classes[kind, _DY]
    dz, k, c, k_rest = classes[kind, _DZ], classes[kind, _K], classes[kind, _C], classes[kind, _KREST]
    off, shift = u(off), u(shift)
    for q in range(u(lo), u(hi)):
        j = q + off
        d0 = o[0, j] - o[0, q]
        d1 = dy + (o[1, j] - o[1, q])
        d2 = dz + (o[2, j] - o[2, q])
        e0 = v[0, j] - v[0, q]
        e1 = v[1, j] - v[1, q]
        e2 = v[2, j] - v[2, q]
        length2 = d0 * d0 + d1 * d1 + d2 * d2
        rate = e0 * d0 + e1 * d1 + e2 * d2
        inv_len = np.float32(1.0) / np.sqrt(length2)
        scale = k + inv_len * (c * rate * inv_len - k_rest)
        t[line, q + shift] = scale * d0
        t[line + 1, q + shift] = scale * d1
        t[line + 2, q + shift] = scale * d2


@njit(inline="always")
def _zero32(t, line, shift, r0, r1, width, last):
    """Zero the t of rows r0 .. r1 - 1 (at t[line : line + 3, r width + q + shift]) whose first
    knot's column q is outside [1, last]: springs from or to a pad, or from a row's end to the
    next row's start."""
    for r in range(r0, r1):
        base = r * width + shift
        for a in range(line, line + 3):
            t[a, base] = 0.0
            for q in range(last + 1, width):
                t[a, base + q] = 0.0


@njit(inline="always")
def _springs(o, v, t, classes, rows, width, cols, r0, r1):
    """t of the springs of rows r0 .. r1 - 1 (o, v: the state as (3, rows W) flat knots): their
    horizontal ones (the hem on the bottom row, the top cord on the top row) and the bands to the
    row above (none above the top row)."""
    mesh0, mesh1 = max(r0, 1), min(r1, rows - 1)
    if r0 == 0 and rows > 1:
        _line32(o, v, 0, width, 1, classes, GRID_HEM, False, t, _H, 1)
    if mesh0 < mesh1:
        _line32(o, v, mesh0 * width, mesh1 * width, 1, classes, GRID_MESH, False, t, _H, 1)
    if r1 == rows:
        _line32(o, v, (rows - 1) * width, rows * width - 1, 1, classes, GRID_CORD, False, t, _H, 1)
    _zero32(t, _H, 1, r0, r1, width, cols - 1)
    band1 = min(r1, rows - 1)  # bands from rows r0 .. band1 - 1 to the row above
    if r0 < band1:
        lo, hi = r0 * width, band1 * width
        _line32(o, v, lo, hi, width, classes, GRID_VERTICAL, False, t, _V, width + 1)
        # the last band's spring from the last knot would end past the grid: left out (a pad's, zeroed)
        _line32(o, v, lo, hi - (band1 == rows - 1), width + 1, classes, GRID_SHEAR, False, t, _D1, width + 1)
        _line32(o, v, lo + 1, hi + 1, width - 1, classes, GRID_SHEAR, True, t, _D2, width)
        _zero32(t, _V, width + 1, r0, band1, width, cols)
        _zero32(t, _D1, width + 1, r0, band1, width, cols - 1)
        _zero32(t, _D2, width + 1, r0, band1, width, cols - 1)


@njit(inline="always")
def _axis32(o, v, a, factors, floor, t, lo, hi, width, vertical):
    """Axis a of flat knots lo .. hi - 1 stepped in place (step_grid's sum order); `vertical` (a
    constant bool): z, with gravity and the playing surface (net_kernel/kernels/table.py) at the
    offset `floor`, which pads and knots far above never reach."""
    u = np.uint64
    one, up, up1 = u(1), u(width), u(width + 1)
    h, vb, d1, d2 = _H + a, _V + a, _D1 + a, _D2 + a
    for q in range(u(lo), u(hi)):
        f = t[d1, q + up1] - t[d1, q]  # above-right - below-left
        f -= t[vb, q + one]  # below
        f -= t[d2, q + one]  # below-right
        f -= t[h, q]  # left
        f += t[h, q + one]  # right
        f += t[d2, q + up]  # above-left
        f += t[vb, q + up1]  # above
        nv = factors[_B, q] * v[a, q] + factors[_HW, q] * f
        if vertical:
            nv -= factors[_HG, q]
            z = o[a, q] + factors[_S, q] * nv
            below_floor = z < floor[q]
            o[a, q] = floor[q] if below_floor else z
            v[a, q] = max(nv, np.float32(0.0)) if below_floor else nv
        else:
            v[a, q] = nv
            o[a, q] += factors[_S, q] * nv


@njit(inline="always")
def _knots(o, v, t, factors, floor, width, r0, r1):
    """Rows r0 .. r1 - 1 stepped in place, axis by axis, from the springs' t (factors (4, rows W),
    floor (rows W): net32's, flat)."""
    lo, hi = r0 * width, r1 * width
    _axis32(o, v, 0, factors, floor, t, lo, hi, width, False)
    _axis32(o, v, 1, factors, floor, t, lo, hi, width, False)
    _axis32(o, v, 2, factors, floor, t, lo, hi, width, True)


@njit(inline="always")
def _flat(net32):
    """net32's state, factors and table as flat knots: (3, n) offsets, (3, n) velocities, (4, n), (n,)."""
    state = net32[_STATE]
    n = state.shape[2] * state.shape[3]
    return state[0].reshape(3, n), state[1].reshape(3, n), net32[_KNOT].reshape(4, n), net32[_TABLE].reshape(n)


@njit(inline="always")
def _springs_body(net32, cols, r0, r1):
    o, v, _, _ = _flat(net32)
    state = net32[_STATE]
    _springs(o, v, net32[_WORK], net32[_CLASS], state.shape[2], state.shape[3], cols, r0, r1)


@njit(inline="always")
def _knots_body(net32, r0, r1):
    o, v, factors, floor = _flat(net32)
    _knots(o, v, net32[_WORK], factors, floor, net32[_STATE].shape[3], r0, r1)


# Each phase compiled once per variant (its fastmath flags over the whole inlined phase) for the
# parallel kernel; the serial kernel inlines the same bodies into one function per variant
# (_serial_*). The exact variant is IEEE in both; with FMA the same expressions are fused alike
# (tests/net_kernel/test_grid32.py steps both variants serially and in parallel, bit for bit).
@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _springs_exact(net32, cols, r0, r1):
    _springs_body(net32, cols, r0, r1)


@njit(cache=True, fastmath=_FMA_FLAGS, error_model="numpy", _nrt=False)
def _springs_fma(net32, cols, r0, r1):
    _springs_body(net32, cols, r0, r1)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _knots_exact(net32, r0, r1):
    _knots_body(net32, r0, r1)


@njit(cache=True, fastmath=_FMA_FLAGS, error_model="numpy", _nrt=False)
def _knots_fma(net32, r0, r1):
    _knots_body(net32, r0, r1)


@njit(inline="always")
def _serial_body(net32, cols, n_steps):
    """n_steps substeps on one thread, the row blocks in turn: the phases' bodies inlined into one
    function, so a substep pays no call (and no views made again) between them."""
    o, v, factors, floor = _flat(net32)
    t, classes = net32[_WORK], net32[_CLASS]
    rows, width = net32[_STATE].shape[2], net32[_STATE].shape[3]
    blocks = net32[_BLOCKS]
    for _ in range(n_steps):
        for b in range(blocks):
            _springs(o, v, t, classes, rows, width, cols, b * rows // blocks, (b + 1) * rows // blocks)
        for b in range(blocks):
            _knots(o, v, t, factors, floor, width, b * rows // blocks, (b + 1) * rows // blocks)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _serial_exact(net32, cols, n_steps):
    _serial_body(net32, cols, n_steps)


@njit(cache=True, fastmath=_FMA_FLAGS, error_model="numpy", _nrt=False)
def _serial_fma(net32, cols, n_steps):
    _serial_body(net32, cols, n_steps)


@njit(inline="always")
def _springs32(net32, cols, r0, r1):
    if net32[_VARIANT] == GRID32_FMA:
        _springs_fma(net32, cols, r0, r1)
    else:
        _springs_exact(net32, cols, r0, r1)


@njit(inline="always")
def _knots32(net32, r0, r1):
    if net32[_VARIANT] == GRID32_FMA:
        _knots_fma(net32, r0, r1)
    else:
        _knots_exact(net32, r0, r1)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _enter32(knot_state, grid_params, gravity, drag, h, net32):
    """The float64 state into net32's float32 offsets and velocities; the per-knot factors for (h, drag, gravity)
    (kept while those stay the same: the same bits as making them anew) and the class constants."""
    ref, state, factors, inv_mass, classes = net32[_REF], net32[_STATE], net32[_KNOT], net32[_MASS], net32[_CLASS]
    rows, cols = ref.shape[1], ref.shape[2]
    # Indexed in place, not through per-row views: a view costs more than a row's conversions.
    u = np.uint64
    one = u(1)
    for a in range(3):
        for r in range(rows):
            for c in range(u(cols)):
                state[0, a, r, c + one] = np.float32(knot_state[0, a, r, c] - ref[a, r, c])
                state[1, a, r, c + one] = np.float32(knot_state[1, a, r, c])
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


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def _leave32(knot_state, knot_inv_mass, net32):
    """net32's float32 state back into the float64 state, free knots only (a fixed knot keeps its bits)."""
    ref, state = net32[_REF], net32[_STATE]
    rows, cols = ref.shape[1], ref.shape[2]
    u = np.uint64
    one = u(1)
    for a in range(3):
        for r in range(rows):
            for c in range(u(cols)):
                if knot_inv_mass[r, c] != 0.0:
                    knot_state[0, a, r, c] = ref[a, r, c] + np.float64(state[0, a, r, c + one])
                    knot_state[1, a, r, c] = np.float64(state[1, a, r, c + one])


@njit(cache=True, parallel={"fusion": False}, fastmath=False, error_model="numpy")
def _parallel_steps(net32, cols, n_steps):
    """n_steps substeps, the row blocks in parallel: all springs' t from the state before the
    substep, then the knots, which read the t of the rows beside theirs. No parfor fusion:
    numba cannot see the first phase's writes through net32 (a tuple) and would fuse the two
    phases' loops into one, racing the t that the second phase reads."""
    rows = net32[_STATE].shape[2]
    blocks = net32[_BLOCKS]
    for _ in range(n_steps):
        for b in prange(blocks):
            _springs32(net32, cols, b * rows // blocks, (b + 1) * rows // blocks)
        for b in prange(blocks):
            _knots32(net32, b * rows // blocks, (b + 1) * rows // blocks)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """n_steps of step_grid's model in float32 on offsets from the built grid, row blocks in parallel.

    The state goes to float32 offsets once on entry and back once on exit (see the notes above).
    Deterministic: blocks never write what another reads in a phase, every sum is a per-knot
    gather in a fixed order, no prange reduction, and no fastmath flag reorders a sum, so any
    number of blocks or threads gives the same bits.

    Args:
        knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps: as step_grid.
        net32: grid32_work's tuple for this net (its blocks: the row blocks).
    """
    if n_steps > 0:
        _enter32(knot_state, grid_params, gravity, drag, h, net32)
        _parallel_steps(net32, knot_state.shape[3], n_steps)
        _leave32(knot_state, knot_inv_mass, net32)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """step_grid32 on one thread (the same blocks and phases in turn, same bits). Args as step_grid32."""
    if n_steps > 0:
        _enter32(knot_state, grid_params, gravity, drag, h, net32)
        if net32[_VARIANT] == GRID32_FMA:
            _serial_fma(net32, knot_state.shape[3], n_steps)
        else:
            _serial_exact(net32, knot_state.shape[3], n_steps)
        _leave32(knot_state, knot_inv_mass, net32)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32_free(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                     sleep_ticks, quiet_ticks, reach, box):
    """step_grid_free with step_grid32_serial's steps (grid_work: grid32_work's tuple): the same bits as as many
    NetSim ticks of a float32 net without a ball. Args and returns as step_grid_free."""
    return free_ticks(step_grid32_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work,
                      ticks, sleep_speed, sleep_ticks, quiet_ticks, reach, box)
