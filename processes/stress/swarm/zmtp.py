"""A peer that speaks ZMTP 3.0 itself (RFC 23/ZMTP, NULL mechanism) over a plain TCP socket, so it
can send what no libzmq socket sends: the frames of a multipart message that never ends.

A libzmq DEALER keeps a multipart message until its last frame and sends it whole; an attacker
writes the wire itself. The pingpong stress `abuse` scenario and the gateway's tests use this to
show the gateway bounds what such a peer makes it hold.
"""
from __future__ import annotations

import socket
import struct
import time

GREETING_BYTES = 64
FRAME_MORE, FRAME_LONG, FRAME_COMMAND = 0x01, 0x02, 0x04


def greeting() -> bytes:
    """ZMTP 3.0 greeting: signature, version 3.0, mechanism NULL, as-server 0, filler."""
    return b"\xff" + bytes(8) + b"\x7f" + bytes([3, 0]) + b"NULL".ljust(20, b"\0") + b"\0" + bytes(31)


def command(name: bytes, properties: dict[bytes, bytes]) -> bytes:
    """A ZMTP command frame (READY: its metadata properties)."""
    body = bytes([len(name)]) + name
    for key, value in properties.items():
        body += bytes([len(key)]) + key + struct.pack(">I", len(value)) + value
    return frame(body, more=False, flags=FRAME_COMMAND)


def frame(data: bytes, more: bool, flags: int = 0) -> bytes:
    """One ZMTP frame of `data` (MORE: another frame of the same message follows)."""
    flags |= FRAME_MORE if more else 0
    if len(data) < 256:
        return bytes([flags, len(data)]) + data
    return bytes([flags | FRAME_LONG]) + struct.pack(">Q", len(data)) + data


class RawPeer:
    """A DEALER (or, socket_type b"SUB", a feed subscriber) as seen on the wire: send(message)
    whole, or open_message(n, size) that sends n frames of a message and never its last one.
    Every wait is bounded (a send that makes no progress for timeout_s ends it)."""

    def __init__(self, host: str, port: int, timeout_s: float = 5.0, socket_type: bytes = b"DEALER"):
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        self.sock.sendall(greeting())
        got = b""
        while len(got) < GREETING_BYTES:
            chunk = self.sock.recv(GREETING_BYTES - len(got))
            if not chunk:
                raise ConnectionError("the server closed the connection during the ZMTP greeting")
            got += chunk
        self.sock.sendall(command(b"READY", {b"Socket-Type": socket_type}))

    def send(self, data: bytes) -> None:
        """One single-frame message."""
        self.sock.sendall(frame(data, more=False))

    def open_message(self, frames: int, size: int, deadline_s: float) -> int:
        """Send up to `frames` frames of `size` bytes, each with MORE set (the message never
        ends), until the server cuts the connection or deadline_s passes; returns the bytes sent."""
        chunk = frame(bytes(size), more=True) * 16
        sent = 0
        end = time.monotonic() + deadline_s
        try:
            for _ in range(0, frames, 16):
                if time.monotonic() > end:
                    break
                self.sock.sendall(chunk)
                sent += len(chunk)
        except OSError:  # cut by the server: what it is meant to do
            pass
        return sent

    def closed_by_server(self, timeout_s: float) -> bool:
        """Whether the server ends the connection within timeout_s (reads and drops what it sends)."""
        self.sock.settimeout(timeout_s)
        end = time.monotonic() + timeout_s
        try:
            while time.monotonic() < end:
                if not self.sock.recv(65536):
                    return True
        except socket.timeout:
            return False
        except OSError:
            return True
        return False

    def close(self) -> None:
        self.sock.close()
