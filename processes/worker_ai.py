"""The AI worker: one controller per AI-driven bat. It only applies forces, never sets positions.

At every AI control tick the physics worker copies the state into the AI's view and gives it
its turn, then steps on; the AI computes every AI's force and torque from the view with
engine.match.ai_inputs (the very function the in-process match calls) and posts them to the
bat-input mailbox, which the physics worker drains under its lock at the next control tick.
Asked again for the tick it last did (the physics restarted, or timed out waiting), it posts
its last answer again rather than deciding twice: the AIs' plans and random draws move on once
per control tick, as in the reference.
"""
from __future__ import annotations

import os
import signal
import time

import numpy as np

from engine.dtypes import physics_snapshot_dtype
from engine.match import ai_inputs, make_ais
from engine.world import build_model, copy_record
from processes.handoff import HandoffTimeout
from processes.locks import LockTable
from processes.mailbox import Mailbox
from processes.shm import Arena
from processes.worker import GO_TIMEOUT_S, Control, WorkerState

MAX_BATS = 2
# One record per AI tick carries every AI bat's inputs (one locked post, not one per bat).
INPUT_DTYPE = np.dtype([("tick", "<i8"), ("mask", "<i8"), ("inputs", "<f8", (MAX_BATS, 6))])
LOCK_NAMES = ("bat_inputs",)


def ai_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """options: seed, baton (processes.handoff.Baton), lock_path."""
    model = build_model(scene)
    ais = make_ais(scene, model, options["seed"])
    n_bats = len(scene.bats)
    baton = options["baton"].attach(arena["baton"].array)
    locks = LockTable(options["lock_path"], LOCK_NAMES, arena["lock_holders"])
    box = Mailbox("bat_inputs", arena["inputs_header"], arena["inputs"], locks)
    view = arena["ai_view"].array
    snap = np.zeros(1, physics_snapshot_dtype(n_bats))
    ball_y = snap["ball"].view("<f8")  # views into the snapshot copy: nothing else is copied
    bats = snap["bats"][0]
    rally = snap[0]["rally"]
    world = snap[0]["world"]
    record = np.zeros((), INPUT_DTYPE)
    inputs = record["inputs"][:n_bats]
    record["mask"] = sum(1 << player for player in ais)
    for ai in ais.values():
        ai.warm_up()
    control.set_state(WorkerState.READY)
    control.send("ready", 0)
    control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    busy = 0.0
    last_tick = None
    try:
        while True:
            try:
                tick = baton.wait_turn(Control.HEARTBEAT_S)
            except HandoffTimeout:
                control.beat(int(control.row["tick"]))  # idle: still alive, still listening
                continue
            if tick is None:
                break
            t0 = time.perf_counter()
            if tick != last_tick:
                copy_record(view, snap)  # our own copy, byte for byte: the AIs keep views into it
                ai_inputs(ais, float(world["time"]), ball_y, bats, (int(rally["rally"]), int(rally["shots"])),
                          int(rally["phase"]), int(rally["server"]), int(rally["striker"]), inputs)
                record["tick"] = tick
                last_tick = tick
            box.post(record)
            busy += time.perf_counter() - t0
            baton.done()
            if tick == options.get("crash_at_tick"):
                os.kill(os.getpid(), signal.SIGKILL)
            control.beat(tick)
        control.row["busy_s"] = float(control.row["busy_s"]) + busy
        control.send("done", {"tick": int(control.row["tick"]), "busy_s": busy})
    finally:
        del view, snap, box, baton, ball_y, bats, rally, world
        locks.close()
