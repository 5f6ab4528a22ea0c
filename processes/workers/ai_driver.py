"""The physics worker's side of the hand-off to the AI worker: AIDriver, the engine's ai_driver
(engine.match.Match) done by the AI worker through the run's shared records, and PlanFollower,
the AIs' forces between their decisions from their last answer.

The physics worker's other stand-ins live beside it: RemoteNet (processes.workers.remote_net,
the net worker's side of NetSim) and RemoteInputs (processes.workers.remote_inputs, the
gateway's players). Each does through shared memory (processes.workers.layout) what the
in-process engine does itself, so the physics steps the same bits as the reference.
"""
from __future__ import annotations

import math
import time

import numpy as np

from engine.ai import BAT_FLOATS, CTL_NORMAL, CTL_SIZE, control_bats
from engine.bot import FAULTS
from engine.dtypes import BAT_DTYPE
from engine.match import Match
from engine.world import copy_record
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.workers.layout import decision_key
from processes.workers.options import RunOptions

# A hand-off waits options.handoff_s, gives the turn again (a killed AI worker is being
# restarted) and waits again, for this long in all.
AI_GIVE_UP_S = 60.0


class PlanFollower:
    """The physics side: the AIs' forces at a control tick that needs no decision, from the
    ctl rows of their last answer (the same control_bats the AIs call, so the same bits).

    Args:
        scene: the match scene (its AI bats, in order, are the answer's ctl rows).
    """

    def __init__(self, scene):
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


class AIDriver:
    """An ai_driver for engine.match.Match that asks the AI worker, which thinks while we step.

    request() at a control tick: if the AIs must decide (processes.workers.ai: the decision key
    changed since their last decision, or the clock reached its wakes), copy the state into the
    AI's view and give the AI worker its turn, at once; otherwise compute the forces here, as
    the AI would, with control_bats on the ctl rows of its last answer. collect() at the next
    control tick: wait (bounded) until the AI is done with the turn given and read its decision
    from the `ai_answer` record (the baton orders the AI's write before our read). The view is
    not written again before the turn is collected, so the AI always decides from exactly the
    state the reference decides from.
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, scene):
        self.control = control
        self.n_bats = len(scene.bats)
        self.plans = PlanFollower(scene)
        self.baton = options.ai_baton.attach(arena["ai_baton"].array)
        self.handoff_s = options.handoff_s
        self.answer = arena["ai_answer"].array
        self.view = arena["ai_view"].array
        local = arena["ai_local"].array
        self.local_tick = local["tick"]  # (1,): written after the inputs
        self.local_inputs = local["inputs"][0][:self.n_bats]
        self.floats = None  # the match's bats as (n_bats, BAT_FLOATS) float64, made at the first request
        self.turn: int | None = None  # the tick whose decision is in flight
        self.restored = None  # inputs computed here before a restart, to collect after it
        self.waits = 0.0  # wall time spent waiting for the AI (its work beyond our own)
        self.turns = self.local = 0  # control ticks that asked the AI, that did not

    def request(self, match: Match, now: float) -> None:
        tick = int(match.state.world[0]["tick"])
        ref = match.referee
        if not self.plans.needs_decision(decision_key(match.rally, ref.shots, int(ref.phase), ref.server, ref.striker),
                                         now):
            if self.floats is None:
                bats = match.state.bats
                self.floats = bats.view(np.float64).reshape(len(bats), -1)
            self.plans.control(now, self.floats, match.ai_next)
            self.local_inputs[:] = match.ai_next
            self.local_tick[0] = tick
            self.local += 1
            return
        copy_record(match.state.record, self.view, 0)
        self.baton.give(tick)
        self.turn = tick
        self.turns += 1

    def collect(self, match: Match) -> list:
        """The AIs' decision into match.ai_next; returns its faults [(player, tick, fault, detail)]."""
        if self.turn is None:
            if self.restored is not None:
                match.ai_next[:] = self.restored
                self.restored = None
            return []
        faults = []
        started = time.perf_counter()
        # The AI worker may be restarting: stay alive and ask again (the view still holds the state).
        self.baton.wait_done_or_retry(self.turn, self.handoff_s, AI_GIVE_UP_S, self.control.beat)
        answer = self.answer[0]
        if int(answer["tick"]) == self.turn:  # done with our turn: its answer, written before done
            mask = int(answer["mask"])
            for bat in range(self.n_bats):
                if mask >> bat & 1:
                    match.ai_next[bat] = answer["inputs"][bat]
                    if answer["fault"][bat]:
                        faults.append((bat, self.turn, FAULTS[int(answer["fault"][bat])],
                                       bytes(answer["fault_text"][bat]).decode("utf-8", "replace")))
            self.plans.take(answer)
        self.turn = None
        self.waits += time.perf_counter() - started
        return faults

    def resume(self, tick: int, period: int) -> None:
        """After a restart at `tick`: the decision of the last control tick before it is in
        flight (the AI's turn), or was computed here (kept in `ai_local`)."""
        self.turn = (tick - 1) // period * period if tick > 0 else None
        if self.turn is not None and self.local_tick[0] == self.turn:
            self.restored = self.local_inputs.copy()
            self.turn = None
        if int(self.answer[0]["tick"]) >= 0:  # the AIs' last answer (a turn in flight brings a newer one)
            self.plans.take(self.answer[0])

    def close(self) -> None:
        del self.view, self.answer, self.local_tick, self.local_inputs, self.floats
