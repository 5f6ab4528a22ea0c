"""`python -m tests.warmup`: load or compile, once, the numba kernels that the suite's processes run.

A cold numba cache compiles for minutes (one specialisation per effect combination and array
type), and a worker compiles before it says it is ready: a test that starts a server on a cold
cache would spend its wait for the server's first line on compiling. `make test` runs this first,
so the suite's tests load the kernels from the cache instead. It runs what the tests run: a
match in worker processes on each bundled match scene (the physics, net and AI workers
compile what they run, numba.config.CACHE_DIR is the same for every process of this checkout),
a served match's workers, a bot's client, the in-process match, and the batched vector
environment with each net (its step is one kernel that two test files run). Prints what each step took.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.waits import DEADLINE_S, POLL_S, Deadline

ROOT = Path(__file__).resolve().parents[1]
IN_PROCESS = """\
from engine.physics.scene import load_scene
from engine.play.match import Match
from processes.cli.join import _warm_up
for name in ("match_rigid", "match"):
    Match(load_scene(name), 0).play(max_ticks=2)
_warm_up("pro")
"""
BATCHED = """\
import numpy as np
from engine.learning.vector_env import PingPongVectorEnv
for net in ("rigid", "cloth"):
    vector = PingPongVectorEnv(1, opponent="novice", version=1, net=net)
    vector.reset(seed=0)
    vector.step(np.zeros((1, 6)))
"""
# Stages one after the other, the steps of a stage side by side. The first compiles nearly every
# kernel (its physics, net and AI workers side by side, on both cores); the others then load
# those from the cache and compile only their own few, so they do not compile the same twice.
STAGES = (
    (("match workers", ["-m", "processes", "match", "--scene", "match", "--ticks", "2", "--json"]),),
    (("in-process match and bot", ["-c", IN_PROCESS]),
     ("match_rigid workers", ["-m", "processes", "match", "--scene", "match_rigid", "--ticks", "2", "--json"]),
     ("served match", ["-m", "processes", "serve", "--players", "0", "--ticks", "2", "--json"]),
     ("batched vector env", ["-c", BATCHED])),
)


def main() -> int:
    start = time.monotonic()
    failed = []
    for stage in STAGES:
        failed += _run_stage(stage)
    print(f"warm-up: {time.monotonic() - start:.0f} s", flush=True)
    for name, err in failed:
        print(f"warm-up: {name} failed (the tests will say why):\n{err[-2000:]}", file=sys.stderr)
    return 0  # a failing step is the suite's to report, with its own test


def _run_stage(stage) -> list[tuple[str, str]]:
    """Runs the stage's steps side by side; says when each ended; (name, stderr) of those that failed."""
    began = time.monotonic()
    running, failed = {}, []
    for name, args in stage:
        err = tempfile.TemporaryFile("w+")  # a file, not a pipe: nobody reads it until the step ends
        running[name] = (subprocess.Popen([sys.executable, *args], cwd=ROOT, stdin=subprocess.DEVNULL,
                                          stdout=subprocess.DEVNULL, stderr=err, text=True), err)
    deadline = Deadline()
    while running:
        for name, (proc, err) in list(running.items()):
            if proc.poll() is None and not deadline.expired():
                continue
            if proc.poll() is None:
                proc.kill()
                proc.wait()
                failed.append((name, f"still running after {DEADLINE_S:.0f} s"))
            elif proc.returncode:
                err.seek(0)
                failed.append((name, err.read()))
            print(f"warm-up: {name}: {time.monotonic() - began:.0f} s", flush=True)
            err.close()
            del running[name]
        time.sleep(POLL_S)  # polling the steps' exits, bounded by the deadline
    return failed


if __name__ == "__main__":
    sys.exit(main())
