"""The gateway's seats: who gets one, who keeps it, and a token that takes it back, on real sockets.

Sockets bind to 127.0.0.1 on random ports and close with linger 0; every receive is polled with
a timeout and every wait for an event is bounded by the suite's deadline (tests/waits.py). The
tests drive a Gateway in this process (the rig fixture) with a clock they set, so a timeout or
a grace needs no sleep.
"""
import pytest
import zmq

from processes.runtime import shm
from processes.network.client.client import Client, Rejected
from processes.network.server.gateway import Gateway
from processes.network.wire import GoodbyeReason, Kind, RejectReason, Slot
from tests.helpers.gateway import Rig
from tests.waits import Deadline


def test_two_players_get_seats_a_third_is_told_full_and_spectators_watch(rig):
    r = rig()
    a, b, c = r.client(name="ann"), r.client(name="bob"), r.client(name="cy")
    welcome_a, welcome_b = r.join(a), r.join(b)
    assert (welcome_a["slot"], welcome_b["slot"]) == (Slot.A, Slot.B)
    assert welcome_a["token"] != bytes(16) and welcome_a["token"] != welcome_b["token"]
    assert welcome_b["name_a"] == "ann" and welcome_b["name_b"] == "bob"
    with pytest.raises(Rejected) as refused:
        r.join(c)
    assert refused.value.reason == RejectReason.FULL
    watcher = r.client(role="spectator")
    welcome = r.join(watcher)
    assert welcome["slot"] == Slot.NONE and welcome["token"] == bytes(16)
    snapshot = r.until(watcher, lambda m: m.kind == Kind.SNAPSHOT, serve=True)
    assert snapshot["winner"] == -1
    assert r.gateway.stats()["rejected.full"] == 1 and r.gateway.seats_filled


def test_a_seat_played_by_the_ai_is_not_given_away(rig):
    r = rig(remote=(Slot.A,))
    with pytest.raises(Rejected) as refused:
        r.join(r.client(slot=Slot.B))
    assert refused.value.reason == RejectReason.FULL and "AI" in refused.value.detail
    assert r.join(r.client())["slot"] == Slot.A


def test_a_silent_player_is_dropped_and_its_token_reclaims_the_seat(rig):
    r = rig(remote=(Slot.A,), heartbeat_s=1.0, timeout_s=5.0, grace_s=30.0)
    player = r.client(name="ann")
    r.join(player)
    token = player.token
    r.clock.now += 6.0  # past the timeout without a word from the player
    goodbye = r.until(player, lambda m: m.kind == Kind.GOODBYE)
    assert goodbye["reason"] == GoodbyeReason.TIMEOUT
    assert r.gateway.counts["timeouts"] == 1 and not r.gateway.seats_filled
    assert r.posted == []  # nothing posted: the physics lets go of the absent arm's last input
    with pytest.raises(Rejected) as refused:  # within the grace only the token takes the seat
        r.join(r.client(name="bob"))
    assert refused.value.reason == RejectReason.FULL
    with pytest.raises(Rejected) as refused:
        r.join(r.client(token=bytes(range(16))))
    assert refused.value.reason == RejectReason.BAD_TOKEN
    back = r.client(name="ann", token=token)
    welcome = r.join(back)
    assert welcome["slot"] == Slot.A and welcome["token"] == token
    assert r.gateway.counts["rejoined"] == 1 and r.gateway.seats_filled


def test_the_token_takes_the_seat_over_from_a_connection_still_open(rig):
    r = rig(remote=(Slot.A,))
    first = r.client(name="ann")
    r.join(first)
    second = r.client(name="ann", token=first.token)
    welcome = r.join(second)
    assert welcome["slot"] == Slot.A and welcome["token"] == first.token
    assert r.until(first, lambda m: m.kind == Kind.GOODBYE)["reason"] == GoodbyeReason.KICKED
    first.send_input([1.0, 0, 0, 0, 0, 0], tick=1)  # the old connection has no say any more
    second.send_input([2.0, 0, 0, 0, 0, 0], tick=2)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1 and r.gateway.counts["dropped.no_session"] == 1)
    assert r.posted[-1][3][0] == 2.0 and r.gateway.counts["rejoined"] == 1


def test_a_player_who_says_goodbye_frees_the_seat_at_once(rig):
    r = rig(remote=(Slot.A,))
    leaving = r.client(name="ann")
    r.join(leaving)
    leaving.leave()
    r.settle(lambda: r.gateway.counts["quits"] == 1)
    assert r.join(r.client(name="bob"))["slot"] == Slot.A


def test_a_token_expires_with_the_grace_and_the_seat_is_anyones(rig):
    r = rig(remote=(Slot.A,), heartbeat_s=1.0, timeout_s=5.0, grace_s=30.0)
    ann = r.client(name="ann")
    token = r.join(ann)["token"]
    r.clock.now += 6.0
    assert r.until(ann, lambda m: m.kind == Kind.GOODBYE)["reason"] == GoodbyeReason.TIMEOUT
    r.clock.now += 30.0  # the grace is over
    with pytest.raises(Rejected) as refused:
        r.join(r.client(name="ann", token=token))
    assert refused.value.reason == RejectReason.BAD_TOKEN and r.gateway.counts["tokens_expired"] == 1
    bob = r.join(r.client(name="bob"))
    assert bob["slot"] == Slot.A and bob["token"] != token and bob["name_a"] == "bob"
    with pytest.raises(Rejected) as refused:  # and the old token is no key to the new player's seat
        r.join(r.client(name="ann", token=token))
    assert refused.value.reason == RejectReason.BAD_TOKEN


def test_a_session_of_a_replaced_gateway_is_told_goodbye_once_and_rejoins(zctx, no_leftovers):
    from processes.network.server.seats import SEAT_DTYPE, SeatStore

    arena = shm.Arena()
    store = SeatStore(arena.snapshot_block("seats", SEAT_DTYPE, 2))
    old_context = zmq.Context()  # the first gateway's own: terminating it frees the port at once
    first = Rig(old_context, remote=(Slot.A,), seat_store=store)
    endpoint = first.gateway.endpoint
    ann = Client(endpoint, "player", "ann", zctx=zctx)
    first.clients.append(ann)
    token = first.join(ann)["token"]
    first.gateway.close(linger_ms=0)  # gone without a word, as a killed gateway
    old_context.term()
    second = Rig(zctx, remote=(Slot.A,), bind=endpoint, seat_store=store)  # its successor, same endpoint
    try:
        goodbye = None
        deadline = Deadline()
        while not deadline.expired():  # the client's heartbeats reach the new gateway once it reconnects
            ann.send(Kind.HEARTBEAT, ack=0)
            second.step()
            goodbye = ann.recv(5)
            if goodbye is not None:
                break
        assert goodbye is not None and goodbye.kind == Kind.GOODBYE
        assert goodbye["reason"] == GoodbyeReason.UNKNOWN_SESSION
        ann.send(Kind.HEARTBEAT, ack=0)
        second.settle(lambda: second.gateway.counts["dropped.no_session"] >= 2)
        assert second.gateway.counts["goodbyes_to_strangers"] == 1  # told once per connection
        welcome = second.join(ann)  # hello again: the token (kept by the client) reclaims the seat
        assert welcome["slot"] == Slot.A and welcome["token"] == token and second.gateway.counts["rejoined"] == 1
    finally:
        ann.close()
        second.close()
        del store
        arena.close()


# --- seats outlive a gateway --------------------------------------------------------------------
def test_a_restarted_gateway_finds_its_seats_and_the_token_reclaims_one(zctx, no_leftovers):
    from processes.network.server.seats import SEAT_DTYPE, SeatStore

    arena = shm.Arena()
    first = second = None
    try:
        store = SeatStore(arena.snapshot_block("seats", SEAT_DTYPE, 2))
        first = Rig(zctx, seat_store=store)
        ann = first.client(name="ann")
        welcome = first.join(ann)
        token = welcome["token"]
        first.gateway.close()  # killed: no goodbye, no last save; only what it saved on the way
        # (the worker's successor binds the same endpoint: the served test below; here any port)
        second = Rig(zctx, seat_store=store)
        assert second.gateway.counts["seats_restored"] == 1
        thief = second.client(name="eve", slot=Slot.A)
        with pytest.raises(Rejected) as refused:  # the seat waits for its token
            second.join(thief)
        assert refused.value.reason == RejectReason.FULL
        back = second.client(name="ann", token=token)
        again = second.join(back)
        assert again["slot"] == Slot.A and again["token"] == token and again["name_a"] == "ann"
        assert second.gateway.stats()["rejoined"] == 1
        del store
    finally:
        for r in (first, second):
            if r is not None:
                for client in r.clients:
                    client.close()
        if second is not None:
            second.gateway.close()
        arena.close()
