"""The watch task: N spectators and M players that take every message.

Players send a zero force at input_hz (an arm at rest). Per snapshot the receipt time
(CLOCK_MONOTONIC) and tick go to SPEC "record" (.npz) for the latency; per client the snapshots,
the messages missed (gaps in the server's sequence numbers: the gateway numbers every message it
tries to send a session, and its feed numbers every message it publishes, so a gap is a message
dropped at the high-water mark), score or tick regressions, goodbyes. A spectator subscribes to the
feed its welcome names (its snapshots and events come there, heartbeats and goodbye on the
session). With "rejoin" a client silent for silence_s says hello again (a restarted gateway lost
its sessions).

Snapshots are parsed by their header and score bytes on the hot path (fixed offsets of
wire.Snapshot); one in `validate_every` is decoded in full and every other message always is.
"""
from __future__ import annotations

import struct
import time
from array import array
from collections import Counter

import numpy as np
import zmq

from processes.network import wire
from processes.network.client import Client, Rejected
from processes.network.wire import Kind, RejectReason
from processes.stress.probes import fd_count, rss_kb
from processes.stress.swarm import NO_TOKEN, context, emit

HEADER = struct.Struct("<4sHBBQq")  # wire.HEADER_DTYPE
SCORE = struct.Struct("<HHBB")  # snapshot score[2], games_won[2] at offset 324
SCORE_OFFSET = wire.SPECS[Kind.SNAPSHOT].dtype.fields["score"][1]


# A watch swarm's spectators read their feeds on libzmq I/O thread 1, the sessions stay on 0: with
# one thread, 250 feeds' 30,000 messages a second delayed the heartbeats out (as in the gateway).
FEED_OPTIONS = {zmq.AFFINITY: 1 << 1}


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
    zctx = context(2 * n_spec + n_play, io_threads=2)  # a spectator has two sockets: its session and its feed
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

