"""Shared-memory snapshots are never torn, and segments never outlive their run."""

import numpy as np

from processes.runtime.shm import Arena, SnapshotBlock, leftover_segments
from tests.waits import DEADLINE_S, Deadline

RECORD = np.dtype([("counter", "<i8"), ("values", "<f8", (64,)), ("checksum", "<f8")])


def _hammer(name, stop, started, limit):
    block = SnapshotBlock(name, RECORD, 4)
    record = np.zeros(4, RECORD)
    started.set()
    for i in range(1, limit):
        if stop.is_set():
            break
        record["counter"] = i
        record["values"] = np.arange(64) * i
        record["checksum"] = record["values"].sum(axis=1)
        block.publish(record, i)
    block.close()


def test_reader_never_sees_a_torn_snapshot(ctx, procs, no_leftovers):
    arena = Arena()
    try:
        block = arena.snapshot_block("hammer", RECORD, 4)
        stop, started = ctx.Event(), ctx.Event()
        writer = ctx.Process(target=_hammer, args=(block.name, stop, started, 10_000_000))
        procs.append(writer)
        writer.start()
        assert started.wait(DEADLINE_S)
        out = np.zeros(4, RECORD)
        seen = set()
        deadline, reads = Deadline(), 0
        # 20,000 snapshots at least, and on until the writer has been seen at 10 writes (the
        # machine decides how many it gets done meanwhile)
        while (reads < 20_000 or len(seen) <= 10) and not deadline.expired():
            reads += 1
            block.snapshot(out)
            counters = set(out["counter"].tolist())
            assert len(counters) == 1, f"records from different writes in one snapshot: {counters}"
            np.testing.assert_array_equal(out["values"], np.arange(64)[None, :] * out["counter"][:, None])
            np.testing.assert_array_equal(out["checksum"], out["values"].sum(axis=1))
            seen.add(int(out["counter"][0]))
        stop.set()
        writer.join(DEADLINE_S)
        assert len(seen) > 10  # the writer really was writing while we read
    finally:
        arena.close()


def test_arena_close_removes_every_segment():
    arena = Arena()
    arena.snapshot_block("a", RECORD, 1)
    arena.shared_array("b", RECORD, 3)
    assert len(leftover_segments(arena.run_id)) == 2
    arena.close()
    assert leftover_segments(arena.run_id) == []


def test_last_consistent_snapshot_survives_a_torn_write():
    arena = Arena()
    try:
        block = arena.snapshot_block("torn", RECORD, 1)
        record = np.zeros(1, RECORD)
        record["counter"] = 7
        block.publish(record, 7)
        # A writer that died mid-write leaves the version odd and its slot half-written.
        writing = (block.version // 2 + 1) % 2  # the slot a writer fills next
        block.header["version"][0] += 1
        block._slots[writing]["counter"] = -1
        out = np.zeros(1, RECORD)
        block.snapshot(out)
        assert out["counter"][0] == 7
        record["counter"] = 8  # a restarted writer publishes over the torn slot
        block.publish(record, 8)
        block.snapshot(out)
        assert out["counter"][0] == 8 and block.version % 2 == 0
    finally:
        arena.close()
