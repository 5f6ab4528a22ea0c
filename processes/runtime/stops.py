"""StopSignals: SIGTERM and SIGINT on a process that owns workers and shared memory, in every phase.

A stop signal is one request, however many times it comes. While the run's resources are being
built it is held (a half-built arena is not torn down by an exception in the middle of creating
a segment); once they are built it raises (SIGTERM: SystemExit(143), SIGINT: KeyboardInterrupt),
so the owner's `finally` stops the workers and removes the segments; while that cleanup runs,
later signals are counted and ignored, so a second Ctrl-C or `kill` cannot cut it short (which
left segments for Python's resource tracker, BufferError tracebacks from views still open, and
a gateway killed before it wrote its last counters). After a stop signal was raised, restore()
leaves both signals ignored instead of putting the old handlers back: the owner still has its
last words to say (`pingpong serve` prints its end line), which SIGTERM's default action would
cut short. A signal that was ignored when the handlers were installed (a shell's background job
ignores SIGINT) stays ignored.
"""
from __future__ import annotations

import signal
import threading

STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT)


class StopSignals:
    """The handlers of SIGTERM and SIGINT between install() and restore(): held, then raising
    (arm), then ignored (shield). Only the main thread can install handlers; elsewhere every
    method does nothing and the process's handlers stay as they are."""

    def __init__(self):
        self._previous: dict[int, object] = {}
        self._mode = "hold"
        self.held: int | None = None  # the first signal received while held
        self.raised = False  # whether a stop signal was raised: the process is stopping on it
        self.ignored = 0  # signals received while shielded

    def install(self) -> StopSignals:
        if threading.current_thread() is not threading.main_thread():
            return self
        for signum in STOP_SIGNALS:
            previous = signal.getsignal(signum)
            if signum == signal.SIGINT and previous == signal.SIG_IGN:
                continue
            self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def arm(self) -> None:
        """From now on a stop signal raises; one held so far raises now."""
        self._mode = "raise"
        if self.held is not None:
            self.raised = True
            _raise_for(self.held)

    def shield(self) -> None:
        """From now on a stop signal is counted and ignored: the stop is under way."""
        self._mode = "ignore"

    def restore(self) -> None:
        """The handlers as they were before install(); ignored, after a stop signal was raised."""
        for signum, previous in self._previous.items():
            signal.signal(signum, signal.SIG_IGN if self.raised else previous)
        self._previous.clear()

    def _handle(self, signum, frame) -> None:
        if self._mode == "raise":
            self._mode = "ignore"  # one request: the next one finds the stop under way
            self.raised = True
            _raise_for(signum)
        elif self._mode == "hold":
            if self.held is None:
                self.held = signum
        else:
            self.ignored += 1


def ignore_stop_signals() -> None:
    """Ignore SIGTERM and SIGINT from now on: for a process whose run has ended and whose exit is
    bounded (its last counters printed), which a later signal would only cut short."""
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)


def _raise_for(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise SystemExit(128 + signum)
