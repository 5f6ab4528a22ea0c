"""Lock arbitration: bounded waits naming the holder, global order, recovery from dead holders."""
import os
import signal

import numpy as np
import pytest

from processes.runtime.locks import HOLDER_DTYPE, LockOrderError, LockTable, LockTimeout
from processes.runtime.mailbox import MAILBOX_HEADER, Mailbox
from processes.runtime.shm import Arena
from tests.waits import DEADLINE_S

NAMES = ("net_impulses", "bat_inputs")


@pytest.fixture
def table(tmp_path, no_leftovers):
    arena = Arena()
    holders = arena.shared_array("holders", HOLDER_DTYPE, len(NAMES))
    path = str(tmp_path / "locks")
    locks = LockTable.create(path, NAMES, holders)
    yield locks, arena, path
    locks.close()
    arena.close()


def _hold_forever(path, layout, name, held, never):
    """A worker that takes a lock and never releases it (blocked on an event nobody sets)."""
    arena = Arena.attach(layout)
    locks = LockTable(path, NAMES, arena["holders"])
    locks.acquire(name, timeout=DEADLINE_S)
    held.set()
    never.wait()  # bounded by the test, which kills this process


def _take_and_die(path, layout, name, dirty_mailbox):
    arena = Arena.attach(layout)
    locks = LockTable(path, NAMES, arena["holders"])
    locks.acquire(name, timeout=DEADLINE_S)
    if dirty_mailbox:
        arena["inbox_header"].array["dirty"][0] = 1  # died in the middle of a post
        arena["inbox_header"].array["count"][0] = 1
    os._exit(0)  # dies holding the lock


def test_lock_never_released_is_detected_reported_and_recovered(table, ctx, procs):
    locks, arena, path = table
    held, never = ctx.Event(), ctx.Event()
    stuck = ctx.Process(target=_hold_forever, args=(path, arena.layout(), "bat_inputs", held, never))
    procs.append(stuck)
    stuck.start()
    assert held.wait(DEADLINE_S)
    # Detected within its bound, and the report names the lock and the holder's pid.
    with pytest.raises(LockTimeout, match=rf"lock 'bat_inputs' not acquired within 0.3 s: held by pid {stuck.pid} \(alive\)"):
        locks.acquire("bat_inputs", timeout=0.3)
    # Recovered: the supervisor's remedy is to kill the stuck holder; the kernel drops its lock.
    pid, _ = locks.holder("bat_inputs")
    os.kill(pid, signal.SIGKILL)
    stuck.join(DEADLINE_S)
    got = locks.acquire("bat_inputs", timeout=DEADLINE_S)
    assert got.recovered_from == stuck.pid
    locks.release("bat_inputs")
    assert locks.stats("bat_inputs")["recovered"] == 1


def test_dead_holder_never_hangs_the_next(table, ctx, procs):
    locks, arena, path = table
    dier = ctx.Process(target=_take_and_die, args=(path, arena.layout(), "net_impulses", False))
    procs.append(dier)
    dier.start()
    dier.join(DEADLINE_S)
    got = locks.acquire("net_impulses", timeout=DEADLINE_S)
    assert got.recovered_from == dier.pid
    locks.release("net_impulses")
    got = locks.acquire("net_impulses", timeout=DEADLINE_S)
    assert got.recovered_from == 0  # released cleanly this time
    locks.release("net_impulses")


def test_global_order_is_enforced(table):
    locks, _, _ = table
    with locks.hold("net_impulses", 1):
        with locks.hold("bat_inputs", 1):
            pass
    with locks.hold("bat_inputs", 1):
        with pytest.raises(LockOrderError, match="global order is net_impulses < bat_inputs"):
            locks.acquire("net_impulses", 1)


RECORD = np.dtype([("tick", "<i8"), ("force", "<f8", (3,))])


def test_mailbox_posts_drains_and_counts_overflow(table):
    locks, arena, _ = table
    header = arena.shared_array("inbox_header", MAILBOX_HEADER, 1)
    body = arena.shared_array("inbox", RECORD, 4)
    box = Mailbox("bat_inputs", header, body, locks)
    for tick in range(6):
        box.post(np.array((tick, (1.0, 2.0, 3.0)), RECORD))
    out = np.zeros(4, RECORD)
    assert box.drain(out) == 4
    assert out["tick"].tolist() == [0, 1, 2, 3]
    assert box.stats() == {"pending": 0, "dropped_full": 2, "discarded_torn": 0}


def test_mailbox_discards_what_a_dying_sender_half_wrote(table, ctx, procs):
    locks, arena, path = table
    header = arena.shared_array("inbox_header", MAILBOX_HEADER, 1)
    body = arena.shared_array("inbox", RECORD, 4)
    box = Mailbox("bat_inputs", header, body, locks)
    dier = ctx.Process(target=_take_and_die, args=(path, arena.layout(), "bat_inputs", True))
    procs.append(dier)
    dier.start()
    dier.join(DEADLINE_S)
    assert box.drain(np.zeros(4, RECORD)) == 0  # the torn record is not acted on
    assert box.stats()["discarded_torn"] == 1
