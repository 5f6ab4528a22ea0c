"""Fault injection, for tests and `pingpong stress`: a worker that dies, raises or answers late on
purpose. A production run has no FaultPlan (RunOptions.faults is None): its loops only ask
whether there is one."""
from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass

CRASH_KINDS = ("kill", "raise")


class InjectedFault(RuntimeError):
    """What a worker raises when its FaultPlan asks it to (kind "raise")."""


@dataclass(frozen=True)
class FaultPlan:
    """What one incarnation of one worker is told to do wrong.

    Attributes:
        crash_at_tick: the worker ends at this tick (None: never), as each worker's loop says
            where (after publishing it, after a turn that holds it ...), the way `kind` says:
            "kill" SIGKILLs it (a worker that dies), "raise" raises InjectedFault (a worker's
            exception, shipped to the supervisor with its traceback like any other).
        slow_turn_s: s, the worker answers each turn (the AI, the net) or steps each tick of a
            match (the physics) this much later, as one descheduled on a busy machine does.
    """

    crash_at_tick: int | None = None
    kind: str = "kill"
    slow_turn_s: float = 0.0

    def __post_init__(self):
        if self.kind not in CRASH_KINDS:
            raise ValueError(f"crash kind must be one of {', '.join(CRASH_KINDS)}, got {self.kind!r}")

    def crashes_in(self, first: int, end: int) -> bool:
        """Is the crash tick in first .. end - 1 (the ticks a turn or a run held)?"""
        return self.crash_at_tick is not None and first <= self.crash_at_tick < end

    def crash(self, tick: int) -> None:
        """End this worker now, at `tick`, as `kind` says."""
        if self.kind == "raise":
            raise InjectedFault(f"fault injection: raised at tick {tick}")
        os.kill(os.getpid(), signal.SIGKILL)

    def delay(self) -> None:
        """Answer late: slow_turn_s of sleep (a descheduled worker, not synchronisation)."""
        if self.slow_turn_s:
            time.sleep(self.slow_turn_s)
