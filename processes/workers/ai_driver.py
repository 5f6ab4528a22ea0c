"""The physics worker's side of the AI's turns: AIDriver, the engine's ai_driver
(engine.match.Match) done by the AI worker through the run's shared rings.

The physics worker's other stand-ins live beside it: RemoteNet (processes.workers.remote_net,
the net worker's side of NetSim) and RemoteInputs (processes.workers.remote_inputs, the
gateway's players). Each does through shared memory (processes.workers.layout) what the
in-process engine does itself, so the physics steps the same bits as the reference.
"""
from __future__ import annotations

import time
from collections import deque

from engine.bot import FAULTS
from engine.match import Match
from engine.world import copy_record
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.runtime.timeline import WAIT_AI, WORK, Timeline
from processes.workers.layout import decision_key
from processes.workers.options import RunOptions

# A wait for an answer beats every options.handoff_s (the AI worker may be restarting, and goes
# on from the queue's counts) and gives up after this long in all.
AI_GIVE_UP_S = 60.0


class AIDriver:
    """An ai_driver for engine.match.Match whose players decide in the AI worker, match.delay
    ticks ahead of the physics.

    request() at control tick B gives the AI worker a turn (the state into the next slot of the
    `ai_views` ring, then the queue's post) and returns at once, when the AIs must decide or may:
    while a turn is unanswered, or when the newest answer's wakes say a decision can change
    (the decision key changed, or the clock reached the AIs' due or end: BatAI.wakes). Otherwise
    the AIs' decision would change nothing and no turn is given. collect() at B + match.delay
    waits (bounded) for the answer of the turn given at B, if one was, and puts its plans in
    effect (match.arm). A turn the AIs did not need changes nothing in them (Players.decide
    decides only where a decision can change), so giving one more is never wrong, and the
    plans, the faults and the AIs' random draws are the reference's bit for bit.
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, scene):
        self.control = control
        self.timeline: Timeline | None = None  # the physics' (its waits for the AI are marked), or None
        self.queue = options.ai_queue.attach(arena["ai_queue"].array)
        self.handoff_s = options.handoff_s
        self.views = arena["ai_views"].array
        self.answers = arena["ai_answers"].array
        self.n_ai = sum(1 for bat in scene.bats if bat.skill is not None)
        self.pending: deque = deque()  # (tick, turn) of the turns given whose plans are yet to take effect
        self.given = -1  # the tick of the newest turn given
        self._known = (0, None, 0.0, 0.0)  # (turn, key, due, end) of the newest answer read
        self.waits = 0.0  # wall time spent waiting for the AI (its work beyond our own)
        self.turns = self.local = self.waited = 0  # control ticks that gave a turn, that did not; collects that waited

    def _needs_turn(self, key, now: float) -> bool:
        """Whether the AIs may decide differently now (see the class)."""
        posted = self.queue.posted
        if posted == 0 or self.queue.answered < posted:
            return True
        turn, known_key, due, end = self._known
        if turn != posted:
            answer = self.answers[posted % len(self.answers)]
            known_key = tuple(int(v) for v in answer["key"])
            due, end = float(answer["due"]), float(answer["end"])
            self._known = (posted, known_key, due, end)
        return key != known_key or now >= due or now > end

    def request(self, match: Match, now: float) -> None:
        tick = int(match.state.world[0]["tick"])
        if tick <= self.given:
            return  # given before a restart, from the same state
        ref = match.referee
        if not self._needs_turn(decision_key(match.rally, ref.shots, int(ref.phase), ref.server, ref.striker), now):
            self.local += 1
            return
        turn = self.queue.posted + 1
        if self.pending and turn - self.pending[0][1] >= len(self.views) - 1:
            raise RuntimeError(f"ai: {len(self.pending)} turns in flight fill the ring of {len(self.views)} "
                               "(processes.workers.layout.ai_ring_size)")
        copy_record(match.state.record, self.views, turn % len(self.views))
        self.queue.post()
        self.pending.append((tick, turn))
        self.given = tick
        self.turns += 1

    def collect(self, match: Match, tick: int) -> list:
        """The plans of the turn given at tick - match.delay into match.arm; returns its faults
        [(player, tick, fault, detail)]."""
        if not self.pending or self.pending[0][0] != tick - match.delay:
            return []
        given, turn = self.pending.popleft()
        if self.queue.answered < turn:
            started = time.perf_counter()
            if self.timeline is not None:
                self.timeline.mark(WAIT_AI)
            self.queue.wait_answered(turn, self.handoff_s, AI_GIVE_UP_S, self.control.beat)
            if self.timeline is not None:
                self.timeline.mark(WORK)
            self.waits += time.perf_counter() - started
            self.waited += 1
        answer = self.answers[turn % len(self.answers)]
        if int(answer["turn"]) != turn or int(answer["tick"]) != given:
            raise RuntimeError(f"ai: the answer in turn {turn}'s slot is turn {int(answer['turn'])} of tick "
                               f"{int(answer['tick'])}, not of tick {given}")
        match.arm[:] = answer["ctl"][:self.n_ai]
        faults = []
        for player in match.ai_bats:
            if answer["fault"][player]:
                faults.append((player, given, FAULTS[int(answer["fault"][player])],
                               bytes(answer["fault_text"][player]).decode("utf-8", "replace")))
        return faults

    def resume(self, match: Match, tick: int) -> None:
        """After a restart at `tick`: the turns still to take effect from the rings, and the plans
        in effect from the newest answer before them (the idle arms before any)."""
        size = len(self.views)
        period = match.ai_every
        first = -(-tick // period) * period  # the first control tick still to do
        posted = self.queue.posted
        self.pending.clear()
        for turn in range(max(1, posted - size + 2), posted + 1):  # slots a killed physics was not writing
            given = int(self.views[turn % size]["world"]["tick"])
            if given >= first - match.delay:
                self.pending.append((given, turn))
                self.given = given
        before = self.pending[0][1] - 1 if self.pending else posted
        if before >= 1:
            answer = self.answers[before % size]
            if int(answer["turn"]) != before:
                raise RuntimeError(f"ai: restarted at tick {tick}, the answer of turn {before} is no longer kept")
            match.arm[:] = answer["ctl"][:self.n_ai]

    def close(self) -> None:
        del self.views, self.answers
