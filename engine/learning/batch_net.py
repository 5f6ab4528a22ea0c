"""The cloth net of the batched tables (engine.learning.batch): the ticks the engine steps
without the net, compiled, and the net's own steps, in Python, where the ball comes near it.

engine.physics.world._advance_with_cloth steps the ball alone (the tick kernel) out of the net's
reach (model.cloth_reach) and, while the net sleeps or rings in its linear tail (quiet), out of
the watched box (model.cloth_watch); nearer, it steps runs of ticks (_run_near_net) in which the
quiet net does nothing at a tick whose ball is far from the net's box (NetSim.step_run,
ball_far_from_box). advance_cloth does all of these here, in that order, and the net owes the
ticks it did not see (NET_OWED: NetSim.step_free takes them in one run when the ball next comes
near; a net never met again in its episode is never stepped, and a net that would blow up in
those ticks raises when they are stepped, or not at all). Anything else (an awake net near
the ball, a quiet one the ball may touch) stops the table for Python: step_net hands the
table's state to its match's, lets its NetSim take the ticks it owes, and steps the rest of the
call with the engine's own advance(). Splitting a call there is Match.tick's own contract: any
chunking of its ticks gives the same match; and as a call of the batch is at most FRAME_EVERY
ticks (engine.learning.env), fewer than NET_RUN_TICKS, a run of _advance_with_cloth ends where
the call does, here as there, so the environment's rewards sample the ball at the same ticks.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from engine.physics.tick import STOP_LIMIT, STOP_WATCH, advance_ticks, ball_inside
from engine.physics.world import NET_RUN_TICKS, advance
from engine.play.match import _GONE_RADIUS_2, _GONE_Z, OUT_OF_PLAY_DISTANCE

# A table's net as the compiled call sees it (TableBatch.net_ints' columns): the ticks its NetSim
# owes; 1 while it sleeps or rings in its linear tail, as of its last step in Python (ticks
# without the ball keep it so: a tail runs on or falls asleep). TableBatch.net_box: its box then
# (NetSim.box, lo xyz, hi xyz), which holds its knots from then on while it is quiet.
NET_OWED, NET_QUIET = 0, 1
# advance_cloth's outcomes
ADVANCED, FAILED, NEAR_NET = 0, 1, 2


@njit(inline="always")
def table_kernel(table, n_max, deadline, watch, physics):
    """engine.physics.tick.advance_ticks on a batch table's rows (engine.learning.batch.run_tables'
    `table`): (ticks, events, STOP_* reason, error)."""
    w, ball, bats, _, bat_motion, bat_tmp, work, scratch, event_rows = table[:9]
    h, bat_mass, bat_inertia, method, gravity, drag_k, magnus_k, rtol, atol, surface, floor_z, rigid_net, posts, \
        params, materials = physics
    return advance_ticks(n_max, h, w, bats, bat_mass, bat_inertia, bat_motion, bat_tmp, ball[0:9], method, gravity,
                         drag_k, magnus_k, rtol, atol, surface, floor_z, rigid_net, posts, params, materials, work,
                         scratch, w[0]['ball_adapt'], event_rows, _GONE_RADIUS_2, _GONE_Z, deadline, watch)


@njit(inline="always")
def _far(box, reach, dt, ball):
    """net_kernel.sim.ball_far_from_box of a quiet net's box (lo xyz, hi xyz): reach is the ball's
    radius plus a knot's, dt the net's tick (s), ball the flat state at the tick's start."""
    for i in range(3):
        start = ball[i]
        end = start + ball[3 + i] * dt
        if min(start, end) > box[3 + i] + reach or max(start, end) < box[i] - reach:
            return True
    return False


@njit(cache=True, _nrt=False)
def advance_cloth(table, reach, watch, net, box, n_max, deadline, contact, dt, physics):
    """Up to n_max ticks of a cloth-net table (reach, watch: model.cloth_reach and cloth_watch;
    net, box: its NET_* row and its box; contact: the ball's radius plus a knot's, m; dt: the
    net's tick, s) as _advance_with_cloth steps them, while the net has nothing to do.

    Returns (ADVANCED, the last tick's events, 0) after the ticks, an event or another STOP_*
    reason, or the end of a run near the net (where _advance_with_cloth returns); (NEAR_NET,
    ticks left, 0) where Python must go on (step_net); (FAILED, 0, the kernel's error)."""
    ball = table[1]
    done = 0
    while done < n_max:
        if not ball_inside(reach, ball):
            near = reach
        elif net[NET_QUIET] == 0:
            return NEAR_NET, n_max - done, 0
        elif not ball_inside(watch, ball):
            near = watch
        else:  # a run near a quiet net (_run_near_net), ending where the ball leaves its reach
            for _ in range(min(n_max - done, NET_RUN_TICKS)):
                if ball_inside(watch, ball) and not _far(box, contact, dt, ball):
                    return NEAR_NET, n_max - done, 0  # it may touch the net: NetSim.step's
                _, n, reason, error = table_kernel(table, 1, deadline, None, physics)
                if error != 0:
                    return FAILED, 0, error
                net[NET_OWED] += 1
                done += 1
                if reason != STOP_LIMIT or not ball_inside(reach, ball):
                    return ADVANCED, n, 0
            return ADVANCED, 0, 0
        ticks, n, reason, error = table_kernel(table, n_max - done, deadline, near, physics)
        if error != 0:
            return FAILED, 0, error
        net[NET_OWED] += ticks
        done += ticks
        if reason != STOP_WATCH:
            return ADVANCED, n, 0
    return ADVANCED, 0, 0


def step_net(match, world: np.ndarray, ball: np.ndarray, bats: np.ndarray, bat_motion: np.ndarray,
             event_rows: np.ndarray, net_row: np.ndarray, box: np.ndarray, ticks: int, deadline: float) -> int:
    """A table's ticks near its cloth net in Python: its match's state takes the table's rows
    (world (1,) record, ball, bats, bat_motion), its NetSim the ticks it owes, then
    engine.physics.world.advance steps `ticks` ticks as Match.tick would from here, and the rows
    take the state back, the last tick's contacts into event_rows (what the referee reads), the
    net's quiet flag and box into net_row and box. Returns the contacts."""
    state = match.state
    state.world[0] = world[0]
    state.ball_flat[:] = ball
    state.bat_flat[:] = bats
    state.bat_motion[:] = bat_motion
    net = state.net_sim
    if net_row[NET_OWED]:
        net.step_free(int(net_row[NET_OWED]))
        net_row[NET_OWED] = 0
    _, n, _ = advance(match.model, state, ticks, None, match.events, gone_radius=OUT_OF_PLAY_DISTANCE, gone_z=_GONE_Z,
                      deadline=deadline)
    world[0] = state.world[0]
    ball[:] = state.ball_flat
    bats[:] = state.bat_flat
    bat_motion[:] = state.bat_motion
    events = match.events
    for e in range(n):  # engine.physics.world._copy_events' columns
        event_rows[e, 0], event_rows[e, 1], event_rows[e, 2:5] = events[e]["time"], events[e]["body"], events[e]["pos"]
    mirror_net(net, net_row, box)
    return n


def mirror_net(net, net_row: np.ndarray, box: np.ndarray) -> None:
    """A NetSim's quiet flag and box into a table's NET_* row and box (advance_cloth reads them)."""
    net_row[NET_QUIET] = net.sleeping or net.in_tail
    box[0:3], box[3:6] = net.box[0], net.box[1]
