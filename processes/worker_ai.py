"""The AI worker: one controller per AI-driven bat. It only applies forces, never sets positions.

At every AI control tick the physics worker copies the state into the AI's view and gives it
its turn, then steps on; the AI computes every AI's force and torque from the view with
engine.match.ai_inputs (the very function the in-process match calls) and writes them into the
`ai_answer` record before it says the turn is done; the physics reads it after that, at the next
control tick. The baton orders the two sides (as for `ai_view` and the net's `net_io`), so the
answer needs no lock: a lock and mailbox cost the turn two fcntl calls a side (the locked post
alone took ~18 us a turn at load 3). Asked again for the tick it last did (the physics
restarted, or timed out waiting), it answers with its last answer again rather than deciding
twice: the AIs' plans and random draws move on once per control tick, as in the reference.

A stroke is thought out between the turns (BatAI.think_step), in the time the physics takes to
step to the next control tick, so the physics does not wait for it: a stroke starts when the
ball changes hands and is played only after the reaction time, and what is not thought out by
then is finished at that turn (BatAI.finish_thinking). The strokes are the same, bit for bit,
however the thinking was spread.
"""
from __future__ import annotations

import math
import os
import signal
import time

import numpy as np

from engine.dtypes import physics_snapshot_dtype
from engine.match import ai_inputs, make_ais
from engine.world import build_model, copy_record
from processes.handoff import HandoffTimeout
from processes.shm import Arena
from processes.worker import GO_TIMEOUT_S, Control, WorkerState

MAX_BATS = 2
# Thinking after a turn stops this share of the time between turns after the turn came: the
# physics asks for the next answer about two such times after it, and the think step under way
# (mostly 10-50 us; a service's check of its path up to ~200 us) and the next answer must fit
# in between.
THINK_SHARE = 0.9
PERIOD_WINDOW = 32  # turns over which the least time between two turns is the estimate
# One record per AI tick carries every AI bat's inputs: the tick it answers, a bit per AI bat.
INPUT_DTYPE = np.dtype([("tick", "<i8"), ("mask", "<i8"), ("inputs", "<f8", (MAX_BATS, 6))])


def ai_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """options: seed, baton (processes.handoff.Baton)."""
    model = build_model(scene)
    ais = make_ais(scene, model, options["seed"], eager=False)
    thinkers = list(ais.values())
    n_bats = len(scene.bats)
    baton = options["baton"].attach(arena["baton"].array)
    answer = arena["ai_answer"].array
    view = arena["ai_view"].array
    snap = np.zeros(1, physics_snapshot_dtype(n_bats))
    ball_y = snap["ball"].view("<f8")  # views into the snapshot copy: nothing else is copied
    bats = snap["bats"][0]
    rally = snap[0]["rally"]
    world = snap[0]["world"]
    record = np.zeros((), INPUT_DTYPE)
    inputs = record["inputs"][:n_bats]
    record["mask"] = sum(1 << player for player in ais)
    ais.warm_up()
    control.set_state(WorkerState.READY)
    control.send("ready", 0)
    control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    busy = think = longest = 0.0
    turns = 0
    last_tick = None
    period = 0.0  # s between turns (no thinking between turns until it is measured)
    least, n_periods, last_turn_at, prompt = math.inf, 0, 0.0, False
    try:
        while True:
            try:
                tick = baton.wait_turn(Control.HEARTBEAT_S)
            except HandoffTimeout:
                control.beat(int(control.row["tick"]))  # idle: still alive, still listening
                prompt = False
                continue
            if tick is None:
                break
            t0 = time.perf_counter()
            if prompt:  # we were waiting for this turn: the time since the last is the physics'
                least = min(least, t0 - last_turn_at)
                n_periods += 1
                if n_periods == PERIOD_WINDOW:
                    period, least, n_periods = least, math.inf, 0
            last_turn_at = t0
            if tick != last_tick:
                copy_record(view, snap)  # our own copy, byte for byte: the AIs keep views into it
                ai_inputs(ais, float(world["time"]), ball_y, bats, (int(rally["rally"]), int(rally["shots"])),
                          int(rally["phase"]), int(rally["server"]), int(rally["striker"]), inputs)
                record["tick"] = tick
                last_tick = tick
            answer[0] = record
            took = time.perf_counter() - t0
            busy += took
            longest = max(longest, took)
            turns += 1
            baton.done()
            prompt = True
            until = t0 + THINK_SHARE * period
            for ai in thinkers:
                while ai.thinking and time.perf_counter() < until:
                    if prompt:
                        t1, prompt = time.perf_counter(), False
                    ai.think_step()
            if not prompt:
                think += time.perf_counter() - t1
            if tick == options.get("crash_at_tick"):
                os.kill(os.getpid(), signal.SIGKILL)
            control.beat(tick)
        busy += think
        control.row["busy_s"] = float(control.row["busy_s"]) + busy
        control.send("done", {"tick": int(control.row["tick"]), "busy_s": busy, "think_s": think,
                              "late_thoughts": sum(ai.late_thoughts for ai in thinkers),
                              "late_thinking_s": sum(ai.late_thinking_s for ai in thinkers),
                              "turns": turns, "longest_turn_s": longest})
    finally:
        del view, snap, answer, baton, ball_y, bats, rally, world
