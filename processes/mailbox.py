"""Mailboxes: where one process asks another to change state it owns (DESIGN.md).

A mailbox is a shared array of records plus a small header, guarded by an arbitrated lock.
Senders post under the lock; the owner drains under the lock. A `dirty` flag is raised for the
duration of every change, so when the lock is recovered from a holder that died mid-change the
drainer knows the contents are suspect and discards them (counted) instead of acting on a
half-written record.
"""
from __future__ import annotations

import numpy as np

from processes.locks import LockTable
from processes.shm import SharedArray

MAILBOX_HEADER = np.dtype([("count", "<i8"), ("dirty", "<i8"), ("dropped_full", "<i8"), ("discarded_torn", "<i8")])


class Mailbox:
    """Records of `dtype` sent to the owner of some state; capacity bounded, overflow counted."""

    def __init__(self, name: str, header: SharedArray, body: SharedArray, locks: LockTable, timeout: float = 0.5):
        self.name = name
        self._header = header.array
        self._body = body.array
        self._locks = locks
        self.timeout = timeout

    @property
    def capacity(self) -> int:
        return self._body.shape[0]

    def _check_recovered(self, got) -> None:
        if got.recovered_from and self._header["dirty"][0]:
            self._header["discarded_torn"][0] += self._header["count"][0]
            self._header["count"][0] = 0
            self._header["dirty"][0] = 0

    def post(self, record: np.ndarray) -> bool:
        """Append one record; False (and counted) if the mailbox is full."""
        with self._locks.hold(self.name, self.timeout) as got:
            self._check_recovered(got)
            count = int(self._header["count"][0])
            if count >= self.capacity:
                self._header["dropped_full"][0] += 1
                return False
            self._header["dirty"][0] = 1
            self._body[count] = record
            self._header["count"][0] = count + 1
            self._header["dirty"][0] = 0
            return True

    def drain(self, out: np.ndarray) -> int:
        """Move every record into `out` (capacity-sized), oldest first; returns how many."""
        with self._locks.hold(self.name, self.timeout) as got:
            self._check_recovered(got)
            count = int(self._header["count"][0])
            self._header["dirty"][0] = 1
            out[:count] = self._body[:count]
            self._header["count"][0] = 0
            self._header["dirty"][0] = 0
            return count

    def stats(self) -> dict:
        h = self._header[0]
        return {"pending": int(h["count"]), "dropped_full": int(h["dropped_full"]), "discarded_torn": int(h["discarded_torn"])}
