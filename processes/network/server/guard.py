"""ConnectionGuard: what one TCP connection can make libzmq hold in the gateway, bounded.

libzmq bounds a frame (ZMQ_MAXMSGSIZE) and the complete messages queued from a peer
(ZMQ_RCVHWM), but not the frames of one message: a peer that opens a multipart message and
never ends it makes its pipe keep every frame it sends, because the pipe counts a message
towards the high-water mark only at its last frame and keeps the frames before it unflushed
(libzmq src/pipe.cpp pipe_t::write, src/ypipe.hpp); ZMQ_MAXMSGSIZE applies to each frame
alone (libzmq issue #4526 and the zmq_setsockopt docs). Nothing reaches the application
until the message ends, so the gateway cannot see such a peer in what it receives.

It can see it in the kernel's counters. For every connection the ROUTER accepted (its socket
monitor reports the descriptor), the bytes libzmq has read from it are the TCP connection's
bytes received (TCP_INFO tcpi_bytes_received) less those still in the socket's receive queue
(FIONREAD). The gateway reports what it took out of each connection (ZMQ_SRCFD of the frames it
receives), so the difference is what libzmq holds for that peer: its queued messages, at most
ZMQ_RCVHWM of them, and an unfinished message. A connection holding more than the limit is
shut down (shutdown(2) on a duplicate of its descriptor: libzmq sees the connection end and
frees its pipe, the unfinished frames with it) and counted; so is a connection beyond the
most the gateway keeps open. The memory is then given back to the system (glibc malloc_trim:
the freed frames sit in the I/O thread's malloc arena, which glibc does not trim by itself).

The guard runs on a thread of its own and looks every GUARD_PERIOD_S: at the connections
whenever the gateway's resident memory grew by SCAN_GROWTH_BYTES since it last looked, and at
least every SCAN_EVERY_S. It touches only its monitor socket and the descriptors' duplicates,
never the ROUTER itself (ZeroMQ sockets are not thread-safe).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import fcntl
import os
import socket
import struct
import termios
import threading
import time
from collections import Counter

import zmq
from zmq.utils.monitor import parse_monitor_message

GUARD_PERIOD_S = 0.005  # s between two looks at the gateway's memory
SCAN_GROWTH_BYTES = 8 << 20  # resident growth that makes the guard look at every connection at once
SCAN_EVERY_S = 1.0  # the guard looks at every connection at least this often
TRIM_EVERY_S = 1.0  # memory of closed connections is given back at most this often
# What a connection carries besides the messages the gateway takes: the ZMTP greeting (64 bytes)
# and handshake (NULL: READY with its properties; CURVE: HELLO 200, INITIATE 257 and metadata),
HANDSHAKE_BYTES = 4096
# each frame's header (at most 9 bytes) and, with CURVE, its box (MESSAGE command, nonce, MAC: 33),
FRAME_OVERHEAD_BYTES = 64
# and the ZMTP PING commands a peer may send (ZMQ_HEARTBEAT_IVL), which never become messages.
IDLE_BYTES_PER_S = 64
_TCPI_BYTES_RECEIVED = 128  # offset of tcpi_bytes_received in struct tcp_info (linux/tcp.h, Linux 4.1+)
_PAGE = os.sysconf("SC_PAGE_SIZE")


def resident_bytes() -> int:
    """This process's resident memory (bytes), from /proc/self/statm."""
    with open("/proc/self/statm", "rb") as f:
        return int(f.read().split()[1]) * _PAGE


def _libc_trim():
    """glibc's malloc_trim, or None (another C library)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


_MALLOC_TRIM = _libc_trim()


def give_back_memory() -> None:
    """Return the freed memory of every malloc arena to the system (glibc; elsewhere nothing)."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def connection_bytes(fd: int) -> tuple[int, int] | None:
    """(bytes the TCP connection `fd` received, bytes of them not yet read), or None when `fd`
    is no longer a TCP socket of this process (closed meanwhile)."""
    try:
        sock = socket.socket(fileno=os.dup(fd))
    except OSError:
        return None
    try:
        info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 256)
        unread = struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]
    except OSError:
        return None
    finally:
        sock.close()  # the duplicate only: the connection stays libzmq's
    if len(info) < _TCPI_BYTES_RECEIVED + 8:
        return None
    return struct.unpack_from("<Q", info, _TCPI_BYTES_RECEIVED)[0], unread


def cut(fd: int) -> bool:
    """End the TCP connection `fd` (libzmq then closes it as if the peer had); False if it is gone."""
    try:
        sock = socket.socket(fileno=os.dup(fd))
    except OSError:
        return False
    try:
        sock.shutdown(socket.SHUT_RDWR)
        return True
    except OSError:
        return False
    finally:
        sock.close()


class ConnectionGuard:
    """Bounds the bytes libzmq holds for each connection of `router`, and the connections.

    Args:
        router: the gateway's ROUTER, before it binds (the monitor must see every accept).
        held_limit: bytes libzmq may hold for one connection (its queued messages and an
            unfinished one) before the guard cuts it.
        max_connections: connections kept open at once; a later one is cut at once.
        prefix: of its counters' names (the feed's guard: "feed_").

    The gateway calls took(fd, nbytes) for every message it receives (from its own thread),
    start() once bound and close() before closing the ROUTER. counts: connections cut, by
    reason (disconnected.held_bytes, disconnected.too_many_connections,
    disconnected.unconfirmed_for_newcomer), and memory trims.

    newcomer_grace_s: at the connection limit, a newcomer takes the place of the connection
    that has carried no message of a confirmed session (valued()) for longest, if that is more
    than this long, and is cut itself only when there is none: a peer's connections that never
    answer a welcome (a hoarder's, reconnecting as fast as it is cut) cannot keep honest
    newcomers out. Every newcomer gets this grace to confirm. None: the newcomer is cut (the
    feed, whose subscribers send nothing to value them by).
    """

    def __init__(self, router, held_limit: int, max_connections: int, prefix: str = "",
                 newcomer_grace_s: float | None = None):
        self.held_limit = held_limit
        self.prefix = prefix
        self.max_connections = max_connections
        self.newcomer_grace_s = newcomer_grace_s
        self.counts: Counter[str] = Counter()
        self.delivered: dict[int, int] = {}  # fd -> bytes taken from it, framing included (the gateway's thread)
        self._valued: dict[int, float] = {}  # fd -> when it last carried a confirmed session's message (or was accepted)
        self._router = router
        self._monitor = router.get_monitor_socket(zmq.EVENT_ACCEPTED | zmq.EVENT_DISCONNECTED)
        self._open: dict[int, tuple[float, int]] = {}  # fd -> (accepted at, delivered[fd] then)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed_since_trim = False
        self._next_trim = 0.0

    def took(self, fd: int, nbytes: int) -> None:
        """The gateway took a message of nbytes (all its frames, framing allowance included) from fd."""
        self.delivered[fd] = self.delivered.get(fd, 0) + nbytes

    def valued(self, fd: int, now: float) -> None:
        """fd carried a message of a session that answered its welcome (the gateway's thread)."""
        self._valued[fd] = now

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="gateway-guard", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop looking (the thread ends within GUARD_PERIOD_S) and close the monitor."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(5.0)
        self._thread = None
        try:
            self._router.disable_monitor()
        except zmq.ZMQError:
            pass
        self._monitor.close(linger=0)

    @property
    def connections(self) -> int:
        return len(self._open)

    @property
    def connections_unconfirmed(self) -> int:
        """Open connections a newcomer at the limit would take the place of (none without a grace)."""
        if self.newcomer_grace_s is None:
            return 0
        since = time.monotonic() - self.newcomer_grace_s
        return sum(self._valued.get(fd, at) < since for fd, (at, _) in list(self._open.items()))

    def _run(self) -> None:
        scanned_rss = resident_bytes()
        next_scan = time.monotonic() + SCAN_EVERY_S
        while not self._stop.wait(GUARD_PERIOD_S):
            now = time.monotonic()
            self._events(now)
            rss = resident_bytes()
            if rss < scanned_rss + SCAN_GROWTH_BYTES and now < next_scan:
                continue
            if self.scan(now) or (self._closed_since_trim and now >= self._next_trim):
                give_back_memory()
                self.counts[f"{self.prefix}memory_trims"] += 1
                self._closed_since_trim = False
                self._next_trim = now + TRIM_EVERY_S
            scanned_rss = resident_bytes()
            next_scan = now + SCAN_EVERY_S

    def _events(self, now: float) -> None:
        """The monitor's accepts and disconnects since the last look."""
        stale: list[tuple[float, int]] | None = None  # made once a look, when the first newcomer needs it
        while self._monitor.poll(0):
            event = parse_monitor_message(self._monitor.recv_multipart())
            fd = int(event["value"])
            if event["event"] != zmq.EVENT_ACCEPTED:
                self._open.pop(fd, None)
                self._valued.pop(fd, None)
                self._closed_since_trim = True
                continue
            self._open[fd] = (now, self.delivered.get(fd, 0))
            self._valued[fd] = now  # a newcomer's grace to say hello and answer its welcome
            if len(self._open) <= self.max_connections:
                continue
            if self.newcomer_grace_s is not None and stale is None:
                stale = self._stale(now)
            victim = self._victim(stale, now) if stale else None
            if victim is not None and cut(victim):
                self._open.pop(victim)
                self.counts[f"{self.prefix}disconnected.unconfirmed_for_newcomer"] += 1
            elif cut(fd):
                self._open.pop(fd)
                self.counts[f"{self.prefix}disconnected.too_many_connections"] += 1

    def _stale(self, now: float) -> list[tuple[float, int]]:
        """The open connections that carried no confirmed session's message within the grace,
        the longest silent last (popped first)."""
        since = now - self.newcomer_grace_s
        return sorted(((self._valued.get(fd, at), fd) for fd, (at, _) in self._open.items()
                       if self._valued.get(fd, at) < since), reverse=True)

    def _victim(self, stale: list[tuple[float, int]], now: float) -> int | None:
        since = now - self.newcomer_grace_s
        while stale:
            _, fd = stale.pop()
            if fd in self._open and self._valued.get(fd, 0.0) < since:  # still open, still silent
                return fd
        return None

    def scan(self, now: float) -> int:
        """Cut every connection that makes libzmq hold more than held_limit; returns how many."""
        cuts = 0
        for fd, (since, base) in list(self._open.items()):
            got = connection_bytes(fd)
            if got is None:
                continue
            received, unread = got
            allowed = self.held_limit + HANDSHAKE_BYTES + int(IDLE_BYTES_PER_S * (now - since))
            held = received - unread - (self.delivered.get(fd, 0) - base)
            if held > allowed and cut(fd):
                self._open.pop(fd, None)
                self.counts[f"{self.prefix}disconnected.held_bytes"] += 1
                cuts += 1
        return cuts
