"""The seat table as it outlives a gateway: each seat's token, name and grace in shared memory.

A SnapshotBlock the supervisor owns holds one SEAT_DTYPE record per seat; the gateway of the
moment is its one writer (it saves on every change), and a gateway restarted after a crash loads
it, so a player's rejoin token still reclaims its seat.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processes.network.wire import NO_TOKEN, Slot

SEAT_DTYPE = np.dtype([("slot", "u1"), ("taken", "u1"), ("token", "u1", (16,)), ("name", "u1", (32,)),
                       ("grace_until", "<f8")])  # taken: a connection held it; grace_until: time.monotonic s


@dataclass
class Seat:
    """One seat of a served match, as the gateway keeps it."""

    slot: Slot
    remote: bool  # False: the AI plays this bat, no client may take it
    token: bytes = NO_TOKEN
    identity: bytes | None = None
    name: str = ""
    grace_until: float = 0.0  # while empty: only `token` may take it until then


def restore_seats(seats: dict, table, now: float, grace_s: float) -> int:
    """Seats (Slot -> Seat) from a predecessor's table: tokens and names kept; a seat whose
    connection was open then waits grace_s from `now` for its token (that connection is gone
    with the old socket). Returns how many seats were restored."""
    restored = 0
    for row in table:
        seat = seats.get(Slot(int(row["slot"]))) if int(row["slot"]) in (1, 2) else None
        token = row["token"].tobytes()
        if seat is None or not seat.remote or token == NO_TOKEN:
            continue
        seat.token = token
        seat.name = row["name"].tobytes().rstrip(b"\0").decode("utf-8", errors="replace")
        seat.grace_until = now + grace_s if row["taken"] else float(row["grace_until"])
        restored += 1
    return restored


def free_seat(seats: dict, wanted: Slot, now: float) -> Seat | None:
    """The seat a new player may take: `wanted` (Slot.NONE: either) if remote, empty and past its
    grace; None if there is none."""
    candidates = [seats[wanted]] if wanted != Slot.NONE else list(seats.values())
    return next((seat for seat in candidates if seat.remote and seat.identity is None and now >= seat.grace_until),
                None)


def expire_tokens(seats: dict, now: float) -> int:
    """A seat left empty past its grace loses its token (and name): it is free for anyone. How many did."""
    expired = [seat for seat in seats.values()
               if seat.identity is None and seat.token != NO_TOKEN and now >= seat.grace_until]
    for seat in expired:
        seat.token, seat.name, seat.grace_until = NO_TOKEN, "", 0.0
    return len(expired)


class SeatStore:
    """The seat table in a processes.runtime.shm.SnapshotBlock of SEAT_DTYPE records (one per seat): a
    restarted gateway finds its seats' tokens there, so a rejoin token outlives the gateway.
    Double-buffered, so a gateway killed mid-save leaves the previous table intact."""

    def __init__(self, block):
        self.block = block
        self._table = np.zeros(block.count, SEAT_DTYPE)

    def save(self, seats) -> None:
        table = self._table
        table[:] = 0
        for i, seat in enumerate(seats):
            raw = seat.name.encode("utf-8")[:32]
            table[i]["slot"], table[i]["taken"] = int(seat.slot), seat.identity is not None
            table[i]["token"] = np.frombuffer(seat.token, np.uint8)
            table[i]["name"] = np.frombuffer(raw.ljust(32, b"\0"), np.uint8)
            table[i]["grace_until"] = seat.grace_until
        self.block.publish(table, 0)

    def load(self) -> np.ndarray | None:
        """The last table saved, None if no gateway saved one yet."""
        if self.block.version < 2:
            return None
        out = np.zeros(self.block.count, SEAT_DTYPE)
        self.block.snapshot(out)
        return out
