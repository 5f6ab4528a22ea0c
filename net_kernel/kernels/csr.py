"""Knot steps over the CSR adjacency (any topology): semi-implicit Euler, parallel and serial; the knot speed.

The general path: knots in (n_knots, 3) arrays, each knot's springs listed in the topology's
CSR slots (adj_start, adj_knot, adj_spring). The model, the determinism rules and the error
model are in the package's docstring (net_kernel/kernels/__init__.py).
"""
import math

from numba import njit, prange

from net_kernel.kernels.table import TABLE_Z

STEP_WORK_ROWS = 3  # spring_work rows of step_knots: |L|^2, (v_j - v_i) . L, f / |L|


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
    # The knot pass is written out in both kernels, not shared through an inline helper: through
    # a helper (inline="always" or a plain njit call) the pass was several times slower.
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
        if z < TABLE_Z:  # the playing surface stops the knot (net_kernel/kernels/table.py)
            z = TABLE_Z
            nv2 = max(nv2, 0.0)
        out_vel[i, 0] = nv0
        out_vel[i, 1] = nv1
        out_vel[i, 2] = nv2
        out_pos[i, 0] = xi0 + h * nv0
        out_pos[i, 1] = xi1 + h * nv1
        out_pos[i, 2] = z


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
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
        if z < TABLE_Z:  # the playing surface stops the knot (net_kernel/kernels/table.py)
            z = TABLE_Z
            nv2 = max(nv2, 0.0)
        out_vel[i, 0] = nv0
        out_vel[i, 1] = nv1
        out_vel[i, 2] = nv2
        out_pos[i, 0] = xi0 + h * nv0
        out_pos[i, 1] = xi1 + h * nv1
        out_pos[i, 2] = z


@njit(cache=True, fastmath=False, _nrt=False)
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
