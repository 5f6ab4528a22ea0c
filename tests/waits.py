"""How a test waits: for an event, with one long safety deadline, and a failure that names what
was awaited and what came instead.

A deadline here is a safety net against a hang, not a guess at how fast the machine is: a cold
numba cache, a slower CPU or other jobs on the same cores stretch every wait, and none of them
is a failure of the product. So every wait of the suite (a line, a file, a socket, a page's
counter, a subprocess) is bounded by DEADLINE_S. pytest-timeout's per-test alarm
(`timeout` in pyproject.toml) is longer still, ALARM_DEADLINES times it, because one test may
wait for several events in a row; the alarm catches a wait that has no deadline at all.
"""
from __future__ import annotations

import os
import queue
import select
import subprocess
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any

DEADLINE_S = 600.0  # s: the bound of any one wait of a test
ALARM_DEADLINES = 3  # the per-test alarm, in DEADLINE_S (pyproject.toml; tests/test_waits.py keeps them so)
POLL_S = 0.01  # s: how often a condition without an event of its own (a shared flag, a file) is polled


class Deadline:
    """A point DEADLINE_S (or `seconds`) from now on the monotonic clock."""

    def __init__(self, seconds: float = DEADLINE_S):
        self.seconds = seconds
        self.end = time.monotonic() + seconds

    def left(self) -> float:
        """s left, never below 0."""
        return max(0.0, self.end - time.monotonic())

    def expired(self) -> bool:
        return time.monotonic() >= self.end


def wait_for(check: Callable[[], Any], awaited: str, seen: Callable[[], Any] | None = None,
             seconds: float = DEADLINE_S, poll_s: float = POLL_S) -> Any:
    """check()'s first truthy value, calling it every poll_s until the deadline.

    Polling a condition with a deadline, not a sleep used as a handshake: check() reads the state
    of another process or thread. On expiry: AssertionError naming `awaited` and what seen()
    (default: check()'s last value) shows."""
    deadline = Deadline(seconds)
    while True:
        value = check()
        if value:
            return value
        if deadline.expired():
            raise AssertionError(f"{awaited}: not within {seconds:.0f} s; saw {seen() if seen else value!r}")
        time.sleep(poll_s)


def line(proc: subprocess.Popen, awaited: str, seconds: float = DEADLINE_S) -> str:
    """The next line `proc` writes to its stdout (a text pipe). Fails naming `awaited` if none
    comes within the deadline or the process ends first, with its exit status and stderr's start.

    A thread reads the pipe: select() on the pipe alone would miss a second line that the first
    readline() already pulled into the file's buffer, and wait for a line that has come."""
    reader = _reader(proc)
    try:
        text = reader.lines.get(timeout=seconds)
    except queue.Empty:
        raise AssertionError(f"{awaited}: no line within {seconds:.0f} s (process "
                             f"{'running' if proc.poll() is None else f'ended, status {proc.returncode}'})") from None
    if text is None:
        reader.lines.put(None)  # the end stays the end for the next caller
        status = proc.poll()
        raise AssertionError(f"{awaited}: the process closed its output first (status {status}); stderr: {_stderr(proc)}")
    return text


def rest(proc: subprocess.Popen, awaited: str, seconds: float = DEADLINE_S) -> str:
    """What `proc` writes to its stdout after the lines line() returned, up to the end of the pipe."""
    reader = _reader(proc)
    reader.join(seconds)
    if reader.is_alive():
        raise AssertionError(f"{awaited}: the output has not ended within {seconds:.0f} s")
    texts = []
    while (text := reader.lines.get_nowait()) is not None:
        texts.append(text)
    reader.lines.put(None)
    return "".join(texts)


class _Reader(threading.Thread):
    """Reads a text stream line by line into a queue; None marks its end."""

    def __init__(self, stream):
        super().__init__(daemon=True)
        self.stream = stream
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.start()

    def run(self) -> None:
        try:
            for text in iter(self.stream.readline, ""):
                self.lines.put(text)
        except (OSError, ValueError):  # the test closed the pipe
            pass
        self.lines.put(None)


_READERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_READERS_LOCK = threading.Lock()


def _reader(proc: subprocess.Popen) -> _Reader:
    with _READERS_LOCK:
        if proc not in _READERS:
            _READERS[proc] = _Reader(proc.stdout)
        return _READERS[proc]


def exited(proc: subprocess.Popen, awaited: str, seconds: float = DEADLINE_S) -> int:
    """proc's exit status once it ends; fails naming `awaited` if it is still running at the deadline."""
    try:
        return proc.wait(seconds)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"{awaited}: still running after {seconds:.0f} s") from None


def run(args: list[str], **kwargs) -> subprocess.CompletedProcess:
    """subprocess.run(args, ...) bounded by the deadline; a run still going then fails the test,
    saying which command it was and what it had written."""
    kwargs.setdefault("timeout", DEADLINE_S)
    try:
        return subprocess.run(args, **kwargs)
    except subprocess.TimeoutExpired as late:
        raise AssertionError(f"{' '.join(map(str, args))[:200]}: still running after {late.timeout:.0f} s; "
                             f"stdout: {_text(late.stdout)[-400:]!r} stderr: {_text(late.stderr)[-400:]!r}") from None


def _text(data) -> str:
    if data is None:
        return ""
    return data.decode(errors="replace") if isinstance(data, bytes) else data


def _stderr(proc: subprocess.Popen) -> str:
    """What is waiting on proc's stderr pipe now (at most 64 kB), without blocking: its children
    may hold the pipe open after it ended."""
    if proc.stderr is None or proc.stderr.closed:
        return "(not captured)"
    ready, _, _ = select.select([proc.stderr], [], [], 0)
    return repr(_text(os.read(proc.stderr.fileno(), 65536))[-800:]) if ready else "(nothing)"
