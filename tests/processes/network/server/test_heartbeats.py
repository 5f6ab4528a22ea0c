"""The gateway's heartbeats and timeouts: both ways, from their own thread, the fast path, the goodbye.

A Gateway in this process (the rig fixture) with a clock the test sets, so a timeout needs no sleep.
"""
import time

import numpy as np
import pytest

from processes.network import wire
from processes.network.client.client import Rejected
from processes.network.server.gateway import Gateway
from processes.network.wire import GoodbyeReason, Kind, RejectReason
from tests.waits import DEADLINE_S, Deadline


def test_heartbeats_keep_a_session_alive_both_ways(rig):
    r = rig(heartbeat_s=1.0, timeout_s=5.0)
    player = r.client()
    r.join(player)
    for _ in range(4):  # 12 s in all, never 5 s silent: heartbeats from the client keep it
        r.clock.now += 3.0
        beat = r.until(player, lambda m: m.kind == Kind.HEARTBEAT)  # the server's heartbeat
        assert beat["ack"] >= 1
        player.send(Kind.HEARTBEAT, ack=player.max_seq_in)
        before = r.gateway.counts["heartbeats_received"]
        r.settle(lambda: r.gateway.counts["heartbeats_received"] > before)
    assert r.gateway.counts["timeouts"] == 0 and len(r.gateway.sessions) == 1


def test_heartbeats_come_from_their_own_thread_while_the_loop_stands(rig):
    # The worker's loop may wait (a busy machine, a copy of the physics' state): with
    # start_heartbeats the heartbeats keep coming although nothing calls the gateway any more.
    r = rig(clock=time.monotonic, heartbeat_s=0.1, timeout_s=60.0)
    player = r.client()
    r.join(player)
    r.gateway.start_heartbeats()
    seqs, deadline = [], Deadline()
    while len(seqs) < 5 and not deadline.expired():  # this thread never calls the gateway again
        message = player.recv(100)
        if message is not None and message.kind == Kind.HEARTBEAT:
            seqs.append(message.seq)
    assert len(seqs) == 5, f"{len(seqs)} heartbeats in {DEADLINE_S:.0f} s with the loop standing"
    assert seqs == sorted(set(seqs))


def test_the_heartbeat_fast_path_takes_exactly_what_decode_accepts(rig):
    r = rig()
    watcher = r.client(role="spectator")
    r.join(watcher)
    (identity, session), = r.gateway.sessions.items()
    rng = np.random.default_rng(8)
    good = wire.encode(Kind.HEARTBEAT, seq=5, tick=7, ack=3)
    cases = [good, good + b"\0", good[:-1], wire.encode(Kind.HEARTBEAT, seq=9, tick=0, ack=2**64 - 1)]
    for _ in range(3000):  # one to three bytes of a heartbeat's header or body changed
        data = bytearray(good)
        for at in rng.integers(0, len(data), rng.integers(1, 4)):
            data[at] = rng.integers(0, 256)
        cases.append(bytes(data))
    for data in cases:
        try:
            valid = wire.decode(data).kind == Kind.HEARTBEAT  # (a scene_request has a heartbeat's size)
        except wire.WireError:
            valid = False
        before = r.gateway.counts["heartbeats_received"]
        session.bad = 0  # (a run of bad ones would get it kicked)
        r.gateway.handle([identity, data])
        assert (r.gateway.counts["heartbeats_received"] == before + 1) == valid, data.hex()
    assert r.gateway.sessions == {identity: session}


def test_a_vanished_feed_spectator_is_timed_out_on_its_session_and_counted(rig):
    r = rig(heartbeat_s=1.0, timeout_s=5.0)
    gone, stays = r.client(role="spectator", name="gone"), r.client(role="spectator", name="stays")
    for client in (gone, stays):
        r.join(client)
        r.until(client, lambda m: m.kind == Kind.SNAPSHOT, serve=True)  # watching on the feed
    gone.close()  # vanishes: no goodbye, its feed and session connections just go
    for _ in range(6):  # 6 s of the gateway's clock: only the one that heartbeats stays
        r.clock.now += 1.0
        stays.send(Kind.HEARTBEAT, ack=stays.max_seq_in)
        r.until(stays, lambda m: m.kind == Kind.HEARTBEAT)
    stats = r.gateway.stats()
    assert stats["timeouts"] == 1 and stats["spectators"] == 1 and stats["spectators_joined"] == 2
    assert [s.name for s in r.gateway.sessions.values()] == ["stays"]
    r.clients.remove(gone)


def test_shutdown_says_goodbye_to_everyone_and_refuses_newcomers(rig):
    r = rig()
    clients = [r.client(), r.client(), r.client(role="spectator")]
    for client in clients:
        r.join(client)
    assert r.gateway.shutdown() == 3
    for client in clients:
        goodbye = r.until(client, lambda m: m.kind == Kind.GOODBYE)
        assert goodbye["reason"] == GoodbyeReason.SHUTDOWN
    with pytest.raises(Rejected) as refused:
        r.join(r.client())
    assert refused.value.reason == RejectReason.SHUTTING_DOWN


def test_a_stopping_gateway_tells_a_hello_that_comes_after_its_goodbyes_it_is_shutting_down(rig):
    r = rig()
    r.gateway.shutdown()
    late = r.client()
    late.hello()  # in the socket before the gateway's last answers
    r.gateway.drain()
    message = r.until(late, lambda m: m.kind == Kind.REJECT)
    assert message["reason"] == RejectReason.SHUTTING_DOWN
