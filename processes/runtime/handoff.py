"""Lockstep hand-offs: the hub worker (physics) gives another worker its turn and waits,
bounded, until that worker is done (a Baton: the net's runs), or posts turns in order and waits
only for the answer it needs (a TurnQueue: the AI's control ticks).

A Baton is a pair of POSIX semaphores (futex-backed, so a waiting worker sleeps in the kernel
and costs no CPU) plus a shared tick slot; the data itself crosses through shared records that
the turns order (the net's net_io, the AI's rings of views and answers) and SnapshotBlocks,
never through the semaphores, so nothing is pickled per tick. The hub gives turns in the same
order whatever the timing, which keeps lockstep deterministic.

Both sides spin briefly (SPIN_S) before they sleep, and a sleeping worker says so in a shared
word: the hub posts a wake-up only to a sleeper (glibc's sem_post enters the kernel only to
wake one), so when the other side is at work or answers within the spin nobody enters the
kernel: no wake-up, and above all no wake-up preemption, where the woken worker takes the CPU
from the one that woke it. Where the computing workers outnumber the cores, a spinning side
holds a core another worker needs, so such a run's channels do not spin (spin_s 0).
`pingpong bench handoff` measures a hand-off against a plain semaphore ping-pong.
"""
from __future__ import annotations

import time

import numpy as np


class HandoffTimeout(TimeoutError):
    """A worker did not take or finish its turn within the bound."""


TICK_SLOT_DTYPE = np.dtype([("tick", "<i8"), ("command", "<i8"), ("done_tick", "<i8"), ("asleep", "<i8")])
RUN, STOP = 1, 2
NO_TURN = -1  # wait_turn: no turn given, work pending (ticks are >= 0)
# How long a side polls before it sleeps: about one AI turn or ten physics ticks, so a turn
# answered in that time costs no system call; a longer wait sleeps and costs no CPU.
SPIN_S = 100e-6
# A sleeping worker that tells the hub so (Baton.wait_turn with pending, TurnQueue.wait_posted)
# looks again at least this often: the bound on a wake-up lost between its flag and the hub's
# shared state, whose stores cross on no barrier.
NAP_S = 5e-3


def _acquire(semaphore, timeout: float, spin_s: float) -> bool:
    """Take the semaphore: spin up to spin_s, then sleep up to the rest of `timeout`."""
    if semaphore.acquire(False):
        return True
    clock = time.perf_counter
    start = clock()
    while clock() - start < spin_s:
        if semaphore.acquire(False):
            return True
    return semaphore.acquire(timeout=max(timeout - spin_s, 0.0))


class Baton:
    """One hub <-> worker hand-off channel.

    Args:
        name: for messages. ctx: the multiprocessing context the workers are started from.
        slot: a (1,) TICK_SLOT_DTYPE shared array (processes.runtime.shm.SharedArray.array).
        spin_s: how long a side polls before it sleeps (SPIN_S; 0: at once).
    """

    def __init__(self, name: str, ctx, slot: np.ndarray, spin_s: float = SPIN_S):
        self.name = name
        self.spin_s = spin_s
        self._go = ctx.Semaphore(0)
        self._done = ctx.Semaphore(0)
        self.attach(slot)

    def __getstate__(self):
        # The shared slot is re-attached by the worker from the arena; semaphores pickle by handle.
        return {"name": self.name, "spin_s": self.spin_s, "_go": self._go, "_done": self._done, "_words": None}

    def attach(self, slot: np.ndarray) -> "Baton":
        """Point at the shared (1,) TICK_SLOT_DTYPE slot: words 0 tick, 1 command, 2 tick done,
        3 the worker sleeps (1) or not (0)."""
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
            if left <= 0 or not _acquire(self._done, left, self.spin_s):
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
        """Wake the worker without a turn, if it sleeps: it rereads the shared state it works from.

        A worker at work or spinning rereads that state before it sleeps (wait_turn's `pending`),
        so only a sleeper is posted: a post to a sleeper costs the hub a system call and often
        its core, which the woken worker takes.
        """
        words = self._words
        if words[3]:
            words[3] = 0
            self._go.release()

    def stop(self) -> None:
        self._words[1] = STOP
        self._go.release()

    # worker side
    @property
    def stopped(self) -> bool:
        """Told to stop: also seen by a worker restarted after the stop's wake-up went to the one it replaces."""
        return self._words[1] == STOP

    def wait_turn(self, timeout: float, pending=None) -> int | None:
        """The tick to do, None when told to stop, NO_TURN when pending() says there is work
        without a turn (the worker's own test of the shared state a nudge would point it to);
        raises HandoffTimeout after `timeout` s.

        Spins spin_s, then says it sleeps and sleeps NAP_S at a time, looking at
        pending() between naps: the flag and the hub's shared state cross on no barrier, so a
        nudge may be missed, for a nap at most.
        """
        if self._go.acquire(False):
            return self._turn()
        words = self._words
        clock = time.perf_counter
        started = clock()
        while True:
            if pending is not None and pending():
                return NO_TURN
            elapsed = clock() - started
            if elapsed < self.spin_s:
                if self._go.acquire(False):
                    return self._turn()
                continue
            if elapsed > timeout:
                raise HandoffTimeout(f"{self.name}: no turn given within {timeout} s")
            words[3] = 1
            woken = pending is None or not pending()
            woken = woken and self._go.acquire(timeout=min(NAP_S if pending is not None else timeout,
                                                           max(timeout - elapsed, 0.0)))
            words[3] = 0
            if woken:
                return self._turn()

    def _turn(self) -> int | None:
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


def _nothing_else() -> bool:
    """TurnQueue.wait_work's `pending` for a worker that has no work beside its turns."""
    return False


QUEUE_WORDS = 4  # a TurnQueue's shared words: turns posted, turns answered, command (RUN or STOP), worker asleep


class TurnQueue:
    """Turns in order, from a hub to one worker that answers each in turn: the hub posts turn 1,
    2, ... without waiting and waits (bounded) only for the answer it needs, so the worker may
    work several turns behind; the turns' data cross through shared rings indexed by the turn's
    number, which the counts order (processes.workers.ai_driver).

    Args:
        name: for messages. ctx: the multiprocessing context the workers are started from.
        words: a (QUEUE_WORDS,) int64 shared array (processes.runtime.shm.SharedArray.array).
        spin_s: how long a side polls before it sleeps (SPIN_S; 0: at once).

    A side sleeps on the other's semaphore only when the count it waits for has not moved,
    watching the count for spin_s first. The worker says in a shared word that it sleeps, and
    the hub posts the semaphore only then: a post to a sleeper costs the hub a system call and
    often its core (the woken worker takes it), and a worker at work or spinning sees the count
    move without one. The flag and the count cross on no barrier, so a sleeping worker naps
    NAP_S at a time and looks at the count between naps; a hub about to wait for an answer
    wakes a sleeper first. A side that finds its count moved does not take the post, which a
    later wait then takes and finds nothing new behind. The counts live in shared memory, so a
    restarted worker, or hub, goes on from them.
    """

    def __init__(self, name: str, ctx, words: np.ndarray, spin_s: float = SPIN_S):
        self.name = name
        self.spin_s = spin_s
        self._posted = ctx.Semaphore(0)
        self._answered = ctx.Semaphore(0)
        self.attach(words)

    def __getstate__(self):
        return {"name": self.name, "spin_s": self.spin_s, "_posted": self._posted, "_answered": self._answered,
                "_words": None}

    def attach(self, words: np.ndarray) -> "TurnQueue":
        """Point at the shared (QUEUE_WORDS,) int64 words: 0 turns posted, 1 answered, 2 command,
        3 the worker sleeps (1) or not (0)."""
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
        """Post the next turn (its data already written), waking the worker if it sleeps; returns its number."""
        words = self._words
        words[0] += 1
        if words[3]:
            words[3] = 0
            self._posted.release()
        return words[0]

    def wait_answered(self, turn: int, timeout: float, give_up: float, on_wait) -> None:
        """Wait until turn `turn` is answered. Every `timeout` s without an answer: on_wait(turn)
        (a heartbeat: the worker may be restarting, and goes on from the counts); raises
        HandoffTimeout after `give_up` s."""
        words = self._words
        self.wait_for(lambda: words[1] >= turn, f"turn {turn} was not answered", timeout, give_up,
                      lambda: on_wait(turn))

    def wait_for(self, ready, what: str, timeout: float, give_up: float, on_wait) -> None:
        """Wait until ready(), which the worker makes true before it counts an answer (the count's
        post wakes this wait), waking a sleeping worker first. Every `timeout` s without it:
        on_wait(); raises HandoffTimeout saying `what` after `give_up` s."""
        words = self._words
        if not ready() and words[3]:
            words[3] = 0
            self._posted.release()
        deadline = time.monotonic() + give_up
        while not ready():
            if not _acquire(self._answered, timeout, self.spin_s):
                on_wait()
                if time.monotonic() > deadline:
                    raise HandoffTimeout(f"{self.name}: {what} within {give_up} s (answered {words[1]} of "
                                         f"{words[0]})")

    def nudge(self) -> None:
        """Wake the worker without a turn, if it sleeps: it rereads the shared state beside the
        queue it works from (a speculating net's grants, processes.workers.net)."""
        words = self._words
        if words[3]:
            words[3] = 0
            self._posted.release()

    def rewind(self, turns: int) -> None:
        """Take back the turns posted after turn `turns`: the next post is turn `turns` + 1 again.
        Only for a worker that will not take a turn past `turns` until the hub tells it otherwise
        (a speculating net halted at a touch, processes.workers.net)."""
        if not self._words[1] <= turns <= self._words[0]:
            raise ValueError(f"{self.name}: cannot rewind to turn {turns} (answered {self._words[1]}, "
                             f"posted {self._words[0]})")
        self._words[0] = turns

    def withdraw(self, turns: int) -> None:
        """Take back every turn posted after turn `turns`, answered or not: a restarted hub sends
        its worker back to turn `turns`, and the worker, taking no turn past it from now on,
        counts its answers back to it itself (answer(turns)); the next post is turn `turns` + 1."""
        if not 0 <= turns <= self._words[0]:
            raise ValueError(f"{self.name}: cannot withdraw to turn {turns} (posted {self._words[0]})")
        self._words[0] = turns

    def stop(self) -> None:
        self._words[2] = STOP
        self._posted.release()

    # worker side
    @property
    def stopped(self) -> bool:
        """Told to stop (also seen by a worker restarted after the stop's post)."""
        return self._words[2] == STOP

    def wait_work(self, after: int, timeout: float, pending) -> bool:
        """wait_posted, also ending when pending() says there is work beside the turns (a nudge
        points to it); False after `timeout` s without either."""
        words = self._words
        clock = time.perf_counter
        started = clock()
        while words[0] <= after and words[2] != STOP and not pending():
            now = clock()
            if now - started < self.spin_s:
                continue
            if now - started > timeout:
                return False
            words[3] = 1
            if words[0] <= after and words[2] != STOP and not pending():
                self._posted.acquire(timeout=NAP_S)
            words[3] = 0
        return True

    def wait_posted(self, after: int, timeout: float) -> bool:
        """Wait until a turn after `after` is posted, or a stop; False after `timeout` s without either."""
        return self.wait_work(after, timeout, _nothing_else)

    def answer(self, turn: int) -> None:
        """Turn `turn` is answered (its answer already written)."""
        self._words[1] = turn
        self._answered.release()

    def wake_hub(self) -> None:
        """Wake a hub waiting (wait_for) on shared state beside the counts, just changed."""
        self._answered.release()
