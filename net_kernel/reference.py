"""Numpy twins of net_kernel/kernels/: same signatures, vectorised, for checking and profiling.

Each twin evaluates every CSR slot at once and sums a knot's slots with np.add.reduceat, so
it sums in the same slot order as the kernels; results match them to rounding (the tests
state the tolerance). Twins allocate freely; they are the reference, not the fast path.
"""
import math

import numpy as np

from net_kernel.kernels import (  # noqa: F401  (shared)
    GRID_CLASSES,    FREE_ASLEEP,
    FREE_AWAKE,
    FREE_NOT_FINITE,
    FREE_OUT_OF_REACH,
    GRID_CORD,
    GRID_HEM,
    GRID_MESH,
    GRID_SHEAR,
    GRID_VERTICAL,
    KNOT_WORK_ROWS,
    NO_CONTACT,
    SPRING_WORK_COLS,
    STEP_WORK_ROWS,
    TABLE_Z,
)
from net_kernel.kernels.grid32 import LANES as GRID32_LANES
from net_kernel.kernels.grid32 import WORK32_LINES
from net_kernel.kernels.modal import FREE_TAIL


def _slot_owner(adj_start):
    """(2 n_springs,) the knot owning each slot."""
    return np.repeat(np.arange(adj_start.shape[0] - 1), np.diff(adj_start.astype(np.intp)))


def _gather(per_slot, adj_start):
    """(n_knots, 3) sums of per-slot rows over each knot's slots, in slot order (0 for no slots)."""
    n = adj_start.shape[0] - 1
    adj_start = adj_start.astype(np.intp)
    out = np.zeros((n, 3))
    has = adj_start[1:] > adj_start[:-1]
    if per_slot.shape[0]:
        out[has] = np.add.reduceat(per_slot, adj_start[:-1][has], axis=0)
    return out


def spring_forces(knot_pos, knot_vel, adj_start, adj_knot, adj_spring, spring_ij, spring_rest, spring_k, spring_c):
    """(n_knots, 3) N, the spring-damper force on each knot (the kernels' model and order)."""
    i, j = spring_ij[:, 0], spring_ij[:, 1]
    d = knot_pos[j] - knot_pos[i]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    inv_len = 1.0 / length
    rate = np.einsum("ij,ij->i", knot_vel[j] - knot_vel[i], d)
    scale = (spring_k * (length - spring_rest) + spring_c * rate * inv_len) * inv_len
    owner = _slot_owner(adj_start)
    return _gather(scale[adj_spring][:, None] * (knot_pos[adj_knot] - knot_pos[owner]), adj_start)


def _on_table(free, pos_z, vel_z):
    """The kernels' knot-table contact, in place: free knots below TABLE_Z put on it, their downward speed removed."""
    below = free & (pos_z < TABLE_Z)
    pos_z[below] = TABLE_Z
    vel_z[below] = np.maximum(vel_z[below], 0.0)


def step_knots(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_rest, spring_k,
               spring_c, gravity, drag, h, spring_work, out_pos, out_vel):
    """Numpy twin of kernels.step_knots (args and meaning identical; spring_work is unused)."""
    force = spring_forces(knot_pos, knot_vel, adj_start, adj_knot, adj_spring, spring_ij, spring_rest, spring_k,
                          spring_c)
    accel = knot_inv_mass[:, None] * force - drag * knot_vel
    accel[:, 2] -= gravity
    free = knot_inv_mass > 0
    out_vel[:] = np.where(free[:, None], knot_vel + h * accel, knot_vel)
    out_pos[:] = np.where(free[:, None], knot_pos + h * out_vel, knot_pos)
    _on_table(free, out_pos[:, 2], out_vel[:, 2])


step_knots_serial = step_knots


def step_knots_scatter(knot_pos, knot_vel, knot_inv_mass, spring_ij, spring_rest, spring_k, spring_c, gravity, drag, h,
                       knot_force, out_pos, out_vel):
    """Numpy twin of kernels.step_knots_scatter, bit for bit: np.add.at adds in the kernel's order."""
    i, j = spring_ij[:, 0], spring_ij[:, 1]
    d = knot_pos[j] - knot_pos[i]
    length = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    n = d * (1.0 / length)[:, None]
    e = knot_vel[j] - knot_vel[i]
    rate = e[:, 0] * n[:, 0] + e[:, 1] * n[:, 1] + e[:, 2] * n[:, 2]
    f = (spring_k * (length - spring_rest) + spring_c * rate)[:, None] * n
    knot_force[:] = 0.0
    # Spring s adds +f to knot i, then -f to knot j (x - f is x + (-f) exactly), in spring order.
    np.add.at(knot_force, np.stack([i, j], axis=1).ravel(), np.stack([f, -f], axis=1).reshape(-1, 3))
    g = np.array([0.0, 0.0, gravity])
    free = (knot_inv_mass != 0.0)[:, None]
    nv = knot_vel + h * (knot_inv_mass[:, None] * knot_force - drag * knot_vel - g)
    out_vel[:] = np.where(free, nv, knot_vel)
    out_pos[:] = np.where(free, knot_pos + h * nv, knot_pos)
    _on_table(free[:, 0], out_pos[:, 2], out_vel[:, 2])


def _grid_t(xi, xj, vi, vj, k, c, rest):
    """(3, ...) t = scale (x_j - x_i) per spring, kernels.grid._grid_line's operations in its order."""
    d0, d1, d2 = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
    e0, e1, e2 = vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]
    length2 = d0 * d0 + d1 * d1 + d2 * d2
    rate = e0 * d0 + e1 * d1 + e2 * d2
    length = np.sqrt(length2)
    inv_len = 1.0 / length
    scale = (k * (length - rest) + c * rate * inv_len) * inv_len
    return np.stack([scale * d0, scale * d1, scale * d2])


def _below(a):
    """a shifted up one row: row r holds a's row r - 1 (zeros in row 0)."""
    out = np.zeros_like(a)
    out[:, 1:] = a[:, :-1]
    return out


def _left(a):
    """a shifted one column: column q holds a's column q - 1 (zeros in column 0)."""
    out = np.zeros_like(a)
    out[:, :, 1:] = a[:, :, :-1]
    return out


def step_grid(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work):
    """Numpy twin of kernels.step_grid (args, in-place update and bits identical; grid_work is unused).

    Every spring class at once over the whole grid; a missing spring's t is 0, as in the kernel.
    """
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    w = knot_inv_mass
    fixed = w == 0.0
    top = (np.arange(rows) == rows - 1)[:, None]
    bottom = (np.arange(rows) == 0)[:, None]
    # (rows, 1): the top row's horizontals are the top cord, the bottom row's the bottom cord.
    h_kind = np.where(top, GRID_CORD, np.where(bottom, GRID_HEM, GRID_MESH))
    for _ in range(n_steps):
        x, v = knot_state[0].copy(), knot_state[1].copy()  # the step's start: every spring reads it
        t_h = np.zeros((3, rows, cols))
        t_v = np.zeros((3, rows, cols))
        t_d1 = np.zeros((3, rows, cols))
        t_d2 = np.zeros((3, rows, cols))
        p = grid_params
        t_h[:, :, :-1] = _grid_t(x[:, :, :-1], x[:, :, 1:], v[:, :, :-1], v[:, :, 1:], p[h_kind, 0], p[h_kind, 1],
                                 p[h_kind, 2])
        t_v[:, :-1] = _grid_t(x[:, :-1], x[:, 1:], v[:, :-1], v[:, 1:], *p[GRID_VERTICAL])
        t_d1[:, :-1, :-1] = _grid_t(x[:, :-1, :-1], x[:, 1:, 1:], v[:, :-1, :-1], v[:, 1:, 1:], *p[GRID_SHEAR])
        t_d2[:, :-1, :-1] = _grid_t(x[:, :-1, 1:], x[:, 1:, :-1], v[:, :-1, 1:], v[:, 1:, :-1], *p[GRID_SHEAR])
        # The kernel's slot order: below-left, below, below-right, left, right, above-left, above, above-right.
        f = (-_left(_below(t_d1)) - _below(t_v) - _below(t_d2) - _left(t_h) + t_h + _left(t_d2) + t_v + t_d1)
        for k in range(3):
            g = gravity if k == 2 else 0.0
            nv = v[k] + h * (w * f[k] - drag * v[k] - g)
            knot_state[1, k] = np.where(fixed, v[k], nv)
            knot_state[0, k] = np.where(fixed, x[k], x[k] + h * nv)
        _on_table(~fixed, knot_state[0, 2], knot_state[1, 2])


step_grid_serial = step_grid


def grid32_work(built, knot_inv_mass, blocks, variant):
    """Numpy twin of kernels.grid32_work: the same tuple, the same values."""
    rows, cols = built.shape[1], built.shape[2]
    width = (cols // GRID32_LANES + 1) * GRID32_LANES + 1
    inv_mass = np.zeros((rows, width), dtype=np.float32)
    inv_mass[:, 1:cols + 1] = knot_inv_mass
    table = np.full((rows, width), -np.inf, dtype=np.float32)
    table[:, 1:cols + 1] = TABLE_Z - built[2]
    classes = np.zeros((GRID_CLASSES, 5), dtype=np.float32)
    across_y, up_z = built[1, 0, 1] - built[1, 0, 0], built[2, 1, 0] - built[2, 0, 0]
    classes[[GRID_MESH, GRID_CORD, GRID_HEM, GRID_SHEAR], 0] = across_y
    classes[[GRID_VERTICAL, GRID_SHEAR], 1] = up_z
    return (built.copy(), np.zeros((2, 3, rows, width), dtype=np.float32), np.zeros((4, rows, width), dtype=np.float32),
            inv_mass, table, np.zeros((WORK32_LINES, (rows + 1) * width + 1), dtype=np.float32), classes,
            np.int64(variant), np.full(3, np.nan), np.int64(blocks))


def _grid32_t(oi, oj, vi, vj, dy, dz, k, c, k_rest):
    """(3, ...) float32 t = scale d per spring, kernels.grid32._spring32's operations in its order."""
    d0, d1, d2 = oj[0] - oi[0], dy + (oj[1] - oi[1]), dz + (oj[2] - oi[2])
    e0, e1, e2 = vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]
    length2 = d0 * d0 + d1 * d1 + d2 * d2
    rate = e0 * d0 + e1 * d1 + e2 * d2
    inv_len = np.float32(1.0) / np.sqrt(length2)
    scale = k + inv_len * (c * rate * inv_len - k_rest)
    return np.stack([scale * d0, scale * d1, scale * d2])


def step_grid32(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32):
    """Numpy twin of kernels.step_grid32 (args, in-place update; the GRID32_EXACT variant's bits, whatever
    net32's variant: numpy fuses nothing). net32's scratch is unused."""
    if n_steps <= 0:
        return
    f32 = np.float32
    ref, classes = net32[0], net32[6]
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    free = knot_inv_mass != 0.0
    o = (knot_state[0] - ref).astype(f32)
    v = knot_state[1].astype(f32)
    step = f32(h)
    hw = step * knot_inv_mass.astype(f32)
    b = np.where(free, f32(1.0) - step * f32(drag), f32(1.0)).astype(f32)
    hg = np.where(free, step * f32(gravity), f32(0.0)).astype(f32)
    s = np.where(free, step, f32(0.0)).astype(f32)
    floor = (TABLE_Z - ref[2]).astype(f32)
    k, c = grid_params[:, 0].astype(f32), grid_params[:, 1].astype(f32)
    k_rest = k * grid_params[:, 2].astype(f32)
    top = (np.arange(rows) == rows - 1)[:, None]
    bottom = (np.arange(rows) == 0)[:, None]
    h_kind = np.where(top, GRID_CORD, np.where(bottom, GRID_HEM, GRID_MESH))  # (rows, 1)

    def line(oi, oj, vi, vj, kind, mirror=False):
        dy = -classes[kind, 0] if mirror else classes[kind, 0]
        return _grid32_t(oi, oj, vi, vj, dy, classes[kind, 1], k[kind], c[kind], k_rest[kind])

    for _ in range(n_steps):
        t_h = np.zeros((3, rows, cols), dtype=f32)
        t_v = np.zeros((3, rows, cols), dtype=f32)
        t_d1 = np.zeros((3, rows, cols), dtype=f32)
        t_d2 = np.zeros((3, rows, cols), dtype=f32)
        t_h[:, :, :-1] = line(o[:, :, :-1], o[:, :, 1:], v[:, :, :-1], v[:, :, 1:], h_kind)
        t_v[:, :-1] = line(o[:, :-1], o[:, 1:], v[:, :-1], v[:, 1:], GRID_VERTICAL)
        t_d1[:, :-1, :-1] = line(o[:, :-1, :-1], o[:, 1:, 1:], v[:, :-1, :-1], v[:, 1:, 1:], GRID_SHEAR)
        t_d2[:, :-1, :-1] = line(o[:, :-1, 1:], o[:, 1:, :-1], v[:, :-1, 1:], v[:, 1:, :-1], GRID_SHEAR, mirror=True)
        # The kernel's order: above-right - below-left, - below, - below-right, - left, + right, + above-left, + above.
        f = t_d1 - _left(_below(t_d1))
        f -= _below(t_v)
        f -= _below(t_d2)
        f -= _left(t_h)
        f += t_h
        f += _left(t_d2)
        f += t_v
        nv = b * v + hw * f
        nv[2] -= hg
        v = nv
        o = o + s * nv
        below = o[2] < floor
        o[2] = np.where(below, floor, o[2])
        v[2] = np.where(below, np.maximum(v[2], f32(0.0)), v[2])
    knot_state[0] = np.where(free, ref + o.astype(np.float64), knot_state[0])
    knot_state[1] = np.where(free, v.astype(np.float64), knot_state[1])


step_grid32_serial = step_grid32


def grid_knots(knot_state, knot_pos, knot_vel):
    """Numpy twin of kernels.grid_knots."""
    knot_pos[:] = knot_state[0].reshape(3, -1).T
    knot_vel[:] = knot_state[1].reshape(3, -1).T


def step_grid32_free(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                     sleep_ticks, quiet_ticks, reach, box):
    """Numpy twin of kernels.step_grid32_free (args and returns as step_grid_free)."""
    return _free_ticks(step_grid32, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks,
                       sleep_speed, sleep_ticks, quiet_ticks, reach, box)


def step_grid_free(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                   sleep_ticks, quiet_ticks, reach, box):
    """Numpy twin of kernels.step_grid_free (args, returns and bits identical)."""
    return _free_ticks(step_grid, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks,
                       sleep_speed, sleep_ticks, quiet_ticks, reach, box)


def _free_ticks(step, knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
                sleep_ticks, quiet_ticks, reach, box):
    """step_grid_free's ticks with `step` for their steps (kernels.grid.free_ticks)."""
    pos = knot_state[0].reshape(3, -1).T
    vel = knot_state[1].reshape(3, -1).T
    for t in range(ticks):
        step(knot_state, knot_inv_mass, grid_params, gravity, drag, h, substeps, grid_work)
        speed = knot_speed_max(pos, vel)
        if not math.isfinite(speed):
            return t + 1, quiet_ticks, FREE_NOT_FINITE
        pos.min(axis=0, out=box[0])
        pos.max(axis=0, out=box[1])
        quiet_ticks = quiet_ticks + 1 if speed < sleep_speed else 0
        if quiet_ticks >= sleep_ticks:
            knot_state[1] = 0.0
        if (box[0] < reach[0]).any() or (box[1] > reach[1]).any():
            return t + 1, quiet_ticks, FREE_OUT_OF_REACH
        if quiet_ticks >= sleep_ticks:
            return t + 1, quiet_ticks, FREE_ASLEEP
    return ticks, quiet_ticks, FREE_AWAKE


def knot_speed_max(knot_pos, knot_vel):
    """Numpy twin of kernels.knot_speed_max."""
    if not (np.all(np.isfinite(knot_pos)) and np.all(np.isfinite(knot_vel))):
        return math.inf
    if knot_vel.shape[0] == 0:
        return 0.0
    return float(np.sqrt(np.max(np.einsum("ij,ij->i", knot_vel, knot_vel))))


def step_knots_implicit(knot_pos, knot_vel, knot_inv_mass, adj_start, adj_knot, adj_spring, spring_ij, spring_rest,
                        spring_k, spring_c, gravity, drag, h, cg_tol, cg_max_iter, knot_work, spring_work,
                        out_pos, out_vel):
    """Numpy twin of kernels.step_knots_implicit (backward Euler, CG); returns CG iterations."""
    i, j = spring_ij[:, 0], spring_ij[:, 1]
    d = knot_pos[j] - knot_pos[i]
    length = np.linalg.norm(d, axis=1)
    n = d / length[:, None]
    rate = np.einsum("ij,ij->i", knot_vel[j] - knot_vel[i], n)
    transverse = np.maximum(0.0, spring_k * (1.0 - spring_rest / length))
    a = h * h * transverse
    b_k = h * h * (spring_k - transverse)
    b_c = h * spring_c
    axial = spring_k * (length - spring_rest) + spring_c * rate
    owner = _slot_owner(adj_start)
    sign = np.where(spring_ij[adj_spring, 0] == owner, 1.0, -1.0)
    fixed = knot_inv_mass == 0
    mass = np.where(fixed, 0.0, 1.0 / np.where(fixed, 1.0, knot_inv_mass))

    def blocks(q, coef_a, coef_b):
        ns = n[adj_spring]
        t = coef_b[adj_spring] * np.einsum("ij,ij->i", ns, q)
        return coef_a[adj_spring][:, None] * q + t[:, None] * ns

    q = knot_vel[owner] - knot_vel[adj_knot]
    rhs = _gather((sign * h * axial[adj_spring])[:, None] * n[adj_spring] - blocks(q, a, b_k), adj_start)
    rhs += h * (-drag * mass[:, None] * knot_vel)
    rhs[:, 2] -= h * mass * gravity
    rhs[fixed] = 0.0

    def apply(p):
        pj = np.where(fixed[adj_knot][:, None], 0.0, p[adj_knot])
        out = ((1.0 + h * drag) * mass)[:, None] * p + _gather(blocks(p[owner] - pj, a, b_k + b_c), adj_start)
        out[fixed] = p[fixed]
        return out

    dv = np.zeros_like(knot_vel)
    r = rhs.copy()
    p = r.copy()
    rr = float(np.sum(r * r))
    stop = cg_tol * cg_tol * rr
    it = 0
    while it < cg_max_iter and rr > stop:
        ap = apply(p)
        alpha = rr / float(np.sum(p * ap))
        dv += alpha * p
        r -= alpha * ap
        rr_new = float(np.sum(r * r))
        p = r + (rr_new / rr) * p
        rr = rr_new
        it += 1
    out_vel[:] = knot_vel + dv
    out_pos[:] = knot_pos + h * out_vel
    _on_table(~fixed, out_pos[:, 2], out_vel[:, 2])
    return it


def collide_ball(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                 restitution, dt, max_hits, out_impulse, out_ball_pos):
    """Numpy twin of kernels.collide_ball (same contract, same in-place changes)."""
    out_impulse[:] = 0.0
    reach = ball_radius + knot_radius
    p = np.array(ball_pos, dtype=float)
    b = np.array(ball_vel, dtype=float)
    t_now = 0.0
    first = NO_CONTACT
    free = knot_inv_mass > 0
    e = knot_pos - p
    dist = np.linalg.norm(e, axis=1)
    inside = free & (dist < reach) & (dist > 0.0)
    knot_pos[inside] = p + e[inside] * (reach / dist[inside])[:, None]
    for _ in range(max_hits):
        d = knot_pos + knot_vel * t_now - p
        w = knot_vel - b
        bb = np.einsum("ij,ij->i", d, w)
        cc = np.einsum("ij,ij->i", d, d) - reach * reach
        aa = np.einsum("ij,ij->i", w, w)
        disc = bb * bb - aa * cc
        with np.errstate(invalid="ignore", divide="ignore"):
            t = t_now + (-bb - np.sqrt(np.where(disc >= 0, disc, 0.0))) / aa
        t = np.where(cc <= 0.0, t_now, t)
        ok = (bb < 0.0) & ((cc <= 0.0) | ((disc >= 0.0) & (t <= dt)))
        if not ok.any():
            break
        t_hit = float(np.min(t[ok]))
        c = p + b * (t_hit - t_now)
        e = knot_pos + knot_vel * t_hit - c
        dist = np.linalg.norm(e, axis=1)
        touch = (dist <= 1.1 * reach) & (dist > 0.0)
        normal = np.sum(e[touch] / dist[touch][:, None], axis=0)
        norm = float(np.linalg.norm(normal))
        if norm == 0.0:
            break
        normal /= norm
        pinned = bool(np.any(touch & ~free))
        moving = touch & free
        mass = float(np.sum(1.0 / knot_inv_mass[moving])) if moving.any() else 0.0
        if pinned or mass == 0.0:
            u, inv_knots = np.zeros(3), 0.0
        else:
            u = np.sum(knot_vel[moving] / knot_inv_mass[moving][:, None], axis=0) / mass
            inv_knots = 1.0 / mass
        rel = b - u
        closing = float(rel @ normal)
        if closing <= 0.0:
            t_now = t_hit + 1e-9 * dt
            p = c + b * 1e-9 * dt
            if t_now >= dt:
                break
            continue
        m_eff = 1.0 / (ball_inv_mass + inv_knots)
        jn = (1.0 + restitution) * closing
        if pinned or mass == 0.0:
            jv = m_eff * jn * normal
        else:
            jv = m_eff * (jn * normal + rel - closing * normal)
        out_impulse -= jv
        b = b - jv * ball_inv_mass
        if not pinned and mass > 0.0:
            dv = jv * inv_knots
            knot_vel[moving] += dv
            knot_pos[moving] -= dv * t_hit
        if first == NO_CONTACT:
            first = t_hit / dt
        p = c
        t_now = t_hit
    out_ball_pos[:] = p + b * (dt - t_now)
    return first


def collide_ball_near(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                      restitution, dt, max_hits, out_impulse, out_ball_pos, near):
    """Numpy twin of kernels.collide_ball_near: the full sweep (the cull changes no result); near unused."""
    if near.shape[0] < knot_pos.shape[0]:
        raise ValueError("collide_ball_near: near must hold one int64 per knot (shape (n_knots,))")
    return collide_ball(knot_pos, knot_vel, knot_inv_mass, ball_pos, ball_vel, ball_radius, ball_inv_mass, knot_radius,
                        restitution, dt, max_hits, out_impulse, out_ball_pos)


def step_grid_ball(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work, ball, ball_radius,
                   ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    """Numpy twin of kernels.step_grid_ball (args and in-place updates identical): collide_ball, then step_grid, n_steps times."""
    return _ball_substeps(step_grid, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work, ball,
                          ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)


def step_grid32_ball(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32, ball, ball_radius,
                     ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    """Numpy twin of kernels.step_grid32_ball: collide_ball, then step_grid32, n_steps times."""
    return _ball_substeps(step_grid32, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32, ball,
                          ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)


def _ball_substeps(step, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work, ball, ball_radius,
                   ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    rows, cols = knot_state.shape[2], knot_state.shape[3]
    n = rows * cols
    knot_pos = knot_state[0].reshape(3, n).T
    knot_vel = knot_state[1].reshape(3, n).T
    flat_inv_mass = knot_inv_mass.reshape(n)
    out_impulse[:] = 0.0
    toi = NO_CONTACT
    for k in range(n_steps):
        hit = collide_ball_near(knot_pos, knot_vel, flat_inv_mass, ball[0], ball[1], ball_radius, ball_inv_mass,
                                knot_radius, restitution, h, max_hits, ball[3], ball[2], near)
        if hit != NO_CONTACT:
            if toi == NO_CONTACT:
                toi = (k + hit) / n_steps
            out_impulse += ball[3]
            ball[1] += ball[3] * ball_inv_mass
        ball[0] = ball[2]
        step(knot_state, knot_inv_mass, grid_params, gravity, drag, h, 1, grid_work)
    return toi


def step_grid_tick(*args):
    """Numpy twin of kernels.step_grid_tick (args, in-place updates and returns identical)."""
    return _tick(step_grid_ball, *args)


def step_grid32_tick(*args):
    """Numpy twin of kernels.step_grid32_tick."""
    return _tick(step_grid32_ball, *args)


def _tick(ball_tick, knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, grid_work, ball, ball_radius,
          ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks, sleep_speed, reach,
          box, out_impulse, out_offset):
    pos = knot_state[0].reshape(3, -1).T
    vel = knot_state[1].reshape(3, -1).T
    v0 = ball[5]
    closing = math.sqrt(v0[0] * v0[0] + v0[1] * v0[1] + v0[2] * v0[2]) + knot_speed_max(pos, vel)
    taken = max(substeps, math.ceil(min(closing, speed_max) * dt / travel))
    ball[0:2] = ball[4:6]
    toi = ball_tick(knot_state, knot_inv_mass, grid_params, gravity, drag, dt / taken, taken, grid_work, ball,
                    ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)
    out_offset[:] = 0.0 if toi == NO_CONTACT else ball[0] - ball[4] - ball[5] * dt
    if toi != NO_CONTACT:
        quiet_ticks = 0
    speed = knot_speed_max(pos, vel)
    if not math.isfinite(speed):
        return toi, taken, quiet_ticks, FREE_NOT_FINITE
    pos.min(axis=0, out=box[0])
    pos.max(axis=0, out=box[1])
    quiet_ticks = quiet_ticks + 1 if speed < sleep_speed else 0
    if (box[0] < reach[0]).any() or (box[1] > reach[1]).any():
        return toi, taken, quiet_ticks, FREE_OUT_OF_REACH
    return toi, taken, quiet_ticks, FREE_AWAKE


def potential_energy(knot_pos, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity):
    """Numpy twin of kernels.potential_energy (to rounding: the sums run in numpy's order)."""
    d = knot_pos[spring_ij[:, 1]] - knot_pos[spring_ij[:, 0]]
    stretch = np.sqrt(np.einsum("ij,ij->i", d, d)) - spring_rest
    free = knot_inv_mass != 0.0
    return float(np.sum(0.5 * spring_k * stretch * stretch) + np.sum(knot_mass[free] * gravity * knot_pos[free, 2]))


def motion_energy(knot_pos, knot_vel, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity,
                  rest_energy, limit):
    """Numpy twin of kernels.motion_energy."""
    free = knot_inv_mass != 0.0
    kinetic = float(np.sum(0.5 * knot_mass[free] * np.einsum("ij,ij->i", knot_vel[free], knot_vel[free])))
    if kinetic > limit:
        return kinetic
    return kinetic + potential_energy(knot_pos, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k,
                                      gravity) - rest_energy


def _free_tail(free, knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
               sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k,
               rest_energy, tail_energy):
    pos = knot_state[0].reshape(3, -1).T
    vel = knot_state[1].reshape(3, -1).T
    taken = 0
    while taken < ticks:
        t, quiet_ticks, status = free(knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, 1,
                                      sleep_speed, sleep_ticks, quiet_ticks, reach, box)
        taken += t
        if status != FREE_AWAKE:
            return taken, quiet_ticks, status
        if motion_energy(pos, vel, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity, rest_energy,
                         tail_energy) <= tail_energy:
            return taken, quiet_ticks, FREE_TAIL
    return taken, quiet_ticks, FREE_AWAKE


def step_grid_free_tail(*args):
    """Numpy twin of kernels.step_grid_free_tail."""
    return _free_tail(step_grid_free, *args)


def step_grid32_free_tail(*args):
    """Numpy twin of kernels.step_grid32_free_tail."""
    return _free_tail(step_grid32_free, *args)


def modal_coefficients(knot_pos, knot_vel, rest_pos, free, out_proj, out_e, in_proj, in_inverse, out_c, in_w, q, p,
                       in_scratch, dofs):
    """Numpy twin of kernels.modal_coefficients (to rounding)."""
    q[:] = out_proj.T @ (knot_pos[free, 0] - rest_pos[free, 0])
    p[:] = out_proj.T @ knot_vel[free, 0]
    out_c[:] = 0.5 * q + 1j * (0.5 * q * out_e.real - 0.5 * p) / out_e.imag
    k = in_proj.shape[1]
    in_scratch[:k] = in_proj.T @ (knot_pos[free, 1:] - rest_pos[free, 1:]).ravel()
    in_scratch[k:] = in_proj.T @ knot_vel[free, 1:].ravel()
    in_w[:] = in_inverse @ in_scratch


def modal_detuning(out_detune, out_c, out_shift):
    """Numpy twin of kernels.modal_detuning (to rounding)."""
    out_shift[:] = out_detune.T @ (out_c.real ** 2 + out_c.imag ** 2)


def modal_state(ticks, rest_pos, free, out_shape, out_c, out_e, out_log_r, out_theta, out_shift, out_rate, in_pos,
                in_vel, in_w, in_log_r, in_theta, q, p, xi, dofs, knot_pos, knot_vel):
    """Numpy twin of kernels.modal_state (to rounding)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        summed = np.where(out_log_r == 0.0, float(ticks), np.expm1(2.0 * ticks * out_log_r) / np.expm1(2.0 * out_log_r))
    angle = ticks * out_theta + out_shift * summed
    z = out_c * np.exp(ticks * out_log_r) * (np.cos(angle) + 1j * np.sin(angle))
    scale = 1.0 + out_shift * np.exp(2.0 * ticks * out_log_r) / out_rate
    w = in_w * np.exp(ticks * in_log_r) * (np.cos(ticks * in_theta) + 1j * np.sin(ticks * in_theta))
    q[:] = 2.0 * z.real
    p[:] = 2.0 * (z * (out_e.real + 1j * out_e.imag * scale)).real
    xi[0], xi[1] = w.real, w.imag
    knot_pos[:] = rest_pos
    knot_vel[:] = 0.0
    knot_pos[free, 0] += out_shape.T @ q
    knot_vel[free, 0] += out_shape.T @ p
    knot_pos[free, 1:] += (in_pos[0].T @ xi[0] - in_pos[1].T @ xi[1]).reshape(-1, 2)
    knot_vel[free, 1:] += (in_vel[0].T @ xi[0] - in_vel[1].T @ xi[1]).reshape(-1, 2)


def modal_bounds(out_shape, out_c, out_e, out_shift, out_rate, in_pos_abs, in_vel_abs, in_w, disp, speed):
    """Numpy twin of kernels.modal_bounds (to rounding)."""
    disp[0] = np.abs(out_shape).T @ (2.0 * np.abs(out_c))
    fastest = out_e.real + 1j * out_e.imag * (1.0 + np.abs(out_shift) / out_rate)
    speed[0] = np.abs(out_shape).T @ (2.0 * np.abs(out_c) * np.abs(fastest))
    disp[1:] = (in_pos_abs.T @ np.abs(in_w)).reshape(-1, 2).T
    speed[1:] = (in_vel_abs.T @ np.abs(in_w)).reshape(-1, 2).T


def quiet_from(sleep_speed, max_ticks, out_log_r, in_log_r, speed):
    """Numpy twin of kernels.quiet_from (the same bisection on the same bounds)."""
    r_out, r_in = min(float(out_log_r.max()), 0.0), min(float(in_log_r.max()), 0.0)

    def loud(n):
        scaled = speed * np.array([[math.exp(n * r_out)], [math.exp(n * r_in)], [math.exp(n * r_in)]])
        return bool((np.einsum("ij,ij->j", scaled, scaled) >= sleep_speed * sleep_speed).any())

    lo, hi = 0, 1
    while loud(hi):
        if hi >= max_ticks:
            return max_ticks
        lo, hi = hi, min(2 * hi, max_ticks)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if loud(mid) else (lo, mid)
    return hi
