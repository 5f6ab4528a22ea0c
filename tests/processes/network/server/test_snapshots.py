"""The gateway's snapshots and events: on the match clock, numbered by rally, and what a slow spectator loses.

A Gateway in this process (the rig fixture) serving records the test writes; every wait bounded.
"""
import time

import numpy as np
import zmq

from engine.physics.scene import load_scene
from processes.network import wire
from processes.network.server.config import GatewayConfig
from processes.network.server.gateway import Gateway
from processes.network.server.pacing import RATE_WINDOW_S
from processes.network.wire import Kind, Slot
from tests.waits import DEADLINE_S, Deadline


def test_snapshots_follow_the_match_clock_and_say_how_fast_it_runs(rig):
    # 100 Hz and 1 ms ticks: one snapshot every 10 ticks of match time. The match runs at half
    # the wall clock's speed, then at its speed, then stands: the snapshots come every 10 ticks
    # (so at 50 Hz, then 100 Hz), then repeat the same tick at 100 Hz, and realtime_factor says
    # 0.5, 1, 0. Tolerance 0.002: a tick of 500 in the 1 s window the factor is measured over.
    # On a loaded machine the ZeroMQ I/O thread may fall behind and the player's pipe reach its
    # high-water mark: the gateway then drops a snapshot and counts it, so a gap is a multiple
    # of 10 ticks and the received ones plus the counted drops make the rate. A snapshot is
    # judged by when the gateway made it (its seq names the millisecond that sent it), not by
    # its place among the received ones, which drops shift.
    r = rig(remote=(Slot.A,), snapshot_hz=100, timeout_s=60.0)
    player = r.client()
    r.join(player)
    assert r.gateway.pacer.ticks == 10
    session, = r.gateway.sessions.values()
    world = r.record["world"]
    phases = {"half": [], "full": [], "stand": []}
    made_ms = {}  # the seq of each message the gateway sent the player -> the ms of its phase
    dropped = {}
    tick = 0

    def read(phase, wait_ms):
        while (message := player.recv(wait_ms)) is not None:
            if message.kind == Kind.SNAPSHOT:
                phases[phase].append((message.tick, float(message["realtime_factor"]), made_ms[message.seq]))
                return True
        return False

    for phase, ms, advance in (("half", 3000, 0.5), ("full", 2000, 1.0), ("stand", 2000, 0.0)):
        start, dropped_before = tick, r.gateway.counts["snapshots_dropped"]
        for k in range(1, ms + 1):
            r.clock.now += 0.001
            tick = start + int(k * advance)
            world["tick"], world["time"] = tick, tick * 0.001
            r.gateway.poll(0)
            seq_before = session.seq_out
            r.gateway.service(r.record)
            made_ms.update((seq, k) for seq in range(seq_before + 1, session.seq_out + 1))
            while read(phase, 0):
                pass
        # every snapshot sent in this phase counts for it, also one still in the socket
        sent = r.gateway.counts["snapshots_sent"]
        deadline = Deadline()
        while sum(map(len, phases.values())) < sent and not deadline.expired():
            read(phase, 100)
        dropped[phase] = r.gateway.counts["snapshots_dropped"] - dropped_before
    for phase, expected_hz, factor in (("half", 50, 0.5), ("full", 100, 1.0), ("stand", 100, 0.0)):
        ticks = [t for t, _, _ in phases[phase]]
        steps = set(np.diff(ticks[1:]))
        if phase == "stand":
            assert steps == {0}, (phase, sorted(steps))
        else:
            assert all(step > 0 and step % 10 == 0 for step in steps), (phase, sorted(steps))
        seconds = {"half": 3, "full": 2, "stand": 2}[phase]
        offered = len(ticks) + dropped[phase]  # received plus dropped: the snapshots the gateway made
        assert abs(offered - expected_hz * seconds) <= 2, (phase, len(ticks), dropped[phase])
        late = [f for _, f, ms in phases[phase] if ms > 1000 * RATE_WINDOW_S]  # a full window in the phase
        assert late, (phase, len(ticks), dropped[phase])
        assert max(abs(f - factor) for f in late) <= 0.002, (phase, late[:3])


def test_the_rally_number_is_the_rally_in_play_and_an_event_carries_the_rally_it_decided(rig):
    # A whole best-of-1 match in process, served tick by tick as the gateway worker serves it:
    # the first rally is number 1 from its toss on, every point event carries the number the
    # snapshots carried while it was played, and the match event the last rally's.
    from engine.physics.dtypes import POINT_DTYPE
    from engine.play.match import Match, point_row

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
