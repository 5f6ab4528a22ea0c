"""The gateway worker: the network.server.gateway.Gateway fed by the run's shared memory.

It reads the physics snapshots and the point log, pairs each snapshot with the remote inputs it
acknowledges (remote_acks), and posts the remote players' inputs to the locked remote-input
mailbox that the physics drains before each tick. In a run with a net worker (a scene with a
cloth net: processes.workers.workers_for; build_layout then makes the net_show block) it also
reads the net as the net worker shows it (processes.workers.net.NetShow: the knots at a tick,
also in the net's linear tail), never torn (SnapshotBlock.snapshot) and only when a net message
is due, for the clients' view of the net (network.server.feed.NetFeed). It only reads: the
net's physics runs in the net worker alone.
"""
from __future__ import annotations

import time

import numpy as np
import zmq

from engine.physics.compiled import CompiledScene
from engine.physics.dtypes import physics_snapshot_dtype
from processes.network.server.config import GatewayConfig
from processes.network.server.gateway import STATS_EVERY_S, Gateway
from processes.network.server.seats import SeatStore
from processes.network.wire import GoodbyeReason, Slot
from processes.runtime.control import Control, StopRequested
from processes.runtime.locks import LockTable
from processes.runtime.mailbox import Mailbox
from processes.runtime.shm import Arena
from processes.workers.layout import NET_SHOW, REMOTE_INPUT_DTYPE, RUN_LOCK_NAMES, read_ack
from processes.workers.options import RunOptions


def _consistent_snapshot(snapshots, acks: np.ndarray, record: np.ndarray, tries: int = 3):
    """The latest physics snapshot and the input seqs acknowledged at its very tick (None after
    `tries` snapshots whose tick left the ring meanwhile)."""
    for _ in range(tries):
        snapshots.snapshot(record)
        rec = record[0]
        ack = read_ack(acks, int(rec["world"]["tick"]))
        if ack is not None:
            return rec, ack
    return record[0], None


def _read_net(block, out: np.ndarray) -> tuple[int, bool, np.ndarray] | None:
    """(tick, asleep, knot_pos) of the net as the net worker shows it (net_show), None before it did."""
    if block.version < 2:
        return None
    block.snapshot(out)
    row = out[0]
    return int(row["tick"]), bool(row["asleep"]), row["pos"]


def gateway_worker(control: Control, arena: Arena, compiled: CompiledScene, options: RunOptions) -> None:
    """Serve the run's match to network clients until the match ends or the supervisor stops it.

    options: gateway (GatewayConfig), handles.lock_path, ticks (the run's tick limit),
    handles.start_event (set while every remote seat is held, clear while one is empty: the
    physics worker waits for it before the first serve and pauses while it is clear), faults
    (tests: end this process once the physics reached the crash tick).

    A restarted gateway binds the same endpoint and has lost its sessions, not its seats: the
    seat table lives in the supervisor's "seats" block (SeatStore), so clients that hear nothing
    more hello again, a player with its token gets its seat back. Its feed binds a free port
    again (the supervisor passes on the session's endpoint only): the new welcome names it.
    The "ready" report names both endpoints; the counters go to GatewayConfig.stats_path every
    STATS_EVERY_S and at the end (the supervisor's "done" report carries them at a match's end
    only: a stopped worker's last message is never read).
    """
    config: GatewayConfig = options.gateway
    locks = LockTable(options.handles.lock_path, RUN_LOCK_NAMES, arena["lock_holders"])
    box = Mailbox("remote_inputs", arena["remote_header"], arena["remote_inputs"], locks)
    acks = arena["remote_acks"].array
    points = arena["points"].array
    snapshots = arena["physics"]
    scene = compiled.scene
    record = np.zeros(1, physics_snapshot_dtype(len(scene.bats)))
    post = np.zeros((), REMOTE_INPUT_DTYPE)

    def post_input(bat: int, seq: int, tick: int, inputs) -> bool:
        post["tick"], post["seq"], post["bat"], post["inputs"] = tick, seq, bat, inputs
        return box.post(post)

    remote = [Slot.of_bat(i) for i, bat in enumerate(scene.bats) if bat.remote]
    zctx = zmq.Context(io_threads=2)  # sessions and the feed's fan-out each on their own (Gateway)
    seat_store = SeatStore(arena["seats"]) if "seats" in arena.blocks else None
    shown = shown_net = net_grid = None
    if NET_SHOW in arena.blocks:  # the run has a net worker
        spec = scene.cloth
        net_grid = (spec.cols, spec.rows, spec.width, spec.height)
        shown = arena[NET_SHOW]
        shown_net = np.zeros(1, shown.dtype)
    gateway = Gateway(zctx, config, scene=compiled, remote_slots=remote, post_input=post_input, seat_store=seat_store,
                      net_grid=net_grid)
    start_event = options.handles.start_event
    n_ticks = options.ticks
    faults = options.faults
    reason = GoodbyeReason.SHUTDOWN
    try:
        control.start({"endpoint": gateway.endpoint, "feed": gateway.feed_endpoint})
        if shown is not None and (net := _read_net(shown, shown_net)) is not None:
            # The net as the net worker started (shown before it said it was ready, so before the
            # run started), before any session is served: every session, also one welcomed
            # before the loop's first look at the net, gets it after its welcome
            # (NetFeed.latest), where a feed message it subscribed too late for would be lost.
            gateway.service_net(*net)
        # Heartbeats and timeouts also from a thread of their own: the copies of the physics' and
        # the net's states below wait, outside the gateway's lock, for writers a busy machine may
        # deschedule mid-write.
        gateway.start_heartbeats()
        lock = gateway.lock
        poll_ms = max(1, int(500 / config.snapshot_hz))
        next_stats = 0.0
        while True:
            with lock:
                gateway.poll(poll_ms)
                if config.stats_path and time.monotonic() >= next_stats:
                    next_stats = time.monotonic() + STATS_EVERY_S
                    gateway.write_stats({"end": None, "tick": gateway.tick})
            rec, ack = _consistent_snapshot(snapshots, acks, record)
            if ack is None:
                with lock:
                    gateway.counts["snapshots_without_ack"] += 1  # the gateway fell a ring behind: skip one
                    gateway.service(None)
                continue
            with lock:
                gateway.service(rec, ack, points)
            if shown is not None and gateway.net_due() and (net := _read_net(shown, shown_net)) is not None:
                with lock:
                    gateway.service_net(*net)
            if start_event is not None and gateway.seats_filled != start_event.is_set():
                if gateway.seats_filled:
                    start_event.set()  # the physics plays
                elif config.pause_for_players:
                    start_event.clear()  # the physics pauses (and a restarted one waits)
            control.beat(gateway.tick)
            if faults is not None and faults.crashes_in(-1, gateway.tick + 1):  # the physics reached it
                faults.crash(gateway.tick)
            if int(rec["rally"]["winner"]) >= 0 or gateway.tick >= n_ticks:
                with lock:
                    gateway.broadcast_snapshot(rec, ack)  # the final state
                reason = GoodbyeReason.MATCH_OVER
                break
    except StopRequested as stop:
        # the run stops (shutdown), fails (server_error), or this gateway alone is replaced: then,
        # as after a crash, its sessions hear nothing and hello again to the new one
        reason = {"error": GoodbyeReason.SERVER_ERROR, "restart": None}.get(stop.reason, GoodbyeReason.SHUTDOWN)
        raise
    except BaseException:
        reason = None  # raised: restarted like a gateway that died (above)
        raise
    finally:
        told = gateway.shutdown(reason) if reason is not None else 0
        if reason is not None:
            gateway.drain()  # hellos meanwhile are told shutting_down
        stats = gateway.stats()
        stats["goodbyes_at_end"] = told
        gateway.write_stats({"goodbyes_at_end": told, "end": "restart" if reason is None else reason.name.lower(),
                             "tick": gateway.tick})
        if gateway.send_log is not None:
            gateway.send_log.save()
        gateway.close()
        zctx.term()
        del record, acks, points, snapshots, box, seat_store, shown
        locks.close()
        if reason == GoodbyeReason.MATCH_OVER:
            control.send("done", {"tick": gateway.tick, "gateway": stats})
