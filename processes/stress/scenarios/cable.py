"""cable: pulled cables, detected by the heartbeat timeout.

Traffic of a player and a spectator black-holed by a local TCP proxy (connections open, nothing
passes), a second player silent with its socket open: the heartbeat timeout frees the seats, the
token reclaims a seat within the grace, anyone after it.
"""
from __future__ import annotations

import os
import time

import zmq

from processes.network.client.client import Client, Rejected
from processes.stress.harness import Proxy, Run, until
from processes.stress.probes import fd_count, shm_names
from processes.stress.result import base, check, finish
from processes.stress.server import Server


def _pump(clients, seconds: float) -> None:
    """Keep these clients alive (heartbeats, reads) for a while (bounded)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for client in clients:
            client.heartbeat_if_due()
            for _ in range(50):
                if client.recv(0) is None:
                    break
        time.sleep(0.005)  # the clients' own cadence: a heartbeat is due every 0.25 s


def _goodbye(client, seconds: float):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and client.goodbye is None:
        client.recv(20)
    return client.goodbye


def scenario(args, run: Run) -> dict:
    result = base("cable")
    shm_before = shm_names()
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=1.0, grace_s=2.0, max_spectators=4))
    gateway = server.pids["gateway"]
    fds0, harness0 = fd_count(gateway), fd_count(os.getpid())
    port = int(server.endpoint.rsplit(":", 1)[1])
    proxy = Proxy(port)
    proxy.start()
    zctx = zmq.Context()
    clients = []

    def client(role, via_proxy=False, token=bytes(16), name="c"):
        address = f"tcp://127.0.0.1:{proxy.port}" if via_proxy else server.endpoint
        c = Client(address, role, name, token=token, zctx=zctx)
        clients.append(c)
        return c

    def outcome(c):
        try:
            return c.join(10)["slot"].name
        except Rejected as err:
            return err.reason.name.lower()

    counts = {}
    timeout, grace = server.spec["timeout_s"], server.spec["grace_s"]
    try:
        pulled, direct, watcher = client("player", True, name="ann"), client("player", name="bob"), client("spectator", True)
        counts["pulled_slot"], counts["direct_slot"], _ = outcome(pulled), outcome(direct), outcome(watcher)
        _pump([pulled, direct, watcher], 0.5)
        counts["snapshots_through_proxy"] = pulled.received
        proxy.black_hole()  # the cable is pulled: connections open, nothing passes
        t_pull = time.monotonic()
        _pump([direct], timeout + 1.0)  # past the timeout with room for a busy gateway, within the grace
        counts["during_grace_newcomer"] = outcome(client("player", name="cy"))
        proxy.restore()  # what the server sent into the hole comes out now: its goodbye
        counts["pulled_goodbye"] = getattr(_goodbye(pulled, 3.0), "name", None)
        counts["watcher_goodbye"] = getattr(_goodbye(watcher, 3.0), "name", None)
        rejoin = client("player", token=pulled.token, name="ann")
        counts["token_rejoin"] = outcome(rejoin)
        counts["rejoin_within_s"] = round(time.monotonic() - t_pull, 2)
        # the second kind of pulled cable: the rejoined client goes silent with its socket open
        t_silent = time.monotonic()
        _pump([direct], timeout + grace + 0.7)
        counts["silent_goodbye_pending"] = rejoin.goodbye is None  # nothing read yet: it is silent
        counts["after_grace_newcomer"] = outcome(client("player", name="dan"))
        counts["silent_goodbye"] = getattr(_goodbye(rejoin, 3.0), "name", None)
        counts["freed_after_s"] = round(time.monotonic() - t_silent, 2)
        spectators = [client("spectator", name=f"s{i}") for i in range(5)]
        fill = [outcome(c) for c in spectators]
        counts["spectator_fill"] = {k: fill.count(k) for k in set(fill)}
        counts["proxy_bytes"] = proxy.forwarded
    finally:
        for c in clients:
            if c.goodbye is None:
                c.leave()
            c.sock.setsockopt(zmq.LINGER, 500)
            c.close()
        zctx.term()
        proxy.close()
    settled = until(lambda: fd_count(gateway) is not None and fd_count(gateway) <= fds0, 10)
    fds1 = fd_count(gateway)
    server.stop()
    result["counts"] = counts
    side = counts["pulled_slot"]
    check(result, side in ("A", "B") and counts["direct_slot"] in ("A", "B"), f"players not seated: {counts}")
    check(result, counts["snapshots_through_proxy"] > 0, "no snapshot through the proxy before the pull")
    check(result, counts["during_grace_newcomer"] == "full", "a newcomer took the pulled seat within the grace")
    check(result, counts["pulled_goodbye"] == "TIMEOUT", f"pulled player got {counts['pulled_goodbye']}, "
                                                          "expected the timeout goodbye")
    check(result, counts["watcher_goodbye"] == "TIMEOUT", f"pulled spectator got {counts['watcher_goodbye']}")
    check(result, counts["token_rejoin"] == side, f"token rejoin got {counts['token_rejoin']}, expected {side}")
    check(result, counts["after_grace_newcomer"] == side, f"after the grace a newcomer got "
                                                           f"{counts['after_grace_newcomer']}, expected seat {side}")
    check(result, counts["silent_goodbye"] == "TIMEOUT", f"silent player got {counts['silent_goodbye']}")
    check(result, counts["spectator_fill"] == {"NONE": 4, "full": 1}, f"spectator places after the pulls: "
                                                                     f"{counts['spectator_fill']}")
    check(result, settled, f"gateway descriptors {fds0} before, {fds1} after")
    fds = {"gateway": (fds1 or 0) - (fds0 or 0), "harness": (fd_count(os.getpid()) or 0) - (harness0 or 0)}
    return finish(result, run, server, shm_before, fds)
