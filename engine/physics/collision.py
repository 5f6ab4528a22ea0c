"""Continuous collision detection for the ball: one tick, every impact located inside it.

Conservative advancement (Mirtich, "Impulse-based dynamic simulation of rigid body systems",
PhD thesis, Berkeley 1996, ch. 4): the gap to every body is a signed distance, which changes no
faster than the relative speed bound V, so after measuring gap g at time tau nothing can be hit
before tau + g/V. The ball's position at tau is always the integrator's own step of length tau
from the state where the search started, so impacts are located on the trajectory the
integrator would follow, to CONTACT_TOL, and the step order survives an impact. After each
impact the rest of the tick is searched again (a ball may hit the table and then the bat in one
tick). Thin bodies cannot be tunnelled: the advance never exceeds the measured gap.
"""
import math

from numba import njit

from engine.physics.contact import impact, supported_advance
from engine.physics.forces import ball_accel
from engine.physics.geometry import Body, box_sdf, disc_sdf
from engine.physics.integrators import advance

CONTACT_TOL = 1e-6  # m: an impact is applied once the gap is below this
MAX_IMPACTS_PER_TICK = 16
_MAX_ADVANCE_ITERS = 200  # conservative advancement steps before the doubling fallback
_SUPPORT_NORMAL_Z = 0.999  # a contact this close to +z can become resting contact

# Row layout of a bat's motion over one tick, as the orchestrator fills it.
BAT_POS0, BAT_POS1, BAT_AXIS0, BAT_AXIS1, BAT_ANG_VEL, BAT_RADIUS, BAT_HALF_THICKNESS = 0, 3, 6, 9, 12, 15, 16
BAT_ROW = 17
# Ball parameters, as one small array.
P_RADIUS, P_MASS, P_INERTIA, P_REST_SPEED = range(4)
N_PARAMS = 4
# Event row layout (a float64 mirror of CONTACT_DTYPE, without the tick).
E_TIME, E_BODY, E_POS, E_NORMAL, E_VEL_IN, E_VEL_OUT, E_SPIN_IN, E_SPIN_OUT, E_SPEED = 0, 1, 2, 5, 8, 11, 14, 17, 20
EVENT_ROW = 21
SCRATCH_SHAPE = (8, 9)

# Body ids as plain ints: numba unifies them with loop-computed bat ids.
_TABLE, _FLOOR, _NET, _POST, _BAT_A = int(Body.TABLE), int(Body.FLOOR), int(Body.NET), int(Body.POST), int(Body.BAT_A)

# Error codes returned instead of an event count.
ERR_SUBSTEPS = -1
ERR_IMPACTS = -2
ERR_NONFINITE = -3


@njit(inline="always", cache=True, _nrt=False)
def _bit(body):
    return 1 << body


@njit(cache=True, _nrt=False)
def _gap(p, frac, table, floor_z, net, posts, bats, params, skip, normal, tmp):
    """Smallest gap (m) between the ball at p and any body not in the skip mask, and its body.

    frac: fraction of the tick elapsed, for the bats' interpolated poses. normal: (3,) written
    with the closest body's outward normal. tmp: (4, 9) scratch.
    """
    radius = params[P_RADIUS]
    best = math.inf
    body = 0
    n = tmp[0, 0:3]
    if table is not None and not skip & _bit(_TABLE):
        best, body = _closer(box_sdf(p, table, n) - radius, _TABLE, n, best, body, normal)
    if floor_z is not None and not skip & _bit(_FLOOR):
        n[0], n[1], n[2] = 0.0, 0.0, 1.0
        best, body = _closer(p[2] - floor_z - radius, _FLOOR, n, best, body, normal)
    if net is not None and not skip & _bit(_NET):
        best, body = _closer(box_sdf(p, net, n) - radius, _NET, n, best, body, normal)
    if posts is not None and not skip & _bit(_POST):
        for k in range(posts.shape[0]):
            best, body = _closer(box_sdf(p, posts[k], n) - radius, _POST, n, best, body, normal)
    if bats is not None:
        centre = tmp[1, 0:3]
        axis = tmp[2, 0:3]
        for b in range(bats.shape[0]):
            if skip & _bit(_BAT_A + b):
                continue
            _bat_pose(bats[b], frac, centre, axis)
            d = disc_sdf(p, centre, axis, bats[b, BAT_RADIUS], bats[b, BAT_HALF_THICKNESS], n) - radius
            best, body = _closer(d, _BAT_A + b, n, best, body, normal)
    return best, body


@njit(inline="always", cache=True, _nrt=False)
def _closer(gap, candidate, n, best, body, normal):
    """Keep the smaller gap: (gap, candidate) with its normal n, or the best so far."""
    if gap < best:
        normal[0], normal[1], normal[2] = n[0], n[1], n[2]
        return gap, candidate
    return best, body


@njit(inline="always", cache=True, _nrt=False)
def _bat_pose(row, frac, centre, axis):
    """Bat centre and face normal at a fraction of the tick: linear position, normalised lerp of the axis."""
    norm = 0.0
    for i in range(3):
        centre[i] = row[BAT_POS0 + i] + frac * (row[BAT_POS1 + i] - row[BAT_POS0 + i])
        axis[i] = row[BAT_AXIS0 + i] + frac * (row[BAT_AXIS1 + i] - row[BAT_AXIS0 + i])
        norm += axis[i] * axis[i]
    norm = math.sqrt(norm)
    for i in range(3):
        axis[i] /= norm


@njit(inline="always", cache=True, _nrt=False)
def _norm3(v):
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True, _nrt=False)
def _speed_bound(cur, t_left, h, gravity, drag_k, magnus_k, bats, params, acc):
    """Upper bound (m/s) on how fast any gap can shrink over the remaining t_left."""
    ball_accel(cur[3:6], cur[6:9], gravity, drag_k, magnus_k, acc)
    # Speed along the step stays below |v| + |a| t; doubled |a| covers drag and Magnus growing
    # with the speed within one tick, with a 1 % margin for round-off.
    v_ball = 1.01 * (_norm3(cur[3:6]) + 2.0 * _norm3(acc) * t_left) + 1e-9
    v_max = v_ball
    if bats is not None and h > 0.0:
        for b in range(bats.shape[0]):
            row = bats[b]
            reach = row[BAT_RADIUS] + params[P_RADIUS]
            lin = 0.0
            turn = 0.0
            for i in range(3):
                lin += (row[BAT_POS1 + i] - row[BAT_POS0 + i]) ** 2
                turn += (row[BAT_AXIS1 + i] - row[BAT_AXIS0 + i]) ** 2
            v_bat = math.sqrt(lin) / h + max(_norm3(row[BAT_ANG_VEL:BAT_ANG_VEL + 3]) * reach,
                                             1.1 * math.sqrt(turn) / h * reach)
            v_max = max(v_max, v_ball + v_bat)
    return v_max


@njit(cache=True, _nrt=False)
def _advance_state(cur, tau, support, surface_z, method, gravity, drag_k, magnus_k, rtol, atol,
                   params, friction, work, adapt, out):
    """The ball's state tau after cur: in flight by the integrator, on a support by the constraint."""
    if support != 0:
        supported_advance(cur, tau, surface_z, gravity, drag_k, magnus_k, params[P_RADIUS],
                          params[P_MASS], params[P_INERTIA], friction, work, out)
        return 1
    return advance(cur, tau, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, out)


@njit(cache=True, _nrt=False)
def _body_point_velocity(body, p, normal, frac, h, bats, params, centre, axis, out):
    """Velocity of the body's surface point under the ball, m/s (zero for static bodies)."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if bats is not None and body >= _BAT_A:
        row = bats[body - _BAT_A]
        _bat_pose(row, frac, centre, axis)
        r = params[P_RADIUS]
        # Lever arm from the bat centre to the contact point p - r n.
        lx = p[0] - r * normal[0] - centre[0]
        ly = p[1] - r * normal[1] - centre[1]
        lz = p[2] - r * normal[2] - centre[2]
        w = row[BAT_ANG_VEL:BAT_ANG_VEL + 3]
        out[0] = (row[BAT_POS1] - row[BAT_POS0]) / h + w[1] * lz - w[2] * ly
        out[1] = (row[BAT_POS1 + 1] - row[BAT_POS0 + 1]) / h + w[2] * lx - w[0] * lz
        out[2] = (row[BAT_POS1 + 2] - row[BAT_POS0 + 2]) / h + w[0] * ly - w[1] * lx


@njit(cache=True, _nrt=False)
def ball_tick(y, h, support, flight, geometry, bats, params, materials, work, scratch, adapt, events):
    """Advance the ball by one tick h, applying every impact inside it.

    Args:
        y: (9,) ball state pos m, vel m/s, spin rad/s; updated in place.
        h: tick, s. support: Body id the ball rests on at the start, 0 in flight.
        flight: the ball's model, (method, gravity, drag_k, magnus_k, rtol, atol) as
            engine.physics.integrators.advance (engine.physics.world.Model.flight).
        geometry: the static bodies, (table, floor_z, net, posts) (engine.physics.world.Model.geometry):
            table (6,) box or None, floor_z m or None, net (6,) box or None (rigid net), posts
            (n, 6) boxes or None. An absent body (None) is compiled out of the kernel; the
            records are unpacked here, because numba prunes a None only where it is an argument.
        bats: (n_bats, BAT_ROW) motion over the tick, or None.
        params: (N_PARAMS,) ball parameters, see P_*. materials: (n_body_ids, 2) restitution, friction.
        work: WORK_SHAPE scratch. scratch: SCRATCH_SHAPE scratch. adapt: dopri5 bookkeeping.
        events: (n, EVENT_ROW) written with the tick's impacts.

    Returns:
        (n_events or a negative ERR_* code, support at the end of the tick).
    """
    method, gravity, drag_k, magnus_k, rtol, atol = flight
    table, floor_z, net, posts = geometry
    cur = scratch[0]
    trial = scratch[1]
    normal = scratch[2, 0:3]
    body_vel = scratch[2, 3:6]
    acc = scratch[2, 6:9]
    tmp = scratch[3:7]
    for i in range(9):
        cur[i] = y[i]
    t_done = 0.0
    n_events = 0
    skip = 0
    surface_z = _surface_z(support, table, floor_z)
    for _ in range(MAX_IMPACTS_PER_TICK + 1):
        t_left = h - t_done
        if t_left <= 0.0:
            break
        if support != 0:
            # Leave the surface when lifted (Magnus) or rolled off the table's top.
            ball_accel_z = _lift_check(cur, gravity, drag_k, magnus_k, acc)
            off_table = support == _TABLE and _off_table(cur, table)
            if ball_accel_z > 0.0 or off_table:
                support = 0
        friction = materials[support, 1]
        mask = skip | _bit(support) if support != 0 else skip
        v_max = _speed_bound(cur, t_left, h, gravity, drag_k, magnus_k, bats, params, acc)
        # Conservative advancement from cur along the trajectory tau -> advance(cur, tau).
        tau = 0.0
        g, body = _gap(cur[0:3], t_done / h, table, floor_z, net, posts, bats, params, mask, normal, tmp)
        hit = False
        doubling = 0.0
        for it in range(_MAX_ADVANCE_ITERS + 64):
            if g <= CONTACT_TOL:
                hit = True
                break
            if it < _MAX_ADVANCE_ITERS:
                step = g / v_max
            else:
                # Grazing: advancement converges slowly; probe with doubling steps and bisect.
                doubling = g / v_max if doubling == 0.0 else 2.0 * doubling
                step = doubling
            if tau + step >= t_left:
                if it < _MAX_ADVANCE_ITERS:
                    break  # nothing can be reached before the tick ends
                step = t_left - tau
            tau_next = tau + step
            rc = _advance_state(cur, tau_next, support, surface_z, method, gravity, drag_k, magnus_k,
                                rtol, atol, params, friction, work, adapt, trial)
            if rc < 0:
                return ERR_SUBSTEPS, support
            g_next, body_next = _gap(trial[0:3], (t_done + tau_next) / h, table, floor_z, net, posts,
                                     bats, params, mask, normal, tmp)
            if g_next < 0.0 and it >= _MAX_ADVANCE_ITERS:
                tau, g, body = _bisect(cur, tau, g, body, tau_next, t_done, h, support, surface_z, method, gravity,
                                       drag_k, magnus_k, rtol, atol, table, floor_z, net, posts, bats,
                                       params, friction, mask, work, adapt, trial, normal, tmp)
                hit = True
                break
            tau, g, body = tau_next, g_next, body_next
            if tau >= t_left:
                break
        # Move to the time of impact, or to the end of the tick when nothing is hit.
        reach = tau if hit else t_left
        if reach > 0.0:
            rc = _advance_state(cur, reach, support, surface_z, method, gravity, drag_k, magnus_k,
                                rtol, atol, params, friction, work, adapt, trial)
            if rc < 0:
                return ERR_SUBSTEPS, support
            for i in range(9):
                cur[i] = trial[i]
        if not hit:
            t_done = h
            break
        if tau > 0.0:  # the normal at the impact point (at tau = 0 it is the one just measured)
            _gap(cur[0:3], (t_done + tau) / h, table, floor_z, net, posts, bats, params, mask, normal, tmp)
        t_done += tau
        frac = t_done / h
        _body_point_velocity(body, cur[0:3], normal, frac, h, bats, params, tmp[1, 0:3], tmp[2, 0:3], body_vel)
        v_n = 0.0
        for i in range(3):
            v_n += (cur[3 + i] - body_vel[i]) * normal[i]
        horizontal = normal[2] > _SUPPORT_NORMAL_Z and (body == _TABLE or body == _FLOOR)
        if v_n >= 0.0:
            # Touching but not approaching: rest on it if pressed into it, else let it go.
            if horizontal and v_n < params[P_REST_SPEED] and _lift_check(cur, gravity, drag_k, magnus_k, acc) <= 0.0:
                support = body
                surface_z = _surface_z(body, table, floor_z)
                cur[5] = 0.0
            skip |= _bit(body)
            continue
        restitution = materials[body, 0]
        if -v_n < params[P_REST_SPEED]:
            # Resting contact, not an impact: stop the approach, record no event (a ball lying
            # on a bat would otherwise log one event a tick).
            impact(cur[3:6], cur[6:9], normal, body_vel, params[P_RADIUS], params[P_MASS],
                   params[P_INERTIA], 0.0, materials[body, 1], cur[3:6], cur[6:9])
            if horizontal:
                support = body
                surface_z = _surface_z(body, table, floor_z)
                cur[2] = surface_z + params[P_RADIUS]
                cur[5] = 0.0
            skip |= _bit(body)
            continue
        if n_events >= events.shape[0] or n_events >= MAX_IMPACTS_PER_TICK:
            return ERR_IMPACTS, support
        ev = events[n_events]
        ev[E_TIME] = t_done
        ev[E_BODY] = body
        for i in range(3):
            ev[E_POS + i] = cur[i]
            ev[E_NORMAL + i] = normal[i]
            ev[E_VEL_IN + i] = cur[3 + i]
            ev[E_SPIN_IN + i] = cur[6 + i]
        speed = impact(cur[3:6], cur[6:9], normal, body_vel, params[P_RADIUS], params[P_MASS],
                       params[P_INERTIA], restitution, materials[body, 1], cur[3:6], cur[6:9])
        if horizontal and speed < params[P_REST_SPEED]:
            support = body
            surface_z = _surface_z(body, table, floor_z)
            cur[2] = surface_z + params[P_RADIUS]
            cur[5] = 0.0
        for i in range(3):
            ev[E_VEL_OUT + i] = cur[3 + i]
            ev[E_SPIN_OUT + i] = cur[6 + i]
        ev[E_SPEED] = speed
        n_events += 1
        skip |= _bit(body)
    _project_out(cur, h, table, floor_z, net, posts, bats, params, normal, body_vel, tmp)
    # Cheap invariant after the tick (pymunk's step check): the state stays finite. The index of
    # the first bad component goes to scratch[7, 0] so the caller can name the quantity.
    for i in range(9):
        if not math.isfinite(cur[i]):
            scratch[7, 0] = i
            return ERR_NONFINITE, support
    for i in range(9):
        y[i] = cur[i]
    return n_events, support


@njit(cache=True, _nrt=False)
def _project_out(cur, h, table, floor_z, net, posts, bats, params, normal, body_vel, tmp):
    """Position correction at the end of a tick (Box2D's non-penetration projection).

    A ball left inside a body (resting on a bat, squeezed, trapped) is moved out along the normal
    and loses the inward part of its velocity relative to that body, so contact never drifts
    inwards. Static bodies come first; a bat is projected out of only if that does not push the
    ball back into a static body: squeezed between a bat and the table or the net, the ball stays
    put and the bat yields (a player's grip gives way long before a table does).
    """
    # The supporting surface counts too: a resting ball sits at gap 0 and is left alone by it.
    _project_once(cur, h, table, floor_z, net, posts, None, params, 0, normal, body_vel, tmp)
    if bats is None:
        return
    saved = tmp[3]
    for i in range(6):
        saved[i] = cur[i]
    if _project_once(cur, h, None, None, None, None, bats, params, 0, normal, body_vel, tmp):
        g, _ = _gap(cur[0:3], 1.0, table, floor_z, net, posts, None, params, 0, normal, tmp)
        if g < -CONTACT_TOL:  # that would squeeze it into the table or the net: the bat yields
            for i in range(6):
                cur[i] = saved[i]


@njit(cache=True, _nrt=False)
def _project_once(cur, h, table, floor_z, net, posts, bats, params, mask, normal, body_vel, tmp):
    """Project the ball out of the deepest body not in `mask`; True if it moved."""
    g, body = _gap(cur[0:3], 1.0, table, floor_z, net, posts, bats, params, mask, normal, tmp)
    if body == 0 or g >= 0.0:
        return False
    for i in range(3):
        cur[i] -= g * normal[i]
    if h > 0.0 and bats is not None:
        _body_point_velocity(body, cur[0:3], normal, 1.0, h, bats, params, tmp[1, 0:3], tmp[2, 0:3], body_vel)
    else:
        body_vel[0] = body_vel[1] = body_vel[2] = 0.0
    v_n = 0.0
    for i in range(3):
        v_n += (cur[3 + i] - body_vel[i]) * normal[i]
    if v_n < 0.0:
        for i in range(3):
            cur[3 + i] -= v_n * normal[i]
    return True


@njit(cache=True, _nrt=False)  # not inlined: its None tests must see table and floor_z as arguments (ball_tick)
def _surface_z(body, table, floor_z):
    """Height of the horizontal surface a resting ball lies on, m."""
    if body == _FLOOR and floor_z is not None:
        return floor_z
    if body == _TABLE and table is not None:
        return table[2] + table[5]
    return 0.0


@njit(cache=True, _nrt=False)
def _off_table(cur, table):
    """The ball's centre beyond the table top's edges in x or y (False without a table)."""
    if table is None:
        return False
    return abs(cur[0] - table[0]) > table[3] or abs(cur[1] - table[1]) > table[4]


@njit(cache=True, _nrt=False)
def _lift_check(cur, gravity, drag_k, magnus_k, acc):
    """Vertical acceleration of the ball from the flight forces, m/s^2 (> 0 lifts it off)."""
    ball_accel(cur[3:6], cur[6:9], gravity, drag_k, magnus_k, acc)
    return acc[2]


@njit(cache=True, _nrt=False)
def _bisect(cur, tau_lo, g_lo, body_lo, tau_hi, t_done, h, support, surface_z, method, gravity, drag_k, magnus_k,
            rtol, atol, table, floor_z, net, posts, bats, params, friction, mask, work, adapt, trial,
            normal, tmp):
    """Bisect [tau_lo (gap > 0), tau_hi (gap < 0)] until the gap at tau_lo is within CONTACT_TOL."""
    g = g_lo
    body = body_lo
    for _ in range(80):
        mid = 0.5 * (tau_lo + tau_hi)
        _advance_state(cur, mid, support, surface_z, method, gravity, drag_k, magnus_k, rtol, atol,
                       params, friction, work, adapt, trial)
        g_mid, body_mid = _gap(trial[0:3], (t_done + mid) / h, table, floor_z, net, posts, bats,
                               params, mask, normal, tmp)
        if g_mid < 0.0:
            tau_hi = mid
        else:
            tau_lo, g, body = mid, g_mid, body_mid
            if g_mid <= CONTACT_TOL:
                break
    return tau_lo, g, body
