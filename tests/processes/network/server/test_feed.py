"""The cloth net on the wire in a served match: a spectator's net messages carry the net worker's
knots, within the wire's quantisation step, while the net is awake and once when it sleeps.

A served default match (`pingpong serve`) with one remote seat: the physics does not step before
the seat is held, so the spectator joins first and sees the net from its first tick: it starts
in its hanging rest shape, awake until its sleep test passes, far from the ball. Until the ball comes near it the
net steps only its free ticks (NetSim.step_free), bit for bit as the in-process NetSim does
(tests/processes/workers/test_net_worker.py), which is the reference here.
"""
import json
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.physics.scene import load_scene
from net_kernel import NetSim, build_topology
from processes.network import wire
from processes.network.client.client import Client
from processes.network.server.feed import NetFeed
from processes.network.wire import Kind
from tests.helpers.commands import pingpong
from tests.waits import DEADLINE_S, line

TICKS = 1500  # 1.5 s of realtime play: the net falls asleep within it


def _reference(spec, dt, ticks) -> dict[int, np.ndarray]:
    """{tick: knot_pos} of the net stepped free from its built shape, for each of `ticks`."""
    sim = NetSim(build_topology(spec), dt)
    out, tick = {}, 0
    for wanted in sorted(ticks):
        sim.step_free(wanted - tick)
        tick = wanted
        out[wanted] = sim.knot_pos.copy()
    return out


def test_a_spectator_gets_the_net_workers_knots_while_the_net_is_awake_and_once_asleep(served):
    server = pingpong("serve", "--players", "1", "--ticks", str(TICKS), "--json")
    served.append(server)
    endpoint = json.loads(line(server, "the server's listening line"))["listening"]
    spectator = Client(endpoint, "spectator", "net-watcher")
    player = Client(endpoint, "player", "idle")
    nets = []  # (tick, asleep, first, knots of the message)
    try:
        spectator.join(DEADLINE_S)
        player.join(DEADLINE_S)  # the match starts: the net's first tick
        deadline = time.monotonic() + DEADLINE_S
        while spectator.goodbye is None and not spectator.server_lost and time.monotonic() < deadline:
            player.heartbeat_if_due()
            player.recv_batch(0)
            spectator.heartbeat_if_due()
            message = spectator.recv(20)
            if message is not None and message.kind == Kind.NET:
                knots = np.full((message["cols"] * message["rows"], 3), np.nan)
                wire.net_knots(message, knots)
                first, count = message["first"], message["count"]
                nets.append((message.tick, message["asleep"], first, knots[first:first + count]))
    finally:
        spectator.close()
        player.close()
    assert spectator.goodbye == wire.GoodbyeReason.MATCH_OVER
    scene = load_scene("match")
    spec = scene.cloth
    chunks = -(-spec.cols * spec.rows // wire.NET_CHUNK_KNOTS)
    awake = [n for n in nets if not n[1]]
    asleep = [n for n in nets if n[1]]
    # the net starts in its hanging rest shape (net_kernel.topology.hanging_shape), awake until
    # its sleep test passes: at least that first state comes while it is awake
    assert len({tick for tick, *_ in awake}) >= 1
    assert len(asleep) == chunks  # one state when it fell asleep, nothing more while it sleeps
    fell_asleep = asleep[0][0]
    assert all(tick < fell_asleep for tick, *_ in awake)
    reference = _reference(spec, scene.dt, {tick for tick, *_ in nets})
    for tick, _, first, knots in nets:
        expected = reference[tick][first:first + len(knots)]
        # round to the nearest 0.01 mm step: half a step, plus float64 rounding
        np.testing.assert_allclose(knots, expected, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)


def test_the_gateway_sends_a_moving_net_at_its_rate_a_sleeping_one_once_and_the_latest_to_a_newcomer(rig):
    """In-process: a Gateway with a 4 x 2 net (one message a state), 100 Hz snapshots and 1 ms
    ticks: a net state is due after a snapshot, on a grid of 17 ticks (1 / 60 s of match time),
    whatever the wall clock does; the knots of the last state come to a spectator who joins
    after it, on its session, right after its welcome."""
    rig = rig(snapshot_hz=100)
    gateway = rig.gateway
    gateway.net = NetFeed((4, 2, 1.0, 0.2), gateway.config.snapshot_hz, 0.001)
    knots = wire.net_rest(4, 2, 1.0, 0.2)
    knots[5, 0] = 0.01
    assert not gateway.net_due()  # nothing before a snapshot
    snapshot_ticks = []

    def snapshot(tick):
        rig.record["world"]["tick"] = tick
        gateway.broadcast_snapshot(rig.record)
        snapshot_ticks.append(tick)

    snapshot(10)
    assert gateway.net_due()
    gateway.service_net(10, False, knots)
    assert gateway.counts["nets_published"] == 1 and not gateway.net_due()
    snapshot(16)  # the grid of 17 ticks: the next one is due from tick 17
    assert not gateway.net_due()
    rig.clock.now += 10.0  # the wall clock says nothing: a slow match's net waits for its ticks
    snapshot(16)  # a paused match: its standing tick again
    assert not gateway.net_due()
    snapshot(27)
    assert gateway.net_due()
    gateway.service_net(27, True, knots)  # it fell asleep: once
    snapshot(34)
    gateway.service_net(34, True, knots)  # asleep still: nothing more
    assert gateway.counts["nets_published"] == 2 <= len(snapshot_ticks)
    spectator = rig.client("spectator")
    rig.join(spectator)
    message = rig.until(spectator, lambda m: m.kind == Kind.NET)
    assert message.tick == 27 and message["asleep"] == 1
    got = np.zeros_like(knots)
    wire.net_knots(message, got)
    np.testing.assert_allclose(got, knots, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # rounding to a step


@settings(deadline=None, max_examples=300)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=200), st.sampled_from([1, 4, 17]))
def test_net_states_are_due_at_most_once_a_snapshot_and_once_a_period_of_ticks(steps, every):
    # ticks as snapshots bring them: forward by 0..40 ticks (0: a standing clock), and once in
    # a while back to 0 (a restarted physics starts again from its last snapshot, earlier)
    feed = NetFeed((4, 2, 1.0, 0.2), 60, 1.0 / 60 / every)
    assert feed.every_ticks == every
    tick, due = 0, []
    for i, step in enumerate(steps):
        tick = 0 if step == 40 else tick + step
        feed.snapshot_sent(tick)
        if feed.due():
            due.append(tick)
            feed.update(tick, False, wire.net_rest(4, 2, 1.0, 0.2))
    assert len(due) <= len(steps)  # never more than the snapshots
    runs, run = [], []  # the due ticks between two times the clock went back
    for tick in due:
        if run and tick <= run[-1]:
            assert tick < run[-1] - every or tick == 0  # a state again only after the clock went back
            runs.append(run)
            run = []
        run.append(tick)
    runs.append(run)
    for run in runs:  # on a grid of `every` ticks: one per cell the run's span touches, at most
        assert len(run) <= (run[-1] - run[0]) // every + 2
