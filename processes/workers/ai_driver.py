"""The physics worker's side of each hand-off: to the AI worker (AIDriver, PlanFollower), to the
net worker (RemoteNet) and from the gateway (RemoteInputs).

Each is what the in-process engine calls (engine.match.Match's ai_driver, engine.world's
state.net_sim, the bats' inputs), done by another process through the run's shared records
(processes.workers.layout), so the physics steps the same bits as the reference.
"""
from __future__ import annotations

import math
import time
from collections import Counter

import numpy as np

from engine.ai import BAT_FLOATS, CTL_NORMAL, CTL_SIZE, control_bats
from engine.arm import brake_force
from engine.bot import FAULTS
from engine.dtypes import BAT_DTYPE
from engine.match import Match
from engine.world import copy_record
from net_kernel import NO_CONTACT, NetContact, NetSim
from net_kernel.sim import ball_far_from_box
from processes.network.wire import MAX_FORCE_N, MAX_TORQUE_NM
from processes.runtime.control import Control
from processes.runtime.locks import LockTable
from processes.runtime.mailbox import Mailbox
from processes.runtime.shm import Arena
from processes.workers.layout import REMOTE_INPUT_DTYPE, RUN_LOCK_NAMES, NetIO, decision_key, write_ack
from processes.workers.options import RunOptions

# A hand-off waits options.handoff_s, gives the turn again (a killed worker is being restarted)
# and waits again, for this long in all.
AI_GIVE_UP_S = 60.0
NET_GIVE_UP_S = 60.0


class PlanFollower:
    """The physics side: the AIs' forces at a control tick that needs no decision, from the
    ctl rows of their last answer (the same control_bats the AIs call, so the same bits).

    Args:
        scene: the match scene (its AI bats, in order, are the answer's ctl rows).
    """

    def __init__(self, scene):
        self.n_bats = len(scene.bats)
        self.players = np.array([i for i, bat in enumerate(scene.bats) if bat.skill is not None], np.int64)
        self.ctl = np.zeros((len(self.players), CTL_SIZE))
        self.key = None  # the decision key of the last answer taken; None: none yet
        self.due = self.end = -math.inf
        self._control_bats = control_bats
        # Load (or compile) control_bats for these array types (the AIs' own) before the run.
        bats = np.zeros(self.n_bats, BAT_DTYPE)
        bats["quat"] = (1.0, 0.0, 0.0, 0.0)
        ctl = self.ctl.copy()
        ctl[:, CTL_NORMAL] = 1.0
        control_bats(0.0, bats.view(np.float64).reshape(self.n_bats, BAT_FLOATS), ctl, self.players,
                     np.zeros((self.n_bats, 6)))

    def take(self, answer) -> None:
        """What the AIs' controllers track until their next decision, from an ANSWER_DTYPE record."""
        self.ctl[:] = answer["ctl"][:len(self.players)]
        self.key = tuple(int(v) for v in answer["key"])
        self.due, self.end = float(answer["due"]), float(answer["end"])

    def needs_decision(self, key, now: float) -> bool:
        """Whether BatAI.decide could change anything now (see BatAI.wakes): the key changed, or
        the clock reached a wake."""
        return key != self.key or now >= self.due or now > self.end

    def control(self, now: float, bat_floats: np.ndarray, out: np.ndarray) -> None:
        """bat_floats: (n_bats, BAT_FLOATS) float64 view of the bats; out: (n_bats, 6), written at the AI rows."""
        self._control_bats(now, bat_floats, self.ctl, self.players, out)


class AIDriver:
    """An ai_driver for engine.match.Match that asks the AI worker, which thinks while we step.

    request() at a control tick: if the AIs must decide (processes.workers.ai: the decision key
    changed since their last decision, or the clock reached its wakes), copy the state into the
    AI's view and give the AI worker its turn, at once; otherwise compute the forces here, as
    the AI would, with control_bats on the ctl rows of its last answer. collect() at the next
    control tick: wait (bounded) until the AI is done with the turn given and read its decision
    from the `ai_answer` record (the baton orders the AI's write before our read). The view is
    not written again before the turn is collected, so the AI always decides from exactly the
    state the reference decides from.
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, scene):
        self.control = control
        self.n_bats = len(scene.bats)
        self.plans = PlanFollower(scene)
        self.baton = options.ai_baton.attach(arena["ai_baton"].array)
        self.handoff_s = options.handoff_s
        self.answer = arena["ai_answer"].array
        self.view = arena["ai_view"].array
        local = arena["ai_local"].array
        self.local_tick = local["tick"]  # (1,): written after the inputs
        self.local_inputs = local["inputs"][0][:self.n_bats]
        self.floats = None  # the match's bats as (n_bats, BAT_FLOATS) float64, made at the first request
        self.turn: int | None = None  # the tick whose decision is in flight
        self.restored = None  # inputs computed here before a restart, to collect after it
        self.waits = 0.0  # wall time spent waiting for the AI (its work beyond our own)
        self.turns = self.local = 0  # control ticks that asked the AI, that did not

    def request(self, match: Match, now: float) -> None:
        tick = int(match.state.world[0]["tick"])
        ref = match.referee
        if not self.plans.needs_decision(decision_key(match.rally, ref.shots, int(ref.phase), ref.server, ref.striker),
                                         now):
            if self.floats is None:
                bats = match.state.bats
                self.floats = bats.view(np.float64).reshape(len(bats), -1)
            self.plans.control(now, self.floats, match.ai_next)
            self.local_inputs[:] = match.ai_next
            self.local_tick[0] = tick
            self.local += 1
            return
        copy_record(match.state.record, self.view, 0)
        self.baton.give(tick)
        self.turn = tick
        self.turns += 1

    def collect(self, match: Match) -> list:
        """The AIs' decision into match.ai_next; returns its faults [(player, tick, fault, detail)]."""
        if self.turn is None:
            if self.restored is not None:
                match.ai_next[:] = self.restored
                self.restored = None
            return []
        faults = []
        started = time.perf_counter()
        # The AI worker may be restarting: stay alive and ask again (the view still holds the state).
        self.baton.wait_done_or_retry(self.turn, self.handoff_s, AI_GIVE_UP_S, self.control.beat)
        answer = self.answer[0]
        if int(answer["tick"]) == self.turn:  # done with our turn: its answer, written before done
            mask = int(answer["mask"])
            for bat in range(self.n_bats):
                if mask >> bat & 1:
                    match.ai_next[bat] = answer["inputs"][bat]
                    if answer["fault"][bat]:
                        faults.append((bat, self.turn, FAULTS[int(answer["fault"][bat])],
                                       bytes(answer["fault_text"][bat]).decode("utf-8", "replace")))
            self.plans.take(answer)
        self.turn = None
        self.waits += time.perf_counter() - started
        return faults

    def resume(self, tick: int, period: int) -> None:
        """After a restart at `tick`: the decision of the last control tick before it is in
        flight (the AI's turn), or was computed here (kept in `ai_local`)."""
        self.turn = (tick - 1) // period * period if tick > 0 else None
        if self.turn is not None and self.local_tick[0] == self.turn:
            self.restored = self.local_inputs.copy()
            self.turn = None
        if int(self.answer[0]["tick"]) >= 0:  # the AIs' last answer (a turn in flight brings a newer one)
            self.plans.take(self.answer[0])

    def close(self) -> None:
        del self.view, self.answer, self.local_tick, self.local_inputs, self.floats


def remote_input_refusal(bat: int, values, remote_bats: frozenset[int]) -> str | None:
    """Why the physics refuses a remote input (None: it is applied).

    The gateway posts only inputs that wire.decode accepted (finite, |force| <= MAX_FORCE_N,
    |torque| <= MAX_TORQUE_NM); these writes bypass
    engine.world._check_inputs (they go straight into the bats' records), so the same rules
    are checked again here, where they are applied: a bad input is refused and counted by
    the caller, never applied.

    Args:
        bat: the mailbox entry's bat index. values: (6,) force N, torque N m, world frame.
        remote_bats: the indices of the scene's remote bats (the only ones a remote arm drives).

    Returns:
        "not_remote_bat", "non_finite", "force_out_of_range", "torque_out_of_range" or None.
    """
    if bat not in remote_bats:
        return "not_remote_bat"
    fx, fy, fz, tx, ty, tz = (float(v) for v in values)
    if not all(math.isfinite(v) for v in (fx, fy, fz, tx, ty, tz)):
        return "non_finite"
    if math.sqrt(fx * fx + fy * fy + fz * fz) > MAX_FORCE_N:  # a square that overflows to inf is beyond it too
        return "force_out_of_range"
    if math.sqrt(tx * tx + ty * ty + tz * tz) > MAX_TORQUE_NM:
        return "torque_out_of_range"
    return None


class RemoteInputs:
    """The remote players' inputs: drained from the gateway's locked mailbox before each tick,
    and the idle arm of each remote bat.

    Each input is checked again before it touches a bat (remote_input_refusal); a refused one is
    counted in `refused` by reason (reported with the worker's "done") and its seq is not
    acknowledged. An input holds from the tick it is applied for hold_ticks (the gateway's
    input_hold_s of match time), unless another comes; then, and for a bat whose seat has had no
    input yet, the arm is idle: every tick, before the step, its force is the brake of
    engine.arm.brake_force from the bat's velocity at that tick (the law the client's
    prediction applies too). Computed here from the state being stepped, the brake has no delay
    whatever the load: a gateway posting it from the snapshots it saw braked with a delay that
    grew with the load, and a PD law with enough delay drives the bat instead of stopping it.
    """

    def __init__(self, arena: Arena, options: RunOptions, match: Match):
        self.locks = LockTable(options.lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
        self.box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], self.locks)
        self.inbox = np.zeros(self.box.capacity, REMOTE_INPUT_DTYPE)
        self.applied = arena["remote_applied"].array
        self.acks = arena["remote_acks"].array
        self.match = match
        self.remote_bats = frozenset(i for i, bat in enumerate(match.scene.bats) if bat.remote)
        self.refused: Counter[str] = Counter()
        self.hold_ticks = max(1, round(options.gateway.input_hold_s / match.model.dt))
        # the tick from which each bat's arm is idle; 0: from the start (a restarted physics has
        # lost its players' holds: it brakes until their next input)
        self.idle_from = np.zeros(len(match.scene.bats), np.int64)
        self._idle = sorted(self.remote_bats)
        self._mass = [float(m) for m in match.model.bat_mass]
        self._brake = np.zeros(6)
        self.brake_ticks = 0  # ticks stepped with an idle arm's brake, summed over the remote bats

    def apply(self, tick: int) -> None:
        """Before the step from `tick`: each new input holds from now on, in the bat's record
        (held between AI ticks) and in the match's inputs (which an AI control tick writes to
        every bat); an idle arm's bat gets its brake."""
        n = self.box.drain(self.inbox)
        bats = self.match.state.bats
        for k in range(n):
            bat = int(self.inbox[k]["bat"])
            values = self.inbox[k]["inputs"]
            reason = remote_input_refusal(bat, values, self.remote_bats)
            if reason is not None:
                self.refused[reason] += 1
                continue
            self.match.inputs[bat] = values
            bats[bat]["force"] = values[0:3]
            bats[bat]["torque"] = values[3:6]
            self.applied[bat] = self.inbox[k]["seq"]
            self.idle_from[bat] = tick + self.hold_ticks
        for bat in self._idle:
            if tick >= self.idle_from[bat]:
                brake = brake_force(self._mass[bat], bats[bat]["vel"], self._brake)
                self.match.inputs[bat] = brake
                bats[bat]["force"] = brake[0:3]
                bats[bat]["torque"] = brake[3:6]
                self.brake_ticks += 1

    def publish_ack(self, tick: int) -> None:
        """Before the snapshot of `tick` is published: the seqs it acknowledges (the inputs applied
        so far, none of the next tick's), for the gateway to pair with that snapshot."""
        write_ack(self.acks, tick, self.applied)

    def close(self) -> None:
        del self.applied, self.acks, self.box
        self.locks.close()


class RemoteNet:
    """The physics worker's stand-in for the NetSim in engine.world: same `sleeping`, `in_tail`,
    step() and step_free().

    Args:
        control: the physics worker's Control (heartbeats while it waits).
        arena, options: the run's (net_io, net_baton).
        world: the physics state's world record (its tick says which tick is being stepped).
        local: a NetSim of the same net as built (its knot radius, tick and built shape).

    A sleeping net and a ball that cannot touch its frozen shape cost no hand-off, exactly as
    NetSim.step returns early: the stand-in keeps the box the net froze in (from net_io after each
    ball tick). So does a net in its linear tail (net_kernel/tail.py) and a ball far from the box
    that holds the tail's knots: NetSim.step only counts such a tick, so the stand-in grants it
    free, and knows from the net's last answer the tick at which the tail falls asleep. What it
    knows of `sleeping` otherwise comes from the net's last answer, so after free ticks, in which
    the net may have fallen asleep or into its tail, it may still think the net awake: that costs
    a hand-off more, never a different bit (the net worker then steps exactly as NetSim.step would).
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, world, local: NetSim):
        self.control = control
        self.local = local
        self.world = world
        self.baton = options.net_baton.attach(arena["net_baton"].array)
        self.handoff_s = options.handoff_s
        self.io = NetIO(arena["net_io"].array)
        self._none = np.zeros(3)
        self.waits = 0.0
        self.ball_ticks = 0  # ticks handed to the net worker with the ball (and waited for)
        self.free_ticks = 0  # ticks granted without the ball (not waited for)
        self.turns_again = 0  # turns given again because the net's answer took longer than one wait's bound
        # Nothing known yet (a fresh run's net is as built and awake; a resumed one, whatever the
        # net says at its first answer): awake is the guess that can cost a hand-off but no bit.
        self._sleeping = False
        self._tail_until = -1  # the tick at which the tail of the last answer falls asleep (-1: no tail)
        self.box = local.box.copy()

    @property
    def sleeping(self) -> bool:
        """Asleep after the ticks done, as far as the net's last answer tells."""
        return self._sleeping or 0 <= self._tail_until <= int(self.world["tick"])

    @property
    def in_tail(self) -> bool:
        """In its linear tail after the ticks done, as far as the net's last answer tells."""
        return self._tail_until > int(self.world["tick"])

    def step_free(self, ticks: int) -> None:
        """NetSim.step_free: grant the net the ticks just done (the world's tick is past them) and go on."""
        if ticks > 0:
            self.io.granted = int(self.world["tick"])
            self.baton.nudge()
            self.free_ticks += ticks

    def step(self, ball_pos, ball_vel, ball_radius: float, ball_inv_mass: float) -> NetContact:
        """NetSim.step, done by the net worker (called after the ball's tick, as engine.world does)."""
        local = self.local
        tick = int(self.world["tick"]) - 1
        tail = self._tail_until > tick  # the net's state at this tick's start
        if (self._sleeping or tail or 0 <= self._tail_until <= tick) and ball_far_from_box(
                self.box, True, local.knot_radius, local.dt, ball_pos, ball_vel, ball_radius):
            if tail:  # a tick of the tail: counted free (NetSim.step with the ball far)
                self.io.granted = tick + 1
                self.free_ticks += 1
            self._none[:] = 0.0
            return NetContact(NO_CONTACT, self._none, self._none)
        started = time.perf_counter()
        row = self.io
        # `turn` odd while the fields are written, even once they all are (see net_worker): the
        # worker may wake on an earlier post at any moment and must never read half of them.
        row.turn = row.turn // 2 * 2 + 1
        row.tick = tick
        row.ball[0] = ball_pos
        row.ball[1] = ball_vel
        row.radius = ball_radius
        row.inv_mass = ball_inv_mass
        row.turn += 1
        self.baton.give(tick)
        # The net may still be stepping free ticks, or restarting: stay alive and ask again (a
        # new turn; net_io still holds the ball).
        self.baton.wait_done_or_retry(tick, self.handoff_s, NET_GIVE_UP_S, self._ask_again)
        self._sleeping = bool(row.sleeping)
        self._tail_until = row.tail_until
        self.box[:] = row.box
        self.waits += time.perf_counter() - started
        self.ball_ticks += 1
        return NetContact(row.toi, row.impulse.copy(), row.offset.copy())

    def _ask_again(self, tick: int) -> None:
        self.control.beat(tick)
        self.turns_again += 1
        self.io.turn += 2  # the same fields, a new turn (even: nothing is being written)
