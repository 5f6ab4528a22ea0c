"""Client prediction and reconciliation against an in-process server world (processes.network.client.prediction)."""
import math
from dataclasses import replace

import numpy as np
import pytest

from engine.physics.scene import load_scene
from engine.physics.world import build_model, initial_state, new_events, step
from processes.network import wire
from processes.network.client.prediction import MAX_AHEAD_TICKS, ErrorStats, Predictor, ServerClock
from processes.network.wire import Slot

SNAPSHOT_EVERY = 10  # ticks between snapshots: 100 Hz at the match scene's 1 ms tick


def _scene():
    """The match scene with the ball struck towards B: it bounces on B's court within 0.3 s."""
    scene = load_scene("match_rigid")
    return replace(scene, ball=replace(scene.ball, pos=(-1.2, 0.0, 0.25), vel=(6.0, 0.3, 0.5), spin=(0.0, 40.0, 0.0)))


class Server:
    """The authoritative world: applies each input at a tick of its own choosing."""

    def __init__(self, scene):
        self.model = build_model(scene)
        self.state = initial_state(scene)
        self.events = new_events()
        self.acked = 0
        self.seq = 0

    @property
    def tick(self):
        return int(self.state.world[0]["tick"])

    def apply(self, seq, inputs, player=0):
        self.state.bats[player]["force"], self.state.bats[player]["torque"] = inputs[0:3], inputs[3:6]
        self.acked = seq

    def step(self):
        step(self.model, self.state, None, self.events)

    def snapshot(self):
        self.seq += 1
        return wire.decode(wire.snapshot_from_physics(self.state.record[0], seq=self.seq, input_seq=(self.acked, 0)))


def _force(k):
    """A varied input: force (N) and torque (N m), like an arm's."""
    return np.array([40.0 * math.sin(0.3 * k), 25.0 * math.cos(0.2 * k), 10.0, 0.0, 0.2 * math.sin(0.1 * k), 0.0])


def _play(delay_ticks, lead=5, ticks=300):
    """A client `lead` ticks ahead of the server sends an input every 4 ticks stamped with its
    present tick; the server applies each at its stamp plus delay_ticks; a snapshot every 10
    ticks reaches the client when its present is `lead` ticks past it."""
    scene = _scene()
    server = Server(scene)
    client = Predictor(scene, Slot.A)
    client.reconcile(server.snapshot())
    queue = []  # (apply at tick, seq, inputs)
    seq = 0
    for present in range(lead, ticks + lead):
        client.advance_to(present)
        if present % 4 == 0:
            seq += 1
            inputs = _force(seq)
            client.record_input(seq, present, inputs)
            queue.append((present + delay_ticks, seq, inputs))
        while server.tick < present - lead + 1:
            for item in [q for q in queue if q[0] <= server.tick]:
                server.apply(item[1], item[2])
                queue.remove(item)
            server.step()
            if server.tick % SNAPSHOT_EVERY == 0:
                snapshot = server.snapshot()
                assert client.tick >= snapshot.tick  # the snapshot is from the client's past
                client.reconcile(snapshot)
                # the rewind is exact: after the replay, the prediction for the snapshot's tick is it
                row = client._hist[snapshot.tick % len(client._hist)]
                assert np.array_equal(row[0:3], snapshot["ball_pos"]) and np.array_equal(row[3:6], snapshot["bat_pos"][0])
    return client


def test_inputs_applied_at_their_stamps_are_predicted_exactly():
    client = _play(delay_ticks=0)
    stats = client.stats()
    assert stats["scored"] >= 25 and stats["tosses"] == 0 and stats["engine_errors"] == 0
    # the same kernel, the same inputs at the same ticks, an opponent bat with no force on either
    # side: the prediction equals the authority bit for bit (tolerance 0, not a float tolerance)
    assert stats["ball"]["max_mm"] == 0.0 and stats["bat"]["max_mm"] == 0.0
    assert stats["replayed_ticks"] > 0 and client.pending <= 2  # only inputs after the last ack stay


def test_inputs_applied_late_show_as_bat_error_and_reconcile_back():
    client = _play(delay_ticks=2)
    stats = client.stats()
    assert stats["scored"] >= 25
    # each input held 2 ticks too early: |force| ~ 48 N on the 0.17 kg bat for 2 ms gives
    # ~0.5 m/s of velocity error, a few mm of position over a snapshot interval; the replay
    # from every snapshot keeps it from growing (bounded by 10 mm over the whole run)
    assert 0.0 < stats["bat"]["p50_mm"] < 10.0 and stats["bat"]["max_mm"] < 10.0
    assert stats["ball"]["max_mm"] < stats["bat"]["max_mm"]  # the ball meets no bat in this flight


def test_a_snapshot_older_than_the_base_is_ignored_and_a_toss_is_not_scored():
    scene = _scene()
    server = Server(scene)
    client = Predictor(scene, Slot.A)
    first = server.snapshot()
    assert client.reconcile(first) is None  # nothing predicted yet
    for _ in range(SNAPSHOT_EVERY):
        server.step()
    client.advance_to(server.tick)
    second = server.snapshot()
    assert client.reconcile(second) == (0.0, 0.0)
    assert client.reconcile(first) is None and client.counts["late"] == 1
    server.state.record[0]["rally"]["rally"] = 1  # the server tossed the ball for a new rally
    server.state.ball[0]["pos"] = (1.47, 0.0, 0.12)
    for _ in range(SNAPSHOT_EVERY):
        server.step()
    client.advance_to(server.tick)
    assert client.reconcile(server.snapshot()) is None and client.counts["tosses"] == 1
    client.advance_to(server.tick + 10 * MAX_AHEAD_TICKS)  # a silent server: the prediction stops
    assert client.tick == server.tick + MAX_AHEAD_TICKS
    with pytest.raises(ValueError, match="slot must be A or B"):
        Predictor(scene, Slot.NONE)


def test_error_stats_summary_in_millimetres():
    stats = ErrorStats()
    assert stats.summary()["n"] == 0 and stats.summary()["max_mm"] is None
    for metres in (0.001, 0.002, 0.003, 0.010):
        stats.add(metres)
    summary = stats.summary()
    assert summary["n"] == 4 and summary["max_mm"] == pytest.approx(10.0, abs=1e-12)
    assert summary["mean_mm"] == pytest.approx(4.0, abs=1e-12) and summary["p50_mm"] == pytest.approx(2.5, abs=1e-12)


# --- the server's clock, the baseline, the round trip ----------------------------------------
DT = 0.001


def test_the_server_clock_follows_the_least_delayed_snapshot():
    clock = ServerClock(DT)
    assert clock.tick_at(1.0) is None
    clock.observe(100, arrival=0.150)  # 50 ms late
    clock.observe(110, arrival=0.112)  # 2 ms late
    assert clock.tick_at(0.2) == pytest.approx(198.0, abs=1e-9)


def test_the_baseline_without_prediction_is_measured_alongside():
    client = _play(delay_ticks=2)
    stats = client.stats()
    stale = stats["without_prediction"]
    assert stale["ball"]["n"] == stats["ball"]["n"] == stats["scored"]
    # showing the previous snapshot lags the ball by 10 ms of a ~6 m/s flight: ~60 mm, against
    # the prediction's 0 (no bat in its way); the bat under ~48 N moves mm per snapshot interval
    assert stale["ball"]["p50_mm"] > 30.0 and stats["ball"]["max_mm"] < 1e-3
    assert stale["bat"]["mean_mm"] > stats["bat"]["mean_mm"]


def test_the_round_trip_is_the_least_time_from_an_input_to_its_first_acknowledgement():
    from processes.network.client.prediction import RoundTrip

    trip = RoundTrip(window=4)
    assert trip.seconds == 0.0
    for seq, sent, acked in ((1, 0.000, 0.009), (2, 0.010, 0.013), (3, 0.020, 0.027)):
        trip.sent(seq, sent)
        trip.acked(seq, acked)
    trip.acked(3, 0.050)  # acknowledged again by a later snapshot: no new sample
    trip.sent(4, 0.030)
    trip.sent(5, 0.031)
    trip.acked(5, 0.040)  # 4 and 5 acknowledged together: the sample is 5's (9 ms), not 4's (10 ms)
    assert trip.summary()["n"] == 4 and trip.seconds == pytest.approx(0.003, abs=1e-12)


def test_a_rejoined_client_ignores_the_previous_sessions_acknowledgement():
    scene = _scene()
    server = Server(scene)
    client = Predictor(scene, Slot.A)
    server.acked = 5000  # the seat's previous session got that far before we rejoined
    client.reconcile(server.snapshot())
    client.record_input(1, 0, _force(1))  # our first input, seq 1 of our new session
    for _ in range(SNAPSHOT_EVERY):
        server.step()
    client.advance_to(server.tick)
    client.reconcile(server.snapshot())  # still acknowledges 5000: not ours, our input stays pending
    assert client.pending == 1
