"""The swarm's header-only counting (processes.stress.swarm.tally) against full decoding.

One feed, as a spectator receives it: snapshots with gaps in their sequence numbers, a tick that
goes backwards, a restarted stream, heartbeats and events between them, and broken messages (bad
magic, another version, cut short, one byte too many, a flag set, a snapshot's type byte on a
heartbeat). Counting it from the 24-byte header alone must give exactly what counting the
decoded messages gives.
"""
import random
import struct

import numpy as np

from processes.network import wire
from processes.network.wire import Kind
from processes.stress.swarm.tally import Sequence, Tally, header


def _snapshot(seq: int, tick: int) -> bytes:
    rec = np.zeros((), wire.SPECS[Kind.SNAPSHOT].dtype)
    rec["magic"], rec["version"], rec["kind"] = wire.MAGIC, wire.PROTOCOL_VERSION, Kind.SNAPSHOT
    rec["seq"], rec["tick"] = seq, tick
    rec["bat_quat"] = [[1, 0, 0, 0], [1, 0, 0, 0]]
    rec["winner"] = -1
    return rec.tobytes()


def _broken(data: bytes, rng: random.Random) -> bytes:
    how = rng.choice(["magic", "version", "short", "long", "flags", "kind"])
    buf = bytearray(data)
    if how == "magic":
        buf[0:4] = b"PPNX"
    elif how == "version":
        buf[4:6] = struct.pack("<H", wire.PROTOCOL_VERSION + 1)
    elif how == "short":
        return bytes(buf[:-1])
    elif how == "long":
        return bytes(buf) + b"\0"
    elif how == "flags":
        buf[7] = 1
    else:
        buf[6] = Kind.HEARTBEAT if buf[6] == Kind.SNAPSHOT else Kind.SNAPSHOT
    return bytes(buf)


def _feed(n: int, seed: int) -> list[bytes]:
    rng = random.Random(seed)
    out, seq, tick = [], 0, 0
    for _ in range(n):
        seq += 1 if rng.random() > 0.05 else rng.randrange(2, 6)  # gaps: messages dropped at a high-water mark
        tick += 8 if rng.random() > 0.01 else -20  # now and then a tick that goes backwards
        if rng.random() < 0.005:
            seq = 1  # a restarted gateway numbers from 1 again
        roll = rng.random()
        if roll < 0.05:
            data = wire.encode(Kind.HEARTBEAT, seq=seq, tick=max(tick, 0), ack=seq)
        elif roll < 0.08:
            data = wire.encode(Kind.EVENT, seq=seq, tick=max(tick, 0), event=wire.EventKind.POINT, winner=0, reason=1,
                               game=0, score=[1, 0], games_won=[0, 0], shots=3, rally=1)
        else:
            data = _snapshot(seq, max(tick, 0))
        out.append(_broken(data, rng) if rng.random() < 0.03 else data)
    return out


def _count(feed: list[bytes], by_header: bool) -> dict:
    tally, sequence, kinds = Tally(), Sequence(), {}
    for i, data in enumerate(feed):
        t = 0.001 * i
        if by_header:
            fixed = header(data)
            if fixed is None:
                try:  # what the swarm does with any other message: decode it in full
                    message = wire.decode(data)
                except wire.WireError:
                    kinds["dropped"] = kinds.get("dropped", 0) + 1
                    continue
                kind, seq, tick = message.kind, message.seq, message.tick
            else:
                kind, seq, tick = fixed
        else:
            try:
                message = wire.decode(data)
            except wire.WireError:
                kinds["dropped"] = kinds.get("dropped", 0) + 1
                continue
            kind, seq, tick = message.kind, message.seq, message.tick
        kinds[Kind(kind).name] = kinds.get(Kind(kind).name, 0) + 1
        sequence.see(seq)
        if kind == Kind.SNAPSHOT:
            tally.snapshot(tick, t)
    return {"snapshots": tally.snapshots, "first": tally.first, "last": tally.last, "last_tick": tally.last_tick,
            "tick_regressions": tally.tick_regressions, "missed": sequence.missed, "resets": sequence.resets,
            "kinds": kinds}


def test_header_only_counting_equals_full_decoding_on_the_same_feed():
    feed = _feed(20_000, seed=7)
    by_header, decoded = _count(feed, by_header=True), _count(feed, by_header=False)
    assert by_header == decoded
    # the feed has every case the counting must get right
    assert decoded["missed"] > 0 and decoded["resets"] > 0 and decoded["tick_regressions"] > 0
    assert decoded["kinds"]["dropped"] > 0 and decoded["kinds"]["HEARTBEAT"] > 0 and decoded["kinds"]["EVENT"] > 0


def test_header_takes_only_well_framed_snapshots_and_heartbeats():
    snapshot = _snapshot(5, 40)
    assert header(snapshot) == (Kind.SNAPSHOT, 5, 40)
    assert header(wire.encode(Kind.HEARTBEAT, seq=3, tick=2, ack=1)) == (Kind.HEARTBEAT, 3, 2)
    assert header(wire.encode(Kind.GOODBYE, seq=4, reason=wire.GoodbyeReason.QUIT)) is None  # decoded in full
    rng = random.Random(0)
    assert all(header(_broken(snapshot, rng)) is None for _ in range(50))
