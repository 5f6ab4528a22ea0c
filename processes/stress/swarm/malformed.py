"""The malformed task: N bad messages of every class, and the gateway counter each one must move.

Sessionless sockets send them (each one's expected gateway counter computed here with wire.decode
on the same bytes), plus a player session sending the other player's bat and replayed inputs and
a spectator session sending inputs (each kicked after MAX_BAD and joining again), and oversized
frames (libzmq drops the connection). Every socket ends with a round trip, so everything before it
was handled: a spectator's hello and its welcome (only the welcome counts: a reject that comes then
answers a flood message, e.g. "full" for one of the valid player hellos in the mix, which a loaded
gateway answered after the flood's last drain). The oversized frames' round trip is on a new
connection: libzmq drops the connection that carried a frame beyond MAXMSGSIZE, and with it
whatever followed that frame on it (a hello sent behind the last one is lost).
"""
from __future__ import annotations

import random
import struct
import time
from collections import Counter

import numpy as np
import zmq

from processes.network import wire
from processes.network.client.client import Client, Rejected
from processes.network.wire import MAX_BAD, MAX_FRAME_BYTES, NO_TOKEN, GoodbyeReason, InputMode, Kind, Role, Slot
from processes.stress.probes import fd_count
from processes.stress.swarm import context


def _input(seq=1, slot=Slot.A, force=(1.0, 0.0, 0.0)) -> bytes:
    return wire.encode(Kind.INPUT, seq=seq, tick=1, slot=slot, mode=InputMode.FORCE, force=force, torque=[0, 0, 0],
                       target_pos=[0, 0, 0], target_quat=[0, 0, 0, 0])


_POOL: list[bytes] = []
_INPUTS: list[bytes] = []


def _valid(rng: random.Random) -> bytes:
    """A valid message of a random type, from a pool built once (encoding validates: it is slow)."""
    if not _POOL:
        pool_rng = random.Random(12345)
        _POOL.extend(_make_valid(pool_rng) for _ in range(256))
        _INPUTS.extend(_input(pool_rng.randrange(1, 1 << 40)) for _ in range(256))
    return rng.choice(_POOL)


def _any_input(rng: random.Random) -> bytes:
    _valid(rng)
    return rng.choice(_INPUTS)


def _make_valid(rng: random.Random) -> bytes:
    kind = rng.choice(["input", "hello", "heartbeat", "goodbye", "snapshot", "event"])
    if kind == "input":
        return _input(rng.randrange(1, 1 << 40))
    if kind == "hello":
        return wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="x", token=NO_TOKEN)
    if kind == "heartbeat":
        return wire.encode(Kind.HEARTBEAT, seq=rng.randrange(1, 1000), ack=3)
    if kind == "goodbye":
        return wire.encode(Kind.GOODBYE, reason=GoodbyeReason.QUIT)
    if kind == "event":
        return wire.encode(Kind.EVENT, event=wire.EventKind.POINT, winner=0, reason=1, game=0, score=[1, 0],
                           games_won=[0, 0], shots=3, rally=1)
    return bytes(_SNAPSHOT)


_SNAPSHOT = bytearray(wire.SIZES[Kind.SNAPSHOT])


def _init_snapshot() -> None:
    rec = np.zeros((), wire.SPECS[Kind.SNAPSHOT].dtype)
    rec["magic"], rec["version"], rec["kind"] = wire.MAGIC, wire.PROTOCOL_VERSION, Kind.SNAPSHOT
    rec["bat_quat"] = [[1, 0, 0, 0], [1, 0, 0, 0]]
    rec["winner"] = -1
    _SNAPSHOT[:] = rec.tobytes()


_init_snapshot()


def _patched(data: bytes, offset: int, raw: bytes) -> bytes:
    buf = bytearray(data)
    buf[offset:offset + len(raw)] = raw
    return bytes(buf)


_HELLO = wire.encode(Kind.HELLO, role=Role.SPECTATOR, slot=Slot.NONE, name="eve", token=NO_TOKEN)
FORCE_AT = wire.SPECS[Kind.INPUT].dtype.fields["force"][1]
MODE_AT = wire.SPECS[Kind.INPUT].dtype.fields["mode"][1]
NAME_AT = wire.SPECS[Kind.HELLO].dtype.fields["name"][1]


def _bad(cls: str, rng: random.Random, replays: list) -> list[bytes]:
    """One message of class `cls` as its frames."""
    if cls == "random_bytes":
        return [rng.randbytes(rng.randrange(0, 400))]
    if cls == "truncated":
        data = _valid(rng)
        return [data[:rng.randrange(0, len(data))]]
    if cls == "too_long":
        data = _valid(rng)
        return [data + rng.randbytes(rng.randrange(1, MAX_FRAME_BYTES - len(data)))]
    if cls == "bad_magic":
        return [rng.randbytes(4) + _valid(rng)[4:]]
    if cls == "wrong_version":
        return [_patched(_valid(rng), 4, struct.pack("<H", rng.choice([0, 1, 3, 255, 65535])))]
    if cls == "wrong_type":
        return [_patched(_valid(rng), 6, bytes([rng.choice([0, *range(9, 256)])]))]
    if cls == "bad_flags":
        return [_patched(_valid(rng), 7, bytes([rng.randrange(1, 256)]))]
    if cls == "non_finite":
        value = rng.choice([float("nan"), float("inf"), float("-inf")])
        return [_patched(_any_input(rng), FORCE_AT + 8 * rng.randrange(3), struct.pack("<d", value))]
    if cls == "out_of_range":
        value = rng.choice([501.0, 1e6, -1e300, 5e3])
        return [_patched(_any_input(rng), FORCE_AT + 8 * rng.randrange(3), struct.pack("<d", value))]
    if cls == "bad_enum":
        return [_patched(_any_input(rng), MODE_AT, bytes([rng.randrange(3, 256)]))]
    if cls == "bad_text":
        return [_patched(_HELLO, NAME_AT, rng.choice([b"\x1b[2J", b"a\0b", b" x", b"\xff\xfe", b"\xe2\x80\xae"]))]
    if cls == "multi_frame":
        return [_valid(rng), rng.randbytes(rng.randrange(0, 40))]
    if cls == "replay":
        return [rng.choice(replays)]
    raise ValueError(cls)


SESSIONLESS = ("random_bytes", "truncated", "too_long", "bad_magic", "wrong_version", "wrong_type", "bad_flags",
               "non_finite", "out_of_range", "bad_enum", "bad_text", "multi_frame", "replay")
SESSION = ("other_bat", "spectator_input", "stale_replay")
CLASSES = SESSIONLESS + SESSION + ("oversized",)


def expected_reason(frames: list[bytes]) -> str:
    """The gateway counter a sessionless message moves (gateway.Gateway.handle's rules)."""
    if len(frames) != 1:
        return "dropped.bad_framing"
    try:
        message = wire.decode(frames[0])
    except wire.WireError as err:
        return f"dropped.{err.reason}"
    return "hello" if message.kind == Kind.HELLO else "dropped.no_session"


def _send(sock, frames, sent_counter, key) -> bool:
    for _ in range(50):
        try:
            sock.send_multipart(frames, flags=zmq.NOBLOCK)
            sent_counter[key] += 1
            return True
        except zmq.Again:
            sock.poll(20, zmq.POLLOUT)
    return False


def _drain(sock) -> list:
    out = []
    for _ in range(1000):
        try:
            out.append(sock.recv(zmq.NOBLOCK))
        except zmq.Again:
            break
    return out


class _Session:
    """A session that misbehaves on purpose, joining again each time it is kicked."""

    def __init__(self, address, role, zctx, counts):
        self.client = Client(address, role, f"evil{role[0]}", zctx=zctx)
        self.counts = counts
        self.bad = 0
        self.ok = self._join()

    def _join(self) -> bool:
        self.client.token = NO_TOKEN
        try:
            self.client.join(10.0)
        except (Rejected, TimeoutError) as err:
            self.counts[f"session_join_failed.{type(err).__name__}"] += 1
            return False
        self.counts[f"joins.{self.client.role.name.lower()}"] += 1
        self.bad = 0
        return True

    def misbehave(self) -> None:
        """One bad message; on the MAX_BAD-th, wait for the kick and join again."""
        client = self.client
        if client.role == Role.PLAYER:
            other = Slot.B if client.slot == Slot.A else Slot.A
            client.send_input([1.0, 0, 0, 0, 0, 0], slot=other)  # the other player's bat
        else:
            client.send_input([1.0, 0, 0, 0, 0, 0], slot=Slot.A)  # a spectator controls nothing
        self.bad += 1
        if self.bad >= MAX_BAD:
            deadline = time.monotonic() + 5.0
            client.goodbye = None
            while client.goodbye is None and time.monotonic() < deadline:
                client.recv(50)
            self.counts[f"kicked_seen.{client.goodbye.name.lower() if client.goodbye else 'none'}"] += 1
            self.ok = self._join()

    def replay(self) -> None:
        """A valid input, then the same bytes again: the replay is stale."""
        client = self.client
        client.seq += 1
        data = wire.encode(Kind.INPUT, seq=client.seq, tick=client.tick, slot=client.slot, mode=InputMode.FORCE,
                           force=[0.5, 0, 0], torque=[0, 0, 0], target_pos=[0, 0, 0], target_quat=[0, 0, 0, 0])
        client.send_raw(data)
        client.send_raw(data)

    def sync(self) -> bool:
        """A heartbeat, then wait for the server's heartbeat acknowledging it: all before it was handled."""
        client = self.client
        client.send(Kind.HEARTBEAT, ack=client.max_seq_in)
        mark = client.seq
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            message = client.recv(50)
            if message is not None and message.kind == Kind.HEARTBEAT and message["ack"] >= mark:
                return True
            client.heartbeat_if_due()
        return False


def malformed(spec: dict) -> dict:
    rng = random.Random(spec.get("seed", 0))
    n, rate = spec["n"], spec.get("rate", 20000)
    fds_before = fd_count()
    zctx = context(64)
    sockets = []
    for _ in range(spec.get("sockets", 8)):
        sock = zctx.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.connect(spec["address"])
        sockets.append(sock)
    sent: Counter[str] = Counter()
    expected: Counter[str] = Counter()
    counts: Counter[str] = Counter()
    replays = [_input(s) for s in range(1, 50)]
    oversized = zctx.socket(zmq.DEALER)
    oversized.setsockopt(zmq.LINGER, 0)
    oversized.connect(spec["address"])
    n_oversized = min(spec.get("oversized", 20), n)
    plan = [CLASSES[i % (len(CLASSES) - 1)] for i in range(n - n_oversized)] + ["oversized"] * n_oversized
    rng.shuffle(plan)
    # every sessionless message and the counter it must move, built before the match starts (our
    # player's hello takes the second seat, and the match's length is fixed from then)
    frames = [_bad(cls, rng, replays) if cls in SESSIONLESS else None for cls in plan]
    reasons = [expected_reason(f) if f is not None else None for f in frames]
    player = _Session(spec["address"], "player", zctx, counts)
    watcher = _Session(spec["address"], "spectator", zctx, counts)
    started = time.monotonic()
    deadline = started + spec.get("max_seconds", 120.0)
    replies = 0
    batch = max(1, rate // 100)
    for start in range(0, len(plan), batch):
        if time.monotonic() > deadline:
            counts["stopped_at_deadline"] += 1
            break
        for k in range(start, min(start + batch, len(plan))):
            cls = plan[k]
            if cls == "oversized":
                _send(oversized, [rng.randbytes(MAX_FRAME_BYTES + 1 + rng.randrange(0, 60000))], sent, cls)
            elif cls in SESSION:
                session = player if cls in ("other_bat", "stale_replay") else watcher
                if not session.ok:
                    counts[f"unsent.{cls}"] += 1
                    continue
                if cls == "stale_replay":
                    session.replay()
                else:
                    session.misbehave()
                sent[cls] += 1
            elif _send(sockets[k % len(sockets)], frames[k], sent, cls):
                expected[reasons[k]] += 1
        # pace to `rate` (rate limiting, not synchronisation) while taking what came back
        target = started + (start + batch) / rate
        for s in (player, watcher):
            if s.ok:
                s.client.heartbeat_if_due()
        while time.monotonic() < target:
            for sock in sockets:
                replies += len(_drain(sock))
            left = target - time.monotonic()
            if left > 0:
                sockets[0].poll(int(left * 1000) + 1, zmq.POLLIN)
    # round trips: a hello on each sessionless socket; its welcome means everything before was handled
    oversized.close(linger=0)  # what followed an oversized frame on its connection is lost: a new one
    after_oversized = zctx.socket(zmq.DEALER)
    after_oversized.setsockopt(zmq.LINGER, 0)
    after_oversized.connect(spec["address"])
    synced = 0
    unsynced = []
    replies_at_sync: Counter[str] = Counter()
    for i, sock in enumerate(sockets + [after_oversized]):
        sock.send(wire.encode(Kind.HELLO, role=Role.SPECTATOR, slot=Slot.NONE, name="sync", token=NO_TOKEN))
        expected["hello"] += 1
        deadline = time.monotonic() + 10.0
        welcomed = False
        while not welcomed and time.monotonic() < deadline:
            if sock.poll(100, zmq.POLLIN):
                for data in _drain(sock):
                    try:
                        message = wire.decode(data)
                    except wire.WireError:
                        continue
                    if message.kind == Kind.WELCOME:
                        welcomed = True
                    else:  # late answers to the flood: rejects of wrong versions and of player hellos
                        reason = message.fields.get("reason")
                        replies_at_sync[f"{message.kind.name.lower()}.{getattr(reason, 'name', reason)}".lower()] += 1
        if welcomed:
            synced += 1
            sock.send(wire.encode(Kind.GOODBYE, seq=2, reason=GoodbyeReason.QUIT))
        else:
            unsynced.append("after_oversized" if sock is after_oversized else f"sessionless{i}")
    sessions_synced = sum(s.sync() for s in (player, watcher) if s.ok)
    for s in (player, watcher):
        s.client.sock.setsockopt(zmq.LINGER, 1000)
        s.client.leave()
        s.client.close()
    for sock in sockets + [after_oversized]:
        sock.close(linger=1000)
    zctx.term()
    return {"sent": dict(sent), "sent_total": sum(sent.values()), "expected": dict(expected),
            "counts": dict(counts), "synced_sockets": synced, "sockets": len(sockets) + 1, "unsynced": unsynced,
            "late_replies_at_sync": dict(replies_at_sync),
            "sessions_synced": sessions_synced, "replies": replies, "seconds": time.monotonic() - started,
            "fds_before": fds_before, "fds_after": fd_count()}

