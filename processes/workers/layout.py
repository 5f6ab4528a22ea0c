"""The run's shared layout: every record and block a run shares, its dtype, and who writes it.

One writer per block (others ask its owner through a mailbox, processes.runtime.mailbox); the supervisor creates them all here, before any worker starts,
and removes them at the end. The blocks of a run, by name:

| name | dtype | writer | readers |
|---|---|---|---|
| physics | engine physics snapshot (SnapshotBlock) | physics | supervisor, gateway, a restarted physics |
| events | CONTACT_DTYPE ring of EVENT_LOG_CAPACITY | physics | supervisor |
| status | runtime.control.STATUS_DTYPE, a row per worker | each worker its row | supervisor |
| trace | physics snapshot per tick (with trace) | physics | supervisor |
| points | POINT_DTYPE log (a match) | physics | supervisor, gateway |
| frames | physics snapshot every frame_every ticks (replays) | physics | supervisor |
| net_a, net_b | net snapshot (SnapshotBlock), published into each in turn | net | physics, a restarted net |
| net_show | net show record (SnapshotBlock, a run with a net and a gateway): the knots as clients see them | net | gateway |
| net_io | NET_IO_DTYPE | physics and net, ordered by net_baton | both |
| ai_queue | TurnQueue's words: turns posted, turns answered, command | physics the first, ai the second | both |
| ai_views | physics snapshot ring of ai_ring_size: turn k's state in slot k % size, before its post | physics | ai, a restarted physics |
| ai_answers | ANSWER_DTYPE ring of ai_ring_size: turn k's answer in slot k % size, before its count | ai | physics |
| ai_journal, ai_journal_turns | physics snapshot ring of AI_JOURNAL_TURNS, and each one's (turn, tick, decision): the views of the turns a player decided at, before they are counted answered | ai | a restarted ai |
| ai_state | AI_STATE_DTYPE (SnapshotBlock): the AIs' pickled state after a decision, after it is counted answered | ai | a restarted ai |
| net_queue, net_runs, net_answers, net_spec | a speculating run's runs near the net, their answers and its words (SPEC_WORDS) | physics the runs, net the answers | both |
| net_states | net_state_dtype ring of NET_STATES: the net's state after each run it answered | net | a restarted net or physics |
| spec_cut | processes.workers.cut.CUT_DTYPE, two rows: what goes with each snapshot published | physics | a restarted physics |
| ai_void, ai_spec | a speculating run's turns taken back, and the newest turn no go-back can take back | physics | ai |
| remote_header, remote_inputs | Mailbox of REMOTE_INPUT_DTYPE (locked) | gateway posts | physics drains |
| remote_applied, remote_acks | seqs applied per bat, REMOTE_ACK_DTYPE ring | physics | gateway |
| seats | network.server.seats.SEAT_DTYPE (SnapshotBlock) | gateway | a restarted gateway |
| lock_holders | runtime.locks.HOLDER_DTYPE | lock table | lock table |
"""
from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from engine.physics.dtypes import (CONTACT_DTYPE, POINT_DTYPE, ai_answer_dtype, net_show_dtype, net_snapshot_dtype,
                                   physics_snapshot_dtype)
from engine.physics.compiled import CompiledScene
from engine.physics.world import NET_RUN_TICKS
from engine.play.arm import CTL_SIZE
from processes.network.server.seats import SEAT_DTYPE
from processes.runtime.control import STATUS_DTYPE
from processes.runtime.handoff import QUEUE_WORDS, SPIN_S, TICK_SLOT_DTYPE, Baton, TurnQueue
from processes.runtime.locks import HOLDER_DTYPE, LockTable
from processes.runtime.mailbox import MAILBOX_HEADER
from processes.runtime.shm import Arena
from processes.workers.cut import CUT_DTYPE, CUT_ROWS

if TYPE_CHECKING:
    from multiprocessing.synchronize import Event

EVENT_LOG_CAPACITY = 1 << 16
POINT_LOG_CAPACITY = 1 << 12  # a best-of-9 match has at most a few hundred rallies

MAX_BATS = 2
ANSWER_DTYPE = ai_answer_dtype(MAX_BATS, CTL_SIZE)
FAULT_TEXT_BYTES = ANSWER_DTYPE["fault_text"].base.itemsize
# What a restarted AI worker decides on from (processes.workers.ai.StateKeeper): the AIs' state
# after a decision (engine.play.players.Players.state, the decision's count and its answer), pickled,
# and the views of the decisions since, replayed. Two AI profiles' plans, thoughts and random
# states take a few kilobytes (a bot's own objects are not kept). The state is kept after every
# AI_KEEP_EVERY-th decision is answered, off the physics' path; the journal holds the decisions since.
AI_STATE_BYTES = 1 << 14
AI_STATE_DTYPE = np.dtype([("size", "<i8"), ("data", "u1", (AI_STATE_BYTES,))])
AI_KEEP_EVERY = 8
AI_JOURNAL_TURNS = 2 * AI_KEEP_EVERY  # the decisions since the state kept, and those of a keep cut short

# The physics' hand-off of a run of ticks near the net to the net worker (engine.physics.world's
# _run_near_net), and the net's answer (NetSim.step_run's).
NET_IO_DTYPE = np.dtype([
    ("tick", "<i8"),  # the run's first tick (the physics' tick at its start)
    ("count", "<i8"),  # the run's ticks, at most NET_RUN_TICKS
    ("ball", "<f8", (NET_RUN_TICKS, 2, 3)),  # each tick's ball at its start: position m, velocity m/s
    ("radius", "<f8"), ("inv_mass", "<f8"),  # m, 1/kg
    ("taken", "<i8"),  # the ticks the net stepped: up to the first that touched the ball, or all
    ("toi", "<f8"), ("impulse", "<f8", 3), ("offset", "<f8", 3),  # the contact in the last of them
    ("sleeping", "<i8"),  # the net sleeps after the run
    ("tail_until", "<i8"),  # -1, or the tick at which the linear tail holding the net after the run falls asleep
    ("box", "<f8", (2, 3)),  # m, lo and hi corners of the knots' box after the run (NetSim.box)
    ("bounded", "<i8"),  # 1: `bound` holds the awake net's knots from the run's end until a ball comes near
    ("bound", "<f8", (2, 3)),  # m, lo and hi corners of that box (NetSim.bound_box)
    ("granted", "<i8"),  # the physics: the net may step every tick below this without the ball
    ("turn", "<i8"),  # the physics: two a run, odd while its fields are written (a repeated turn counts again)
    ("served", "<i8"),  # the worker: the last turn it answered
])
NET_BLOCKS = ("net_a", "net_b")
NET_SHOW = "net_show"

# A speculating run (RunOptions.speculate): the physics posts its runs near the net on a queue
# (processes.runtime.handoff.TurnQueue, "net_queue") into the ring `net_runs` and steps on as if
# the net touched none of them; the net answers each in order into `net_answers` (a run's turn
# number mod SPEC_RUNS is its slot in both) and halts at a touch until the physics has gone back
# to it (processes.workers.speculation). The words of `net_spec`: the tick below which the net
# may step without the ball (granted), the number of the physics' go-backs (epoch), and the run
# whose end a restarted physics sends the net back to (back; -1: none asked).
SPEC_RUNS = 64
# The net's states kept after its runs: a restarted physics sends the net back to its state after
# the last run before the snapshot it resumes from, which is at most SPEC_RUNS // 2 runs before
# the oldest run not yet confirmed (processes.workers.speculation publishes one at least that
# often), and the net may have answered up to twice SPEC_RUNS runs past that one.
NET_STATES = 4 * SPEC_RUNS
SPEC_RUN_DTYPE = np.dtype([("tick", "<i8"), ("count", "<i8"), ("ball", "<f8", (NET_RUN_TICKS, 2, 3)),
                           ("radius", "<f8"), ("inv_mass", "<f8")])
SPEC_ANSWER_DTYPE = np.dtype([
    ("run", "<i8"), ("taken", "<i8"), ("toi", "<f8"), ("impulse", "<f8", 3), ("offset", "<f8", 3),
    ("sleeping", "<i8"), ("tail_until", "<i8"), ("box", "<f8", (2, 3)), ("bounded", "<i8"), ("bound", "<f8", (2, 3))])
SPEC_GRANTED, SPEC_EPOCH, SPEC_BACK = 0, 1, 2  # words of net_spec
SPEC_WORDS = 3
# The AI's rings in a speculating run hold the turns of every control tick the physics may still
# go back over (a turn's answer is collected again after a go-back), and `ai_void` marks the
# turns a go-back took back (the turn's number in its slot); `ai_spec` holds the newest turn
# no go-back can take back.
AI_SPEC_RING = 1024
# A speculating run's AI journal: the decisions since the newest state that no go-back can take
# back, which may be as many turns behind the newest as the physics keeps in flight: a ring's worth.
AI_SPEC_JOURNAL = AI_SPEC_RING + 2 * AI_KEEP_EVERY


def net_state_dtype(n_knots: int) -> np.dtype:
    """A slot of a speculating run's `net_states` ring: the net's state after run `run` (written
    before the run is counted answered), the physics' go-backs counted when it was answered
    (epoch) and whether the net touched the ball in it (then the net halted there until the
    epoch moved)."""
    return np.dtype([("run", "<i8"), ("epoch", "<i8"), ("touched", "<i8"), ("state", net_snapshot_dtype(n_knots))])

def _net_word(name: str) -> int:
    return NET_IO_DTYPE.fields[name][1] // 8  # every field of NET_IO_DTYPE is made of 8-byte words


def _net_int(name: str) -> property:
    k = _net_word(name)
    return property(lambda self: self._ints[k], lambda self, value: self._ints.__setitem__(k, int(value)), doc=name)


def _net_float(name: str) -> property:
    k = _net_word(name)
    return property(lambda self: self._floats[k], lambda self, value: self._floats.__setitem__(k, float(value)),
                    doc=name)


class NetIO:
    """The (1,) NET_IO_DTYPE record with each field bound once: its scalars as properties over
    its 8-byte words (memoryviews: Python ints and floats, no numpy scalars), its vectors as views.

    A ball tick reads and writes a dozen fields on each side; a numpy record's field lookup
    costs about a microsecond, these a tenth of that. Each word is one 8-byte store, as the
    record's own (the turn protocol in processes.workers.net relies on their order alone).
    """

    tick = _net_int("tick")
    count = _net_int("count")
    taken = _net_int("taken")
    radius = _net_float("radius")
    inv_mass = _net_float("inv_mass")
    toi = _net_float("toi")
    sleeping = _net_int("sleeping")
    tail_until = _net_int("tail_until")
    bounded = _net_int("bounded")
    granted = _net_int("granted")
    turn = _net_int("turn")
    served = _net_int("served")

    def __init__(self, array: np.ndarray):
        self.array = array
        self._ints = memoryview(array.view("<i8")).cast("B").cast("q")
        self._floats = memoryview(array.view("<f8")).cast("B").cast("d")
        record = array[0]
        self.ball = record["ball"]  # (NET_RUN_TICKS, 2, 3) m, m/s; the others (3,) and (2, 3), all views
        self.impulse = record["impulse"]
        self.offset = record["offset"]
        self.box = record["box"]
        self.bound = record["bound"]

    def close(self) -> None:
        """Drop every view of the shared record (before its segment is closed)."""
        self._ints.release()
        self._floats.release()
        del self.array, self.ball, self.impulse, self.offset, self.box, self.bound

# One remote input on its way to the physics worker (the remote-input mailbox's record).
REMOTE_INPUT_DTYPE = np.dtype([("tick", "<i8"), ("seq", "<u8"), ("bat", "<i8"), ("inputs", "<f8", (6,))])
REMOTE_CAPACITY = 64  # inputs queued between two physics ticks; more are dropped and counted
# The acknowledged input seq per bat at each published tick, written by the physics worker just
# before it publishes that tick's snapshot, in a ring indexed by tick: the gateway pairs a
# snapshot of tick T with the entry of tick T, so snapshot.input_seq names exactly the inputs
# whose effect the snapshot shows (the last input applied before the step T-1 -> T).
REMOTE_ACK_DTYPE = np.dtype([("tick", "<i8"), ("input_seq", "<u8", (2,))])
REMOTE_ACK_RING = 1024  # ticks (1 s at 1 kHz): a reader this late gets None, never a wrong pair
# Every arbitrated lock of a run, in the one global order of acquisition.
RUN_LOCK_NAMES = ("remote_inputs",)


def ai_ring_size(compiled: CompiledScene, speculate: bool = False) -> int:
    """Slots of the AI's rings of views and answers: a turn's slot is taken again only after its
    plans took effect (the physics waits for that), and one turn a control tick is given, so the
    turns of one decision delay, the one being given and one whose slot a killed physics may have
    been writing fit.""" 
    return AI_SPEC_RING if speculate else compiled.decision_delay // compiled.control_period + 3


def write_ack(ring: np.ndarray, tick: int, input_seq) -> None:
    """Physics side: the acknowledged seqs of tick `tick`, written before that tick is published.

    ring: (REMOTE_ACK_RING,) REMOTE_ACK_DTYPE in shared memory. The entry's tick is made invalid
    (-1) while its seqs change and set last, so a reader never pairs a tick with a torn entry
    (stores stay in order on x86-64, as processes/runtime/shm.py relies on too).
    """
    i = tick % len(ring)
    ring["tick"][i] = -1
    ring["input_seq"][i] = input_seq
    ring["tick"][i] = tick


def read_ack(ring: np.ndarray, tick: int) -> tuple[int, int] | None:
    """Gateway side: the acknowledged seqs (bat A, bat B) of tick `tick`, or None if the ring no
    longer (or not yet) holds that tick."""
    i = tick % len(ring)
    before = int(ring["tick"][i])
    seqs = ring["input_seq"][i].copy()
    after = int(ring["tick"][i])
    if before != tick or after != tick:
        return None
    return int(seqs[0]), int(seqs[1])


@dataclass
class RunLayout:
    """A run's shared memory and the synchronisation objects its workers are handed.

    arena: every block of the table above that the run's workers need. ai_queue: the AI's turns
    (None without an AI worker); net_baton: the net's turns' baton (None without a net worker). lock_path: the lock table's file (a run with a
    gateway, else None). start_event: set while every remote seat is held (a run with a gateway).
    """

    arena: Arena
    ai_queue: TurnQueue | None = None
    net_baton: Baton | None = None
    lock_path: str | None = None
    start_event: Event | None = None
    net_queue: TurnQueue | None = None
    _lock_dir: str | None = None

    def stop_turns(self) -> None:
        """Stop the turns: a worker waiting for its turn exits at once."""
        for turns in (self.ai_queue, self.net_baton, self.net_queue):
            if turns is not None:
                turns.stop()

    def close(self) -> None:
        """Remove every segment and the lock table's file (after the workers are gone)."""
        self.arena.close()
        if self._lock_dir is not None:
            shutil.rmtree(self._lock_dir, ignore_errors=True)


def build_layout(compiled: CompiledScene, kinds: list[str], ticks: int, trace: bool, frame_every: int, ctx,
                 speculate: bool = False, spin_s: float = SPIN_S) -> RunLayout:
    """Create the run's blocks for the workers `kinds` (processes.workers.workers_for).

    Args:
        compiled: the run's scene (engine.physics.compiled). kinds: the run's workers. ticks: the run's length (sizes trace and frames).
        trace: keep every tick's snapshot. frame_every: a replay frame every this many ticks, 0: none.
        ctx: the multiprocessing context the workers start from (batons and events belong to it).
        speculate: the blocks of a speculating run (RunOptions.speculate) too.
        spin_s: how long a side of the run's hand-offs polls before it sleeps (Baton, TurnQueue).
    """
    arena = Arena()
    scene = compiled.scene
    snapshot = physics_snapshot_dtype(len(scene.bats))
    layout = RunLayout(arena)
    try:
        arena.snapshot_block("physics", snapshot, 1)
        arena.shared_array("events", CONTACT_DTYPE, EVENT_LOG_CAPACITY)
        arena.shared_array("status", STATUS_DTYPE, len(kinds))
        if trace:
            arena.shared_array("trace", snapshot, ticks + 1)
        if scene.match is not None:
            arena.shared_array("points", POINT_DTYPE, POINT_LOG_CAPACITY)
            if speculate:
                arena.shared_array("spec_cut", CUT_DTYPE, CUT_ROWS).array["tick"] = -1
            if frame_every:
                arena.shared_array("frames", snapshot, ticks // frame_every + 1)
        if "net" in kinds:
            n_knots = compiled.topology.n_knots
            for name in NET_BLOCKS:
                arena.snapshot_block(name, net_snapshot_dtype(n_knots), 1)
            if "gateway" in kinds:
                arena.snapshot_block(NET_SHOW, net_show_dtype(n_knots), 1)
            arena.shared_array("net_io", NET_IO_DTYPE, 1)
            layout.net_baton = Baton("net", ctx, arena.shared_array("net_baton", TICK_SLOT_DTYPE, 1).array, spin_s)
            if speculate:
                arena.shared_array("net_runs", SPEC_RUN_DTYPE, SPEC_RUNS)
                arena.shared_array("net_answers", SPEC_ANSWER_DTYPE, SPEC_RUNS).array["run"] = -1
                arena.shared_array("net_spec", np.int64, SPEC_WORDS).array[SPEC_BACK] = -1
                arena.shared_array("net_states", net_state_dtype(n_knots), NET_STATES).array["run"] = -1
                layout.net_queue = TurnQueue("net", ctx, arena.shared_array("net_queue", np.int64, QUEUE_WORDS).array,
                                             spin_s)
        if "ai" in kinds:
            # The views and the answers are ordered by the queue's counts (a slot is written before
            # the count that covers it moves, and x86-64 keeps stores in order), so neither needs a
            # seqlock or a lock. Turn and tick -1: none yet.
            ring = ai_ring_size(compiled, speculate)
            if speculate:
                arena.shared_array("ai_void", np.int64, ring).array[:] = -1
                arena.shared_array("ai_spec", np.int64, 1)
            arena.shared_array("ai_views", snapshot, ring)
            answers = arena.shared_array("ai_answers", ANSWER_DTYPE, ring).array
            answers["turn"], answers["tick"] = -1, -1
            journal = AI_SPEC_JOURNAL if speculate else AI_JOURNAL_TURNS
            arena.shared_array("ai_journal", snapshot, journal)
            arena.shared_array("ai_journal_turns", np.int64, (journal, 3)).array[:, 0] = -1  # (turn, tick, decision)
            arena.snapshot_block("ai_state", AI_STATE_DTYPE, 1)
            layout.ai_queue = TurnQueue("ai", ctx, arena.shared_array("ai_queue", np.int64, QUEUE_WORDS).array, spin_s)
        if "gateway" in kinds:
            layout._lock_dir = tempfile.mkdtemp(prefix=f"pingpong-{arena.run_id}-")
            layout.lock_path = str(Path(layout._lock_dir) / "locks")
            holders = arena.shared_array("lock_holders", HOLDER_DTYPE, len(RUN_LOCK_NAMES))
            LockTable.create(layout.lock_path, RUN_LOCK_NAMES, holders).close()
            arena.shared_array("remote_header", MAILBOX_HEADER, 1)
            arena.shared_array("remote_inputs", REMOTE_INPUT_DTYPE, REMOTE_CAPACITY)
            arena.shared_array("remote_applied", np.dtype("<u8"), 2)  # seq of the last input applied per bat
            arena.shared_array("remote_acks", REMOTE_ACK_DTYPE, REMOTE_ACK_RING)  # those seqs by published tick
            arena.snapshot_block("seats", SEAT_DTYPE, 2)  # the seat table, so a restarted gateway keeps its tokens
            layout.start_event = ctx.Event()
    except BaseException:
        layout.stop_turns()
        layout.close()
        raise
    return layout
