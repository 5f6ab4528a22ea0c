"""SnapshotPacer: when the gateway's next snapshot is due, on the match clock, and how fast that
clock runs against the wall clock (snapshot.realtime_factor); SendLog: when each one went out."""
from __future__ import annotations

import time
from collections import deque

import numpy as np

RATE_WINDOW_S = 1.0  # snapshot.realtime_factor: the match time run over this much wall time
SEND_LOG_SIZE = 1 << 17  # snapshots a SendLog keeps (18 min at 120 Hz): 2 MB


class SnapshotPacer:
    """One snapshot every 1/snapshot_hz s of match time (`ticks`, on a grid of ticks, so the
    poll loop's latency does not drift it), at most snapshot_hz a wall second (a grid of wall
    times, restarted from now after a stall); while the clock stands, its tick again each wall
    period. A server slower than realtime thus sends them as often in match time and less often
    in wall time. A clock that stops between two ticks of the grid (a paused match) has its
    standing tick sent once it stood a whole period, and again each period after.

    Args:
        snapshot_hz: snapshots per second of match time. dt: s, the tick.
    """

    def __init__(self, snapshot_hz: int, dt: float):
        self.period_s = 1.0 / snapshot_hz
        self.ticks = max(1, round(self.period_s / dt))
        self.realtime_factor = 0.0  # match s per wall s over RATE_WINDOW_S; 0 until measured
        self._next_wall = 0.0
        self._last_tick: int | None = None  # the tick of the last snapshot sent
        self._last_wall = 0.0  # when it was sent
        self._due_tick = 0  # from this tick on the next one is due
        self._seen_tick: int | None = None  # the tick of the latest call
        self._seen_since = 0.0  # since when the clock has stood at it
        self._samples: deque[tuple[float, float]] = deque()  # (wall s, match s)

    def due(self, now: float, tick: int, match_s: float) -> bool:
        """Measure the clock at `now` (s) and say whether the snapshot of `tick` (at match_s s)
        is due; if it is, it counts as sent."""
        self._measure(now, match_s)
        if tick != self._seen_tick:
            self._seen_tick, self._seen_since = tick, now
        if now < self._next_wall:
            return False
        last = self._last_tick
        standing = now - self._seen_since >= 0.99 * self.period_s  # 0.99: a float clock's rounding
        if last is not None and last < tick < self._due_tick and not standing:
            return False  # the match clock has not yet reached the next one's tick (a slow server)
        if tick == last and now - self._last_wall < 0.99 * self.period_s:
            return False  # a clock slower than a tick per period has not stood a whole period yet
        self._next_wall = max(self._next_wall + self.period_s, now)
        if last is not None and tick < last:
            self._due_tick = tick + self.ticks  # the clock went back (a restarted physics)
        elif tick != last and tick >= self._due_tick:  # (a standing tick off the grid keeps it)
            self._due_tick = max(self._due_tick + self.ticks, tick + 1)
        self._last_tick, self._last_wall = tick, now
        return True

    def _measure(self, now: float, match_s: float) -> None:
        samples = self._samples
        if samples and match_s < samples[-1][1]:
            samples.clear()  # the clock went back: start over
        samples.append((now, match_s))
        while len(samples) > 2 and now - samples[1][0] >= RATE_WINDOW_S:
            samples.popleft()
        wall = now - samples[0][0]
        if wall >= RATE_WINDOW_S / 4:
            self.realtime_factor = (match_s - samples[0][1]) / wall


class SendLog:
    """(tick, CLOCK_MONOTONIC s) of the last SEND_LOG_SIZE snapshots the gateway published, saved
    to `path` (.npy, oldest first) when it ends (GatewayConfig.send_log_path)."""

    def __init__(self, path: str):
        self.path = path
        self.rows = np.zeros((SEND_LOG_SIZE, 2))
        self.count = 0

    def sent(self, tick: int) -> None:
        self.rows[self.count % SEND_LOG_SIZE] = tick, time.monotonic()
        self.count += 1

    def save(self) -> None:
        rows = np.roll(self.rows, -(self.count % SEND_LOG_SIZE), axis=0) if self.count > SEND_LOG_SIZE \
            else self.rows[:self.count]
        np.save(self.path, rows)
