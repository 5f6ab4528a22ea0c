"""A swarm of ZeroMQ clients in one process, for `pingpong stress` (processes/stress.py).

Run as `python -m processes.stress.swarm SPEC_JSON`; prints JSON lines on stdout: {"event": "ready",
...} once its clients are in, {"event": "progress", ...} now and then, and a final {"event":
"report", ...}. Tasks (SPEC "task"):

- watch: N spectators and M players (players send a zero force at input_hz: an arm at rest) take
  every message; per snapshot the receipt time (CLOCK_MONOTONIC) and tick go to SPEC "record"
  (.npz) for the latency; per client the snapshots, the messages missed (gaps in the server's
  sequence numbers: the gateway numbers every message it tries to send a session, and its feed
  numbers every message it publishes, so a gap is a message dropped at the high-water mark),
  score or tick regressions, goodbyes. A spectator subscribes to the feed its welcome names
  (its snapshots and events come there, heartbeats and goodbye on the session). With "rejoin"
  a client silent for silence_s, or told goodbye unknown_session, says hello again (a restarted
  gateway lost its sessions).
- churn: join and leave in a loop, `concurrency` sessions in flight: players claim and free
  seats, spectators come and go, a fraction leaves without goodbye (socket closed, linger 0).
- malformed: N bad messages of every class from sessionless sockets (each one's expected
  gateway counter computed here with wire.decode on the same bytes), plus a player session
  sending the other player's bat and replayed inputs and a spectator session sending inputs
  (each kicked after MAX_BAD and joining again), and oversized frames (libzmq drops the
  connection). Every socket ends with a round trip, so everything before it was handled: a
  spectator's hello and its welcome (only the welcome counts: a reject that comes then answers a
  flood message, e.g. "full" for one of the valid player hellos in the mix, which a loaded
  gateway answered after the flood's last drain). The oversized frames' round trip is on a new
  connection: libzmq drops the connection that carried a frame beyond MAXMSGSIZE, and with it
  whatever followed that frame on it (a hello sent behind the last one is lost).

Snapshots are parsed by their header and score bytes on the hot path (fixed offsets of
wire.Snapshot); one in `validate_every` is decoded in full and every other message always is.
"""
from __future__ import annotations

import json
import os
import random
import struct
import sys
import time
from array import array
from collections import Counter

import numpy as np
import zmq

from processes.network import wire
from processes.network.client import Client, Rejected
from processes.network.gateway import MAX_BAD, MAX_FRAME_BYTES
from processes.network.wire import GoodbyeReason, InputMode, Kind, RejectReason, Role, Slot

HEADER = struct.Struct("<4sHBBQq")  # wire.HEADER_DTYPE
SCORE = struct.Struct("<HHBB")  # snapshot score[2], games_won[2] at offset 324
SCORE_OFFSET = wire.SPECS[Kind.SNAPSHOT].dtype.fields["score"][1]
NO_TOKEN = bytes(wire.TOKEN_SIZE)


def emit(obj) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def fd_count(pid: int | str = "self") -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def rss_kb(pid: int | str = "self") -> int:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def _context(n_sockets: int, io_threads: int = 1):
    zctx = zmq.Context(io_threads=io_threads)
    zctx.set(zmq.MAX_SOCKETS, max(1023, n_sockets + 64))  # default 1023 sockets a context
    return zctx


# A watch swarm's spectators read their feeds on libzmq I/O thread 1, the sessions stay on 0: with
# one thread, 250 feeds' 30,000 messages a second delayed the heartbeats out (as in the gateway).
FEED_OPTIONS = {zmq.AFFINITY: 1 << 1}


# --- watch ---------------------------------------------------------------------------------------
class _Watcher:
    def __init__(self, client: Client, role: str):
        self.client = client
        self.role = role
        self.welcomed = False
        self.snapshots = 0
        self.first = self.last = 0.0
        self.last_snapshot = 0.0
        self.last_seq = 0
        self.missed = 0
        self.feed = None  # the client's feed socket as registered with the poller
        self.feed_seq = 0
        self.feed_missed = 0
        self.seq_resets = 0
        self.last_tick = -1
        self.last_score = (-1, -1)
        self.goodbye: str | None = None
        self.hello_at = 0.0
        self.hellos = 0
        self.rejoined = 0
        self.next_input = 0.0
        self.inputs = 0


def watch(spec: dict) -> dict:
    n_spec, n_play = spec.get("spectators", 0), spec.get("players", 0)
    fds_before = fd_count()
    zctx = _context(2 * n_spec + n_play, io_threads=2)  # a spectator has two sockets: its session and its feed
    watchers = [_Watcher(Client(spec["address"], "spectator", f"{spec.get('name', 'w')}{i}", zctx=zctx,
                                feed_options=FEED_OPTIONS), "spectator") for i in range(n_spec)]
    watchers += [_Watcher(Client(spec["address"], "player", f"{spec.get('name', 'w')}p{i}", zctx=zctx), "player")
                 for i in range(n_play)]
    by_sock = {w.client.sock: w for w in watchers}
    poller = zmq.Poller()
    for w in watchers:
        poller.register(w.client.sock, zmq.POLLIN)
    rejected: Counter[str] = Counter()
    bad: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    ticks, times = array("q"), array("d")
    regressions = {"score": 0, "tick": 0}
    events = 0
    validate_every = spec.get("validate_every", 50)
    silence_s = spec.get("silence_s", 1.0)
    input_dt = 1.0 / spec.get("input_hz", 50)
    join_deadline = time.monotonic() + spec.get("join_timeout", 30.0)
    for w in watchers:
        w.client.hello()
        w.hello_at = time.monotonic()
        w.hellos = 1
    ready_sent = False
    started = time.monotonic()
    end = started + spec.get("duration", 10.0)
    rss_start = None
    next_sweep = 0.0
    last_sweep = 0.0
    sweep_gap = 0.0
    done = set()

    def finished(w: _Watcher) -> bool:
        return w.goodbye is not None or w in done

    while True:
        now = time.monotonic()
        if now >= end:
            break
        if spec.get("until_goodbye") and ready_sent and all(finished(w) for w in watchers):
            break
        if not ready_sent and (all(w.welcomed or finished(w) for w in watchers) or now > join_deadline):
            ready_sent = True
            rss_start = rss_kb()
            emit({"event": "ready", "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
                  "fds": fd_count(), "t": now})
        for sock, _ in poller.poll(20):
            w = by_sock[sock]
            client = w.client
            on_feed = sock is w.feed
            for _ in range(64):
                try:
                    data = sock.recv(zmq.NOBLOCK)
                except zmq.Again:
                    break
                t = time.monotonic()
                if len(data) == wire.SIZES[Kind.SNAPSHOT] and data[6] == Kind.SNAPSHOT and data[:4] == wire.MAGIC:
                    _, _, _, _, seq, tick = HEADER.unpack_from(data)
                    if on_feed:
                        if w.feed_seq and seq > w.feed_seq:
                            w.feed_missed += seq - w.feed_seq - 1
                        w.feed_seq = seq
                    w.snapshots += 1
                    w.last_snapshot = t
                    if w.snapshots == 1:
                        w.first = t  # the rate is taken between the first and the last snapshot
                    if validate_every and w.snapshots % validate_every == 0:
                        if client.drops.decode(data) is None:
                            bad["snapshot"] += 1
                    ticks.append(tick)
                    times.append(t)
                    sa, sb, ga, gb = SCORE.unpack_from(data, SCORE_OFFSET)
                    score = (ga + gb, sa + sb)
                    if score < w.last_score and w.last_tick >= 0:
                        regressions["score"] += 1
                    if tick < w.last_tick:
                        regressions["tick"] += 1
                    w.last_score, w.last_tick = score, tick
                    client.tick = max(client.tick, tick)
                    if on_feed:
                        continue  # the feed's seqs are its own stream, not the session's
                else:
                    message = client.drops.decode(data)
                    if message is None:
                        bad["other"] += 1
                        continue
                    seq = message.seq
                    kinds[message.kind.name.lower()] += 1
                    if on_feed:
                        if message.kind not in (Kind.SNAPSHOT, Kind.EVENT):
                            bad["not_on_feed"] += 1
                            continue
                        if w.feed_seq and seq > w.feed_seq:
                            w.feed_missed += seq - w.feed_seq - 1
                        w.feed_seq = seq
                        events += message.kind == Kind.EVENT
                        continue
                    if message.kind in (Kind.WELCOME, Kind.REJECT):
                        try:
                            client.accept(message)
                        except Rejected as err:
                            rejected[err.reason.name.lower()] += 1
                            if err.reason == RejectReason.BAD_TOKEN:
                                client.token = NO_TOKEN  # a restarted gateway forgot it: ask for any seat
                            elif not spec.get("rejoin"):
                                done.add(w)
                            continue
                        w.rejoined += w.welcomed
                        w.welcomed = True
                        w.last_seq = seq
                        w.last = t
                        if client.feed is not w.feed:  # subscribed (or, after a restart, to a new port)
                            if w.feed is not None:
                                poller.unregister(w.feed)
                                by_sock.pop(w.feed, None)
                            w.feed, w.feed_seq = client.feed, 0
                            if w.feed is not None:
                                poller.register(w.feed, zmq.POLLIN)
                                by_sock[w.feed] = w
                        continue
                    if message.kind == Kind.GOODBYE:
                        if message["reason"] == GoodbyeReason.UNKNOWN_SESSION and spec.get("rejoin"):
                            client.hello()  # a restarted gateway lost our session: hello again now
                            w.hello_at = t
                            w.hellos += 1
                        else:
                            w.goodbye = message["reason"].name.lower()
                    elif message.kind == Kind.EVENT:
                        events += 1
                if seq <= w.last_seq:
                    w.seq_resets += 1  # a new gateway numbers from 1 again
                elif w.welcomed:
                    w.missed += seq - w.last_seq - 1
                w.last_seq = seq
                w.last = t
        now = time.monotonic()
        if now >= next_sweep:
            if ready_sent and last_sweep:
                sweep_gap = max(sweep_gap, now - last_sweep)  # our own stalls: a heartbeat may be late by this
            last_sweep = now
            next_sweep = now + 0.05
            for w in watchers:
                if finished(w):
                    continue
                client = w.client
                if w.welcomed:
                    client.heartbeat_if_due()
                    if w.role == "player" and now >= w.next_input:
                        w.next_input = now + input_dt
                        client.send_input(np.zeros(6))
                        w.inputs += 1
                if spec.get("rejoin") and now - max(w.last, w.hello_at) > silence_s and w.hellos < 100:
                    client.hello()  # the gateway went silent: a restarted one needs a hello
                    w.hello_at = now
                    w.hellos += 1
    if not ready_sent:
        emit({"event": "ready", "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
              "fds": fd_count(), "t": time.monotonic()})
    stopped = time.monotonic()
    if spec.get("leave_at_end", True):
        for w in watchers:
            if w.goodbye is None and w.welcomed:
                w.client.sock.setsockopt(zmq.LINGER, 1000)  # the goodbye leaves before the socket goes
                w.client.leave()
    rss_end = rss_kb()
    for w in watchers:
        w.client.close()
    zctx.term()
    fds_after = fd_count()
    if spec.get("record"):
        np.savez(spec["record"], ticks=np.frombuffer(ticks, np.int64), times=np.frombuffer(times, np.float64))
    rates = [(w.snapshots - 1) / (w.last_snapshot - w.first) for w in watchers
             if w.snapshots > 1 and w.last_snapshot > w.first]
    return {"clients": len(watchers), "welcomed": sum(w.welcomed for w in watchers), "rejected": dict(rejected),
            "snapshots": sum(w.snapshots for w in watchers), "missed": sum(w.missed for w in watchers),
            "missed_max": max((w.missed for w in watchers), default=0),
            "feed_missed": sum(w.feed_missed for w in watchers),
            "feed_missed_max": max((w.feed_missed for w in watchers), default=0),
            "on_feed": sum(w.feed is not None for w in watchers),
            "seq_resets": sum(w.seq_resets for w in watchers), "rejoined": sum(w.rejoined for w in watchers),
            "hellos": sum(w.hellos for w in watchers), "inputs": sum(w.inputs for w in watchers),
            "goodbyes": dict(Counter(w.goodbye for w in watchers if w.goodbye)),
            "no_goodbye": sum(1 for w in watchers if w.goodbye is None and w.welcomed),
            "events": events, "messages": dict(kinds), "invalid": dict(bad),
            "decode_drops": {k: v for w in watchers for k, v in w.client.drops.by_reason.items()},
            "regressions": regressions, "rate_min": min(rates, default=0.0),
            "rate_median": float(np.median(rates)) if rates else 0.0, "rate_max": max(rates, default=0.0),
            "seconds": stopped - started, "fds_before": fds_before, "fds_after": fds_after,
            "rss_start_kb": rss_start or rss_end, "rss_end_kb": rss_end,
            "last_tick": max((w.last_tick for w in watchers), default=-1), "sweep_gap_max_s": round(sweep_gap, 3)}


# --- churn ---------------------------------------------------------------------------------------
def churn(spec: dict) -> dict:
    rng = random.Random(spec.get("seed", 0))
    cycles, concurrency = spec["cycles"], spec.get("concurrency", 8)
    p_player, p_abrupt = spec.get("p_player", 0.2), spec.get("p_abrupt", 0.1)
    join_timeout = spec.get("join_timeout", 10.0)
    fds_before = fd_count()
    zctx = _context(concurrency * 2)
    counts: Counter[str] = Counter()
    join_ms = array("d")
    live: dict = {}  # sock -> (client, started, role)
    poller = zmq.Poller()
    started = time.monotonic()
    deadline = started + spec.get("max_seconds", 600.0)
    begun = 0
    finished = 0
    progress_every = max(1, cycles // 10)
    rss_start = None

    def end(sock, graceful: bool, why: str | None = None) -> None:
        nonlocal finished
        client = live.pop(sock)[0]
        poller.unregister(sock)
        if graceful:
            sock.setsockopt(zmq.LINGER, 1000)
            client.leave()
            counts["left_goodbye"] += 1
        else:
            counts[why or "left_abrupt"] += 1
        client.close()
        finished += 1
        if finished % progress_every == 0:
            emit({"event": "progress", "done": finished, "t": time.monotonic()})

    while (begun < cycles or live) and time.monotonic() < deadline:
        while begun < cycles and len(live) < concurrency:
            role = "player" if rng.random() < p_player else "spectator"
            client = Client(spec["address"], role, f"c{begun % 1000}", zctx=zctx)
            client.hello()
            live[client.sock] = (client, time.monotonic(), role)
            poller.register(client.sock, zmq.POLLIN)
            begun += 1
            counts[f"{role}_hellos"] += 1
        for sock, _ in poller.poll(50):
            client, t0, role = live[sock]
            message = client.recv(0)
            if message is None:
                continue
            try:
                if not client.accept(message):
                    continue
            except Rejected as err:
                counts[f"{role}_rejected.{err.reason.name.lower()}"] += 1
                end(sock, graceful=False, why="closed_after_reject")  # the server has no session for it
                continue
            join_ms.append(1000 * (time.monotonic() - t0))
            counts[f"{role}_welcomed" if role == "spectator" else f"player_welcomed.{client.slot.name}"] += 1
            if role == "player":
                client.send_input(np.zeros(6))
            if finished == cycles // 10 and rss_start is None:
                rss_start = rss_kb()
            end(sock, graceful=rng.random() >= p_abrupt)
        now = time.monotonic()
        for sock, (client, t0, role) in list(live.items()):
            if now - t0 > join_timeout:
                end(sock, graceful=False, why="join_timeouts")
    counts["not_started"] = cycles - begun
    for sock in list(live):
        end(sock, graceful=False, why="unfinished")
    rss_end = rss_kb()
    zctx.term()
    ms = np.frombuffer(join_ms, np.float64)
    return {"cycles": begun, "counts": dict(counts), "seconds": time.monotonic() - started,
            "join_ms_p50": float(np.percentile(ms, 50)) if len(ms) else None,
            "join_ms_p99": float(np.percentile(ms, 99)) if len(ms) else None,
            "fds_before": fds_before, "fds_after": fd_count(), "rss_start_kb": rss_start or rss_end,
            "rss_end_kb": rss_end}


# --- malformed -----------------------------------------------------------------------------------
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
    zctx = _context(64)
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


TASKS = {"watch": watch, "churn": churn, "malformed": malformed}


def main(argv: list[str]) -> int:
    spec = json.loads(argv[0])
    report = TASKS[spec["task"]](spec)
    emit({"event": "report", "pid": os.getpid(), **report})
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
