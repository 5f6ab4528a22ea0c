"""What every `pingpong` command family shares: the common flags."""
from __future__ import annotations

import argparse

FORMATTER = argparse.ArgumentDefaultsHelpFormatter


def add_common(parser: argparse.ArgumentParser) -> None:
    """--seed and --json, the flags most commands take."""
    parser.add_argument("--seed", type=int, default=0, help="seed of every random number in the run")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a human summary")
