"""GatewayConfig: how the gateway talks to its peers, and what it lets one peer hold."""
from __future__ import annotations

from dataclasses import dataclass

from processes.network.wire import (DEFAULT_GRACE_S, DEFAULT_HEARTBEAT_S, DEFAULT_MAX_SPECTATORS, DEFAULT_SNAPSHOT_HZ,
                                    DEFAULT_SNDHWM, DEFAULT_TIMEOUT_S, INPUT_HOLD_S, MAX_FRAME_BYTES)

# Whole messages libzmq queues from one session before it stops reading that peer (ZMQ_RCVHWM):
# a session sends heartbeats and inputs, and the gateway reads every few milliseconds.
ROUTER_RCVHWM = 32
MESSAGE_HELD_BYTES = MAX_FRAME_BYTES + 64  # a queued message at most: its frame and libzmq's framing
PENDING_CONNECTIONS = 64  # connections beyond the places: peers between connect and hello, or leaving


@dataclass(frozen=True)
class GatewayConfig:
    """How the gateway talks to its peers.

    bind: ZeroMQ endpoint; port 0 or * picks a free port (see Gateway.endpoint).
    snapshot_hz: snapshots per second to every session. heartbeat_s: a heartbeat at least this
    often. timeout_s: a silent peer is dropped after this long. grace_s: a dropped player's
    seat waits this long for its token. input_hold_s: s of match time, the physics lets go of a
    player's input this long after it applied it unless another came, and brakes the bat. sndhwm: messages queued per peer before its snapshots
    are dropped. sndbuf: the kernel's send buffer per connection in bytes, 0: the OS default.
    max_spectators: more are told "full". curve_secret_key, curve_public_key: Z85 keys of the
    server (`pingpong keys DIR`): every session and the feed are then encrypted and a client
    must know the public key to connect at all (libzmq accepts any client key pair: no ZAP
    handler runs). feed: spectators take snapshots and events from the PUB feed (False: on
    their sessions, one send each, as protocol version 1 did: the fan-out it replaces, kept to
    measure against); it needs a tcp:// bind. feed_bind: the feed's endpoint; "": the session's
    host on a free port. stats_path: a JSON file the gateway writes its counters to (atomically)
    every second and when it ends, whether the match ended or it was stopped; "": none.
    pause_for_players: the served match (its physics worker) pauses while a remote seat is
    empty once every seat was held (False: it plays on against the empty seat's idle arm).
    max_held_bytes: what libzmq may hold for one connection (its queued messages and an
    unfinished multipart message) before the gateway cuts it (processes.network.server.guard);
    at least ROUTER_RCVHWM whole messages. max_connections: connections kept open at once, a
    later one is cut at once; 0: twice the places (max_spectators and the two seats) and
    PENDING_CONNECTIONS more. coalesce_inputs: of one player's valid inputs received in one
    poll only the newest is decoded and posted (the physics applies the newest input it drains
    before a tick, and an input holds until the next, so the others could not act); the rest
    are checked in one vectorised pass and counted inputs_coalesced; every other count
    (malformed, refused, stale) is what it would be without. Off: every input is decoded and
    posted, one by one (kept to measure against). send_log_path: a .npy file the gateway writes
    as it ends: (tick, CLOCK_MONOTONIC s when it was sent) of the last pacing.SEND_LOG_SIZE snapshots
    it published, so a measurement on the same machine can tell the gateway's part of a
    spectator's latency (`pingpong stress --scenario load`); "": none.
    max_sessions_per_address, hellos_per_s_per_address: what one peer IP address may take
    (sessions.AddressLimits; a refused hello is told full, with why); 0: no limit, the default
    (clients behind one NAT share an address).
    """

    bind: str = "tcp://127.0.0.1:0"
    snapshot_hz: int = DEFAULT_SNAPSHOT_HZ
    heartbeat_s: float = DEFAULT_HEARTBEAT_S
    timeout_s: float = DEFAULT_TIMEOUT_S
    grace_s: float = DEFAULT_GRACE_S
    sndhwm: int = DEFAULT_SNDHWM
    sndbuf: int = 0
    max_spectators: int = DEFAULT_MAX_SPECTATORS
    input_hold_s: float = INPUT_HOLD_S
    curve_secret_key: bytes = b""  # Z85; set: every session is CURVE-encrypted and the server authenticated
    curve_public_key: bytes = b""  # Z85, the secret key's public half
    feed: bool = True
    feed_bind: str = ""
    stats_path: str = ""
    pause_for_players: bool = True
    max_held_bytes: int = 256 * 1024
    max_connections: int = 0
    coalesce_inputs: bool = True
    send_log_path: str = ""
    max_sessions_per_address: int = 0
    hellos_per_s_per_address: float = 0.0

    def __post_init__(self):
        least = ROUTER_RCVHWM * MESSAGE_HELD_BYTES
        if self.max_held_bytes < least:
            raise ValueError(f"GatewayConfig.max_held_bytes: {self.max_held_bytes} is below what ROUTER_RCVHWM = "
                             f"{ROUTER_RCVHWM} queued messages of a peer take ({least} bytes); give at least that")
        if self.max_sessions_per_address < 0 or self.hellos_per_s_per_address < 0:
            raise ValueError(f"GatewayConfig.max_sessions_per_address ({self.max_sessions_per_address}) and "
                             f"hellos_per_s_per_address ({self.hellos_per_s_per_address}) must be >= 0 (0: no limit)")
        if self.max_connections < 0:
            raise ValueError(f"GatewayConfig.max_connections: {self.max_connections} must be >= 0 (0: derived)")

    @property
    def connections_limit(self) -> int:
        """max_connections, or its default from the places."""
        return self.max_connections or 2 * (self.max_spectators + 2) + PENDING_CONNECTIONS
