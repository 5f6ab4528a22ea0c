"""`python -m tests.hogs N -- COMMAND...`: run COMMAND with N CPU hogs beside it, then stop them.

A busy machine on demand, to check that the suite passes on one (`make test-busy` runs
`make test` with two): each hog is a Python process spinning `while True: pass` at the default
priority, as another user's job would. The hogs are stopped when the command ends, fails or is
interrupted (Ctrl-C, SIGTERM), and die with this process if it is killed (Linux's
PR_SET_PDEATHSIG). Exits with the command's status and says how long it ran and the load
average it saw.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time

from processes.stress.hogs import CpuHogs


def _terminated(signum, frame):
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.hogs", description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("hogs", type=int, help="CPU hogs to run beside the command")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if args.hogs < 0:
        parser.error(f"N must be 0 or more, got {args.hogs}")
    if not command:
        parser.error("no command: python -m tests.hogs 2 -- make test")
    signal.signal(signal.SIGTERM, _terminated)
    hogs = CpuHogs(args.hogs)
    try:
        hogs.start()
        print(f"hogs: {hogs.n} running (pids {' '.join(str(p) for p in hogs.pids)}): {' '.join(command)}",
              file=sys.stderr, flush=True)
        start = time.monotonic()
        status = subprocess.call(command)
        print(f"hogs: the command ended with status {status} after {time.monotonic() - start:.0f} s beside "
              f"{hogs.n} hogs; load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}",
              file=sys.stderr, flush=True)
        return status
    except KeyboardInterrupt:
        return 130
    finally:
        hogs.stop()


if __name__ == "__main__":
    sys.exit(main())
