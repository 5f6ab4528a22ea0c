"""Lock arbitration: bounded waits, one global order of acquisition, recovery from dead holders.

Each lock is one byte of a per-run lock file, taken with a POSIX record lock (fcntl F_SETLKW).
The kernel releases a record lock when its holder dies, which multiprocessing.Lock does not,
so a SIGKILLed holder never hangs the others. Every wait is bounded: a blocking wait is cut by
an interval timer (main thread) or replaced by polling with backoff (other threads). The
holder's pid and the time it took the lock live in shared memory, so a timeout names who holds
the lock, and the next holder sees that the previous one never released it (it died) and says
so: the data the lock protects may be half-written and must be checked (see mailbox.py).

Record locks belong to a process, and closing any descriptor of the file drops them all, so
each process opens the lock file once (LockTable.attach) and never closes it while holding.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import threading
import time
from dataclasses import dataclass

import numpy as np

from processes.runtime.shm import SharedArray

HOLDER_DTYPE = np.dtype([
    ("pid", "<i8"),  # holder, 0 = free
    ("since", "<f8"),  # time.monotonic() when taken (same clock in every process of the machine)
    ("acquired", "<i8"),  # times taken
    ("recovered", "<i8"),  # times taken from a holder that died holding it
])


class LockTimeout(TimeoutError):
    """A lock was not acquired within its bound; the message names the lock and its holder."""


class LockOrderError(RuntimeError):
    """A process asked for locks against the global order (a potential deadlock)."""


@dataclass
class Acquired:
    """What the acquirer learns: whether the previous holder died holding the lock, and who."""

    name: str
    recovered_from: int  # pid of a dead previous holder, 0 if released cleanly


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class _Alarm(Exception):
    pass


def _raise_alarm(signum, frame):
    raise _Alarm()


class LockTable:
    """The arbitrated locks of one run, in their global order of acquisition.

    Args:
        path: the lock file (created by the supervisor, one byte per lock).
        names: lock names, lowest rank first; a process holding a lock may only take later ones.
        holders: shared (len(names),) HOLDER_DTYPE array.
    """

    def __init__(self, path: str, names: tuple[str, ...], holders: SharedArray):
        self.path = path
        self.names = tuple(names)
        self._rank = {name: i for i, name in enumerate(self.names)}
        self._holders = holders
        # Holder rows through typed memoryviews (4 words a lock): cheap on the per-tick path.
        self._ints = memoryview(holders.array.view("<i8")).cast("B").cast("q")
        self._floats = memoryview(holders.array.view("<f8")).cast("B").cast("d")
        self._pid = os.getpid()
        self._fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
        self._held: list[int] = []

    @classmethod
    def create(cls, path: str, names: tuple[str, ...], holders: SharedArray) -> "LockTable":
        with open(path, "wb") as f:
            f.write(b"\0" * max(len(names), 1))
        return cls(path, names, holders)

    def holder(self, name: str) -> tuple[int, float]:
        """(pid, seconds held) of the current holder, (0, 0) if free."""
        base = 4 * self._rank[name]
        pid = self._ints[base]
        return pid, (time.monotonic() - self._floats[base + 1]) if pid else 0.0

    def stats(self, name: str) -> dict:
        row = self._holders.array[self._rank[name]]
        return {"acquired": int(row["acquired"]), "recovered": int(row["recovered"])}

    def _try(self, rank: int) -> bool:
        try:
            fcntl.lockf(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, rank)
            return True
        except (BlockingIOError, PermissionError):
            return False

    def _wait(self, rank: int, timeout: float) -> bool:
        """Block for the lock at most `timeout` s."""
        if threading.current_thread() is threading.main_thread():
            previous = signal.signal(signal.SIGALRM, _raise_alarm)
            signal.setitimer(signal.ITIMER_REAL, timeout)
            try:
                fcntl.lockf(self._fd, fcntl.LOCK_EX, 1, rank)
                return True
            except _Alarm:
                return False
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, previous)
        # Signals only reach the main thread: poll, backing off from 50 us to 5 ms.
        deadline = time.monotonic() + timeout
        pause = 5e-5
        while time.monotonic() < deadline:
            if self._try(rank):
                return True
            time.sleep(min(pause, max(deadline - time.monotonic(), 0.0)))
            pause = min(pause * 2, 5e-3)
        return self._try(rank)

    def acquire(self, name: str, timeout: float) -> Acquired:
        """Take `name`, waiting at most `timeout` s.

        Raises:
            LockOrderError: this process holds a lock of equal or later rank.
            LockTimeout: not acquired in time; names the holder pid and whether it is alive.
        """
        rank = self._rank[name]
        if self._held and rank <= max(self._held):
            held = ", ".join(self.names[r] for r in self._held)
            raise LockOrderError(f"lock {name!r} requested while holding {held}; the global order is "
                                 f"{' < '.join(self.names)}")
        if not (self._try(rank) or self._wait(rank, timeout)):
            pid, held_for = self.holder(name)
            state = "alive" if pid and _alive(pid) else "gone"
            raise LockTimeout(f"lock {name!r} not acquired within {timeout:g} s: held by pid {pid} ({state}) "
                              f"for {held_for:.3f} s")
        base = 4 * rank  # pid, since, acquired, recovered
        previous = self._ints[base]
        recovered_from = previous if previous and previous != self._pid else 0
        if recovered_from:
            self._ints[base + 3] += 1
        self._ints[base] = self._pid
        self._floats[base + 1] = time.monotonic()
        self._ints[base + 2] += 1
        self._held.append(rank)
        return Acquired(name, recovered_from)

    def release(self, name: str) -> None:
        rank = self._rank[name]
        self._held.remove(rank)
        self._ints[4 * rank] = 0
        fcntl.lockf(self._fd, fcntl.LOCK_UN, 1, rank)

    @contextlib.contextmanager
    def hold(self, name: str, timeout: float):
        """`with table.hold("bat_inputs", 0.1) as got:` ... released on exit, also on error."""
        got = self.acquire(name, timeout)
        try:
            yield got
        finally:
            self.release(name)

    def close(self) -> None:
        self._ints.release()
        self._floats.release()
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
