"""Lockstep hand-offs: the hub worker (physics) gives another worker its turn for a tick and
waits, bounded, until that worker is done.

A Baton is a pair of POSIX semaphores (futex-backed, so a waiting worker sleeps in the kernel
and costs no CPU) plus a shared tick slot; the data itself crosses through shared records that
the turn orders (the AI's view and answer, the net's net_io) and SnapshotBlocks, never through
the baton, so nothing is pickled per tick. The hub calls only the workers a tick needs (a
sleeping net, an AI control tick that needs no decision, the ball in free flight wake nobody),
always in the same order, which keeps lockstep deterministic.

Both sides spin briefly (SPIN_S, polling the semaphore without blocking) before they sleep.
glibc's sem_post makes the futex wake-up call only when a waiter is asleep, so when the other
side answers within the spin nobody enters the kernel: no wake-up, and above all no wake-up
preemption, where the woken worker takes the CPU from the one that woke it. `pingpong bench
handoff` measures a hand-off against a plain semaphore ping-pong.
"""
from __future__ import annotations

import time

import numpy as np


class HandoffTimeout(TimeoutError):
    """A worker did not take or finish its turn within the bound."""


TICK_SLOT_DTYPE = np.dtype([("tick", "<i8"), ("command", "<i8"), ("done_tick", "<i8")])
RUN, STOP = 1, 2
NO_TURN = -1  # try_turn: no turn given (ticks are >= 0)
# How long a side polls before it sleeps: about one AI turn or ten physics ticks, so a turn
# answered in that time costs no system call; a longer wait sleeps and costs no CPU.
SPIN_S = 100e-6


def _acquire(semaphore, timeout: float) -> bool:
    """Take the semaphore: spin up to SPIN_S, then sleep up to the rest of `timeout`."""
    if semaphore.acquire(False):
        return True
    clock = time.perf_counter
    start = clock()
    while clock() - start < SPIN_S:
        if semaphore.acquire(False):
            return True
    return semaphore.acquire(timeout=max(timeout - SPIN_S, 0.0))


class Baton:
    """One hub <-> worker hand-off channel.

    Args:
        name: for messages. ctx: the multiprocessing context the workers are started from.
        slot: a (1,) TICK_SLOT_DTYPE shared array (processes.runtime.shm.SharedArray.array).
    """

    def __init__(self, name: str, ctx, slot: np.ndarray):
        self.name = name
        self._go = ctx.Semaphore(0)
        self._done = ctx.Semaphore(0)
        self.attach(slot)

    def __getstate__(self):
        # The shared slot is re-attached by the worker from the arena; semaphores pickle by handle.
        return {"name": self.name, "_go": self._go, "_done": self._done, "_words": None}

    def attach(self, slot: np.ndarray) -> "Baton":
        """Point at the shared (1,) TICK_SLOT_DTYPE slot: words 0 tick, 1 command, 2 tick done."""
        self._words = memoryview(slot.view("<i8")).cast("B").cast("q")
        return self

    # hub side
    def call(self, tick: int, timeout: float) -> None:
        """Give the worker its turn for `tick` and wait until it is done with that tick."""
        self.give(tick)
        self.wait_done(tick, timeout)

    def give(self, tick: int) -> None:
        """Give the worker its turn for `tick` and return at once (the hub works on meanwhile)."""
        words = self._words
        words[0] = tick
        words[1] = RUN
        self._go.release()

    def wait_done(self, tick: int, timeout: float) -> None:
        """Wait until the worker is done with `tick`; raises HandoffTimeout after `timeout` s.

        A 'done' for another tick (a late answer to a turn that had timed out) is skipped.
        """
        words = self._words
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not _acquire(self._done, left):
                raise HandoffTimeout(f"{self.name}: worker did not finish tick {tick} within {timeout} s")
            if words[2] == tick:
                return

    def wait_done_or_retry(self, tick: int, timeout: float, give_up: float, on_wait) -> None:
        """wait_done, and while the worker may be restarting, give it the turn again.

        Every `timeout` s without an answer: on_wait(tick) (a heartbeat), then the turn is given
        again (its inputs are still in place, and the worker answers a repeated turn as the
        first); raises HandoffTimeout after `give_up` s.
        """
        deadline = time.monotonic() + give_up
        while True:
            try:
                self.wait_done(tick, timeout)
                return
            except HandoffTimeout:
                on_wait(tick)
                if time.monotonic() > deadline:
                    raise
                self.give(tick)

    def nudge(self) -> None:
        """Wake the worker without a turn: it rereads the shared state it works from."""
        self._go.release()

    def stop(self) -> None:
        self._words[1] = STOP
        self._go.release()

    # worker side
    @property
    def stopped(self) -> bool:
        """Told to stop: also seen by a worker restarted after the stop's wake-up went to the one it replaces."""
        return self._words[1] == STOP

    def wait_turn(self, timeout: float) -> int | None:
        """The tick to do, None when told to stop; raises HandoffTimeout after `timeout` s."""
        if not _acquire(self._go, timeout):
            raise HandoffTimeout(f"{self.name}: no turn given within {timeout} s")
        if self._words[1] == STOP:
            return None
        return self._words[0]

    def try_turn(self) -> int | None:
        """wait_turn without waiting: the tick to do, None when told to stop, NO_TURN when no
        turn was given (a worker with work of its own polls between its pieces of work)."""
        if not self._go.acquire(False):
            return NO_TURN
        if self._words[1] == STOP:
            return None
        return self._words[0]

    def done(self, tick: int) -> None:
        """Say the turn for `tick` is done: the tick the worker answered, not the slot's latest
        (a turn given again while the worker was busy with it leaves a second wake-up behind,
        and the hub may have given the next tick by the time that one is answered; marking the
        answer with the slot's tick would pass the old answer off as the new one's)."""
        self._words[2] = tick
        self._done.release()


QUEUE_WORDS = 3  # a TurnQueue's shared words: turns posted, turns answered, command (RUN or STOP)


class TurnQueue:
    """Turns in order, from a hub to one worker that answers each in turn: the hub posts turn 1,
    2, ... without waiting and waits (bounded) only for the answer it needs, so the worker may
    work several turns behind; the turns' data cross through shared rings indexed by the turn's
    number, which the counts order (processes.workers.ai_driver).

    Args:
        name: for messages. ctx: the multiprocessing context the workers are started from.
        words: a (QUEUE_WORDS,) int64 shared array (processes.runtime.shm.SharedArray.array).

    A side sleeps on the other's semaphore only when the count it waits for has not moved,
    spinning SPIN_S first as a Baton does (a worker whose turns come every few tens of
    microseconds then never sleeps, and a post to it costs the hub no system call: glibc's
    sem_post enters the kernel only to wake a sleeper); a side that finds its count moved does
    not take the post, which a later wait then takes and finds nothing new behind. The counts
    live in shared memory, so a restarted worker, or hub, goes on from them.
    """

    def __init__(self, name: str, ctx, words: np.ndarray):
        self.name = name
        self._posted = ctx.Semaphore(0)
        self._answered = ctx.Semaphore(0)
        self.attach(words)

    def __getstate__(self):
        return {"name": self.name, "_posted": self._posted, "_answered": self._answered, "_words": None}

    def attach(self, words: np.ndarray) -> "TurnQueue":
        """Point at the shared (QUEUE_WORDS,) int64 words: 0 turns posted, 1 answered, 2 command."""
        self._words = memoryview(words.view("<i8")).cast("B").cast("q")
        return self

    @property
    def posted(self) -> int:
        """Turns posted so far (the newest turn's number)."""
        return self._words[0]

    @property
    def answered(self) -> int:
        """Turns answered so far (the newest answer's turn)."""
        return self._words[1]

    # hub side
    def post(self) -> int:
        """Post the next turn (its data already written); returns its number."""
        words = self._words
        words[0] += 1
        self._posted.release()
        return words[0]

    def wait_answered(self, turn: int, timeout: float, give_up: float, on_wait) -> None:
        """Wait until turn `turn` is answered. Every `timeout` s without an answer: on_wait(turn)
        (a heartbeat: the worker may be restarting, and goes on from the counts); raises
        HandoffTimeout after `give_up` s."""
        words = self._words
        deadline = time.monotonic() + give_up
        while words[1] < turn:
            if not _acquire(self._answered, timeout):
                on_wait(turn)
                if time.monotonic() > deadline:
                    raise HandoffTimeout(f"{self.name}: turn {turn} was not answered within {give_up} s "
                                         f"(answered {words[1]} of {words[0]})")

    def stop(self) -> None:
        self._words[2] = STOP
        self._posted.release()

    # worker side
    @property
    def stopped(self) -> bool:
        """Told to stop (also seen by a worker restarted after the stop's post)."""
        return self._words[2] == STOP

    def wait_posted(self, after: int, timeout: float) -> bool:
        """Wait until a turn after `after` is posted, or a stop; False after `timeout` s without either."""
        words = self._words
        while words[0] <= after and words[2] != STOP:
            if not _acquire(self._posted, timeout):
                return False
        return True

    def answer(self, turn: int) -> None:
        """Turn `turn` is answered (its answer already written)."""
        self._words[1] = turn
        self._answered.release()
