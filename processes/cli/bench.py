"""`pingpong bench NAME` and `pingpong profile-net`: any study of the bench registry, by name.

The command knows no study: it lists bench.STUDIES and hands the arguments after NAME to the
study's own parser (bench.study.run), which the study's module builds when it runs, so
`pingpong --help` imports none of them.
"""
from __future__ import annotations

import argparse

from bench import STUDIES, load_study
from bench import study as contract


def run_study(name: str, argv: list[str], prog: str) -> int:
    """Run the study `name` with its own flags argv; the exit status."""
    return contract.run(load_study(name), argv, prog, name)


def bench_command(args: argparse.Namespace) -> int:
    """Run `pingpong bench NAME ...`; returns the exit status."""
    return run_study(args.what, args.study_args, f"pingpong bench {args.what}")


def profile_net_command(args: argparse.Namespace) -> int:
    """Run `pingpong profile-net ...`, the study `bench profile-net`; returns the exit status."""
    return run_study("profile-net", args.unparsed, "pingpong profile-net")


def add_commands(sub) -> None:
    """`pingpong bench NAME` and `pingpong profile-net`."""
    listing = "\n".join(f"  {name:<16}{summary}" for name, (_, summary) in STUDIES.items())
    bench = sub.add_parser("bench", help="measured answers to 'what does it cost'",
                           formatter_class=argparse.RawDescriptionHelpFormatter,
                           epilog=f"studies:\n{listing}\n`pingpong bench NAME --help` gives a study's own flags "
                                  "(every study takes --json, most --quick).")
    bench.add_argument("what", choices=list(STUDIES), metavar="NAME", help="which study to run")
    bench.add_argument("study_args", nargs=argparse.REMAINDER, metavar="...", help="the study's own flags")
    bench.set_defaults(func=bench_command)
    # Its flags (and --help) are the study's: processes.cli.main hands them on unparsed.
    profile = sub.add_parser("profile-net", help=f"{STUDIES['profile-net'][1]} "
                             "(= pingpong bench profile-net)", add_help=False)
    profile.set_defaults(func=profile_net_command, takes_unparsed=True)
