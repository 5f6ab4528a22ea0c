"""The gateway: ZeroMQ sessions of remote players and spectators; their inputs in, snapshots out.

Two sockets. The sessions live on a ROUTER: a client is a DEALER that sends one-frame wire
messages (processes/network/wire/); the gateway sees [identity, message]. What every spectator gets
(snapshots, events) goes out once on a PUB socket, the feed, whose port the welcome announces
(welcome.feed_port): the gateway encodes and sends a snapshot once per tick and libzmq's I/O
thread copies it to each subscriber, where one send per spectator session would cost the
gateway's Python a send each, times the spectators, times the snapshot rate. Players keep
theirs on the session (two sends, and a player's snapshots are counted per session). Sessions:

- hello -> welcome (slot A/B with a fresh rejoin token, or spectator) or reject (full,
  version, bad_request, bad_token, shutting_down), and the session is closed on a reject. A
  frame that claims to be a hello (magic, version, kind) but fails to decode is rejected
  bad_request, with the decoder's reason in the detail.
- heartbeats both ways: the gateway sends one every `heartbeat_s` to each session (with
  start_heartbeats, also from a thread of its own, which no wait of the caller's loop holds up);
  a heartbeat, an input or a goodbye counts as a sign of life (a hello within a session does
  not); a peer silent for `timeout_s` is sent goodbye (timeout) and dropped. A dropped player's seat is kept for `grace_s`: only its token may
  reclaim it (rejoin); after the grace the token expires (bad_token) and anyone may take the
  seat. A player who says goodbye frees its seat at once. A hello with the token of a seat
  whose old connection is still open takes the seat over (the old session is told goodbye,
  kicked).
- input: decoded and validated, accepted only for the sender's own bat (another bat's input,
  a spectator's input, target mode and stale sequence numbers are refused and counted; all but
  stale ones count towards MAX_BAD: target mode is reserved since protocol 3), then posted to
  the locked remote-input mailbox that the physics worker drains each tick; of a player's
  inputs that arrived together, only the newest valid one (handle_inputs).
- snapshots at `snapshot_hz` from the physics snapshot block, plus point/game/match events
  from the point log (server.events.MatchEvents), and a cloth net's knots (server.feed.NetFeed).
  Sends never block: ROUTER_MANDATORY with NOBLOCK raises when a peer's pipe is at its
  high-water mark (SNDHWM), and that peer's snapshot is dropped and counted, so a slow peer
  stalls nobody; the feed's own slow-subscriber policy is server.feed's.
- scene_request -> the served scene's TOML text in scene_part messages on the session (at
  most MAX_SCENE_REQUESTS a session; a request of another digest is a bad message): a client
  plays the server's scene, whatever its own disk holds.
- goodbye to every session on shutdown (shutdown), when the run failed (server_error) or at the
  end of the match (match_over); a
  peer without a session that sends anything but a hello (a session of the gateway this one
  replaced after a crash) is told goodbye (unknown_session), once per connection, and may
  hello again (a player with its token, within the grace).
- snapshots follow the match clock: one every 1/snapshot_hz s of match time (snapshot_ticks),
  at most snapshot_hz a wall second, the same tick again each period while the clock stands;
  each says the realtime factor measured over the last second (network.pacing).
- a snapshot of tick T says in input_seq the inputs applied before the step into T (the
  physics writes them per tick into the remote_acks ring before publishing T), so a client
  rewinds to T and replays exactly its later inputs. The gateway only forwards inputs: the
  physics lets go of one input_hold_s after it applied it and brakes the bat itself
  (processes.workers.remote_inputs.RemoteInputs), as it brakes the bat of a seat without a player.
- the seat table (tokens, names, grace) is saved to a SeatStore on every change: a gateway
  restarted after a crash restores it and a player's token still reclaims its seat.
- with a CURVE key pair (`pingpong keys`, `serve --curve-secret`) every session and the feed are
  encrypted and only clients that know the server's public key can connect.

Every message from outside that fails wire.decode, or arrives in more than one frame, or comes
from a peer without a session, is dropped and counted by reason, never fatal. A session that
sends MAX_BAD bad messages is kicked.

`Gateway` is the socket logic alone (the tests drive it in-process);
processes.workers.gateway runs it as the supervisor's worker, fed by the run's shared memory.
"""
from __future__ import annotations

import os
import secrets
import struct
import threading
import time
from collections import Counter

import numpy as np
import zmq

from engine.physics.compiled import CompiledScene, compile_scene
from engine.physics.scene import Scene
from processes.network import wire
from processes.network.server.config import ROUTER_RCVHWM, GatewayConfig
from processes.network.server.events import MatchEvents
from processes.network.server.feed import NetFeed, feed_socket
from processes.network.server.guard import FRAME_OVERHEAD_BYTES, ConnectionGuard
from processes.network.server.pacing import SendLog, SnapshotPacer
from processes.network.server.served_scene import ServedScene
from processes.network.server.seats import Seat, SeatStore, expire_tokens, free_seat, restore_seats
from processes.network.server.sessions import (CONFIRM_HEARTBEATS, AddressLimits, Session, oldest_silent,
                                               retry_s)
from processes.network.wire import (MAX_BAD, MAX_FRAME_BYTES, NO_TOKEN, GoodbyeReason, InputMode, Kind, RejectReason,
                                    Role, Slot)

MAX_STRANGERS_TOLD = 4096  # connections without a session told goodbye, remembered so each is told once
MAX_MESSAGES_PER_POLL = 512  # one poll handles at most this many incoming messages
# ... and for at most this long: the caller's loop publishes the snapshots between two polls, so
# a flood of messages that cost a decode and an answer each (500 hellos to a full server) delays
# the feed by this much, not by the whole flood's handling.
POLL_BUDGET_S = 0.002
SWEEPS_PER_HEARTBEAT = 10  # passes over every session (timeouts, heartbeats) per heartbeat period
STATS_EVERY_S = 1.0  # the worker writes its counters to GatewayConfig.stats_path this often
STOP_DRAIN_S = 0.2  # s after its goodbyes a stopping gateway still answers (a hello: reject shutting_down)
# A session's heartbeat, the message a thousand spectators send twice a second: magic, version,
# kind, flags 0 and the size say it all (its only body field, ack, is any u64), so it is taken by
# this fixed prefix and the tick's sign, exactly what wire.decode would accept, without decoding.
_HEARTBEAT_PREFIX = wire.MAGIC + struct.pack("<HBB", wire.PROTOCOL_VERSION, Kind.HEARTBEAT, 0)
_HEARTBEAT_SIZE = wire.SIZES[Kind.HEARTBEAT]
_HELLO_PREFIX = wire.MAGIC + struct.pack("<HB", wire.PROTOCOL_VERSION, Kind.HELLO)
_SEQ_TICK = struct.Struct("<Qq")
_INPUT_PREFIX = wire.MAGIC + struct.pack("<HB", wire.PROTOCOL_VERSION, Kind.INPUT)
_INPUT_SIZE = wire.SIZES[Kind.INPUT]


class Gateway:
    """The gateway's sessions over one ROUTER socket.

    Args:
        zctx: a zmq.Context. config: GatewayConfig.
        scene: the served engine.physics.scene.Scene, or the run's CompiledScene
            (engine.physics.compiled): its name, best_of, dt and digest go in every welcome, its
            TOML text (engine.physics.scene.scene_toml) to a session that asks for it.
        remote_slots: the seats remote players may take (Slot.A and/or Slot.B).
        post_input(bat, seq, tick, inputs6) -> bool: hand an accepted input to the physics
            (False: it could not be queued; counted).
        clock: seconds, monotonic (tests may pass their own).
        seat_store: a SeatStore the seat table is saved to on every change and restored from at
            start (a restarted gateway: seats held at its predecessor's death wait `grace_s`
            for their tokens); None: seats live and die with this object.
        net_grid: (cols, rows, width m, height m) of a cloth net (service_net); None: no net messages.
    """

    def __init__(self, zctx, config: GatewayConfig, *, scene: Scene | CompiledScene, remote_slots, post_input,
                 clock=time.monotonic, seat_store: SeatStore | None = None, net_grid=None):
        self.config = config
        self.served = ServedScene(compile_scene(scene))
        self.dt = self.served.dt
        self.post_input = post_input
        self.clock = clock
        self.seats = {slot: Seat(slot, slot in set(remote_slots)) for slot in (Slot.A, Slot.B)}
        self.seat_store = seat_store
        self.sessions: dict[bytes, Session] = {}
        self.counts: Counter[str] = Counter()
        self.drops = wire.DropCounter()
        self.tick = 0
        self.shutting_down = False
        self._next_sweep = 0.0
        self.events = MatchEvents()
        self._strangers_told: set[bytes] = set()
        self.net = NetFeed(net_grid, config.snapshot_hz, self.dt) if net_grid is not None else None
        # one snapshot per 1/snapshot_hz of match time (and at most snapshot_hz a wall second)
        self.pacer = SnapshotPacer(config.snapshot_hz, self.dt)
        self.send_log = SendLog(config.send_log_path) if config.send_log_path else None
        self.address_limits = AddressLimits(config.max_sessions_per_address, config.hellos_per_s_per_address)
        self._hello_address = ""  # the Peer-Address of the hello being handled
        self.lock = threading.Lock()  # with start_heartbeats: held around every other call
        self._sweeper: threading.Thread | None = None
        self._stop_sweeps = threading.Event()
        self.router = zctx.socket(zmq.ROUTER)
        self.router.setsockopt(zmq.LINGER, 0)
        self._two_io_threads = zctx.get(zmq.IO_THREADS) >= 2
        if self._two_io_threads:  # sessions on libzmq's I/O thread 0, the feed's fan-out on thread 1
            self.router.setsockopt(zmq.AFFINITY, 1 << 0)
        self.router.setsockopt(zmq.ROUTER_MANDATORY, 1)
        self.router.setsockopt(zmq.SNDHWM, config.sndhwm)
        self.router.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)
        self.router.setsockopt(zmq.RCVHWM, ROUTER_RCVHWM)
        if config.sndbuf:
            self.router.setsockopt(zmq.SNDBUF, config.sndbuf)
        if config.curve_secret_key:  # before bind: the handshake is chosen per connection at accept
            self.router.curve_server = True
            self.router.curve_secretkey = config.curve_secret_key
            if config.curve_public_key:
                self.router.curve_publickey = config.curve_public_key
        self.guard = ConnectionGuard(self.router, config.max_held_bytes, config.connections_limit,  # before bind
                                     newcomer_grace_s=CONFIRM_HEARTBEATS * config.heartbeat_s)
        self.router.bind(_any_port(config.bind))
        self.endpoint = self.router.getsockopt_string(zmq.LAST_ENDPOINT)
        self.guard.start()
        self.feed = None  # the PUB socket of spectators' snapshots and events
        self.feed_guard: ConnectionGuard | None = None
        self.feed_endpoint = ""
        self.feed_port = 0
        self.feed_seq = 0
        if config.feed and self.endpoint.startswith("tcp://"):
            feed_bind = _any_port(config.feed_bind or self.endpoint.rsplit(":", 1)[0] + ":0")
            self.feed, self.feed_guard = feed_socket(zctx, config, feed_bind, self._two_io_threads, MAX_FRAME_BYTES)
            self.feed_endpoint = self.feed.getsockopt_string(zmq.LAST_ENDPOINT)
            self.feed_port = int(self.feed_endpoint.rsplit(":", 1)[1])
        self._beat = bytearray(wire.encode(Kind.HEARTBEAT, tick=0, ack=0))
        if seat_store is not None:
            self._restore_seats(seat_store.load())

    # --- state ---------------------------------------------------------------------------------
    def _restore_seats(self, table) -> None:
        """Seats from a predecessor's table (seats.restore_seats)."""
        if table is not None:
            self.counts["seats_restored"] += restore_seats(self.seats, table, self.clock(), self.config.grace_s)
            self._save_seats()

    def _save_seats(self) -> None:
        if self.seat_store is not None:
            self.seat_store.save(list(self.seats.values()))

    @property
    def seats_filled(self) -> bool:
        """Every remote seat has a connected player."""
        return all(seat.identity is not None for seat in self.seats.values() if seat.remote)

    def stats(self) -> dict:
        """Counters: sessions, inputs, refusals, drops by reason, snapshots sent and dropped."""
        net_counts = self.net.counts if self.net is not None else {}
        feed_counts = self.feed_guard.counts if self.feed_guard is not None else {}
        out = dict(sorted({**self.counts, **self.events.counts, **net_counts, **self.guard.counts, **feed_counts}.items()))
        for reason, n in self.drops.by_reason.items():
            out[f"dropped.{reason}"] = out.get(f"dropped.{reason}", 0) + n
        out["dropped_total"] = sum(v for k, v in out.items() if k.startswith("dropped."))
        out["disconnected_total"] = sum(v for k, v in out.items() if "disconnected." in k)
        out["sessions"] = len(self.sessions)
        out["connections"] = self.guard.connections
        out["connections_unconfirmed"] = self.guard.connections_unconfirmed
        out["spectators"] = sum(1 for s in self.sessions.values() if s.role == Role.SPECTATOR)
        out["feed_port"] = self.feed_port
        return out

    def write_stats(self, extra: dict | None = None) -> None:
        """The counters (and `extra`) to config.stats_path, atomically (a reader never sees half)."""
        path = self.config.stats_path
        if not path:
            return
        import json

        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            json.dump({**self.stats(), **(extra or {})}, f)
        os.replace(tmp, path)

    # --- sending -------------------------------------------------------------------------------
    def _send(self, session: Session, data: bytes, what: str) -> bool:
        """One message to one peer, never blocking: a full pipe drops it (counted)."""
        session.seq_out += 1
        buf = bytearray(data)
        buf[8:16] = session.seq_out.to_bytes(8, "little")
        try:
            self.router.send_multipart([session.identity, bytes(buf)], flags=zmq.NOBLOCK)
        except zmq.Again:
            self.counts[f"{what}_dropped"] += 1
            session.snapshots_dropped += what == "snapshots"
            return False
        except zmq.ZMQError:  # EHOSTUNREACH: the peer's connection is gone
            self.counts["unreachable"] += 1
            return False
        self.counts[f"{what}_sent"] += 1
        return True

    def _reply(self, identity: bytes, data: bytes) -> None:
        """A message to a peer without a session (a reject)."""
        try:
            self.router.send_multipart([identity, data], flags=zmq.NOBLOCK)
        except zmq.ZMQError:
            self.counts["unreachable"] += 1

    def _reject(self, identity: bytes, reason: RejectReason, detail: str) -> None:
        self.counts[f"rejected.{reason.name.lower()}"] += 1
        detail = detail.encode("utf-8")[:wire.DETAIL_SIZE].decode("utf-8", errors="ignore").strip()
        try:
            data = wire.encode(Kind.REJECT, tick=self.tick, reason=reason, detail=detail)
        except wire.WireError:  # a detail quoting what the peer sent may hold text the wire refuses
            data = wire.encode(Kind.REJECT, tick=self.tick, reason=reason, detail="")
        self._reply(identity, data)

    def _welcome(self, session: Session, token: bytes) -> None:
        config = self.config
        heartbeat_ms = max(1, int(config.heartbeat_s * 1000))
        self._send(session, wire.encode(
            Kind.WELCOME, tick=self.tick, slot=session.slot, best_of=self.served.best_of, snapshot_hz=config.snapshot_hz,
            heartbeat_ms=heartbeat_ms, timeout_ms=max(heartbeat_ms, int(config.timeout_s * 1000)), dt=self.dt,
            token=token, scene=self.served.name[:32], name_a=self.seats[Slot.A].name, name_b=self.seats[Slot.B].name,
            feed_port=self.feed_port if session.role == Role.SPECTATOR else 0, scene_digest=self.served.digest),
            "welcomes")
        for data in self.net.latest if self.net is not None else ():  # on the session: the feed may not be up yet
            self._send(session, data, "nets")

    def _goodbye(self, session: Session, reason: GoodbyeReason) -> None:
        self._send(session, wire.encode(Kind.GOODBYE, tick=self.tick, reason=reason), "goodbyes")

    # --- receiving -----------------------------------------------------------------------------
    def poll(self, timeout_ms: int) -> int:
        """Wait at most timeout_ms for messages, then handle those waiting, MAX_MESSAGES_PER_POLL
        and POLL_BUDGET_S s of handling at most (the rest wait for the next poll); returns how
        many were handled."""
        if not self.router.poll(timeout_ms, zmq.POLLIN):
            return 0
        handled = 0
        pending: dict[bytes, list] = {}  # identity -> its inputs (frames) received in this poll, in order
        budget_end = time.perf_counter() + POLL_BUDGET_S
        while handled < MAX_MESSAGES_PER_POLL and (handled % 8 or not handled or time.perf_counter() < budget_end):
            try:
                parts = self.router.recv_multipart(flags=zmq.NOBLOCK, copy=False)
            except zmq.Again:
                break
            handled += 1
            frames = [part.bytes for part in parts]
            # what this connection's libzmq pipe no longer holds (the guard bounds the rest)
            fd = parts[-1].get(zmq.SRCFD)
            self.guard.took(fd, sum(map(len, frames[1:])) + FRAME_OVERHEAD_BYTES * len(frames))
            identity = frames[0]
            session = self.sessions.get(identity)
            if session is not None and session.confirmed:
                self.guard.valued(fd, time.monotonic())  # the guard's clock: a connection worth keeping
            if (self.config.coalesce_inputs and len(frames) == 2 and len(frames[1]) == _INPUT_SIZE
                    and frames[1].startswith(_INPUT_PREFIX)):
                pending.setdefault(identity, []).append(frames)
                continue
            if identity in pending:  # this peer's inputs first: a goodbye after them ends the session after them
                self.handle_inputs(pending.pop(identity))
            if len(frames) == 2 and frames[1].startswith(_HELLO_PREFIX):
                self._hello_address = parts[-1].get("Peer-Address") or ""
            self.handle(frames)
        for inputs in pending.values():
            self.handle_inputs(inputs)
        return handled

    def handle_inputs(self, inputs: list) -> None:
        """One peer's inputs that arrived together (frames each, in order). The physics applies
        the newest of those it drains before a tick, and an input holds until the next, so of
        a player's inputs only the newest valid one is decoded and posted; the others are
        checked (wire.own_force_inputs: one vectorised pass) and counted inputs_coalesced. A
        flood then costs a receive and a fraction of a decode per input, not a decode and a
        post to the physics' mailbox, and the feed keeps its pace. Any input the check does not
        pass (malformed, another bat's, target mode, a spectator's) is handled on its own, so
        it is counted and refused exactly as without coalescing, and the inputs before it are
        settled first."""
        session = self.sessions.get(inputs[0][0])
        if len(inputs) == 1 or session is None or session.role != Role.PLAYER:
            for frames in inputs:
                self.handle(frames)
            return
        good = wire.own_force_inputs([frames[1] for frames in inputs], int(session.slot))
        newest, newest_seq = None, session.input_seq
        for frames, ok in zip(inputs, good):
            if not ok or self.sessions.get(frames[0]) is not session:  # in order: what came before it first
                if newest is not None:
                    self.handle(newest)
                    newest = None
                self.handle(frames)
                continue
            seq = _SEQ_TICK.unpack_from(frames[1], 8)[0]
            session.last_seen, session.confirmed = self.clock(), True
            if seq <= newest_seq:
                self.counts["refused.stale_input"] += 1  # as _input counts it: reordered or replayed
                continue
            if newest is not None:
                self.counts["inputs_coalesced"] += 1
            newest, newest_seq = frames, seq
        if newest is not None:
            self.handle(newest)

    def handle(self, frames: list) -> None:
        """One incoming multipart: [identity, message]."""
        now = self.clock()
        identity = frames[0]
        session = self.sessions.get(identity)
        if len(frames) != 2:
            self.counts["dropped.bad_framing"] += 1
            self._bad(session)
            return
        data = frames[1]
        if session is not None and len(data) == _HEARTBEAT_SIZE and data.startswith(_HEARTBEAT_PREFIX):
            seq, tick = _SEQ_TICK.unpack_from(data, 8)
            if tick >= 0:  # else: decode below names the fault
                session.last_seen = now
                session.confirmed = True
                session.seq_in = max(session.seq_in, seq)
                self.counts["heartbeats_received"] += 1
                return
        try:
            message = wire.decode(frames[1])
        except wire.BadVersion as err:
            self.drops.by_reason[err.reason] += 1
            if session is None:
                self._reject(identity, RejectReason.VERSION,
                             f"server speaks protocol {wire.PROTOCOL_VERSION}, you {err.version}")
            else:
                self._bad(session)
            return
        except wire.WireError as err:
            self.drops.by_reason[err.reason] += 1
            if session is None and data[:len(_HELLO_PREFIX)] == _HELLO_PREFIX:  # a hello of ours, malformed
                self._reject(identity, RejectReason.BAD_REQUEST, str(err))
            self._bad(session)
            return
        if session is None:
            if message.kind == Kind.HELLO:
                self._hello(identity, message, now)
            else:
                self.counts["dropped.no_session"] += 1
                self._goodbye_stranger(identity)
            return
        if message.kind not in (Kind.INPUT, Kind.HEARTBEAT, Kind.GOODBYE, Kind.SCENE_REQUEST):
            # a hello in a session or a server's message: bad, and no sign of life (hellos sent
            # again and again must not keep a place the session never confirmed)
            self.counts["dropped.hello_in_session" if message.kind == Kind.HELLO else "dropped.server_message"] += 1
            self._bad(session)
            return
        session.last_seen = now
        session.confirmed = True
        session.seq_in = max(session.seq_in, message.seq)
        if message.kind == Kind.INPUT:
            self._input(session, message)
        elif message.kind == Kind.HEARTBEAT:
            self.counts["heartbeats_received"] += 1
        elif message.kind == Kind.SCENE_REQUEST:
            refused = self.served.refusal(session, message["digest"])
            if refused:
                self.counts[f"dropped.{refused}"] += 1
                self._bad(session)
            for data in () if refused else self.served.parts:
                self._send(session, data, "scene_parts")
        else:
            self.counts["quits"] += 1
            self._end(session, keep_seat=False)

    def _goodbye_stranger(self, identity: bytes) -> None:
        """Goodbye (unknown_session), once per connection, to a peer that talks as if it had a
        session: a session of a gateway this one replaced (restarted after a crash), or one
        already closed. It may hello again (with its token, within the grace)."""
        if identity in self._strangers_told:
            return
        if len(self._strangers_told) >= MAX_STRANGERS_TOLD:
            self._strangers_told.clear()
        self._strangers_told.add(identity)
        self.counts["goodbyes_to_strangers"] += 1
        self._reply(identity, wire.encode(Kind.GOODBYE, tick=self.tick, reason=GoodbyeReason.UNKNOWN_SESSION))

    def _bad(self, session: Session | None) -> None:
        if session is None:
            return
        session.bad += 1
        if session.bad >= MAX_BAD:
            self.counts["kicked"] += 1
            self._goodbye(session, GoodbyeReason.KICKED)
            self._end(session, keep_seat=False)

    def _hello(self, identity: bytes, message: wire.Message, now: float) -> None:
        if self.shutting_down:
            self._reject(identity, RejectReason.SHUTTING_DOWN, "the server is shutting down")
            return
        name = message["name"]
        refusal = self.address_limits.refusal(self._hello_address, self.sessions.values(), now)
        if refusal is not None:
            self.counts["rejected.address"] += 1
            self._reject(identity, RejectReason.FULL, refusal)
            return
        if message["role"] == Role.SPECTATOR:
            spectators = [s for s in self.sessions.values() if s.role == Role.SPECTATOR]
            if len(spectators) >= self.config.max_spectators and not self._evict_unconfirmed(spectators, now):
                retry = retry_s(spectators, now, self.config.heartbeat_s) or self.config.timeout_s
                self._reject(identity, RejectReason.FULL, f"{len(spectators)} spectators already watch; "
                             f"retry in {retry:g} s")
                return
            session = self._open(identity, Role.SPECTATOR, Slot.NONE, name, now, message.seq)
            self.counts["spectators_joined"] += 1
            self._welcome(session, NO_TOKEN)
            return
        token, wanted = message["token"], message["slot"]
        self._expire_tokens(now)
        if token != NO_TOKEN:
            seat = next((s for s in self.seats.values() if s.remote and s.token == token), None)
            if seat is None or (wanted != Slot.NONE and wanted != seat.slot):
                self._reject(identity, RejectReason.BAD_TOKEN, "unknown or expired rejoin token")
                return
            if seat.identity is not None:  # the old connection is still open: the token wins
                old = self.sessions.pop(seat.identity)
                self._goodbye(old, GoodbyeReason.KICKED)
            self.counts["rejoined"] += 1
        else:
            seat = free_seat(self.seats, wanted, now)
            holders = [self.sessions[s.identity] for s in self.seats.values()
                       if s.remote and s.identity in self.sessions and (wanted == Slot.NONE or s.slot == wanted)]
            if seat is None and self._evict_unconfirmed(holders, now):
                seat = free_seat(self.seats, wanted, now)
            if seat is None:
                remote = [s.slot.name for s in self.seats.values() if s.remote]
                detail = (f"seat {wanted.name} is played by the AI" if wanted != Slot.NONE and not self.seats[wanted].remote
                          else f"remote seats {'/'.join(remote) or 'none'} are taken")
                retry = retry_s(holders, now, self.config.heartbeat_s)
                if retry is not None:  # a bare hello's seat is free again soon
                    detail += f"; retry in {retry:g} s"
                self._reject(identity, RejectReason.FULL, detail)
                return
            seat.token = secrets.token_bytes(wire.TOKEN_SIZE)
            self.counts["players_joined"] += 1
        seat.identity, seat.name, seat.grace_until = identity, name, 0.0
        self._save_seats()
        session = self._open(identity, Role.PLAYER, seat.slot, name, now, message.seq)
        self._welcome(session, seat.token)

    def _expire_tokens(self, now: float) -> None:
        expired = expire_tokens(self.seats, now)
        if expired:
            self.counts["tokens_expired"] += expired
            self._save_seats()

    def _evict_unconfirmed(self, holders: list[Session], now: float) -> bool:
        """Make a place: the oldest of `holders` that has sent nothing in the heartbeat period
        since its hello is told goodbye (kicked) and its place freed (a player's seat and token
        too); False if none."""
        oldest = oldest_silent(holders, now, self.config.heartbeat_s)
        if oldest is None:
            return False
        self.counts["evicted.unconfirmed"] += 1
        self._goodbye(oldest, GoodbyeReason.KICKED)
        self._end(oldest, keep_seat=False)
        return True

    def _open(self, identity: bytes, role: Role, slot: Slot, name: str, now: float, seq: int) -> Session:
        session = Session(identity, role, slot, name, last_seen=now, next_beat=now + self.config.heartbeat_s,
                           seq_in=seq, opened=now, address=self._hello_address)
        self.sessions[identity] = session
        return session

    def _end(self, session: Session, keep_seat: bool) -> None:
        """Close a session; a player's seat waits for its token (keep_seat) or is free at once."""
        self.sessions.pop(session.identity, None)
        if session.role != Role.PLAYER:
            return
        seat = self.seats[session.slot]
        if seat.identity != session.identity:
            return
        seat.identity = None  # its last input expires in the physics, which then brakes the bat
        if keep_seat:
            seat.grace_until = self.clock() + self.config.grace_s
        else:
            seat.token, seat.name, seat.grace_until = NO_TOKEN, "", 0.0
        self._save_seats()

    def _input(self, session: Session, message: wire.Message) -> None:
        if session.role != Role.PLAYER:
            self.counts["refused.spectator_input"] += 1
            self._bad(session)
            return
        if message["slot"] != session.slot:
            self.counts["refused.other_bat"] += 1
            self._bad(session)
            return
        if message["mode"] != InputMode.FORCE:
            self.counts["refused.target_mode"] += 1  # reserved (protocols 3 and 4): no server-side arm controller
            self._bad(session)
            return
        if message.seq <= session.input_seq:
            self.counts["refused.stale_input"] += 1  # reordered or replayed
            return
        session.input_seq = message.seq
        inputs = np.concatenate([message["force"], message["torque"]])
        if self.post_input(session.slot.bat, message.seq, message.tick, inputs):
            self.counts["inputs_accepted"] += 1
        else:
            self.counts["mailbox_full"] += 1

    # --- time ----------------------------------------------------------------------------------
    def service(self, record=None, input_seq=(0, 0), points=None) -> None:
        """Heartbeats, timeouts, and (when due) the snapshot of `record` and new events.

        record: one physics_snapshot_dtype(2) record or None. input_seq: last applied input per
        bat. points: the run's POINT_DTYPE log (events for the points `record` counts).
        """
        now = self.clock()
        self.sweep(now)
        if record is None:
            return
        self.tick = int(record["world"]["tick"])
        if points is not None:
            for data in self.events.new(record, points, self.tick):
                self._broadcast(data, "events")
        if self.pacer.due(now, self.tick, float(record["world"]["time"])):
            self.broadcast_snapshot(record, input_seq)

    def sweep(self, now: float) -> None:
        """Every session's timeout and heartbeat, when due: a few times per heartbeat period, not
        every call (with 1000 spectators a pass is ~0.5 ms of Python and the worker calls
        service every few ms)."""
        if now < self._next_sweep:
            return
        self._next_sweep = now + self.config.heartbeat_s / SWEEPS_PER_HEARTBEAT
        self._expire_tokens(now)
        confirm_s = CONFIRM_HEARTBEATS * self.config.heartbeat_s
        for session in list(self.sessions.values()):
            if not session.confirmed and now - session.opened > confirm_s:
                self.counts["timeouts.unconfirmed"] += 1  # a bare hello holds no place for long
                self._goodbye(session, GoodbyeReason.TIMEOUT)
                self._end(session, keep_seat=False)
            elif now - session.last_seen > self.config.timeout_s:
                self.counts["timeouts"] += 1
                self._goodbye(session, GoodbyeReason.TIMEOUT)
                self._end(session, keep_seat=True)
            elif now >= session.next_beat:
                session.next_beat = now + self.config.heartbeat_s
                self._send(session, self._heartbeat(session.seq_in), "heartbeats")

    def start_heartbeats(self) -> None:
        """Sweep also from a thread of its own from now on: the worker's loop waits outside
        `lock` for the physics' and the net's published states (a writer descheduled mid-write on
        a busy machine holds such a copy up), and the heartbeats and timeouts go on meanwhile.
        The caller holds `lock` around every other call from then on (ZeroMQ sockets are not
        thread-safe); shutdown() and close() stop the thread."""
        def run():
            period = self.config.heartbeat_s / SWEEPS_PER_HEARTBEAT / 2
            while not self._stop_sweeps.wait(period):
                with self.lock:
                    self.sweep(self.clock())

        self._sweeper = threading.Thread(target=run, name="gateway-heartbeats", daemon=True)
        self._sweeper.start()

    def _stop_heartbeats(self) -> None:
        if self._sweeper is not None:
            self._stop_sweeps.set()
            if self._sweeper is not threading.current_thread():
                self._sweeper.join(5.0)
            self._sweeper = None

    def net_due(self) -> bool:
        """Is the cloth net's state at the newest snapshot's tick due (NetFeed)?"""
        return self.net is not None and self.net.due()

    def service_net(self, tick: int, asleep: bool, knot_pos) -> None:
        """The cloth net's state at `tick` to every client, if NetFeed takes it."""
        for data in self.net.update(tick, asleep, knot_pos):
            self._broadcast(data, "nets")

    def _heartbeat(self, ack: int) -> bytes:
        """A heartbeat at the current tick acknowledging `ack` (seq set by _send): the fixed
        layout patched in place, not encoded anew for each of a thousand sessions."""
        beat = self._beat
        beat[16:24] = self.tick.to_bytes(8, "little", signed=True)
        beat[24:32] = ack.to_bytes(8, "little")
        return beat

    def broadcast_snapshot(self, record, input_seq=(0, 0)) -> None:
        try:
            data = wire.snapshot_from_physics(record, seq=0, input_seq=input_seq,
                                              realtime_factor=self.pacer.realtime_factor)
        except wire.WireError as err:
            self.counts["snapshots_unencodable"] += 1  # e.g. a bat beyond the wire's ranges
            self.counts[f"snapshots_unencodable.{err.reason}"] += 1
            return
        self._broadcast(data, "snapshots")
        if self.send_log is not None:
            self.send_log.sent(int(record["world"]["tick"]))
        if self.net is not None:
            self.net.snapshot_sent(int(record["world"]["tick"]))

    def _broadcast(self, data: bytes, what: str) -> None:
        """To every session, or with a feed: once on the feed (spectators) and to each player."""
        feed = self.feed
        if feed is not None:
            self.feed_seq += 1
            buf = bytearray(data)
            buf[8:16] = self.feed_seq.to_bytes(8, "little")
            feed.send(buf, flags=zmq.NOBLOCK)  # PUB never blocks: a full subscriber's copy is dropped
            self.counts[f"{what}_published"] += 1
        for session in list(self.sessions.values()):
            if feed is None or session.role == Role.PLAYER:
                self._send(session, data, what)

    def shutdown(self, reason: GoodbyeReason = GoodbyeReason.SHUTDOWN) -> int:
        """Goodbye to every session; returns how many were told."""
        self._stop_heartbeats()
        self.shutting_down = True
        told = 0
        for session in list(self.sessions.values()):
            self._goodbye(session, reason)
            told += 1
            self.sessions.pop(session.identity, None)
        return told

    def drain(self, seconds: float = STOP_DRAIN_S) -> None:
        """After shutdown(): go on answering for `seconds` of wall time, so that a hello which
        arrives while the server stops is rejected shutting_down rather than left unanswered
        (a later one finds the socket closed and ends in its sender's bounded wait). Anything
        else is the last of sessions already told goodbye: read and let go, not counted."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            if not self.router.poll(max(1, int(left * 1000)), zmq.POLLIN):
                continue
            frames = self.router.recv_multipart(flags=zmq.NOBLOCK, copy=True)
            if len(frames) == 2 and frames[1][:len(_HELLO_PREFIX)] == _HELLO_PREFIX:
                self.handle(frames)
            # else: the last heartbeats and goodbyes of sessions already told goodbye

    def close(self, linger_ms: int = 500) -> None:
        """Close the sockets; what is still queued (the goodbyes of shutdown) gets up to linger_ms
        to leave (linger 0 discarded them: `pingpong stress` saw bots miss their goodbye)."""
        self._stop_heartbeats()
        self.guard.close()
        self.router.close(linger=linger_ms)
        if self.feed is not None:
            self.feed_guard.close()
            self.feed.close(linger=0)  # a snapshot nobody took yet is worth nothing after the end


def _any_port(endpoint: str) -> str:
    """tcp://host:0 means any free port, which libzmq spells tcp://host:*."""
    return endpoint[:-2] + ":*" if endpoint.endswith(":0") else endpoint
