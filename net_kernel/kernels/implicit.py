"""Backward-Euler knot step over the CSR adjacency, solved matrix-free by conjugate gradients."""
import math

from numba import njit

from net_kernel.kernels.table import TABLE_Z

# Implicit Euler: Baraff & Witkin, "Large steps in cloth simulation", SIGGRAPH 1998, one Newton
# step of backward Euler, (M - h D - h^2 K) dv = h (f0 + h K v0), solved matrix-free by
# conjugate gradients (Shewchuk, "An introduction to the conjugate gradient method without
# the agonizing pain", 1994). The spring Hessian block is
# H_s = k_s n n^T + max(0, k_s (1 - L_rest/|L|)) (I - n n^T): the transverse part is clamped at
# zero for compressed springs so the system stays symmetric positive definite (Choi & Ko,
# "Stable but responsive cloth", SIGGRAPH 2002). Dashpots enter as h k_d n n^T.
# The CG pieces run serially: each iteration is a handful of short loops, and waking the
# thread pool for each of them costs more than the loops, most of all on a machine whose cores
# other processes hold.
# spring_work columns: n0, n1, n2, h^2 transverse stiffness (coefficient of I), h^2 axial
# stiffness minus it, h k_d (both coefficients of n n^T), axial force (N).
SPRING_WORK_COLS = 7
KNOT_WORK_ROWS = 4  # dv, residual r, search direction p, A p


@njit(inline="always", cache=True, _nrt=False)
def _block_apply(spring_work, s, p0, p1, p2):
    """(B_s p): B_s = a I + b n n^T, the spring's share of A."""
    n0 = spring_work[s, 0]
    n1 = spring_work[s, 1]
    n2 = spring_work[s, 2]
    a = spring_work[s, 3]
    b = (spring_work[s, 4] + spring_work[s, 5]) * (n0 * p0 + n1 * p1 + n2 * p2)
    return a * p0 + b * n0, a * p1 + b * n1, a * p2 + b * n2


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
def _dot(a, b):
    """Serial dot product of two (n, 3) arrays: a fixed summation order, so fixed bits."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return total


@njit(cache=True, fastmath=False, _nrt=False)
def _axpy(alpha, x, y):
    """y += alpha x, elementwise."""
    for i in range(x.shape[0]):
        y[i, 0] += alpha * x[i, 0]
        y[i, 1] += alpha * x[i, 1]
        y[i, 2] += alpha * x[i, 2]


@njit(cache=True, fastmath=False, _nrt=False)
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
        if knot_inv_mass[i] != 0.0 and out_pos[i, 2] < TABLE_Z:  # the playing surface (kernels/table.py)
            out_pos[i, 2] = TABLE_Z
            out_vel[i, 2] = max(out_vel[i, 2], 0.0)
    return it
