"""N tables' environment steps in one numba call: the batched step of engine.learning.vector_env.

A table is one engine.learning.env.PingPongEnv (version 1, `hold` actions, either net). Its
episode begins as the environment's does (PingPongEnv.begin_episode: the draws, the match, the
ball machine's ball, in Python); then TableBatch.load copies what the batch reads and writes
into its arrays, and from there the batch plays it: a drive's lead-in, then each control period
of a step, in one compiled call over all the tables (run_tables), doing what PingPongEnv.reset's
lead-in and PingPongEnv.step do in Python, in the same order and arithmetic:

- at each control tick (engine.play.match.Match.tick): the plans decided a decision delay before
  take effect, the arm law turns the plans in effect into the bats' forces
  (engine.play.arm.control_bats), the agent's action becomes its plan (in a lead-in the stand-in,
  the opponent's profile, plays the agent's bat), and a seat played by an AI profile decides when
  its gate is open (engine.play.players.gate_open: its decision key changed or its wakes came);
- the physics to the next control tick, a frame boundary or the first tick that needs the
  referee (engine.physics.tick.advance_ticks), the referee's judgement of each contact, the ball
  out of play, the next rally's toss (engine.play.judge); with the cloth net, the ticks in which
  the net has nothing to do (below);
- a lead-in ends when the opponent drove (the reset's observation), or, if the match ended
  first, is played again in the env's next match (PingPongEnv.next_match);
- a step's rewards (PingPongEnv.play_period's, sparse and dense), the end of the episode, and
  the observation in the agent's frame (engine.learning.agent_frame.observe).

An AI profile's decision is Python (its BatAI thinks a stroke out): the compiled call stops a
table whose seat must decide, the batch calls that table's engine.play.players.Seat on the state
there, and the next call goes on from it. The opponent's decisions that need no Python (the
ball changed hands without a stroke for it to think out, its plan ran out) are taken in the
compiled call on a mirror of its BatAI (_quiet_decision) and handed back before its next Python
decision (TableBatch._sync). The stand-in is asked only when its gate is open, where the
environment asks it at every control tick: BatAI.wakes promises that the decisions in between
change nothing. Between decisions the arm law is compiled like the rest.

The cloth net (engine.learning.batch_net): the ticks in which it has nothing to do (the ball
out of its reach, or a quiet net far from the ball) are the compiled call's, and the net owes
them; where it may touch the ball the compiled call stops the table and TableBatch._step_net,
in Python, steps its NetSim over the ticks it owes and then the ticks Match.tick would step
from there, with the engine's own code, on the table's state. A net never met again in the
episode is never stepped: its episode does not depend on it (a net that would blow up in those
ticks raises when they are stepped, or not at all). A table's episodes are
the single environment's bit for bit, and so is the net the ball meets
(tests/engine/test_vector_env.py).
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from engine.learning import agent_frame
from engine.learning.agent_frame import hold_plans, next_striker, observe_state
from engine.learning.batch_net import (ADVANCED, FAILED, NEAR_NET, NET_OWED, advance_cloth, mirror_net, step_net,
                                      table_kernel)
from engine.learning.env import APPROACH, FRAME_EVERY, NET_CLEAR, RETURN_LANDED, RETURN_STRIKE, PingPongEnv
from engine.physics.bat import FORCE_AT, TORQUE_AT
from engine.physics.collision import BAT_ROW, EVENT_ROW, MAX_IMPACTS_PER_TICK, P_RADIUS, SCRATCH_SHAPE
from engine.physics.dtypes import RALLY_DTYPE, WORLD_DTYPE
from engine.physics.integrators import WORK_SHAPE
from engine.play.arm import (ARM_TARGET, BAT_FLOATS, CTL_HOLD, CTL_KIND, CTL_N_SEGMENTS, CTL_SEGMENTS,
                             CTL_SIZE, control_bats)
from engine.play.judge import NO_POINT, ball_out_of_play, next_rally_and_toss, on_contact
from engine.play.match import _GONE_RADIUS_2, _GONE_Z
from engine.play.players import NO_KEY
from engine.play.rules import Phase

# A table's progress through a step or a lead-in (TableBatch.status); LEAD_OVER: the match ended
# before the lead-in's drive; NET: its ticks near the cloth net are Python's (TableBatch._step_net).
IDLE, START, STEPPING, WAITING, DONE, LEAD_OVER, NET = range(7)
# Integer bookkeeping of a step in progress (TableBatch.ints' columns), and the floats' (TableBatch.floats).
# I_LANDED + end: whether end's return landed in the step. I_WAIT: the seats that must decide (bit
# p: seat p). I_LEAD: 1 while the table plays a drive's lead-in.
I_STOP_AT, I_CTL_TICK, I_REQ_TICK, I_DECIDED, I_LANDED, I_SHOTS, I_PHASE, I_STRIKER, I_POINTS, I_WINNER = (
    0, 1, 2, 3, 4, 6, 7, 8, 9, 10)
I_WAIT, I_LEAD, I_KEY = 11, 12, 13  # I_KEY: the decision key (engine.play.players.decision_key) there, 4 ints
# I_EVENTS: the contacts of the ticks just advanced (in event_rows); I_NET_TICKS: the ticks the cloth
# net's Python is to advance; I_NET: 1 once it did (the compiled call then judges them).
I_EVENTS, I_NET_TICKS, I_NET = 17, 18, 19
N_INTS = 20
# The opponent's BatAI as the compiled call sees it (TableBatch.opp_ai's columns): its turn_key and
# planned_key (rally, shots; -1 for none), whether its plan is tracked, the decisions taken here,
# whether its plan ran out there; TableBatch.opp_floats': its turn_seen_at (s), its ready pose
# (hold m, face normal).
OPP_TURN, OPP_PLANNED, OPP_TRACKED, OPP_TAKEN, OPP_EXPIRED = 0, 2, 4, 5, 6
OPP_AI_SIZE = 7
OPP_SEEN, OPP_READY = 0, 1
OPP_FLOATS = 7
F_REWARD, F_POTENTIAL, F_BALL_X = 0, 2, 4
N_FLOATS = 5
_OVER = int(Phase.OVER)
_WAITING_SERVE = int(Phase.WAITING_SERVE)
_BOUNCED = int(Phase.BOUNCED)
_STRUCK = int(Phase.STRUCK)


@njit(cache=True, _nrt=False)
def _potential(bats, ball, r, end):
    """PingPongEnv._potentials for `end`: -APPROACH |bat - ball| while it is to strike next, else 0."""
    if next_striker(r) != end:
        return 0.0
    dx, dy, dz = bats[end, 0] - ball[0], bats[end, 1] - ball[1], bats[end, 2] - ball[2]
    return -APPROACH * math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(inline="always")
def _copy_plans(src, dst):
    """dst[:, :] = src, element by element: an array assignment may copy through a temporary,
    which a kernel compiled without the runtime (_nrt=False) cannot allocate."""
    for p in range(src.shape[0]):
        for i in range(src.shape[1]):
            dst[p, i] = src[p, i]


@njit(cache=True, _nrt=False)
def _gate_open(r, now, ctl_row, key, due, end):
    """engine.play.players.Seat.needs_decision of an AI profile's seat: key, due and end are the
    seat's gate (its decision key at its last decision, its wakes)."""
    if ctl_row[CTL_KIND] != ARM_TARGET:
        return True
    rally, shots, striker, serve = _decision_key(r)
    if key[0] != rally or key[1] != shots or key[2] != striker or key[3] != serve:
        return True
    return now >= due or now > end


@njit(cache=True, _nrt=False)
def _decision_key(r):
    """engine.play.players.decision_key of the record: (rally, shots, the player to strike next,
    whether that strike is a service)."""
    return r['rally'], r['shots'], next_striker(r), 1 if r['phase'] == _WAITING_SERVE else 0


@njit(cache=True, _nrt=False)
def observe_table(k, ball, bats, rally, player, axis, obs):
    """_observe of table k's state into obs[k]."""
    observe_state(ball[k], bats[k], rally[k], player, axis, obs[k])


@njit(cache=True, _nrt=False)
def _quiet_decision(r, now, ctl_row, key, due, end, opp, ai, floats):
    """Whether the opponent's decision, its gate open, needs no Python: the ball changed hands
    without a stroke for it to think out (BatAI.decide: turn_key and turn_seen_at), and/or its
    plan ran out with no stroke due (its arm back to the ready pose); if so it is taken here, into
    its ctl row and gate. ai (OPP_AI_SIZE ints) and floats (OPP_FLOATS) mirror its BatAI
    (TableBatch._mirror); TableBatch._sync hands what was taken here to the Python objects."""
    if ai[OPP_TRACKED] != 1 or ctl_row[CTL_KIND] != ARM_TARGET or now >= due[0]:
        return False
    rally, shots, striker, serve = _decision_key(r)
    if striker == opp and (ai[OPP_PLANNED] != rally or ai[OPP_PLANNED + 1] != shots):
        return False  # its turn, a stroke to think out: Python
    if ai[OPP_TURN] != rally or ai[OPP_TURN + 1] != shots:
        ai[OPP_TURN], ai[OPP_TURN + 1] = rally, shots
        floats[OPP_SEEN] = now
    if now > end[0]:  # BatAI._track(None, end_sign): the ready pose, no segments
        for i in range(6):
            ctl_row[CTL_HOLD + i] = floats[OPP_READY + i]
        ctl_row[CTL_N_SEGMENTS] = 0.0
        end[0] = math.inf
        ai[OPP_EXPIRED] = 1
    key[0], key[1], key[2], key[3] = rally, shots, striker, serve
    ai[OPP_TAKEN] += 1
    return True


@njit(cache=True, _nrt=False)
def _opponent_drove(r, opp):
    """PingPongEnv._opponent_drove: the opponent struck a return the agent must now play."""
    return r['shots'] >= 2 and r['striker'] == opp and (r['phase'] == _STRUCK or r['phase'] == _BOUNCED)


@njit(cache=True, _nrt=False)
def run_tables(status, ints, floats, world, ball, bats, rally, bat_motion, bat_tmp, work, scratch, event_rows,
               ctl, arm, inputs, players, pending, pending_tick, pending_at, plans, gate_key, gate_due, gate_end, opp_ai,
               opp_floats, net_ints, net_box,
               steps, rewards, terminated, truncated, obs, errors, axis, player, rally_task, dense, best_of, every,
               delay, max_seconds, max_rally_s, toss_speed, cloth, physics):
    """Go on with every table whose status is START or STEPPING (its step, or its lead-in while
    ints[k, I_LEAD] is set) until it is DONE, LEAD_OVER, its players must decide (WAITING) or its
    ball is near the cloth net (NET); returns how many wait for Python. The tables' arrays are
    TableBatch's; cloth: None for the rigid net, else the cloth net's model.cloth_reach and
    cloth_watch, the ball's radius plus a knot's (m) and the net's tick (s) (batch_net.advance_cloth);
    physics: the model's arrays and numbers that engine.physics.tick.advance_ticks reads."""
    waiting = 0
    for k in range(status.shape[0]):
        if status[k] != START and status[k] != STEPPING:
            continue
        # table k's rows, in the order _control_tick and _advance unpack them
        table = (world[k:k + 1], ball[k], bats[k], rally[k], bat_motion[k], bat_tmp[k], work[k], scratch[k],
                 event_rows[k], ctl[k], arm[k], inputs[k], pending[k], pending_tick[k], pending_at[k], gate_key[k],
                 gate_due[k], gate_end[k], opp_ai[k], opp_floats[k])
        if ints[k, I_LEAD] == 1:
            status[k] = _lead_table(ints[k], table, cloth, net_ints[k], net_box[k], players, plans[k], errors[k:k + 1],
                                    obs[k], axis, player, best_of, every, delay, max_rally_s, toss_speed, physics)
        else:
            status[k] = _step_table(status[k], ints[k], floats[k], table, cloth, net_ints[k], net_box[k], players,
                                    plans[k], steps[k:k + 1], rewards[k:k + 1], terminated[k:k + 1],
                                    truncated[k:k + 1], obs[k], errors[k:k + 1], axis, player, rally_task, dense,
                                    best_of, every, delay, max_seconds, max_rally_s, toss_speed, physics)
        if status[k] == WAITING or status[k] == NET:
            waiting += 1
    return waiting


@njit(cache=True, _nrt=False)
def _control_tick(si, table, players, plan, player, lead, delay):
    """engine.play.match.Match.tick at a control tick, up to its decisions (LocalAI.collect, the
    arm law); then the agent's action becomes its plan, unless the stand-in plays its bat in a
    lead-in; returns the seats whose gate is open (bit p: seat p), who must decide first."""
    w, ball, bats, r, _, _, _, _, _, ctl, arm, inputs, pending, pending_tick, pending_at, key, due, end, opp_ai, \
        opp_floats = table
    tick = w[0]['tick']
    n_pending = pending_at[1]
    if n_pending > 0 and pending_tick[pending_at[0]] == tick:
        _copy_plans(pending[pending_at[0]], arm)
        pending_at[0] = (pending_at[0] + 1) % pending.shape[0]
        pending_at[1] = n_pending - 1
    control_bats(w[0]['time'], bats, arm, players, inputs)
    si[I_CTL_TICK] = tick
    wait = 0
    if lead:
        if _gate_open(r, w[0]['time'], ctl[player], key[player], due[player], end[player]):
            wait |= 1 << player
    else:
        row = ctl[player]
        row[CTL_KIND] = ARM_TARGET
        for i in range(6):
            row[CTL_HOLD + i] = plan[i]
        row[CTL_N_SEGMENTS] = 0.0
        row[CTL_SEGMENTS:] = 0.0
    opp = 1 - player
    if _gate_open(r, w[0]['time'], ctl[opp], key[opp], due[opp], end[opp]) and not _quiet_decision(
            r, w[0]['time'], ctl[opp], key[opp], due[opp:opp + 1], end[opp:opp + 1], opp, opp_ai, opp_floats):
        wait |= 1 << opp
    if wait != 0:
        si[I_KEY], si[I_KEY + 1], si[I_KEY + 2], si[I_KEY + 3] = _decision_key(r)
    return wait


@njit(cache=True, _nrt=False)
def _advance(si, table, cloth, net, box, errors, n_max, every, delay, max_rally_s, physics):
    """The rest of Match.tick from where the decisions were taken, up to the referee: their plans
    wait `delay` ticks (LocalAI.request), the forces are applied, the physics runs up to n_max
    ticks (engine.physics.tick.advance_ticks); their contacts are left in event_rows (si[I_EVENTS]).
    With a cloth net (cloth: run_tables'; net, box: the table's rows) the ticks the net need not see
    (engine.learning.batch_net.advance_cloth). Returns ADVANCED, FAILED on a kernel error (in
    errors[0]), or NEAR_NET when the cloth net's Python must go on (si[I_NET_TICKS] ticks)."""
    w, bats, r, ctl, inputs, pending, pending_tick, pending_at = table[0], table[2], table[3], table[9], table[11], \
        table[12], table[13], table[14]
    tick = w[0]['tick']
    if tick % every == 0:
        if si[I_REQ_TICK] != tick:
            at = (pending_at[0] + pending_at[1]) % pending.shape[0]
            _copy_plans(ctl, pending[at])
            pending_tick[at] = tick + delay
            pending_at[1] += 1
            si[I_REQ_TICK] = tick
        for b in range(inputs.shape[0]):  # engine.physics.world._apply_inputs
            for i in range(3):
                bats[b, FORCE_AT + i] = inputs[b, i]
                bats[b, TORQUE_AT + i] = inputs[b, 3 + i]
    deadline = r['rally_started'] + max_rally_s
    if cloth is None:
        _, n, _, error = table_kernel(table, n_max, deadline, None, physics)
        got = ADVANCED if error == 0 else FAILED
    else:
        reach, watch, contact, dt = cloth
        got, n, error = advance_cloth(table, reach, watch, net, box, n_max, deadline, contact, dt, physics)
    if got == FAILED:
        errors[0] = error
    elif got == NEAR_NET:
        si[I_NET_TICKS] = n
    else:
        si[I_EVENTS] = n
    return got


@njit(cache=True, _nrt=False)
def _judge(si, table, best_of, max_rally_s, toss_speed):
    """Match.tick's referee after the ticks advanced: each contact judged, a ball out of play, the
    next rally tossed (engine.play.judge)."""
    w, ball, r, event_rows = table[0], table[1], table[3], table[8]
    point = NO_POINT
    for e in range(si[I_EVENTS]):
        won, _ = on_contact(r, int(event_rows[e, 1]), event_rows[e, 2], event_rows[e, 3], best_of)
        if won != NO_POINT:
            point = won
    if point == NO_POINT and r['phase'] != _OVER:
        x, y, z = ball[0], ball[1], ball[2]
        if x * x + y * y > _GONE_RADIUS_2 or z < _GONE_Z or w[0]['ball_support'] != 0 or \
                w[0]['time'] > r['rally_started'] + max_rally_s:
            point, _ = ball_out_of_play(r, x, y, best_of)
    if point != NO_POINT:
        si[I_WINNER] = point
        if r['winner'] < 0:
            next_rally_and_toss(r, ball, w[0], toss_speed)


@njit(cache=True, _nrt=False)
def _tick_call(si, table, cloth, net, box, players, plan, player, lead, errors, stop_at, every, delay, max_rally_s,
               physics):
    """One call of Match.tick from the table's tick up to its referee, ending by stop_at: the
    control tick's decisions if one is due (_control_tick), then the ticks to the next control
    tick, frame boundary or stop_at (_advance). Returns STEPPING when they were advanced (the
    referee's next), else the table's status: WAITING (its seats must decide), NET (the cloth
    net's Python is next) or DONE (a kernel error)."""
    tick = table[0][0]['tick']
    if tick % every == 0 and si[I_CTL_TICK] != tick:
        si[I_WAIT] = _control_tick(si, table, players, plan, player, lead, delay)
        if si[I_WAIT] != 0:
            return WAITING
    n_max = min(stop_at - tick, FRAME_EVERY - tick % FRAME_EVERY, every - tick % every)
    got = _advance(si, table, cloth, net, box, errors, n_max, every, delay, max_rally_s, physics)
    if got == FAILED:
        return DONE
    if got == NEAR_NET:
        return NET
    return STEPPING


@njit(cache=True, _nrt=False)
def _lead_table(si, table, cloth, net, box, players, plan, errors, obs, axis, player, best_of, every, delay,
                max_rally_s, toss_speed, physics):
    """A drive's lead-in from where it stands (PingPongEnv._lead_in: the stand-in, the opponent's
    profile, plays the agent's bat until the opponent drove), then the reset's observation;
    returns DONE, WAITING, NET, or LEAD_OVER when the match ended first (the episode's next match
    then leads in anew)."""
    w, ball, bats, r = table[0], table[1], table[2], table[3]
    while True:
        if si[I_NET] == 1:  # the ticks near the net, advanced in Python: judged from here on
            si[I_NET] = 0
        else:
            if _opponent_drove(r, 1 - player):
                break
            if r['winner'] >= 0:
                return LEAD_OVER
            got = _tick_call(si, table, cloth, net, box, players, plan, player, True, errors, w[0]['tick'] + every,
                             every, delay, max_rally_s, physics)
            if got != STEPPING:
                return got
        _judge(si, table, best_of, max_rally_s, toss_speed)
    si[I_LEAD] = 0
    observe_state(ball, bats, r, player, axis, obs)
    return DONE


@njit(cache=True, _nrt=False)
def _step_table(status, si, sf, table, cloth, net, box, players, plan, steps, rewards, terminated, truncated, obs,
                errors, axis, player, rally_task, dense, best_of, every, delay, max_seconds, max_rally_s, toss_speed,
                physics):
    """One table's step from where it stands (PingPongEnv.step and play_period); its new status."""
    w, ball, bats, r = table[0], table[1], table[2], table[3]
    if status == START:
        si[I_STOP_AT] = w[0]['tick'] + every
        si[I_DECIDED] = si[I_LANDED] = si[I_LANDED + 1] = 0
        si[I_POINTS] = r['points_total']
        si[I_SHOTS], si[I_PHASE], si[I_STRIKER] = r['shots'], r['phase'], r['striker']
        sf[F_REWARD] = sf[F_REWARD + 1] = 0.0
        if dense:
            sf[F_POTENTIAL] = _potential(bats, ball, r, 0)
            sf[F_POTENTIAL + 1] = _potential(bats, ball, r, 1)
        sf[F_BALL_X] = ball[0]
    landed_now = False
    while True:
        if si[I_NET] == 1:  # the ticks near the net, advanced in Python: judged from here on
            si[I_NET] = 0
        else:
            if w[0]['tick'] >= si[I_STOP_AT] or si[I_DECIDED] != 0:
                break
            got = _tick_call(si, table, cloth, net, box, players, plan, player, False, errors, si[I_STOP_AT],
                             every, delay, max_rally_s, physics)
            if got != STEPPING:
                return got
        _judge(si, table, best_of, max_rally_s, toss_speed)
        # PingPongEnv.play_period's rewards
        striker = r['striker']
        if r['shots'] > si[I_SHOTS]:
            sf[F_REWARD + striker] += RETURN_STRIKE
        if dense:
            x = ball[0]
            if r['shots'] > 0 and ((x > 0.0 >= sf[F_BALL_X]) if striker == 0 else (x < 0.0 <= sf[F_BALL_X])):
                sf[F_REWARD + striker] += NET_CLEAR
            sf[F_BALL_X] = x
        if r['points_total'] > si[I_POINTS]:
            si[I_DECIDED] = 1
            winner = si[I_WINNER]
            if (rally_task or dense) and winner >= 0:
                sf[F_REWARD + winner] += 1.0
                sf[F_REWARD + 1 - winner] -= 1.0
        elif r['phase'] == _BOUNCED and not (si[I_PHASE] == _BOUNCED and si[I_STRIKER] == striker):
            sf[F_REWARD + striker] += RETURN_LANDED
            si[I_LANDED + striker] = 1
            if not rally_task and striker == player:
                landed_now = True
                break
        si[I_SHOTS], si[I_PHASE], si[I_STRIKER] = r['shots'], r['phase'], striker
    if dense and si[I_DECIDED] == 0:
        for end in range(2):
            sf[F_REWARD + end] += _potential(bats, ball, r, end) - sf[F_POTENTIAL + end]
    done = si[I_DECIDED] == 1 or (not rally_task and (landed_now or si[I_LANDED + player] == 1))
    steps[0] += 1
    rewards[0] = sf[F_REWARD + player]
    terminated[0] = done
    truncated[0] = not done and steps[0] * every * physics[0] >= max_seconds
    observe_state(ball, bats, r, player, axis, obs)
    return DONE


class TableBatch:
    """The arrays of N tables' steps (one row a table) and the calls that step them.

    Args:
        envs: the tables' PingPongEnv (version 1, hold actions, one net, task, opponent,
            player, reward and max_seconds); a table is loaded (load) after its env began an
            episode (PingPongEnv.begin_episode).
    """

    def __init__(self, envs: list[PingPongEnv]):
        first = envs[0]
        n = len(envs)
        self.envs = envs
        self.status = np.full(n, IDLE, np.int64)
        self.ints = np.zeros((n, N_INTS), np.int64)
        self.floats = np.zeros((n, N_FLOATS))
        self.world = np.zeros(n, WORLD_DTYPE)
        self.ball = np.zeros((n, 9))
        self.bats = np.zeros((n, 2, BAT_FLOATS))
        self.rally = np.zeros(n, RALLY_DTYPE)
        self.bat_motion = np.zeros((n, 2, BAT_ROW))
        self.bat_tmp = np.zeros((n, 3, 3))
        self.work = np.zeros((n,) + WORK_SHAPE)
        self.scratch = np.zeros((n,) + SCRATCH_SHAPE)
        self.event_rows = np.zeros((n, MAX_IMPACTS_PER_TICK, EVENT_ROW))
        self.ctl = np.zeros((n, 2, CTL_SIZE))
        self.arm = np.zeros((n, 2, CTL_SIZE))
        self.inputs = np.zeros((n, 2, 6))
        self.players = np.array([0, 1], np.int64)
        self.plans = np.zeros((n, 6))
        # each seat's decision gate (engine.play.players.Players.gates): its key at its last decision, its wakes
        self.gate_key = np.zeros((n, 2, 4), np.int64)
        self.gate_due = np.zeros((n, 2))
        self.gate_end = np.zeros((n, 2))
        self.opp_ai = np.zeros((n, OPP_AI_SIZE), np.int64)  # the opponent's BatAI, mirrored (_mirror)
        self.opp_floats = np.zeros((n, OPP_FLOATS))
        self.net_ints = np.zeros((n, 2), np.int64)  # with a cloth net: its NET_* row and box (batch_net)
        self.net_box = np.zeros((n, 6))
        self.steps = np.zeros(n, np.int64)
        self.rewards = np.zeros(n)
        self.terminated = np.zeros(n, np.bool_)
        self.truncated = np.zeros(n, np.bool_)
        self.obs = np.zeros((n, len(agent_frame.OBSERVATION_NAMES)))
        self.errors = np.zeros(n, np.int64)
        self.axis = np.zeros((3, 3))
        self.axis[2, 0] = 1.0  # the bat's local x axis, rotated into the world's by _observe
        self.pending = self.pending_tick = self.pending_at = None  # shaped by the first match loaded
        self.player, self.opp = first.player, 1 - first.player
        self.rally_task, self.dense = first.task == "rally", first.reward == "dense"
        self.max_seconds = first.max_seconds
        self._scalars = None
        # wall seconds in the compiled call, in the AI profiles' decisions and in the cloth net's
        # ticks near the ball (bench.env reports them)
        self.seconds = {"compiled": 0.0, "decisions": 0.0, "net": 0.0}

    def _shape_from(self, env: PingPongEnv) -> None:
        """The arrays and numbers that depend on the match: its decision delay and model."""
        match = env.match
        n = len(self.envs)
        slots = match.delay // match.ai_every + 2  # decisions in flight: one a control tick of the delay
        self.pending = np.zeros((n, slots, 2, CTL_SIZE))
        self.pending_tick = np.zeros((n, slots), np.int64)
        self.pending_at = np.zeros((n, 2), np.int64)  # the oldest's slot, how many
        model = match.model
        physics = (float(model.dt), model.bat_mass, model.bat_inertia, model.method, model.gravity, model.drag_k,
                   model.magnus_k, model.scene.rtol, model.scene.atol, model.table, model.floor_z, model.net,
                   model.posts, model.ball_params, model.materials)
        net, cloth = match.state.net_sim, None
        if net is not None:  # NetSim.step_run's ball_far: its radius, a knot's and no margin (quiet)
            cloth = (model.cloth_reach, model.cloth_watch, float(model.ball_params[P_RADIUS]) + net.knot_radius + 0.0,
                     net.dt)
        self._scalars = (int(self.player), self.rally_task, self.dense, int(match.scene.match.best_of),
                         int(match.ai_every), int(match.delay), float(self.max_seconds),
                         float(match.scene.match.max_rally_s), float(match.scene.match.toss_speed), cloth, physics)

    def load(self, k: int, lead_in: bool) -> None:
        """Table k's match as its env left it (PingPongEnv.begin_episode or next_match) into the
        batch's rows; lead_in: its drive's lead-in is still to be played (lead_in())."""
        env = self.envs[k]
        match = env.match
        if self.pending is None:
            self._shape_from(env)
        state = match.state
        self.world[k] = state.world[0]
        self.ball[k] = state.ball_flat
        self.bats[k] = state.bat_flat
        self.rally[k] = state.record[0]["rally"]
        self.bat_motion[k] = state.bat_motion
        self.arm[k] = match.arm
        self.ctl[k] = match.ais.ctl
        self.inputs[k] = match.inputs
        pending = match.ai_driver.pending
        if len(pending) > self.pending.shape[1]:
            raise RuntimeError(f"table {k}: {len(pending)} decisions in flight, the batch keeps {self.pending.shape[1]}")
        self.pending_at[k] = (0, len(pending))
        for slot, (tick, plans, _) in enumerate(pending):
            self.pending[k, slot], self.pending_tick[k, slot] = plans, tick
        for player in (0, 1):
            self._gate(k, player)
        self._mirror(k)
        self.ints[k, I_CTL_TICK] = self.ints[k, I_REQ_TICK] = -1
        self.ints[k, I_LEAD] = int(lead_in)
        self.ints[k, I_NET] = self.net_ints[k, NET_OWED] = 0
        if state.net_sim is not None:
            mirror_net(state.net_sim, self.net_ints[k], self.net_box[k])
        self.steps[k] = 0
        self.errors[k] = 0
        self.status[k] = IDLE

    def _gate(self, k: int, player: int) -> None:
        """Seat `player`'s gate into table k's rows: its key at its last decision and its wakes
        (the agent's seat: its stand-in's while one plays it)."""
        seat = self.envs[k].match.ais[player]
        self.gate_key[k, player] = NO_KEY if seat.key is None else seat.key
        stand_in = seat.bot.stand_in if player == self.player else None
        self.gate_due[k, player], self.gate_end[k, player] = seat.wakes() if stand_in is None else stand_in.wakes()

    def _mirror(self, k: int) -> None:
        """The opponent's BatAI into table k's opp_ai and opp_floats, which the compiled call reads to
        take the decisions that need no Python (_quiet_decision), and writes."""
        seat = self.envs[k].match.ais[self.opp]
        ai, row = seat.bot.ai, self.opp_ai[k]
        row[OPP_TURN:OPP_TURN + 2] = (-1, -1) if ai.turn_key is None else ai.turn_key
        row[OPP_PLANNED:OPP_PLANNED + 2] = (-1, -1) if ai.planned_key is None else ai.planned_key
        row[OPP_TRACKED] = ai.plan is ai._tracking[0] and seat.bot.end_sign == ai._tracking[1]
        row[OPP_TAKEN] = row[OPP_EXPIRED] = 0
        floats = self.opp_floats[k]
        floats[OPP_SEEN] = ai.turn_seen_at
        pos, normal = ai.ready_pose(seat.bot.end_sign)
        floats[OPP_READY:OPP_READY + 3], floats[OPP_READY + 3:OPP_READY + 6] = pos, normal

    def _sync(self, k: int) -> None:
        """Hand the opponent's decisions the compiled call took (_quiet_decision) to its Seat and BatAI."""
        taken = int(self.opp_ai[k, OPP_TAKEN])
        if taken == 0:
            return
        seat = self.envs[k].match.ais[self.opp]
        ai = seat.bot.ai
        rally, shots = self.opp_ai[k, OPP_TURN:OPP_TURN + 2].tolist()
        if rally >= 0:
            ai.turn_key, ai.turn_seen_at = (rally, shots), float(self.opp_floats[k, OPP_SEEN])
        if self.opp_ai[k, OPP_EXPIRED]:
            ai.plan = None
            ai._track(None, seat.bot.end_sign)
            seat.ctl[:] = self.ctl[k, self.opp]
        seat.key = tuple(self.gate_key[k, self.opp].tolist())
        seat.decisions += taken
        self.opp_ai[k, OPP_TAKEN] = self.opp_ai[k, OPP_EXPIRED] = 0

    def lead_in(self, mask: np.ndarray) -> None:
        """Play the lead-in of the loaded tables of `mask` whose load said so (PingPongEnv.reset's
        lead-in, each in the match its env made next when one ended first); obs then holds every
        such table's reset observation, and their envs' episode_info is the episode's."""
        leading = mask & (self.ints[:, I_LEAD] == 1)
        if leading.any():
            self._play(np.where(leading, START, IDLE))

    def step(self, actions: np.ndarray, mask: np.ndarray, lead: np.ndarray | None = None) -> None:
        """One step of the tables of `mask` with the checked actions (N, 6) in [-1, 1], and the
        lead-ins of the tables of `lead` (loaded with lead_in): rewards, terminated, truncated
        and obs then hold the steps' results, obs the lead-ins' reset observations."""
        hold_plans(actions, self.player, self.plans)
        start = mask if lead is None else mask | (lead & (self.ints[:, I_LEAD] == 1))
        self._play(np.where(start, START, IDLE))

    def _play(self, status: np.ndarray) -> None:
        """Run the tables from `status` to their end: the players' decisions where they wait, the
        cloth net's ticks where the ball is near it, the next match where a lead-in's match ended."""
        self.status[:] = status
        seconds = self.seconds
        while True:
            started = time.perf_counter()
            waiting = self._run()
            decided = time.perf_counter()
            seconds["compiled"] += decided - started
            over = np.flatnonzero(self.status == LEAD_OVER)
            if not waiting and not len(over):
                break
            for k in np.flatnonzero(self.status == WAITING):
                self._decide(k)
                self.status[k] = STEPPING
            seconds["decisions"] += time.perf_counter() - decided
            near = np.flatnonzero(self.status == NET)
            if len(near):
                netted = time.perf_counter()
                for k in near:
                    self._step_net(k)
                    self.status[k] = STEPPING
                seconds["net"] += time.perf_counter() - netted
            for k in over:
                self.envs[k].next_match()
                self.load(k, True)
                self.status[k] = START
        if self.errors.any():
            k = int(np.flatnonzero(self.errors)[0])
            raise RuntimeError(f"table {k}: the tick kernel failed with code {int(self.errors[k])} at tick "
                               f"{int(self.world[k]['tick'])}")

    def _run(self) -> int:
        return run_tables(self.status, self.ints, self.floats, self.world, self.ball, self.bats, self.rally,
                          self.bat_motion, self.bat_tmp, self.work, self.scratch, self.event_rows, self.ctl, self.arm,
                          self.inputs, self.players, self.pending, self.pending_tick, self.pending_at, self.plans,
                          self.gate_key, self.gate_due, self.gate_end, self.opp_ai, self.opp_floats, self.net_ints,
                          self.net_box, self.steps, self.rewards, self.terminated, self.truncated, self.obs, self.errors,
                          self.axis, *self._scalars)

    def _decide(self, k: int) -> None:
        """The seats of table k that must decide do, in seat order, on the state there
        (engine.play.players.Players.decide; the compiled call left the control tick and the
        decision key in the table's ints)."""
        seats = self.envs[k].match.ais
        ints = self.ints[k].tolist()
        tick, wait, key = ints[I_CTL_TICK], ints[I_WAIT], tuple(ints[I_KEY:I_KEY + 4])
        now, ball, bats, rally = float(self.world[k]["time"]), self.ball[k], self.bats[k], self.rally[k]
        for player in (0, 1):
            if not wait >> player & 1:
                continue
            if player == self.opp:
                self._sync(k)
            fault = seats[player].decide(tick, now, ball, bats, rally, key)
            if fault is not None:
                raise RuntimeError(f"table {k}: the decision of seat {player} failed: {fault}")
            self.ctl[k, player] = seats.ctl[player]
            self._gate(k, player)
            if player == self.opp:
                self._mirror(k)

    def _step_net(self, k: int) -> None:
        """Table k's ticks near its cloth net, in Python (batch_net.step_net); the compiled call then
        judges them."""
        match, ints = self.envs[k].match, self.ints[k]
        deadline = float(self.rally[k]["rally_started"]) + match.scene.match.max_rally_s
        ints[I_EVENTS] = step_net(match, self.world[k:k + 1], self.ball[k], self.bats[k], self.bat_motion[k],
                                  self.event_rows[k], self.net_ints[k], self.net_box[k], int(ints[I_NET_TICKS]),
                                  deadline)
        ints[I_NET] = 1

    def observe(self, k: int) -> np.ndarray:
        """Table k's observation of the state loaded or reached (agent_frame.observe, compiled), in obs[k]."""
        observe_table(k, self.ball, self.bats, self.rally, self.player, self.axis, self.obs)
        return self.obs[k]
