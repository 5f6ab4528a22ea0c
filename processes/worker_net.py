"""The net worker: the cloth net (net_kernel.NetSim) in a process of its own.

The physics worker gives it the baton for every tick the net must step or test (the net is
awake, or the ball is near its frozen shape; a sleeping net with the ball far away wakes nobody). The ball's state at
the tick's start crosses in the shared `net_io` record and the net's answer (time of impact,
impulse, offset, whether it now sleeps) comes back in it; the baton orders the two sides, so
the record needs no lock. The physics then applies the answer exactly as the in-process engine
applies NetSim.step's, which keeps lockstep runs bit for bit equal to the reference.

After every step the worker publishes its whole state (engine.dtypes.net_snapshot_dtype) into
one of two SnapshotBlocks, by the parity of the tick it holds, so the state before the last step
is always kept too. That makes restarts exact: a restarted net worker resumes from its newest
state; a restarted physics worker may ask again for the tick the net has just stepped, and the
net then goes back to the state before it (in the other block).
"""
from __future__ import annotations

import os
import signal
import time

import numpy as np

from engine.dtypes import net_snapshot_dtype
from net_kernel import NO_CONTACT, NetContact, NetSim, build_topology
from net_kernel.sim import ball_far_from_box, net_box
from processes.handoff import HandoffTimeout
from processes.shm import Arena
from processes.worker import GO_TIMEOUT_S, Control, WorkerState

NET_IO_DTYPE = np.dtype([
    ("tick", "<i8"),  # the tick to step (the physics' tick at its start)
    ("ball", "<f8", (2, 3)),  # position m, velocity m/s at the tick's start
    ("radius", "<f8"), ("inv_mass", "<f8"),  # m, 1/kg
    ("toi", "<f8"), ("impulse", "<f8", 3), ("offset", "<f8", 3),  # NetSim.step's answer
    ("sleeping", "<i8"),  # the net sleeps after this step
    ("box", "<f8", (2, 3)),  # m, lo and hi corners of the knots' box after this step (NetSim.box)
])
NET_BLOCKS = ("net_even", "net_odd")  # by the parity of the tick a state holds
NET_HANDOFF_S = 1.0  # one wait's bound; retried while a killed net worker is restarted
NET_GIVE_UP_S = 60.0


def net_blocks(arena: Arena) -> list:
    return [arena[name] for name in NET_BLOCKS]


def newest_state(blocks, out: np.ndarray, at_most: int | None = None) -> bool:
    """Copy into out[0] the newest published net state whose tick is <= at_most (any if None).

    Returns False when no block holds such a state (a fresh run: the net is as built).
    """
    best = None
    for block in blocks:
        if block.version < 2:  # never published
            continue
        tick = block.tick
        if (at_most is None or tick <= at_most) and (best is None or tick > best.tick):
            best = block
    if best is None:
        return False
    best.snapshot(out)
    return True


def _load(sim: NetSim, state) -> None:
    sim.knot_pos[:] = state["pos"]
    sim.knot_vel[:] = state["vel"]
    sim.sleeping = bool(state["sleeping"])
    sim.quiet_ticks = int(state["quiet_ticks"])
    net_box(sim.knot_pos, out=sim.box)


def _save(sim: NetSim, tick: int, state) -> None:
    state["tick"] = tick
    state["sleeping"] = sim.sleeping
    state["quiet_ticks"] = sim.quiet_ticks
    state["pos"] = sim.knot_pos
    state["vel"] = sim.knot_vel


def net_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """options: net_baton (processes.handoff.Baton); crash_at_tick (tests: SIGKILL this process
    after publishing that tick's state and before saying it is done, the hardest moment)."""
    topo = build_topology(scene.cloth)
    sim = NetSim(topo, scene.dt)
    NetSim(topo, scene.dt).step(topo.knot_pos[0], np.zeros(3))  # compile or load the kernels
    baton = options["net_baton"].attach(arena["net_baton"].array)
    io = arena["net_io"].array
    blocks = net_blocks(arena)
    state = np.zeros(1, net_snapshot_dtype(topo.n_knots))
    if newest_state(blocks, state):
        _load(sim, state[0])  # restarted: resume from the newest state
        net_tick = int(state[0]["tick"])
    else:
        net_tick = 0
        _save(sim, net_tick, state[0])
        blocks[0].publish(state, net_tick)
    control.set_state(WorkerState.READY)
    control.send("ready", net_tick)
    control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    busy = 0.0
    steps = 0
    try:
        while True:
            try:
                tick = baton.wait_turn(Control.HEARTBEAT_S)
            except HandoffTimeout:
                control.beat(int(control.row["tick"]))  # a sleeping net: still alive, still listening
                continue
            if tick is None:
                break
            t0 = time.perf_counter()
            if net_tick > tick:
                # The physics does this tick again (it was restarted): back to the state before it.
                newest_state(blocks, state, at_most=tick)
                _load(sim, state[0])
            row = io[0]
            contact = sim.step(row["ball"][0], row["ball"][1], float(row["radius"]), float(row["inv_mass"]))
            row["toi"] = contact.toi
            row["impulse"] = contact.impulse
            row["offset"] = contact.offset
            row["sleeping"] = sim.sleeping
            row["box"] = sim.box
            net_tick = tick + 1
            _save(sim, net_tick, state[0])
            blocks[net_tick % 2].publish(state, net_tick)
            steps += 1
            busy += time.perf_counter() - t0
            if tick == options.get("crash_at_tick"):
                os.kill(os.getpid(), signal.SIGKILL)
            baton.done()
            control.beat(tick)
        control.row["busy_s"] = float(control.row["busy_s"]) + busy
        control.send("done", {"tick": net_tick, "busy_s": busy, "steps": steps})
    finally:
        del io, blocks


class RemoteNet:
    """The physics worker's stand-in for the NetSim in engine.world: same `sleeping`, same step().

    Args:
        control: the physics worker's Control (heartbeats while it waits).
        arena, options: the run's (net_io, the two net blocks, net_baton).
        world: the physics state's world record (its tick says which tick is being stepped).
        local: a NetSim of the same net as built (its knot radius, tick and built shape).

    A sleeping net and a ball that cannot touch its frozen shape cost no hand-off, exactly as
    NetSim.step returns early: the stand-in keeps the box the net froze in (from net_io after
    each step; on a resume, from the state it resumes from, as the net worker does).
    """

    def __init__(self, control: Control, arena: Arena, options: dict, world, local: NetSim):
        self.control = control
        self.local = local
        self.world = world
        self.baton = options["net_baton"].attach(arena["net_baton"].array)
        self.io = arena["net_io"].array
        self._none = np.zeros(3)
        self.waits = 0.0
        # The net's sleep state at the tick we resume from (a fresh run: the net as built).
        state = np.zeros(1, net_snapshot_dtype(local.topo.n_knots))
        tick = int(world["tick"])
        if newest_state(net_blocks(arena), state, tick):
            self.sleeping = bool(state[0]["sleeping"])
            self.box = net_box(state[0]["pos"])
        else:
            self.sleeping = local.sleeping
            self.box = local.box.copy()

    def step(self, ball_pos, ball_vel, ball_radius: float, ball_inv_mass: float) -> NetContact:
        """NetSim.step, done by the net worker (called after the ball's tick, as engine.world does)."""
        local = self.local
        if self.sleeping and ball_far_from_box(self.box, True, local.knot_radius, local.dt, ball_pos, ball_vel,
                                               ball_radius):
            self._none[:] = 0.0
            return NetContact(NO_CONTACT, self._none, self._none)
        started = time.perf_counter()
        tick = int(self.world["tick"]) - 1
        row = self.io[0]
        row["tick"] = tick
        row["ball"][0] = ball_pos
        row["ball"][1] = ball_vel
        row["radius"] = ball_radius
        row["inv_mass"] = ball_inv_mass
        self.baton.give(tick)
        # The net worker may be restarting: stay alive and ask again (net_io still holds the ball).
        self.baton.wait_done_or_retry(tick, NET_HANDOFF_S, NET_GIVE_UP_S, self.control.beat)
        self.sleeping = bool(row["sleeping"])
        self.box[:] = row["box"]
        self.waits += time.perf_counter() - started
        return NetContact(float(row["toi"]), row["impulse"].copy(), row["offset"].copy())
