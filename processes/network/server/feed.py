"""The gateway's feed: its PUB socket, and which states of a cloth net go out on it (NetFeed).

What every spectator gets goes out once on the feed (processes.network.server.gateway explains why);
since protocol 3 that includes a cloth net's knots (wire.Net), after a snapshot at most NET_HZ
times a second of match time while the net moves, once when it falls asleep, and its latest
state on each new session.

The slow-subscriber policy: the PUB queues at most SNDHWM messages per subscriber (plus what
the kernel's socket buffers hold); beyond that libzmq drops that subscriber's newest messages
and nobody else's. The gateway cannot see those drops; the subscriber can: the feed numbers its
messages (header seq, one stream for all subscribers), so a gap is a message lost at the mark.
A spectator's session (heartbeats both ways, timeout, goodbye) is what says it is alive: a
spectator that vanishes is timed out there and counted, whatever its feed connection does. The
feed serves whoever connects to its port, as the session port welcomes any spectator
(max_spectators bounds sessions, not feed readers; with CURVE the feed is encrypted and the
server authenticated like the sessions, clients are not).
"""
from __future__ import annotations

from collections import Counter

import zmq

from processes.network import wire
from processes.network.server.guard import ConnectionGuard
from processes.network.wire import NET_HZ

# What libzmq may hold for one feed subscriber: subscribers send only their subscription.
FEED_HELD_BYTES = 64 * 1024


def feed_socket(zctx, config, endpoint: str, own_io_thread: bool, max_frame_bytes: int):
    """The PUB socket bound to `endpoint`: SNDHWM messages per subscriber at most (then that
    subscriber's newest are dropped), never blocking; a CURVE server with the sessions' keys;
    and its ConnectionGuard, started (close it before the socket).

    config: the gateway's GatewayConfig (sndhwm, sndbuf, curve keys). own_io_thread: put it on
    libzmq's I/O thread 1. max_frame_bytes: MAXMSGSIZE, what a subscriber may send (subscriptions).
    """
    feed = zctx.socket(zmq.PUB)
    feed.setsockopt(zmq.LINGER, 0)
    if own_io_thread:
        # its own I/O thread: 120,000 copies a second to 1000 subscribers kept one thread
        # busy, and the sessions' heartbeats on the same thread waited behind them for
        # seconds (`pingpong stress`: every spectator timed out, its heartbeats unread)
        feed.setsockopt(zmq.AFFINITY, 1 << 1)
    feed.setsockopt(zmq.SNDHWM, config.sndhwm)
    feed.setsockopt(zmq.MAXMSGSIZE, max_frame_bytes)
    if config.sndbuf:
        feed.setsockopt(zmq.SNDBUF, config.sndbuf)
    if config.curve_secret_key:
        feed.curve_server = True
        feed.curve_secretkey = config.curve_secret_key
        if config.curve_public_key:
            feed.curve_publickey = config.curve_public_key
    guard = ConnectionGuard(feed, FEED_HELD_BYTES, config.connections_limit, prefix="feed_")
    feed.bind(endpoint)
    guard.start()
    return feed, guard


class NetFeed:
    """Which states of the scene's cloth net become net messages, and when.

    Net messages follow the snapshots, on the match clock: after a snapshot goes out, the net's
    state at that snapshot's tick is due if 1/min(NET_HZ, snapshot_hz) s of match time (a grid of
    ticks) have passed since the last one was due. So they never come more often than snapshots,
    also when the match runs slower than realtime, and a newcomer's latest net state has the
    tick of the newest snapshot while the net moves (a net paced by the wall clock outnumbered
    the snapshots of a slowed match, and lagged them).

    Args:
        grid: (cols, rows, width m, height m) of the cloth net (scene.cloth).
        snapshot_hz: the gateway's snapshot rate. dt: s, the tick.

    Attributes:
        latest: the messages of the state sent last, for each new session after its welcome.
        counts: net_clamped (states with a knot beyond the wire's +-0.33 m, drawn at the edge),
            net_unencodable (a grid the wire cannot carry: no net message at all, viewers draw a panel).
    """

    def __init__(self, grid: tuple[int, int, float, float], snapshot_hz: int, dt: float):
        self.grid: tuple | None = grid
        self.every_ticks = max(1, round(1.0 / min(NET_HZ, snapshot_hz) / dt))
        self.next_tick = 0  # the next state due is that of the first snapshot from this tick on
        self.wanted: int | None = None  # the tick of a snapshot sent whose net state is due
        self.tick: int | None = None  # the tick of the state sent last
        self.asleep = False  # the state sent last was asleep: the net is frozen, nothing more to send
        self.latest: list[bytes] = []
        self.counts: Counter[str] = Counter()

    def snapshot_sent(self, tick: int) -> None:
        """A snapshot of `tick` went out: the net's state at that tick becomes due if its time has
        come (on the grid of every_ticks; from `tick` on after a clock that jumped back or ahead)."""
        went_back = tick < self.next_tick - self.every_ticks  # before the last one due: a restarted physics
        if self.grid is None or (tick < self.next_tick and not went_back):
            return
        on_grid = not went_back and tick < self.next_tick + self.every_ticks
        self.next_tick = (self.next_tick if on_grid else tick) + self.every_ticks
        self.wanted = tick

    def due(self) -> bool:
        """Is the net's state due (a caller reads it only then)?"""
        return self.wanted is not None

    def update(self, tick: int, asleep: bool, knot_pos) -> list[bytes]:
        """The messages to send of the net's state at `tick` (knot_pos (cols * rows, 3) m): those
        of a new state while the net is awake, or of the first state asleep; [] otherwise."""
        self.wanted = None
        if self.grid is None or tick == self.tick or (asleep and self.asleep):
            return []
        cols, rows, width, height = self.grid
        try:
            messages, clamped = wire.net_messages(knot_pos, cols=cols, rows=rows, width=width, height=height,
                                                  asleep=asleep, tick=tick)
        except wire.WireError:
            self.counts["net_unencodable"] += 1
            self.grid = None
            return []
        if clamped:
            self.counts["net_clamped"] += 1
        self.tick, self.asleep, self.latest = tick, asleep, messages
        return messages
