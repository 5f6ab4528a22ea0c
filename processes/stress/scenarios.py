"""`pingpong stress`: a real server and a swarm of client processes, scenario by scenario, with a report.

Each scenario starts its own server (processes/stress_server.py: the Supervisor with its gateway and
physics workers, as `pingpong serve` runs it, plus a tick clock) and client processes
(processes/stress_swarm.py, many ZeroMQ clients each; bots are `pingpong join --bot`), all on
127.0.0.1, every wait bounded, every process killed and reaped at the end whatever happened.

- load: N spectators watch while two bots play a match of `duration` seconds; per-client
  snapshot rate, latency (server tick -> client receipt), snapshots missed, tick jitter, CPU.
- churn: join/leave cycles (players claim and free seats, spectators come and go, some leave
  without goodbye); then every seat and spectator place must be free again: a fill to exactly
  the limit is welcomed and one more is told "full".
- cable: traffic of a player and a spectator black-holed by a local TCP proxy (connections open,
  nothing passes), a second player silent with its socket open: the heartbeat timeout frees the
  seats, the token reclaims a seat within the grace, anyone after it.
- kill: SIGKILL a swarm process and a bot mid-match, then the gateway, then the physics worker:
  the supervisor restarts each, clients join again, no point is lost; then every slot is
  filled and the server shut down: every client gets goodbye.
- malformed: N bad messages of every class; the gateway's own counters (reported at the end of
  the match) must equal what the sender computed with wire.decode on the same bytes.

Invariants become `problems` (empty when the scenario passes). Numbers that depend on the machine
(rates, latency, jitter, CPU) are reported, never asserted.
"""
from __future__ import annotations

import argparse
import json
import os
import selectors
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processes.runtime import shm

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ("load", "churn", "cable", "kill", "malformed")
PER_SWARM = 250  # clients per swarm process (each one socket, two descriptors)
CLK_TCK = os.sysconf("SC_CLK_TCK")


class StressError(RuntimeError):
    """A process of the harness did not do what it had to within its bound."""


# --- /proc ----------------------------------------------------------------------------------------
def cpu_seconds(pid: int) -> float | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime, stime (fields 14, 15)


def fd_count(pid: int) -> int | None:
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None


def rss_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def shm_names() -> set[str]:
    return set(os.listdir("/dev/shm")) if os.path.isdir("/dev/shm") else set()


def thread_cpu_seconds(pid: int) -> dict[str, float]:
    """CPU seconds of each thread of a process, summed by thread name (/proc/PID/task/TID/stat:
    the Python thread is named like its program, libzmq's are ZMQbg/IO/0, ZMQbg/Reaper)."""
    out: dict[str, float] = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            text = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
        except OSError:
            continue
        name = text[text.index("(") + 1:text.rindex(")")]
        fields = text.rsplit(")", 1)[1].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / CLK_TCK
    return out


class CpuMeter:
    """CPU time of named processes between start() and stop(), as % of one core; for the
    processes named in `threads`, also per thread name (e.g. the gateway's libzmq I/O thread)."""

    def __init__(self, threads=()):
        self.t0 = 0.0
        self.threads = set(threads)
        self.start_cpu: dict[str, tuple[int, float]] = {}
        self.start_threads: dict[str, tuple[int, dict]] = {}
        self.result: dict[str, float] = {}

    def start(self, pids: dict[str, int]) -> None:
        self.t0 = time.monotonic()
        self.start_cpu = {name: (pid, cpu_seconds(pid)) for name, pid in pids.items() if cpu_seconds(pid) is not None}
        self.start_threads = {name: (pid, thread_cpu_seconds(pid)) for name, pid in pids.items() if name in self.threads}

    def stop(self) -> dict[str, float | None]:
        """% of one core per process; None for one that exited meanwhile (a match that ended
        early takes its server's processes with it: their CPU time is gone with them)."""
        wall = max(time.monotonic() - self.t0, 1e-9)
        for name, (pid, c0) in self.start_cpu.items():
            c1 = cpu_seconds(pid)
            self.result[name] = None if c1 is None else round(100.0 * (c1 - c0) / wall, 1)
        for name, (pid, before) in self.start_threads.items():
            for thread, c1 in thread_cpu_seconds(pid).items():
                self.result[f"{name}[{thread}]"] = round(100.0 * (c1 - before.get(thread, 0.0)) / wall, 1)
        self.result["_wall_s"] = round(wall, 2)
        return self.result


# --- child processes ------------------------------------------------------------------------------
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


class Server(Child):
    """processes/stress_server.py: a served match; `state()` asks it for pids, restarts and score."""

    def __init__(self, tmp: str, players: int = 2, snapshot_hz: int = 120, heartbeat_s: float = 0.5,
                 timeout_s: float = 5.0, grace_s: float = 30.0, max_spectators: int = 64, seconds: float = 3600.0,
                 best_of: int = 9, feed: bool = True):
        stamp = time.monotonic_ns()
        self.tick_log = os.path.join(tmp, f"ticks-{stamp}.npz")
        self.spec = {"players": players, "snapshot_hz": snapshot_hz, "heartbeat_s": heartbeat_s,
                     "timeout_s": timeout_s, "grace_s": grace_s, "max_spectators": max_spectators,
                     "ticks": int(seconds * 1000), "best_of": best_of, "tick_log": self.tick_log, "feed": feed,
                     "gateway_stats": os.path.join(tmp, f"gateway-{stamp}.json")}
        super().__init__(["-m", "processes.stress.server", json.dumps(self.spec)], "server")
        hello = self.expect(lambda o: "listening" in o, 120, "listening line")
        self.endpoint, self.run_id, self.pids, self.dt = hello["listening"], hello["run_id"], hello["pids"], hello["dt"]
        self.feed = hello.get("feed", "")
        self.rlimit_nofile = hello["rlimit_nofile"]
        self.end: dict | None = None

    def state(self) -> dict:
        self.send("pids")
        state = self.expect(lambda o: "restarts" in o, 10, "state line")
        self.pids = state["pids"]
        return state

    def tick(self) -> int | None:
        """The physics tick now, None once the server has ended (its match is over)."""
        if self.proc.poll() is not None or any("end" in o for o in self.pending):
            return None
        try:
            return self.state()["tick"]
        except StressError:
            if self.proc.poll() is not None or any("end" in o for o in self.pending):
                return None
            raise

    def all_pids(self) -> dict[str, int]:
        return {"supervisor": self.pid, **{k: v for k, v in self.pids.items() if v}}

    def stop(self, timeout: float = 30.0) -> dict:
        """SIGTERM (the supervisor stops its workers: the gateway says goodbye to everyone)."""
        if self.proc.poll() is None:
            os.kill(self.pid, signal.SIGTERM)
        return self.finish(timeout)

    def finish(self, timeout: float) -> dict:
        self.end = self.expect(lambda o: "end" in o, timeout, "end line")
        self.wait(10)
        return self.end

    def tick_clock(self) -> dict | None:
        if not os.path.exists(self.tick_log):
            return None
        with np.load(self.tick_log) as data:
            return {k: data[k] for k in data.files}


def swarm(spec: dict, name: str) -> Child:
    return Child(["-m", "processes.stress.swarm", json.dumps(spec)], name)


def bot(endpoint: str, seconds: float, seed: int) -> Child:
    return Child(["-m", "processes.cli", "join", endpoint, "--as", "player", "--bot", "--json", "--seconds",
                  str(seconds), "--seed", str(seed)], f"bot{seed}")


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


# --- results --------------------------------------------------------------------------------------
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


def percentiles_ms(values: np.ndarray) -> dict:
    if len(values) == 0:
        return {"p50": None, "p99": None, "max": None, "n": 0}
    ms = values * 1000.0
    return {"p50": round(float(np.percentile(ms, 50)), 3), "p99": round(float(np.percentile(ms, 99)), 3),
            "max": round(float(ms.max()), 3), "n": int(len(ms))}


def tick_schedule(clock: dict, dt: float):
    """Per physics incarnation (pid): first time seen, and the schedule's base (lower envelope of
    seen - tick*dt, the incarnation's first sample left out: it may predate the start)."""
    ticks, times, pids = clock["ticks"], clock["times"], clock["pids"]
    segments = []
    for pid in dict.fromkeys(pids.tolist()):
        idx = np.flatnonzero(pids == pid)
        if len(idx) < 3:
            continue
        idx = idx[1:]
        offsets = times[idx] - ticks[idx] * dt
        segments.append((float(times[idx[0]]), float(offsets.min()), idx))
    return segments


def jitter(clock: dict | None, dt: float, t0: float, t1: float) -> dict:
    """Lateness of each tick the clock saw inside [t0, t1] against its incarnation's schedule."""
    if clock is None:
        return {"p99": None, "max": None, "n": 0}
    late = []
    for _, base, idx in tick_schedule(clock, dt):
        times, ticks = clock["times"][idx], clock["ticks"][idx]
        keep = (times >= t0) & (times <= t1)
        late.append(times[keep] - (base + ticks[keep] * dt))
    values = np.concatenate(late) if late else np.zeros(0)
    out = percentiles_ms(values)
    duration = float(clock["times"][-1] - clock["times"][0]) if len(clock["times"]) > 1 else 0.0
    out["resolution_ms"] = round(1000 * duration / max(int(clock["samples"]), 1), 3)
    out["ticks_seen_pct"] = round(100.0 * len(values) / max((t1 - t0) / dt, 1), 1)
    return out


def latency(clock: dict | None, dt: float, records: list[str]) -> dict:
    """Receipt time minus the scheduled publish time of the snapshot's tick, over every snapshot."""
    if clock is None:
        return percentiles_ms(np.zeros(0))
    segments = tick_schedule(clock, dt)
    if not segments:
        return percentiles_ms(np.zeros(0))
    starts = np.array([s[0] for s in segments])
    bases = np.array([s[1] for s in segments])
    values = []
    for path in records:
        if not os.path.exists(path):
            continue
        with np.load(path) as data:
            ticks, times = data["ticks"], data["times"]
        playing = times >= starts[0]  # snapshots of tick 0 while the match waited for its players: no schedule yet
        ticks, times = ticks[playing], times[playing]
        which = np.searchsorted(starts, times, side="right") - 1
        values.append(times - (bases[which] + ticks * dt))
    return percentiles_ms(np.concatenate(values) if values else np.zeros(0))


def _gateway_stats(server: "Server") -> dict:
    """The gateway's counters as it last wrote them (every second), {} before the first."""
    try:
        with open(server.spec["gateway_stats"]) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def _points_problems(end: dict) -> int:
    """Points the server's own log lost: each point adds one to one side's score in its game."""
    lost = 0
    prev_game, prev = 0, [0, 0]
    for row in end.get("points", []):
        score = row["score_after"]
        if row["game"] != prev_game:
            prev_game, prev = row["game"], [0, 0]
        if row["winner"] >= 0 and sum(score) != sum(prev) + 1:
            lost += abs(sum(score) - sum(prev) - 1)
        prev = score
    return lost


def _base(name: str) -> dict:
    return {"scenario": name, "ok": False, "crashes": 0, "lost_points": 0, "leaked_fds": 0, "leaked_shm": 0,
            "rss_growth_pct": None, "latency_ms": None, "tick_jitter_ms": None, "cpu_pct": {}, "counts": {},
            "problems": [], "findings": []}


def _crashes(children: list[Child], expected_dead: set, server: Server | None, intended_restarts: int = 0) -> tuple:
    """Exits that nobody asked for and worker restarts beyond the intended kills."""
    crashes, notes = 0, []
    for child in children:
        code = child.proc.poll()
        if child.pid in expected_dead:
            continue
        if code not in (0, None) or "Traceback" in child.stderr():
            crashes += 1
            notes.append(f"{child.name} exit {code}: {child.stderr()[-600:]} {json.dumps(child.lines[-1:])[-400:]}")
    if server is not None and server.end is not None:
        restarts = sum(w.get("restarts", 0) for w in server.end.get("summary", {}).get("workers", {}).values())
        if server.end.get("summary") and restarts > intended_restarts:
            crashes += restarts - intended_restarts
            notes.append(f"worker restarts {restarts}, intended {intended_restarts}")
    return crashes, notes


def _finish(result: dict, run: Run, server: Server, shm_before: set, fds: dict, expected_dead=(),
            intended_restarts: int = 0) -> dict:
    crashes, notes = _crashes(run.children, set(expected_dead), server, intended_restarts)
    result["crashes"] += crashes
    result["problems"] += notes
    left = set(shm_names()) - shm_before
    ours = [n for n in left if server.run_id in n]
    result["leaked_shm"] = len(ours)
    result["leaked_fds"] = sum(max(0, v) for v in fds.values())
    result["fds"] = fds
    if server.end is not None:
        result["lost_points"] += _points_problems(server.end)
        # the gateway's counters, also when the server was stopped (from its stats file)
        result.setdefault("gateway", server.end.get("gateway", {}))
    for key in ("crashes", "lost_points", "leaked_fds", "leaked_shm"):
        if result[key]:
            result["problems"].append(f"{key} = {result[key]}")
    result["ok"] = not result["problems"]
    result["limits"] = {"rlimit_nofile": server.rlimit_nofile, "zmq_max_sockets_default": 1023,
                        "clients_per_swarm_process": PER_SWARM, "cores": os.cpu_count()}
    return result


def _check(result: dict, condition: bool, message: str) -> None:
    if not condition:
        result["problems"].append(message)


# --- scenarios ------------------------------------------------------------------------------------
def _watch_spec(endpoint, n_spec, n_play, name, record=None, **kw) -> dict:
    return {"task": "watch", "address": endpoint, "spectators": n_spec, "players": n_play, "name": name,
            "record": record, **kw}


def _split(n: int) -> list[int]:
    k = max(1, -(-n // PER_SWARM))
    return [n // k + (i < n % k) for i in range(k)]


def scenario_load(args, run: Run) -> dict:
    result = _base("load")
    shm_before = shm_names()
    n, seconds = args.spectators, args.duration
    fanout = getattr(args, "fanout", "pub")  # pub: the feed; router: one send per session (protocol 1's way)
    server = run.add(Server(run.tmp, players=2, snapshot_hz=args.hz, max_spectators=max(n, 1), seconds=seconds,
                            feed=fanout == "pub"))
    records = [os.path.join(run.tmp, f"load-{i}.npz") for i in range(len(_split(n)))]
    swarms = [run.add(swarm(_watch_spec(server.endpoint, k, 0, f"s{i}_", records[i], duration=seconds + 120,
                                        until_goodbye=True), f"swarm{i}")) for i, k in enumerate(_split(n)) if k]
    readies = [s.expect(lambda o: o.get("event") == "ready", 60 + n / 20, "ready") for s in swarms]
    if getattr(args, "still_players", False):  # players that hold their bats still: the fan-out alone
        bots = [run.add(swarm(_watch_spec(server.endpoint, 0, 2, "still", None, duration=seconds + 120,
                                          until_goodbye=True), "still_players"))]
    else:
        bots = [run.add(bot(server.endpoint, seconds + 120, seed)) for seed in range(args.players)]
    until(lambda: (server.tick() or 0) > 0, 120, 0.2)
    gateway = server.pids["gateway"]
    meter = CpuMeter(threads=("gateway",))
    meter.start({**server.all_pids(), **{s.name: s.pid for s in swarms}, **{b.name: b.pid for b in bots},
                 "harness": os.getpid()})
    published0 = _gateway_stats(server).get("snapshots_published", 0)
    t0 = time.monotonic()
    rss0 = rss_kb(gateway)
    ticks = server.spec["ticks"]
    until(lambda: (server.tick() or ticks) >= 0.9 * ticks, seconds + 60, 0.25)
    rss1 = rss_kb(gateway)
    gateway_cpu = cpu_seconds(gateway)  # its whole life so far: set against every message it sent
    result["cpu_pct"] = meter.stop()
    published = _gateway_stats(server).get("snapshots_published", 0) - published0
    if published > 0 and result["cpu_pct"].get("gateway") is not None:
        # the gateway's CPU (both threads) per snapshot published while the meter ran, and per copy
        # to one subscriber: what the fan-out costs the server, startup and the join phase left out
        us = 1e4 * result["cpu_pct"]["gateway"] * result["cpu_pct"]["_wall_s"] / published
        result["gateway_cpu_us"] = {"per_snapshot": round(us, 1), "per_snapshot_per_spectator": round(us / max(n, 1), 2),
                                    "published_while_metered": published}
    # the gateway counts as its whole process here; its threads are listed apart in cpu_pct
    sides = {"server": set(server.all_pids()), "swarm": {s.name for s in swarms}, "players": {b.name for b in bots}}
    result["cpu_pct_by_side"] = {side: round(sum(v or 0.0 for k, v in result["cpu_pct"].items() if k in names), 1)
                                 for side, names in sides.items()}
    t1 = time.monotonic()
    end = server.finish(60)
    reports = [s.expect(lambda o: o.get("event") == "report", 60, "report") for s in swarms]
    bot_reports = []
    for b in bots:
        try:
            if b.name == "still_players":
                report = b.expect(lambda o: o.get("event") == "report", 30, "report")
                bot_reports.append({"slot": "a+b", "goodbye": next(iter(report["goodbyes"]), "server_lost"),
                                    "snapshots": report["snapshots"], "inputs_sent": report["inputs"]})
                continue
            bot_reports.append(b.expect(lambda o: "goodbye" in o, 30, "summary"))
            b.wait(10)
        except StressError:  # still reading behind, long after the match: a finding, then killed
            b.kill()
            bot_reports.append({"goodbye": "still_running", "tick": None})
    late = [r for r in bot_reports if r.get("goodbye") in ("server_lost", "still_running")]
    if late:  # `pingpong join` exits 1 when its server went silent without a goodbye
        result["findings"].append(
            f"{len(late)} bot(s) got no goodbye and ended by timeout or were still reading 30 s on (last tick read "
            f"{[r.get('tick') for r in late]} of {ticks}); the gateway sends its goodbye without blocking (dropped "
            "at the high-water mark like a snapshot) and closes its socket with linger 0 right after (a goodbye "
            "still queued is discarded), so a peer reading behind can miss it")
    clock = server.tick_clock()
    result["latency_ms"] = latency(clock, server.dt, records)
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    stats = end.get("gateway", {})
    result["gateway"] = stats
    welcomed = sum(r["welcomed"] for r in reports)
    snapshots = sum(r["snapshots"] for r in reports)
    missed = sum(r["missed"] for r in reports)
    feed_missed = sum(r.get("feed_missed", 0) for r in reports)
    on_feed = sum(r.get("on_feed", 0) for r in reports)
    goodbyes = sum(r["goodbyes"].get("match_over", 0) for r in reports)
    result["counts"] = {
        "spectators": n, "welcomed": welcomed, "rejected": sum(sum(r["rejected"].values()) for r in readies),
        "fanout": fanout, "on_feed": on_feed, "feed": server.feed,
        "snapshot_hz": args.hz, "snapshots_received": snapshots, "snapshots_missed": missed + feed_missed,
        "feed_missed": feed_missed, "feed_missed_max": max((r.get("feed_missed_max", 0) for r in reports), default=0),
        "session_messages_missed": missed,
        "gateway_snapshots_published": stats.get("snapshots_published", 0),
        "gateway_snapshots_sent": stats.get("snapshots_sent"), "gateway_snapshots_dropped": stats.get("snapshots_dropped", 0),
        "rate_min_hz": round(min(r["rate_min"] for r in reports), 1) if reports else None,
        "rate_median_hz": round(float(np.median([r["rate_median"] for r in reports])), 1) if reports else None,
        "goodbye_match_over": goodbyes, "bots_without_goodbye": len(late), "bots": [{k: r.get(k) for k in ("slot", "goodbye", "snapshots", "inputs_sent")}
                                                  for r in bot_reports],
        "points": end.get("final", {}).get("points_total"), "match_ticks": end.get("summary", {}).get("ticks"),
        "score_regressions": sum(r["regressions"]["score"] for r in reports),
        "tick_regressions": sum(r["regressions"]["tick"] for r in reports),
        "invalid_snapshots": sum(sum(r["invalid"].values()) for r in reports),
        "gateway_timeouts": stats.get("timeouts", 0),
        "swarm_heartbeat_gap_max_s": max((r.get("sweep_gap_max_s", 0.0) for r in reports), default=0.0),
    }
    sends = sum(v for k, v in stats.items() if k.endswith("_sent") or k.endswith("_published"))
    if gateway_cpu and stats.get("snapshots_published"):
        # the feed: the gateway's whole CPU per snapshot it published (the session traffic included)
        result["counts"]["gateway_cpu_us_per_snapshot"] = round(1e6 * gateway_cpu / stats["snapshots_published"], 1)
    elif gateway_cpu and sends:
        # the fan-out's own ceiling: one gateway process on one core sends this many snapshots a
        # second to each of n sessions (its CPU per message sent, heartbeats and polls included)
        per_send_us = 1e6 * gateway_cpu / sends
        result["counts"]["gateway_cpu_us_per_message"] = round(per_send_us, 1)
        result["counts"]["fanout_ceiling_hz_one_core"] = round(1e6 / (per_send_us * max(n, 1)), 1)
    result["counts"]["gateway_snapshots_unencodable"] = stats.get("snapshots_unencodable", 0)
    result["counts"]["unencodable_examples"] = end.get("unencodable_examples", {})
    result["counts"]["states_beyond_wire_ranges"] = f"{sum(end.get('unencodable', {}).values())} of " \
                                                    f"{end.get('encode_checked')} checked"
    if stats.get("snapshots_unencodable"):
        result["findings"].append(
            f"the gateway could not encode {stats['snapshots_unencodable']} snapshots (the state was beyond the "
            f"wire's ranges, e.g. {next(iter(end.get('unencodable_examples', {}).values()), '?')}): no snapshot went "
            "out for those slots, so the per-client rate is below the snapshot rate")
    result["lost_points"] = result["counts"]["score_regressions"] + result["counts"]["tick_regressions"]
    _check(result, welcomed == n, f"{n - welcomed} spectators not welcomed")
    if fanout == "pub":
        _check(result, on_feed == welcomed, f"{welcomed - on_feed} of {welcomed} spectators not on the feed")
    _check(result, goodbyes == welcomed, f"{welcomed - goodbyes} spectators without the match_over goodbye")
    _check(result, end.get("end") == "match_over", f"server ended {end.get('end')}")
    _check(result, result["counts"]["invalid_snapshots"] == 0, "snapshots failed validation")
    fds = {s.name: r["fds_after"] - r["fds_before"] for s, r in zip(swarms, reports)}
    timed_out = {b.pid for b, r in zip(bots, bot_reports)
                 if (r.get("goodbye") == "server_lost" and b.proc.poll() == 1) or r.get("goodbye") == "still_running"}
    return _finish(result, run, server, shm_before, fds, expected_dead=timed_out)


def scenario_churn(args, run: Run) -> dict:
    result = _base("churn")
    shm_before = shm_names()
    places = args.churn_places
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=1.0, grace_s=0.5, max_spectators=places))
    gateway = server.pids["gateway"]
    fds0 = fd_count(gateway)
    meter = CpuMeter()
    meter.start(server.all_pids())
    parts = [args.churn // 2, args.churn - args.churn // 2] if args.churn >= 100 else [args.churn]
    churners = [run.add(swarm({"task": "churn", "address": server.endpoint, "cycles": c, "seed": i,
                               "concurrency": 8, "max_seconds": args.churn_seconds}, f"churn{i}"))
                for i, c in enumerate(parts)]
    churners[0].expect(lambda o: o.get("event") == "progress", args.churn_seconds, "first progress")
    rss0 = rss_kb(gateway)
    reports = [c.expect(lambda o: o.get("event") == "report", args.churn_seconds + 30, "report") for c in churners]
    rss1 = rss_kb(gateway)
    result["cpu_pct"] = meter.stop()
    churn_end = time.monotonic()
    counts: dict = {}
    for r in reports:
        for k, v in r["counts"].items():
            counts[k] = counts.get(k, 0) + v
    # every abrupt leaver is dropped after the timeout and its seat freed after the grace
    wait = server.spec["timeout_s"] + server.spec["grace_s"] + 1.0
    until(lambda: time.monotonic() - churn_end > wait, wait + 1)
    fill = run.add(swarm(_watch_spec(server.endpoint, places + 1, 3, "fill", duration=1.0, leave_at_end=True,
                                     join_timeout=20), "fill"))
    ready = fill.expect(lambda o: o.get("event") == "ready", 60, "fill ready")
    fill_report = fill.expect(lambda o: o.get("event") == "report", 60, "fill report")
    settled = until(lambda: fd_count(gateway) is not None and fd_count(gateway) <= fds0, 10)
    fds1 = fd_count(gateway)
    end = server.stop()
    cycles = sum(r["cycles"] for r in reports)
    result["counts"] = {"cycles": cycles, **counts, "fill_welcomed": ready["welcomed"], "fill_rejected": ready["rejected"],
                        "join_ms_p50": reports[0]["join_ms_p50"], "join_ms_p99": reports[0]["join_ms_p99"],
                        "seconds": round(max(r["seconds"] for r in reports), 1),
                        "cycles_per_s": round(cycles / max(max(r["seconds"] for r in reports), 1e-9), 1),
                        "gateway_fds_before": fds0, "gateway_fds_after": fds1,
                        "goodbyes_at_shutdown": fill_report["goodbyes"]}
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    _check(result, cycles == args.churn, f"{args.churn - cycles} cycles not run")
    _check(result, counts.get("join_timeouts", 0) == 0, f"{counts.get('join_timeouts')} joins got no answer")
    _check(result, ready["welcomed"] == places + 2, f"after churn {ready['welcomed']} of {places} spectators + 2 "
                                                      "players welcomed: places leaked")
    _check(result, ready["rejected"] == {"full": 2}, f"the extra spectator and player: {ready['rejected']}, "
                                                      "expected full for both")
    _check(result, settled, f"gateway descriptors {fds0} before, {fds1} after")
    _check(result, end.get("end") == "stopped", f"server ended {end.get('end')}")
    fds = {"gateway": (fds1 or 0) - (fds0 or 0), **{c.name: r["fds_after"] - r["fds_before"]
                                                    for c, r in zip(churners, reports)}}
    return _finish(result, run, server, shm_before, fds)


def _pump(clients, seconds: float) -> None:
    """Keep these clients alive (heartbeats, reads) for a while (bounded)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for client in clients:
            client.heartbeat_if_due()
            for _ in range(50):
                if client.recv(0) is None:
                    break
        time.sleep(0.005)  # the clients' own cadence: a heartbeat is due every 0.25 s


def _goodbye(client, seconds: float):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and client.goodbye is None:
        client.recv(20)
    return client.goodbye


def scenario_cable(args, run: Run) -> dict:
    import zmq

    from processes.network.client import Client, Rejected

    result = _base("cable")
    shm_before = shm_names()
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=1.0, grace_s=2.0, max_spectators=4))
    gateway = server.pids["gateway"]
    fds0, harness0 = fd_count(gateway), fd_count(os.getpid())
    port = int(server.endpoint.rsplit(":", 1)[1])
    proxy = Proxy(port)
    proxy.start()
    zctx = zmq.Context()
    clients = []

    def client(role, via_proxy=False, token=bytes(16), name="c"):
        address = f"tcp://127.0.0.1:{proxy.port}" if via_proxy else server.endpoint
        c = Client(address, role, name, token=token, zctx=zctx)
        clients.append(c)
        return c

    def outcome(c):
        try:
            return c.join(10)["slot"].name
        except Rejected as err:
            return err.reason.name.lower()

    counts = {}
    timeout, grace = server.spec["timeout_s"], server.spec["grace_s"]
    try:
        pulled, direct, watcher = client("player", True, name="ann"), client("player", name="bob"), client("spectator", True)
        counts["pulled_slot"], counts["direct_slot"], _ = outcome(pulled), outcome(direct), outcome(watcher)
        _pump([pulled, direct, watcher], 0.5)
        counts["snapshots_through_proxy"] = pulled.received
        proxy.black_hole()  # the cable is pulled: connections open, nothing passes
        t_pull = time.monotonic()
        _pump([direct], timeout + 1.0)  # past the timeout with room for a busy gateway, within the grace
        counts["during_grace_newcomer"] = outcome(client("player", name="cy"))
        proxy.restore()  # what the server sent into the hole comes out now: its goodbye
        counts["pulled_goodbye"] = getattr(_goodbye(pulled, 3.0), "name", None)
        counts["watcher_goodbye"] = getattr(_goodbye(watcher, 3.0), "name", None)
        rejoin = client("player", token=pulled.token, name="ann")
        counts["token_rejoin"] = outcome(rejoin)
        counts["rejoin_within_s"] = round(time.monotonic() - t_pull, 2)
        # the second kind of pulled cable: the rejoined client goes silent with its socket open
        t_silent = time.monotonic()
        _pump([direct], timeout + grace + 0.7)
        counts["silent_goodbye_pending"] = rejoin.goodbye is None  # nothing read yet: it is silent
        counts["after_grace_newcomer"] = outcome(client("player", name="dan"))
        counts["silent_goodbye"] = getattr(_goodbye(rejoin, 3.0), "name", None)
        counts["freed_after_s"] = round(time.monotonic() - t_silent, 2)
        spectators = [client("spectator", name=f"s{i}") for i in range(5)]
        fill = [outcome(c) for c in spectators]
        counts["spectator_fill"] = {k: fill.count(k) for k in set(fill)}
        counts["proxy_bytes"] = proxy.forwarded
    finally:
        for c in clients:
            if c.goodbye is None:
                c.leave()
            c.sock.setsockopt(zmq.LINGER, 500)
            c.close()
        zctx.term()
        proxy.close()
    settled = until(lambda: fd_count(gateway) is not None and fd_count(gateway) <= fds0, 10)
    fds1 = fd_count(gateway)
    end = server.stop()
    result["counts"] = counts
    side = counts["pulled_slot"]
    _check(result, side in ("A", "B") and counts["direct_slot"] in ("A", "B"), f"players not seated: {counts}")
    _check(result, counts["snapshots_through_proxy"] > 0, "no snapshot through the proxy before the pull")
    _check(result, counts["during_grace_newcomer"] == "full", "a newcomer took the pulled seat within the grace")
    _check(result, counts["pulled_goodbye"] == "TIMEOUT", f"pulled player got {counts['pulled_goodbye']}, "
                                                          "expected the timeout goodbye")
    _check(result, counts["watcher_goodbye"] == "TIMEOUT", f"pulled spectator got {counts['watcher_goodbye']}")
    _check(result, counts["token_rejoin"] == side, f"token rejoin got {counts['token_rejoin']}, expected {side}")
    _check(result, counts["after_grace_newcomer"] == side, f"after the grace a newcomer got "
                                                           f"{counts['after_grace_newcomer']}, expected seat {side}")
    _check(result, counts["silent_goodbye"] == "TIMEOUT", f"silent player got {counts['silent_goodbye']}")
    _check(result, counts["spectator_fill"] == {"NONE": 4, "full": 1}, f"spectator places after the pulls: "
                                                                     f"{counts['spectator_fill']}")
    _check(result, settled, f"gateway descriptors {fds0} before, {fds1} after")
    fds = {"gateway": (fds1 or 0) - (fds0 or 0), "harness": (fd_count(os.getpid()) or 0) - (harness0 or 0)}
    return _finish(result, run, server, shm_before, fds)


def scenario_kill(args, run: Run) -> dict:
    result = _base("kill")
    shm_before = shm_names()
    n = max(args.kill_spectators, 2)
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=2.0, grace_s=1.0, max_spectators=n))
    records = [os.path.join(run.tmp, f"kill-{i}.npz") for i in range(3)]
    keep = run.add(swarm(_watch_spec(server.endpoint, n // 2, 0, "keep", records[0], duration=300, rejoin=True,
                                     until_goodbye=True, silence_s=1.0), "keep"))
    doomed = [run.add(swarm(_watch_spec(server.endpoint, max(1, (n - n // 2) // args.kill), 0, f"doom{i}", None,
                                        duration=300), f"doomed{i}")) for i in range(args.kill)]
    players = run.add(swarm(_watch_spec(server.endpoint, 0, 2, "pl", None, duration=300), "players"))
    for s in (keep, *doomed, players):
        s.expect(lambda o: o.get("event") == "ready", 60, "ready")
    if not until(lambda: server.state()["tick"] > 300, 120, 0.2):
        raise StressError("the match did not start")
    meter = CpuMeter()
    meter.start({**server.all_pids(), "keep": keep.pid})
    t0 = time.monotonic()
    counts: dict = {}
    for s in (*doomed, players):  # client processes die mid-match, the players' one too
        s.kill()
    counts["client_processes_killed"] = len(doomed) + 1
    before = server.state()
    os.kill(before["pids"]["gateway"], signal.SIGKILL)
    counts["gateway_restarted"] = until(lambda: server.state()["restarts"].get("gateway", 0) >= 1
                                        and server.state()["tick"] > before["tick"] + 200, 60, 0.2)
    mid = server.state()
    os.kill(mid["pids"]["physics"], signal.SIGKILL)
    counts["physics_restarted"] = until(lambda: server.state()["restarts"].get("physics", 0) >= 1
                                        and server.state()["tick"] > mid["tick"] + 200, 60, 0.2)
    after = server.state()
    counts["points_before_physics_kill"] = mid["points_total"]
    counts["points_after_restart"] = after["points_total"]
    counts["ticks"] = [before["tick"], mid["tick"], after["tick"]]
    lost = max(0, mid["points_total"] - after["points_total"])
    if after["points_total"] == mid["points_total"]:
        lost += int(sum(after["games_won"]) < sum(mid["games_won"]) or
                    (after["games_won"] == mid["games_won"] and sum(after["score"]) < sum(mid["score"])))
    # every slot full: the rest of the spectator places and both seats, then one spectator too many
    others = n - n // 2
    fill = run.add(swarm(_watch_spec(server.endpoint, others + 1, 2, "fill", records[1], duration=300,
                                     until_goodbye=True, join_timeout=30), "fill"))
    fill_ready = fill.expect(lambda o: o.get("event") == "ready", 60, "fill ready")
    keep_state = server.state()
    result["cpu_pct"] = meter.stop()
    t1 = time.monotonic()
    end = server.stop()
    keep_report = keep.expect(lambda o: o.get("event") == "report", 30, "report")
    fill_report = fill.expect(lambda o: o.get("event") == "report", 30, "report")
    clock = server.tick_clock()
    result["latency_ms"] = latency(clock, server.dt, records[:2])
    result["tick_jitter_ms"] = jitter(clock, server.dt, t0, t1)
    told = keep_report["goodbyes"].get("shutdown", 0) + fill_report["goodbyes"].get("shutdown", 0)
    present = (keep_report["welcomed"] - keep_report["no_goodbye"] + fill_report["welcomed"])
    counts.update({"keep_rejoined": keep_report["rejoined"], "keep_welcomed": keep_report["welcomed"],
                   "fill_welcomed": fill_ready["welcomed"], "fill_rejected": fill_ready["rejected"],
                   "restarts": keep_state["restarts"], "goodbye_shutdown": told,
                   "clients_at_shutdown": keep_report["welcomed"] + fill_report["welcomed"],
                   "score_regressions": keep_report["regressions"]["score"] + fill_report["regressions"]["score"],
                   "tick_regressions": keep_report["regressions"]["tick"] + fill_report["regressions"]["tick"]})
    result["counts"] = counts
    result["lost_points"] = lost + counts["score_regressions"] + counts["tick_regressions"]
    _check(result, counts["gateway_restarted"], "the gateway was not restarted")
    _check(result, counts["physics_restarted"], "the physics worker was not restarted")
    _check(result, keep_report["rejoined"] >= keep_report["welcomed"] > 0, f"{keep_report['welcomed']} watchers, "
                                                                         f"{keep_report['rejoined']} joined again")
    _check(result, fill_ready["welcomed"] == others + 2 and fill_ready["rejected"] == {"full": 1},
           f"fill: {fill_ready['welcomed']} welcomed of {others} + 2, rejected {fill_ready['rejected']}")
    _check(result, told == present, f"{present - told} of {present} clients without the shutdown goodbye")
    _check(result, end.get("end") == "stopped", f"server ended {end.get('end')}")
    dead = {s.pid for s in (*doomed, players)}  # killed on purpose
    fds = {"keep": keep_report["fds_after"] - keep_report["fds_before"],
           "fill": fill_report["fds_after"] - fill_report["fds_before"]}
    return _finish(result, run, server, shm_before, fds, expected_dead=dead, intended_restarts=2)


def scenario_malformed(args, run: Run) -> dict:
    result = _base("malformed")
    shm_before = shm_names()
    n, rate = args.malformed, args.malformed_rate
    # The match must outlast the flood at its rate (4x: a loaded machine is slower) and the round
    # trips after it: the gateway reports its counters when the match ends. 20 s of margin: with
    # 9 s a cold-cache CI run (two test workers compiling) saw the match end before the round trips.
    seconds = n / rate * 4.0 + 20.0
    # A 30 s silence timeout: the flood's own player and watcher share a process with the flood,
    # and a cold-cache CI run starved their heartbeats past 5 s, so the gateway dropped them and
    # counted their later messages as sessionless (this scenario counts drops, not timeouts).
    server = run.add(Server(run.tmp, players=2, heartbeat_s=0.25, timeout_s=30.0, max_spectators=32, seconds=seconds))
    gateway = server.pids["gateway"]
    legit = run.add(swarm(_watch_spec(server.endpoint, 4, 1, "ok", None, duration=seconds + 120, until_goodbye=True),
                          "legit"))
    legit.expect(lambda o: o.get("event") == "ready", 60, "ready")
    rss0 = rss_kb(gateway)
    meter = CpuMeter()
    meter.start(server.all_pids())
    flood = run.add(swarm({"task": "malformed", "address": server.endpoint, "n": n, "rate": rate, "seed": args.seed,
                           "max_seconds": seconds - 4.0}, "malformed"))
    report = flood.expect(lambda o: o.get("event") == "report", seconds + 60, "report")
    rss1 = rss_kb(gateway)
    result["cpu_pct"] = meter.stop()
    end = server.finish(seconds + 60)
    legit_report = legit.expect(lambda o: o.get("event") == "report", 30, "report")
    stats = end.get("gateway", {})
    result["gateway"] = stats
    sent, expected = report["sent"], report["expected"]
    kicks = sum(v for k, v in report["counts"].items() if k.startswith("kicked_seen."))
    mismatched = {k: (v, stats.get(k, 0)) for k, v in expected.items() if k.startswith("dropped.") and stats.get(k, 0) != v}
    refusals = {"refused.other_bat": sent.get("other_bat", 0), "refused.spectator_input": sent.get("spectator_input", 0),
                "refused.stale_input": sent.get("stale_replay", 0), "kicked": kicks}
    mismatched.update({k: (v, stats.get(k, 0)) for k, v in refusals.items() if stats.get(k, 0) != v})
    extra = {k: v for k, v in stats.items() if k.startswith("dropped.") and k not in expected}
    result["counts"] = {"sent": report["sent_total"], "by_class": sent, "gateway_dropped_total": stats.get("dropped_total"),
                        "expected_dropped_total": sum(v for k, v in expected.items() if k.startswith("dropped.")),
                        "kicks": kicks, "sessions": report["counts"], "seconds": round(report["seconds"], 1),
                        "legit_goodbyes": legit_report["goodbyes"], "legit_snapshots": legit_report["snapshots"],
                        "legit_inputs": legit_report["inputs"], "gateway_inputs_accepted": stats.get("inputs_accepted"),
                        "mismatched_counters": mismatched, "unexpected_counters": extra,
                        "synced": f"{report['synced_sockets']}/{report['sockets']} sockets, "
                                  f"{report['sessions_synced']}/2 sessions",
                        "unsynced": report.get("unsynced", []),
                        "late_replies_at_sync": report.get("late_replies_at_sync", {})}
    result["rss_growth_pct"] = round(100.0 * (rss1 - rss0) / rss0, 2) if rss0 and rss1 else None
    result["lost_points"] = legit_report["regressions"]["score"] + legit_report["regressions"]["tick"]
    _check(result, end.get("end") == "match_over", f"server ended {end.get('end')} (no gateway counters)")
    _check(result, report["sent_total"] == n, f"{n - report['sent_total']} of {n} messages not sent")
    _check(result, report["synced_sockets"] == report["sockets"] and report["sessions_synced"] == 2,
           f"round trips: {result['counts']['synced']} (unsynced: {result['counts']['unsynced']})")
    _check(result, not mismatched, f"gateway counters differ from the sender's (expected, counted): {mismatched}")
    _check(result, not extra, f"gateway counted drops nobody sent: {extra}")
    _check(result, legit_report["goodbyes"] == {"match_over": 5}, f"legit clients ended {legit_report['goodbyes']}")
    fds = {"malformed": report["fds_after"] - report["fds_before"],
           "legit": legit_report["fds_after"] - legit_report["fds_before"]}
    return _finish(result, run, server, shm_before, fds)


RUNNERS = {"load": scenario_load, "churn": scenario_churn, "cable": scenario_cable, "kill": scenario_kill,
           "malformed": scenario_malformed}


def loadavg() -> list[float]:
    return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]


def run_scenario(name: str, args) -> dict:
    with tempfile.TemporaryDirectory(prefix="pingpong-stress-") as tmp:
        run = Run(tmp, [])
        before = loadavg()  # the machine is shared: how busy it was says how far to trust the times
        try:
            result = RUNNERS[name](args, run)
            result["loadavg_before_after"] = [before, loadavg()]
        except StressError as err:
            result = _base(name)
            result["crashes"] = 1
            result["problems"].append(str(err))
        finally:
            removed = run.close()
        if removed:  # a server that had to be killed: its segments are removed here, and counted
            result["leaked_shm"] = max(result["leaked_shm"], len(removed))
            result["problems"].append(f"segments of a killed server removed by the harness: {len(removed)}")
            result["ok"] = False
        return result


# --- report ---------------------------------------------------------------------------------------
def _fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, dict):
        return "/".join(_fmt(value.get(k)) for k in ("p50", "p99", "max") if k in value)
    return str(value)


def _summary(result: dict) -> str:
    c = result["counts"]
    name = result["scenario"]
    if name == "load":
        return (f"{c.get('welcomed')}/{c.get('spectators')} spectators at {c.get('snapshot_hz')} Hz "
                f"({c.get('fanout')} fan-out, {c.get('on_feed')} on the feed), rate median "
                f"{c.get('rate_median_hz')} min {c.get('rate_min_hz')} Hz, missed {c.get('snapshots_missed')} "
                f"(feed gaps {c.get('feed_missed')}, gateway dropped {c.get('gateway_snapshots_dropped')}), "
                f"{c.get('points')} points")
    if name == "churn":
        return (f"{c.get('cycles')} cycles in {c.get('seconds')} s ({c.get('cycles_per_s')}/s), "
                f"{c.get('left_abrupt', 0)} without goodbye; fill after: {c.get('fill_welcomed')} welcomed, "
                f"rejected {c.get('fill_rejected')}")
    if name == "cable":
        return (f"pulled {c.get('pulled_slot')}: grace newcomer {c.get('during_grace_newcomer')}, goodbye "
                f"{c.get('pulled_goodbye')}, token -> {c.get('token_rejoin')}; silent: after grace -> "
                f"{c.get('after_grace_newcomer')} in {c.get('freed_after_s')} s")
    if name == "kill":
        return (f"{c.get('client_processes_killed')} client processes, gateway restarted {c.get('gateway_restarted')},"
                f" physics restarted {c.get('physics_restarted')}, rejoined {c.get('keep_rejoined')}; shutdown: "
                f"{c.get('goodbye_shutdown')}/{c.get('clients_at_shutdown')} goodbyes")
    if name == "malformed":
        return (f"{c.get('sent')} sent, gateway dropped {c.get('gateway_dropped_total')} (expected "
                f"{c.get('expected_dropped_total')}), {c.get('kicks')} kicks, legit {c.get('legit_goodbyes')}")
    return json.dumps(c)[:120]


def print_table(results: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="pingpong stress")
    for column in ("scenario", "ok", "crashes", "lost points", "leaked fds", "leaked shm", "RSS growth %"):
        table.add_column(column, no_wrap=column == "scenario")
    for r in results:
        table.add_row(r["scenario"], "yes" if r["ok"] else "NO", str(r["crashes"]), str(r["lost_points"]),
                      str(r["leaked_fds"]), str(r["leaked_shm"]), _fmt(r["rss_growth_pct"]))
    console = Console()
    console.print(table)
    for r in results:
        jit = r.get("tick_jitter_ms") or {}
        timing = (f"; latency ms p50/p99/max {_fmt(r['latency_ms'])}, tick jitter ms p99/max "
                  f"{_fmt(jit.get('p99'))}/{_fmt(jit.get('max'))}" if r.get("latency_ms") else "")
        console.print(f"[bold]{r['scenario']}[/]: {_summary(r)}{timing}; load average before/after "
                      f"{r.get('loadavg_before_after')}")
    for r in results:
        if r.get("cpu_pct"):
            console.print(f"[bold]{r['scenario']}[/] CPU % of one core: " +
                          ", ".join(f"{k} {v}" for k, v in r["cpu_pct"].items()))
        if r.get("cpu_pct_by_side"):
            console.print(f"[bold]{r['scenario']}[/] CPU % of one core by side: " +
                          ", ".join(f"{k} {v}" for k, v in r["cpu_pct_by_side"].items()))
        for problem in r["problems"]:
            console.print(f"[red]{r['scenario']}: {problem}[/]")
        for finding in r.get("findings", []):
            console.print(f"[yellow]{r['scenario']}: finding: {finding}[/]")


def stress_command(args: argparse.Namespace) -> int:
    names = [s.strip() for s in args.scenario.split(",") if s.strip()]
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown:
        print(f"pingpong stress: unknown scenario {', '.join(unknown)}; choose from {','.join(SCENARIOS)}",
              file=sys.stderr)
        return 2
    if args.players != 2:
        print("pingpong stress: --players must be 2 (the served match waits for both seats)", file=sys.stderr)
        return 2
    for flag in ("spectators", "churn", "malformed", "kill", "hz"):
        if getattr(args, flag) < 1:
            print(f"pingpong stress: --{flag} must be at least 1, got {getattr(args, flag)}", file=sys.stderr)
            return 2
    results = []
    for name in names:
        result = run_scenario(name, args)
        results.append(result)
        if args.json:
            print(json.dumps(result), flush=True)
    if not args.json:
        print_table(results)
    return 0 if all(r["ok"] for r in results) else 1
