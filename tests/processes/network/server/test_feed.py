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

from engine.scene import load_scene
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
    """In-process: a Gateway with a 4 x 2 net (one message a state) and 100 Hz snapshots, so a
    net message at most every 1 / 60 s; the knots of the first state come to a spectator who
    joins after it, on its session, right after its welcome."""
    rig = rig(snapshot_hz=100)
    gateway = rig.gateway
    gateway.net = NetFeed((4, 2, 1.0, 0.2), gateway.config.snapshot_hz)
    knots = wire.net_rest(4, 2, 1.0, 0.2)
    knots[5, 0] = 0.01
    assert gateway.net_due()
    gateway.service_net(10, False, knots)
    assert gateway.counts["nets_published"] == 1 and not gateway.net_due()  # the next one in 1 / 60 s
    gateway.service_net(10, False, knots)  # the same state again: nothing
    rig.clock.now += 1.0 / 60.0
    gateway.service_net(20, True, knots)  # it fell asleep: once
    rig.clock.now += 1.0 / 60.0
    gateway.service_net(30, True, knots)  # asleep still: nothing more
    assert gateway.counts["nets_published"] == 2
    spectator = rig.client("spectator")
    rig.join(spectator)
    message = rig.until(spectator, lambda m: m.kind == Kind.NET)
    assert message.tick == 20 and message["asleep"] == 1
    got = np.zeros_like(knots)
    wire.net_knots(message, got)
    np.testing.assert_allclose(got, knots, rtol=0, atol=wire.NET_STEP_M / 2 + 1e-12)  # rounding to a step
