"""The gateway: sessions, seats, refusals, drops, heartbeats and a served match, on real sockets.

Sockets bind to 127.0.0.1 on random ports and close with linger 0; every receive is polled with
a timeout and every wait for an event is bounded by the suite's deadline (tests/waits.py).
The session tests drive a Gateway in this process with a clock they set, so a heartbeat timeout
needs no sleep; the match tests run `pingpong serve` and `pingpong join --bot` as processes.
"""
import json
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
import zmq

from engine.dtypes import physics_snapshot_dtype
from engine.scene import SceneError, load_scene, parse_scene, with_remote_players
from processes.network import wire
from processes.runtime import shm
from processes.network.client.client import Client, Rejected
from processes.network.server.gateway import Gateway, GatewayConfig
from processes.supervisor import workers_for
from processes.network.wire import GoodbyeReason, Kind, RejectReason, Role, Slot
from tests.processes.conftest import ctrl_c_able
from tests.waits import DEADLINE_S, Deadline, line, rest

ROOT = Path(__file__).resolve().parents[4]
ROUNDS = 400  # pump rounds of a bounded exchange (each polls for at most 10 ms)


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class Rig:
    """A Gateway on a random port of 127.0.0.1, its clients, and a physics record to serve."""

    def __init__(self, zctx, remote=(Slot.A, Slot.B), seat_store=None, clock=None, **config):
        self.zctx = zctx
        self.clock = Clock() if clock is None else clock
        self.posted = []
        settings = dict(bind="tcp://127.0.0.1:0", snapshot_hz=1000, heartbeat_s=1.0, timeout_s=5.0, grace_s=30.0)
        settings.update(config)
        self.gateway = Gateway(zctx, GatewayConfig(**settings), scene_name="match_rigid", best_of=1, dt=0.001,
                               remote_slots=remote, post_input=self._post, clock=self.clock, seat_store=seat_store)
        self.record = np.zeros(1, physics_snapshot_dtype(2))[0]
        self.record["bats"]["quat"] = (1.0, 0.0, 0.0, 0.0)
        self.record["rally"]["winner"] = -1
        self.clients = []

    def _post(self, bat, seq, tick, inputs):
        self.posted.append((bat, seq, tick, np.array(inputs)))
        return True

    def client(self, role="player", slot=Slot.NONE, token=bytes(16), name="p", socket_options=None) -> Client:
        client = Client(self.gateway.endpoint, role, name, slot, token, zctx=self.zctx, socket_options=socket_options)
        self.clients.append(client)
        return client

    def step(self, serve=False):
        self.gateway.poll(2)
        if serve:  # a snapshot per step: a feed subscriber that is still connecting misses the first ones
            self.clock.now += 1.0 / self.gateway.config.snapshot_hz
        self.gateway.service(self.record if serve else None)

    def until(self, client, predicate, serve=False):
        """Pump gateway and client until the client gets a message satisfying predicate (within the deadline)."""
        deadline, last = Deadline(), None
        while not deadline.expired():
            self.step(serve)
            message = client.recv(5)
            if message is not None:
                if predicate(message):
                    return message
                last = message
        raise AssertionError(f"no such message within {DEADLINE_S:.0f} s; the last one: {last}")

    def settle(self, check):
        """Pump the gateway until check() holds (within the deadline)."""
        deadline = Deadline()
        while not deadline.expired():
            self.step()
            if check():
                return
        raise AssertionError(f"the gateway never got there within {DEADLINE_S:.0f} s; counts: {self.gateway.counts}")

    def join(self, client):
        client.hello()
        message = self.until(client, lambda m: m.kind in (Kind.WELCOME, Kind.REJECT))
        client.accept(message)
        return message

    def close(self):
        for client in self.clients:
            client.close()
        self.gateway.close()


@pytest.fixture
def rig(zctx):
    made = []

    def make(**kwargs):
        made.append(Rig(zctx, **kwargs))
        return made[-1]

    yield make
    for r in made:
        r.close()


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


def test_a_player_moves_only_its_own_bat_and_the_refusals_are_counted(rig):
    r = rig()
    a, b = r.client(), r.client()
    r.join(a)
    r.join(b)
    a.send_input([1.0, 2.0, 3.0, 0.1, 0.2, 0.3], tick=7)
    a.send_input([5.0, 0, 0, 0, 0, 0], tick=8, slot=Slot.B)  # the other player's bat
    a.send_input([6.0, 0, 0, 0, 0, 0], tick=9)
    watcher = r.client(role="spectator")
    r.join(watcher)
    watcher.send_input([1.0, 0, 0, 0, 0, 0], tick=9, slot=Slot.A)  # a spectator controls nothing
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 2 and r.gateway.counts["refused.spectator_input"] == 1)
    assert r.gateway.counts["refused.other_bat"] == 1
    assert [(bat, tick) for bat, _, tick, _ in r.posted] == [(0, 7), (0, 9)]  # bat 0 = A; nothing for B
    np.testing.assert_array_equal(r.posted[0][3], [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    assert r.posted[1][1] > r.posted[0][1]  # the input's seq rides along, for the snapshot's echo


def test_the_gateway_only_forwards_inputs_the_idle_arm_is_the_physics(rig):
    # The hold and the brake are the physics' (processes.workers.hub.RemoteInputs): the gateway
    # posts nothing when an input's hold passes, for a moving bat on an empty seat, or as a
    # player leaves.
    r = rig(remote=(Slot.A,), input_hold_s=0.1, timeout_s=5.0)
    r.record["bats"]["vel"][0] = (2.0, 0.0, 0.0)  # bat A moves
    a = r.client()
    r.join(a)
    a.send_input([30.0, 0, 0, 0, 0, 0], tick=3)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1)
    r.clock.now += 1.0  # long past the hold
    for _ in range(5):
        r.step(serve=True)
    a.leave()
    r.settle(lambda: r.gateway.seats[Slot.A].identity is None)
    r.step(serve=True)
    assert len(r.posted) == 1 and r.posted[0][3][0] == 30.0


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


def test_snapshots_follow_the_match_clock_and_say_how_fast_it_runs(rig):
    # 100 Hz and 1 ms ticks: one snapshot every 10 ticks of match time. The match runs at half
    # the wall clock's speed, then at its speed, then stands: the snapshots come every 10 ticks
    # (so at 50 Hz, then 100 Hz), then repeat the same tick at 100 Hz, and realtime_factor says
    # 0.5, 1, 0. Tolerance 0.002: a tick of 500 in the 1 s window the factor is measured over.
    r = rig(remote=(Slot.A,), snapshot_hz=100, timeout_s=60.0)
    player = r.client()
    r.join(player)
    assert r.gateway.pacer.ticks == 10
    world = r.record["world"]
    phases = {"half": [], "full": [], "stand": []}
    tick = 0

    def read(phase, wait_ms):
        while (message := player.recv(wait_ms)) is not None:
            if message.kind == Kind.SNAPSHOT:
                phases[phase].append((message.tick, float(message["realtime_factor"])))
                return True
        return False

    for phase, ms, advance in (("half", 3000, 0.5), ("full", 2000, 1.0), ("stand", 2000, 0.0)):
        start = tick
        for k in range(1, ms + 1):
            r.clock.now += 0.001
            tick = start + int(k * advance)
            world["tick"], world["time"] = tick, tick * 0.001
            r.gateway.poll(0)
            r.gateway.service(r.record)
            while read(phase, 0):
                pass
        # every snapshot sent in this phase counts for it, also one still in the socket
        sent = r.gateway.counts["snapshots_sent"]
        deadline = Deadline()
        while sum(map(len, phases.values())) < sent and not deadline.expired():
            read(phase, 100)
    for phase, expected_hz, factor in (("half", 50, 0.5), ("full", 100, 1.0), ("stand", 100, 0.0)):
        ticks = [t for t, _ in phases[phase]]
        steps = set(np.diff(ticks[1:]))
        assert steps == ({0} if phase == "stand" else {10}), (phase, sorted(steps))
        seconds = {"half": 3, "full": 2, "stand": 2}[phase]
        assert abs(len(ticks) - expected_hz * seconds) <= 2, (phase, len(ticks))
        late = [f for _, f in phases[phase][len(ticks) // 2:]]  # after a full window in the phase
        assert max(abs(f - factor) for f in late) <= 0.002, (phase, late[:3])


def test_the_rally_number_is_the_rally_in_play_and_an_event_carries_the_rally_it_decided(rig):
    # A whole best-of-1 match in process, served tick by tick as the gateway worker serves it:
    # the first rally is number 1 from its toss on, every point event carries the number the
    # snapshots carried while it was played, and the match event the last rally's.
    from engine.dtypes import POINT_DTYPE
    from engine.match import Match, point_row

    from dataclasses import replace

    scene = load_scene("match_rigid")
    match = Match(replace(scene, match=replace(scene.match, best_of=1)), seed=3)
    r = rig(remote=(Slot.A,), snapshot_hz=100, timeout_s=600.0)  # the fake clock runs the whole match
    watcher = r.client()  # a player's session gets events and snapshots (no feed)
    r.join(watcher)
    points = np.zeros(len(match.referee.points) + 64, POINT_DTYPE)
    playing, decided = {}, []
    for _ in range(400_000):
        if match.referee.match_over:
            break
        match.tick(10)  # up to a snapshot's 10 ticks (the same match for any chunk: Match.tick)
        for k in range(int(match.state.record[0]["rally"]["points_total"])):
            points[k] = point_row(match.referee.points[k], 0)
        r.clock.now += 0.001 * match.ticks_done
        r.gateway.service(match.state.record[0], points=points)
        session = next(iter(r.gateway.sessions.values()))
        deadline = Deadline()  # read every message sent so far: none is lost to the socket's high-water mark
        while watcher.max_seq_in < session.seq_out and not deadline.expired():
            if (message := watcher.recv(100)) is None:
                continue
            if message.kind == Kind.SNAPSHOT:
                playing.setdefault(int(message["rally"]), []).append(message.tick)
            elif message.kind == Kind.EVENT:
                decided.append((int(message["event"]), int(message["rally"])))
    assert match.referee.match_over
    n = len(match.referee.points)
    assert min(playing) == 1 and sorted(playing) == list(range(1, n + 1))  # 1 from the first toss on
    point_rallies = [rally for event, rally in decided if event == wire.EventKind.POINT]
    assert point_rallies == list(range(1, n + 1))  # each point: the rally it decided
    assert [rally for event, rally in decided if event == wire.EventKind.MATCH] == [n]


def _good_input(seq=1):
    return bytearray(wire.encode(Kind.INPUT, seq=seq, tick=1, slot=Slot.A, mode=wire.InputMode.FORCE,
                                 force=[1.0, 0, 0], torque=[0, 0, 0], target_pos=[0, 0, 0],
                                 target_quat=[0, 0, 0, 0]))


def _malformed() -> dict:
    good = _good_input()
    wrong_version = bytearray(good)
    wrong_version[4:6] = (9).to_bytes(2, "little")
    wrong_type = bytearray(good)
    wrong_type[6] = 99
    nan = bytearray(good)
    nan[26:34] = np.float64("nan").tobytes()
    out_of_range = bytearray(good)
    out_of_range[26:34] = np.float64(1e6).tobytes()
    return {"too_short": bytes(good[:20]), "too_long": bytes(good) + b"\0", "bad_version": bytes(wrong_version),
            "unknown_type": bytes(wrong_type), "non_finite": bytes(nan), "out_of_range": bytes(out_of_range),
            "bad_magic": b"XXXX" + bytes(good[4:])}


def test_malformed_messages_are_dropped_counted_and_never_fatal(rig):
    r = rig()
    player = r.client()
    r.join(player)
    bad = _malformed()
    for data in bad.values():
        player.send_raw(data)
    player.sock.send_multipart([bytes(_good_input(50)), b"extra"])  # two frames: not one message
    stranger = r.client()
    stranger.send_raw(bytes(_good_input()))  # valid, but no session
    r.settle(lambda: r.gateway.stats()["dropped_total"] == len(bad) + 2)
    stats = r.gateway.stats()
    for reason in bad:
        assert stats[f"dropped.{reason}"] == 1, reason
    assert stats["dropped.bad_framing"] == 1 and stats["dropped.no_session"] == 1
    assert r.posted == [] and len(r.gateway.sessions) == 1  # nothing reached the bat; the player is still in
    player.send_input([2.0, 0, 0, 0, 0, 0], tick=3)
    r.settle(lambda: r.gateway.counts["inputs_accepted"] == 1)
    version = r.client()
    version.send_raw(bytes(bytearray(wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="old",
                                                 token=bytes(16)))[:4]) + (1).to_bytes(2, "little")
                     + wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="old", token=bytes(16))[6:])
    reject = r.until(version, lambda m: m.kind == Kind.REJECT)
    assert reject["reason"] == RejectReason.VERSION


def _first_snapshot(r, client, tick):
    """Serve ticks from `tick` on until `client` gets a snapshot (its feed subscription is live);
    returns the next tick to serve."""
    deadline = Deadline()
    while not deadline.expired():
        r.record["world"]["tick"] = tick
        r.clock.now += 0.002
        r.gateway.service(r.record)
        tick += 1
        message = client.recv(10)
        if message is not None and message.kind == Kind.SNAPSHOT:
            return tick
    raise AssertionError(f"no snapshot on the feed within {DEADLINE_S:.0f} s (served up to tick {tick})")


def test_a_slow_spectator_loses_feed_snapshots_countably_not_the_match(rig):
    # The feed's policy: a subscriber whose queue holds SNDHWM messages (beyond the kernel's
    # buffers) loses the newest ones, nobody else does; the gaps in the feed's seqs count them.
    r = rig(sndhwm=64, sndbuf=4096, timeout_s=60.0)  # the clock runs 4 s with nobody heartbeating
    fast = r.client(role="spectator")
    slow = r.client(role="spectator", socket_options={zmq.RCVHWM: 1, zmq.RCVBUF: 4096})
    for client in (fast, slow):
        assert r.join(client)["feed_port"] == r.gateway.feed_port > 0
        assert client.feed is not None
    tick = _first_snapshot(r, slow, 1)
    tick = _first_snapshot(r, fast, tick)
    while fast.recv(50) is not None:  # what the fast one had queued so far
        pass
    first, received, seqs = tick, 0, []
    for tick in range(first, first + 2000):  # the slow one does not read; the fast one keeps up
        r.record["world"]["tick"] = tick
        r.clock.now += 0.002
        r.gateway.service(r.record)
        deadline = Deadline()
        while not deadline.expired():
            message = fast.recv(100)
            if message is not None and message.kind == Kind.SNAPSHOT:
                received += 1
                if message.tick == tick:
                    break
    assert received == 2000 and fast.feed_missed == 0  # the fast one got every snapshot
    for _ in range(2000):  # the slow one reads again: what was queued for it (bounded)
        message = slow.recv(200)
        if message is None:
            break
        if message.kind == Kind.SNAPSHOT:  # (its session's heartbeats are another stream)
            seqs.append(message.seq)
    r.record["world"]["tick"] = tick + 1  # one more snapshot: its seq shows the slow one the gap
    r.clock.now += 0.002
    r.gateway.service(r.record)

    def counted(message):  # what the reading above had not reached yet counts as received too
        if message.kind == Kind.SNAPSHOT and message.tick != tick + 1:
            seqs.append(message.seq)
        return message.kind == Kind.SNAPSHOT and message.tick == tick + 1

    last = r.until(slow, counted)
    assert slow.feed_missed > 1000  # most of the 2000 were dropped for the slow one
    assert len(seqs) + 1 + slow.feed_missed == last.seq - seqs[0] + 1  # each one received or counted missing
    assert len(r.gateway.sessions) == 2 and r.gateway.counts["timeouts"] == 0  # nobody lost the match
    assert r.gateway.counts["snapshots_sent"] == 0  # one publish a tick, no send per spectator


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
            wire.decode(data)
            valid = True
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


def test_a_slow_spectator_loses_snapshots_not_the_match_without_a_feed(rig):
    # The fan-out of protocol 1 (GatewayConfig.feed=False): one send per session, drops counted
    # per session by the gateway.
    # A pipe's writer learns of reads only in credit batches of about hwm/2 messages, sent by the
    # reader's I/O thread; with hwm 4 a loaded machine let a fast reader look full for one tick
    # (CI, 2026-11-23). At 64 the credit lag of a reader that keeps up is far below the mark,
    # while the slow reader, which never reads again, still fills it within a few hundred ticks.
    r = rig(sndhwm=64, sndbuf=4096, feed=False)
    fast = r.client(role="spectator")
    slow = r.client(role="spectator", socket_options={zmq.RCVHWM: 1, zmq.RCVBUF: 4096})
    r.join(fast)
    r.join(slow)
    received = 0
    for tick in range(1, 20_001):  # the slow one never reads again; the fast one keeps up
        r.record["world"]["tick"] = tick
        r.clock.now += 0.002
        r.gateway.service(r.record)
        deadline = Deadline()
        while not deadline.expired():  # the fast one reads this tick's snapshot before the next is sent
            message = fast.recv(100)
            if message is not None and message.kind == Kind.SNAPSHOT:
                received += 1
                if message.tick == tick:
                    break
        if r.gateway.counts["snapshots_dropped"] >= 100:
            break
    assert r.gateway.counts["snapshots_dropped"] >= 100
    dropped = sorted(session.snapshots_dropped for session in r.gateway.sessions.values())
    assert dropped[0] == 0 and dropped[1] >= 100  # only the slow one lost any
    assert received == tick  # the fast one got every snapshot


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


def test_a_malformed_hello_is_rejected_bad_request_with_the_decoders_reason(rig):
    r = rig()
    hello = wire.encode(Kind.HELLO, role=Role.PLAYER, slot=Slot.NONE, name="ann", token=bytes(16))
    bad_name = bytearray(hello)
    bad_name[26:30] = b"\x1b[2J"[:4]  # a terminal escape in the name
    watcher_with_slot = bytearray(wire.encode(Kind.HELLO, role=Role.SPECTATOR, slot=Slot.NONE, name="sp",
                                              token=bytes(16)))
    watcher_with_slot[25] = int(Slot.A)
    cases = {"too_short": hello[:40], "too_long": hello + b"\0", "bad_text": bytes(bad_name),
             "out_of_range": bytes(watcher_with_slot)}
    for reason, data in cases.items():
        client = r.client()
        client.send_raw(data)
        reject = r.until(client, lambda m: m.kind == Kind.REJECT)
        assert reject["reason"] == RejectReason.BAD_REQUEST and reject["detail"], reason
        assert r.gateway.stats()[f"dropped.{reason}"] == 1
    assert "hello.slot" in reject["detail"]  # the decoder's own words: what was wrong
    assert r.gateway.counts["rejected.bad_request"] == len(cases) and r.gateway.sessions == {}
    stranger = r.client()
    stranger.send_raw(bytes(_good_input()))  # not a hello: no reject (a goodbye, see below)
    assert r.until(stranger, lambda m: True).kind == Kind.GOODBYE


def test_target_mode_is_refused_counted_and_kicks_like_any_bad_message(rig):
    from processes.network.wire import MAX_BAD

    r = rig()
    player = r.client()
    r.join(player)
    for _ in range(MAX_BAD):
        player.send(Kind.INPUT, slot=Slot.A, mode=wire.InputMode.TARGET, force=[0, 0, 0], torque=[0, 0, 0],
                    target_pos=[-1.6, 0.0, 0.15], target_quat=[1.0, 0, 0, 0])
    goodbye = r.until(player, lambda m: m.kind == Kind.GOODBYE)
    assert goodbye["reason"] == GoodbyeReason.KICKED
    assert r.gateway.counts["refused.target_mode"] == MAX_BAD and r.gateway.counts["kicked"] == 1
    assert r.posted == []  # no target reached the bat


def test_a_force_input_with_target_fields_is_dropped_and_counted_as_a_bad_message(rig):
    r = rig()
    player = r.client()
    r.join(player)
    data = bytearray(wire.encode(Kind.INPUT, slot=Slot.A, mode=wire.InputMode.FORCE, force=[1.0, 0, 0],
                                 torque=[0, 0, 0], target_pos=[0, 0, 0], target_quat=[0, 0, 0, 0]))
    at = wire.SPECS[Kind.INPUT].dtype.fields["target_pos"][1]
    data[at:at + 8] = np.float64(0.5).tobytes()  # target_pos.x, which force mode keeps zero
    player.send_raw(bytes(data))
    r.settle(lambda: r.gateway.drops.by_reason["out_of_range"] == 1)
    assert r.posted == [] and [s.bad for s in r.gateway.sessions.values()] == [1]  # not applied; one bad
    assert player.recv(100) is None  # and not answered


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


def test_a_relay_republishes_the_feed_byte_for_byte_to_its_subscribers(rig, zctx):
    from processes.network.server.relay import Relay

    r = rig()
    watcher = r.client(role="spectator")
    r.join(watcher)  # a spectator of the gateway itself, to compare with
    relay = Relay(r.gateway.feed_endpoint, "tcp://127.0.0.1:0")
    endpoint = relay.start()
    subscribers = []
    try:
        for _ in range(2):
            sub = zctx.socket(zmq.SUB)
            sub.setsockopt(zmq.LINGER, 0)
            sub.setsockopt(zmq.SUBSCRIBE, b"")
            sub.connect(endpoint)
            subscribers.append(sub)
        tick = 0
        got = [None, None]
        deadline = Deadline()
        while not deadline.expired():  # serve ticks until both relayed subscriptions are live
            tick += 1
            r.record["world"]["tick"] = tick
            r.clock.now += 0.002
            r.gateway.service(r.record)
            for i, sub in enumerate(subscribers):
                if got[i] is None and sub.poll(5, zmq.POLLIN):
                    got[i] = sub.recv()
            if all(got):
                break
        assert all(got), "the relay forwarded nothing"
        later = tick + 1  # one more snapshot: every subscriber gets exactly the feed's bytes
        r.record["world"]["tick"] = later
        r.clock.now += 0.002
        r.gateway.service(r.record)
        relayed = []
        for sub in subscribers:
            for _ in range(ROUNDS):
                assert sub.poll(int(1000 * DEADLINE_S), zmq.POLLIN), f"the relay lost the snapshot of tick {later}"
                data = sub.recv()
                if wire.decode(data).tick == later:
                    relayed.append(data)
                    break
        direct = _first_tick(watcher, later)
        direct_bytes = wire.encode(direct.kind, seq=direct.seq, tick=direct.tick, flags=direct.flags, **direct.fields)
        assert relayed[0] == relayed[1] == direct_bytes  # the feed's own bytes, its seq included
    finally:
        for sub in subscribers:
            sub.close(linger=0)
        relay.stop()


def _first_tick(client, tick):
    deadline = Deadline()
    while not deadline.expired():
        message = client.recv(10)
        if message is not None and message.kind == Kind.SNAPSHOT and message.tick == tick:
            return message
    raise AssertionError(f"no snapshot of tick {tick} within {DEADLINE_S:.0f} s")


def test_serve_web_shows_the_page_beside_the_match(served):
    import urllib.request

    server = _pingpong("serve", "--players", "0", "--ticks", "600000", "--web", "127.0.0.1:0", "--json")
    served.append(server)
    assert "listening" in json.loads(line(server, "the server's listening line"))
    url = json.loads(line(server, "the web bridge's line"))["web"]  # the bridge joined as a spectator, serves the page
    with urllib.request.urlopen(url, timeout=DEADLINE_S) as reply:
        assert reply.status == 200 and b"app.js" in reply.read()
    os.kill(server.pid, signal.SIGINT)
    assert server.wait(DEADLINE_S) == 130
    interrupted = json.loads(rest(server, "the server's counters").strip().splitlines()[-1])
    assert interrupted["gateway"]["spectators_joined"] == 1  # the bridge, a gateway client like any other


def test_watch_smoke_runs(served):
    lonely = _pingpong("watch", "tcp://127.0.0.1:9", "--web", "127.0.0.1:0", "--join-timeout", "0.5")
    served.append(lonely)
    assert lonely.wait(DEADLINE_S) == 4 and "no welcome" in lonely.stderr.read()  # nobody there: no welcome in time
    bad = _pingpong("watch", "tcp://127.0.0.1:9", "--web", "8080")
    served.append(bad)
    assert bad.wait(DEADLINE_S) == 2 and "HOST:PORT" in bad.stderr.read()


def test_relay_smoke_runs(served):
    relay = _pingpong("relay", "tcp://127.0.0.1:9", "--bind", "tcp://127.0.0.1:0", "--seconds", "0.2", "--json")
    served.append(relay)
    said = json.loads(line(relay, "the relay's listening line"))
    assert said["relaying"] == "tcp://127.0.0.1:9" and said["listening"].startswith("tcp://127.0.0.1:")
    assert relay.wait(DEADLINE_S) == 0


def test_serving_a_scene_makes_its_bats_remote_and_starts_a_gateway():
    scene = load_scene("match_rigid")
    one, two = with_remote_players(scene, 1), with_remote_players(scene, 2)
    assert [b.remote for b in one.bats] == [True, False] and one.bats[1].skill == "pro"
    assert workers_for(one) == ["physics", "ai", "gateway"]
    assert workers_for(two) == ["physics", "gateway"] and "ai" not in two.effects
    assert workers_for(scene) == ["physics", "ai"]
    with pytest.raises(SceneError):
        with_remote_players(load_scene("rally"), 1)


# --- served matches: pingpong serve and join as processes -------------------------------------
def _pingpong(*args) -> subprocess.Popen:
    """`pingpong ARGS` in a session of its own, with SIGINT's default handling (conftest.ctrl_c_able)."""
    return subprocess.Popen(ctrl_c_able(*args), cwd=ROOT, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _descendants(pid: int) -> set[int]:
    found, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = (task / "children").read_text().split()
            except OSError:
                continue
            for child in map(int, children):
                if child not in found:
                    found.add(child)
                    todo.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().split("State:")[1].split("\n")[0]
    except (OSError, IndexError):
        return False


@pytest.fixture
def served():
    """`pingpong` processes of a test: stopped and reaped at the end, whatever happened.

    SIGTERM first, so a server's supervisor removes its shared memory (a SIGKILLed supervisor
    cannot: a test that failed mid-match left its segments in /dev/shm); then SIGKILL to the
    whole session for whatever is left."""
    started = []
    yield started
    for proc in started:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                pass
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
        proc.stdout.close()
        proc.stderr.close()


def _await_gone(pids, seconds=DEADLINE_S):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.1)  # polling for exits of other processes, bounded
    return [p for p in pids if _alive(p)]


def test_two_bot_players_and_a_spectator_play_a_served_match(served):
    server = _pingpong("serve", "--players", "2", "--best-of", "1", "--ticks", "2500", "--snapshot-hz", "100",
                       "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    endpoint = hello["listening"]
    assert endpoint.startswith("tcp://127.0.0.1:")
    # the clients leave at the match's end; --seconds is only their own safety net
    bots = [_pingpong("join", endpoint, "--as", "player", "--bot", "--json", "--seconds", f"{DEADLINE_S:.0f}")
            for _ in range(2)]
    served.extend(bots)
    spectator = _pingpong("join", endpoint, "--as", "spectator", "--json", "--seconds", f"{DEADLINE_S:.0f}")
    served.append(spectator)
    summary = json.loads(line(server, "the server's summary"))
    assert server.wait(DEADLINE_S) == 0
    reports = [json.loads(line(p, "a client's report")) for p in (*bots, spectator)]
    assert sorted(r["slot"] for r in reports) == ["a", "b", "none"]
    for report in reports:
        assert report["goodbye"] == "match_over", report
        assert report["snapshots"] > 0 and report["dropped"] == {}
    for bot in reports[:2]:  # the physics applied this bot's inputs: the snapshots echo their seq
        assert bot["inputs_sent"] > 0 and bot["input_seq"]["ab".index(bot["slot"])] > 0
        prediction = bot["prediction"]  # each bot predicted and scored its prediction on the snapshots
        assert prediction["scored"] > 0 and prediction["ball"]["n"] == prediction["bat"]["n"] == prediction["scored"]
        assert prediction["ball"]["max_mm"] >= prediction["ball"]["p99_mm"] >= prediction["ball"]["p50_mm"] >= 0.0
    assert reports[2]["interpolation"]["samples"] > 0  # the spectator's view was interpolated
    gateway = summary["gateway"]
    assert summary["ticks"] == 2500 or summary["winner"] is not None
    assert gateway["players_joined"] == 2 and gateway["spectators_joined"] == 1
    assert gateway["inputs_accepted"] > 100 and gateway.get("refused.other_bat", 0) == 0
    assert gateway["goodbyes_at_end"] == 3 and gateway["dropped_total"] == 0
    assert not shm.leftover_segments(hello["run_id"])


def test_serve_and_join_smoke_runs(served):
    server = _pingpong("serve", "--players", "0", "--ticks", "2", "--json")
    served.append(server)
    # The first line comes once the workers are ready: on a cold numba cache they compile first.
    assert json.loads(line(server, "the server's listening line"))["players"] == 0
    summary = json.loads(line(server, "the server's summary"))
    assert summary["ticks"] == 2 and summary["gateway"]["goodbyes_at_end"] == 0
    assert server.wait(DEADLINE_S) == 0
    lonely = _pingpong("join", "tcp://127.0.0.1:9", "--as", "spectator", "--join-timeout", "0.5")
    served.append(lonely)
    assert lonely.wait(DEADLINE_S) == 4  # nobody there: no welcome in time
    keyboard = _pingpong("join", "tcp://127.0.0.1:9", "--as", "player")
    served.append(keyboard)
    assert keyboard.wait(DEADLINE_S) == 2 and "keyboard" in keyboard.stderr.read()


def test_ctrl_c_on_the_server_says_goodbye_and_leaves_nothing_behind(served, zctx):
    server = _pingpong("serve", "--players", "1", "--ticks", "600000", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    client = Client(hello["listening"], "player", "ann", zctx=zctx)
    try:
        welcome = client.join(DEADLINE_S)
        assert welcome["slot"] == Slot.A
        snapshots = 0
        deadline = Deadline()
        while not deadline.expired():  # the match has started: snapshots arrive
            client.heartbeat_if_due()
            message = client.recv(100)
            snapshots += message is not None and message.kind == Kind.SNAPSHOT
            if snapshots >= 5:
                break
        assert snapshots >= 5
        workers = _descendants(server.pid)
        assert len(workers) >= 3  # forkserver, physics, AI, gateway (and the resource tracker)
        os.kill(server.pid, signal.SIGINT)
        goodbye, deadline = None, Deadline()
        while not deadline.expired():
            message = client.recv(100)
            if message is not None and message.kind == Kind.GOODBYE:
                goodbye = message
                break
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.SHUTDOWN
    finally:
        client.close()
    assert server.wait(DEADLINE_S) == 130
    interrupted = json.loads(rest(server, "the server's counters").strip().splitlines()[-1])  # the counters, also on Ctrl-C
    assert interrupted["interrupted"] and interrupted["gateway"]["players_joined"] == 1
    assert interrupted["gateway"]["goodbyes_at_end"] == 1 and interrupted["gateway"]["end"] == "shutdown"
    assert _await_gone(workers) == []
    assert not shm.leftover_segments(hello["run_id"])


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_serve_in_the_background_stops_cleanly_on_sigint_and_sigterm(served, zctx, signum, code):
    # Started as a shell starts a background job (SIGINT ignored): either signal stops it, every
    # client is told goodbye shutdown, the summary is printed, nothing is left behind.
    server = subprocess.Popen([sys.executable, "-m", "processes.cli", "serve", "--players", "0", "--ticks", "600000",
                               "--json"], cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, start_new_session=True,
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    watcher = Client(hello["listening"], "spectator", "sp", zctx=zctx)
    try:
        watcher.join(DEADLINE_S)
        workers = _descendants(server.pid)
        os.kill(server.pid, signum)
        goodbye, _ = _until_goodbye(watcher)
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.SHUTDOWN
    finally:
        watcher.close()
    assert server.wait(DEADLINE_S) == code
    summary = json.loads(rest(server, "the server's summary").strip().splitlines()[-1])
    assert summary["interrupted"] and summary["signal"] == signal.Signals(signum).name
    assert summary["gateway"]["goodbyes_at_end"] == 1 and summary["gateway"]["end"] == "shutdown"
    assert _await_gone(workers) == []
    assert not shm.leftover_segments(hello["run_id"])


def test_serve_tells_how_to_join_what_it_serves():
    from processes.cli.serve import _serving_line

    assert "--as player" not in _serving_line("match", "tcp://127.0.0.1:1", 0)  # nobody to play: watch
    assert "--as spectator" in _serving_line("match", "tcp://127.0.0.1:1", 0)
    assert "--as player" in _serving_line("match", "tcp://127.0.0.1:1", 1)


def _ticks_seen(client, count):
    """The ticks of the next `count` snapshots `client` gets (heartbeating; within the deadline)."""
    ticks, deadline = [], Deadline()
    while not deadline.expired():
        client.heartbeat_if_due()
        message = client.recv(100)
        if message is not None and message.kind == Kind.SNAPSHOT:
            ticks.append(message.tick)
            if len(ticks) == count:
                return ticks
    raise AssertionError(f"{len(ticks)} snapshots of {count} within {DEADLINE_S:.0f} s")


def test_a_served_match_waits_for_its_player_and_pauses_while_the_seat_is_in_its_grace(served, zctx):
    server = _pingpong("serve", "--players", "1", "--ticks", "600000", "--timeout", "1", "--grace", "60", "--json")
    served.append(server)
    endpoint = json.loads(line(server, "the server's listening line"))["listening"]
    watcher = Client(endpoint, "spectator", "sp", zctx=zctx)
    player = Client(endpoint, "player", "ann", zctx=zctx)
    try:
        watcher.join(DEADLINE_S)
        assert set(_ticks_seen(watcher, 30)) == {0}  # nobody on seat A: no serve, the clock stands
        token = player.join(DEADLINE_S)["token"]
        deadline = Deadline()
        while not deadline.expired():  # the match starts: the ticks move
            player.heartbeat_if_due()
            player.recv(0)
            if _ticks_seen(watcher, 1)[0] > 0:
                break
        else:
            raise AssertionError("the match never started")
        # the player falls silent: dropped after the 1 s timeout, its seat in its grace, the match paused
        deadline = Deadline()
        while not deadline.expired():
            window = _ticks_seen(watcher, 30)
            if len(set(window)) == 1:
                break
        else:
            raise AssertionError("the match never paused")
        paused_at = window[0]
        assert paused_at > 0
        player.token = token
        player.hello()  # back with the token: the match goes on from where it stood
        deadline = Deadline()
        while not deadline.expired():
            message = player.recv(100)
            if message is not None and player.accept(message):
                break
        else:
            raise AssertionError("no welcome back")
        deadline = Deadline()
        while not deadline.expired():
            player.heartbeat_if_due()
            player.recv(0)
            tick = _ticks_seen(watcher, 1)[0]
            if tick > paused_at:
                break
        assert tick > paused_at
    finally:
        watcher.close()
        player.close()


def test_a_remote_bat_needs_the_effect_and_no_skill():
    data = tomllib.loads((ROOT / "scenes" / "match_rigid.toml").read_text())
    data["bats"]["a"]["remote"] = True
    with pytest.raises(SceneError, match="either by the AI"):
        parse_scene(data, "t.toml")
    del data["bats"]["a"]["skill"]
    with pytest.raises(SceneError, match="needs the effect 'remote'"):
        parse_scene(data, "t.toml")
    data["effects"].append("remote")
    scene = parse_scene(data, "t.toml")
    assert scene.bats[0].remote and workers_for(scene) == ["physics", "ai", "gateway"]


def test_a_killed_gateway_is_restarted_on_the_same_endpoint_and_the_token_reclaims_the_seat(served, zctx):
    server = _pingpong("serve", "--players", "1", "--ticks", "6000", "--crash-gateway-at-tick", "500", "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    player = Client(hello["listening"], "player", "ann", zctx=zctx)
    thief = Client(hello["listening"], "player", "eve", Slot.A, zctx=zctx)
    try:
        first = player.join(DEADLINE_S)
        assert first["slot"] == Slot.A
        # Snapshots until the gateway dies at tick 500; the restarted one on the same endpoint
        # has no session for our heartbeats and says goodbye unknown_session, on which the
        # client says hello again with its token (Client.recv, as the document tells a client):
        # its welcome ends the wait.
        ticks, welcome, deadline = [], None, Deadline()
        while not deadline.expired():
            player.heartbeat_if_due()
            message = player.recv(100)
            if message is not None and message.kind == Kind.SNAPSHOT:
                ticks.append(message.tick)
            elif message is not None and message.kind == Kind.WELCOME:
                welcome = message
                break
        assert ticks and max(ticks) < 6000 and player.rejoins == 1
        # the seat table outlived the gateway: the token is still good and gives the same seat
        assert welcome is not None and welcome.tick > 500
        assert welcome["slot"] == Slot.A and welcome["token"] == first["token"] and welcome["name_a"] == "ann"
        with pytest.raises(Rejected) as refused:  # and nobody else may take it
            thief.join(DEADLINE_S)
        assert refused.value.reason == RejectReason.FULL
        goodbye, deadline = None, Deadline()
        while not deadline.expired():
            player.heartbeat_if_due()
            message = player.recv(100)
            if message is not None and message.kind == Kind.GOODBYE:
                goodbye = message
                break
        assert goodbye is not None and goodbye["reason"] == GoodbyeReason.MATCH_OVER
    finally:
        player.close()
        thief.close()
    summary = json.loads(line(server, "the server's summary"))
    assert server.wait(DEADLINE_S) == 0
    assert summary["workers"]["gateway"]["restarts"] == 1 and summary["ticks"] == 6000
    assert summary["gateway"]["seats_restored"] == 1 and summary["gateway"]["rejoined"] == 1
    assert not shm.leftover_segments(hello["run_id"])


def _until_goodbye(client):
    """Heartbeat and read until the server's goodbye (None if it never came within the deadline); the snapshot ticks seen."""
    ticks, deadline = [], Deadline()
    while not deadline.expired():
        client.heartbeat_if_due()
        message = client.recv(100)
        if message is not None and message.kind == Kind.GOODBYE:
            return message, ticks
        if message is not None and message.kind == Kind.SNAPSHOT:
            ticks.append(message.tick)
    return None, ticks


@pytest.mark.parametrize("budget", [3, 0])
def test_a_worker_that_raises_is_restarted_and_past_the_budget_clients_are_told_server_error(served, zctx, budget):
    # The physics raises at tick 300 (the match starts when the player is seated, so it is there):
    # within the budget it is restarted and the match goes on to its end; past it, the run ends
    # and the player is told why: server_error, not shutdown.
    server = _pingpong("serve", "--players", "1", "--ticks", "1500", "--fault", "physics:raise:300",
                       "--restart-budget", str(budget), "--json")
    served.append(server)
    hello = json.loads(line(server, "the server's listening line"))
    player = Client(hello["listening"], "player", "ann", zctx=zctx)
    try:
        assert player.join(DEADLINE_S)["slot"] == Slot.A
        goodbye, ticks = _until_goodbye(player)
    finally:
        player.close()
    assert goodbye is not None, f"no goodbye; last snapshot ticks {ticks[-5:]}"
    if budget:
        assert goodbye["reason"] == GoodbyeReason.MATCH_OVER and max(ticks) == 1500
        summary = json.loads(line(server, "the server's summary"))
        assert server.wait(DEADLINE_S) == 0
        assert summary["workers"]["physics"]["raised"] == 1 and summary["workers"]["physics"]["restarts"] == 1
    else:
        assert goodbye["reason"] == GoodbyeReason.SERVER_ERROR and max(ticks) <= 300
        failed = json.loads(line(server, "the server's failure line"))
        assert server.wait(DEADLINE_S) == 1
        assert "physics worker raised InjectedFault" in failed["failed"] and "restart budget" in failed["failed"]
        assert "Traceback" in server.stderr.read()  # logged with its traceback
    assert not shm.leftover_segments(hello["run_id"])


# --- acknowledged input seqs: a snapshot names exactly the inputs it shows --------------------
def test_a_snapshot_acknowledges_the_inputs_applied_before_its_tick_not_the_next_ones(tmp_path, no_leftovers):
    """The physics applies an input after publishing tick T (for the step T -> T+1); a gateway
    reading tick T's snapshot right then must still say the previous seq (the bug this replaced:
    it read the live 'applied' seqs, one tick ahead of the snapshot)."""
    from engine.match import Match
    from processes.workers.gateway import _consistent_snapshot
    from processes.workers.layout import (REMOTE_ACK_DTYPE, REMOTE_ACK_RING, REMOTE_CAPACITY, REMOTE_INPUT_DTYPE,
                                          RUN_LOCK_NAMES, read_ack, write_ack)
    from processes.runtime.locks import HOLDER_DTYPE, LockTable
    from processes.runtime.mailbox import MAILBOX_HEADER, Mailbox
    from processes.workers.hub import RemoteInputs
    from processes.workers.options import RunOptions

    scene = with_remote_players(load_scene("match_rigid"), 2)
    arena = shm.Arena()
    try:
        snapshots = arena.snapshot_block("physics", physics_snapshot_dtype(2), 1)
        lock_path = str(tmp_path / "locks")
        LockTable.create(lock_path, RUN_LOCK_NAMES, arena.shared_array("lock_holders", HOLDER_DTYPE,
                                                                       len(RUN_LOCK_NAMES))).close()
        arena.shared_array("remote_header", MAILBOX_HEADER, 1)
        arena.shared_array("remote_inputs", REMOTE_INPUT_DTYPE, REMOTE_CAPACITY)
        applied = arena.shared_array("remote_applied", np.dtype("<u8"), 2).array
        acks = arena.shared_array("remote_acks", REMOTE_ACK_DTYPE, REMOTE_ACK_RING).array
        match = Match(scene, 0)
        physics = RemoteInputs(arena, RunOptions(ticks=0, lock_path=lock_path, gateway=GatewayConfig()), match)
        gateway_locks = LockTable(lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
        box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], gateway_locks)
        post = np.zeros((), REMOTE_INPUT_DTYPE)
        record = np.zeros(1, physics_snapshot_dtype(2))

        def send(seq, force_x):
            post["seq"], post["bat"], post["inputs"] = seq, 0, (force_x, 0, 0, 0, 0, 0)
            assert box.post(post)

        def physics_tick(tick):  # the worker's order: apply, step (the tick advances), ack, publish
            physics.apply(tick - 1)
            match.state.world[0]["tick"] = tick
            physics.publish_ack(tick)
            snapshots.publish(match.state.record, tick)

        send(4, 1.0)
        physics_tick(1)
        send(5, 2.0)
        physics.apply(1)  # the next tick's input is applied right after tick 1 was published ...
        assert int(applied[0]) == 5  # ... which the live seqs already show
        rec, ack = _consistent_snapshot(snapshots, acks, record)
        assert int(rec["world"]["tick"]) == 1 and ack == (4, 0)
        assert float(rec["bats"]["force"][0][0]) == 1.0  # the snapshot holds seq 4's force, as acknowledged
        match.state.world[0]["tick"] = 2
        physics.publish_ack(2)
        snapshots.publish(match.state.record, 2)
        rec, ack = _consistent_snapshot(snapshots, acks, record)
        assert int(rec["world"]["tick"]) == 2 and ack == (5, 0) and float(rec["bats"]["force"][0][0]) == 2.0
        write_ack(acks, 2 + REMOTE_ACK_RING, (6, 0))  # a ring later the entry of tick 2 is gone
        assert read_ack(acks, 2) is None and read_ack(acks, 2 + REMOTE_ACK_RING) == (6, 0)
        physics.close()
        gateway_locks.close()
        del applied, acks, box, match, physics
    finally:
        arena.close()


# --- CURVE ------------------------------------------------------------------------------------
def _unanswered(r, client, rounds=40):
    """True if the client hears nothing while the gateway is pumped `rounds` times (bounded)."""
    client.hello()
    for _ in range(rounds):
        r.step(serve=True)
        if client.recv(10) is not None:
            return False
    return True


def test_a_curve_session_works_and_a_client_without_the_server_key_cannot_join(rig, zctx, tmp_path):
    import zmq.auth

    from processes.cli import main
    from processes.network.client.client import curve_client_options, load_curve_key

    assert main(["keys", str(tmp_path / "keys"), "--json"]) == 0  # `pingpong keys DIR`
    public_file, secret_file = tmp_path / "keys" / "server.key", tmp_path / "keys" / "server.key_secret"
    public, secret = load_curve_key(str(secret_file), secret=True)
    r = rig(curve_secret_key=secret, curve_public_key=public)
    good = r.client(name="ann", socket_options=curve_client_options(str(public_file)))
    assert r.join(good)["slot"] == Slot.A
    snapshot = r.until(good, lambda m: m.kind == Kind.SNAPSHOT, serve=True)
    assert snapshot["winner"] == -1
    (tmp_path / "other").mkdir()
    other_public, _ = zmq.auth.create_certificates(str(tmp_path / "other"), "server")
    wrong = r.client(name="eve", socket_options=curve_client_options(other_public))
    assert _unanswered(r, wrong)  # its handshake fails: no message either way
    plain = r.client(name="bob")  # no CURVE at all
    assert _unanswered(r, plain)
    assert len(r.gateway.sessions) == 1
    assert r.gateway.stats()["players_joined"] == 1
    # the feed is a CURVE server too: a spectator with the key watches there, a SUB without it gets nothing
    watcher = r.client(role="spectator", name="sam", socket_options=curve_client_options(str(public_file)))
    assert r.join(watcher)["feed_port"] == r.gateway.feed_port > 0
    snapshot = r.until(watcher, lambda m: m.kind == Kind.SNAPSHOT, serve=True)
    assert watcher.feed_seq == snapshot.seq > 0  # it came on the feed
    eavesdropper = zctx.socket(zmq.SUB)
    eavesdropper.setsockopt(zmq.SUBSCRIBE, b"")
    eavesdropper.connect(r.gateway.feed_endpoint)
    for _ in range(40):
        r.step(serve=True)
        assert not eavesdropper.poll(10, zmq.POLLIN)
    assert r.until(watcher, lambda m: m.kind == Kind.SNAPSHOT, serve=True).seq > snapshot.seq  # still served
    with pytest.raises(ValueError, match="no secret key"):
        load_curve_key(str(public_file), secret=True)
    with pytest.raises(ValueError, match="not a ZeroMQ certificate"):
        load_curve_key(str(tmp_path / "missing.key"), secret=False)


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
