"""What every worker process shares: its state enum, status row, start handshake, entry point and command loop.

A worker is started by the supervisor with a control pipe (commands in, reports out: pickled,
but only at start, end and on errors, never per tick), attaches the run's shared memory, and
reports its progress in its row of the shared status array. It ignores SIGINT: Ctrl-C reaches
the whole process group, and the supervisor alone decides how the run ends.
"""
from __future__ import annotations

import enum
import os
import resource
import signal
import threading
import time
import traceback

import numpy as np

from processes.runtime.shm import Arena

STATUS_DTYPE = np.dtype([
    ("pid", "<i8"),
    ("state", "<i4"),  # WorkerState
    ("restarts", "<i4"),
    ("tick", "<i8"),  # ticks completed
    ("heartbeat", "<f8"),  # time.monotonic() of the last sign of life
    ("late_ticks", "<i8"),  # realtime: ticks that started after their due time
    ("max_late_s", "<f8"),
    ("busy_s", "<f8"),  # wall time spent on its own work
    ("handoff_s", "<f8"),  # wall time spent handing off to other workers and waiting for them
])



def _switches() -> tuple[int, int]:
    """This process's context switches so far: (voluntary, involuntary)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_nvcsw, usage.ru_nivcsw

class WorkerState(enum.IntEnum):
    NONE = 0
    STARTING = 1
    READY = 2
    RUNNING = 3
    DONE = 4
    FAILED = 5
    STOPPED = 6


# Starting, a worker imports, then compiles or loads its numba kernels: with a cold cache on a
# loaded 2-core machine that has taken over 120 s. A thread keeps its heartbeat fresh meanwhile
# (_beat_while_starting), so the supervisor tells a slow start from a hung one: silent for
# READY_TIMEOUT_S is hung; a start longer than STARTUP_LIMIT_S in all is given up too.
READY_TIMEOUT_S = 120.0
STARTUP_LIMIT_S = 1800.0
STARTUP_BEAT_S = 1.0
# A ready worker waits for "go" until every sibling is ready too; an orphan still stops at once
# (Control.check_parent).
GO_TIMEOUT_S = STARTUP_LIMIT_S


class StopRequested(Exception):
    """The supervisor asked the worker to stop, or went away.

    reason: why the run stops, from the stop command: "shutdown" (an ordered stop, or the
    supervisor gone), "error" (the run failed: a worker past its restart budget), "restart"
    (this worker alone is replaced).
    """

    def __init__(self, reason: str = "shutdown"):
        super().__init__(reason)
        self.reason = reason


class Control:
    """The worker's side of its control pipe and status row."""

    HEARTBEAT_S = 0.05

    def __init__(self, conn, status_row: np.ndarray, tick_word: memoryview | None = None):
        """tick_word: a one-element int64 memoryview of status_row's "tick" (status_tick_word):
        beat() writes through it, far cheaper than a numpy field, once a physics chunk."""
        self.conn = conn
        self.row = status_row
        self._tick_word = tick_word
        self._parent = os.getppid()
        self._next_check = 0.0
        self._cpu_start = time.process_time()  # from the run's start on (start())
        self._switches_start = _switches()

    def start(self, report=None) -> float:
        """The start handshake: say ready (with `report`), wait (bounded) for "go", run.

        Returns go's payload: the supervisor's time.monotonic() at which the run starts.
        """
        self.set_state(WorkerState.READY)
        self.send("ready", report)
        start_wall = self.wait_for("go", GO_TIMEOUT_S)
        self.set_state(WorkerState.RUNNING)
        self._cpu_start = time.process_time()
        self._switches_start = _switches()
        return start_wall

    def finish(self, busy_s: float, handoff_s: float, report: dict) -> None:
        """Add the worker's own work and its hand-offs to its status row; say done with `report`,
        and with the CPU time this incarnation used since the run started (cpu_s: its own work
        counts wall time, in which a worker another one took the core from counts too) and its
        context switches since (switches: (voluntary, involuntary), getrusage's: it slept, or
        the scheduler took its core)."""
        self.row["busy_s"] = float(self.row["busy_s"]) + busy_s
        self.row["handoff_s"] = float(self.row["handoff_s"]) + handoff_s
        switches = tuple(now - then for now, then in zip(_switches(), self._switches_start))
        self.send("done", {**report, "cpu_s": time.process_time() - self._cpu_start, "switches": switches})

    def set_state(self, state: WorkerState) -> None:
        self.row["state"] = state
        self.row["heartbeat"] = time.monotonic()

    def send(self, kind: str, payload=None) -> None:
        self.conn.send((kind, payload))

    def wait_for(self, expected: str, timeout: float):
        """Block (bounded) for one command; returns its payload."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"worker {os.getpid()}: no {expected!r} from the supervisor within {timeout} s")
            if self.conn.poll(min(left, 0.2)):
                kind, payload = self.conn.recv()
                if kind == "stop":
                    raise StopRequested(payload or "shutdown")
                if kind == expected:
                    return payload
            self.check_parent()

    def check_parent(self) -> None:
        if os.getppid() != self._parent:
            raise StopRequested()

    def beat(self, tick: int) -> None:
        """Per tick: record progress; every HEARTBEAT_S also look for a stop command."""
        now = time.monotonic()
        if self._tick_word is not None:
            self._tick_word[0] = tick
        else:
            self.row["tick"] = tick
        if now >= self._next_check:
            self._next_check = now + self.HEARTBEAT_S
            self.row["heartbeat"] = now
            if self.conn.poll(0):
                kind, payload = self.conn.recv()
                if kind == "stop":
                    raise StopRequested(payload or "shutdown")
            self.check_parent()


def status_tick_word(status: np.ndarray, index: int) -> memoryview:
    """The "tick" of row `index` of a STATUS_DTYPE array as a one-element int64 memoryview."""
    start = index * STATUS_DTYPE.itemsize + STATUS_DTYPE.fields["tick"][1]
    return memoryview(status.view(np.uint8)).cast("B")[start:start + 8].cast("q")


def _beat_while_starting(row, started: threading.Event) -> None:
    """Keep a STARTING worker's heartbeat fresh (a daemon thread; numba compiles in the main one)."""
    while not started.wait(STARTUP_BEAT_S) and row["state"] == WorkerState.STARTING:
        row["heartbeat"] = time.monotonic()


def worker_main(target, conn, layout: dict, status_index: int, compiled, options) -> None:
    """Process entry point: attach the run's memory, run `target(control, arena, compiled, options)`
    (a worker function of the processes.workers registry; compiled: the run's
    engine.physics.compiled.CompiledScene), ship any error back with its traceback."""
    # Ctrl-C (the terminal's process group) and a SIGTERM to the whole group (systemd, `kill --
    # -PGID`) are the supervisor's to act on: it stops its workers in order (the gateway's goodbyes
    # and last counters first), and kills one that does not stop.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    arena = Arena.attach(layout)
    status = arena["status"].array
    row = status[status_index]
    row["pid"] = os.getpid()
    control = Control(conn, row, status_tick_word(status, status_index))
    control.set_state(WorkerState.STARTING)
    started = threading.Event()
    threading.Thread(target=_beat_while_starting, args=(row, started), name="startup-heartbeat", daemon=True).start()
    try:
        target(control, arena, compiled, options)
        control.set_state(WorkerState.DONE)
    except StopRequested:
        control.set_state(WorkerState.STOPPED)
    except BaseException as exc:  # noqa: BLE001 - everything goes back to the supervisor
        control.set_state(WorkerState.FAILED)
        try:
            # a ValueError is the run's input refused (a bot's setup, a scene): the user reads its message
            control.send("error", {"type": type(exc).__name__, "message": str(exc), "traceback": traceback.format_exc(),
                                   "refused": isinstance(exc, ValueError)})
        except (OSError, BrokenPipeError):
            pass
    finally:
        started.set()
        control._tick_word.release()
        del row, control, status
        arena.close()
        conn.close()
