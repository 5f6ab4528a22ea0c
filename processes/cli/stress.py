"""`pingpong stress`: the gateway's connections under load, churn, pulled cables, kills and bad messages."""
from __future__ import annotations

import argparse

from processes.cli.common import FORMATTER


def _stress_command(args: argparse.Namespace) -> int:
    from processes.stress.scenarios import stress_command

    return stress_command(args)


def add_commands(sub) -> None:
    """`pingpong stress`."""
    stress = sub.add_parser("stress", help="stress-test the gateway: load, churn, pulled cables, kills, bad messages",
                            formatter_class=FORMATTER)
    stress.add_argument("--scenario", default="load,churn,cable,kill,malformed", help="comma-separated scenarios")
    stress.add_argument("--spectators", type=int, default=1000, help="load: spectators watching")
    stress.add_argument("--players", type=int, default=2, help="bot players of the served match (2)")
    stress.add_argument("--hz", type=int, default=120, help="load: snapshots per second")
    stress.add_argument("--duration", type=float, default=10.0, help="load: seconds of play")
    stress.add_argument("--still-players", action="store_true", help="load: players that hold their bats still "
                        "instead of two bots (measures the fan-out alone)")
    stress.add_argument("--fanout", choices=("pub", "router"), default="pub",
                        help="load: spectators' snapshots from the gateway's PUB feed, or one send per session "
                             "(protocol 1's fan-out, to compare)")
    stress.add_argument("--churn", type=int, default=10_000, help="churn: join/leave cycles")
    stress.add_argument("--churn-places", type=int, default=64, help="churn: spectator places, filled after it")
    stress.add_argument("--churn-seconds", type=float, default=600.0, help="churn: give up after this long")
    stress.add_argument("--malformed", type=int, default=100_000, help="malformed: bad messages sent")
    stress.add_argument("--malformed-rate", type=int, default=10_000, help="malformed: messages per second at most")
    stress.add_argument("--kill", type=int, default=2, help="kill: client processes SIGKILLed (then gateway, physics)")
    stress.add_argument("--kill-spectators", type=int, default=100, help="kill: spectator places, all full at shutdown")
    stress.add_argument("--seed", type=int, default=0, help="seed of the churn mix and of the bad messages")
    stress.add_argument("--json", action="store_true", help="one JSON object per scenario, one per line")
    stress.set_defaults(func=_stress_command)
