"""What a swarm client counts of the messages it receives, from their fixed header alone.

The hot path of a swarm reads the header of a snapshot or a heartbeat (magic, version, type,
sequence number, tick: wire.HEADER_DTYPE, the first 24 bytes) and its size, nothing else: enough
to count it, to find the gaps in the stream's sequence numbers and to time it against its tick. A
sample of them and every other message are decoded in full (wire.decode) to validate them;
counting decoded messages gives the same tallies (tests/processes/stress/test_tally.py).
"""
from __future__ import annotations

import struct

from processes.network import wire
from processes.network.wire import Kind

HEADER = struct.Struct("<4sHBBQq")  # wire.HEADER_DTYPE: magic, version, kind, flags, seq, tick
BY_HEADER = {wire.SIZES[Kind.SNAPSHOT]: Kind.SNAPSHOT, wire.SIZES[Kind.HEARTBEAT]: Kind.HEARTBEAT}


def header(data: bytes) -> tuple[int, int, int] | None:
    """(kind, seq, tick) of a snapshot or a heartbeat whose framing is right (the size of its
    type, magic, version, no flags); None for any other message, which the caller decodes in full."""
    kind = BY_HEADER.get(len(data))
    if kind is None:
        return None
    magic, version, kind_read, flags, seq, tick = HEADER.unpack_from(data)
    if kind_read != kind or magic != wire.MAGIC or version != wire.PROTOCOL_VERSION or flags:
        return None
    return kind, seq, tick


class Sequence:
    """The gaps in one stream's sequence numbers. The gateway numbers every message it tries to
    send a session, and its feed every message it publishes, so a gap is a message dropped at a
    high-water mark (the gateway's, or the client's own when it reads too slowly)."""

    __slots__ = ("last", "missed", "resets")

    def __init__(self, last: int = 0):
        self.last = last
        self.missed = 0
        self.resets = 0

    def see(self, seq: int) -> None:
        last = self.last
        if seq > last:
            if last:
                self.missed += seq - last - 1
        else:
            self.resets += 1  # a new gateway numbers from 1 again
        self.last = seq


class Tally:
    """One client's snapshots: how many, the first and last receipt time (CLOCK_MONOTONIC, s),
    and how often the tick went backwards."""

    __slots__ = ("snapshots", "first", "last", "last_tick", "tick_regressions")

    def __init__(self):
        self.snapshots = 0
        self.first = self.last = 0.0
        self.last_tick = -1
        self.tick_regressions = 0

    def snapshot(self, tick: int, t: float) -> None:
        if not self.snapshots:
            self.first = t  # the rate is taken between the first and the last snapshot
        self.snapshots += 1
        self.last = t
        if tick < self.last_tick:
            self.tick_regressions += 1
        self.last_tick = tick

    def rate_hz(self) -> float | None:
        """Snapshots a second between the first and the last; None with fewer than two."""
        if self.snapshots < 2 or self.last <= self.first:
            return None
        return (self.snapshots - 1) / (self.last - self.first)
