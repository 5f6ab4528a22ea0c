"""Mailboxes: where one process asks another to change state it owns (every shared block has one
writing process; another that must change it posts to the owner's mailbox instead).

A mailbox is a shared array of records plus a small header, guarded by an arbitrated lock.
Senders post under the lock; the owner drains under the lock. A `dirty` flag is raised for the
duration of every change, so when the lock is recovered from a holder that died mid-change the
drainer knows the contents are suspect and discards them (counted) instead of acting on a
half-written record.
"""
from __future__ import annotations

import numpy as np

from processes.runtime.locks import LockTable
from processes.runtime.shm import SharedArray

MAILBOX_HEADER = np.dtype([("count", "<i8"), ("dirty", "<i8"), ("dropped_full", "<i8"), ("discarded_torn", "<i8")])


class Mailbox:
    """Records of `dtype` sent to the owner of some state; capacity bounded, overflow counted."""

    def __init__(self, name: str, header: SharedArray, body: SharedArray, locks: LockTable, timeout: float = 0.5):
        self.name = name
        self._header = header.array
        # count, dirty, dropped_full, discarded_torn as a typed memoryview (cheap per tick).
        self._words = memoryview(header.array.view("<i8")).cast("B").cast("q")
        self._body = body.array
        self._locks = locks
        self.timeout = timeout

    @property
    def capacity(self) -> int:
        return self._body.shape[0]

    def _check_recovered(self, got) -> None:
        words = self._words
        if got.recovered_from and words[1]:
            words[3] += words[0]
            words[0] = 0
            words[1] = 0

    def post(self, record: np.ndarray) -> bool:
        """Append one record; False (and counted) if the mailbox is full."""
        words = self._words
        got = self._locks.acquire(self.name, self.timeout)
        try:
            self._check_recovered(got)
            count = words[0]
            if count >= self.capacity:
                words[2] += 1
                return False
            words[1] = 1
            self._body[count] = record
            words[0] = count + 1
            words[1] = 0
            return True
        finally:
            self._locks.release(self.name)

    def drain(self, out: np.ndarray) -> int:
        """Move every record into `out` (capacity-sized), oldest first; returns how many."""
        words = self._words
        got = self._locks.acquire(self.name, self.timeout)
        try:
            self._check_recovered(got)
            count = words[0]
            if count:
                words[1] = 1
                out[:count] = self._body[:count]
                words[0] = 0
                words[1] = 0
            return count
        finally:
            self._locks.release(self.name)

    def stats(self) -> dict:
        words = self._words
        return {"pending": words[0], "dropped_full": words[2], "discarded_torn": words[3]}
