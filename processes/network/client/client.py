"""The network client: a session with the gateway (DEALER socket) and its spectator feed (SUB).

A client says hello, waits (bounded) for welcome or reject, then exchanges wire messages: it
sends a heartbeat at least as often as the welcome asks, inputs for its own bat, and goodbye
when it leaves; it takes snapshots, events, heartbeats and the server's goodbye. Every wait is
bounded and a server silent past the welcome's timeout ends the session. A spectator whose
welcome names a feed (welcome.feed_port) subscribes to it (a SUB socket, CURVE like the
session) and takes its snapshots and events there; the session still carries heartbeats and
goodbye, and only the session says whether the server is alive. Gaps in the feed's sequence
numbers are the messages the gateway dropped at the high-water mark (`feed_missed`). Told
goodbye unknown_session (a restarted gateway lost the session), a client says hello again at
once, a player with its token; the welcome that answers goes on with the session.

CURVE keys (`pingpong keys DIR`) make the session encrypted and the server authenticated.
"""
from __future__ import annotations

import re
import time
from collections import deque

import numpy as np
import zmq

from processes.network import wire
from processes.network.wire import NO_TOKEN, GoodbyeReason, InputMode, Kind, Role, Slot

JOIN_TIMEOUT_S = 10.0
HELLO_AGAIN_S = 1.0  # s without an answer after which join says hello again
RETRY_IN = re.compile(r"retry in ([0-9.]+) s")  # a `full` reject's hint (docs/protocol.md)


def load_curve_key(path: str, secret: bool) -> tuple[bytes, bytes | None]:
    """(public, secret) Z85 keys from a ZeroMQ certificate file (zmq.auth.create_certificates,
    `pingpong keys DIR`); secret=True needs the secret file (NAME.key_secret)."""
    import zmq.auth

    try:
        public, secret_key = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: not a ZeroMQ certificate ({err}); make one with `pingpong keys DIR`") from None
    if public is None or len(public) != 40:
        raise ValueError(f"{path}: no 40-character Z85 public key in it; make one with `pingpong keys DIR`")
    if secret and (secret_key is None or len(secret_key) != 40):
        raise ValueError(f"{path}: no secret key in it; the server needs the .key_secret file of `pingpong keys DIR`")
    return public, secret_key


def curve_client_options(server_key_file: str | None) -> dict:
    """Socket options of a CURVE client of the server whose public key is in that file (a fresh
    key pair of our own each session; the server authenticates itself, the session is
    encrypted); {} without a file."""
    if not server_key_file:
        return {}
    if not zmq.has("curve"):
        raise ValueError("this libzmq has no CURVE support; install pyzmq's wheel (it bundles libsodium)")
    server_public, _ = load_curve_key(server_key_file, secret=False)
    public, secret = zmq.curve_keypair()
    return {zmq.CURVE_SERVERKEY: server_public, zmq.CURVE_PUBLICKEY: public, zmq.CURVE_SECRETKEY: secret}


def feed_address(session_address: str, port: int) -> str:
    """The feed's endpoint: the session's tcp:// host with the welcome's feed_port."""
    if not session_address.startswith("tcp://") or not 0 < port < 65536:
        raise ValueError(f"a feed on port {port} needs a tcp:// session address, got {session_address!r}")
    return f"{session_address.rsplit(':', 1)[0]}:{port}"


class Rejected(RuntimeError):
    """The server turned the hello away; `reason` is a wire.RejectReason."""

    def __init__(self, reason, detail: str):
        super().__init__(f"rejected: {reason.name.lower()}: {detail}")
        self.reason = reason
        self.detail = detail

    @property
    def retry_s(self) -> float | None:
        """When the server says a place may be free (a `full` reject's detail ends `retry in N s`,
        docs/protocol.md), in s; None if it does not say."""
        found = RETRY_IN.search(self.detail)
        return float(found.group(1)) if found else None


class Client:
    """One session with a gateway.

    Args:
        address: the server's ZeroMQ endpoint. role: "player" or "spectator". name: shown to others.
        slot: the seat wanted (Slot.NONE: any). token: a rejoin token from an earlier welcome.
        zctx: a zmq.Context (a new one by default, terminated on close).
        socket_options: extra {zmq option: value} set before connecting (the session's socket
            and the feed's: CURVE keys, buffers). feed_options: more for the feed's socket only
            (e.g. zmq.AFFINITY: a process of many clients reads its feeds on an I/O thread of
            their own, so its heartbeats do not queue behind them).
    """

    def __init__(self, address: str, role: str = "spectator", name: str = "client", slot: Slot = Slot.NONE,
                 token: bytes = NO_TOKEN, zctx=None, socket_options: dict | None = None,
                 feed_options: dict | None = None):
        self.address = address
        self.role = Role.PLAYER if role == "player" else Role.SPECTATOR
        self.name = name
        self.wanted = slot
        self.token = token
        self._own_ctx = zctx is None
        self.zctx = zctx or zmq.Context()
        self.socket_options = dict(socket_options or {})
        self.feed_options = dict(feed_options or {})
        self.sock = self.zctx.socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.setsockopt(zmq.RCVHWM, 256)
        for option, value in self.socket_options.items():
            self.sock.setsockopt(option, value)
        self.sock.connect(address)
        self.feed = None  # the SUB socket of a spectator's feed, once a welcome names one
        self.feed_address = ""
        self.feed_seq = 0  # last seq seen on the feed
        self.feed_missed = 0  # gaps in the feed's seqs: messages dropped at the gateway's high-water mark
        self._poller = zmq.Poller()
        self._poller.register(self.sock, zmq.POLLIN)
        self.seq = 0
        self.tick = 0
        self.slot = Slot.NONE
        self.welcome: wire.Message | None = None
        self.drops = wire.DropCounter()
        self.received = 0
        self.goodbye: GoodbyeReason | None = None
        self.last_data = b""  # the bytes of the last valid message received
        self.rejoins = 0  # hellos again after a goodbye unknown_session (a restarted gateway)
        self.rejected = None  # the RejectReason that ended a rejoin, if one did
        self.last_seen = time.monotonic()
        self._next_beat = 0.0
        self.heartbeat_s = 0.5
        self.timeout_s = 5.0
        self.max_seq_in = 0
        self._held: deque[wire.Message] = deque()  # messages that came while request_scene waited

    def send(self, kind, header_tick: int | None = None, **fields) -> None:
        """One message, header tick our estimate of the server's (or header_tick)."""
        self.seq += 1
        tick = self.tick if header_tick is None else header_tick
        self.sock.send(wire.encode(kind, seq=self.seq, tick=tick, **fields), flags=zmq.NOBLOCK)

    def send_raw(self, data: bytes) -> None:
        """Bytes as they are (tests of the gateway's validation)."""
        self.sock.send(data, flags=zmq.NOBLOCK)

    def hello(self) -> None:
        """Ask for a seat (or to watch); the answer comes as a welcome or a reject (see accept)."""
        token = self.token if self.role == Role.PLAYER else NO_TOKEN
        self.send(Kind.HELLO, header_tick=0, role=self.role,  # a hello's header tick is 0, also on a rejoin
                  slot=self.wanted if self.role == Role.PLAYER else Slot.NONE, name=self.name, token=token)

    def accept(self, message: wire.Message) -> bool:
        """Take the server's answer to the hello: True on a welcome, Rejected on a reject,
        False for anything else."""
        if message.kind == Kind.REJECT:
            raise Rejected(message["reason"], message["detail"])
        if message.kind != Kind.WELCOME:
            return False
        self.welcome = message
        self.goodbye = self.rejected = None  # a new session (a rejoin's welcome)
        self.slot = message["slot"]
        self.token = message["token"]
        self.heartbeat_s = message["heartbeat_ms"] / 1000.0
        # the document's rule: a server silent for max(timeout_ms, SERVER_SILENCE_BEATS heartbeats) is gone
        self.timeout_s = max(message["timeout_ms"], wire.SERVER_SILENCE_BEATS * message["heartbeat_ms"]) / 1000.0
        self.subscribe(message["feed_port"])
        # a heartbeat at once: the server keeps the place of a session that answered its welcome
        self.send(Kind.HEARTBEAT, ack=message.seq)
        self._next_beat = time.monotonic() + self.heartbeat_s
        return True

    def subscribe(self, port: int) -> None:
        """Take snapshots and events from the feed on `port` of the session's host (0: none,
        they come on the session). A welcome of a restarted gateway may name another port: the
        old feed is closed and the new one subscribed."""
        address = feed_address(self.address, port) if port else ""
        if address == self.feed_address:
            return
        if self.feed is not None:
            self._poller.unregister(self.feed)
            self.feed.close(linger=0)
            self.feed = None
        self.feed_address, self.feed_seq = address, 0
        if not address:
            return
        feed = self.zctx.socket(zmq.SUB)
        feed.setsockopt(zmq.LINGER, 0)
        feed.setsockopt(zmq.RCVHWM, 256)
        for option, value in {**self.socket_options, **self.feed_options}.items():
            feed.setsockopt(option, value)
        feed.setsockopt(zmq.SUBSCRIBE, b"")
        feed.connect(address)
        self.feed = feed
        self._poller.register(feed, zmq.POLLIN)

    def _waiting(self, timeout_ms: int):
        """The sockets with a message waiting (the session first), after at most timeout_ms."""
        if self.feed is None:
            return [self.sock] if self.sock.poll(timeout_ms, zmq.POLLIN) else []
        ready = dict(self._poller.poll(timeout_ms))
        return [sock for sock in (self.sock, self.feed) if sock in ready]

    def join(self, timeout_s: float = JOIN_TIMEOUT_S) -> wire.Message:
        """Say hello and wait (bounded) for the welcome; raises Rejected or TimeoutError.

        Unanswered for HELLO_AGAIN_S, it says hello again: a server at its connection limit may
        cut a connection before it read the hello on it, and libzmq's reconnection does not
        resend what the kernel had taken (a hello that did arrive makes the second one a
        hello within a session, which the server refuses and counts, nothing more)."""
        self.hello()
        deadline = time.monotonic() + timeout_s
        again = time.monotonic() + HELLO_AGAIN_S
        while time.monotonic() < deadline:
            message = self.recv(int(1000 * min(0.2, max(deadline - time.monotonic(), 0.0))) + 1)
            if message is not None and self.accept(message):
                return message
            if time.monotonic() >= again:
                again += HELLO_AGAIN_S
                self.hello()
        raise TimeoutError(f"no welcome from {self.address} within {timeout_s} s")

    def request_scene(self, timeout_s: float = JOIN_TIMEOUT_S) -> str:
        """The served scene's TOML text, asked for with scene_request (the welcome's digest) and
        joined from the scene_part answers; what else arrives meanwhile is kept for recv. Asks
        once more halfway through timeout_s (a part may have been dropped at the server's
        high-water mark). Raises TimeoutError, or wire.OutOfRange for parts that do not fit
        together."""
        digest = self.welcome["scene_digest"]
        assembly = wire.SceneAssembly(digest)
        self.send(Kind.SCENE_REQUEST, digest=digest)
        start = time.monotonic()
        deadline, again = start + timeout_s, start + timeout_s / 2
        while (now := time.monotonic()) < deadline:
            if again is not None and now >= again:
                again = None
                self.send(Kind.SCENE_REQUEST, digest=digest)
            self.heartbeat_if_due()
            message = self._receive(int(1000 * min(0.1, deadline - now)) + 1)
            if message is None:
                continue
            if message.kind != Kind.SCENE_PART:
                self._held.append(message)
                if self.goodbye is not None:  # the session ended meanwhile: no scene will come
                    raise TimeoutError(f"{self.address} said goodbye ({self.goodbye.name.lower()}) before it "
                                       "sent the scene")
            elif (text := assembly.add(message)) is not None:
                return text
        raise TimeoutError(f"no scene from {self.address} within {timeout_s} s (parts {sorted(assembly.parts)} of "
                           f"{assembly.count or '?'} came)")

    def recv(self, timeout_ms: int) -> wire.Message | None:
        """The next valid message within timeout_ms, session or feed, or None (bad ones are
        counted and dropped)."""
        if self._held:
            return self._held.popleft()
        return self._receive(timeout_ms)

    def _receive(self, timeout_ms: int) -> wire.Message | None:
        waiting = self._waiting(timeout_ms)
        if not waiting:
            return None
        sock = waiting[0]
        try:
            data = sock.recv(flags=zmq.NOBLOCK)
        except zmq.Again:
            return None
        message = self.drops.decode(data)
        if message is None:
            return None
        self.last_data = data  # the message's own bytes (the web bridge forwards them unchanged)
        self.received += 1
        self.tick = max(self.tick, message.tick)
        if sock is self.feed:
            if message.kind not in (Kind.SNAPSHOT, Kind.EVENT, Kind.NET):
                self.drops.by_reason["not_on_feed"] += 1  # only snapshots, events and nets go out on the feed
                return None
            if self.feed_seq and message.seq > self.feed_seq:
                self.feed_missed += message.seq - self.feed_seq - 1
            self.feed_seq = message.seq
            return message
        self.last_seen = time.monotonic()  # only the session says the server is alive
        self.max_seq_in = max(self.max_seq_in, message.seq)
        if message.kind == Kind.GOODBYE and message["reason"] == GoodbyeReason.UNKNOWN_SESSION and self.welcome:
            self.rejoins += 1
            self.hello()  # a restarted gateway lost our session: hello again (a player with its token)
        elif message.kind == Kind.GOODBYE:
            self.goodbye = message["reason"]
        elif message.kind == Kind.WELCOME and self.welcome is not None:
            self.accept(message)  # the answer to the hello of a rejoin
        elif message.kind == Kind.REJECT and self.welcome is not None:
            self.rejected = message["reason"]  # a rejoin turned away (the token expired, or the seat
            self.goodbye = GoodbyeReason.UNKNOWN_SESSION  # is gone): the session is over
        return message

    def recv_batch(self, timeout_ms: int, limit: int = 256) -> list[wire.Message]:
        """Every valid message waiting (at most `limit`), waiting at most timeout_ms for the
        first: a loop that handles them all at once never falls behind the server."""
        messages = []
        if not self._held and not self._waiting(timeout_ms):
            return messages
        for _ in range(limit):
            message = self.recv(0)
            if message is not None:
                messages.append(message)
            elif not self._held and not self._waiting(0):
                break
        return messages

    def heartbeat_if_due(self) -> None:
        now = time.monotonic()
        if now >= self._next_beat:
            self._next_beat = now + self.heartbeat_s
            self.send(Kind.HEARTBEAT, ack=self.max_seq_in)

    @property
    def server_lost(self) -> bool:
        return time.monotonic() - self.last_seen > self.timeout_s

    def send_input(self, inputs, tick: int | None = None, slot: Slot | None = None) -> None:
        """Force (N) and torque (N m), world frame, for our bat (slot: tests may name another)."""
        inputs = np.asarray(inputs, dtype=np.float64)
        if tick is not None:
            self.tick = tick
        self.send(Kind.INPUT, slot=self.slot if slot is None else slot, mode=InputMode.FORCE, force=inputs[0:3],
                  torque=inputs[3:6], target_pos=np.zeros(3), target_quat=np.zeros(4))

    def leave(self) -> None:
        try:
            self.send(Kind.GOODBYE, reason=GoodbyeReason.QUIT)
        except zmq.ZMQError:
            pass

    def close(self) -> None:
        if self.feed is not None:
            self.feed.close(linger=0)
        self.sock.close(linger=0)
        if self._own_ctx:
            self.zctx.term()
