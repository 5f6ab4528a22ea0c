"""OS processes and their plumbing: shared memory, locks, workers, supervisor, gateway, CLI."""
from __future__ import annotations

import signal
import sys

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """The `pingpong` command (processes.cli.main). A Ctrl-C that no command takes over, even one
    while its modules are still being imported, ends it with status 130 and one line, not a
    traceback."""
    try:
        from processes.cli import main as cli_main

        return cli_main(argv)
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # one request: a second Ctrl-C finds it ending
        sys.stderr.write("pingpong: interrupted\n")
        return 130
