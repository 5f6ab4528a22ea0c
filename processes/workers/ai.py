"""The AI worker: one controller per AI-driven bat. It only decides plans, never sets positions.

At every AI control tick B the physics worker copies the state into the next slot of the
`ai_views` ring, posts the turn on the queue (processes.runtime.handoff.TurnQueue) and steps
on. The AI takes the turns in order and lets the players decide from each view with
engine.play.match.ai_decide (the very function the in-process match calls), then writes the plans
after it (each AI's ctl row: the planned path, the face normal, gains and limits, or a raw
force, or the brake) and whether a player decided into the turn's slot of `ai_answers` before
it counts the turn answered. The physics puts the plans in effect match.delay ticks after B
(CompiledScene.decision_delay), waiting only if the answer is not there yet, so the AI thinks
while the physics steps. A restarted AI worker goes on from the players' state it kept and the
decisions it journalled since (StateKeeper), then from the queue's counts, so a killed AI
worker leaves the match as the reference plays it.

Most turns need no decision: while the rally key, the striker and the serve stay as they were
and the world clock has not reached the AIs' wakes (BatAI.wakes: a stroke is to be decided, a
plan runs out), Players.decide lets nobody decide, and the turn costs a few microseconds; the
physics plays the plans in effect with the arm law (engine.play.arm.control_bats) itself. The plans
cross only from the AI to the physics, and the bats still get forces only.

A stroke is thought out between the turns (BatAI.think_step) while the physics steps on: the AI
answers the turns posted meanwhile between think steps (each mostly 10-50 us). A stroke starts when the ball
changes hands and is decided only a decision delay before it is played, and what is not thought
out by then is finished at that turn (BatAI.finish_thinking). The strokes are the same, bit for
bit, however the thinking was spread.
"""
from __future__ import annotations

import pickle
import sys
import time

import numpy as np

from engine.play.bot import FAULT_CODES
from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.compiled import CompiledScene
from engine.physics.world import copy_record
from engine.play.match import ai_decide, make_ais
from processes.runtime.shm import Arena
from processes.runtime.control import Control
from processes.runtime.timeline import IDLE, THINK, WORK, Timeline
from processes.workers.layout import AI_KEEP_EVERY, AI_STATE_BYTES, AI_STATE_DTYPE, ANSWER_DTYPE, FAULT_TEXT_BYTES
from processes.workers.options import RunOptions



class Answerer:
    """The AI side of a turn: the AIs' decision from one state, as an ANSWER_DTYPE record.

    Args:
        ais: engine.play.players.Players. n_bats: the scene's bats. say_faults: write each fault
            on stderr as it happens (a served match, whose operator sees no summary of them);
            else the physics records it and the match's summary says it, once. gates: write
            the players' gates into each answer (a run that gates its AI turns,
            RunOptions.gate_ai_turns).
    """

    def __init__(self, ais, n_bats: int, say_faults: bool = False, gates: bool = False):
        self.ais = ais
        self.say_faults = say_faults
        self.gates = gates
        self.snap = np.zeros(1, physics_snapshot_dtype(n_bats))
        self.ball_flat = self.snap["ball"].view("<f8")  # views into the snapshot copy: nothing else is copied
        self.bats = self.snap["bats"][0]
        self.rally = self.snap[0]["rally"]
        self.world = self.snap[0]["world"]
        self.record = np.zeros(1, ANSWER_DTYPE)
        self.ctl = self.record["ctl"][0][:len(ais)]
        self.gate_key, self.gate_due, self.gate_end = (self.record[name][0] for name in ("gate_key", "gate_due", "gate_end"))
        self.faults = 0

    def answer(self, view: np.ndarray, turn: int, before=None) -> np.ndarray:
        """Decide from view[0] (a physics snapshot record) for turn `turn`; returns self.record, (1,).
        before: called once before a player decides, if one does (engine.play.players.Players.decide)."""
        copy_record(view, self.snap)  # our own copy, byte for byte: the AIs keep views into it
        rally = self.rally
        tick = int(self.world["tick"])
        faults = ai_decide(self.ais, tick, float(self.world["time"]), self.ball_flat, self.bats, rally, before)
        record = self.record
        record["fault"] = 0
        record["changed"] = self.ais.decided
        for player, fault, detail in faults:
            record["fault"][0][player] = FAULT_CODES[fault]
            record["fault_text"][0][player] = detail.encode("utf-8", "replace")[:FAULT_TEXT_BYTES]
            if self.say_faults:
                print(f"pingpong ai worker: bot {self.ais[player].name} (player {'AB'[player]}) at tick {tick}: "
                      f"{fault}: {detail}", file=sys.stderr, flush=True)
            self.faults += 1
        self.ctl[:] = self.ais.ctl
        if self.gates:
            n = len(self.ais)
            self.ais.gates(self.gate_key[:n], self.gate_due[:n], self.gate_end[:n])
        record["turn"], record["tick"] = turn, tick
        return record

    def void(self, turn: int) -> np.ndarray:
        """The answer of a turn taken back (a speculating run): nobody decided."""
        record = self.record
        record["changed"], record["fault"], record["turn"], record["tick"] = 0, 0, turn, -1
        self.gate_due[:] = -np.inf  # no gate: the physics never reads a turn taken back
        return record


TAKEN_BACK = -2  # a journal entry's turn: its decision was taken back


class TakeBacks:
    """The AI worker's way back from decisions on states a speculating physics may take back
    (RunOptions.speculate; processes.workers.speculation): before deciding at a turn that
    `ai_spec` does not yet say final, it keeps the players' state (pickled: nothing is shared
    with the players it goes on with); when `ai_void` marks such a turn taken back, the players
    become what they were before its decision. The turns taken back are answered without a
    decision; the physics posts their control ticks again as new turns, decided from the states
    it steps again, so the decisions are the in-process match's."""

    def __init__(self, arena: Arena, ais):
        self.void = arena["ai_void"].array
        self.final = arena["ai_spec"].array
        self.ais = ais
        self.turn = 0  # the turn being answered
        self.decisions = 0  # the decisions journalled before it (StateKeeper)
        # (turn, the decisions journalled before it, the players' state before its decision), oldest first
        self.kept: list[tuple[int, int, bytes]] = []
        self.taken_back = 0  # decisions taken back
        self.on_taken_back = None  # called with the decisions journalled before the first taken back

    def voided(self, turn: int) -> bool:
        """Is `turn` taken back? Before that, the players go back from any decision taken back."""
        kept = self.kept
        final = int(self.final[0])  # read first: the physics marks the turns it takes back before it raises it
        void, size = self.void, len(self.void)
        for k, (decided, _, state) in enumerate(kept):
            if void[decided % size] == decided:
                self.ais.load_state(pickle.loads(state))
                if self.on_taken_back is not None:
                    self.on_taken_back(kept[k][1])
                self.taken_back += len(kept) - k
                del kept[k:]
                break
        while kept and kept[0][0] <= final:
            kept.pop(0)
        return void[turn % size] == turn

    def voided_turn(self, turn: int) -> bool:
        """Is `turn` marked taken back (its slot of `ai_void` holds it)?"""
        return self.void[turn % len(self.void)] == turn

    def at(self, turn: int, decisions: int):
        """The turn about to be answered and the decisions journalled before it; returns the hook
        Players.decide calls before a player decides (before)."""
        self.turn, self.decisions = turn, decisions
        return self.before

    def before(self) -> None:
        """A player is about to decide at self.turn: keep the players' state unless the turn is final."""
        turn = self.turn
        if turn > int(self.final[0]):
            self.kept.append((turn, self.decisions, pickle.dumps(self.ais.state(), protocol=pickle.HIGHEST_PROTOCOL)))

    def settled(self) -> tuple[int, bytes | None]:
        """The players' state after every decision no go-back can take back: (the decisions
        journalled before it, the state pickled), or (-1, None): the players' state now."""
        if self.kept:
            _, decisions, state = self.kept[0]
            return decisions, state
        return -1, None


class StateKeeper:
    """What a restarted AI worker decides on from: the AIs' state after a decision, and a journal
    of the views of the decisions since.

    The view of each turn at which a player decided goes into the `ai_journal` ring before the
    turn is counted answered (one record copy); after every AI_KEEP_EVERY-th decision is
    answered, the worker pickles its players' state (engine.play.players.Players.state), the
    decision's count and its answer into `ai_state`. A restarted worker loads that state and
    decides the journal's later views again: the same decisions, bit for bit (the strokes do not
    depend on how the thinking was spread; at the turns in between nobody decided, which changes
    nothing), so with AI profiles in the seats a killed AI worker leaves the match as the
    reference plays it. A bot's own objects are not kept (pickling them at every decision would
    cost what the bot is made of): a restarted worker's bot starts afresh from the scene, and
    says so.

    In a speculating run (takebacks: its TakeBacks) the state kept is the one after every
    decision no go-back can take back (TakeBacks.settled), and a restarted worker decides again
    only the journal's decisions at turns not taken back, keeping a way back from those not yet
    final.
    """

    def __init__(self, arena: Arena, ais, answerer: Answerer, takebacks: TakeBacks | None = None):
        self.block = arena["ai_state"]
        self.views = arena["ai_journal"].array
        self.entries = arena["ai_journal_turns"].array  # (turn, tick, decision) of each view; turn -1: torn or none
        self.ais = ais
        self.answerer = answerer
        self.takebacks = takebacks
        if takebacks is not None:
            takebacks.on_taken_back = self.take_back
        self.record = np.zeros(1, AI_STATE_DTYPE)
        self.decisions = 0  # the decisions journalled

    def write(self, view: np.ndarray, turn: int, tick: int) -> None:
        """Journal the decision of turn `turn` before it is counted answered: its view."""
        self.decisions += 1
        k = self.decisions % len(self.entries)
        self.entries[k, 0] = -1  # torn until its turn is written, last
        self.entries[k, 1], self.entries[k, 2] = tick, self.decisions
        copy_record(view, self.views, k)
        self.entries[k, 0] = turn

    def take_back(self, decisions: int) -> None:
        """The journalled decisions after the first `decisions` are taken back: marked so (turn
        TAKEN_BACK), a restart decides them never again."""
        entries = self.entries
        for k in range(len(entries)):
            if entries[k, 0] >= 0 and entries[k, 2] > decisions:
                entries[k, 0] = TAKEN_BACK

    def keep(self, tick: int) -> None:
        """Publish the state after the decision just answered (`tick`), if it is an AI_KEEP_EVERY-th."""
        if self.decisions % AI_KEEP_EVERY:
            return
        decisions, state, answer = self.decisions, None, self.answerer.record.copy()
        if self.takebacks is not None:
            decisions, state = self.takebacks.settled()
            if state is None:
                decisions = self.decisions
            answer = None  # the answer after a decision taken back may follow it: none is kept
            if self.decisions - decisions > len(self.entries) - AI_KEEP_EVERY:
                raise RuntimeError(f"the AI's journal of {len(self.entries)} decisions cannot hold the "
                                   f"{self.decisions - decisions} not yet final (layout.AI_SPEC_JOURNAL)")
        if state is None:
            state = self.ais.state()
        data = pickle.dumps((decisions, state, answer, self.answerer.faults), protocol=pickle.HIGHEST_PROTOCOL)
        if len(data) > AI_STATE_BYTES:
            raise RuntimeError(f"the AIs' state takes {len(data)} bytes, above AI_STATE_BYTES = {AI_STATE_BYTES}")
        self.record["size"] = len(data)
        self.record["data"][0][:len(data)] = np.frombuffer(data, np.uint8)
        self.block.publish(self.record, tick)

    def load(self, publish) -> None:
        """A restart: load the state kept and decide the journal's later views again, calling
        publish(turn, record) for each."""
        decisions = 0
        if self.block.version >= 2:
            self.block.snapshot(self.record)
            size = int(self.record["size"][0])
            decisions, state, answer, faults = pickle.loads(self.record["data"][0][:size].tobytes())
            self.ais.load_state(pickle.loads(state) if isinstance(state, bytes) else state)
            if answer is not None:
                self.answerer.record[:] = answer
            self.answerer.faults = faults
        later = sorted((int(d), int(turn), k) for k, (turn, tick, d) in enumerate(self.entries)
                       if (turn >= 0 or turn == TAKEN_BACK) and d > decisions)
        if [d for d, _, _ in later] != list(range(decisions + 1, decisions + 1 + len(later))):
            raise RuntimeError(f"the AI's journal lacks decisions after decision {decisions} (it holds "
                               f"{[d for d, _, _ in later]}): AI_JOURNAL_TURNS = {len(self.entries)} is too few")
        takebacks = self.takebacks
        for d, turn, k in later:
            before = None
            if turn == TAKEN_BACK or takebacks is not None and takebacks.voided_turn(turn):
                decisions = d
                continue  # taken back (the worker killed before it marked the journal): as if never decided
            if takebacks is not None:
                before = takebacks.at(turn, d - 1)
            publish(turn, self.answerer.answer(self.views[k:k + 1], turn, before))
            decisions = d
        self.decisions = decisions
        if decisions:
            for seat in self.ais.values():
                if not seat.profile:
                    print(f"pingpong ai worker: restarted; bot {seat.name} starts afresh (a bot's own state is not "
                          f"kept)", file=sys.stderr, flush=True)


def ai_worker(control: Control, arena: Arena, compiled: CompiledScene, options: RunOptions) -> None:
    """options: seed, handles.ai_queue, bot_budget_s; faults (tests: end this process after its
    first turn at or after the crash tick; answer each turn slow_turn_s later). A bot's hung
    decision is interrupted (SIGALRM)."""
    ais = make_ais(compiled, options.seed, eager=False, budget_s=options.bot_budget_s, interrupt=True)
    thinkers = ais.thinkers
    queue = options.handles.ai_queue.attach(arena["ai_queue"].array)
    answers = arena["ai_answers"].array
    views = arena["ai_views"].array
    size = len(views)
    answerer = Answerer(ais, len(compiled.scene.bats), say_faults=options.gateway is not None,
                        gates=options.gate_ai_turns)
    takebacks = TakeBacks(arena, ais) if options.speculate else None
    keeper = StateKeeper(arena, ais, answerer, takebacks)
    faults = options.faults
    ais.warm_up()

    def publish(turn: int, record: np.ndarray) -> None:
        """A turn's answer into its slot, then counted (one not yet counted: a replayed one may be)."""
        if turn > queue.answered:
            copy_record(record, answers, turn % size)
            queue.answer(turn)

    keeper.load(publish)  # a restart: what the AIs were after their last decision answered
    done = queue.answered
    control.start(0)
    timeline = Timeline(options.timeline_dir, "ai") if options.timeline_dir is not None else None
    busy = think = longest = 0.0
    turns = decisions = 0
    try:
        while True:
            if queue.posted > done:
                if timeline is not None:
                    timeline.mark(WORK)
                t0 = time.perf_counter()
                turn = done + 1
                view = views[turn % size:turn % size + 1]
                before = None
                if takebacks is not None:
                    if takebacks.voided(turn):
                        publish(turn, answerer.void(turn))
                        done = turn
                        continue
                    before = takebacks.at(turn, keeper.decisions)
                record = answerer.answer(view, turn, before)
                tick = int(record[0]["tick"])
                decided = ais.decided
                decisions += decided
                if decided:
                    keeper.write(view, turn, tick)
                if faults is not None:
                    faults.delay()
                publish(turn, record)
                done = turn
                turns += 1
                if decided:
                    keeper.keep(tick)  # off the physics' path: it has its answer
                took = time.perf_counter() - t0
                busy += took
                longest = max(longest, took)
                if faults is not None and faults.crashes_in(-1, tick + 1):  # the first turn at or after it
                    faults.crash(tick)
                control.beat(tick)
                continue
            if queue.stopped:
                break
            thinker = next((ai for ai in thinkers if ai.thinking), None)
            if thinker is not None:  # think a step, then look for a turn again
                if timeline is not None:
                    timeline.mark(THINK)
                t1 = time.perf_counter()
                thinker.think_step()
                think += time.perf_counter() - t1
                control.beat(int(control.row["tick"]))
                continue
            if timeline is not None:
                timeline.mark(IDLE)
            if not queue.wait_posted(done, Control.HEARTBEAT_S):
                control.beat(int(control.row["tick"]))  # idle: still alive, still listening
        busy += think
        if timeline is not None:
            timeline.save()
        control.finish(busy, 0.0, {"tick": int(control.row["tick"]), "busy_s": busy, "think_s": think,
                                   "late_thoughts": sum(ai.late_thoughts for ai in thinkers),
                                   "late_thinking_s": sum(ai.late_thinking_s for ai in thinkers),
                                   "turns": turns, "decisions": keeper.decisions,
                                   "taken_back": 0 if takebacks is None else takebacks.taken_back, "longest_turn_s": longest,
                                   "bot_faults": answerer.faults})
    finally:
        del views, answers, answerer, keeper, takebacks
