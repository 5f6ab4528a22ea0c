"""Numba kernels of the net: knot steps (semi-implicit and implicit Euler) and the ball's contact.

Model (issue 4, after Provot, "Deformation constraints in a mass-spring model", Graphics
Interface 1995): each spring s between knots i and j is a spring-damper; with
L = x_j - x_i, n = L/|L|, the force on knot i is

    f_i = (k_s (|L| - L_rest) + k_d ((v_j - v_i) . n)) n,      f_j = -f_i.

Determinism: every sum over springs here is a per-knot gather in a fixed order: over the CSR
adjacency (knot i sums its own springs in the topology's slot order), or, in the grid kernels
(step_grid), over the 8 grid neighbours in that same order; per-spring passes write one value
per spring. So `parallel=True` changes no bit: no prange scatter-add, no prange reduction;
reductions (CG dot products, speed maximum) are serial loops. fastmath stays off. No kernel
allocates; scratch comes in as arguments.

Knot-table contact: after every step, a free knot below the playing surface (TABLE_Z) is put
back on it with its downward velocity removed (a one-sided, inelastic, frictionless contact,
the projection cloth solvers apply against colliders).

Every kernel has a numpy twin with the same signature in net_kernel/reference.py.
"""
import math

import numpy as np
from numba import njit, prange

NO_CONTACT = -1.0
# m: the playing surface (DESIGN.md frame). No free knot ends a step below it: a knot that would
# is put on it and loses its downward speed (an inelastic, frictionless one-sided contact). A
# hanging net's hem swings down onto the table when struck low; a real net cannot pass through it.
TABLE_Z = 0.0
STEP_WORK_ROWS = 3  # spring_work rows of step_knots: |L|^2, (v_j - v_i) . L, f / |L|
# error_model="numpy" on the step kernels: no ZeroDivisionError test on 1/|L| (the builder
# refuses zero-length springs, and a collapse would surface as a non-finite knot, which NetSim
# checks after every tick). With python's error model that test kept the loop scalar: the
# root/division loop measured 50 us against 13 us on the 184 x 16 net.


@njit(cache=True, parallel=True, fastmath=False, error_model="numpy")
def step_knots(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_rest, spring_k,
               spring_c, gravity, drag, h, spring_work, out_pos, out_vel):
    """One semi-implicit (symplectic) Euler step of every knot, parallel.

    Two passes, both race-free: (1) over springs, each spring writes its own scalar
    f_s / |L_s| (one root and one division per spring, not per end; the gather of its ends
    and the root/division are separate loops so the second one vectorises);
    (2) over knots, each knot gathers scale * (x_j - x_i) over its CSR slots in their fixed
    order and steps. Springs act before knots move: both passes read the old state and the
    new one goes to separate buffers (out_pos, out_vel) that the caller swaps. Bit-for-bit the
    same with any thread count (no scatter, no reduction).

    Args:
        knot_pos: (n_knots, 3) m, world frame, at the step's start.
        knot_vel: (n_knots, 3) m/s.
        knot_inv_mass: (n_knots,) 1/kg; 0 marks a fixed knot.
        adj_start: (n_knots + 1,) uint64 CSR row starts.
        adj_knot: (2 n_springs,) uint32, the other knot of each slot.
        adj_spring: (2 n_springs,) uint32, the spring of each slot.
        spring_ij: (n_springs, 2) uint32 knot indices.
        spring_rest: (n_springs,) m.
        spring_k: (n_springs,) N/m.
        spring_c: (n_springs,) N s/m.
        gravity: m/s^2 along -z.
        drag: 1/s, linear air damping of free knots.
        h: s, the step; stable below NetTopology.h_max.
        spring_work: (STEP_WORK_ROWS, n_springs) scratch, written: |L|^2 (m^2),
            (v_j - v_i) . L (m^2/s), force over length (N/m).
        out_pos: (n_knots, 3) m, written; must not alias knot_pos.
        out_vel: (n_knots, 3) m/s, written; must not alias knot_vel.
    """
    length2 = spring_work[0]
    rate = spring_work[1]
    spring_scale = spring_work[2]
    for s in prange(spring_ij.shape[0]):
        # Gather the spring's ends: |L|^2 and (v_j - v_i) . L.
        x = knot_pos
        v = knot_vel
        i = spring_ij[s, 0]
        j = spring_ij[s, 1]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        length2[s] = d0 * d0 + d1 * d1 + d2 * d2
        rate[s] = (v[j, 0] - v[i, 0]) * d0 + (v[j, 1] - v[i, 1]) * d1 + (v[j, 2] - v[i, 2]) * d2
    for s in prange(spring_ij.shape[0]):
        # Contiguous, so it vectorises (sqrt and division are exact in SIMD too: same bits).
        # Spring s's force over its length (N/m): the force on knot i is scale * (x_j - x_i).
        length = math.sqrt(length2[s])
        inv_len = 1.0 / length
        spring_scale[s] = (spring_k[s] * (length - spring_rest[s]) + spring_c[s] * rate[s] * inv_len) * inv_len
    # The knot pass is written out in both kernels, not shared through an inline helper: the
    # helper (inline="always" or a plain njit call) measured 4-5x slower on the 184 x 16 net.
    for i in prange(knot_pos.shape[0]):
        w = knot_inv_mass[i]
        x = knot_pos
        v = knot_vel
        if w == 0.0:
            # Fixed knots keep their place; skipping their gather saves the posts' and table's springs.
            out_pos[i, 0] = x[i, 0]
            out_pos[i, 1] = x[i, 1]
            out_pos[i, 2] = x[i, 2]
            out_vel[i, 0] = v[i, 0]
            out_vel[i, 1] = v[i, 1]
            out_vel[i, 2] = v[i, 2]
            continue
        xi0, xi1, xi2 = x[i, 0], x[i, 1], x[i, 2]
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        for slot in range(adj_start[i], adj_start[i + 1]):
            j = adj_knot[slot]
            c = spring_scale[adj_spring[slot]]
            # scale * (x_j - x_i) is the force on knot i whichever end of the spring i is.
            f0 += c * (x[j, 0] - xi0)
            f1 += c * (x[j, 1] - xi1)
            f2 += c * (x[j, 2] - xi2)
        vi0, vi1, vi2 = v[i, 0], v[i, 1], v[i, 2]
        # v' = v + h (f/m - g z - drag v); x' = x + h v' (symplectic: the new velocity moves the knot).
        nv0 = vi0 + h * (w * f0 - drag * vi0)
        nv1 = vi1 + h * (w * f1 - drag * vi1)
        nv2 = vi2 + h * (w * f2 - drag * vi2 - gravity)
        z = xi2 + h * nv2
        if z < TABLE_Z:  # the playing surface stops the knot (one-sided, inelastic, frictionless)
            z = TABLE_Z
            nv2 = max(nv2, 0.0)
        out_vel[i, 0] = nv0
        out_vel[i, 1] = nv1
        out_vel[i, 2] = nv2
        out_pos[i, 0] = xi0 + h * nv0
        out_pos[i, 1] = xi1 + h * nv1
        out_pos[i, 2] = z


@njit(cache=True, fastmath=False, error_model="numpy")
def step_knots_serial(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_rest,
                      spring_k, spring_c, gravity, drag, h, spring_work, out_pos, out_vel):
    """step_knots on one thread, bit-for-bit equal to it (same passes, same order).

    For small nets, where waking the thread pool costs more than the step. Args as step_knots.
    """
    length2 = spring_work[0]
    rate = spring_work[1]
    spring_scale = spring_work[2]
    for s in range(spring_ij.shape[0]):
        # Gather the spring's ends: |L|^2 and (v_j - v_i) . L.
        x = knot_pos
        v = knot_vel
        i = spring_ij[s, 0]
        j = spring_ij[s, 1]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        length2[s] = d0 * d0 + d1 * d1 + d2 * d2
        rate[s] = (v[j, 0] - v[i, 0]) * d0 + (v[j, 1] - v[i, 1]) * d1 + (v[j, 2] - v[i, 2]) * d2
    for s in range(spring_ij.shape[0]):
        # Contiguous, so it vectorises (sqrt and division are exact in SIMD too: same bits).
        # Spring s's force over its length (N/m): the force on knot i is scale * (x_j - x_i).
        length = math.sqrt(length2[s])
        inv_len = 1.0 / length
        spring_scale[s] = (spring_k[s] * (length - spring_rest[s]) + spring_c[s] * rate[s] * inv_len) * inv_len
    for i in range(knot_pos.shape[0]):  # the same knot pass as step_knots, keep the two in step
        w = knot_inv_mass[i]
        x = knot_pos
        v = knot_vel
        if w == 0.0:
            # Fixed knots keep their place; skipping their gather saves the posts' and table's springs.
            out_pos[i, 0] = x[i, 0]
            out_pos[i, 1] = x[i, 1]
            out_pos[i, 2] = x[i, 2]
            out_vel[i, 0] = v[i, 0]
            out_vel[i, 1] = v[i, 1]
            out_vel[i, 2] = v[i, 2]
            continue
        xi0, xi1, xi2 = x[i, 0], x[i, 1], x[i, 2]
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        for slot in range(adj_start[i], adj_start[i + 1]):
            j = adj_knot[slot]
            c = spring_scale[adj_spring[slot]]
            # scale * (x_j - x_i) is the force on knot i whichever end of the spring i is.
            f0 += c * (x[j, 0] - xi0)
            f1 += c * (x[j, 1] - xi1)
            f2 += c * (x[j, 2] - xi2)
        vi0, vi1, vi2 = v[i, 0], v[i, 1], v[i, 2]
        # v' = v + h (f/m - g z - drag v); x' = x + h v' (symplectic: the new velocity moves the knot).
        nv0 = vi0 + h * (w * f0 - drag * vi0)
        nv1 = vi1 + h * (w * f1 - drag * vi1)
        nv2 = vi2 + h * (w * f2 - drag * vi2 - gravity)
        z = xi2 + h * nv2
        if z < TABLE_Z:  # the playing surface stops the knot (one-sided, inelastic, frictionless)
            z = TABLE_Z
            nv2 = max(nv2, 0.0)
        out_vel[i, 0] = nv0
        out_vel[i, 1] = nv1
        out_vel[i, 2] = nv2
        out_pos[i, 0] = xi0 + h * nv0
        out_pos[i, 1] = xi1 + h * nv1
        out_pos[i, 2] = z


# ---------------------------------------------------------------------------------------------
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
# checks stay few enough to vectorise it: written together, a knot pass that read 19 arrays
# and wrote 6 stayed scalar (47 us on the 184 x 16 net, 16 us split).

# Spring classes of a grid net: rows of NetTopology.grid_params (k N/m, c N s/m, rest m); the
# top row's horizontals are the top cord, the bottom row's the bottom cord (hem).
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
    """t of row r's horizontal springs (the top cord on the last row, the bottom cord on the first) into work[_H : _H + 3]."""
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
        if k == 2 and w != 0.0 and z < TABLE_Z:  # the playing surface (TABLE_Z)
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
            # sank the force sum under the condition and loaded the 8 terms with masked loads
            # (vmaskmovpd): 14 us against 11 us for this pass on the 184 x 16 net. Same bits:
            # 1.0 * y is y, and vi + 0.0 * y is vi (a -0.0 velocity becomes +0.0).
            free = 1.0 if w != 0.0 else 0.0
            nv = vi + free * (h * (w * f - drag * vi - g))
            v_row[q] = nv
            x_row[q] = xi + free * (h * nv)
        if k == 2:
            # The playing surface (TABLE_Z): fixed knots never start below it, so only free ones
            # are moved; a separate pass keeps the force loop above free of branches.
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
    rows = knot_state.shape[2]
    cols = knot_state.shape[3]
    x = knot_state[0]
    v = knot_state[1]
    for t in range(ticks):
        step_grid_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work)
        top = 0.0
        for a in range(3):
            box[0, a] = math.inf
            box[1, a] = -math.inf
        for r in range(rows):
            for c in range(cols):
                s = v[0, r, c] * v[0, r, c] + v[1, r, c] * v[1, r, c] + v[2, r, c] * v[2, r, c]
                p = x[0, r, c] + x[1, r, c] + x[2, r, c]
                if not (s < math.inf and p - p == 0.0):
                    return t + 1, quiet_ticks, FREE_NOT_FINITE
                if s > top:
                    top = s
                for a in range(3):
                    box[0, a] = min(box[0, a], x[a, r, c])
                    box[1, a] = max(box[1, a], x[a, r, c])
        quiet_ticks = quiet_ticks + 1 if math.sqrt(top) < sleep_speed else 0
        if quiet_ticks >= sleep_ticks:
            v[:] = 0.0
        for a in range(3):
            if box[0, a] < reach[0, a] or box[1, a] > reach[1, a]:
                return t + 1, quiet_ticks, FREE_OUT_OF_REACH
        if quiet_ticks >= sleep_ticks:
            return t + 1, quiet_ticks, FREE_ASLEEP
    return ticks, quiet_ticks, FREE_AWAKE


@njit(cache=True, fastmath=False)
def knot_speed_max(knot_pos, knot_vel):
    """m/s, the largest knot speed; inf if any knot position or velocity is not finite.

    Serial: a max is order-independent, but a prange reduction would still be one more pool wake.
    """
    top = 0.0
    for i in range(knot_pos.shape[0]):
        s = knot_vel[i, 0] * knot_vel[i, 0] + knot_vel[i, 1] * knot_vel[i, 1] + knot_vel[i, 2] * knot_vel[i, 2]
        p = knot_pos[i, 0] + knot_pos[i, 1] + knot_pos[i, 2]
        if not (s < math.inf and p - p == 0.0):
            return math.inf
        if s > top:
            top = s
    return math.sqrt(top)


# ---------------------------------------------------------------------------------------------
# Implicit Euler: Baraff & Witkin, "Large steps in cloth simulation", SIGGRAPH 1998, one Newton
# step of backward Euler, (M - h D - h^2 K) dv = h (f0 + h K v0), solved matrix-free by
# conjugate gradients (Shewchuk, "An introduction to the conjugate gradient method without
# the agonizing pain", 1994). The spring Hessian block is
# H_s = k_s n n^T + max(0, k_s (1 - L_rest/|L|)) (I - n n^T): the transverse part is clamped at
# zero for compressed springs so the system stays symmetric positive definite (Choi & Ko,
# "Stable but responsive cloth", SIGGRAPH 2002). Dashpots enter as h k_d n n^T.
# The CG pieces run serially: each iteration is a handful of short loops, and waking the
# thread pool for each of them cost more than the loops on a loaded 2-core machine (a 200-step
# 24 x 8 test went from seconds to minutes while other processes held the cores).
# spring_work columns: n0, n1, n2, h^2 transverse stiffness (coefficient of I), h^2 axial
# stiffness minus it, h k_d (both coefficients of n n^T), axial force (N).
SPRING_WORK_COLS = 7
KNOT_WORK_ROWS = 4  # dv, residual r, search direction p, A p


@njit(inline="always", cache=True)
def _block_apply(spring_work, s, p0, p1, p2):
    """(B_s p): B_s = a I + b n n^T, the spring's share of A."""
    n0 = spring_work[s, 0]
    n1 = spring_work[s, 1]
    n2 = spring_work[s, 2]
    a = spring_work[s, 3]
    b = (spring_work[s, 4] + spring_work[s, 5]) * (n0 * p0 + n1 * p1 + n2 * p2)
    return a * p0 + b * n0, a * p1 + b * n1, a * p2 + b * n2


@njit(cache=True, fastmath=False)
def _spring_prepare(knot_pos, knot_vel, spring_ij, spring_rest, spring_k, spring_c, h, spring_work):
    """Per spring: direction, A's block coefficients and the axial force."""
    for s in range(spring_ij.shape[0]):
        i = spring_ij[s, 0]
        j = spring_ij[s, 1]
        d0 = knot_pos[j, 0] - knot_pos[i, 0]
        d1 = knot_pos[j, 1] - knot_pos[i, 1]
        d2 = knot_pos[j, 2] - knot_pos[i, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        n0 = d0 / length
        n1 = d1 / length
        n2 = d2 / length
        rate = ((knot_vel[j, 0] - knot_vel[i, 0]) * n0 + (knot_vel[j, 1] - knot_vel[i, 1]) * n1
                + (knot_vel[j, 2] - knot_vel[i, 2]) * n2)
        k = spring_k[s]
        transverse = max(0.0, k * (1.0 - spring_rest[s] / length))
        spring_work[s, 0] = n0
        spring_work[s, 1] = n1
        spring_work[s, 2] = n2
        spring_work[s, 3] = h * h * transverse
        spring_work[s, 4] = h * h * (k - transverse)
        spring_work[s, 5] = h * spring_c[s]
        spring_work[s, 6] = k * (length - spring_rest[s]) + spring_c[s] * rate


@njit(cache=True, fastmath=False)
def _apply_system(knot_inv_mass, adj_start, adj_knot, adj_spring, spring_work, drag, h, p, out):
    """out = A p, gathered per knot; fixed knots' rows are the identity (their dv stays 0)."""
    for i in range(p.shape[0]):
        w = knot_inv_mass[i]
        if w == 0.0:
            out[i, 0] = p[i, 0]
            out[i, 1] = p[i, 1]
            out[i, 2] = p[i, 2]
            continue
        m = (1.0 + h * drag) / w
        o0 = m * p[i, 0]
        o1 = m * p[i, 1]
        o2 = m * p[i, 2]
        for slot in range(adj_start[i], adj_start[i + 1]):
            j = adj_knot[slot]
            q0 = p[i, 0]
            q1 = p[i, 1]
            q2 = p[i, 2]
            if knot_inv_mass[j] != 0.0:
                q0 -= p[j, 0]
                q1 -= p[j, 1]
                q2 -= p[j, 2]
            b0, b1, b2 = _block_apply(spring_work, adj_spring[slot], q0, q1, q2)
            o0 += b0
            o1 += b1
            o2 += b2
        out[i, 0] = o0
        out[i, 1] = o1
        out[i, 2] = o2


@njit(cache=True, fastmath=False)
def _implicit_rhs(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_work,
                  gravity, drag, h, out):
    """out = h (f0 - drag m v0 - m g z) - h^2 sum_s H_s (v0_i - v0_j), zero for fixed knots."""
    for i in range(knot_pos.shape[0]):
        w = knot_inv_mass[i]
        if w == 0.0:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
            continue
        m = 1.0 / w
        r0 = -drag * m * knot_vel[i, 0]
        r1 = -drag * m * knot_vel[i, 1]
        r2 = -drag * m * knot_vel[i, 2] - m * gravity
        r0 *= h
        r1 *= h
        r2 *= h
        for slot in range(adj_start[i], adj_start[i + 1]):
            s = adj_spring[slot]
            # The spring's n points from spring_ij[s, 0] to spring_ij[s, 1]; the force pulls i toward j.
            sign = 1.0 if spring_ij[s, 0] == i else -1.0
            f = sign * h * spring_work[s, 6]
            r0 += f * spring_work[s, 0]
            r1 += f * spring_work[s, 1]
            r2 += f * spring_work[s, 2]
            j = adj_knot[slot]
            # Only the stiffness part of the block (h^2 H_s): rebuild it from the stored a, b.
            a = spring_work[s, 3]
            b = spring_work[s, 4]
            q0 = knot_vel[i, 0] - knot_vel[j, 0]
            q1 = knot_vel[i, 1] - knot_vel[j, 1]
            q2 = knot_vel[i, 2] - knot_vel[j, 2]
            t = b * (spring_work[s, 0] * q0 + spring_work[s, 1] * q1 + spring_work[s, 2] * q2)
            r0 -= a * q0 + t * spring_work[s, 0]
            r1 -= a * q1 + t * spring_work[s, 1]
            r2 -= a * q2 + t * spring_work[s, 2]
        out[i, 0] = r0
        out[i, 1] = r1
        out[i, 2] = r2


@njit(cache=True, fastmath=False)
def _dot(a, b):
    """Serial dot product of two (n, 3) arrays: a fixed summation order, so fixed bits."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return total


@njit(cache=True, fastmath=False)
def _axpy(alpha, x, y):
    """y += alpha x, elementwise."""
    for i in range(x.shape[0]):
        y[i, 0] += alpha * x[i, 0]
        y[i, 1] += alpha * x[i, 1]
        y[i, 2] += alpha * x[i, 2]


@njit(cache=True, fastmath=False)
def _xpby(x, beta, y):
    """y = x + beta y, elementwise."""
    for i in range(x.shape[0]):
        y[i, 0] = x[i, 0] + beta * y[i, 0]
        y[i, 1] = x[i, 1] + beta * y[i, 1]
        y[i, 2] = x[i, 2] + beta * y[i, 2]


@njit(cache=True, fastmath=False)
def step_knots_implicit(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_rest,
                        spring_k, spring_c, gravity, drag, h, cg_tol, cg_max_iter, knot_work, spring_work,
                        out_pos, out_vel):
    """One backward-Euler step of every knot (Baraff & Witkin 1998), stable at any h.

    Solves (M (1 + h drag) - h D - h^2 K) dv = h (f0 - drag M v0 - M g z + h K v0) for dv by
    conjugate gradients from dv = 0, then v' = v0 + dv, x' = x0 + h v'. Fixed knots keep
    dv = 0. Products with the matrix are per-knot gathers; everything runs on one thread.

    Args:
        knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_rest,
            spring_k, spring_c, gravity, drag, h, out_pos, out_vel: as step_knots.
        spring_ij: (n_springs, 2) uint32 knot indices.
        cg_tol: relative residual |r| / |r0| at which CG stops.
        cg_max_iter: CG iterations at most.
        knot_work: (KNOT_WORK_ROWS, n_knots, 3) scratch.
        spring_work: (n_springs, SPRING_WORK_COLS) scratch.

    Returns:
        CG iterations taken.
    """
    dv = knot_work[0]
    r = knot_work[1]
    p = knot_work[2]
    ap = knot_work[3]
    _spring_prepare(knot_pos, knot_vel, spring_ij, spring_rest, spring_k, spring_c, h, spring_work)
    _implicit_rhs(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_work,
                  gravity, drag, h, r)
    dv[:] = 0.0
    p[:] = r
    rr = _dot(r, r)
    stop = cg_tol * cg_tol * rr
    it = 0
    while it < cg_max_iter and rr > stop:
        _apply_system(knot_inv_mass, adj_start, adj_knot, adj_spring, spring_work, drag, h, p, ap)
        alpha = rr / _dot(p, ap)
        _axpy(alpha, p, dv)
        _axpy(-alpha, ap, r)
        rr_new = _dot(r, r)
        _xpby(r, rr_new / rr, p)
        rr = rr_new
        it += 1
    for i in range(knot_pos.shape[0]):
        for c in range(3):
            out_vel[i, c] = knot_vel[i, c] + dv[i, c]
            out_pos[i, c] = knot_pos[i, c] + h * out_vel[i, c]
        if knot_inv_mass[i] != 0.0 and out_pos[i, 2] < TABLE_Z:  # the playing surface (TABLE_Z)
            out_pos[i, 2] = TABLE_Z
            out_vel[i, 2] = max(out_vel[i, 2], 0.0)
    return it


# ---------------------------------------------------------------------------------------------
# Ball contact: swept sphere against knot spheres (radius knot_radius), linear relative motion
# over the tick (Ericson, Real-Time Collision Detection, 2005, 4.4.2 / 5.5.7 "intersecting a
# moving sphere against a sphere").


@njit(inline="always", cache=True)
def _sweep(x, v, j, p0, p1, p2, b0, b1, b2, reach, t0, t1):
    """Earliest t in [t0, t1] (s, from the tick's start) with |x_j(t) - p(t)| = reach and closing, else inf."""
    d0 = x[j, 0] + v[j, 0] * t0 - p0
    d1 = x[j, 1] + v[j, 1] * t0 - p1
    d2 = x[j, 2] + v[j, 2] * t0 - p2
    w0 = v[j, 0] - b0
    w1 = v[j, 1] - b1
    w2 = v[j, 2] - b2
    b = d0 * w0 + d1 * w1 + d2 * w2
    c = d0 * d0 + d1 * d1 + d2 * d2 - reach * reach
    if b >= 0.0:
        return math.inf  # separating (or resting): no new contact
    if c <= 0.0:
        return t0  # already touching and closing
    a = w0 * w0 + w1 * w1 + w2 * w2
    disc = b * b - a * c
    if disc < 0.0:
        return math.inf
    t = t0 + (-b - math.sqrt(disc)) / a
    return t if t <= t1 else math.inf


# Ball near the net: the contact sweep visits only the knots the ball can reach this call (its
# cull), gathered by one cheap pass into a scratch list in index order, so every sum and
# minimum runs over the same knots in the same order as the full sweep: the same bits.
# Conservative: a knot is left out only if on some axis its offset from the ball's start
# exceeds near_radius + dt |v_j|_1 (|.|_inf <= |.|_2 and |.|_2 <= |.|_1, so its distance to
# the ball's start stays above near_radius over the call); the ball's path is piecewise linear,
# so its largest distance from the start is at a segment's end, and while that stays within
# near_radius - NEAR_SLACK x touch distance, a left-out knot never comes within touch
# distance. If a contact turns the ball so far (a rebound faster than it came) the sweep falls
# back to all knots for the rest of the call: never wrong, only slower.
NEAR_SLACK = 1.5  # touch distances kept between the cull's sphere and the ball's furthest point
_ALL_KNOTS = np.zeros(0, dtype=np.int64)  # the full sweep's "list": never read (n_near = -1)


@njit(cache=True, fastmath=False)
def _gather_near(knot_pos, knot_vel, p0, p1, p2, near_radius, dt, near):
    """Indices (increasing) of the knots that can come within near_radius of (p0, p1, p2) over dt into near; their count."""
    count = 0
    for j in range(knot_pos.shape[0]):
        grow = near_radius + dt * (abs(knot_vel[j, 0]) + abs(knot_vel[j, 1]) + abs(knot_vel[j, 2]))
        # y (along the net) first: it rejects most knots of a net, x (across its plane) fewest.
        if (abs(knot_pos[j, 1] - p1) <= grow and abs(knot_pos[j, 2] - p2) <= grow
                and abs(knot_pos[j, 0] - p0) <= grow):
            near[count] = j
            count += 1
    return count


@njit(cache=True, fastmath=False)
def _ball_within(q0, q1, q2, s0, s1, s2, limit):
    """|q - s| <= limit (m): the ball's point q is within the cull's guarantee around its start s."""
    e0 = q0 - s0
    e1 = q1 - s1
    e2 = q2 - s2
    return e0 * e0 + e1 * e1 + e2 * e2 <= limit * limit


@njit(cache=True, fastmath=False)
def _collide(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
             restitution, dt, max_hits, out_impulse, out_ball_pos, near, n_near, limit):
    """collide_ball's contract over the first n_near knots listed in `near` (_gather_near), or every knot
    for n_near < 0; limit: m, how far from its start the ball's path may go before that list stops
    covering it (see the notes above _gather_near)."""
    out_impulse[0] = 0.0
    out_impulse[1] = 0.0
    out_impulse[2] = 0.0
    reach = ball_radius + knot_radius
    touch = 1.1 * reach
    p0, p1, p2 = ball_pos[0], ball_pos[1], ball_pos[2]
    b0, b1, b2 = ball_vel[0], ball_vel[1], ball_vel[2]
    t_now = 0.0
    first = NO_CONTACT
    cull = n_near >= 0
    n = n_near if cull else knot_pos.shape[0]
    # Knots the springs pulled inside the ball since the last sweep go back onto its surface
    # (a position projection, as cloth solvers do against colliders): a knot left inside
    # would count as separating and let the ball through.
    for idx in range(n):
        j = near[idx] if cull else idx
        if knot_inv_mass[j] == 0.0:
            continue
        e0 = knot_pos[j, 0] - p0
        e1 = knot_pos[j, 1] - p1
        e2 = knot_pos[j, 2] - p2
        dist = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if dist < reach and dist > 0.0:
            push = reach / dist
            knot_pos[j, 0] = p0 + e0 * push
            knot_pos[j, 1] = p1 + e1 * push
            knot_pos[j, 2] = p2 + e2 * push
    s0, s1, s2 = p0, p1, p2  # the ball's start: the cull's centre
    for _ in range(max_hits):
        if cull and not _ball_within(p0 + b0 * (dt - t_now), p1 + b1 * (dt - t_now), p2 + b2 * (dt - t_now),
                                     s0, s1, s2, limit):
            # The ball's new path leaves the cull's guarantee: every knot from here on.
            cull = False
            n = knot_pos.shape[0]
        t_hit = math.inf
        for idx in range(n):
            t = _sweep(knot_pos, knot_vel, near[idx] if cull else idx, p0, p1, p2, b0, b1, b2, reach, t_now, dt)
            if t < t_hit:
                t_hit = t
        if t_hit == math.inf:
            break
        # The ball at the contact time; gather the knots touching it.
        c0 = p0 + b0 * (t_hit - t_now)
        c1 = p1 + b1 * (t_hit - t_now)
        c2 = p2 + b2 * (t_hit - t_now)
        m0 = 0.0
        m1 = 0.0
        m2 = 0.0
        mass = 0.0
        mom0 = 0.0
        mom1 = 0.0
        mom2 = 0.0
        pinned = False
        for idx in range(n):
            j = near[idx] if cull else idx
            e0 = knot_pos[j, 0] + knot_vel[j, 0] * t_hit - c0
            e1 = knot_pos[j, 1] + knot_vel[j, 1] * t_hit - c1
            e2 = knot_pos[j, 2] + knot_vel[j, 2] * t_hit - c2
            dist = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if dist > touch or dist == 0.0:
                continue
            m0 += e0 / dist
            m1 += e1 / dist
            m2 += e2 / dist
            w = knot_inv_mass[j]
            if w == 0.0:
                pinned = True
            else:
                mass += 1.0 / w
                mom0 += knot_vel[j, 0] / w
                mom1 += knot_vel[j, 1] / w
                mom2 += knot_vel[j, 2] / w
        norm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        if norm == 0.0:
            break
        m0 /= norm
        m1 /= norm
        m2 /= norm
        # Relative velocity of the ball against the struck knots' centre of mass.
        if pinned or mass == 0.0:
            u0 = 0.0
            u1 = 0.0
            u2 = 0.0
            inv_knots = 0.0
        else:
            u0 = mom0 / mass
            u1 = mom1 / mass
            u2 = mom2 / mass
            inv_knots = 1.0 / mass
        r0 = b0 - u0
        r1 = b1 - u1
        r2 = b2 - u2
        closing = r0 * m0 + r1 * m1 + r2 * m2
        if closing <= 0.0:
            # Touching but not closing: nothing to resolve; step past this instant.
            t_now = t_hit + 1e-9 * dt
            p0 = c0 + b0 * 1e-9 * dt
            p1 = c1 + b1 * 1e-9 * dt
            p2 = c2 + b2 * 1e-9 * dt
            if t_now >= dt:
                break
            continue
        # Normal: Newton's law with `restitution`. Tangential: the threads grip the ball
        # (sticking), so struck knots move with it instead of being shoved aside, which would
        # open the mesh under a fast ball. Against fixed knots, the normal part only.
        m_eff = 1.0 / (ball_inv_mass + inv_knots)
        jn = (1.0 + restitution) * closing
        if pinned or mass == 0.0:
            j0 = m_eff * jn * m0
            j1 = m_eff * jn * m1
            j2 = m_eff * jn * m2
        else:
            j0 = m_eff * (jn * m0 + r0 - closing * m0)
            j1 = m_eff * (jn * m1 + r1 - closing * m1)
            j2 = m_eff * (jn * m2 + r2 - closing * m2)
        out_impulse[0] -= j0
        out_impulse[1] -= j1
        out_impulse[2] -= j2
        b0 -= j0 * ball_inv_mass
        b1 -= j1 * ball_inv_mass
        b2 -= j2 * ball_inv_mass
        if not pinned and mass > 0.0:
            dv0 = j0 * inv_knots
            dv1 = j1 * inv_knots
            dv2 = j2 * inv_knots
            for idx in range(n):
                j = near[idx] if cull else idx
                w = knot_inv_mass[j]
                if w == 0.0:
                    continue
                e0 = knot_pos[j, 0] + knot_vel[j, 0] * t_hit - c0
                e1 = knot_pos[j, 1] + knot_vel[j, 1] * t_hit - c1
                e2 = knot_pos[j, 2] + knot_vel[j, 2] * t_hit - c2
                dist = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                if dist > touch or dist == 0.0:
                    continue
                knot_vel[j, 0] += dv0
                knot_vel[j, 1] += dv1
                knot_vel[j, 2] += dv2
                # Keep knot_pos + knot_vel t the knot's path: old velocity before t_hit, new after.
                knot_pos[j, 0] -= dv0 * t_hit
                knot_pos[j, 1] -= dv1 * t_hit
                knot_pos[j, 2] -= dv2 * t_hit
        if first == NO_CONTACT:
            first = t_hit / dt
        p0, p1, p2 = c0, c1, c2
        t_now = t_hit
    out_ball_pos[0] = p0 + b0 * (dt - t_now)
    out_ball_pos[1] = p1 + b1 * (dt - t_now)
    out_ball_pos[2] = p2 + b2 * (dt - t_now)
    return first


@njit(cache=True, fastmath=False)
def collide_ball(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                 restitution, dt, max_hits, out_impulse, out_ball_pos):
    """Swept-sphere contact of the ball with the knots over one tick; impulses both ways.

    Contract: free knots found inside the ball at the start are first moved onto its surface
    (radially). Then the ball moves on the straight line ball_pos + ball_vel t, the knots on
    knot_pos + knot_vel t, for t in [0, dt]. The earliest contact (time of impact, ball
    surface meets a knot sphere of radius knot_radius) is resolved with one impulse against
    every knot then within contact distance (reach + 10 %), treated as one body of their summed
    mass: along the mean contact normal Newton's restitution law with `restitution`, across it
    sticking (the threads grip the ball); fixed knots make that body immovable (and then only
    the normal part acts). Then the ball goes on from there with its new velocity and
    the search repeats, up to max_hits contacts. A struck knot's velocity changes in place and
    its knot_pos shifts by -dv t_hit, so knot_pos + knot_vel t stays its path (old velocity
    before the hit, new after): the next net step from knot_pos ends where the knot should. No tunnelling as long as the ball cannot pass
    between knots: the mesh's cell diagonal must stay below 2 (ball_radius + knot_radius)
    (1.4 cm for the default net against 4 cm), any speed.

    out_ball_pos is where that piecewise-linear path ends at dt: the ball's position change
    due to the net is out_ball_pos - (ball_pos + ball_vel dt), its velocity change
    out_impulse * ball_inv_mass. Call it over short intervals (NetSim does, once per substep)
    so that the knots' own motion within dt stays small against the ball's radius.

    Args:
        knot_pos: (n_knots, 3) m, at the tick's start; struck knots shifted in place.
        knot_vel: (n_knots, 3) m/s, struck knots changed in place.
        knot_inv_mass: (n_knots,) 1/kg, 0 for fixed knots.
        ball_pos: (3,) m, ball centre at the tick's start.
        ball_vel: (3,) m/s, over the tick.
        ball_radius: m.
        ball_inv_mass: 1/kg.
        knot_radius: m, the thread's half thickness.
        restitution: in [0, 1].
        dt: s, the tick.
        max_hits: contacts resolved in this tick at most.
        out_impulse: (3,) N s, written: the total impulse on the ball.
        out_ball_pos: (3,) m, written: the ball centre at dt on its path with the contacts.

    Returns:
        Fraction of dt at the first contact, in [0, 1], or NO_CONTACT (-1.0).
    """
    return _collide(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                    restitution, dt, max_hits, out_impulse, out_ball_pos, _ALL_KNOTS, -1, 0.0)


@njit(cache=True, fastmath=False)
def collide_ball_near(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                      restitution, dt, max_hits, out_impulse, out_ball_pos, near):
    """collide_ball over only the knots the ball can reach in dt: the same contacts and the same bits.

    One cheap pass (a box test per knot, no root) lists the knots whose path can come near the
    ball's (see the notes above _gather_near); every other pass of the sweep (projection, time of
    impact, touching knots, impulses) runs over that list, in index order. A contact that
    throws the ball further than the list covers switches to all knots for the rest of the call.

    Args:
        knot_pos ... out_ball_pos: as collide_ball.
        near: (n_knots,) int64 scratch, written: the listed knots' indices.

    Returns:
        As collide_ball.
    """
    if near.shape[0] < knot_pos.shape[0]:
        raise ValueError("collide_ball_near: near must hold one int64 per knot (shape (n_knots,))")
    touch = 1.1 * (ball_radius + knot_radius)  # _collide's touch distance
    travel = math.sqrt(ball_vel[0] * ball_vel[0] + ball_vel[1] * ball_vel[1] + ball_vel[2] * ball_vel[2]) * dt
    # Twice the straight path's length plus a margin: a rebound up to as fast as the ball came stays culled.
    near_radius = 2.0 * travel + (NEAR_SLACK + 1.5) * touch
    n_near = _gather_near(knot_pos, knot_vel, ball_pos[0], ball_pos[1], ball_pos[2], near_radius, dt, near)
    return _collide(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                    restitution, dt, max_hits, out_impulse, out_ball_pos, near, n_near, near_radius - NEAR_SLACK * touch)


@njit(cache=True, fastmath=False, error_model="numpy")
def step_grid_ball(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work, ball, ball_radius,
                   ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    """A tick of a grid net with the ball near: n_steps times collide_ball_near over h, then one step_grid step.

    NetSim's per-substep loop in one call (no Python between substeps), with its arithmetic: the
    same bits as calling collide_ball_near and step_grid_serial(..., 1, ...) in turn and summing
    in float64 as NetSim does. One thread (the grid kernels give the same bits on any number).

    Args:
        knot_state, knot_inv_mass, grid_params, gravity, drag, h, grid_work: as step_grid;
            knot_inv_mass (rows, cols).
        n_steps: substeps (>= 0).
        ball: (4, 3) [position m, velocity m/s, scratch, scratch], the ball at the tick's start;
            rows 0 and 1 are advanced in place to the tick's end along its path with the contacts.
        ball_radius, ball_inv_mass, knot_radius, restitution, max_hits: as collide_ball.
        near: (n_knots,) int64 scratch (collide_ball_near).
        out_impulse: (3,) N s, written: the sum of the substeps' impulses on the ball.

    Returns:
        Fraction of the tick (n_steps h) at the first contact, or NO_CONTACT.
    """
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    n = rows * cols
    knot_pos = knot_state[0].reshape(3, n).T  # (n_knots, 3) views, as NetSim's knot_pos / knot_vel
    knot_vel = knot_state[1].reshape(3, n).T
    flat_inv_mass = knot_inv_mass.reshape(n)
    bp = ball[0]
    bv = ball[1]
    hit_impulse = ball[3]
    out_impulse[:] = 0.0
    toi = NO_CONTACT
    for k in range(n_steps):
        hit = collide_ball_near(knot_pos, knot_vel, flat_inv_mass, bp, bv, ball_radius, ball_inv_mass, knot_radius,
                                restitution, h, max_hits, hit_impulse, ball[2], near)
        if hit != NO_CONTACT:
            if toi == NO_CONTACT:
                toi = (k + hit) / n_steps
            for c in range(3):
                out_impulse[c] += hit_impulse[c]
                bv[c] += hit_impulse[c] * ball_inv_mass
        bp[:] = ball[2]
        step_grid_serial(knot_state, knot_inv_mass, grid_params, gravity, drag, h, 1, grid_work)
    return toi
