"""Places that cannot be hoarded: a session that sends nothing after its hello holds its place
only for CONFIRM_HEARTBEATS heartbeat periods, and a hello that finds the places full takes the
place of the oldest such session silent for a heartbeat period; a full server says when to retry.

A Gateway in this process (the rig fixture) with a clock the test sets. A "bare hello" is a
client that sends its hello and never answers the welcome (Client.join answers it at once).
"""
from processes.network.client.client import Rejected
from processes.network.server.sessions import CONFIRM_HEARTBEATS
from processes.network.wire import GoodbyeReason, Kind, RejectReason, Slot


def _bare_hello(r, **client):
    hoarder = r.client(**client)
    assert _answer(r, hoarder).kind == Kind.WELCOME
    return hoarder


def _answer(r, client):
    client.hello()
    return r.until(client, lambda m: m.kind in (Kind.WELCOME, Kind.REJECT))


def test_a_hello_that_finds_the_places_full_takes_a_bare_hellos_place(rig):
    r = rig(max_spectators=2, heartbeat_s=1.0, timeout_s=5.0)
    hoarders = [_bare_hello(r, role="spectator", name=f"h{i}") for i in range(2)]
    early = r.client(role="spectator", name="early")  # a bare hello's answer may still be on its way
    reject = _answer(r, early)
    assert reject.kind == Kind.REJECT and "retry in 1 s" in reject["detail"]
    assert Rejected(reject["reason"], reject["detail"]).retry_s == 1.0  # what a client reads of it
    r.clock.now += 1.5  # a heartbeat period and more: a live peer would have answered its welcome
    honest = r.client(role="spectator", name="honest")
    assert r.join(honest).kind == Kind.WELCOME
    goodbye = r.until(hoarders[0], lambda m: m.kind == Kind.GOODBYE)  # the oldest one
    assert goodbye["reason"] == GoodbyeReason.KICKED
    assert r.gateway.counts["evicted.unconfirmed"] == 1
    second = r.client(role="spectator", name="second")
    assert r.join(second).kind == Kind.WELCOME  # the other bare hello's place
    third = r.client(role="spectator", name="third")
    reject = _answer(r, third)  # now every place is held by a session that answered its welcome
    assert reject.kind == Kind.REJECT and reject["reason"] == RejectReason.FULL
    assert "2 spectators already watch; retry in 5 s" in reject["detail"]
    assert Rejected(reject["reason"], reject["detail"]).retry_s == 5.0
    assert Rejected(RejectReason.BAD_TOKEN, "unknown or expired rejoin token").retry_s is None


def test_a_bare_hello_is_timed_out_after_a_few_heartbeats_and_frees_its_seat(rig):
    r = rig(heartbeat_s=1.0, timeout_s=5.0)
    hoarder = _bare_hello(r, role="player", slot=Slot.A)
    r.clock.now += CONFIRM_HEARTBEATS * 1.0 + 0.5  # well inside timeout_s
    goodbye = r.until(hoarder, lambda m: m.kind == Kind.GOODBYE)
    assert goodbye["reason"] == GoodbyeReason.TIMEOUT
    assert r.gateway.counts["timeouts.unconfirmed"] == 1 and r.gateway.counts["timeouts"] == 0
    player = r.client(slot=Slot.A)  # the seat is free at once: no grace for a token never used
    assert r.join(player)["slot"] == Slot.A


def test_a_seat_held_by_a_bare_hello_goes_to_a_player_that_asks_for_it(rig):
    r = rig(remote=(Slot.A,), heartbeat_s=1.0, timeout_s=5.0)
    hoarder = _bare_hello(r, role="player", slot=Slot.A)
    r.clock.now += 1.5
    player = r.client(slot=Slot.A, name="honest")
    assert r.join(player)["slot"] == Slot.A
    assert r.until(hoarder, lambda m: m.kind == Kind.GOODBYE)["reason"] == GoodbyeReason.KICKED
    late = r.client(slot=Slot.A, name="late")  # held by a player that answered: refused
    reject = _answer(r, late)
    assert reject.kind == Kind.REJECT and reject["reason"] == RejectReason.FULL


def test_a_session_that_answered_its_welcome_is_never_timed_out_early(rig):
    r = rig(heartbeat_s=1.0, timeout_s=5.0)
    watcher = r.client(role="spectator")
    r.join(watcher)
    r.settle(lambda: all(s.confirmed for s in r.gateway.sessions.values()))
    r.clock.now += 4.5  # past the bare hello's bound, within timeout_s
    for _ in range(20):
        r.step()
    assert len(r.gateway.sessions) == 1 and r.gateway.counts["timeouts.unconfirmed"] == 0


def test_hellos_sent_again_in_a_session_keep_no_place(rig):
    # A hoarder that says hello again on its session every half heartbeat instead of answering:
    # each one is refused (hello_in_session) and is no sign of life, so it is timed out as a
    # session that never answered its welcome.
    r = rig(heartbeat_s=1.0, timeout_s=5.0)
    hoarder = _bare_hello(r, role="spectator", name="h")
    for _ in range(2 * CONFIRM_HEARTBEATS + 1):
        r.clock.now += 0.5
        hoarder.hello()
        r.step()
    goodbye = r.until(hoarder, lambda m: m.kind == Kind.GOODBYE)
    assert goodbye["reason"] == GoodbyeReason.TIMEOUT
    assert r.gateway.counts["timeouts.unconfirmed"] == 1
    assert r.gateway.counts["dropped.hello_in_session"] >= 1


def test_one_address_may_take_only_so_many_sessions_and_hellos_when_the_server_says_so(rig):
    r = rig(max_sessions_per_address=2, heartbeat_s=1.0, timeout_s=5.0)
    assert [r.join(r.client(role="spectator", name=f"s{i}")).kind for i in range(2)] == [Kind.WELCOME] * 2
    third = _answer(r, r.client(role="spectator", name="s2"))
    assert third.kind == Kind.REJECT and third["reason"] == RejectReason.FULL
    assert third["detail"] == "2 sessions from 127.0.0.1 already"
    assert r.gateway.counts["rejected.address"] == 1
    fast = rig(hellos_per_s_per_address=2.0, heartbeat_s=1.0, timeout_s=5.0)
    answers = [_answer(fast, fast.client(role="spectator", name=f"h{i}")) for i in range(3)]  # the clock stands
    assert [a.kind for a in answers] == [Kind.WELCOME, Kind.WELCOME, Kind.REJECT]
    assert answers[2]["detail"] == "more than 2 hellos a second from 127.0.0.1; retry in 1 s"
    fast.clock.now += 0.5  # a second's worth refills in a second: one more hello now
    assert _answer(fast, fast.client(role="spectator", name="later")).kind == Kind.WELCOME


def test_no_address_limit_by_default(rig):
    r = rig(max_spectators=8)
    assert all(r.join(r.client(role="spectator", name=f"s{i}")).kind == Kind.WELCOME for i in range(8))
