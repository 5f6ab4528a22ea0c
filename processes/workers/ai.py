"""The AI worker: one controller per AI-driven bat. It only decides plans, never sets positions.

At an AI control tick B where the AIs must or may decide (processes.workers.ai_driver), the
physics worker copies the state into the next slot of the `ai_views` ring, posts the turn on the
queue (processes.runtime.handoff.TurnQueue) and steps on. The AI takes the turns in order,
decides from each view with engine.match.ai_decide (the very function the in-process match
calls) and writes the plans after it (each AI's ctl row: the planned path, the face normal,
gains and limits, or a raw force, or the brake), the decision key and the AIs' wakes into the
turn's slot of `ai_answers` before it counts the turn answered. The physics puts the plans in
effect match.delay ticks after B (engine.match.decision_delay), waiting only if the answer is not
there yet, so the AI thinks while the physics steps. A restarted AI worker goes on from the
players' state it kept and the turns it journalled since (StateKeeper), then from the queue's
counts, so a killed AI worker leaves the match as the reference plays it.

Most control ticks need no decision: while the rally key, the striker and the serve stay as they
were and the world clock has not reached the AIs' wakes (BatAI.wakes: a stroke thought out is
due, a plan runs out), BatAI.decide changes nothing and no turn is given: the physics plays the
plans in effect with the arm law (engine.arm.control_bats) itself. The AI is asked only when a
decision can change (a few times a rally instead of 100 times a simulated second); the plans
cross only from the AI to the physics, and the bats still get forces only.

A stroke is thought out between the turns (BatAI.think_step) while the physics steps on: the AI
looks for a posted turn between think steps (each mostly 10-50 us). A stroke starts when the ball
changes hands and is decided only a decision delay before it is played, and what is not thought
out by then is finished at that turn (BatAI.finish_thinking). The strokes are the same, bit for
bit, however the thinking was spread.
"""
from __future__ import annotations

import pickle
import sys
import time

import numpy as np

from engine.bot import FAULT_CODES
from engine.dtypes import physics_snapshot_dtype
from engine.match import ai_decide, make_ais
from engine.world import build_model, copy_record
from processes.runtime.shm import Arena
from processes.runtime.control import Control, crash
from processes.runtime.timeline import IDLE, THINK, WORK, Timeline
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
        self.ctl = self.record["ctl"][0][:len(ais)]
        self.faults = 0

    def answer(self, view: np.ndarray, turn: int) -> np.ndarray:
        """Decide from view[0] (a physics snapshot record) for turn `turn`; returns self.record, (1,)."""
        copy_record(view, self.snap)  # our own copy, byte for byte: the AIs keep views into it
        rally = self.rally
        phase, server, striker = int(rally["phase"]), int(rally["server"]), int(rally["striker"])
        tick = int(self.world["tick"])
        faults = ai_decide(self.ais, tick, float(self.world["time"]), self.ball_flat, self.bats, rally)
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
        record["turn"], record["tick"] = turn, tick
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
        self.turns = arena["ai_journal_turns"].array  # (turn, tick) of each view; turn -1: torn or none
        self.ais = ais
        self.answerer = answerer
        self.record = np.zeros(1, AI_STATE_DTYPE)
        self.seq = 0  # the last turn journalled

    def write(self, view: np.ndarray, turn: int) -> None:
        """Journal turn `turn` before its answer is published: its view (the state it is decided from)."""
        self.seq = turn
        k = turn % len(self.turns)
        self.turns[k, 0] = -1  # torn until its turn is written, last
        self.turns[k, 1] = int(view[0]["world"]["tick"])
        copy_record(view, self.views, k)
        self.turns[k, 0] = turn

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

    def load(self, publish) -> int:
        """A restart: load the state kept and decide the journal's later turns again, calling
        publish(turn, record) for each; returns the last turn decided (0: a fresh run)."""
        seq = 0
        if self.block.version >= 2:
            self.block.snapshot(self.record)
            size = int(self.record["size"][0])
            seq, state, answer, faults = pickle.loads(self.record["data"][0][:size].tobytes())
            self.ais.load_state(state)
            self.answerer.record[:] = answer
            self.answerer.faults = faults
        later = sorted((int(turn), k) for k, (turn, tick) in enumerate(self.turns) if turn > seq)
        if [turn for turn, _ in later] != list(range(seq + 1, seq + 1 + len(later))):
            raise RuntimeError(f"the AI's journal lacks turns after turn {seq} (it holds "
                               f"{[turn for turn, _ in later]}): AI_JOURNAL_TURNS = {len(self.turns)} is too few")
        for turn, k in later:
            publish(turn, self.answerer.answer(self.views[k:k + 1], turn))
            seq = turn
        self.seq = seq
        if seq:
            for seat in self.ais.values():
                if not seat.profile:
                    print(f"pingpong ai worker: restarted; bot {seat.name} starts afresh (a bot's own state is not "
                          f"kept)", file=sys.stderr, flush=True)
        return seq


def ai_worker(control: Control, arena: Arena, scene, options: RunOptions) -> None:
    """options: seed, ai_queue, bot_budget_s; crash_at_tick, crash_kind (tests: end this process
    after its first turn at or after that tick); slow_turn_s (tests: answer each turn that much later).
    A bot's hung decision is interrupted (SIGALRM)."""
    model = build_model(scene)
    ais = make_ais(scene, model, options.seed, eager=False, budget_s=options.bot_budget_s, interrupt=True)
    thinkers = ais.thinkers
    queue = options.ai_queue.attach(arena["ai_queue"].array)
    answers = arena["ai_answers"].array
    views = arena["ai_views"].array
    size = len(views)
    answerer = Answerer(ais, len(scene.bats))
    keeper = StateKeeper(arena, ais, answerer)
    crash_at = options.crash_at_tick
    ais.warm_up()

    def publish(turn: int, record: np.ndarray) -> None:
        """A turn's answer into its slot, then counted (one not yet counted: a replayed one may be)."""
        if turn > queue.answered:
            copy_record(record, answers, turn % size)
            queue.answer(turn)

    done = keeper.load(publish)  # a restart: the turns decided so far, and what the AIs were after them
    control.start(0)
    timeline = Timeline(options.timeline_dir, "ai") if options.timeline_dir is not None else None
    busy = think = longest = 0.0
    turns = 0
    try:
        while True:
            if queue.posted > done:
                if timeline is not None:
                    timeline.mark(WORK)
                t0 = time.perf_counter()
                turn = done + 1
                view = views[turn % size:turn % size + 1]
                keeper.write(view, turn)
                record = answerer.answer(keeper.views[turn % len(keeper.turns):turn % len(keeper.turns) + 1], turn)
                tick = int(record[0]["tick"])
                if options.slow_turn_s:
                    time.sleep(options.slow_turn_s)  # fault injection: a descheduled worker, not synchronisation
                publish(turn, record)
                done = turn
                took = time.perf_counter() - t0
                longest = max(longest, took)
                turns += 1
                keeper.keep(tick)  # off the physics' path: it has its answer
                busy += time.perf_counter() - t0
                if crash_at is not None and tick >= crash_at:
                    crash(options.crash_kind, tick)
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
                                   "turns": turns, "longest_turn_s": longest, "bot_faults": answerer.faults})
    finally:
        del views, answers, answerer, keeper
