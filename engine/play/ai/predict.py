"""Flight prediction: the ball's path without bats as the physics steps it, the strike rules, free flights."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.physics import equipment
from engine.physics.collision import EVENT_ROW, E_BODY, E_POS, P_RADIUS, ball_tick
from engine.physics.forces import ball_accel
from engine.physics.geometry import Body, box_sdf
from engine.physics.integrators import advance

HALF_LENGTH = equipment.TABLE_LENGTH / 2
HALF_WIDTH = equipment.TABLE_WIDTH / 2

# What a prediction looks for besides the path itself (predict_flight's stop_rule).
STOP_EVENTS = 0  # nothing: run to n_max ticks, max_events events or the ball at rest
STOP_SERVE_STRIKE = 1  # the tick to strike a tossed ball for a service
STOP_RETURN_STRIKE = 2  # the tick to strike a ball after its bounce on this player's court
STOP_CONTACT = 3  # also at the end of the first tick with a contact
NO_STRIKE = -1  # the ball is not this player's to strike
_UNDECIDED = -2
# The strike rules (strike_index states them in numpy, as the reference).
_SERVE_LOW, _SERVE_HIGH = 0.08, 0.28  # m: a tossed ball is struck on the way down between these heights
_FALLING_Z = 0.05  # m: a ball below this height, falling, is back at table height
_DEEP_X = HALF_LENGTH + 0.5  # m: a ball this far from the net is struck wherever it is
_FAR_X = HALF_LENGTH - 0.6  # m: a ball nearer the net than this is waited for
_TABLE, _FLOOR = int(Body.TABLE), int(Body.FLOOR)
_W_BOUNCE, _W_FLOOR, _W_CANDIDATE, _W_LATER = 0, 1, 2, 3  # predict_flight's bookkeeping of a return


@njit(cache=True, _nrt=False)
def _strike_row(traj, k, stop_rule, watch):
    """Whether row k of a prediction (one with a successor) decides the strike.

    Returns the strike tick, NO_STRIKE, or _UNDECIDED; `watch` keeps the return's bookkeeping.
    """
    z, vz = traj[k, 2], traj[k, 5]
    if stop_rule == STOP_SERVE_STRIKE:
        if vz < 0.0 and _SERVE_LOW < z < _SERVE_HIGH:
            return k
        return _UNDECIDED
    if watch[_W_BOUNCE] < 0 or k < watch[_W_BOUNCE] + 2:
        return _UNDECIDED
    ax = abs(traj[k, 0])
    if watch[_W_LATER] < 0 and ax >= _FAR_X and z > _FALLING_Z:
        watch[_W_LATER] = k
    if watch[_W_CANDIDATE] < 0 and (vz <= 0.0 or ax > _DEEP_X or (z < _FALLING_Z and vz < 0.0)):
        watch[_W_CANDIDATE] = k
    c = watch[_W_CANDIDATE]
    if c >= 0:
        if abs(traj[c, 0]) >= _FAR_X:
            return c
        if watch[_W_LATER] >= 0:
            return watch[_W_LATER]
    return _UNDECIDED


@njit(cache=True, _nrt=False)
def _strike_end(traj, n, stop_rule, watch):
    """The strike once the prediction has ended at row n (the last row, without a successor)."""
    if stop_rule != STOP_RETURN_STRIKE or watch[_W_BOUNCE] < 0 or watch[_W_CANDIDATE] < 0:
        return NO_STRIKE
    if watch[_W_LATER] < 0 and n >= watch[_W_BOUNCE] + 2 and abs(traj[n, 0]) >= _FAR_X and traj[n, 2] > _FALLING_Z:
        watch[_W_LATER] = n
    return watch[_W_LATER] if watch[_W_LATER] >= 0 else watch[_W_CANDIDATE]


_FAST_MARGIN = 2e-3  # m: predict_span steps a tick as free flight only this far from every body (CONTACT_TOL is 1 um)


@njit(cache=True, _nrt=False)
def _static_gap(p, radius, table, floor_z, net, posts, normal):
    """Smallest gap (m) between the ball at p and the table, floor, net and posts (as
    engine.physics.collision's, without bats). normal: (3,) scratch."""
    best = math.inf
    if table is not None:
        best = min(best, box_sdf(p, table, normal) - radius)
    if floor_z is not None:
        best = min(best, p[2] - floor_z - radius)
    if net is not None:
        best = min(best, box_sdf(p, net, normal) - radius)
    if posts is not None:
        for k in range(posts.shape[0]):
            best = min(best, box_sdf(p, posts[k], normal) - radius)
    return best


# predict_span's memo: what a paused prediction keeps between calls.
_M_WATCH, _M_EVENTS, _M_SUPPORT = 0, 4, 5
MEMO_SIZE = 6
PAUSED = -3  # predict_span stopped at its chunk's end; call again to go on


@njit(cache=True)
def predict_span(h, k0, k_stop, n_max, max_events, stop_rule, end_sign, first_row, method, gravity, drag_k,
                 magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work, scratch, adapt,
                 tick_events, traj, events, event_ticks, memo):
    """predict_flight in pieces: steps the path from row k0 (traj[k0] holds the state) to row
    k_stop at most, and goes on exactly as if never stopped when called again from there.

    Far from every body a tick is the integrator's step alone (advance), which is what ball_tick
    computes there: the same bits as stepping every tick with ball_tick.

    first_row: strikes are looked for from this row on, and contacts before its tick are neither
        recorded nor counted (the path as a prediction started at that row sees it).
    memo: (MEMO_SIZE,) int64, kept between calls: the strike rule's bookkeeping (-1 to start),
        the events recorded (0 to start), the support (0 to start): see reset_memo.

    Returns:
        (rows done, error code of ball_tick or 0, strike tick or NO_STRIKE once decided, or PAUSED
        at k_stop before n_max).
    """
    return _span(h, k0, k_stop, n_max, max_events, stop_rule, end_sign, first_row, method, gravity, drag_k, magnus_k,
                 rtol, atol, table, floor_z, net, posts, params, materials, work, scratch, adapt, tick_events, traj,
                 events, event_ticks, memo, np.empty(3))


@njit(cache=True, _nrt=False)
def _span(h, k0, k_stop, n_max, max_events, stop_rule, end_sign, first_row, method, gravity, drag_k, magnus_k, rtol,
          atol, table, floor_z, net, posts, params, materials, work, scratch, adapt, tick_events, traj, events,
          event_ticks, memo, acc):
    """predict_span's steps, acc: (3,) scratch (allocated by predict_span: this kernel, compiled
    without numba's runtime, allocates nothing)."""
    watch = memo[_M_WATCH:_M_WATCH + 4]
    strike_rule = stop_rule == STOP_SERVE_STRIKE or stop_rule == STOP_RETURN_STRIKE
    room = _static_gap(traj[k0], params[P_RADIUS], table, floor_z, net, posts, acc)
    for k in range(k0, min(k_stop, n_max)):
        if strike_rule and k >= first_row:
            strike = _strike_row(traj, k, stop_rule, watch)
            if strike != _UNDECIDED:
                return k, 0, strike
        # Far from every body, ball_tick finds nothing to hit and its tick is advance(y, h) (its
        # conservative advancement stops at once: gap / speed bound >= h); here the gap is a lower
        # bound, the one measured after the last full tick less the reach of each tick since.
        y, v = traj[k], traj[k, 3:6]
        n = 0
        support = memo[_M_SUPPORT]
        fast = False
        if support == 0:
            ball_accel(v, traj[k, 6:9], gravity, drag_k, magnus_k, acc)
            reach = (1.01 * (math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                             + 2.0 * h * math.sqrt(acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2])) + 1e-9) * h
            if reach + _FAST_MARGIN < room:
                advance(y, h, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, traj[k + 1])
                fast = True
                for i in range(9):
                    fast = fast and math.isfinite(traj[k + 1, i])
                room -= reach
        if not fast:  # near a body (or not finite: ball_tick reports it)
            for i in range(9):
                traj[k + 1, i] = y[i]
            n, support = ball_tick(traj[k + 1], h, support, (method, gravity, drag_k, magnus_k, rtol, atol),
                                   (table, floor_z, net, posts), None, params, materials, work, scratch, adapt,
                                   tick_events)
            memo[_M_SUPPORT] = support
            if n < 0:
                return k + 1, n, _strike_end(traj, k + 1, stop_rule, watch)
            room = _static_gap(traj[k + 1], params[P_RADIUS], table, floor_z, net, posts, acc)
        n_events = memo[_M_EVENTS]
        for e in range(n if k >= first_row else 0):
            if n_events < max_events:
                for i in range(EVENT_ROW):
                    events[n_events, i] = tick_events[e, i]
                event_ticks[n_events] = k
                n_events += 1
                if stop_rule == STOP_RETURN_STRIKE and watch[_W_BOUNCE] < 0:
                    body, x = int(tick_events[e, E_BODY]), tick_events[e, E_POS]
                    if body == _TABLE and ((x > 0.0 and end_sign > 0) or (x < 0.0 and end_sign < 0)):
                        watch[_W_BOUNCE] = k
                    elif body == _FLOOR and watch[_W_FLOOR] < 0:
                        watch[_W_FLOOR] = k
        memo[_M_EVENTS] = n_events
        if stop_rule == STOP_RETURN_STRIKE and watch[_W_FLOOR] >= 0 and watch[_W_BOUNCE] < 0:
            return k + 1, 0, NO_STRIKE  # on the floor before any bounce on this court
        if n_events >= max_events or support != 0 or (stop_rule == STOP_CONTACT and n > 0 and k >= first_row):
            return k + 1, 0, _strike_end(traj, k + 1, stop_rule, watch)
    if k_stop < n_max:
        return k_stop, 0, PAUSED
    return n_max, 0, _strike_end(traj, n_max, stop_rule, watch)


@njit(cache=True)
def predict_flight(y0, h, n_max, max_events, stop_rule, end_sign, method, gravity, drag_k, magnus_k, rtol, atol,
                   table, floor_z, net, posts, params, materials, work, scratch, adapt, tick_events,
                   traj, events, event_ticks):
    """The ball's path without bats, tick by tick, exactly as the physics would step it.

    With a strike rule it also finds the tick at which the player of end_sign strikes the ball,
    and stops as soon as that is decided: the answer is the one strike_index gives on the
    whole path (up to n_max ticks, max_events events or the ball at rest), without stepping
    the rest of it.

    Args:
        y0: (9,) start state. h: tick, s. n_max: ticks at most. max_events: stop after this many.
        stop_rule: STOP_EVENTS, STOP_CONTACT, STOP_SERVE_STRIKE or STOP_RETURN_STRIKE.
        end_sign: -1 if the striking player's court is at x < 0 (strike rules only).
        method ... materials: as engine.physics.collision.ball_tick.
        work, scratch, adapt, tick_events: scratch for ball_tick.
        traj: (n_max + 1, 9) written: traj[k] is the state after k ticks.
        events: (max_events, EVENT_ROW) written. event_ticks: (max_events,) tick of each event.

    Returns:
        (ticks simulated, events recorded, error code of ball_tick or 0, strike tick or
        NO_STRIKE (always NO_STRIKE for STOP_EVENTS), support at the end). The path goes on
        exactly as if never stopped when called again from its last row with the same adapt
        and work, if that support is 0.
    """
    for i in range(9):
        traj[0, i] = y0[i]
    memo = np.zeros(MEMO_SIZE, np.int64)
    memo[_M_WATCH:_M_WATCH + 4] = -1
    n, err, strike = predict_span(h, 0, n_max, n_max, max_events, stop_rule, end_sign, 0, method, gravity, drag_k,
                                  magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work,
                                  scratch, adapt, tick_events, traj, events, event_ticks, memo)
    return n, memo[_M_EVENTS], err, strike, memo[_M_SUPPORT]


@njit(cache=True, _nrt=False)
def free_flight_marks(p, v, spin, radius, h, max_steps, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt,
                      cur, nxt, out, low_z=-math.inf):
    """Where a free flight (no table, net or floor) passes the net's plane and comes down to table height.

    Flies from (p, v, spin) in steps h until the ball's centre comes down through z = radius
    (its bottom at the playing surface) or max_steps, interpolating linearly between steps;
    stops at the net's plane if the centre passes it below low_z (m).

    Args:
        p, v, spin: (3,) m, m/s, rad/s. radius: m, the ball's. cur, nxt: (9,) scratch.
        out: (3,) written: z of the centre where x first crosses 0 before that (-inf if it does
            not), then x, y where it comes down (nan if it does not within max_steps, or it
            stopped at the net's plane).
    """
    for i in range(3):
        cur[i], cur[3 + i], cur[6 + i] = p[i], v[i], spin[i]
    out[0], out[1], out[2] = -math.inf, math.nan, math.nan
    crossed = False
    for _ in range(max_steps):
        advance(cur, h, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, nxt)
        if not crossed and cur[0] * nxt[0] <= 0.0 and cur[0] != nxt[0]:
            crossed = True
            f = cur[0] / (cur[0] - nxt[0])
            out[0] = cur[2] + f * (nxt[2] - cur[2])
            if out[0] < low_z:
                return
        if cur[2] > radius >= nxt[2]:
            f = (cur[2] - radius) / (cur[2] - nxt[2])
            out[1] = cur[0] + f * (nxt[0] - cur[0])
            out[2] = cur[1] + f * (nxt[1] - cur[1])
            return
        for i in range(9):
            cur[i] = nxt[i]


def reset_memo(memo: np.ndarray) -> np.ndarray:
    """memo: (MEMO_SIZE,) int64 set to start a prediction with predict_span; returned."""
    memo[:] = 0
    memo[_M_WATCH:_M_WATCH + 4] = -1
    return memo


def strike_index(traj: np.ndarray, events: list, end_sign: int, serve: bool) -> int | None:
    """Tick of a predicted path at which to strike, None if the ball is not ours to play.

    The strike rules in numpy, on a whole path (traj: (n, 9) states a tick apart; events as
    engine.play.ai.BatAI.predict lists them): the reference that predict_flight's strike rules (which
    stop the prediction as soon as the answer is known) are tested against.
    """
    z, x = traj[:, 2], traj[:, 0]
    if serve:
        # The tossed ball: strike it on the way down, 10-30 cm above the surface.
        falling = np.flatnonzero((traj[:-1, 5] < 0) & (z[:-1] < 0.28) & (z[:-1] > 0.08))
        return int(falling[0]) if len(falling) else None
    bounce = next((e for e in events if e[1] == Body.TABLE and np.sign(e[2][0]) == end_sign), None)
    if bounce is None:
        return None
    if any(e[1] in (Body.FLOOR,) and e[0] < bounce[0] for e in events):
        return None
    start = bounce[0] + 2
    if start >= len(traj) - 1:
        return None
    after = slice(start, len(traj) - 1)
    vz = traj[after, 5]
    apex = np.flatnonzero(vz <= 0)
    deep = np.flatnonzero(np.abs(x[after]) > HALF_LENGTH + 0.5)
    floor = np.flatnonzero((z[after] < 0.05) & (vz < 0))  # falling back to table height
    candidates = [a[0] for a in (apex, deep, floor) if len(a)]
    if not candidates:
        return None
    k = start + int(min(candidates))
    if abs(x[k]) < HALF_LENGTH - 0.6:  # not that far over the table: wait for it
        later = np.flatnonzero((np.abs(x[start:]) >= HALF_LENGTH - 0.6) & (z[start:] > 0.05))
        if len(later):
            k = start + int(later[0])
    return k
