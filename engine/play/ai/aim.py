"""The inverse problems of a stroke: the launch velocity to an aim point, the bat face and velocity giving it."""
from __future__ import annotations

import math

from numba import njit

from engine.physics.collision import P_INERTIA, P_MASS, P_RADIUS
from engine.physics.contact import impact
from engine.physics.integrators import advance


@njit(cache=True, _nrt=False)
def _crossing(p, v, spin, x_plane, h, max_steps, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt,
              cur, nxt, out):
    """Fly the ball from (p, v, spin) through everything until x crosses x_plane; `out` is the state
    there, linearly interpolated between ticks. False if it never crosses within max_steps."""
    for i in range(3):
        cur[i], cur[3 + i], cur[6 + i] = p[i], v[i], spin[i]
    side = cur[0] - x_plane
    for _ in range(max_steps):
        advance(cur, h, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, nxt)
        if (nxt[0] - x_plane) * side <= 0.0:
            f = (x_plane - cur[0]) / (nxt[0] - cur[0])
            for i in range(9):
                out[i] = cur[i] + f * (nxt[i] - cur[i])
            return True
        for i in range(9):
            cur[i] = nxt[i]
    return False


@njit(cache=True, _nrt=False)
def shoot(p, spin, target_x, target_y, pace, radius, h, max_steps, method, gravity, drag_k, magnus_k, rtol,
          atol, work, adapt, scratch, v):
    """Launch velocity from p whose free flight reaches (target_x, target_y) at table height.

    Newton iteration on (v_y, v_z) with the horizontal pace fixed, from the drag-free ballistic
    guess, finite-difference Jacobian (1e-4 m/s), steps clipped to 3 m/s; converged when the
    miss is under 1 mm. The residual is taken where the flight crosses x = target_x, which is
    smooth in the launch velocity (the first contact, net or table or floor, is not).

    Args:
        p, spin: (3,) launch point m, spin rad/s. pace: m/s along x. radius: m, the ball's.
        h: s, flight step. scratch: (4, 9). v: (3,) written with the solution.

    Returns:
        True when converged.
    """
    g = 0.0
    if gravity is not None:
        g = gravity
    direction = 1.0 if target_x > p[0] else -1.0
    flight = abs(target_x - p[0]) / pace
    v[0] = direction * pace
    v[1] = (target_y - p[1]) / flight
    v[2] = (radius - p[2]) / flight + 0.5 * g * flight
    cur, nxt, out = scratch[0], scratch[1], scratch[2]
    trial = scratch[3, 0:3]
    for _ in range(12):
        if not _crossing(p, v, spin, target_x, h, max_steps, method, gravity, drag_k, magnus_k, rtol, atol,
                         work, adapt, cur, nxt, out):
            return False
        ry, rz = out[1] - target_y, out[2] - radius
        if math.sqrt(ry * ry + rz * rz) < 1e-3:
            return True
        jac_00 = jac_01 = jac_10 = jac_11 = 0.0  # the Jacobian's rows: d(ry), d(rz); columns: v_y, v_z
        for j in range(2):
            for i in range(3):
                trial[i] = v[i]
            trial[1 + j] += 1e-4
            if not _crossing(p, trial, spin, target_x, h, max_steps, method, gravity, drag_k, magnus_k, rtol,
                             atol, work, adapt, cur, nxt, out):
                return False
            d_ry = (out[1] - target_y - ry) / 1e-4
            d_rz = (out[2] - radius - rz) / 1e-4
            if j == 0:
                jac_00, jac_10 = d_ry, d_rz
            else:
                jac_01, jac_11 = d_ry, d_rz
        det = jac_00 * jac_11 - jac_01 * jac_10
        if det == 0.0:
            return False
        step_y = (-ry * jac_11 + rz * jac_01) / det
        step_z = (-rz * jac_00 + ry * jac_10) / det
        v[1] += min(max(step_y, -3.0), 3.0)
        v[2] += min(max(step_z, -3.0), 3.0)
    return False


@njit(cache=True, _nrt=False)
def stroke(v_in, spin_in, v_out, radius, mass, inertia, restitution, friction, normal, bat_vel, got_v, got_w):
    """Bat face normal and velocity whose impact (engine.physics.contact.impact) turns (v_in, spin_in) into v_out.

    Frictionless, the impulse is along the normal, so the normal is the direction of
    v_out - v_in and the bat speed along it follows from the restitution; friction then bends
    the result, which a fixed-point iteration on the requested change removes (at most 30
    rounds, stops when the outgoing velocity is within 1e-4 m/s).

    Args:
        v_in, spin_in: (3,) m/s, rad/s, the ball before. v_out: (3,) m/s, wanted after.
        radius, mass, inertia: the ball's. restitution, friction: the bat's rubber.
        normal, bat_vel: (3,) written: unit face normal, bat velocity m/s.
        got_v, got_w: (3,) written: the ball's velocity and spin after that impact.
    """
    w0, w1, w2 = v_out[0] - v_in[0], v_out[1] - v_in[1], v_out[2] - v_in[2]
    for _ in range(30):
        delta = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        normal[0], normal[1], normal[2] = w0 / delta, w1 / delta, w2 / delta
        speed_n = v_in[0] * normal[0] + v_in[1] * normal[1] + v_in[2] * normal[2] + delta / (1.0 + restitution)
        for i in range(3):
            bat_vel[i] = speed_n * normal[i]
        impact(v_in, spin_in, normal, bat_vel, radius, mass, inertia, restitution, friction, got_v, got_w)
        e0, e1, e2 = v_out[0] - got_v[0], v_out[1] - got_v[1], v_out[2] - got_v[2]
        if math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) < 1e-4:
            return
        w0, w1, w2 = w0 + e0, w1 + e1, w2 + e2


@njit(cache=True, _nrt=False)
def shot_and_stroke(p, v_in, spin_in, target_x, target_y, pace, params, restitution, friction, h, max_steps,
                    method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, scratch, spin_out, shot, normal,
                    bat_vel, got_v):
    """One round of a stroke's solution: `shoot` with the stroke's spin spin_out (zero in the
    first round), then `stroke` for that shot, which writes the new spin_out.

    Args:
        p, v_in, spin_in: (3,) the ball where it is struck, m, m/s, rad/s. target_x, target_y, pace:
            as shoot's. params: the ball's (radius, mass, inertia first). restitution, friction:
            the bat's rubber. h, max_steps ... scratch: as shoot's (adapt is reset first).
        spin_out: (3,) rad/s, read, then written with the spin the stroke gives.
        shot, normal, bat_vel, got_v: (3,) written: launch velocity, face normal, bat velocity,
            the ball's velocity after that impact.

    Returns:
        False if the shot did not converge (nothing after shot is written then).
    """
    for i in range(adapt.shape[0]):
        adapt[i] = 0.0
    if not shoot(p, spin_out, target_x, target_y, pace, params[P_RADIUS], h, max_steps, method, gravity, drag_k,
                 magnus_k, rtol, atol, work, adapt, scratch, shot):
        return False
    stroke(v_in, spin_in, shot, params[P_RADIUS], params[P_MASS], params[P_INERTIA], restitution, friction, normal,
           bat_vel, got_v, spin_out)
    return True
