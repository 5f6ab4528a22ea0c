"""A gateway's session: one peer's place (a seat or a spectator place) from its hello to its end,
and the rules that a place cannot be hoarded by a peer that says hello and nothing more, nor by
one address (AddressLimits).

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
    address: str = ""  # the peer's IP address (libzmq's Peer-Address of its hello)
    scene_requests: int = 0  # scene_requests answered (at most wire.MAX_SCENE_REQUESTS)


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


class AddressLimits:
    """What one peer address may take: sessions at once, and hellos a second (a token bucket that
    holds a second's worth). 0: no limit. Behind a NAT many honest clients share an address, so
    both are off unless a server sets them (GatewayConfig.max_sessions_per_address,
    hellos_per_s_per_address)."""

    def __init__(self, max_sessions: int, hellos_per_s: float):
        self.max_sessions = max_sessions
        self.hellos_per_s = hellos_per_s
        self._buckets: dict[str, tuple[float, float]] = {}  # address -> (tokens, at)

    def refusal(self, address: str, sessions, now: float) -> str | None:
        """Why a hello from `address` is refused (None: it is not), given the open `sessions`."""
        if self.hellos_per_s > 0:
            tokens, at = self._buckets.get(address, (self.hellos_per_s, now))
            tokens = min(self.hellos_per_s, tokens + (now - at) * self.hellos_per_s)
            if tokens < 1.0:
                self._buckets[address] = (tokens, now)
                return f"more than {self.hellos_per_s:g} hellos a second from {address}; retry in 1 s"
            self._buckets[address] = (tokens - 1.0, now)
            if len(self._buckets) > 4096:  # forget the addresses whose buckets are full again
                self._buckets = {a: (t, w) for a, (t, w) in self._buckets.items()
                                 if t + (now - w) * self.hellos_per_s < self.hellos_per_s}
        if self.max_sessions > 0 and sum(s.address == address for s in sessions) >= self.max_sessions:
            return f"{self.max_sessions} sessions from {address} already"
        return None
