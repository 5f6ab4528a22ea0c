"""The churn task: join and leave in a loop, `concurrency` sessions in flight.

Players claim and free seats, spectators come and go, a fraction leaves without goodbye (socket
closed, linger 0).
"""
from __future__ import annotations

import random
import time
from array import array
from collections import Counter

import numpy as np
import zmq

from processes.network.client.client import Client, Rejected
from processes.stress.probes import fd_count, rss_kb
from processes.stress.swarm import context, emit


def churn(spec: dict) -> dict:
    rng = random.Random(spec.get("seed", 0))
    cycles, concurrency = spec["cycles"], spec.get("concurrency", 8)
    p_player, p_abrupt = spec.get("p_player", 0.2), spec.get("p_abrupt", 0.1)
    join_timeout = spec.get("join_timeout", 10.0)
    fds_before = fd_count()
    zctx = context(concurrency * 2)
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

