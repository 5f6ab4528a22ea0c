"""The server under test of `pingpong stress`: a Supervisor serving a match, as `pingpong serve` runs it,
plus a tick clock that publishes when each physics tick came out; and Server, the harness's handle on it.

Run as `python -m processes.stress.server SPEC_JSON` (Server starts it). It prints JSON lines:
  {"listening": endpoint, "run_id", "pids": {kind: pid}, "server_pid"}    once every worker is ready
  {"pids": {...}, "restarts": {...}, "raised": {...}, "tick": n}           for each "pids" line on stdin
  {"end": "match_over"|"stopped", "summary": {...}, "gateway": {...}, "points": [...], "final": {...}}
("gateway": its counters, from the supervisor at a match's end, else from the file the gateway
writes when it stops, SPEC "gateway_stats").
It writes the tick log (SPEC "tick_log", .npz) at exit.

Why a tick clock: the wire's snapshot carries the tick, not a timestamp. In realtime mode the
physics worker starts tick k at start + k*dt (CLOCK_MONOTONIC, shared by every process of the
machine), but `start` is known only inside it (it is reset when the remote players arrive and
when a restarted worker resumes). A thread here reads the physics block's published tick (a word
of shared memory) every ~0.2 ms and records when it first saw each tick. Per physics incarnation
(its pid), the lower envelope min(seen - k*dt) is the schedule's start plus the smallest step cost,
so T(k) = that + k*dt is the earliest time tick k can be out; a tick's lateness is seen(k) - T(k)
(to within the sampling period, reported), and a client's latency is its receipt time - T(k).
"""
from __future__ import annotations

import json
import os
import resource
import signal
import sys
import threading
import time
from array import array
from collections import Counter

import numpy as np

from processes.network import wire
from processes.runtime.shm import Arena
from processes.stress.harness import Child, StressError

SAMPLE_PERIOD_S = 0.0002
ENCODE_EVERY = 10  # the tick clock checks one published state in this many for the wire's ranges


def _print(obj) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


class TickClock(threading.Thread):
    """Records (tick, first time seen, physics pid) from the run's shared memory, and at the end
    the score state and point log (which the supervisor does not return when it is stopped)."""

    def __init__(self, layout: dict, kinds: list[str]):
        super().__init__(name="tick-clock", daemon=True)
        self.arena = Arena.attach(layout)  # our own mapping: the supervisor unlinks, we close
        self.kinds = kinds
        self.stop_flag = threading.Event()
        self.ticks = array("q")
        self.times = array("d")
        self.pids = array("q")
        self.samples = 0
        self.encode_checked = 0
        self.unencodable: Counter[str] = Counter()
        self.unencodable_examples: dict[str, str] = {}

    def pids_now(self) -> dict:
        status = self.arena["status"].array
        return {kind: int(status[i]["pid"]) for i, kind in enumerate(self.kinds)}

    def restarts_now(self) -> dict:
        status = self.arena["status"].array
        return {kind: int(status[i]["restarts"]) for i, kind in enumerate(self.kinds)}

    def state_now(self) -> dict:
        """Worker pids and restarts, the physics tick and the score state, as the run has them now."""
        record = np.zeros(1, self.arena["physics"].dtype)
        self.arena["physics"].snapshot(record)
        rally = record[0]["rally"]
        return {"pids": self.pids_now(), "restarts": self.restarts_now(), "tick": int(record[0]["world"]["tick"]),
                "score": rally["score"].tolist(), "games_won": rally["games_won"].tolist(),
                "points_total": int(rally["points_total"])}

    def run(self) -> None:
        block = self.arena["physics"]
        status = self.arena["status"].array
        physics = self.kinds.index("physics")
        last = -2
        monotonic, sleep = time.monotonic, time.sleep
        record = np.zeros(1, block.dtype)
        while not self.stop_flag.is_set():
            tick = block.tick
            now = monotonic()
            self.samples += 1
            if tick != last:
                last = tick
                self.ticks.append(tick)
                self.times.append(now)
                self.pids.append(int(status[physics]["pid"]))
                if tick % ENCODE_EVERY == 0:
                    self._encodable(block, record)
            sleep(SAMPLE_PERIOD_S)

    def _encodable(self, block, record) -> None:
        """Can this state go on the wire? (The gateway skips, and only counts, a state it cannot encode.)"""
        block.snapshot(record)
        self.encode_checked += 1
        try:
            wire.snapshot_from_physics(record[0], seq=1)
        except wire.WireError as err:
            self.unencodable[err.reason] += 1
            self.unencodable_examples.setdefault(str(err).split(":")[0], f"tick {int(record[0]['world']['tick'])}: {err}")

    def finish(self, path: str | None) -> dict:
        """Stop sampling, save the log, read the final score state and point log, detach."""
        self.stop_flag.set()
        self.join(5.0)
        if path:
            np.savez(path, ticks=np.frombuffer(self.ticks, np.int64), times=np.frombuffer(self.times, np.float64),
                     pids=np.frombuffer(self.pids, np.int64), samples=self.samples)
        record = np.zeros(1, self.arena["physics"].dtype)
        self.arena["physics"].snapshot(record)
        rally = record[0]["rally"]
        total = int(rally["points_total"])
        points = self.arena["points"].array[:total] if "points" in self.arena.blocks else []
        final = {"tick": int(record[0]["world"]["tick"]), "score": rally["score"].tolist(),
                 "games_won": rally["games_won"].tolist(), "points_total": total, "winner": int(rally["winner"])}
        rows = [{"tick": int(p["tick"]), "game": int(p["game"]), "winner": int(p["winner"]),
                 "score_after": p["score_after"].tolist()} for p in points]
        del record, rally, points
        self.arena.close()
        return {"final": final, "points": rows, "encode_checked": self.encode_checked,
                "unencodable": dict(self.unencodable), "unencodable_examples": self.unencodable_examples}


class Server(Child):
    """This module run as a child: a served match; `state()` asks it for pids, restarts and score."""

    def __init__(self, tmp: str, players: int = 2, snapshot_hz: int = 120, heartbeat_s: float = 0.5,
                 timeout_s: float = 5.0, grace_s: float = 30.0, max_spectators: int = 64, seconds: float = 3600.0,
                 best_of: int = 9, feed: bool = True, bind: str = "tcp://127.0.0.1:0", players_timeout: float = 300.0,
                 scene: str = "match_rigid"):
        stamp = time.monotonic_ns()
        self.tick_log = os.path.join(tmp, f"ticks-{stamp}.npz")
        self.spec = {"players": players, "snapshot_hz": snapshot_hz, "heartbeat_s": heartbeat_s,
                     "timeout_s": timeout_s, "grace_s": grace_s, "max_spectators": max_spectators,
                     "ticks": int(seconds * 1000), "best_of": best_of, "tick_log": self.tick_log, "feed": feed,
                     "gateway_stats": os.path.join(tmp, f"gateway-{stamp}.json"), "bind": bind,
                     "send_log": os.path.join(tmp, f"sends-{stamp}.npy"),
                     "players_timeout": players_timeout, "scene": scene}
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

    def send_log(self) -> np.ndarray | None:
        """The gateway's (tick, sent at) rows of the snapshots it published (written as it ended)."""
        path = self.spec["send_log"]
        return np.load(path) if os.path.exists(path) else None

    def gateway_stats(self) -> dict:
        """The gateway's counters as it last wrote them (every second), {} before the first."""
        try:
            with open(self.spec["gateway_stats"]) as f:
                return json.load(f)
        except (OSError, ValueError):
            return {}


def main(argv: list[str]) -> int:
    spec = json.loads(argv[0])
    # one TCP connection is one descriptor in the gateway: lift the soft limit to the hard one
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    from dataclasses import replace

    from engine.physics.scene import load_scene, with_remote_players
    from processes.network.server.config import GatewayConfig
    from processes.runtime.stops import ignore_stop_signals
    from processes.supervisor import Supervisor

    # The rigid-net match by default: the stress tool loads the gateway, and a cloth net's worker
    # would only share its cores (the busy scenario asks for the cloth match: SPEC "scene").
    scene = with_remote_players(load_scene(spec.get("scene", "match_rigid")), spec["players"])
    if spec.get("best_of"):
        scene = replace(scene, match=replace(scene.match, best_of=spec["best_of"]))
    config = GatewayConfig(bind=spec.get("bind", "tcp://127.0.0.1:0"), snapshot_hz=spec["snapshot_hz"], heartbeat_s=spec["heartbeat_s"],
                           timeout_s=spec["timeout_s"], grace_s=spec["grace_s"], max_spectators=spec["max_spectators"],
                           sndhwm=spec.get("sndhwm", GatewayConfig.sndhwm), feed=spec.get("feed", True),
                           stats_path=spec.get("gateway_stats", ""), send_log_path=spec.get("send_log", ""),
                           pause_for_players=False)  # players are killed on purpose: the match goes on
    supervisor = Supervisor(scene, spec["ticks"], "realtime", seed=spec.get("seed", 0), gateway=config,
                            players_timeout=spec.get("players_timeout", 300.0))
    clock: list[TickClock] = []

    def commands() -> None:  # "pids" on stdin: the current worker pids (a restarted worker has a new one)
        for line in sys.stdin:
            if line.strip() == "pids" and clock:
                _print({**clock[0].state_now(), "raised": supervisor.raised()})

    def ready(reports: dict) -> None:
        clock.append(TickClock(supervisor.arena.layout(), list(supervisor.kinds)))
        clock[0].start()
        _print({"listening": reports["gateway"]["endpoint"], "feed": reports["gateway"].get("feed", ""),
                "run_id": supervisor.arena.run_id,
                "pids": clock[0].pids_now(), "dt": scene.dt, "rlimit_nofile": resource.getrlimit(resource.RLIMIT_NOFILE)})
        threading.Thread(target=commands, name="commands", daemon=True).start()

    end, summary, gateway = "stopped", {}, {}
    try:
        result = supervisor.run(on_ready=ready)
        end = "match_over"
        workers = result.workers
        gateway = workers.get("gateway", {}).get("gateway", {})
        summary = {"ticks": result.ticks, "wall_seconds": result.wall_seconds,
                   "workers": {k: {n: v for n, v in w.items() if n != "gateway"} for k, w in workers.items()}}
    except (SystemExit, KeyboardInterrupt):
        end = "stopped"
    ignore_stop_signals()  # the end line below is what the harness waits for: more signals cannot cut it
    if not gateway and spec.get("gateway_stats"):
        # stopped: the supervisor never reads a stopped worker's last report, so the counters come
        # from the file the gateway writes at its end (and every second before it)
        try:
            with open(spec["gateway_stats"]) as f:
                gateway = json.load(f)
        except (OSError, ValueError):
            gateway = {}
    tail = clock[0].finish(spec.get("tick_log")) if clock else {"final": {}, "points": []}
    _print({"end": end, "summary": summary, "gateway": gateway, **tail})
    return 0


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.exit(main(sys.argv[1:]))
