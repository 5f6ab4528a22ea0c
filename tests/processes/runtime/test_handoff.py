"""Lockstep hand-offs: bounded in both directions; `pingpong bench handoff` smoke run."""
import json
import subprocess
import sys

import numpy as np
import pytest

from processes.runtime.handoff import TICK_SLOT_DTYPE, Baton, HandoffTimeout
from processes.runtime.shm import Arena
from tests.waits import DEADLINE_S


def _take_turns(layout, baton, n):
    arena = Arena.attach(layout)
    baton.attach(arena["slot"].array)
    for _ in range(n):
        tick = baton.wait_turn(10)
        if tick is None:
            break
        arena["seen"].array[tick] = tick * 10
        baton.done(tick)
    del baton
    arena.close()


def test_baton_hands_each_tick_over_in_order(ctx, procs, no_leftovers):
    arena = Arena()
    try:
        slot = arena.shared_array("slot", TICK_SLOT_DTYPE, 1).array
        seen = arena.shared_array("seen", np.dtype("<i8"), 50).array
        baton = Baton("test", ctx, slot)
        worker = ctx.Process(target=_take_turns, args=(arena.layout(), baton, 100))
        procs.append(worker)
        worker.start()
        for tick in range(50):
            baton.call(tick, timeout=DEADLINE_S)
            assert seen[tick] == tick * 10  # the worker's write is visible when call returns
        baton.stop()
        worker.join(DEADLINE_S)
        assert worker.exitcode == 0
        del slot, seen, baton
    finally:
        arena.close()


def test_call_to_a_worker_that_never_answers_times_out(ctx, no_leftovers):
    arena = Arena()
    try:
        baton = Baton("silent", ctx, arena.shared_array("slot", TICK_SLOT_DTYPE, 1).array)
        with pytest.raises(HandoffTimeout, match="silent: worker did not finish tick 3 within 0.2 s"):
            baton.call(3, timeout=0.2)
        with pytest.raises(HandoffTimeout, match="no turn given within 0.1 s"):
            Baton("idle", ctx, arena.shared_array("slot2", TICK_SLOT_DTYPE, 1).array).wait_turn(0.1)
        del baton
    finally:
        arena.close()


def test_bench_handoff_quick_json():
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "handoff", "--quick", "--json"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert set(report["us_per_round_trip"]) == {"semaphore", "shm_spin", "queue", "lockstep_handoff"}
    assert all(v > 0 for v in report["us_per_round_trip"].values())
