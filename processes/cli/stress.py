"""`pingpong stress`: the gateway's connections under load, churn, pulled cables, kills and bad messages."""
from __future__ import annotations

from processes.cli.common import FORMATTER
from processes.stress import add_arguments, stress_command


def add_commands(sub) -> None:
    """`pingpong stress` (its arguments are the stress tool's own: processes.stress.command)."""
    stress = sub.add_parser("stress", help="stress-test the gateway: load, churn, pulled cables, kills, bad messages",
                            formatter_class=FORMATTER)
    add_arguments(stress)
    stress.set_defaults(func=stress_command)
