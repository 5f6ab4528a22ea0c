"""`python -m processes.stress.swarm SPEC_JSON`: run one task, print its report as the last JSON line."""
from __future__ import annotations

import json
import os
import sys

from processes.stress.swarm import emit
from processes.stress.swarm.abuse import abuse
from processes.stress.swarm.churn import churn
from processes.stress.swarm.malformed import malformed
from processes.stress.swarm.spec import WatchSpec
from processes.stress.swarm.watch import watch


def _watch(spec: dict) -> dict:
    return watch(WatchSpec.from_json(spec))


TASKS = {"watch": _watch, "churn": churn, "malformed": malformed, "abuse": abuse}


def main(argv: list[str]) -> int:
    spec = json.loads(argv[0])
    report = TASKS[spec["task"]](spec)
    emit({"event": "report", "pid": os.getpid(), **report})
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
