"""pingpong: a distributed table tennis engine.

Physics, the cloth net and the bat AI run as separate OS processes sharing numpy arrays in
shared memory; a ZeroMQ gateway lets remote people play a bat or watch. Play a match (AI
against AI), replay it, serve it to remote players and spectators, measure what accuracy costs,
profile the net kernel, stress-test the connections, and play tournaments and sweeps of many
matches on a local process pool or a Ray cluster.
"""
from __future__ import annotations

import argparse
import sys

from processes.cli import bench, decode, join, match, run, serve, stress, sweep, tournament

EPILOG = """examples:
  pingpong match                          a best-of-5 AI match in worker processes, live score
  pingpong match --replay m.replay        ... and record it; pingpong replay m.replay --png m.png
  pingpong serve --players 1              serve a match; pingpong join ADDRESS --as player --bot
  pingpong bench accuracy                 what accuracy costs in time (work-precision study)
  pingpong profile-net                    springs per second, share of the memory bandwidth
  pingpong stress --scenario load         1000 spectators against the gateway
  pingpong tournament --seeds 50          every pair of AI profiles, 50 seeds, on all cores (--cluster ray)
  pingpong sweep match --set match.ai_hz=100,250   one scene key's values, each cell's matches as tasks
`pingpong COMMAND --help` describes each command."""

FAMILIES = (run, match, bench, serve, join, decode, stress, tournament, sweep)


def build_parser() -> argparse.ArgumentParser:
    """The whole `pingpong` parser: each command family adds its own commands and arguments."""
    parser = argparse.ArgumentParser(prog="pingpong", description=__doc__,
                                     epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for family in FAMILIES:
        family.add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    # A command whose flags are another parser's (`pingpong profile-net`) takes the rest unparsed.
    args, unparsed = parser.parse_known_args(argv)
    if unparsed and not getattr(args, "takes_unparsed", False):
        parser.error(f"unrecognized arguments: {' '.join(unparsed)}")
    args.unparsed = unparsed
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
