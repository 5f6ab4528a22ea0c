"""The physics worker: ball, bats, contacts and, in a match, the referee and the server's toss.

It owns the physics snapshot (published every tick), the event log and the point log.
"""
from __future__ import annotations

import math
import os
import signal
import time
from collections import Counter

import numpy as np

from engine.dtypes import physics_snapshot_dtype
from engine.match import Match, point_from_row, point_row
from engine.world import build_model, copy_record, initial_state, new_events, step
from processes.runtime.shm import Arena
from processes.network.wire import MAX_FORCE_N, MAX_TORQUE_NM
from processes.workers.ai import decision_key
from processes.runtime.control import GO_TIMEOUT_S, Control, WorkerState

AI_HANDOFF_S = 1.0  # one call's bound; retried while a killed AI worker is restarted
AI_GIVE_UP_S = 60.0


class _Pacer:
    """Realtime mode: start each tick at its wall-clock time; count the late ones, drop none."""

    def __init__(self, start_wall: float, dt: float, row):
        self.start, self.dt, self.row = start_wall, dt, row

    def wait(self, tick: int) -> None:
        due = self.start + tick * self.dt
        now = time.monotonic()
        if now < due:
            time.sleep(due - now)  # pacing to the wall clock, not synchronisation
        elif now - due > self.dt:
            self.row["late_ticks"] += 1
            self.row["max_late_s"] = max(float(self.row["max_late_s"]), now - due)


def physics_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """Run the physics ticks: lockstep (as fast as possible) or realtime (paced by the wall clock).

    options: ticks (total to reach), mode ("lockstep" | "realtime"), trace (bool),
        crash_at_tick (int or None: SIGKILL this process right after publishing that tick),
        and for a match: seed, baton (when the scene has AI bats), lock_path (when it has remote players).
    """
    if scene.match is not None:
        return _match_worker(control, arena, scene, options)
    model = build_model(scene)
    state = initial_state(scene)
    events = new_events()
    snapshots = arena["physics"]
    log = arena["events"].array
    trace = arena["trace"].array if options.get("trace") else None
    record = state.record  # the state lives in the snapshot record: publishing is one copy
    # Compile (or load from the cache) before reporting ready: a zero-length tick is an identity.
    step(model, state, None, events, dt=0.0)
    if snapshots.version >= 2:
        snapshots.snapshot(record)  # restarted: resume from the last consistent snapshot
    else:
        if trace is not None:
            copy_record(record, trace, 0)
        snapshots.publish(record, 0)
    net = _remote_net(control, arena, options, state)
    tick = int(state.world[0]["tick"])
    total_events = int(state.world[0]["events_total"])
    control.set_state(WorkerState.READY)
    control.send("ready", tick)
    start_wall = control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    pacer = _Pacer(start_wall, model.dt, control.row) if options["mode"] == "realtime" else None
    n_ticks = options["ticks"]
    crash_at_tick = options.get("crash_at_tick")
    capacity = log.shape[0]
    busy = 0.0
    while tick < n_ticks:
        if pacer is not None:
            pacer.wait(tick)
        t0 = time.perf_counter()
        n = step(model, state, None, events)
        for k in range(n):
            log[(total_events + k) % capacity] = events[k]
        total_events += n
        tick += 1
        if trace is not None:
            copy_record(record, trace, tick)
        snapshots.publish(record, tick)
        if tick == crash_at_tick:
            os.kill(os.getpid(), signal.SIGKILL)
        busy += time.perf_counter() - t0
        control.beat(tick)
    handoff = _stop_net(net, options)
    control.row["busy_s"] = float(control.row["busy_s"]) + busy - handoff
    control.row["handoff_s"] = float(control.row["handoff_s"]) + handoff
    control.send("done", {"tick": tick, "busy_s": busy - handoff, "handoff_s": handoff, **_net_ticks(net)})


def _remote_net(control: Control, arena: Arena, options: dict, state):
    """With a net worker: the state's cloth net becomes its stand-in (after any resume)."""
    if "net_baton" not in options:
        return None
    from processes.workers.net import RemoteNet

    state.net_sim = RemoteNet(control, arena, options, state.world[0], state.net_sim)
    return state.net_sim


def _stop_net(net, options: dict) -> float:
    """Tell the net worker the run is over; the wall time spent waiting for it."""
    if net is None:
        return 0.0
    options["net_baton"].stop()
    return net.waits


def _net_ticks(net) -> dict:
    """The ticks the physics handed the net worker with the ball (waiting) and without it."""
    return {} if net is None else {"net_ball_ticks": net.ball_ticks, "net_free_ticks": net.free_ticks}


class _RemoteAI:
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

    def __init__(self, control: Control, arena: Arena, options: dict, scene):
        from processes.workers.ai import PlanFollower

        self.control = control
        self.n_bats = len(scene.bats)
        self.plans = PlanFollower(scene)
        self.baton = options["baton"].attach(arena["baton"].array)
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

    def collect(self, match: Match) -> None:
        if self.turn is None:
            if self.restored is not None:
                match.ai_next[:] = self.restored
                self.restored = None
            return
        started = time.perf_counter()
        # The AI worker may be restarting: stay alive and ask again (the view still holds the state).
        self.baton.wait_done_or_retry(self.turn, AI_HANDOFF_S, AI_GIVE_UP_S, self.control.beat)
        answer = self.answer[0]
        if int(answer["tick"]) == self.turn:  # done with our turn: its answer, written before done
            mask = int(answer["mask"])
            for bat in range(self.n_bats):
                if mask >> bat & 1:
                    match.ai_next[bat] = answer["inputs"][bat]
            self.plans.take(answer)
        self.turn = None
        self.waits += time.perf_counter() - started

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
    |torque| <= MAX_TORQUE_NM) and its idle arms' brakes; these writes bypass
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


class _RemoteInputs:
    """The remote players' inputs: drained from the gateway's locked mailbox before each tick.

    Each is checked again before it touches a bat (remote_input_refusal); a refused one is
    counted in `refused` by reason (reported with the worker's "done") and its seq is not
    acknowledged.
    """

    def __init__(self, arena: Arena, options: dict, match: Match):
        from processes.network.gateway import REMOTE_INPUT_DTYPE, RUN_LOCK_NAMES
        from processes.runtime.locks import LockTable
        from processes.runtime.mailbox import Mailbox

        self.locks = LockTable(options["lock_path"], RUN_LOCK_NAMES, arena["lock_holders"])
        self.box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], self.locks)
        self.inbox = np.zeros(self.box.capacity, REMOTE_INPUT_DTYPE)
        self.applied = arena["remote_applied"].array
        self.acks = arena["remote_acks"].array
        self.match = match
        self.remote_bats = frozenset(i for i, bat in enumerate(match.scene.bats) if bat.remote)
        self.refused: Counter[str] = Counter()

    def apply(self) -> None:
        """Each input holds from now on: in the bat's record (held between AI ticks) and in the
        match's inputs (which an AI control tick writes to every bat)."""
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

    def publish_ack(self, tick: int) -> None:
        """Before the snapshot of `tick` is published: the seqs it acknowledges (the inputs applied
        so far, none of the next tick's), for the gateway to pair with that snapshot."""
        from processes.network.gateway import write_ack

        write_ack(self.acks, tick, self.applied)

    def close(self) -> None:
        del self.applied, self.acks, self.box
        self.locks.close()


def _await_players(control: Control, options: dict, tick: int) -> None:
    """A served match starts once the gateway says every remote seat is taken (bounded)."""
    event = options["start_event"]
    deadline = time.monotonic() + options.get("players_timeout", 300.0)
    while not event.wait(0.2) and time.monotonic() < deadline:
        control.beat(tick)


def _match_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    n_bats = len(scene.bats)
    has_ai = any(bat.skill is not None for bat in scene.bats)
    driver = _RemoteAI(control, arena, options, scene) if has_ai else None
    match = Match(scene, options["seed"], ai_driver=driver)
    snapshots = arena["physics"]
    log = arena["events"].array
    points_log = arena["points"].array
    frames = arena["frames"].array if "frames" in arena.blocks else None
    frame_every = options.get("frame_every", 0)
    trace = arena["trace"].array if options.get("trace") else None
    record = match.state.record  # the state lives in the snapshot record: publishing is one copy
    step(match.model, match.state, None, match.events, dt=0.0)  # compile or load the kernels
    if snapshots.version >= 2:
        latest = np.zeros(1, physics_snapshot_dtype(n_bats))
        snapshots.snapshot(latest)
        total = int(latest[0]["rally"]["points_total"])
        match.restore(latest[0], [point_from_row(points_log[i]) for i in range(total)])
    else:
        if trace is not None:
            copy_record(record, trace, 0)
        snapshots.publish(record, 0)
    net = _remote_net(control, arena, options, match.state)
    world = match.state.world[0]
    tick = int(world["tick"])
    total_events = int(world["events_total"])
    points_logged = len(match.referee.points)
    control.set_state(WorkerState.READY)
    control.send("ready", tick)
    start_wall = control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    remote = _RemoteInputs(arena, options, match) if "remote" in scene.effects else None
    if remote is not None:
        _await_players(control, options, tick)
        start_wall = time.monotonic() - tick * match.model.dt  # pace from when play starts
    pacer = _Pacer(start_wall, match.model.dt, control.row) if options["mode"] == "realtime" else None
    n_ticks = options["ticks"]
    crash_at_tick = options.get("crash_at_tick")
    capacity = log.shape[0]
    busy = 0.0
    # pacing, traces and remote inputs (drained before every tick) want every tick
    per_tick = pacer is not None or trace is not None or remote is not None
    while tick < n_ticks and not match.referee.match_over:
        if pacer is not None:
            pacer.wait(tick)
        t0 = time.perf_counter()
        if remote is not None:
            remote.apply()
        chunk = 1 if per_tick else n_ticks - tick
        if frames is not None:
            chunk = min(chunk, frame_every - tick % frame_every)
        if crash_at_tick is not None and tick < crash_at_tick:
            chunk = min(chunk, crash_at_tick - tick)
        match.tick(chunk)
        for k in range(match.n_events):
            log[(total_events + k) % capacity] = match.events[k]
        total_events += match.n_events
        tick += match.ticks_done
        while points_logged < len(match.referee.points):
            points_log[points_logged] = point_row(match.referee.points[points_logged], tick)
            points_logged += 1
        if trace is not None:
            copy_record(record, trace, tick)
        if frames is not None and tick % frame_every == 0 and tick // frame_every < len(frames):
            copy_record(record, frames, tick // frame_every)
        if remote is not None:
            remote.publish_ack(tick)
        snapshots.publish(record, tick)
        if tick == crash_at_tick:
            os.kill(os.getpid(), signal.SIGKILL)
        busy += time.perf_counter() - t0
        control.beat(tick)
    handoff = (driver.waits if driver is not None else 0.0) + _stop_net(net, options)
    ai_ticks = {}
    if driver is not None:
        options["baton"].stop()
        ai_ticks = {"ai_turns": driver.turns, "ai_local_ticks": driver.local}
        driver.close()
    refused = {}
    if remote is not None:
        refused = dict(remote.refused)
        remote.close()
    # busy_s counts the physics' own work; the hand-offs to the AI and the net (and their work
    # inside them, which they report themselves) are reported apart.
    control.row["busy_s"] = float(control.row["busy_s"]) + busy - handoff
    control.row["handoff_s"] = float(control.row["handoff_s"]) + handoff
    control.send("done", {"tick": tick, "busy_s": busy - handoff, "handoff_s": handoff,
                          "remote_inputs_refused": refused, **ai_ticks, **_net_ticks(net)})
