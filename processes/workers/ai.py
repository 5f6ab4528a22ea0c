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
reference. A restarted AI worker goes on from the players' state it kept and the turns it
journalled since (StateKeeper), so a killed AI worker leaves the match as the reference plays it.

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

import pickle
import sys
import time

import numpy as np

from engine.bot import FAULT_CODES
from engine.dtypes import physics_snapshot_dtype
from engine.match import ai_inputs, make_ais
from engine.world import build_model, copy_record
from processes.runtime.handoff import NO_TURN, HandoffTimeout
from processes.runtime.shm import Arena
from processes.runtime.control import Control, crash
from processes.workers.layout import (AI_KEEP_EVERY, AI_STATE_BYTES, AI_STATE_DTYPE, ANSWER_DTYPE, FAULT_TEXT_BYTES,
                                      decision_key)
from processes.workers.options import RunOptions

class Answerer:
    """The AI side of a turn: the AIs' decision from one state, as an ANSWER_DTYPE record.

    Args:
        ais: engine.players.Players. n_bats: the scene's bats. names: each bat's player, for
            the faults this process reports on its stderr.
    """

    def __init__(self, ais, n_bats: int):
        self.ais = ais
        self.snap = np.zeros(1, physics_snapshot_dtype(n_bats))
        self.ball_flat = self.snap["ball"].view("<f8")  # views into the snapshot copy: nothing else is copied
        self.bats = self.snap["bats"][0]
        self.rally = self.snap[0]["rally"]
        self.world = self.snap[0]["world"]
        self.record = np.zeros(1, ANSWER_DTYPE)
        self.inputs = self.record["inputs"][0][:n_bats]
        self.ctl = self.record["ctl"][0][:len(ais)]
        self.record["mask"] = sum(1 << player for player in ais)
        self.faults = 0

    def answer(self, view: np.ndarray, tick: int) -> np.ndarray:
        """Decide from view[0] (a physics snapshot record) for `tick`; returns self.record, (1,)."""
        copy_record(view, self.snap)  # our own copy, byte for byte: the AIs keep views into it
        rally = self.rally
        phase, server, striker = int(rally["phase"]), int(rally["server"]), int(rally["striker"])
        faults = ai_inputs(self.ais, int(self.world["tick"]), float(self.world["time"]), self.ball_flat, self.bats,
                           rally, self.inputs)
        record = self.record
        record["fault"] = 0
        for player, fault, detail in faults:
            record["fault"][0][player] = FAULT_CODES[fault]
            record["fault_text"][0][player] = detail.encode("utf-8", "replace")[:FAULT_TEXT_BYTES]
            print(f"pingpong ai worker: bot {self.ais[player].name} (player {'AB'[player]}) at tick {tick}: "
                  f"{fault}: {detail}", file=sys.stderr, flush=True)
            self.faults += 1
        record["key"] = decision_key(int(rally["rally"]), int(rally["shots"]), phase, server, striker)
        record["due"], record["end"] = self.ais.wakes()
        self.ctl[:] = self.ais.ctl
        record["tick"] = tick
        return record


class StateKeeper:
    """What a restarted AI worker decides on from: the AIs' state after a turn, and a journal of
    the views of the turns answered since.

    Each turn's view goes into the `ai_journal` ring before the turn is done (one record copy on
    the physics' path); after every AI_KEEP_EVERY-th turn is done, off that path, the worker
    pickles its players' state (engine.players.Players.state), the turn's count and its answer
    into `ai_state`. A restarted worker loads that state and answers the journal's later turns
    again from their views: the same decisions, bit for bit (the strokes do not depend on how
    the thinking was spread), so with AI profiles in the seats a killed AI worker leaves the
    match as the reference plays it. A bot's own objects are not kept (pickling them at every
    decision would cost what the bot is made of): a restarted worker's bot starts afresh from
    the scene, and says so.
    """

    def __init__(self, arena: Arena, ais, answerer: Answerer):
        self.block = arena["ai_state"]
        self.views = arena["ai_journal"].array
        self.turns = arena["ai_journal_turns"].array  # (count, tick) of each view; count -1: torn or none
        self.ais = ais
        self.answerer = answerer
        self.record = np.zeros(1, AI_STATE_DTYPE)
        self.seq = 0  # turns answered

    def write(self, view: np.ndarray, tick: int) -> None:
        """Journal the turn about to be done: its view (the state it was decided from)."""
        self.seq += 1
        k = self.seq % len(self.turns)
        self.turns[k, 0] = -1  # torn until its count is written, last
        self.turns[k, 1] = tick
        copy_record(view, self.views, k)
        self.turns[k, 0] = self.seq

    def keep(self, tick: int) -> None:
        """Publish the state after the turn just done (`tick`), if it is an AI_KEEP_EVERY-th."""
        if self.seq % AI_KEEP_EVERY:
            return
        data = pickle.dumps((self.seq, self.ais.state(), self.answerer.record.copy(), self.answerer.faults),
                            protocol=pickle.HIGHEST_PROTOCOL)
        if len(data) > AI_STATE_BYTES:
            raise RuntimeError(f"the AIs' state takes {len(data)} bytes, above AI_STATE_BYTES = {AI_STATE_BYTES}")
        self.record["size"] = len(data)
        self.record["data"][0][:len(data)] = np.frombuffer(data, np.uint8)
        self.block.publish(self.record, tick)

    def load(self) -> int | None:
        """A restart: load the state kept and answer the journal's later turns again; returns the
        tick of the last turn answered, or None (a fresh run)."""
        seq = 0
        if self.block.version >= 2:
            self.block.snapshot(self.record)
            size = int(self.record["size"][0])
            seq, state, answer, faults = pickle.loads(self.record["data"][0][:size].tobytes())
            self.ais.load_state(state)
            self.answerer.record[:] = answer
            self.answerer.faults = faults
        later = sorted((int(count), int(tick), k) for k, (count, tick) in enumerate(self.turns) if count > seq)
        if [count for count, _, _ in later] != list(range(seq + 1, seq + 1 + len(later))):
            raise RuntimeError(f"the AI's journal lacks turns after turn {seq} (it holds "
                               f"{[count for count, _, _ in later]}): AI_JOURNAL_TURNS = {len(self.turns)} is too few")
        for count, tick, k in later:
            self.answerer.answer(self.views[k:k + 1], tick)
            seq = count
        self.seq = seq
        if seq:
            for seat in self.ais.values():
                if not seat.profile:
                    print(f"pingpong ai worker: restarted; bot {seat.name} starts afresh (a bot's own state is not "
                          f"kept)", file=sys.stderr, flush=True)
        if later:
            return later[-1][1]
        return int(self.answerer.record[0]["tick"]) if seq else None


def ai_worker(control: Control, arena: Arena, scene, options: RunOptions) -> None:
    """options: seed, ai_baton, bot_budget_s; crash_at_tick, crash_kind (tests: end this process
    after its first turn at or after that tick); slow_turn_s (tests: answer each turn that much later).
    A bot's hung decision is interrupted (SIGALRM)."""
    model = build_model(scene)
    ais = make_ais(scene, model, options.seed, eager=False, budget_s=options.bot_budget_s, interrupt=True)
    thinkers = ais.thinkers
    baton = options.ai_baton.attach(arena["ai_baton"].array)
    answer = arena["ai_answer"].array
    view = arena["ai_view"].array
    answerer = Answerer(ais, len(scene.bats))
    keeper = StateKeeper(arena, ais, answerer)
    crash_at = options.crash_at_tick
    ais.warm_up()
    last_tick = keeper.load()  # a restart: the answer to this tick is kept, and what the AIs were after it
    control.start(0)
    busy = think = longest = 0.0
    turns = 0
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
            new_turn = tick != last_tick
            if new_turn:
                answerer.answer(view, tick)
                keeper.write(view, tick)
                last_tick = tick
            copy_record(answerer.record, answer)
            took = time.perf_counter() - t0
            busy += took
            longest = max(longest, took)
            turns += 1
            if options.slow_turn_s:
                time.sleep(options.slow_turn_s)  # fault injection: a descheduled worker, not synchronisation
            baton.done(tick)
            if new_turn:  # off the physics' path: it has its answer
                t2 = time.perf_counter()
                keeper.keep(tick)
                busy += time.perf_counter() - t2
            if crash_at is not None and tick >= crash_at:
                crash(options.crash_kind, tick)
            control.beat(tick)
        busy += think
        control.finish(busy, 0.0, {"tick": int(control.row["tick"]), "busy_s": busy, "think_s": think,
                                   "late_thoughts": sum(ai.late_thoughts for ai in thinkers),
                                   "late_thinking_s": sum(ai.late_thinking_s for ai in thinkers),
                                   "turns": turns, "longest_turn_s": longest, "bot_faults": answerer.faults})
    finally:
        del view, answer, baton, answerer
