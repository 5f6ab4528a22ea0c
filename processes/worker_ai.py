"""The AI worker: one controller per AI-driven bat. It only applies forces, never sets positions.

In lockstep the physics worker hands it the baton at every AI control tick; it reads the
physics snapshot, computes every AI's force and torque with engine.match.ai_inputs (the very
function the in-process match calls) and posts them to the bat-input mailbox, which the physics
worker drains under its lock.
"""
from __future__ import annotations

import os
import signal

import numpy as np

from engine.dtypes import BALL_DTYPE, BAT_DTYPE, physics_snapshot_dtype
from engine.match import ai_inputs, make_ais
from engine.world import build_model
from processes.handoff import HandoffTimeout
from processes.locks import LockTable
from processes.mailbox import Mailbox
from processes.shm import Arena
from processes.worker import Control, WorkerState

INPUT_DTYPE = np.dtype([("tick", "<i8"), ("bat", "<i8"), ("force", "<f8", (3,)), ("torque", "<f8", (3,))])
LOCK_NAMES = ("bat_inputs",)
STARTUP_TIMEOUT_S = 30.0


def ai_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """options: seed, baton (processes.handoff.Baton), lock_path."""
    model = build_model(scene)
    ais = make_ais(scene, model, options["seed"])
    n_bats = len(scene.bats)
    baton = options["baton"].attach(arena["baton"].array)
    locks = LockTable(options["lock_path"], LOCK_NAMES, arena["lock_holders"])
    box = Mailbox("bat_inputs", arena["inputs_header"], arena["inputs"], locks)
    snap = np.zeros(1, physics_snapshot_dtype(n_bats))
    ball = np.zeros(1, BALL_DTYPE)
    ball_y = ball.view("<f8")
    bats = np.zeros(n_bats, BAT_DTYPE)
    inputs = np.zeros((n_bats, 6))
    record = np.zeros((), INPUT_DTYPE)
    for ai in ais.values():
        ai.predict(np.array([0.0, 0.0, 0.5, 0, 0, 0, 0, 0, 0]), 0.01)  # compile or load the kernels
    control.set_state(WorkerState.READY)
    control.send("ready", 0)
    control.wait_for("go", STARTUP_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    try:
        while True:
            try:
                tick = baton.wait_turn(Control.HEARTBEAT_S)
            except HandoffTimeout:
                control.beat(int(control.row["tick"]))  # idle: still alive, still listening
                continue
            if tick is None:
                break
            arena["physics"].snapshot(snap)
            rec = snap[0]
            ball[0] = rec["ball"]
            bats[:] = rec["bats"]
            rally = rec["rally"]
            ai_inputs(ais, float(rec["world"]["time"]), ball_y, bats, (int(rally["rally"]), int(rally["shots"])),
                      int(rally["phase"]), int(rally["server"]), int(rally["striker"]), inputs)
            for player in ais:
                record["tick"] = tick
                record["bat"] = player
                record["force"] = inputs[player, 0:3]
                record["torque"] = inputs[player, 3:6]
                box.post(record)
            baton.done()
            if tick == options.get("crash_at_tick"):
                os.kill(os.getpid(), signal.SIGKILL)
            control.beat(tick)
        control.send("done", {"tick": int(control.row["tick"])})
    finally:
        del snap, box, baton
        locks.close()
