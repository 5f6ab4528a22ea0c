"""Lockstep hand-offs and queued turns: bounded in both directions; `pingpong bench handoff` smoke run."""
import json
import subprocess
import sys

import numpy as np
import pytest

from processes.runtime.handoff import NO_TURN, QUEUE_WORDS, SPIN_S, TICK_SLOT_DTYPE, Baton, HandoffTimeout, TurnQueue
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


def test_a_nudge_posts_only_to_a_sleeping_worker_which_looks_for_its_work_first(ctx, no_leftovers):
    arena = Arena()
    try:
        slot = arena.shared_array("slot", TICK_SLOT_DTYPE, 1).array
        baton = Baton("net", ctx, slot)
        baton.nudge()  # the worker is not asleep: it rereads the shared state before it sleeps
        assert not baton._go.acquire(False)
        slot["asleep"] = 1
        baton.nudge()  # asleep: woken
        assert baton._go.acquire(False) and slot["asleep"][0] == 0
        granted = [3]
        assert baton.wait_turn(1.0, lambda: granted[0] > 2) == NO_TURN  # work pending: no sleep
        with pytest.raises(HandoffTimeout, match="net: no turn given within 0.05 s"):
            baton.wait_turn(0.05, lambda: granted[0] > 5)  # none: it sleeps, looking between naps
        assert slot["asleep"][0] == 0  # awake again
        del slot, baton
    finally:
        arena.close()


def _answer_turns(layout, queue, spin_s):
    """A TurnQueue's worker: answers each turn with ten times its datum, in order, until stopped;
    exits with 3 if the queue it was handed polls for another time than spin_s."""
    if queue.spin_s != spin_s:
        sys.exit(3)
    arena = Arena.attach(layout)
    queue.attach(arena["words"].array)
    data, answers = arena["data"].array, arena["answers"].array
    done = queue.answered
    while queue.wait_posted(done, 10) and not (queue.stopped and queue.posted == done):
        while queue.posted > done:
            done += 1
            answers[done % len(answers)] = data[done % len(data)] * 10
            queue.answer(done)
    del queue, data, answers
    arena.close()


@pytest.mark.parametrize("spin_s", [SPIN_S, 0.0])  # 0: a run whose workers outnumber the cores
def test_turn_queue_answers_every_turn_in_order_and_the_hub_waits_only_for_what_it_needs(ctx, procs, no_leftovers,
                                                                                         spin_s):
    arena = Arena()
    try:
        words = arena.shared_array("words", np.int64, QUEUE_WORDS).array
        data = arena.shared_array("data", np.dtype("<i8"), 8).array
        answers = arena.shared_array("answers", np.dtype("<i8"), 8).array
        queue = TurnQueue("test", ctx, words, spin_s)
        worker = ctx.Process(target=_answer_turns, args=(arena.layout(), queue, spin_s))
        procs.append(worker)
        worker.start()
        for turn in range(1, 201):
            data[turn % 8] = turn
            assert queue.post() == turn
            if turn > 4:  # the answer needed four turns behind: the worker works ahead of need
                queue.wait_answered(turn - 4, DEADLINE_S, DEADLINE_S, lambda t: None)
                assert answers[(turn - 4) % 8] == (turn - 4) * 10  # visible once counted
        queue.wait_answered(200, DEADLINE_S, DEADLINE_S, lambda t: None)
        assert queue.answered == 200
        queue.stop()
        worker.join(DEADLINE_S)
        assert worker.exitcode == 0
        del words, data, answers, queue
    finally:
        arena.close()


def test_a_turn_nobody_answers_times_out_naming_it(ctx, no_leftovers):
    arena = Arena()
    try:
        queue = TurnQueue("mute", ctx, arena.shared_array("words", np.int64, QUEUE_WORDS).array)
        queue.post()
        beats = []
        with pytest.raises(HandoffTimeout, match=r"mute: turn 1 was not answered within 0.3 s \(answered 0 of 1\)"):
            queue.wait_answered(1, 0.1, 0.3, beats.append)
        assert beats and set(beats) == {1}  # a heartbeat at every bounded wait
        assert not queue.wait_posted(1, 0.05)  # the worker's side: nothing after turn 1
        del queue
    finally:
        arena.close()


def test_turns_taken_back_are_posted_again_and_never_below_the_answered(ctx, no_leftovers):
    arena = Arena()
    try:
        queue = TurnQueue("net", ctx, arena.shared_array("words", np.int64, QUEUE_WORDS).array)
        for _ in range(5):
            queue.post()
        queue.answer(2)
        queue.rewind(3)  # turns 4 and 5 taken back: the next post is turn 4 again
        assert queue.post() == 4
        with pytest.raises(ValueError, match=r"net: cannot rewind to turn 1 \(answered 2, posted 4\)"):
            queue.rewind(1)
        assert not queue.wait_work(4, 0.05, lambda: False)  # nothing posted after turn 4, nothing pending
        assert queue.wait_work(4, 0.05, lambda: True)  # work beside the turns ends the wait at once
        # A restarted hub withdraws answered turns too; the worker counts its answers back itself.
        queue.withdraw(1)
        assert (queue.posted, queue.answered) == (1, 2)
        queue.answer(1)
        assert queue.post() == 2
        with pytest.raises(ValueError, match=r"net: cannot withdraw to turn 3 \(posted 2\)"):
            queue.withdraw(3)
        del queue
    finally:
        arena.close()


def test_bench_handoff_quick_json():
    done = subprocess.run([sys.executable, "-m", "processes", "bench", "handoff", "--quick", "--json"],
                          capture_output=True, text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert set(report["us_per_round_trip"]) == {"semaphore", "shm_spin", "queue", "lockstep_handoff"}
    assert all(v > 0 for v in report["us_per_round_trip"].values())
