"""What every `pingpong` command family shares: the common flags."""
from __future__ import annotations

import argparse


class Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's help with each option's default appended, except where the default is None (the
    help says what stands in for it: "the scene's") or the help gives it already."""

    def _get_help_string(self, action):
        if action.default is None or "(default:" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


FORMATTER = Formatter
# engine.play.players.DEFAULT_BUDGET_S in ms, spelled out: the parser imports no engine (tests/processes/cli/test_cli.py
# checks the two agree).
BOT_BUDGET_MS = 20.0


def add_common(parser: argparse.ArgumentParser) -> None:
    """--seed and --json, the flags most commands take."""
    parser.add_argument("--seed", type=int, default=0, help="seed of every random number in the run")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a human summary")


def add_session_options(parser: argparse.ArgumentParser, whose: str = "the server's") -> None:
    """--join-timeout and --curve-server-key: how a client command opens its session."""
    parser.add_argument("--join-timeout", type=float, default=10.0, help="s to wait for the welcome")
    parser.add_argument("--curve-server-key", default=None, metavar="FILE",
                        help=f"{whose} public key file: connect CURVE-encrypted (`pingpong keys DIR`)")


def add_bot_options(parser: argparse.ArgumentParser) -> None:
    """--on-bot-error and --bot-budget-ms: what a match does about a bot's failed decision."""
    parser.add_argument("--on-bot-error", choices=["point", "stop"], default="point",
                        help="a bot's decision that raises, returns a malformed, non-finite or oversized action or "
                             "overruns its budget: the point goes to the other player, or the match stops "
                             "(pingpong match then exits with status 1)")
    parser.add_argument("--bot-budget-ms", type=float, default=BOT_BUDGET_MS,
                        help="CPU milliseconds a bot's decision may take (a bot's own budget_s wins)")


def add_players(parser: argparse.ArgumentParser) -> None:
    """--a and --b (each bat's player) and the bot options."""
    for end in ("a", "b"):
        parser.add_argument(f"--{end}", default=None, metavar="PLAYER",
                            help=f"bat {end.upper()}'s player: an AI profile (pro, club, novice) or a bot, "
                                 "FILE.py:Class or module:Class (default: the scene's)")
    add_bot_options(parser)


def bot_budget_s(args: argparse.Namespace) -> float:
    """--bot-budget-ms in seconds, refused unless positive."""
    if not args.bot_budget_ms > 0:
        raise ValueError(f"--bot-budget-ms: must be > 0, got {args.bot_budget_ms}")
    return args.bot_budget_ms / 1000.0


def check_players(players) -> None:
    """Load every bot among the players now, so a bad spec or file is told before anything starts
    (ValueError naming it)."""
    from engine.physics.scene import is_bot_spec
    from engine.play.bot import load_bot

    for player in players:
        if player is not None and is_bot_spec(player):
            load_bot(player)


def with_players(scene, args: argparse.Namespace):
    """The scene with --a and --b as its bats' players (each kept from the scene when not given)."""
    from engine.physics.scene import with_skills

    bot_budget_s(args)
    if args.a is None and args.b is None:
        return scene
    check_players((args.a, args.b))
    a = args.a if args.a is not None else scene.bats[0].skill
    b = args.b if args.b is not None else scene.bats[1].skill
    return with_skills(scene, a, b)
