"""Named shared-memory blocks holding the engine's structured arrays, with untorn snapshots.

A SnapshotBlock keeps two copies (slots) of a structured array plus a 64-bit version counter,
a seqlock over double buffers. With p = version // 2 snapshots published, the latest complete
one is in slot p % 2; the writer makes the version odd (2p + 1) while it fills slot (p + 1) % 2
and even (2p + 2) when that copy is complete. A reader notes the version v1, copies slot
(v1 // 2) % 2 and reads the version again: the writer can only have touched that slot if the
version reached 2 (v1 // 2) + 3, and then the copy is retried. A writer killed mid-write leaves
the previous slot intact, so the last consistent snapshot survives any crash (that is what a
restarted worker resumes from).

x86-64 keeps stores in order and loads in order (TSO), which this protocol relies on; numpy's
copies are separate calls the compiler cannot move across the version reads.

Segments are created only by the supervisor, named `pp<run id>-<name>`, and unlinked by it when
the run ends. Workers only attach. On Python 3.11 attaching registers the segment with the
resource tracker too (cpython issue 82300); workers started by multiprocessing share the
supervisor's tracker, so that registration is the same entry and never unlinks early, and the
tracker still removes the segments if the supervisor itself is killed.
"""
from __future__ import annotations

import os
import secrets
import time
from multiprocessing import shared_memory
from pathlib import Path

import numpy as np

_HEADER = np.dtype([("version", "<u8"), ("writer_pid", "<i8"), ("tick", "<i8"), ("_pad", "<i8")])
SHM_DIR = Path("/dev/shm")
PREFIX = "pp"
# Run ids whose segments this process created: what it alone must clean up (tests check these,
# not every pingpong segment on the machine, which other runs may own).
created_run_ids: set[str] = set()


class SnapshotTimeout(RuntimeError):
    """A reader could not get an untorn copy within its bound (the writer never paused)."""


def new_run_id() -> str:
    """A short random id that names every segment of one run."""
    return secrets.token_hex(4)


def segment_name(run_id: str, name: str) -> str:
    return f"{PREFIX}{run_id}-{name}"


def leftover_segments(run_id: str | None = None) -> list[str]:
    """Names of this project's segments still in /dev/shm (of one run, or of any)."""
    prefix = PREFIX + (f"{run_id}-" if run_id else "")
    if not SHM_DIR.exists():
        return []
    return sorted(p.name for p in SHM_DIR.iterdir() if p.name.startswith(prefix))


def _bytes(records: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """The bytes of a C-contiguous array of `dtype` records (a view, never a copy)."""
    if records.dtype != dtype or not records.flags.c_contiguous:
        raise ValueError(f"expected a C-contiguous array of {dtype}, got {records.dtype} "
                         f"(contiguous: {records.flags.c_contiguous})")
    return records.view(np.uint8)


class SnapshotBlock:
    """A double-buffered structured array in shared memory with one writer and many readers.

    Args:
        name: full segment name. dtype: structured dtype of one record. count: records per slot.
        create: True in the supervisor only.
    """

    def __init__(self, name: str, dtype: np.dtype, count: int, create: bool = False):
        self.name = name
        self.dtype = np.dtype(dtype)
        self.count = count
        slot_bytes = self.dtype.itemsize * count
        # Slots start on 64-byte boundaries so a slot copy never shares a cache line with the header.
        self._slot_offset = 64
        self._slot_stride = -(-slot_bytes // 64) * 64
        size = self._slot_offset + 2 * max(self._slot_stride, 64)
        self._shm = shared_memory.SharedMemory(name=name, create=create, size=size if create else 0)
        buf = self._shm.buf
        self.header = np.ndarray((1,), _HEADER, buffer=buf, offset=0)
        # The seqlock words through a typed memoryview, far cheaper than numpy field views on the
        # per-tick path. 0 version, 1 writer pid, 2 tick.
        self._words = buf[0:32].cast("q")
        self._slots = [
            np.ndarray((count,), self.dtype, buffer=buf, offset=self._slot_offset + k * self._slot_stride)
            for k in (0, 1)
        ]
        # Copies go byte for byte: numpy copies a nested structured dtype field by field, a flat
        # uint8 copy is one memcpy.
        self._raw = [slot.view(np.uint8) for slot in self._slots]
        # publish() copies through memoryviews: a slice assignment is one memcpy without
        # np.copyto's argument handling.
        self._raw_views = [memoryview(raw) for raw in self._raw]
        self._pid = os.getpid()
        self._last_records = self._last_bytes = None
        if create:
            self.header[0] = (0, 0, -1, 0)

    @property
    def version(self) -> int:
        return self._words[0]

    @property
    def tick(self) -> int:
        """Tick of the latest published snapshot (-1 before the first)."""
        return self._words[2]

    def latest(self) -> np.ndarray:
        """A view of the latest complete slot (for the writer itself, or a reader that re-checks)."""
        return self._slots[(self.version // 2) % 2]

    def publish(self, records: np.ndarray, tick: int) -> None:
        """Writer only: copy `records` into the free slot and make it the latest.

        Also right after a writer died mid-write (odd version): its torn slot is the free one.
        """
        words = self._words
        published = words[0] // 2
        words[0] = 2 * published + 1
        if records is not self._last_records:  # a writer publishes the same array every tick
            if self._last_bytes is not None:
                self._last_bytes.release()
            self._last_bytes = memoryview(_bytes(records, self.dtype))
            self._last_records = records
        self._raw_views[(published + 1) % 2][:] = self._last_bytes
        words[1] = self._pid
        words[2] = tick
        words[0] = 2 * published + 2

    def snapshot(self, out: np.ndarray, timeout: float = 1.0) -> int:
        """Copy the latest complete records into `out`; returns how many snapshots were published.

        Raises:
            SnapshotTimeout: no untorn copy could be taken within `timeout` seconds.
        """
        deadline = None
        words = self._words
        out_bytes = _bytes(out, self.dtype)
        while True:
            published = words[0] // 2
            np.copyto(out_bytes, self._raw[published % 2])
            if words[0] <= 2 * published + 2:
                return published
            if deadline is None:
                deadline = time.monotonic() + timeout
            elif time.monotonic() > deadline:
                raise SnapshotTimeout(f"{self.name}: no untorn snapshot within {timeout} s; "
                                      f"writer pid {words[1]} never paused")

    def close(self) -> None:
        # Drop the views first: SharedMemory.close refuses while buffers are exported.
        self.header = None
        self._slots = []
        self._raw = []
        for view in self._raw_views + ([self._last_bytes] if self._last_bytes is not None else []):
            view.release()
        self._raw_views = []
        self._last_records = self._last_bytes = None
        self._words.release()
        self._shm.close()

    def unlink(self) -> None:
        self._shm.unlink()


class SharedArray:
    """A plain shared array (one writer by convention), e.g. a per-tick trace or a mailbox body."""

    def __init__(self, name: str, dtype: np.dtype, shape: tuple[int, ...] | int, create: bool = False):
        self.name = name
        self.dtype = np.dtype(dtype)
        self.shape = (shape,) if isinstance(shape, int) else tuple(shape)
        size = max(int(np.prod(self.shape)) * self.dtype.itemsize, 1)
        self._shm = shared_memory.SharedMemory(name=name, create=create, size=size if create else 0)
        self.array = np.ndarray(self.shape, self.dtype, buffer=self._shm.buf)
        if create:
            self.array.view(np.uint8)[...] = 0

    def close(self) -> None:
        self.array = None
        self._shm.close()

    def unlink(self) -> None:
        self._shm.unlink()


class Arena:
    """Every segment of one run: the supervisor creates them here and removes them all at the end.

    Workers rebuild an Arena from its `layout()` with `Arena.attach`, which opens the same names.
    """

    def __init__(self, run_id: str | None = None):
        self.run_id = run_id or new_run_id()
        self._owner = False
        self._specs: dict[str, tuple] = {}
        self.blocks: dict[str, SnapshotBlock | SharedArray] = {}

    def snapshot_block(self, name: str, dtype: np.dtype, count: int) -> SnapshotBlock:
        self._owner = True
        created_run_ids.add(self.run_id)
        block = SnapshotBlock(segment_name(self.run_id, name), dtype, count, create=True)
        self._specs[name] = ("snapshot", np.dtype(dtype), count)
        self.blocks[name] = block
        return block

    def shared_array(self, name: str, dtype: np.dtype, shape: tuple[int, ...] | int) -> SharedArray:
        self._owner = True
        created_run_ids.add(self.run_id)
        array = SharedArray(segment_name(self.run_id, name), dtype, shape, create=True)
        self._specs[name] = ("array", np.dtype(dtype), array.shape)
        self.blocks[name] = array
        return array

    def layout(self) -> dict:
        """A picklable description a worker attaches with (sent once, at start-up)."""
        return {"run_id": self.run_id, "specs": dict(self._specs)}

    @classmethod
    def attach(cls, layout: dict) -> "Arena":
        arena = cls(layout["run_id"])
        for name, (kind, dtype, size) in layout["specs"].items():
            dtype = np.dtype(dtype)
            full = segment_name(arena.run_id, name)
            arena.blocks[name] = SnapshotBlock(full, dtype, size) if kind == "snapshot" else SharedArray(full, dtype, size)
        return arena

    def __getitem__(self, name: str):
        return self.blocks[name]

    def close(self) -> None:
        """Detach; the owner also unlinks every segment. Safe to call twice."""
        for block in self.blocks.values():
            try:
                block.close()
            except (BufferError, FileNotFoundError):
                pass
            if self._owner:
                try:
                    block.unlink()
                except FileNotFoundError:
                    pass
        self.blocks = {}
