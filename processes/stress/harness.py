"""The run harness of `pingpong stress`: child processes speaking JSON lines, the bots, a TCP proxy
that can pull the cable, and the Run that kills and reaps all of them whatever happened."""
from __future__ import annotations

import json
import os
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from processes.runtime import shm

ROOT = Path(__file__).resolve().parents[2]


class StressError(RuntimeError):
    """A process of the harness did not do what it had to within its bound."""


class Child:
    """A child process speaking JSON lines on stdout; killed (its whole session) on close."""

    def __init__(self, args: list[str], name: str):
        self.name = name
        self.proc = subprocess.Popen([sys.executable, *args], cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, start_new_session=True)
        self.pid = self.proc.pid
        self.lines: list[dict] = []
        self.pending: list[dict] = []
        self._buf = ""
        self.stderr_tail = ""

    def read(self, timeout: float) -> dict | None:
        """The next JSON line within timeout, or None."""
        deadline = time.monotonic() + timeout
        while "\n" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            sel = selectors.DefaultSelector()
            sel.register(self.proc.stdout, selectors.EVENT_READ)
            ready = sel.select(min(left, 0.5))
            sel.close()
            if ready:
                chunk = os.read(self.proc.stdout.fileno(), 65536).decode()
                if not chunk:
                    return None
                self._buf += chunk
        line, self._buf = self._buf.split("\n", 1)
        try:
            obj = json.loads(line)
        except json.JSONDecodeError:
            return {"_text": line}
        self.lines.append(obj)
        return obj

    def expect(self, predicate, timeout: float, what: str) -> dict:
        """The first line, read or still pending, that satisfies predicate; the others stay pending."""
        for obj in self.pending:
            if predicate(obj):
                self.pending.remove(obj)
                return obj
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            obj = self.read(deadline - time.monotonic())
            if obj is None:
                if self.proc.poll() is not None:
                    break
                continue
            if predicate(obj):
                return obj
            self.pending.append(obj)
        raise StressError(f"{self.name} (pid {self.pid}): no {what} within {timeout:.0f} s; "
                          f"exit {self.proc.poll()}; stderr: {self.stderr()[-1500:]}")

    def send(self, line: str) -> None:
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise StressError(f"{self.name} (pid {self.pid}) is gone: exit {self.proc.poll()}; stderr: "
                              f"{self.stderr()[-1500:]}") from None

    def stderr(self) -> str:
        if self.proc.poll() is not None and not self.stderr_tail:
            try:
                self.stderr_tail = self.proc.stderr.read()
            except (OSError, ValueError):
                pass
        return self.stderr_tail

    def wait(self, timeout: float) -> int | None:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def kill(self) -> None:
        if self.proc.poll() is None:
            try:
                os.killpg(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.wait(10)

    def close(self) -> None:
        self.kill()
        self.stderr()
        for stream in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            try:
                stream.close()
            except (OSError, ValueError, BrokenPipeError):
                pass


BOT_JOIN_TIMEOUT_S = 300.0  # a bound, not a guess: on a busy machine the welcome may take many seconds


def bot(endpoint: str, seconds: float, seed: int) -> Child:
    return Child(["-m", "processes.cli", "join", endpoint, "--as", "player", "--bot", "--json", "--seconds",
                  str(seconds), "--seed", str(seed), "--join-timeout", str(BOT_JOIN_TIMEOUT_S)], f"bot{seed}")


def until(predicate, timeout: float, poll_s: float = 0.1) -> bool:
    """Poll a condition on other processes (bounded); True once it holds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(poll_s)  # polling the state of other processes, bounded
    return predicate()


# --- the cable: a TCP proxy that can black-hole its traffic ---------------------------------------
class Proxy(threading.Thread):
    """127.0.0.1 TCP proxy to `target_port`; black_hole() stops all forwarding with every
    connection kept open (a pulled cable), restore() resumes it (what was held passes then)."""

    def __init__(self, target_port: int):
        super().__init__(name="stress-proxy", daemon=True)
        self.target = ("127.0.0.1", target_port)
        self.listener = socket.socket()
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(64)
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.sel = selectors.DefaultSelector()
        self.sel.register(self.listener, selectors.EVENT_READ, None)
        self.pairs: list[tuple[socket.socket, socket.socket]] = []
        self.blocked = threading.Event()
        self.stopping = threading.Event()
        self.forwarded = 0

    def run(self) -> None:
        while not self.stopping.is_set():
            for key, _ in self.sel.select(0.05):
                if key.data is None:
                    try:
                        client, _ = self.listener.accept()
                    except BlockingIOError:
                        continue
                    upstream = socket.create_connection(self.target, timeout=5)
                    for a, b in ((client, upstream), (upstream, client)):
                        a.setblocking(False)
                        self.sel.register(a, selectors.EVENT_READ, b)
                    self.pairs.append((client, upstream))
                    continue
                if self.blocked.is_set():
                    continue  # unread: the kernel buffers fill and nothing passes
                src, dst = key.fileobj, key.data
                try:
                    data = src.recv(65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:
                    self._drop(src)
                    continue
                dst.setblocking(True)
                try:
                    dst.sendall(data)
                    self.forwarded += len(data)
                except OSError:
                    self._drop(src)
                finally:
                    if dst.fileno() >= 0:
                        dst.setblocking(False)
            if self.blocked.is_set():
                self.stopping.wait(0.005)  # the selector reports the unread sockets at once

    def _drop(self, sock) -> None:
        for pair in [p for p in self.pairs if sock in p]:
            self.pairs.remove(pair)
            for s in pair:
                try:
                    self.sel.unregister(s)
                except (KeyError, ValueError):
                    pass
                s.close()

    def black_hole(self) -> None:
        self.blocked.set()

    def restore(self) -> None:
        self.blocked.clear()

    def close(self) -> None:
        self.stopping.set()
        self.join(5)
        for pair in list(self.pairs):
            self._drop(pair[0])
        self.sel.close()
        self.listener.close()


@dataclass
class Run:
    """What every scenario shares: a temp dir, its children, and the cleanup of all of them."""

    tmp: str
    children: list

    def add(self, child: Child) -> Child:
        self.children.append(child)
        return child

    def close(self) -> list[str]:
        """Kill every child (whole sessions, so a server's resource tracker dies too) and remove
        what a killed server left in /dev/shm; returns those segment names."""
        for child in self.children:
            child.close()
        left = []
        for child in self.children:
            run_id = getattr(child, "run_id", None)
            if run_id:
                for name in shm.leftover_segments(run_id):
                    left.append(name)
                    try:
                        os.unlink(shm.SHM_DIR / name)
                    except FileNotFoundError:
                        pass
        return left

