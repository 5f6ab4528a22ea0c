"""A swarm of ZeroMQ clients in one process, for `pingpong stress`; one module per task.

Run as `python -m processes.stress.swarm SPEC_JSON` (launch() starts it); prints JSON lines on
stdout: {"event": "ready", ...} once its clients are in, {"event": "progress", ...} now and then,
and a final {"event": "report", ...}. Tasks (SPEC "task"): watch (spectators and players take
every message, swarm.spec.WatchSpec), churn (join and leave in a loop), malformed (bad messages of
every class), abuse (one hostile peer's attack, swarm.abuse).
"""
from __future__ import annotations

import json
import sys

import zmq

from processes.stress.harness import Child
from processes.stress.swarm.spec import WatchSpec

PER_SWARM = 250  # clients per swarm process (each one socket, two descriptors)


def emit(obj) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def context(n_sockets: int, io_threads: int = 1) -> zmq.Context:
    zctx = zmq.Context(io_threads=io_threads)
    zctx.set(zmq.MAX_SOCKETS, max(1023, n_sockets + 64))  # default 1023 sockets a context
    return zctx


def launch(spec: dict | WatchSpec, name: str) -> Child:
    """A swarm process running the task `spec` describes (a WatchSpec, or a churn or malformed dict)."""
    return Child(["-m", "processes.stress.swarm", json.dumps(spec.to_json() if isinstance(spec, WatchSpec) else spec)],
                 name)


def watch_spec(endpoint, n_spec, n_play, name, record=None, **kw) -> WatchSpec:
    """A watch swarm of n_spec spectators and n_play players on endpoint; kw: WatchSpec's other fields."""
    return WatchSpec(address=endpoint, spectators=n_spec, players=n_play, name=name, record=record, **kw)


def split(n: int) -> list[int]:
    """n clients in as few swarm processes of at most PER_SWARM as can hold them, evenly."""
    k = max(1, -(-n // PER_SWARM))
    return [n // k + (i < n % k) for i in range(k)]
