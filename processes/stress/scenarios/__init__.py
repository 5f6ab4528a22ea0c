"""The scenarios of `pingpong stress`, one module each, and run_scenario, which runs one of them.

Each scenario takes the command line's arguments and a Run, starts its own server and client
processes through it, and returns its result (processes.stress.result): `problems` empty when the
scenario passes.
"""
from __future__ import annotations

import tempfile

from processes.stress.harness import Run, StressError
from processes.stress.probes import loadavg
from processes.stress.result import base
from processes.stress.scenarios import abuse, busy, cable, churn, kill, load, malformed, web

RUNNERS = {"load": load.scenario, "churn": churn.scenario, "cable": cable.scenario, "kill": kill.scenario,
           "malformed": malformed.scenario, "web": web.scenario, "busy": busy.scenario,
           "abuse": abuse.scenario}

__all__ = ["RUNNERS", "run_scenario"]


def run_scenario(name: str, args) -> dict:
    with tempfile.TemporaryDirectory(prefix="pingpong-stress-") as tmp:
        run = Run(tmp, [])
        before = loadavg()  # the machine is shared: how busy it was says how far to trust the times
        try:
            result = RUNNERS[name](args, run)
            result["loadavg_before_after"] = [before, loadavg()]
        except StressError as err:
            result = base(name)
            result["crashes"] = 1
            result["problems"].append(str(err))
        finally:
            removed = run.close()
        if removed:  # a server that had to be killed: its segments are removed here, and counted
            result["leaked_shm"] = max(result["leaked_shm"], len(removed))
            result["problems"].append(f"segments of a killed server removed by the harness: {len(removed)}")
            result["ok"] = False
        return result
