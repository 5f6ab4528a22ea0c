"""A gateway's session: one peer's place (a seat or a spectator place) from its hello to its end,
and the rule that a place cannot be hoarded by a peer that says hello and nothing more.

A live client answers its welcome with a heartbeat at once (docs/protocol.md). A session that
has sent nothing since its hello holds its place for CONFIRM_HEARTBEATS heartbeat periods at most
(the gateway's sweep tells it goodbye timeout), and once silent for a heartbeat period a hello that
finds every place taken takes its place (oldest_silent).
"""
from __future__ import annotations

from dataclasses import dataclass

from processes.network.wire import Role, Slot

CONFIRM_HEARTBEATS = 3  # heartbeat periods a session silent since its hello keeps its place


@dataclass
class Session:
    identity: bytes
    role: Role
    slot: Slot
    name: str
    last_seen: float
    next_beat: float
    seq_out: int = 0
    seq_in: int = 0  # highest seq received
    input_seq: int = 0  # seq of the last input accepted
    bad: int = 0
    snapshots_dropped: int = 0
    confirmed: bool = False  # it sent a valid message after its hello: a live peer, not a bare hello
    opened: float = 0.0  # the gateway's clock at its hello


def oldest_silent(holders: list[Session], now: float, heartbeat_s: float) -> Session | None:
    """The oldest of `holders` that has sent nothing in the heartbeat period since its hello
    (whose place a new hello may take), None if none."""
    silent = [s for s in holders if not s.confirmed and now - s.opened > heartbeat_s]
    return min(silent, key=lambda s: s.opened) if silent else None


def retry_s(holders: list[Session], now: float, heartbeat_s: float) -> float | None:
    """s until the place of the oldest of `holders` silent since its hello may be taken (at
    least 0.1 s), None if every holder has answered its welcome."""
    waiting = [s.opened for s in holders if not s.confirmed]
    if not waiting:
        return None
    return round(max(0.1, min(waiting) + heartbeat_s - now), 1)
