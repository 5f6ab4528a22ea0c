"""The command line of `pingpong stress`: its arguments (add_arguments) and its thin entry point."""
from __future__ import annotations

import argparse
import json
import sys

SCENARIOS = ("load", "churn", "cable", "kill", "malformed", "web", "busy", "abuse")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Every argument of `pingpong stress`, added to its subcommand's parser."""
    parser.add_argument("--scenario", default=",".join(SCENARIOS), help="comma-separated scenarios")
    parser.add_argument("--spectators", type=int, default=1000, help="load: spectators watching")
    parser.add_argument("--players", type=int, default=2, help="bot players of the served match (2)")
    parser.add_argument("--hz", type=int, default=120, help="load: snapshots per second")
    parser.add_argument("--duration", type=float, default=10.0, help="load: seconds of play")
    parser.add_argument("--still-players", action="store_true", help="load: players that hold their bats still "
                        "instead of two bots (measures the fan-out alone)")
    parser.add_argument("--fanout", choices=("pub", "router"), default="pub",
                        help="load: spectators' snapshots from the gateway's PUB feed, or one send per session "
                             "(protocol 1's fan-out, to compare)")
    parser.add_argument("--browsers", type=int, default=50, help="web: WebSocket browsers on one web bridge")
    parser.add_argument("--hogs", type=int, default=2, help="busy: CPU hogs spinning beside the served cloth match")
    parser.add_argument("--busy-spectators", type=int, default=20, help="busy: spectators of the served cloth match")
    parser.add_argument("--busy-browsers", type=int, default=5, help="busy: WebSocket browsers on its web bridge")
    parser.add_argument("--churn", type=int, default=10_000, help="churn: join/leave cycles")
    parser.add_argument("--churn-places", type=int, default=64, help="churn: spectator places, filled after it")
    parser.add_argument("--churn-seconds", type=float, default=600.0, help="churn: give up after this long")
    parser.add_argument("--malformed", type=int, default=100_000, help="malformed: bad messages sent")
    parser.add_argument("--malformed-rate", type=int, default=10_000, help="malformed: messages per second at most")
    parser.add_argument("--abuse-seconds", type=float, default=5.0,
                        help="abuse: seconds of each attack, and of the quiet windows before and after them")
    parser.add_argument("--abuse-spectators", type=int, default=8, help="abuse: honest spectators watching")
    parser.add_argument("--kill", type=int, default=2, help="kill: client processes SIGKILLed (then gateway, physics)")
    parser.add_argument("--kill-spectators", type=int, default=100, help="kill: spectator places, all full at shutdown")
    parser.add_argument("--plots", metavar="DIR", default=None,
                        help="load: write the latency CDF and the per-second rate (PNG) into DIR")
    parser.add_argument("--server-only", action="store_true",
                        help="load: only the server and its players; it prints its address and waits for the "
                             "spectators of a --swarm-only run")
    parser.add_argument("--bind", default="tcp://127.0.0.1:0",
                        help="--server-only: the gateway's endpoint (tcp://0.0.0.0:PORT for other hosts)")
    parser.add_argument("--swarm-only", action="store_true",
                        help="load: only the spectators, against the --server-only server at --target")
    parser.add_argument("--target", metavar="ADDRESS", default=None,
                        help="--swarm-only: the server's endpoint, e.g. tcp://HOST:PORT")
    parser.add_argument("--seed", type=int, default=0, help="seed of the churn mix and of the bad messages")
    parser.add_argument("--json", action="store_true", help="one JSON object per scenario, one per line")


def stress_command(args: argparse.Namespace) -> int:
    # imported here: the parser that add_arguments fills is built for every `pingpong` command
    from processes.stress.report import print_table
    from processes.stress.scenarios import run_scenario

    names = [s.strip() for s in args.scenario.split(",") if s.strip()]
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown:
        print(f"pingpong stress: unknown scenario {', '.join(unknown)}; choose from {','.join(SCENARIOS)}",
              file=sys.stderr)
        return 2
    if args.players != 2:
        print("pingpong stress: --players must be 2 (the served match waits for both seats)", file=sys.stderr)
        return 2
    if args.swarm_only != bool(args.target):
        print("pingpong stress: --swarm-only needs --target ADDRESS, and --target goes with --swarm-only",
              file=sys.stderr)
        return 2
    if (args.swarm_only or args.server_only) and (names != ["load"] or args.swarm_only == args.server_only):
        print("pingpong stress: --swarm-only or --server-only (one of them) run the load scenario alone: "
              "add --scenario load", file=sys.stderr)
        return 2
    for flag in ("hogs", "busy_browsers"):
        if getattr(args, flag) < 0:
            print(f"pingpong stress: --{flag.replace('_', '-')} must be 0 or more, got {getattr(args, flag)}",
                  file=sys.stderr)
            return 2
    if not args.abuse_seconds > 0:
        print(f"pingpong stress: --abuse-seconds must be > 0, got {args.abuse_seconds}", file=sys.stderr)
        return 2
    for flag in ("spectators", "busy_spectators", "churn", "malformed", "kill", "hz", "abuse_spectators"):
        if getattr(args, flag) < 1:
            print(f"pingpong stress: --{flag.replace('_', '-')} must be at least 1, got {getattr(args, flag)}",
                  file=sys.stderr)
            return 2
    results = []
    for name in names:
        result = run_scenario(name, args)
        results.append(result)
        if args.json:
            print(json.dumps(result), flush=True)
    if not args.json:
        print_table(results)
    return 0 if all(r["ok"] for r in results) else 1
