"""The supervisor: builds the run's shared memory, starts only the workers the scene needs,
watches them, restarts a dead one from the last consistent snapshot, and always cleans up.

A worker that dies (any exit before its "done"), stalls (silent for STALL_TIMEOUT_S) or raises
(its exception comes back with its traceback, which is logged) is restarted the same way, and
counted. The restart budget, as an Erlang/OTP supervisor's intensity and period: one worker may
be restarted RESTART_BUDGET times within RESTART_WINDOW_S; one more failure within that window
ends the run with WorkerFailed, and a served match's clients are told goodbye server_error.

Cleanup holds on every exit path: normal end, an exception, Ctrl-C (KeyboardInterrupt) or
SIGTERM (turned into SystemExit), a worker's crash, and any number of further signals during
it (runtime.stops.StopSignals). Workers get a stop command, then a bounded
join, then kill; every segment of the run is unlinked. Should the supervisor
itself be SIGKILLed, its workers notice their parent is gone within a heartbeat and exit, and
the multiprocessing resource tracker unlinks the segments.
"""
from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
import os
import time
from dataclasses import dataclass, field, replace

import numpy as np

from engine.physics.dtypes import CONTACT_DTYPE, physics_snapshot_dtype
from engine.physics.compiled import compile_scene
from engine.physics.scene import Scene
from engine.play.players import DEFAULT_BUDGET_S
from processes.network.server.config import GatewayConfig
from processes.runtime.control import READY_TIMEOUT_S, STARTUP_LIMIT_S, WorkerState, worker_main
from processes.runtime.faults import FaultPlan
from processes.runtime.handoff import SPIN_S
from processes.runtime.shm import Arena
from processes.runtime.stops import StopSignals
from processes.workers import (PLAYERS_TIMEOUT_S, RunHandles, RunLayout, RunOptions, build_layout,
                               speculation_refusal, worker_modules, worker_target, workers_for)
from processes.workers.layout import EVENT_LOG_CAPACITY

STOP_TIMEOUT_S = 5.0
STALL_TIMEOUT_S = 10.0  # a RUNNING worker silent this long is killed and restarted
RESTART_BUDGET = 3  # restarts of one worker allowed within RESTART_WINDOW_S
RESTART_WINDOW_S = 600.0

log = logging.getLogger(__name__)


class WorkerFailed(RuntimeError):
    """A worker failed past its restart budget (or while starting); the message says how,
    with the last traceback of one that raised."""


class WorkerRefused(WorkerFailed, ValueError):
    """A worker refused the run's input while starting (a bot whose setup() raised, a bot file
    that does not load): the message is the reason in one line, as the in-process run says it,
    without the worker's traceback; the run never started."""


@dataclass
class ProcessRunResult:
    """What a multi-process run produced."""

    scene: Scene
    mode: str
    ticks: int
    wall_seconds: float
    startup_seconds: float
    final: np.ndarray  # one physics snapshot record
    events: np.ndarray  # CONTACT_DTYPE, oldest first (the last EVENT_LOG_CAPACITY at most)
    events_total: int
    workers: dict = field(default_factory=dict)  # per worker: pid, restarts, late ticks, busy time
    trace: np.ndarray | None = None
    points: np.ndarray | None = None  # POINT_DTYPE log of a match
    frames: np.ndarray | None = None  # decimated snapshots for a replay

    def match_summary(self, seed: int) -> dict:
        """The run as engine.play.match.MatchResult.summary() reports an in-process match, with the
        workers' own figures beside it (mode, startup, per worker, a bot's errors, a stop)."""
        from engine.play.match import MatchResult, point_from_row
        from engine.play.rules import Referee

        points = [point_from_row(row) for row in self.points]
        spec = self.scene.match
        referee = Referee.restore(self.final["rally"], spec.best_of, "ab".index(spec.first_server), points)
        summary = MatchResult(self.scene, seed, referee, self.ticks, self.ticks * self.scene.dt, self.wall_seconds,
                              self.startup_seconds, 0.0).summary()
        physics = self.workers.get("physics", {})
        summary.update(mode=self.mode, processes=True, startup_seconds=self.startup_seconds,
                       workers=self.workers, compile_seconds=None, ai_seconds=None,
                       bot_errors=physics.get("bot_errors", []), stopped=physics.get("stopped"))
        return summary


class _Worker:
    def __init__(self, kind: str, index: int):
        self.kind = kind
        self.index = index
        self.process = None
        self.conn = None
        self.restarts = 0
        self.restarted_at: list[float] = []  # time.monotonic() of each restart (the budget's window)
        self.raised = 0  # exceptions it shipped back (each restarted it, as a death does)
        self.finished = False
        self.ready: dict = {}  # what the worker reported with "ready" (the gateway: its endpoint)
        self.report: dict = {}  # what it reported with "done"


def _contended(kinds: list[str]) -> bool:
    """Do the run's computing workers (physics, net, AI: the gateway mostly waits on its sockets)
    outnumber the cores this process may run on?"""
    return sum(kind != "gateway" for kind in kinds) > len(os.sched_getaffinity(0))


class Supervisor:
    """One run of a scene in separate processes.

    Args:
        scene: the scene. ticks: ticks to run. mode: "lockstep" or "realtime".
        trace: keep every tick's physics snapshot (for --check-reference).
        crash_at_tick: fault injection for tests and `pingpong stress`: the first incarnation of
            `crash_worker` SIGKILLs itself at this tick.
        seed: the match's seed. frame_every: keep a snapshot every this many ticks (replays), 0: none.
        gateway: processes.network.server.gateway.GatewayConfig for a scene with the effect "remote".
        players_timeout: s, a served match waits this long for its remote players, then starts.
        crash_kind: how `crash_worker` ends at crash_at_tick: "kill" (SIGKILL) or "raise" (an exception).
        restart_budget: restarts of one worker allowed within RESTART_WINDOW_S; one more failure ends the run.
        handoff_s: s, one wait of the physics for the AI's or the net's answer (RunOptions).
        slow_turn_s: fault injection for tests: every incarnation of `crash_worker` answers each
            turn (the AI, the net) or steps each match tick (the physics) this much later.
        on_bot_error, bot_budget_s: engine.play.match.Match's on_bot_error and budget_s.
        timeline_dir: each worker writes its timeline there (RunOptions.timeline_dir).
        speculate: the physics steps on past the net's runs before their answers
            (RunOptions.speculate): True for a lockstep match with a cloth net and AI profiles,
            without traces or frames (ValueError otherwise); None (the default): wherever the
            run allows it; False: never. A dead worker is restarted either way
            (processes.workers.speculation).
        gate_ai_turns: RunOptions.gate_ai_turns; None: where the computing workers outnumber
            the cores this process may run on.
    """

    def __init__(self, scene: Scene, ticks: int, mode: str = "lockstep", trace: bool = False,
                 crash_at_tick: int | None = None, seed: int = 0, frame_every: int = 0,
                 crash_worker: str = "physics", gateway=None, players_timeout: float = PLAYERS_TIMEOUT_S,
                 handoff_s: float = RunOptions.handoff_s, slow_turn_s: float = 0.0, crash_kind: str = "kill",
                 restart_budget: int = RESTART_BUDGET, on_bot_error: str = "point",
                 bot_budget_s: float | None = DEFAULT_BUDGET_S, timeline_dir: str | None = None,
                 speculate: bool | None = None, gate_ai_turns: bool | None = None):
        self.scene = scene
        self.compiled = compile_scene(scene)  # once: every worker is handed it
        self.ticks = ticks
        self.mode = mode
        self.trace = trace
        self.crash_at_tick = crash_at_tick
        self.crash_worker = crash_worker
        self.frame_every = frame_every
        self.kinds = workers_for(scene)
        if "gateway" in self.kinds and gateway is None:
            gateway = GatewayConfig()
        refusal = speculation_refusal(scene, self.kinds, mode, trace, frame_every)
        if speculate and refusal is not None:
            raise ValueError(f"speculate: {refusal}")
        self.options = RunOptions(ticks=ticks, mode=mode, trace=trace, seed=seed, frame_every=frame_every,
                                  players_timeout=players_timeout, gateway=gateway, handoff_s=handoff_s,
                                  on_bot_error=on_bot_error, bot_budget_s=bot_budget_s, timeline_dir=timeline_dir,
                                  gate_ai_turns=_contended(self.kinds) if gate_ai_turns is None else gate_ai_turns,
                                  speculate=refusal is None if speculate is None else speculate)
        FaultPlan(kind=crash_kind)  # a bad kind is refused here, before anything starts
        self.crash_kind = crash_kind
        if restart_budget < 0:
            raise ValueError(f"restart_budget must be >= 0 (restarts within {RESTART_WINDOW_S:.0f} s), "
                             f"got {restart_budget}")
        self.restart_budget = restart_budget
        self.slow_turn_s = slow_turn_s
        self.layout: RunLayout | None = None
        # forkserver: workers fork from a clean server that never ran threads or kernels.
        self._ctx = multiprocessing.get_context("forkserver")
        self._ctx.set_forkserver_preload(["processes.runtime.forkserver", "engine.physics.world", "engine.play.match",
                                          *worker_modules(self.kinds)])
        self.arena: Arena | None = None
        self._workers: list[_Worker] = []

    def _start(self, worker: _Worker) -> None:
        parent, child = self._ctx.Pipe()
        layout = self.layout
        handles = RunHandles(ai_queue=layout.ai_queue, net_baton=layout.net_baton, lock_path=layout.lock_path,
                             start_event=layout.start_event, net_queue=layout.net_queue)
        faults = None  # the worker's, only where a test or `pingpong stress` asked for one
        if worker.kind == self.crash_worker and (self.crash_at_tick is not None or self.slow_turn_s):
            faults = FaultPlan(self.crash_at_tick if worker.restarts == 0 else None, self.crash_kind, self.slow_turn_s)
        options = replace(self.options, handles=handles, faults=faults)
        if worker.kind == "gateway" and worker.ready.get("endpoint"):
            # a restarted gateway listens where its clients already are, its feed included
            options = replace(options, gateway=replace(options.gateway, bind=worker.ready["endpoint"],
                                                       feed_bind=worker.ready.get("feed") or ""))
        worker.process = self._ctx.Process(
            target=worker_main, name=f"pingpong-{worker.kind}",
            args=(worker_target(worker.kind), child, self.arena.layout(), worker.index, self.compiled, options))
        worker.conn = parent
        try:
            worker.process.start()
        finally:
            child.close()
        worker.finished = False

    def _await_ready(self, worker: _Worker) -> None:
        """Until the worker says ready: bounded by its silence (READY_TIMEOUT_S without a heartbeat,
        which a starting worker's thread keeps fresh while it compiles) and by STARTUP_LIMIT_S."""
        row = self.arena["status"].array[worker.index]
        start = time.monotonic()
        while True:
            now = time.monotonic()
            # The heartbeat is 0 until the worker has attached its row: count from our start then.
            silent = now - max(float(row["heartbeat"]), start)
            if silent > READY_TIMEOUT_S:
                raise TimeoutError(f"{worker.kind} worker silent for {silent:.0f} s while starting (hung?)")
            if now - start > STARTUP_LIMIT_S:
                raise TimeoutError(f"{worker.kind} worker not ready within {STARTUP_LIMIT_S:.0f} s")
            ready = multiprocessing.connection.wait([worker.conn, worker.process.sentinel], timeout=0.5)
            if worker.conn in ready:
                kind, payload = worker.conn.recv()
                if kind == "ready":
                    worker.ready = payload if isinstance(payload, dict) else {}
                    return
                if kind == "error" and payload.get("refused"):
                    raise WorkerRefused(payload["message"])
                if kind == "error":
                    raise WorkerFailed(f"{worker.kind} worker failed while starting:\n{payload['traceback']}")
            elif worker.process.sentinel in ready:
                raise WorkerFailed(f"{worker.kind} worker exited with code {worker.process.exitcode} while starting")

    def _restart(self, worker: _Worker, why: str, start_wall: float, detail: str = "") -> None:
        now = time.monotonic()
        worker.restarted_at = [t for t in worker.restarted_at if now - t < RESTART_WINDOW_S]
        if len(worker.restarted_at) >= self.restart_budget:
            raise WorkerFailed(f"{worker.kind} worker {why}; past its restart budget ({self.restart_budget} "
                               f"restarts within {RESTART_WINDOW_S:.0f} s, {worker.restarts} in all)\n{detail}")
        log.warning("%s worker %s; restarting it from the last consistent snapshot (restart %d)", worker.kind, why,
                    worker.restarts + 1)
        self._reap(worker, "restart")
        worker.restarted_at.append(now)
        worker.restarts += 1
        self.arena["status"].array[worker.index]["restarts"] = worker.restarts
        self._start(worker)
        self._await_ready(worker)
        worker.conn.send(("go", start_wall))

    def _reap(self, worker: _Worker, why: str = "shutdown") -> None:
        """Stop one worker: ask (saying why: runtime.control.StopRequested), wait (bounded), kill."""
        process = worker.process
        if process is None:
            return
        if process.pid is None:  # never started (Process.start raised): nothing to stop
            worker.conn.close()
            worker.process = None
            return
        if process.is_alive():
            try:
                worker.conn.send(("stop", why))
            except (OSError, BrokenPipeError):
                pass
            process.join(STOP_TIMEOUT_S)
        if process.is_alive():  # a worker ignores SIGTERM (runtime.control.worker_main): kill it
            process.kill()
            process.join(STOP_TIMEOUT_S)
        worker.conn.close()
        process.close()
        worker.process = None

    def _watch(self, start_wall: float, progress=None) -> None:
        """Until every worker is done: handle reports, deaths and stalls (all waits bounded)."""
        status = self.arena["status"].array
        latest = np.zeros(1, self.arena["physics"].dtype)
        while not all(w.finished for w in self._workers):
            live = [w for w in self._workers if not w.finished]
            handles = [w.conn for w in live] + [w.process.sentinel for w in live]
            ready = multiprocessing.connection.wait(handles, timeout=0.25)
            if progress is not None:
                self.arena["physics"].snapshot(latest)
                progress(latest[0])
            for worker in live:
                if worker.conn in ready:
                    try:
                        kind, payload = worker.conn.recv()
                    except EOFError:
                        kind, payload = "eof", None
                    if kind == "done":
                        worker.finished = True
                        worker.report = payload if isinstance(payload, dict) else {}
                        continue
                    if kind == "error":
                        worker.raised += 1
                        why = f"raised {payload['type']}: {payload['message']}"
                        log.error("%s worker %s\n%s", worker.kind, why, payload["traceback"])
                        self._restart(worker, why, start_wall, payload["traceback"])
                        continue
                if not worker.finished and worker.process.sentinel in ready:
                    self._restart(worker, f"died (exit code {worker.process.exitcode})", start_wall)
                elif not worker.finished:
                    row = status[worker.index]
                    silent = time.monotonic() - float(row["heartbeat"])
                    if row["state"] == WorkerState.RUNNING and silent > STALL_TIMEOUT_S:
                        self._restart(worker, f"stalled ({silent:.1f} s without a heartbeat)", start_wall)

    def run(self, progress=None, on_ready=None) -> ProcessRunResult:
        """Run to the end; `progress(snapshot_record)` is called about four times a second;
        `on_ready({kind: ready report})` once every worker is ready (the gateway's endpoint)."""
        stops = StopSignals().install()
        started = time.monotonic()
        end = "shutdown"  # what the workers are told as they stop (the gateway's goodbye)
        try:
            # Where the computing workers outnumber the cores, a side that polls before it sleeps
            # holds a core another worker needs: the hand-offs sleep at once.
            self.layout = build_layout(self.compiled, self.kinds, self.ticks, self.trace, self.frame_every, self._ctx,
                                       self.options.speculate, 0.0 if _contended(self.kinds) else SPIN_S)
            self.arena = self.layout.arena
            stops.arm()  # a stop signal that came while the segments were being made raises here
            self._workers = [_Worker(kind, i) for i, kind in enumerate(self.kinds)]
            for worker in self._workers:
                self._start(worker)
            for worker in self._workers:
                self._await_ready(worker)
            if on_ready is not None:
                on_ready({w.kind: w.ready for w in self._workers})
            start_wall = time.monotonic()
            startup = start_wall - started
            for worker in self._workers:
                worker.conn.send(("go", start_wall))
            self._watch(start_wall, progress)
            wall = time.monotonic() - start_wall
            return self._collect(wall, startup)
        except Exception:
            end = "error"  # not Ctrl-C or SIGTERM: the run failed
            raise
        finally:
            stops.shield()  # more signals cannot cut the stop short
            if self.layout is not None:
                self.layout.stop_turns()  # an AI or net worker waiting for its turn exits at once
                for worker in self._workers:
                    self._reap(worker, end)
                self.layout.close()
            stops.restore()

    def raised(self) -> dict[str, int]:
        """Per worker kind, the exceptions its workers shipped back so far (each restarted it)."""
        return {w.kind: w.raised for w in self._workers}

    def _collect(self, wall: float, startup: float) -> ProcessRunResult:
        final = np.zeros(1, physics_snapshot_dtype(len(self.scene.bats)))
        self.arena["physics"].snapshot(final)
        total = int(final[0]["world"]["events_total"])
        log = self.arena["events"].array
        first = max(0, total - EVENT_LOG_CAPACITY)
        events = np.array([log[i % EVENT_LOG_CAPACITY] for i in range(first, total)], dtype=CONTACT_DTYPE)
        status = self.arena["status"].array
        workers = {
            w.kind: {
                "restarts": w.restarts,
                "raised": w.raised,
                "late_ticks": int(status[w.index]["late_ticks"]),
                "max_late_s": float(status[w.index]["max_late_s"]),
                "busy_s": float(status[w.index]["busy_s"]),
                "handoff_s": float(status[w.index]["handoff_s"]),
                # the CPU time and the context switches (slept, preempted) of its last incarnation
                # from the run's start (its own work is wall time)
                **({k: w.report[k] for k in ("cpu_s", "switches") if k in w.report}),
                **({"gateway": w.report.get("gateway", {})} if w.kind == "gateway" else {}),
                **({k: w.report[k] for k in ("remote_inputs_refused", "remote_brake_ticks") if k in w.report}),
                # the physics' AI turns (since its last start), at the control ticks where a player
                # could decide (the others skipped): those at which a player decided, and those whose
                # answer it waited for; its cloth net ticks: handed to
                # the net worker with the ball (waited for), and without it (not waited for), and
                # the ball ticks given again because the net's answer took longer than handoff_s;
                # its hand-offs' wall time split into the waits for the net and for the AI; a
                # speculating run's go-backs and the ticks they stepped again
                **({k: w.report[k] for k in ("ai_turns", "ai_skipped", "ai_decisions", "ai_waited_turns", "net_ball_ticks", "net_runs", "net_free_ticks",
                                             "net_turns_again", "handoff_net_s", "handoff_ai_s", "bot_errors", "stopped",
                                             "net_rollbacks", "net_ticks_again")
                    if k in w.report} if w.kind == "physics" else {}),
                # the AI worker's thinking between its turns, and the strokes it had to finish late;
                # a speculating run's decisions taken back
                **({k: w.report[k] for k in ("think_s", "late_thoughts", "late_thinking_s", "turns", "decisions", "longest_turn_s",
                                             "bot_faults", "taken_back") if k in w.report} if w.kind == "ai" else {}),
                # the cloth net's ticks stepped awake (its cost: a sleeping net's ticks cost nothing)
                # and held in its linear tail (a count each)
                **({k: w.report[k] for k in ("awake_ticks", "tail_ticks") if k in w.report} if w.kind == "net" else {}),
            }
            for w in self._workers
        }
        trace = self.arena["trace"].array.copy() if self.trace else None
        ticks = int(final[0]["world"]["tick"])
        points = frames = None
        if self.scene.match is not None:
            points = self.arena["points"].array[: int(final[0]["rally"]["points_total"])].copy()
            if self.frame_every:
                frames = self.arena["frames"].array[: ticks // self.frame_every + 1].copy()
        return ProcessRunResult(scene=self.scene, mode=self.mode, ticks=ticks, wall_seconds=wall,
                                startup_seconds=startup, final=final[0], events=events, events_total=total,
                                workers=workers, trace=trace, points=points, frames=frames)


def first_difference(a: np.ndarray, b: np.ndarray) -> int | None:
    """Index of the first record whose bytes differ, None if all equal (bit-for-bit check)."""
    if a.shape != b.shape or a.dtype != b.dtype:
        raise ValueError(f"traces differ in shape or dtype: {a.shape} {a.dtype} vs {b.shape} {b.dtype}")
    rows_a = a.view(np.uint8).reshape(len(a), -1)
    rows_b = b.view(np.uint8).reshape(len(b), -1)
    differs = np.flatnonzero((rows_a != rows_b).any(axis=1))
    return int(differs[0]) if len(differs) else None
