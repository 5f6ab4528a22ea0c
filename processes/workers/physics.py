"""The physics worker: ball, bats, contacts and, in a match, the referee and the server's toss.

It owns the physics snapshot (published every tick), the event log and the point log.
"""
from __future__ import annotations

import time

import numpy as np

from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.compiled import CompiledScene
from engine.physics.world import State, copy_record, new_events, step
from engine.play.match import Match, point_from_row, point_row
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.runtime.timeline import WORK, Timeline
from processes.workers.ai_driver import AIDriver
from processes.workers.cut import Cuts
from processes.workers.options import RunOptions
from processes.workers.remote_inputs import RemoteInputs
from processes.workers.remote_net import RemoteNet
from processes.workers.speculation import SpeculativeNet, run_speculating


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


class _Publisher:
    """What the physics writes after its ticks: the new events into the event log's ring, the
    trace row, the snapshot (one copy: the state lives in `record`), and the fault injection.

    Args:
        arena: the run's. record: the state's snapshot record. options: the worker's.
        total_events: events logged so far (after a restart, the snapshot's count).
    """

    def __init__(self, arena: Arena, record: np.ndarray, options: RunOptions, total_events: int):
        self.snapshots = arena["physics"]
        self.log = arena["events"].array
        self.trace = arena["trace"].array if options.trace else None
        self.record = record
        self.total_events = total_events
        self.faults = options.faults

    def start(self, resumed: bool) -> None:
        """A fresh run publishes tick 0 (a restarted one resumed from the published snapshot)."""
        if not resumed:
            if self.trace is not None:
                copy_record(self.record, self.trace, 0)
            self.snapshots.publish(self.record, 0)

    def publish(self, tick: int, events: np.ndarray, n_events: int) -> None:
        self.publish_events(events, n_events)
        if self.trace is not None:
            copy_record(self.record, self.trace, tick)
        self.publish_snapshot(tick)
        if self.faults is not None and self.faults.crashes_in(tick, tick + 1):
            self.faults.crash(tick)

    def publish_events(self, events: np.ndarray, n_events: int) -> None:
        """Events into the event log's ring, in order."""
        capacity = self.log.shape[0]
        for k in range(n_events):
            self.log[(self.total_events + k) % capacity] = events[k]
        self.total_events += n_events

    def publish_snapshot(self, tick: int, record: np.ndarray | None = None) -> None:
        """The state at `tick` as the snapshot: `record` ((1,) physics_snapshot_dtype), the state's by default."""
        self.snapshots.publish(self.record if record is None else record, tick)


def physics_worker(control: Control, arena: Arena, compiled: CompiledScene, options: RunOptions) -> None:
    """Run the physics ticks: lockstep (as fast as possible) or realtime (paced by the wall clock).

    options: ticks (total to reach), mode ("lockstep" | "realtime"), trace (bool), faults (tests:
        end this process right after publishing the crash tick, by SIGKILL or an exception; a
        match's every tick slow_turn_s longer), and for a match: seed, handles.ai_queue (when the
        scene has AI bats), handles.lock_path (when it has remote players).
    """
    if compiled.scene.match is not None:
        return _match_worker(control, arena, compiled, options)
    model = compiled.model
    state = compiled.initial_state()
    events = new_events()
    snapshots = arena["physics"]
    # Compile (or load from the cache) before reporting ready: a zero-length tick is an identity.
    step(model, state, None, events, dt=0.0)
    resumed = snapshots.version >= 2
    if resumed:
        snapshots.snapshot(state.record)  # restarted: resume from the last consistent snapshot
    out = _Publisher(arena, state.record, options, int(state.world[0]["events_total"]))
    out.start(resumed)
    net = _remote_net(control, arena, options, state)
    tick = int(state.world[0]["tick"])
    start_wall = control.start(tick)
    timeline = _timeline(options, "physics", net)
    pacer = _Pacer(start_wall, model.dt, control.row) if options.mode == "realtime" else None
    n_ticks = options.ticks
    busy = 0.0
    while tick < n_ticks:
        if pacer is not None:
            pacer.wait(tick)
        t0 = time.perf_counter()
        n = step(model, state, None, events)
        tick += 1
        out.publish(tick, events, n)
        busy += time.perf_counter() - t0
        control.beat(tick)
    _finish(control, tick, busy, net, options, timeline=timeline)


def _remote_net(control: Control, arena: Arena, options: RunOptions, state: State) -> RemoteNet | SpeculativeNet | None:
    """With a net worker: the state's cloth net becomes its stand-in (after any resume); a
    speculating run's posts the runs without waiting (processes.workers.speculation)."""
    if options.handles.net_baton is None:
        return None
    stand_in = SpeculativeNet if options.speculate else RemoteNet
    state.net_sim = stand_in(control, arena, options, state.world[0], state.net_sim)
    return state.net_sim


def _timeline(options: RunOptions, kind: str, *waiters) -> Timeline | None:
    """The worker's timeline if the run keeps them, marked working from now; the stand-ins that
    wait for other workers (RemoteNet, AIDriver; None: absent) mark their waits in it."""
    if options.timeline_dir is None:
        return None
    timeline = Timeline(options.timeline_dir, kind)
    timeline.mark(WORK)
    for waiter in waiters:
        if waiter is not None:
            waiter.timeline = timeline
    return timeline


def _stop_net(net, options: RunOptions) -> float:
    """Tell the net worker the run is over; the wall time spent waiting for it."""
    if net is None:
        return 0.0
    if isinstance(net, SpeculativeNet):
        return net.stop()
    options.handles.net_baton.stop()
    return net.waits


def _finish(control: Control, tick: int, busy: float, net, options: RunOptions, match: Match | None = None,
            driver=None, remote=None, timeline: Timeline | None = None) -> None:
    """The physics' last words: stop the AI's and the net's turns, report the work and hand-offs.

    busy_s counts the physics' own work; the hand-offs to the AI and the net (and their work
    inside them, which they report themselves) are reported apart, as handoff_s, and split into
    handoff_net_s and handoff_ai_s (what the physics waited for each). The report
    also carries the AI's turns (at the control ticks where a player could decide; the others,
    skipped, are counted too), those at which a player decided and those whose answer was waited
    for, the cloth net's ticks (handed to the net worker with the ball and waited
    for, or granted without it), the remote inputs refused by reason and the match's bot errors.
    """
    net_waits = _stop_net(net, options)
    handoff = net_waits
    report = {"tick": tick}
    if net is not None:
        speculating = isinstance(net, SpeculativeNet)
        report.update(net_ball_ticks=net.ball_ticks, net_runs=net.runs_posted if speculating else net.runs,
                      net_free_ticks=net.free_ticks, net_turns_again=net.turns_again, handoff_net_s=net_waits)
        if speculating:
            report.update(net_rollbacks=net.rollbacks, net_ticks_again=net.ticks_again)
    if driver is not None:
        handoff += driver.waits
        options.handles.ai_queue.stop()
        report.update(ai_turns=driver.turns, ai_skipped=driver.skipped, ai_decisions=driver.decided,
                      ai_waited_turns=driver.waited, handoff_ai_s=driver.waits)
        driver.close()
    if match is not None:
        report.update(remote_inputs_refused={} if remote is None else dict(remote.refused), bot_errors=match.bot_errors,
                      stopped=None if match.stopped is None else str(match.stopped))
        if remote is not None:
            report.update(remote_brake_ticks=remote.brake_ticks)
    if remote is not None:
        remote.close()
    report.update(busy_s=busy - handoff, handoff_s=handoff)
    if timeline is not None:
        timeline.save()
    control.finish(busy - handoff, handoff, report)


def _await_players(control: Control, options: RunOptions, tick: int, timeout_s: float | None) -> float:
    """Wait while the gateway says a remote seat is empty (options.handles.start_event clear): at most
    timeout_s (None: until the seats are held or a stop command comes); the wall time waited."""
    event = options.handles.start_event
    start = time.monotonic()
    deadline = start + (float("inf") if timeout_s is None else timeout_s)
    while not event.wait(0.2) and time.monotonic() < deadline:
        control.beat(tick)  # raises StopRequested on the supervisor's stop
    return time.monotonic() - start


def _match_worker(control: Control, arena: Arena, compiled: CompiledScene, options: RunOptions) -> None:
    scene = compiled.scene
    n_bats = len(scene.bats)
    has_ai = any(bat.skill is not None for bat in scene.bats)
    driver = AIDriver(control, arena, options, scene) if has_ai else None
    match = Match(compiled, options.seed, ai_driver=driver, on_bot_error=options.on_bot_error)
    snapshots = arena["physics"]
    points_log = arena["points"].array
    frames = arena["frames"].array if "frames" in arena.blocks else None
    frame_every = options.frame_every
    record = match.state.record  # the state lives in the snapshot record: publishing is one copy
    step(match.model, match.state, None, match.events, dt=0.0)  # compile or load the kernels
    resumed = snapshots.version >= 2
    if resumed:
        latest = np.zeros(1, physics_snapshot_dtype(n_bats))
        snapshots.snapshot(latest)
        total = int(latest[0]["rally"]["points_total"])
        match.restore(latest[0], [point_from_row(points_log[i]) for i in range(total)])
    world = match.state.world[0]
    cuts = Cuts(arena["spec_cut"].array) if options.speculate else None
    if cuts is not None and not resumed:  # the cut of tick 0, before its snapshot
        cuts.write(0, 0, match.arm.copy(), driver.checkpoint() if driver is not None else None)
    out = _Publisher(arena, record, options, int(world["events_total"]))
    out.start(resumed)
    net = _remote_net(control, arena, options, match.state)
    tick = int(world["tick"])
    points_logged = len(match.referee.points)
    start_wall = control.start(tick)
    timeline = _timeline(options, "physics", net, driver)
    remote = RemoteInputs(arena, options, match) if "remote" in scene.effects else None
    # A served match waits for its remote players before the first serve, then pauses while a
    # seat is empty (a dropped player's grace), unless the first wait ran out (then it plays on)
    # or the gateway's config says not to (GatewayConfig.pause_for_players).
    pause_when_empty = False
    start_event = options.handles.start_event
    if remote is not None and start_event is not None:
        _await_players(control, options, tick, options.players_timeout)
        pause_when_empty = start_event.is_set() and options.gateway.pause_for_players
        start_wall = time.monotonic() - tick * match.model.dt  # pace from when play starts
    pacer = _Pacer(start_wall, match.model.dt, control.row) if options.mode == "realtime" else None
    n_ticks = options.ticks
    if options.speculate:
        busy = run_speculating(control, match, net, driver, out, points_log, n_ticks, cuts, resumed, options.faults)
        _finish(control, match.current_tick, busy, net, options, match, driver, remote, timeline)
        return
    faults = options.faults
    crash_at_tick = None if faults is None else faults.crash_at_tick
    busy = 0.0
    # pacing, traces and remote inputs (drained before every tick) want every tick
    per_tick = pacer is not None or options.trace or remote is not None
    while tick < n_ticks and not match.over:
        if pause_when_empty and not start_event.is_set():
            paused = _await_players(control, options, tick, None)
            if pacer is not None:
                pacer.start += paused  # the clock resumes where it stopped: no rush to catch up
        if pacer is not None:
            pacer.wait(tick)
        t0 = time.perf_counter()
        if remote is not None:
            remote.apply(tick)
        chunk = 1 if per_tick else n_ticks - tick
        if frames is not None:
            chunk = min(chunk, frame_every - tick % frame_every)
        if crash_at_tick is not None and tick < crash_at_tick:
            chunk = min(chunk, crash_at_tick - tick)
        match.tick(chunk)
        tick += match.ticks_done
        while points_logged < len(match.referee.points):
            points_log[points_logged] = point_row(match.referee.points[points_logged], tick)
            points_logged += 1
        if frames is not None and tick % frame_every == 0 and tick // frame_every < len(frames):
            copy_record(record, frames, tick // frame_every)
        if remote is not None:
            remote.publish_ack(tick)
        out.publish(tick, match.events, match.n_events)
        busy += time.perf_counter() - t0
        if faults is not None:
            faults.delay()  # a physics on a busy machine
        control.beat(tick)
    _finish(control, tick, busy, net, options, match, driver, remote, timeline)
