"""The AI worker: one controller per AI-driven bat. It only decides forces, never sets positions.

At an AI control tick where the AIs must decide, the physics worker copies the state into the
AI's view and gives it its turn, then steps on; the AI computes every AI's force and torque
from the view with engine.match.ai_inputs (the very function the in-process match calls) and
writes them, with what each AI's controller tracks (its ctl row: the planned path, the face
normal, gains and limits), into the `ai_answer` record before it says the turn is done; the
physics reads it after that, at the next control tick. The baton orders the two sides (as for
`ai_view` and the net's `net_io`), so the answer needs no lock. Asked again for the tick it last
did (the physics restarted, or timed out waiting), it answers with its last answer again rather
than deciding twice: the AIs' plans and random draws move on once per decision, as in the
reference.

Most control ticks need no decision: while the rally key, the striker and the serve stay as they
were and the world clock has not reached the AIs' wakes (BatAI.wakes: a stroke thought out is
due, a plan runs out), BatAI.decide changes nothing and the force is bat_control of the bat's
state and the published ctl rows alone. The physics worker then computes that force itself with
the same numba function (control_bats) and gives no turn: the AI is asked only when a decision
can change (a few times a rally instead of 100 times a simulated second). The force law stays
the AI's, its plan crosses only from the AI to the physics, and the bats still get forces only.

A stroke is thought out between the turns (BatAI.think_step) while the physics steps on: the AI
polls for a turn between think steps (each mostly 10-50 us), so a turn waits at most for the step
under way. A stroke starts when the ball changes hands and is played only after the reaction
time, and what is not thought out by then is finished at that turn (BatAI.finish_thinking). The
strokes are the same, bit for bit, however the thinking was spread.
"""
from __future__ import annotations

import math
import os
import signal
import time

import numpy as np

from engine.ai import BAT_FLOATS, CTL_SIZE
from engine.dtypes import BAT_DTYPE, physics_snapshot_dtype
from engine.match import ai_inputs, make_ais
from engine.rules import Phase, next_striker
from engine.world import build_model, copy_record
from processes.runtime.handoff import NO_TURN, HandoffTimeout
from processes.runtime.shm import Arena
from processes.runtime.control import GO_TIMEOUT_S, Control, WorkerState

MAX_BATS = 2
# The AIs' answer to one turn: the tick it answers, a bit per AI bat, every AI bat's inputs, and
# what the physics needs to compute the forces itself until the next decision: the decision key
# it was made under (decision_key), the wakes (BatAI.wakes) and each AI's ctl row, in the order
# of the scene's AI bats.
ANSWER_DTYPE = np.dtype([("tick", "<i8"), ("mask", "<i8"), ("inputs", "<f8", (MAX_BATS, 6)), ("key", "<i8", (4,)),
                         ("due", "<f8"), ("end", "<f8"), ("ctl", "<f8", (MAX_BATS, CTL_SIZE))])
# The inputs the physics computed itself at its last control tick without a turn (a restarted
# physics takes them up again): written only by the physics worker, read only by its successor.
LOCAL_DTYPE = np.dtype([("tick", "<i8"), ("inputs", "<f8", (MAX_BATS, 6))])


def decision_key(rally: int, shots: int, phase: int, server: int, striker: int) -> tuple[int, int, int, int]:
    """What the AIs' decisions depend on besides the clock and the ball: (rally, shots) (the rally
    key, which changes whenever the ball changes hands), the player to strike next and whether
    that strike is a service (the arguments of ai_inputs)."""
    return (rally, shots, next_striker(phase, server, striker), int(phase == Phase.WAITING_SERVE))


class Answerer:
    """The AI side of a turn: the AIs' decision from one state, as an ANSWER_DTYPE record.

    Args:
        ais: engine.ai.AIPlayers. n_bats: the scene's bats.
    """

    def __init__(self, ais, n_bats: int):
        self.ais = ais
        self.snap = np.zeros(1, physics_snapshot_dtype(n_bats))
        self.ball_y = self.snap["ball"].view("<f8")  # views into the snapshot copy: nothing else is copied
        self.bats = self.snap["bats"][0]
        self.rally = self.snap[0]["rally"]
        self.world = self.snap[0]["world"]
        self.record = np.zeros(1, ANSWER_DTYPE)
        self.inputs = self.record["inputs"][0][:n_bats]
        self.ctl = self.record["ctl"][0][:len(ais)]
        self.record["mask"] = sum(1 << player for player in ais)

    def answer(self, view: np.ndarray, tick: int) -> np.ndarray:
        """Decide from view[0] (a physics snapshot record) for `tick`; returns self.record, (1,)."""
        copy_record(view, self.snap)  # our own copy, byte for byte: the AIs keep views into it
        rally = self.rally
        phase, server, striker = int(rally["phase"]), int(rally["server"]), int(rally["striker"])
        rally_key = (int(rally["rally"]), int(rally["shots"]))
        ai_inputs(self.ais, float(self.world["time"]), self.ball_y, self.bats, rally_key, phase, server, striker,
                  self.inputs)
        record = self.record
        record["key"] = decision_key(*rally_key, phase, server, striker)
        record["due"], record["end"] = self.ais.wakes()
        self.ctl[:] = self.ais.ctl
        record["tick"] = tick
        return record


class PlanFollower:
    """The physics side: the AIs' forces at a control tick that needs no decision, from the
    ctl rows of their last answer (the same control_bats the AIs call, so the same bits).

    Args:
        scene: the match scene (its AI bats, in order, are the answer's ctl rows).
    """

    def __init__(self, scene):
        from engine.ai import CTL_NORMAL, control_bats

        self.n_bats = len(scene.bats)
        self.players = np.array([i for i, bat in enumerate(scene.bats) if bat.skill is not None], np.int64)
        self.ctl = np.zeros((len(self.players), CTL_SIZE))
        self.key = None  # the decision key of the last answer taken; None: none yet
        self.due = self.end = -math.inf
        self._control_bats = control_bats
        # Load (or compile) control_bats for these array types (the AIs' own) before the run.
        bats = np.zeros(self.n_bats, BAT_DTYPE)
        bats["quat"] = (1.0, 0.0, 0.0, 0.0)
        ctl = self.ctl.copy()
        ctl[:, CTL_NORMAL] = 1.0
        control_bats(0.0, bats.view(np.float64).reshape(self.n_bats, BAT_FLOATS), ctl, self.players,
                     np.zeros((self.n_bats, 6)))

    def take(self, answer) -> None:
        """What the AIs' controllers track until their next decision, from an ANSWER_DTYPE record."""
        self.ctl[:] = answer["ctl"][:len(self.players)]
        self.key = tuple(int(v) for v in answer["key"])
        self.due, self.end = float(answer["due"]), float(answer["end"])

    def needs_decision(self, key, now: float) -> bool:
        """Whether BatAI.decide could change anything now (see BatAI.wakes): the key changed, or
        the clock reached a wake."""
        return key != self.key or now >= self.due or now > self.end

    def control(self, now: float, bat_floats: np.ndarray, out: np.ndarray) -> None:
        """bat_floats: (n_bats, BAT_FLOATS) float64 view of the bats; out: (n_bats, 6), written at the AI rows."""
        self._control_bats(now, bat_floats, self.ctl, self.players, out)


def ai_worker(control: Control, arena: Arena, scene, options: dict) -> None:
    """options: seed, baton (processes.runtime.handoff.Baton); crash_at_tick (tests: SIGKILL this process
    after its first turn at or after that tick)."""
    model = build_model(scene)
    ais = make_ais(scene, model, options["seed"], eager=False)
    thinkers = list(ais.values())
    baton = options["baton"].attach(arena["baton"].array)
    answer = arena["ai_answer"].array
    view = arena["ai_view"].array
    answerer = Answerer(ais, len(scene.bats))
    crash_at = options.get("crash_at_tick")
    ais.warm_up()
    control.set_state(WorkerState.READY)
    control.send("ready", 0)
    control.wait_for("go", GO_TIMEOUT_S)
    control.set_state(WorkerState.RUNNING)
    busy = think = longest = 0.0
    turns = 0
    last_tick = None
    try:
        while True:
            thinker = next((ai for ai in thinkers if ai.thinking), None)
            if thinker is not None:  # think a step, unless a turn came meanwhile
                tick = baton.try_turn()
                if tick == NO_TURN:
                    t1 = time.perf_counter()
                    thinker.think_step()
                    think += time.perf_counter() - t1
                    control.beat(int(control.row["tick"]))
                    continue
            else:
                try:
                    tick = baton.wait_turn(Control.HEARTBEAT_S)
                except HandoffTimeout:
                    control.beat(int(control.row["tick"]))  # idle: still alive, still listening
                    continue
            if tick is None:
                break
            t0 = time.perf_counter()
            if tick != last_tick:
                answerer.answer(view, tick)
                last_tick = tick
            copy_record(answerer.record, answer)
            took = time.perf_counter() - t0
            busy += took
            longest = max(longest, took)
            turns += 1
            baton.done()
            if crash_at is not None and tick >= crash_at:
                os.kill(os.getpid(), signal.SIGKILL)
            control.beat(tick)
        busy += think
        control.row["busy_s"] = float(control.row["busy_s"]) + busy
        control.send("done", {"tick": int(control.row["tick"]), "busy_s": busy, "think_s": think,
                              "late_thoughts": sum(ai.late_thoughts for ai in thinkers),
                              "late_thinking_s": sum(ai.late_thinking_s for ai in thinkers),
                              "turns": turns, "longest_turn_s": longest})
    finally:
        del view, answer, baton, answerer
