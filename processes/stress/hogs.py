"""CpuHogs: a busy machine on demand, N Python processes spinning `while True: pass`.

Each hog runs at the default priority, as another user's job would, and dies with the process
that started it however that one ends (Linux's PR_SET_PDEATHSIG), so a killed harness leaves no
spinning process behind. `pingpong stress --scenario busy` runs its match beside them, and
`python -m tests.hogs N -- COMMAND` the test suite.
"""
from __future__ import annotations

import ctypes
import signal
import subprocess
import sys

HOG = "while True: pass"
PR_SET_PDEATHSIG = 1  # prctl(2)


def _die_with_parent() -> None:
    """In the hog, before it runs: SIGKILL when the process that started it ends, however it ends."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


class CpuHogs:
    """`n` spinning processes from start() (or entering the context) until stop() (or leaving it)."""

    def __init__(self, n: int):
        if n < 0:
            raise ValueError(f"hogs: need 0 or more, got {n}")
        self.n = n
        self.procs: list[subprocess.Popen] = []

    def start(self) -> CpuHogs:
        for _ in range(self.n - len(self.procs)):
            self.procs.append(subprocess.Popen([sys.executable, "-c", HOG], stdin=subprocess.DEVNULL,
                                               preexec_fn=_die_with_parent))
        return self

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self.procs]

    def stop(self) -> None:
        for proc in self.procs:
            proc.kill()
        for proc in self.procs:
            proc.wait()
        self.procs = []

    def __enter__(self) -> CpuHogs:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
