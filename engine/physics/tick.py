"""The tick kernel: bats, then the ball, for as many ticks as nothing needs Python's attention.

`advance_ticks` runs up to n ticks in one numba call and stops right after the first tick at
which the orchestrator must act: a contact event (the referee judges it), the ball leaving the
playing area, its support changing (coming to rest, rolling off), or the time passing a
deadline (a rally's limit). Everything the orchestrator checks between ticks is checked here
at the same tick, so advancing in chunks gives the same bits as advancing one tick at a time.
The AI's control ticks are chunk boundaries chosen by the caller.
"""
from numba import njit

from engine.physics.bat import bat_step
from engine.physics.collision import ball_tick

STOP_LIMIT = 0  # ran the ticks asked for
STOP_EVENT = 1
STOP_GONE = 2
STOP_SUPPORT = 3
STOP_DEADLINE = 4
STOP_WATCH = 5
STOP_NET = 6  # engine.physics.world: the cloth net was stepped this tick (a point where net and ball agree)
# advance_ticks' own errors (engine.physics.collision's ERR_* are -1..-3): a bat record not finite
# before the run (nothing stepped), or become non-finite during it (engine.physics.bat.bat_step keeps
# finite records finite and inside the arm's limits; this catches a finite input so large that
# the arithmetic overflows).
ERR_BATS_BEFORE = -10
ERR_BATS_AFTER = -11


@njit(cache=True, _nrt=False)
def _all_finite(a):
    for x in a.flat:
        if x - x != 0.0:  # inf - inf and nan - nan are nan
            return False
    return True


@njit(cache=True, _nrt=False)
def advance_ticks(n_max, h, world, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat, method,
                  gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work,
                  scratch, adapt, event_rows, gone_r2, gone_z, deadline, watch):
    """Advance up to n_max ticks of length h; stop after the first tick that needs attention.

    Args:
        world: (1,) WORLD_DTYPE, updated per tick (tick, time, support, event counts).
        bat_flat, bat_motion: (n_bats, ...) or None together when the scene has no bats;
            bat_mass, bat_inertia, bat_tmp as engine.physics.bat.bat_step.
        ball_flat ... adapt: as engine.physics.collision.ball_tick. event_rows: (MAX_IMPACTS_PER_TICK,
            EVENT_ROW) written with the events of the tick that stopped the run, times absolute.
        gone_r2: m^2, stop once x^2 + y^2 of the ball exceeds it (inf: never).
        gone_z: m, stop once the ball's z is below it (-inf: never).
        deadline: s, stop once the world time exceeds it (inf: never).
        watch: (6,) box lo xyz, hi xyz: stop once the ball is inside it (a cloth net's
            neighbourhood, stepped tick by tick by the caller), or None.

    Returns:
        (ticks done, events in the last tick, STOP_* reason, error code of ball_tick, ERR_BATS_*
        or 0). On a ball_tick error the failing tick is not counted and the ball keeps its state
        from before it; on ERR_BATS_BEFORE nothing was stepped.
    """
    if bat_motion is not None and not _all_finite(bat_flat):
        return 0, 0, STOP_LIMIT, ERR_BATS_BEFORE
    ticks, n, reason, error = _advance(n_max, h, world, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat,
                                       method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts,
                                       params, materials, work, scratch, adapt, event_rows, gone_r2, gone_z,
                                       deadline, watch)
    if error == 0 and bat_motion is not None and not _all_finite(bat_flat):
        return ticks, n, reason, ERR_BATS_AFTER
    return ticks, n, reason, error


@njit(inline="always")
def _one_tick(h, w, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat, method, gravity, drag_k, magnus_k,
              rtol, atol, table, floor_z, net, posts, params, materials, work, scratch, adapt, event_rows):
    """One tick of the bats, then the ball; returns (events, or ball_tick's error code < 0, the
    ball's support before the tick, after it). The world record moves on only without an error."""
    if bat_motion is not None:
        bat_step(bat_flat, h, bat_mass, bat_inertia, bat_motion, bat_tmp)
    support_before = w['ball_support']
    n, support = ball_tick(ball_flat, h, support_before, (method, gravity, drag_k, magnus_k, rtol, atol),
                           (table, floor_z, net, posts), bat_motion, params, materials, work, scratch, adapt,
                           event_rows)
    if n < 0 or h == 0.0:
        return n, support_before, support
    for e in range(n):
        event_rows[e, 0] += w['time']  # event times become absolute, from this tick's exact start
    w['ball_support'] = support
    w['n_events'] = n
    w['events_total'] += n
    w['tick'] += 1
    w['time'] = w['time'] + h
    return n, support_before, support


@njit(inline="always")
def _stop_reason(n, support_before, support, w, ball_flat, gone_r2, gone_z, deadline):
    """The STOP_* reason after a tick that ran (STOP_LIMIT: nothing needs attention)."""
    if n > 0:
        return STOP_EVENT
    if ball_flat[0] * ball_flat[0] + ball_flat[1] * ball_flat[1] > gone_r2 or ball_flat[2] < gone_z:
        return STOP_GONE
    if support != support_before:
        return STOP_SUPPORT
    if w['time'] > deadline:
        return STOP_DEADLINE
    return STOP_LIMIT


@njit(inline="always")
def ball_inside(box, ball_flat):
    """Is the ball's centre inside the (6,) lo xyz, hi xyz box?"""
    return (box[0] <= ball_flat[0] <= box[3] and box[1] <= ball_flat[1] <= box[4]
            and box[2] <= ball_flat[2] <= box[5])


@njit(cache=True, _nrt=False)
def _advance(n_max, h, world, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat, method, gravity, drag_k,
             magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work, scratch, adapt, event_rows,
             gone_r2, gone_z, deadline, watch):
    """advance_ticks' loop, with its arguments and returns."""
    w = world[0]
    for k in range(n_max):
        n, support_before, support = _one_tick(h, w, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat,
                                               method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net,
                                               posts, params, materials, work, scratch, adapt, event_rows)
        if n < 0:
            return k, 0, STOP_LIMIT, n
        if h == 0.0:
            return 0, 0, STOP_LIMIT, 0  # a zero-length tick ran the kernels and changed nothing
        reason = _stop_reason(n, support_before, support, w, ball_flat, gone_r2, gone_z, deadline)
        if reason != STOP_LIMIT:
            return k + 1, n, reason, 0
        if watch is not None and ball_inside(watch, ball_flat):
            return k + 1, 0, STOP_WATCH, 0
    return n_max, 0, STOP_LIMIT, 0


@njit(cache=True, _nrt=False)
def advance_run(n_max, h, world, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat, method, gravity,
                drag_k, magnus_k, rtol, atol, table, floor_z, net, posts, params, materials, work, scratch, adapt,
                event_rows, gone_r2, gone_z, deadline, reach, record, run_ball, run_records):
    """advance_ticks for a run of ticks near a cloth net (engine.physics.world._run_near_net): the same
    ticks, keeping what the net's run and its undo need, up to the first tick that needs
    attention or ends with the ball outside `reach`.

    Args:
        n_max ... deadline: as advance_ticks (no watch box); at most as many ticks as run_ball
            and run_records have rows.
        reach: (6,) lo xyz, hi xyz: stop after a tick that leaves the ball's centre outside it.
        record: the state's whole record as bytes (uint8), of which world, bat_flat and ball_flat are views.
        run_ball: (>= n_max, 2, 3): the ball's position m and velocity m/s at each tick's start.
        run_records: (>= n_max, record's bytes) uint8: the record after each tick.

    Returns:
        As advance_ticks. An error at a tick after the first is no error: the state goes back to
        the record after the tick before it and the run ends there (that tick may never happen:
        the net may touch the ball first; if it does not, the next run steps that tick first and
        returns its error). An error at the first tick is returned as advance_ticks returns it.
    """
    if bat_motion is not None and not _all_finite(bat_flat):
        return 0, 0, STOP_LIMIT, ERR_BATS_BEFORE
    n_max = min(n_max, run_ball.shape[0], run_records.shape[0])  # no more ticks than there are rows to keep
    w = world[0]
    size = record.shape[0]
    for k in range(n_max):
        for i in range(3):
            run_ball[k, 0, i] = ball_flat[i]
            run_ball[k, 1, i] = ball_flat[3 + i]
        n, support_before, support = _one_tick(h, w, bat_flat, bat_mass, bat_inertia, bat_motion, bat_tmp, ball_flat,
                                               method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net,
                                               posts, params, materials, work, scratch, adapt, event_rows)
        error = n if n < 0 else 0
        if error == 0 and bat_motion is not None and not _all_finite(bat_flat):
            error = ERR_BATS_AFTER
        if error != 0:
            if k == 0:
                return (1 if error == ERR_BATS_AFTER else 0), 0, STOP_LIMIT, error
            for b in range(size):
                record[b] = run_records[k - 1, b]
            return k, 0, STOP_LIMIT, 0
        for b in range(size):
            run_records[k, b] = record[b]
        reason = _stop_reason(n, support_before, support, w, ball_flat, gone_r2, gone_z, deadline)
        if reason != STOP_LIMIT or not ball_inside(reach, ball_flat):
            return k + 1, n, reason, 0
    return n_max, 0, STOP_LIMIT, 0
