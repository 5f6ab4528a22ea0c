"""The ball's contact with the knots (swept spheres, full or culled), and a grid net's tick with the ball near.

step_grid_ball and step_grid_tick live here, not in grid.py: they are the contact sweep's loop
over substeps, with one grid step between sweeps, so they depend on both and belong to the
layer above the grid.
"""
import math

import numpy as np
from numba import njit

from net_kernel.kernels.csr import knot_speed_max
from net_kernel.kernels.grid import FREE_AWAKE, FREE_NOT_FINITE, FREE_OUT_OF_REACH, in_reach, knot_checks, step_grid_serial
from net_kernel.kernels.grid32 import step_grid32_serial

NO_CONTACT = -1.0  # collide_ball's return when the ball touched no knot


# Ball contact: swept sphere against knot spheres (radius knot_radius), linear relative motion
# over the tick (Ericson, Real-Time Collision Detection, 2005, 4.4.2 / 5.5.7 "intersecting a
# moving sphere against a sphere").


@njit(inline="always", cache=True, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
def _ball_within(q0, q1, q2, s0, s1, s2, limit):
    """|q - s| <= limit (m): the ball's point q is within the cull's guarantee around its start s."""
    e0 = q0 - s0
    e1 = q1 - s1
    e2 = q2 - s2
    return e0 * e0 + e1 * e1 + e2 * e2 <= limit * limit


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, _nrt=False)
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


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
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
    return _ball_substeps(step_grid_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work,
                          ball, ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32_ball(knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32, ball, ball_radius,
                     ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    """step_grid_ball with the float32 grid step (kernels.grid32.step_grid32_serial) between the contact sweeps.

    The sweep runs on the float64 state as in step_grid_ball; each substep's grid step converts
    the state to float32 offsets and back (step_grid32). Args as step_grid_ball, net32 in place
    of grid_work (grid32_work's tuple).
    """
    return _ball_substeps(step_grid32_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, net32,
                          ball, ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)


@njit(inline="always")
def _ball_substeps(step, knot_state, knot_inv_mass, grid_params, gravity, drag, h, n_steps, grid_work, ball, ball_radius,
                   ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse):
    """step_grid_ball's substeps with `step` (a serial grid kernel of step_grid_serial's signature) as the grid step."""
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
        for c in range(3):
            bp[c] = ball[2, c]
        step(knot_state, knot_inv_mass, grid_params, gravity, drag, h, 1, grid_work)
    return toi


# step_grid_tick's ball rows: 0-3 as step_grid_ball's ball, 4 and 5 the ball's position and
# velocity at the tick's start (read only).
TICK_BALL_ROWS = 6


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid_tick(knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, grid_work, ball, ball_radius,
                   ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks,
                   sleep_speed, reach, box, out_impulse, out_offset):
    """A whole awake tick of a grid net with the ball near, as NetSim.step takes it, in one call.

    The substeps: `substeps` (the stability bound's), or more so that ball and knots close in
    by at most `travel` m in one, at the sum of the ball's and the fastest knot's speed taken up
    to `speed_max` (net_kernel.sim.contact_substeps' arithmetic); then step_grid_ball over
    dt / that many; the ball's offset from its free path where it touched; the knots' speed,
    their finiteness, the sleep count (a contact wakes the net: it starts again from 0; with
    the ball near the net never falls asleep), their box and its reach. The same bits as
    NetSim's calls to knot_speed_max, step_grid_ball and its checks one after the other.

    Args:
        knot_state, knot_inv_mass, grid_params, gravity, drag, grid_work: as step_grid.
        dt: s, the tick. substeps: the stability bound's steps per tick.
        ball: (TICK_BALL_ROWS, 3): rows 0-3 as step_grid_ball's (rows 0 and 1 set to the tick's
            start and advanced in place), rows 4, 5 the ball's position m and velocity m/s at
            the tick's start.
        ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near: as step_grid_ball.
        travel: m, the closing distance a substep may take at most. speed_max: m/s, the closing
            speed taken at most.
        quiet_ticks: ticks in a row so far with every knot slower than sleep_speed (m/s).
        reach: (2, 3) m, lo and hi corners no knot may pass.
        box: (2, 3) m, written: the knots' box after the tick.
        out_impulse: (3,) N s, written: the net's impulse on the ball.
        out_offset: (3,) m, written: the ball's end position minus its free path's (0 without contact).

    Returns:
        (time of impact as step_grid_ball's or NO_CONTACT, substeps taken, quiet_ticks after
        the tick, FREE_AWAKE, FREE_NOT_FINITE or FREE_OUT_OF_REACH).
    """
    return _tick(step_grid_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, grid_work, ball,
                 ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks,
                 sleep_speed, reach, box, out_impulse, out_offset)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32_tick(knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, net32, ball, ball_radius,
                     ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks,
                     sleep_speed, reach, box, out_impulse, out_offset):
    """step_grid_tick with step_grid32_ball's substeps (a float32 net). Args and returns as step_grid_tick,
    net32 in place of grid_work."""
    return _tick(step_grid32_serial, knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, net32, ball,
                 ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks,
                 sleep_speed, reach, box, out_impulse, out_offset)


@njit(inline="always")
def _tick(step, knot_state, knot_inv_mass, grid_params, gravity, drag, dt, substeps, grid_work, ball, ball_radius,
          ball_inv_mass, knot_radius, restitution, max_hits, near, travel, speed_max, quiet_ticks, sleep_speed, reach,
          box, out_impulse, out_offset):
    """step_grid_tick with `step` (a serial grid kernel of step_grid_serial's signature) as the grid step."""
    n = knot_state.shape[2] * knot_state.shape[3]
    knot_speed = knot_speed_max(knot_state[0].reshape(3, n).T, knot_state[1].reshape(3, n).T)
    p0 = ball[4]
    v0 = ball[5]
    closing = math.sqrt(v0[0] * v0[0] + v0[1] * v0[1] + v0[2] * v0[2]) + knot_speed
    taken = max(substeps, int(math.ceil((closing if closing < speed_max else speed_max) * dt / travel)))
    for c in range(3):
        ball[0, c] = p0[c]
        ball[1, c] = v0[c]
    toi = _ball_substeps(step, knot_state, knot_inv_mass, grid_params, gravity, drag, dt / taken, taken, grid_work,
                         ball, ball_radius, ball_inv_mass, knot_radius, restitution, max_hits, near, out_impulse)
    for c in range(3):
        out_offset[c] = 0.0 if toi == NO_CONTACT else ball[0, c] - p0[c] - v0[c] * dt
    if toi != NO_CONTACT:
        quiet_ticks = 0
    speed = knot_checks(knot_state, box)
    if speed == math.inf:
        return toi, taken, quiet_ticks, FREE_NOT_FINITE
    quiet_ticks = quiet_ticks + 1 if speed < sleep_speed else 0
    if not in_reach(box, reach):
        return toi, taken, quiet_ticks, FREE_OUT_OF_REACH
    return toi, taken, quiet_ticks, FREE_AWAKE
