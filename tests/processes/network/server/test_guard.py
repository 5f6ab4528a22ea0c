"""What one connection can make the gateway hold: an unfinished multipart message, connections
beyond the limit; cut, counted, and nobody else's session disturbed.

A peer writes ZMTP itself (processes.stress.swarm.zmtp.RawPeer), since no libzmq socket sends a
message's frames before its last one. A Gateway in this process (the rig fixture); every wait
bounded by the suite's deadline.
"""
import pytest

from processes.network.server.config import ROUTER_RCVHWM, GatewayConfig
from processes.network.wire import Kind
from processes.stress.swarm.zmtp import RawPeer
from tests.waits import DEADLINE_S

FRAMES, FRAME_BYTES = 25_000, 4000  # 100 MB in frames within MAX_FRAME_BYTES, never ended


def _port(endpoint: str) -> int:
    return int(endpoint.rsplit(":", 1)[1])


def test_a_peer_that_never_ends_a_message_is_cut_counted_and_others_play_on(rig):
    r = rig()
    watcher = r.client(role="spectator", name="watcher")
    assert r.join(watcher).kind == Kind.WELCOME
    peer = RawPeer("127.0.0.1", _port(r.gateway.endpoint))
    peer.open_message(FRAMES, FRAME_BYTES, deadline_s=DEADLINE_S)  # returns once the gateway cuts it
    r.settle(lambda: r.gateway.stats().get("disconnected.held_bytes", 0) == 1)
    assert peer.closed_by_server(DEADLINE_S)
    stats = r.gateway.stats()
    assert stats["disconnected_total"] == 1 and stats["sessions"] == 1  # the watcher's session is untouched
    watcher.send(Kind.HEARTBEAT, ack=0)
    late = r.client(role="spectator", name="late")
    assert r.join(late).kind == Kind.WELCOME
    peer.close()


def test_a_feed_subscriber_that_never_ends_a_message_is_cut_and_counted(rig):
    r = rig()
    peer = RawPeer("127.0.0.1", r.gateway.feed_port, socket_type=b"SUB")
    peer.open_message(FRAMES, FRAME_BYTES, deadline_s=DEADLINE_S)
    r.settle(lambda: r.gateway.stats().get("feed_disconnected.held_bytes", 0) == 1)
    assert peer.closed_by_server(DEADLINE_S)
    peer.close()


def test_connections_beyond_the_limit_are_cut_at_once(rig):
    r = rig(max_connections=2)
    peers = [RawPeer("127.0.0.1", _port(r.gateway.endpoint)) for _ in range(3)]
    r.settle(lambda: r.gateway.stats().get("disconnected.too_many_connections", 0) == 1)
    assert peers[2].closed_by_server(DEADLINE_S)
    assert r.gateway.stats()["connections"] == 2
    for peer in peers:
        peer.close()


def test_a_held_limit_below_the_queued_messages_is_refused_with_the_least_it_takes():
    with pytest.raises(ValueError, match=rf"max_held_bytes: 1000 .*ROUTER_RCVHWM = {ROUTER_RCVHWM}"):
        GatewayConfig(max_held_bytes=1000)


def test_at_the_limit_a_newcomer_takes_the_place_of_a_connection_that_never_confirmed(rig):
    # Two raw connections that never say hello hold both places; once they are past their grace
    # (3 heartbeats of 0.1 s) an honest spectator's connection takes the place of one of them.
    r = rig(max_connections=2, heartbeat_s=0.1)
    hoarders = [RawPeer("127.0.0.1", _port(r.gateway.endpoint)) for _ in range(2)]
    r.settle(lambda: r.gateway.stats()["connections_unconfirmed"] == 2)
    honest = r.client(role="spectator", name="honest")
    assert r.join(honest).kind == Kind.WELCOME
    r.settle(lambda: r.gateway.stats().get("disconnected.unconfirmed_for_newcomer", 0) == 1)
    assert r.gateway.stats()["connections"] == 2
    # Newcomers again, while the honest session heartbeats: the other hoarder's connection goes,
    # then the newcomers themselves (in their grace, nothing older to take), never the honest one.
    # A newcomer the gateway refuses may be cut before its greeting is answered (on a busy
    # machine the gateway can act on the accept first): that is the refusal too.
    late = []
    for _ in range(3):
        try:
            late.append(RawPeer("127.0.0.1", _port(r.gateway.endpoint)))
        except ConnectionError:
            pass

    def settled():
        honest.heartbeat_if_due()
        stats = r.gateway.stats()
        return stats.get("disconnected.unconfirmed_for_newcomer", 0) + stats.get("disconnected.too_many_connections", 0) == 4

    r.settle(settled)
    assert r.gateway.stats()["disconnected.unconfirmed_for_newcomer"] == 2
    assert r.gateway.stats()["sessions"] == 1  # the honest session kept its connection
    assert all(peer.closed_by_server(DEADLINE_S) for peer in hoarders)
    for peer in hoarders + late:
        peer.close()
