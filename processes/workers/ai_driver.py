"""The physics worker's side of the AI's turns: AIDriver, the engine's ai_driver
(engine.play.match.Match) done by the AI worker through the run's shared rings.

The physics worker's other stand-ins live beside it: RemoteNet (processes.workers.remote_net,
the net worker's side of NetSim) and RemoteInputs (processes.workers.remote_inputs, the
gateway's players). Each does through shared memory (processes.workers.layout) what the
in-process engine does itself, so the physics steps the same bits as the reference.
"""
from __future__ import annotations

import time
from collections import deque

from engine.play.bot import FAULTS
from engine.physics.world import copy_record
from engine.physics.scene import Scene
from engine.play.match import Match
from engine.play.players import decision_key, gate_open
from processes.runtime.control import Control
from processes.runtime.shm import Arena
from processes.runtime.timeline import WAIT_AI, WORK, Timeline
from processes.workers.cut import Cuts
from processes.workers.options import RunOptions

# A wait for an answer beats every options.handoff_s (the AI worker may be restarting, and goes
# on from the queue's counts) and gives up after this long in all.
AI_GIVE_UP_S = 60.0


class AIDriver:
    """An ai_driver for engine.play.match.Match whose players decide in the AI worker, match.delay
    ticks ahead of the physics.

    request() at a control tick B writes the state into the next slot of the `ai_views` ring
    and posts it on the queue, and returns at once: the AI worker takes the turns in order and
    lets the players decide where a decision can change (Players.decide: the decision key
    changed, or the clock reached a player's wakes), which at most control ticks is nowhere.
    Each answer carries the players' gates after it (Players.gates), so in a run that gates its
    AI turns (RunOptions.gate_ai_turns) where the newest turn posted is answered, request() asks
    the gates itself (players.gate_open) and posts no turn at a control tick where nobody could
    decide: there the AI would answer "unchanged". While an answer is still out, every control
    tick is a turn.
    collect() at B + match.delay waits (bounded) until the AI has answered B's turn and, if a
    player decided there, puts the plans in effect (match.arm) and returns the faults. The
    players decide in the AI worker from exactly the states they decide from in-process, in the
    same order, so the plans, the faults and the AIs' random draws are the reference's bit for bit.
    """

    def __init__(self, control: Control, arena: Arena, options: RunOptions, scene: Scene):
        self.control = control
        self.queue = options.handles.ai_queue.attach(arena["ai_queue"].array)
        self.handoff_s = options.handoff_s
        self.gated = options.gate_ai_turns
        self.views = arena["ai_views"].array
        self.answers = arena["ai_answers"].array
        # a speculating run's (processes.workers.speculation): the turns taken back, and the
        # newest turn no go-back can take back (None: a run that does not speculate)
        self.void = arena["ai_void"].array if "ai_void" in arena.blocks else None
        self.final = arena["ai_spec"].array if "ai_spec" in arena.blocks else None
        self.cuts = Cuts(arena["spec_cut"].array) if "spec_cut" in arena.blocks else None
        self.n_ai = sum(1 for bat in scene.bats if bat.skill is not None)
        self.pending: deque = deque()  # (tick, turn) of the turns given whose plans are yet to take effect
        self.given = -1  # the tick of the newest turn given
        self.last_turn = 0  # the newest turn given (0: none): its answer holds the players' gates now
        self.gates = None  # (keys, dues, ends) from last_turn's answer, once read
        self.timeline: Timeline | None = None  # the physics' (its waits for the AI are marked), or None
        self.waits = 0.0  # wall time spent waiting for the AI (its work beyond our own)
        self.turns = self.waited = self.decided = 0  # turns given; of them, waited for; decided by a player
        self.skipped = 0  # control ticks at which nobody could decide: no turn given

    def request(self, match: Match, now: float) -> None:
        tick = int(match.state.world[0]["tick"])
        if tick <= self.given:
            return  # given before a restart, from the same state
        if self.gated and self._closed(match, now):
            self.skipped += 1
            return
        turn = self.queue.posted + 1
        size = len(self.views)
        if self.pending and turn - self.pending[0][1] >= size - 1:
            raise RuntimeError(f"ai: {len(self.pending)} turns in flight fill the ring of {size} "
                               "(processes.workers.layout.ai_ring_size)")
        copy_record(match.state.record, self.views, turn % size)
        self.queue.post()
        self.pending.append((tick, turn))
        self.given = tick
        self.last_turn, self.gates = turn, None
        self.turns += 1

    def _closed(self, match: Match, now: float) -> bool:
        """Is nobody able to decide now, as the gates after the newest turn given say (False while
        its answer is out: then nothing is known)?"""
        gates = self.gates
        if gates is None:
            turn = self.last_turn
            if turn == 0 or self.queue.answered < turn:
                return False
            answer = self.answers[turn % len(self.answers)]
            if int(answer["turn"]) != turn:
                return False  # a restarted AI worker's answer of an earlier incarnation: ask
            n = self.n_ai
            # As Python numbers: the gates are asked at every control tick until the next answer.
            gates = self.gates = ([tuple(row) for row in answer["gate_key"][:n].tolist()],
                                  answer["gate_due"][:n].tolist(), answer["gate_end"][:n].tolist())
        return not gate_open(decision_key(match.rally_record), now, *gates)

    def collect(self, match: Match, tick: int) -> list:
        """The plans of the turn given at tick - match.delay into match.arm, if a player decided
        there; returns its faults [(player, tick, fault, detail)]."""
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
        if not answer["changed"]:
            return []
        self.decided += 1
        match.arm[:] = answer["ctl"][:self.n_ai]
        faults = []
        for player in match.ai_bats:
            if answer["fault"][player]:
                faults.append((player, given, FAULTS[int(answer["fault"][player])],
                               bytes(answer["fault_text"][player]).decode("utf-8", "replace")))
        return faults

    def checkpoint(self) -> tuple:
        """What rollback() takes the driver back to: its turns in flight, the turns posted, the
        newest one given and its gates."""
        return tuple(self.pending), self.given, self.queue.posted, self.last_turn, self.gates

    def rollback(self, checkpoint: tuple) -> None:
        """Back to a checkpoint() (a speculating physics worker goes back to the state it was
        taken at): the turns posted since are taken back (marked in `ai_void`, so the AI worker
        answers them without deciding and forgets what it decided at them); the turns of the
        control ticks stepped again are posted anew."""
        pending, self.given, posted, self.last_turn, self.gates = checkpoint
        void = self.void
        size = len(void)
        for turn in range(posted + 1, self.queue.posted + 1):
            void[turn % size] = turn
        self.pending = deque(pending)

    def confirm(self, turn: int) -> None:
        """No go-back will take back turn `turn` or any before it (the AI worker keeps no way back
        from their decisions)."""
        self.final[0] = turn

    def resume(self, match: Match, tick: int) -> None:
        """After a restart at `tick`: the turns still to take effect from the rings, and the plans
        in effect from the answer of the turn before them, which holds the plans after it. A
        speculating run's from the snapshot's cut (processes.workers.cut) and `ai_spec`: the
        turns posted after the newest one confirmed were posted from states that may have been
        guesses, and are taken back; those between the cut and it, from the states the physics
        steps again, take effect as they were (their decisions are final)."""
        if self.cuts is not None:
            _, arm, (pending, given, posted, last_turn, gates) = self.cuts.read(tick)
            final = max(int(self.final[0]), posted)  # the physics confirms after it publishes
            self.rollback((pending, given, final, last_turn, gates))
            match.arm[:] = arm
            size = len(self.views)
            for turn in range(posted + 1, final + 1):
                if self.void[turn % len(self.void)] != turn:
                    self.given = int(self.views[turn % size]["world"]["tick"])
                    self.pending.append((self.given, turn))
                    self.last_turn, self.gates = turn, None
            return
        size = len(self.views)
        period = match.ai_every
        first = -(-tick // period) * period  # the first control tick still to do
        posted = self.queue.posted
        self.pending.clear()
        self.last_turn, self.gates = posted, None  # the gates after the newest turn given, once answered
        for turn in range(max(1, posted - size + 2), posted + 1):  # slots a killed physics was not writing
            given = int(self.views[turn % size]["world"]["tick"])
            if given >= first - match.delay:
                self.pending.append((given, turn))
                self.given = given
        before = self.pending[0][1] - 1 if self.pending else posted
        if before >= 1:
            self.queue.wait_answered(before, self.handoff_s, AI_GIVE_UP_S, self.control.beat)
            answer = self.answers[before % size]
            if int(answer["turn"]) != before:
                raise RuntimeError(f"ai: restarted at tick {tick}, the answer of turn {before} is no longer kept")
            match.arm[:] = answer["ctl"][:self.n_ai]

    def close(self) -> None:
        del self.views, self.answers
