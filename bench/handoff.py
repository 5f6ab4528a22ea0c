"""`pingpong bench handoff`: what one lockstep hand-off costs, against raw baselines, same run.

Each method does N round trips between this process and one child:
- semaphore ping-pong: the bare kernel wake-up both ways (the floor for sleeping waits);
- shared-memory spin ping-pong: both sides spin on a shared counter (no kernel, burns a core
  each; on 2 shared cores it is at the mercy of the scheduler);
- multiprocessing.Queue round trip (pickling and a feeder thread);
- lockstep hand-off: a turn the physics gives and waits for (the net's, processes.workers.remote_net,
  through a Baton): copy the state into a shared view record, give the baton and wait until the
  turn is done; the worker copies the view, writes an answer record (an AI's, ANSWER_DTYPE) and
  hands back, and the hub reads the answer. The baton orders the two sides, so no lock is
  taken. (The AI's turns are queued instead, processes.runtime.handoff.TurnQueue: the physics
  waits for an answer only when it is not there a decision delay later.)
"""
from __future__ import annotations

import multiprocessing
import statistics
import time

import numpy as np

from bench.study import Study
from bench.study import run as run_study
from engine.physics.dtypes import physics_snapshot_dtype
from engine.physics.world import copy_record
from processes.runtime.handoff import TICK_SLOT_DTYPE, Baton
from processes.runtime.shm import Arena
from processes.workers.layout import ANSWER_DTYPE
TIMEOUT = 10.0


def _sem_child(a, b, n):
    for _ in range(n):
        if not a.acquire(timeout=TIMEOUT):
            return
        b.release()


def _spin_child(layout, n):
    arena = Arena.attach(layout)
    flag = arena["flag"].array
    deadline = time.monotonic() + 60
    for i in range(n):
        while flag[0] != 2 * i + 1:
            if time.monotonic() > deadline:
                arena.close()
                return
        flag[0] = 2 * i + 2
    del flag
    arena.close()


def _queue_child(qa, qb, n):
    for _ in range(n):
        qb.put(qa.get(timeout=TIMEOUT))


def _handoff_child(layout, baton, n_bats):
    """A worker's side of a turn: copy the view, write an answer record."""
    arena = Arena.attach(layout)
    baton.attach(arena["slot"].array)
    view = arena["ai_view"].array
    answer = arena["ai_answer"].array
    snap = np.zeros(1, physics_snapshot_dtype(n_bats))
    record = np.zeros(1, ANSWER_DTYPE)
    while True:
        tick = baton.wait_turn(TIMEOUT)
        if tick is None:
            break
        copy_record(view, snap)
        record[0]["ctl"][0, 0:3] = snap[0]["ball"]["vel"]
        record[0]["tick"] = tick
        copy_record(record, answer)
        baton.done(tick)
    del view, answer, baton
    arena.close()


def _time(fn, n) -> float:
    start = time.perf_counter()
    fn(n)
    return (time.perf_counter() - start) / n * 1e6


def measure(n: int = 5000, repeats: int = 3) -> dict:
    """Median µs per round trip of each method over `repeats` runs of `n` round trips."""
    ctx = multiprocessing.get_context("forkserver")
    # The children fork from a server that imported what they run, as the supervisor's workers
    # do (processes.supervisor), not the command line that started the benchmark.
    ctx.set_forkserver_preload([__name__])
    results: dict[str, list[float]] = {"semaphore": [], "shm_spin": [], "queue": [], "lockstep_handoff": []}
    for _ in range(repeats):
        a, b = ctx.Semaphore(0), ctx.Semaphore(0)
        child = ctx.Process(target=_sem_child, args=(a, b, n))
        child.start()

        def sem(k):
            for _ in range(k):
                a.release()
                if not b.acquire(timeout=TIMEOUT):
                    raise TimeoutError("semaphore ping-pong stalled")
        results["semaphore"].append(_time(sem, n))
        child.join(TIMEOUT)

        arena = Arena()
        try:
            flag = arena.shared_array("flag", np.dtype("<i8"), 1).array
            child = ctx.Process(target=_spin_child, args=(arena.layout(), n))
            child.start()

            def spin(k):
                deadline = time.monotonic() + 60
                for i in range(k):
                    flag[0] = 2 * i + 1
                    while flag[0] != 2 * i + 2:
                        if time.monotonic() > deadline:
                            raise TimeoutError("spin ping-pong stalled")
            results["shm_spin"].append(_time(spin, n))
            child.join(TIMEOUT)
            del flag
        finally:
            arena.close()

        qa, qb = ctx.Queue(), ctx.Queue()
        m = max(n // 5, 100)
        child = ctx.Process(target=_queue_child, args=(qa, qb, m))
        child.start()

        def queue(k):
            for i in range(k):
                qa.put(i)
                qb.get(timeout=TIMEOUT)
        results["queue"].append(_time(queue, m))
        child.join(TIMEOUT)

        results["lockstep_handoff"].append(_measure_handoff(ctx, n))
    medians = {k: statistics.median(v) for k, v in results.items()}
    return {
        "round_trips": n,
        "repeats": repeats,
        "us_per_round_trip": medians,
        "spread_us": {k: [min(v), max(v)] for k, v in results.items()},
        "handoff_over_semaphore": medians["lockstep_handoff"] / medians["semaphore"],
        "handoff_over_shm_spin": medians["lockstep_handoff"] / medians["shm_spin"],
        "target": "lockstep hand-off <= 2.5x the raw shared-memory ping-pong (semaphore wake-up)",
    }


def _measure_handoff(ctx, n: int) -> float:
    n_bats = 2
    arena = Arena()
    try:
        view = arena.shared_array("ai_view", physics_snapshot_dtype(n_bats), 1).array
        answer = arena.shared_array("ai_answer", ANSWER_DTYPE, 1).array
        answer["tick"] = -1
        slot = arena.shared_array("slot", TICK_SLOT_DTYPE, 1).array
        baton = Baton("bench", ctx, slot)
        child = ctx.Process(target=_handoff_child, args=(arena.layout(), baton, n_bats))
        child.start()
        record = np.zeros(1, physics_snapshot_dtype(n_bats))

        def handoff(k):
            for tick in range(k):
                record[0]["ball"]["vel"] = (tick, 0.0, 0.0)
                copy_record(record, view, 0)
                baton.give(tick)
                baton.wait_done(tick, TIMEOUT)
                if answer[0]["tick"] != tick or answer[0]["ctl"][0, 0] != tick:
                    raise RuntimeError(f"hand-off {tick}: the answer is not the turn's")
        us = _time(handoff, n)
        baton.stop()
        child.join(TIMEOUT)
        del view, answer, slot, baton
    finally:
        arena.close()
    return us


def _run(args, progress=None) -> dict:
    return measure(500 if args.quick else 5000, 1 if args.quick else 3)


def _report(report: dict) -> None:
    us = report["us_per_round_trip"]
    print(f"hand-off cost, median of {report['repeats']} x {report['round_trips']} round trips (µs):")
    for key, label in (("semaphore", "semaphore ping-pong (raw wake-up)"), ("shm_spin", "shared-memory spin ping-pong"),
                       ("queue", "multiprocessing.Queue round trip"), ("lockstep_handoff", "lockstep hand-off (view + baton + answer)")):
        low, high = report["spread_us"][key]
        print(f"  {label:<48} {us[key]:8.2f}   [{low:.2f} .. {high:.2f}]")
    print(f"  hand-off / semaphore ping-pong: {report['handoff_over_semaphore']:.2f}x (target <= 2.5x)")


STUDY = Study(run=_run, report=_report, quick="500 round trips, one round")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.handoff", "handoff"))
