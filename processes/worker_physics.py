"""The physics worker: ball, bats, contacts. It owns the physics snapshot and the event log."""
from __future__ import annotations

import os
import signal
import time

import numpy as np

from engine.dtypes import physics_snapshot_dtype
from engine.run import snapshot_into
from engine.world import build_model, initial_state, new_events, step
from processes.shm import Arena
from processes.worker import Control, WorkerState

STARTUP_TIMEOUT_S = 30.0


def restore(state, record: np.ndarray) -> None:
    """Load a physics snapshot record into the engine state (restart after a crash)."""
    state.ball[0] = record["ball"]
    state.bats[:] = record["bats"]
    state.world[0] = record["world"]


def physics_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """Run the physics ticks: lockstep (as fast as possible) or realtime (paced by the wall clock).

    options: ticks (total to reach), mode ("lockstep" | "realtime"), trace (bool),
        crash_at_tick (int or None: SIGKILL this process right after publishing that tick).
    """
    model = build_model(scene)
    state = initial_state(scene)
    events = new_events()
    snapshots = arena["physics"]
    log = arena["events"].array
    trace = arena["trace"].array if options.get("trace") else None
    record = np.zeros(1, physics_snapshot_dtype(len(scene.bats)))
    # Compile (or load from the cache) before reporting ready: a zero-length tick is an identity.
    step(model, state, None, events, dt=0.0)
    if snapshots.version >= 2:
        restore(state, snapshots.latest()[0])  # restarted: resume from the last consistent snapshot
    else:
        snapshot_into(state, record[0])
        if trace is not None:
            trace[0] = record[0]
        snapshots.publish(record, 0)
    tick = int(state.world[0]["tick"])
    total_events = int(state.world[0]["events_total"])
    control.set_state(WorkerState.READY)
    control.send("ready", tick)
    start_wall = control.wait_for("go", STARTUP_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    realtime = options["mode"] == "realtime"
    n_ticks = options["ticks"]
    dt = model.dt
    row = control.row
    busy = 0.0
    crash_at_tick = options.get("crash_at_tick")
    capacity = log.shape[0]
    while tick < n_ticks:
        if realtime:
            due = start_wall + tick * dt
            now = time.monotonic()
            if now < due:
                time.sleep(due - now)  # pacing to the wall clock, not synchronisation
            else:
                late = now - due
                if late > dt:
                    row["late_ticks"] += 1
                    row["max_late_s"] = max(float(row["max_late_s"]), late)
        t0 = time.perf_counter()
        n = step(model, state, None, events)
        for k in range(n):
            log[(total_events + k) % capacity] = events[k]
        total_events += n
        tick += 1
        snapshot_into(state, record[0])
        if trace is not None:
            trace[tick] = record[0]
        snapshots.publish(record, tick)
        if tick == crash_at_tick:
            os.kill(os.getpid(), signal.SIGKILL)
        busy += time.perf_counter() - t0
        control.beat(tick)
    row["busy_s"] = float(row["busy_s"]) + busy
    control.send("done", {"tick": tick, "busy_s": busy})
