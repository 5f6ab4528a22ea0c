"""A still player that keeps the books: `python -m processes.stress.observer ENDPOINT --seconds S`.

It takes a seat and sends no input at all (only its heartbeats), so its bat must stay where the
idle brake holds it, and it records what a client of docs/protocol.md can check on its session:
the server's heartbeat gaps against the welcome's timeout, the snapshots (their rate in wall
time, the realtime factor they carry once the match plays, its own bat's speed, the ball's),
the net messages (their rate and how far their tick lags the newest snapshot's), the point
events, and the goodbye.

It prints one JSON line once joined, {"joined": slot, "timeout_ms", "heartbeat_ms"}, and one at
the end (the goodbye, the server lost, or `--seconds` run out), the report (Observer.report).
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from processes.network.client.client import Client, Rejected
from processes.network.server.pacing import RATE_WINDOW_S
from processes.network.wire import EventKind, Kind, Slot

JOIN_TIMEOUT_S = 120.0  # a busy machine's server may take long to answer the first hello


class Observer:
    """The books of one still player's session (see the module's docstring)."""

    def __init__(self, client: Client):
        self.client = client
        self.bat = int(client.slot) - 1  # our bat's index in the snapshot's (A, B) arrays
        self.heartbeat_at: float | None = None
        self.heartbeat_gap_max_s = 0.0
        self.snapshot_walls: list[float] = []
        self.snapshot_tick = -1  # the newest snapshot's tick
        self.play_from: float | None = None  # wall s from which the snapshots' realtime factor is play's
        self.realtime_factors: list[float] = []
        self.bat_speed_max = 0.0  # m/s, our own bat
        self.ball_speed_max = 0.0  # m/s
        self.net_walls: list[float] = []
        self.net_lag_ticks: list[int] = []  # the newest snapshot's tick minus the net message's (< 0: it came first)
        self.points: list[dict] = []  # the point events, in order
        self.last_score: list[int] | None = None
        self.final: dict = {}

    def take(self, message, now: float) -> None:
        if message.kind == Kind.HEARTBEAT:
            if self.heartbeat_at is not None:
                self.heartbeat_gap_max_s = max(self.heartbeat_gap_max_s, now - self.heartbeat_at)
            self.heartbeat_at = now
        elif message.kind == Kind.SNAPSHOT:
            self.snapshot_walls.append(now)
            self.snapshot_tick = max(self.snapshot_tick, message.tick)
            if message.tick > 0 and self.play_from is None:
                self.play_from = now + RATE_WINDOW_S  # the factor's window then holds play only
            if self.play_from is not None and now >= self.play_from:
                self.realtime_factors.append(float(message["realtime_factor"]))
            self.bat_speed_max = max(self.bat_speed_max, float(np.linalg.norm(message["bat_vel"][self.bat])))
            self.ball_speed_max = max(self.ball_speed_max, float(np.linalg.norm(message["ball_vel"])))
            self.final = {"tick": message.tick, "score": [int(s) for s in message["score"]],
                          "games_won": [int(g) for g in message["games_won"]], "rally": int(message["rally"])}
        elif message.kind == Kind.NET:
            if int(message["first"]) == 0:  # one per net state: its first message
                self.net_walls.append(now)
                if self.snapshot_tick >= 0:
                    self.net_lag_ticks.append(self.snapshot_tick - message.tick)
        elif message.kind == Kind.EVENT and message["event"] == EventKind.POINT:
            self.points.append({"tick": message.tick, "rally": int(message["rally"]),
                                "winner": int(message["winner"]), "score_after": [int(s) for s in message["score"]]})

    def report(self, welcome, seconds: float) -> dict:
        """What the session showed; rates over the span from the first to the last message of a kind."""
        client = self.client
        goodbye = client.goodbye.name.lower() if client.goodbye is not None else (
            "server_lost" if client.server_lost else "still_running")
        factors = np.array(self.realtime_factors)
        lag = np.array(self.net_lag_ticks)
        return {
            "slot": client.slot.name.lower(), "goodbye": goodbye, "seconds": round(seconds, 3),
            "timeout_ms": int(welcome["timeout_ms"]), "heartbeat_ms": int(welcome["heartbeat_ms"]),
            "heartbeat_gap_max_s": round(self.heartbeat_gap_max_s, 3),
            "snapshots": len(self.snapshot_walls), "snapshot_hz": _rate(self.snapshot_walls),
            "realtime_factor": {"min": round(float(factors.min()), 3), "p50": round(float(np.median(factors)), 3)}
            if len(factors) else None,
            "bat_speed_max": self.bat_speed_max, "ball_speed_max": self.ball_speed_max,
            "nets": len(self.net_walls), "net_hz": _rate(self.net_walls),
            "net_lag_ticks": {"p50": float(np.median(lag)), "max": int(lag.max())} if len(lag) else None,
            "points": self.points, "final": self.final, "dropped": dict(client.drops.by_reason),
        }


def _rate(walls: list[float]) -> float | None:
    """Messages per wall second between the first and the last."""
    if len(walls) < 2 or walls[-1] <= walls[0]:
        return None
    return round((len(walls) - 1) / (walls[-1] - walls[0]), 2)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m processes.stress.observer", description=__doc__.splitlines()[0])
    parser.add_argument("endpoint")
    parser.add_argument("--seconds", type=float, required=True, help="give up after this long (a safety net)")
    parser.add_argument("--name", default="still")
    args = parser.parse_args(argv)
    client = Client(args.endpoint, "player", args.name, slot=Slot.NONE)
    try:
        try:
            welcome = client.join(JOIN_TIMEOUT_S)
        except (Rejected, TimeoutError) as err:
            print(json.dumps({"error": str(err)}), flush=True)
            return 3
        print(json.dumps({"joined": client.slot.name.lower(), "timeout_ms": int(welcome["timeout_ms"]),
                          "heartbeat_ms": int(welcome["heartbeat_ms"])}), flush=True)
        observer = Observer(client)
        start = time.monotonic()
        end = start + args.seconds
        while time.monotonic() < end and client.goodbye is None and not client.server_lost:
            client.heartbeat_if_due()  # alive, and nothing else: no input ever
            for message in client.recv_batch(50):
                observer.take(message, time.monotonic())
        print(json.dumps(observer.report(welcome, time.monotonic() - start)), flush=True)
        return 0
    finally:
        client.close()


if __name__ == "__main__":
    sys.exit(main())
