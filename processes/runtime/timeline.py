"""What a worker does when: its changes of state (working, waiting and for whom, idle) stamped
with the monotonic clock, which every process of the machine shares, so the workers' timelines
line up (`pingpong bench match --timeline`)."""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

# A worker's states, in the order a timeline's picture draws them.
WORK, WAIT_NET, WAIT_AI, IDLE, THINK = range(5)
STATE_NAMES = ("work", "wait for the net", "wait for the AI", "idle", "think")
MARK_DTYPE = np.dtype([("t", "<f8"), ("state", "<i8")])
CAPACITY = 1 << 20  # marks a worker keeps (16 MiB); later ones are dropped and counted


class Timeline:
    """A worker's marks: mark(state) at each change of state, save() at its end.

    Args:
        directory: where save() writes `KIND-PID.npy` (one file a worker process, so a
            restarted worker adds its own). kind: the worker's name.
    """

    def __init__(self, directory: str, kind: str):
        self.path = Path(directory) / f"{kind}-{os.getpid()}.npy"
        self.marks = np.zeros(CAPACITY, MARK_DTYPE)
        self._t = self.marks["t"]
        self._state = self.marks["state"]
        self.count = 0
        self.dropped = 0
        self.state = -1
        self._clock = time.monotonic

    def mark(self, state: int) -> None:
        """From now on the worker is in `state` (a mark only where the state changes)."""
        if state == self.state:
            return
        self.state = state
        k = self.count
        if k < CAPACITY:
            self._t[k] = self._clock()
            self._state[k] = state
            self.count = k + 1
        else:
            self.dropped += 1

    def save(self) -> None:
        self.mark(IDLE)
        np.save(self.path, self.marks[:self.count])


def load(directory: str) -> dict[str, np.ndarray]:
    """{worker kind: its marks in time order} from a run's timeline directory (a restarted
    worker's files joined to its predecessor's)."""
    runs: dict[str, list[np.ndarray]] = {}
    for path in sorted(Path(directory).glob("*.npy")):
        runs.setdefault(path.stem.rsplit("-", 1)[0], []).append(np.load(path))
    return {kind: np.sort(np.concatenate(parts), order="t") for kind, parts in runs.items()}


def intervals(marks: np.ndarray, end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(starts, durations, states) of the spans between a worker's marks, the last one up to `end`."""
    starts = marks["t"]
    stops = np.append(starts[1:], max(end, float(starts[-1]) if len(starts) else end))
    return starts, stops - starts, marks["state"]


def _working_edges(timelines: dict[str, np.ndarray], start: float, end: float) -> list[tuple[float, int, str]]:
    """(time, +1 or -1, worker kind) at each start and end of a worker's work (state WORK or
    THINK) inside `start` .. `end`, in time order."""
    edges = []
    for kind, marks in timelines.items():
        starts, lengths, states = intervals(marks, end)
        working = (states == WORK) | (states == THINK)
        for s, n in zip(starts[working], lengths[working]):
            lo, hi = max(s, start), min(s + n, end)
            if hi > lo:
                edges += [(lo, 1, kind), (hi, -1, kind)]
    edges.sort()
    return edges


def busy_share(timelines: dict[str, np.ndarray], start: float, end: float) -> dict[str, float]:
    """Shares of the wall time from `start` to `end` (s, monotonic) in which no worker, exactly
    one, and two or more worked (state WORK or THINK): on two cores, the last is the share in
    which both cores worked for the run."""
    shares = [0.0, 0.0, 0.0]
    level, last = 0, start
    for t, step, _ in _working_edges(timelines, start, end):
        shares[min(level, 2)] += t - last
        level, last = level + step, t
    shares[min(level, 2)] += end - last
    total = max(end - start, 1e-12)
    return {"none": shares[0] / total, "one": shares[1] / total, "two": shares[2] / total}


def shares_beside(timelines: dict[str, np.ndarray], kind: str, start: float, end: float) -> dict[str, float]:
    """Shares of the wall time from `start` to `end` by who worked: `kind` (whoever else did too),
    and while `kind` did not, each set of the others that worked ("physics", "physics+ai", ...)
    and "none". On a run whose longest chain is `kind`'s work, the wall time is its work plus
    the others' work alone: what can only get shorter by making either cheaper."""
    shares: dict[str, float] = {}
    working: set[str] = set()
    last = start
    for t, step, who in _working_edges(timelines, start, end) + [(end, 0, "")]:
        key = kind if kind in working else "+".join(sorted(working)) or "none"
        shares[key] = shares.get(key, 0.0) + t - last
        if step > 0:
            working.add(who)
        elif step < 0:
            working.discard(who)
        last = t
    total = max(end - start, 1e-12)
    return {key: value / total for key, value in shares.items()}
