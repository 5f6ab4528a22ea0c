"""The result of one scenario: a record every scenario fills, its checks, and the invariants every
scenario shares (crashes, lost points, leaked descriptors and segments) filled in at its end."""
from __future__ import annotations

import json
import os

from processes.stress.harness import Child, Run
from processes.stress.probes import shm_names
from processes.stress.server import Server
from processes.stress.swarm import PER_SWARM


def points_lost(end: dict) -> int:
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


def base(name: str) -> dict:
    return {"scenario": name, "ok": False, "crashes": 0, "lost_points": 0, "leaked_fds": 0, "leaked_shm": 0,
            "rss_growth_pct": None, "latency_ms": None, "tick_jitter_ms": None, "cpu_pct": {}, "counts": {},
            "problems": [], "findings": []}


def crashes_of(children: list[Child], expected_dead: set, server: Server | None, intended_restarts: int = 0) -> tuple:
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


def finish(result: dict, run: Run, server: Server | None, shm_before: set, fds: dict, expected_dead=(),
           intended_restarts: int = 0) -> dict:
    """The shared invariants into `result`, and its verdict. server None: the server runs elsewhere
    (its segments and counters are not ours to check)."""
    crashes, notes = crashes_of(run.children, set(expected_dead), server, intended_restarts)
    result["crashes"] += crashes
    result["problems"] += notes
    if server is not None:
        left = set(shm_names()) - shm_before
        result["leaked_shm"] = len([n for n in left if server.run_id in n])
    result["leaked_fds"] = sum(max(0, v) for v in fds.values())
    result["fds"] = fds
    if server is not None and server.end is not None:
        result["lost_points"] += points_lost(server.end)
        # the gateway's counters, also when the server was stopped (from its stats file)
        result.setdefault("gateway", server.end.get("gateway", {}))
    for key in ("crashes", "lost_points", "leaked_fds", "leaked_shm"):
        if result[key]:
            result["problems"].append(f"{key} = {result[key]}")
    result["ok"] = not result["problems"]
    result["limits"] = {"rlimit_nofile": server.rlimit_nofile if server is not None else None, "zmq_max_sockets_default": 1023,
                        "clients_per_swarm_process": PER_SWARM, "cores": os.cpu_count()}
    return result


def check(result: dict, condition: bool, message: str) -> None:
    if not condition:
        result["problems"].append(message)

