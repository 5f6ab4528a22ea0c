"""The stroke search: a stroke's candidate aims and paces, each solved and judged, in one compiled call.

BatAI._think draws the stroke's aims (its chosen aim and the safer ones, off by the aim noise,
then the safe ones exactly) and its paces; search_strokes tries them in that order, every pace of
an aim before the next aim, and stops at the first candidate whose stroke lands well:
- its solution: shot_and_stroke twice (the stroke's spin changes the flight, so the shot is
  solved again with it);
- its judgement (lands_well): the real path clears the net and bounces where it must (a
  return on the opponent's court; a service on the server's court, then the opponent's), told
  from the free flight to the next contact where that is sure (free_flight_verdict), else from
  the path predicted at the engine's tick (the prediction predict_flight makes).
The arithmetic is that of the Python it replaced, operation for operation; tests/engine/test_ai.py
checks the judgement against a numpy reference on the whole predicted path. Compiled without
numba's runtime: it allocates nothing, the caller's scratch is its memory.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.physics import equipment
from engine.physics.collision import E_BODY, E_POS, ERR_SUBSTEPS
from engine.physics.geometry import Body
from engine.play.ai.aim import shot_and_stroke
from engine.play.ai.predict import (_M_EVENTS, _M_SUPPORT, _M_WATCH, HALF_LENGTH, HALF_WIDTH, STOP_CONTACT,
                                    STOP_EVENTS, _span, free_flight_marks)

PASS, MISS, UNSURE = 1, 0, -1  # free_flight_verdict
NOT_FOUND = -1  # search_strokes: no candidate of the range lands well
_TABLE = int(Body.TABLE)
_NET_HEIGHT = equipment.NET_HEIGHT


@njit(cache=True, _nrt=False)
def on_court(x, y, sign, margin):
    """(x, y) on the court of end `sign`, at least `margin` m inside its end and side lines."""
    return np.sign(x) == sign and abs(x) < HALF_LENGTH - margin and abs(y) < HALF_WIDTH - margin


@njit(cache=True, _nrt=False, error_model="numpy")
def net_clearance(traj, n, radius):
    """Height of the ball's bottom above the net's top where rows 0..n of a path first cross
    x = 0 (m, -inf if they never do)."""
    for k in range(n):
        if np.sign(traj[k, 0]) != np.sign(traj[k + 1, 0]):
            f = traj[k, 0] / (traj[k, 0] - traj[k + 1, 0])
            z = traj[k, 2] + f * (traj[k + 1, 2] - traj[k, 2])
            return z - radius - _NET_HEIGHT
    return -math.inf


@njit(cache=True, _nrt=False)
def judge_path(traj, n, events, n_ev, end_sign, serve, radius, court_margin, clearance):
    """Whether a predicted path (rows 0..n, its first n_ev contacts) lands well: a return's first
    contact a bounce on the opponent's court, a service's first two on the server's court, then
    the opponent's; over the net by more than `clearance` m."""
    if n_ev < 1 or int(events[0, E_BODY]) != _TABLE:
        return False
    if not serve:
        return (on_court(events[0, E_POS], events[0, E_POS + 1], -end_sign, court_margin)
                and net_clearance(traj, n, radius) > clearance)
    if n_ev < 2 or int(events[1, E_BODY]) != _TABLE:
        return False
    return (on_court(events[0, E_POS], events[0, E_POS + 1], end_sign, court_margin)
            and on_court(events[1, E_POS], events[1, E_POS + 1], -end_sign, court_margin)
            and net_clearance(traj, n, radius) > clearance)


@njit(cache=True, _nrt=False)
def free_flight_verdict(y, court_sign, clearance, max_ticks, radius, court_margin, tolerance, flight, has_table,
                        work, adapt, scratch):
    """PASS, MISS or UNSURE: whether a ball in flight at y (9,), over the striker's court, passes
    the net with the clearance and bounces next on the court of court_sign within max_ticks,
    told from its free flight (no table, net or floor) at the engine's tick. Up to its next
    contact that is the real path (the two differ only where a tick is split at a contact, by the
    integrator's error), so a verdict more than `tolerance` from every limit is the one the
    predicted path gets. PASS also needs the ball above table height from the start (it then
    touches nothing before it comes down through table height, over the court, past a net and
    posts it clears) and a table to bounce on.

    flight: (h, method, gravity, drag_k, magnus_k, rtol, atol). work, adapt: the integrator's
    scratch (adapt is reset); scratch: (3, 9).
    """
    h, method, gravity, drag_k, magnus_k, rtol, atol = flight
    for i in range(adapt.shape[0]):
        adapt[i] = 0.0
    out = scratch[2, 0:3]
    # A pass of the net's plane this far below the clearance is a MISS wherever the ball comes
    # down: the flight stops there (1 nm more, so round-off cannot make it a pass below).
    low_z = radius + _NET_HEIGHT + clearance - tolerance - 1e-9
    free_flight_marks(y[0:3], y[3:6], y[6:9], radius, h, max_ticks, method, gravity, drag_k, magnus_k, rtol, atol,
                      work, adapt, scratch[0], scratch[1], out, low_z)
    above_net = out[0] - radius - _NET_HEIGHT - clearance
    if above_net < -tolerance:
        return MISS
    if math.isnan(out[1]) or y[2] <= radius:
        return UNSURE
    if not on_court(out[1], out[2], court_sign, court_margin - tolerance):
        return MISS
    if above_net > tolerance and on_court(out[1], out[2], court_sign, court_margin + tolerance) and has_table:
        return PASS
    return UNSURE


@njit(cache=True, _nrt=False)
def _predict(t0, e0, n_max, max_events, stop_rule, model, scratch):
    """predict_flight into scratch's path from its row t0 (holding the start; its events so far
    e0): as BatAI._predict, which resumes a prediction exactly as if it had not stopped when
    t0 > 0. Returns (rows, events, ERR_SUBSTEPS or 0) counted from the start."""
    h, method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts, params, materials = model
    work, ball_scratch, adapt, tick_events, traj, events, event_ticks, memo, acc = scratch[:9]
    if t0 == 0:
        for i in range(adapt.shape[0]):
            adapt[i] = 0.0
    for i in range(memo.shape[0]):
        memo[i] = 0
    for i in range(4):
        memo[_M_WATCH + i] = -1
    n, err, _ = _span(h, 0, n_max - t0, n_max - t0, max_events - e0, stop_rule, 0, 0, method, gravity, drag_k,
                      magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work, ball_scratch, adapt,
                      tick_events, traj[t0:], events[e0:], event_ticks[e0:], memo, acc)
    n_ev = memo[_M_EVENTS]
    for i in range(e0, e0 + n_ev):
        event_ticks[i] += t0
    # Only the integrator's substep limit fails a prediction; a path that ends at another of the
    # tick's errors is judged as far as it goes (as BatAI._predict does).
    return t0 + n, e0 + n_ev, err if err == ERR_SUBSTEPS else 0


@njit(cache=True, _nrt=False)
def lands_well(p, v, spin, end_sign, serve, limits, model, scratch):
    """The real path of a struck ball (p, v, spin: (3,)) clears the net and bounces where it
    must; (verdict, ERR_SUBSTEPS if a prediction hit the integrator's substep limit, else 0).

    limits: (radius, court_margin, net_margin, service_net_margin, tolerance, path_ticks,
    has_table), path_ticks the ticks of 2 s. scratch: search_strokes's.
    """
    radius, court_margin, net_margin, service_net_margin, tolerance, path_ticks, has_table = limits
    traj, events, free = scratch[4], scratch[5], scratch[9:12]
    flight = model[:7]
    y = traj[0]
    for i in range(3):
        y[i], y[3 + i], y[6 + i] = p[i], v[i], spin[i]
    if not serve:
        verdict = free_flight_verdict(y, -end_sign, net_margin, path_ticks, radius, court_margin, tolerance, flight,
                                      has_table, free[0], free[1], free[2])
        if verdict != UNSURE:
            return verdict == PASS, 0
        n, n_ev, err = _predict(0, 0, min(path_ticks, traj.shape[0] - 1), 1, STOP_EVENTS, model, scratch)
        return judge_path(traj, n, events, n_ev, end_sign, False, radius, court_margin, net_margin), err
    # A service: its path predicted to the tick of its first contact, which must be a bounce on
    # the server's court; from there it flies free to the next contact, so free_flight_verdict
    # judges the rest, or the prediction goes on (exactly as if it had not stopped) to that
    # contact when the free flight is too near a limit to tell.
    n, n_ev, err = _predict(0, 0, path_ticks, 2, STOP_CONTACT, model, scratch)
    if err != 0:
        return False, err
    support = scratch[7][_M_SUPPORT]
    if not (n_ev == 1 and support == 0 and int(events[0, E_BODY]) == _TABLE
            and on_court(events[0, E_POS], events[0, E_POS + 1], end_sign, court_margin)):
        return judge_path(traj, n, events, n_ev, end_sign, True, radius, court_margin, service_net_margin), 0
    verdict = free_flight_verdict(traj[n], -end_sign, service_net_margin, path_ticks - n, radius, court_margin,
                                  tolerance, flight, has_table, free[0], free[1], free[2])
    if verdict != UNSURE:
        return verdict == PASS, 0
    n, n_ev, err = _predict(n, n_ev, path_ticks, 2, STOP_EVENTS, model, scratch)
    return judge_path(traj, n, events, n_ev, end_sign, True, radius, court_margin, service_net_margin), err


@njit(cache=True, _nrt=False)
def search_strokes(p, v_in, spin_in, aims, paces, c_from, c_to, serve, end_sign, aim_margin, limits, shooting, model,
                   scratch, spin_out, shot, normal, bat_vel, got_v):
    """Candidates c_from .. c_to - 1 of a stroke (candidate c: aim c // len(paces) of aims (K, 2),
    x and y m, at pace c % len(paces) of paces, m/s), in order, until one lands well.

    Args:
        p, v_in, spin_in: (3,) the ball where it is struck. serve: a service. end_sign: the
            striker's end (-1: x < 0). aim_margin: an aim this far inside the court (m; negative:
            outside) or more is tried, one off it is not (none of its strokes would land well).
        limits: lands_well's. shooting: (restitution, friction, h, steps) of shot_and_stroke.
        model: (h, method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts,
            params, materials) of the scene.
        scratch: (work, ball scratch, adapt, tick events, path, events, event ticks, memo (6,)
            int64, acc (3,), free work, free adapt, free scratch (3, 9), shoot scratch (4, 9)):
            BatAI's (the path's rows are overwritten: the incoming ball's must be copied first).
        spin_out, shot, normal, bat_vel, got_v: (3,) written as shot_and_stroke's; the found
            candidate's stroke is normal and bat_vel.

    Returns:
        (the first candidate that lands well or NOT_FOUND, the next candidate to try, ERR_SUBSTEPS
        if a prediction hit the integrator's substep limit (the search stops there), else 0).
    """
    restitution, friction, shoot_h, shoot_steps = shooting
    h, method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts, params, materials = model
    work, adapt, shoot_scratch = scratch[0], scratch[2], scratch[12]
    court = end_sign if serve else -end_sign  # where the aim is (a service's: its first bounce)
    n_paces = paces.shape[0]
    for c in range(c_from, c_to):
        a = c // n_paces
        if not on_court(aims[a, 0], aims[a, 1], court, aim_margin):
            continue
        for i in range(3):
            spin_out[i] = 0.0
        solved = True
        for _ in range(2):  # the stroke's spin changes the flight: solve again with it
            solved = shot_and_stroke(p, v_in, spin_in, aims[a, 0], aims[a, 1], paces[c % n_paces], params,
                                     restitution, friction, shoot_h, shoot_steps, method, gravity, drag_k, magnus_k,
                                     rtol, atol, work, adapt, shoot_scratch, spin_out, shot, normal, bat_vel, got_v)
            if not solved:
                break
        if not solved:
            continue
        good, err = lands_well(p, shot, spin_out, end_sign, serve, limits, model, scratch)
        if err != 0:
            return NOT_FOUND, c, err
        if good:
            return c, c + 1, 0
    return NOT_FOUND, c_to, 0


__all__ = ["ERR_SUBSTEPS", "MISS", "NOT_FOUND", "PASS", "UNSURE", "free_flight_verdict", "judge_path", "lands_well",
           "net_clearance", "on_court", "search_strokes"]
