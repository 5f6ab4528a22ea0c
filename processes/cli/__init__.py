"""The `pingpong` command line: one argparse parser with thin subcommand functions."""
from __future__ import annotations

import argparse
import sys

from processes.cli import sweep, tournament


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="seed of every random number in the run")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a human summary")


def _cmd_run(args: argparse.Namespace) -> int:
    from processes.cli.run import run_scene_command

    return run_scene_command(args)


def _cmd_match(args: argparse.Namespace) -> int:
    from processes.cli.match import match_command

    return match_command(args)


def _cmd_replay(args: argparse.Namespace) -> int:
    from processes.cli.match import replay_command

    return replay_command(args)


def _cmd_profile_net(args: argparse.Namespace) -> int:
    from processes.cli.profile_net import profile_net_command

    return profile_net_command(args)


def _cmd_bench(args: argparse.Namespace) -> int:
    if args.what == "handoff":
        from processes.cli.handoff import handoff_command

        return handoff_command(args)
    if args.what == "match":
        from processes.cli.match import bench_match_command

        return bench_match_command(args)
    from processes.cli.bench import bench_command

    return bench_command(args)


def _cmd_stability(args: argparse.Namespace) -> int:
    from processes.cli.run import stability_command

    return stability_command(args)


def _cmd_decode(args: argparse.Namespace) -> int:
    from processes.network.wire import decode_command

    return decode_command(args)


def _cmd_serve(args: argparse.Namespace) -> int:
    from processes.network.client import serve_command

    return serve_command(args)


def _cmd_join(args: argparse.Namespace) -> int:
    from processes.network.client import join_command

    return join_command(args)


def _cmd_stress(args: argparse.Namespace) -> int:
    from processes.stress.scenarios import stress_command

    return stress_command(args)


def _cmd_keys(args: argparse.Namespace) -> int:
    from processes.network.client import keys_command

    return keys_command(args)


def build_parser() -> argparse.ArgumentParser:
    """The whole `pingpong` parser; subcommands share --seed/--json."""
    formatter = argparse.ArgumentDefaultsHelpFormatter
    parser = argparse.ArgumentParser(prog="pingpong", description=__doc__, formatter_class=formatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser("run", help="run a scene in-process", formatter_class=formatter)
    run.add_argument("scene", help="scene TOML file, or the name of a bundled scene (drop, serve, rally)")
    run.add_argument("--ticks", type=int, default=None, help="ticks to run (default: the scene's duration)")
    run.add_argument("--dt", type=float, default=None, help="tick length in seconds (default: the scene's)")
    run.add_argument("--integrator", default=None, help="ball integrator (default: the scene's)")
    run.add_argument("--processes", action="store_true", help="run in separate worker processes")
    run.add_argument("--mode", choices=["lockstep", "realtime"], default="lockstep",
                     help="with --processes: lockstep (deterministic, flat out) or realtime (wall-clock paced)")
    run.add_argument("--check-reference", action="store_true",
                     help="with --processes: also run in-process and check every tick is bitwise equal")
    run.add_argument("--crash-at-tick", type=int, default=None, help=argparse.SUPPRESS)
    _add_common(run)
    run.set_defaults(func=_cmd_run)

    match = sub.add_parser("match", help="play a match (AI against AI by default) in worker processes",
                           formatter_class=formatter)
    match.add_argument("--scene", default="match", help="scene TOML file or bundled scene name")
    match.add_argument("--best-of", type=int, default=None, help="games in the match (default: the scene's)")
    match.add_argument("--mode", choices=["lockstep", "realtime"], default="lockstep",
                       help="lockstep (deterministic, flat out) or realtime (wall-clock paced)")
    match.add_argument("--ticks", type=int, default=None, help="stop after this many ticks even if undecided")
    match.add_argument("--replay", default=None, help="write a replay file here")
    match.add_argument("--in-process", action="store_true", help="run the in-process reference instead of workers")
    _add_common(match)
    match.set_defaults(func=_cmd_match)

    stability = sub.add_parser("stability", help="run the stability suite's hard cases", formatter_class=formatter)
    stability.add_argument("--long", action="store_true", help="also the long runs (10^6 ticks)")
    stability.add_argument("--case", default=None, help="only cases whose name contains this text")
    stability.add_argument("--json", action="store_true", help="one JSON object per case, one per line")
    stability.set_defaults(func=_cmd_stability)

    replay = sub.add_parser("replay", help="summarise a replay file", formatter_class=formatter)
    replay.add_argument("file", help="a file written by `pingpong match --replay`")
    replay.add_argument("--json", action="store_true", help="print one JSON object")
    replay.add_argument("--png", default=None, help="draw side and top views of the last rally to this PNG")
    replay.add_argument("--gif", default=None, help="animate the last seconds to this GIF")
    replay.set_defaults(func=_cmd_replay)

    profile = sub.add_parser("profile-net", help="profile the net kernel", formatter_class=formatter)
    profile.add_argument("--knots", default="184x16", help="knot grid, COLUMNSxROWS")
    profile.add_argument("--steps", type=int, default=None, help="timed steps (default: sized to ~1 s per backend)")
    profile.add_argument("--backend", choices=["numba", "reference", "both"], default="both")
    profile.add_argument("--path", choices=["grid", "csr", "both"], default="both",
                         help="kernel path: the grid kernel NetSim uses, the general CSR kernel, or both")
    profile.add_argument("--json", action="store_true", help="print one JSON object")
    profile.set_defaults(func=_cmd_profile_net)
    bench = sub.add_parser("bench", help="measured answers to 'what does it cost'", formatter_class=formatter)
    bench.add_argument("what", choices=["accuracy", "effects", "handoff", "match", "net-resolution"],
                       help="which study to run")
    bench.add_argument("--best-of", type=int, default=5, help="match: games in the benchmarked match")
    bench.add_argument("--scene", default="match",
                       help="match: scene TOML file or bundled scene name (match_cloth: the cloth net)")
    bench.add_argument("--seed", type=int, default=0, help="match: the match's seed")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    bench.add_argument("--png", default=None, help="accuracy: write the work-precision plot to this PNG file")
    bench.add_argument("--quick", action="store_true", help="fewer step sizes and repeats (smoke runs)")
    bench.add_argument("--sizes", default=None,
                       help="net-resolution: nets as COLSxROWS, comma-separated (the finest is the reference)")
    bench.add_argument("--impacts", type=int, default=None, help="net-resolution: number of impacts")
    bench.set_defaults(func=_cmd_bench)

    decode = sub.add_parser("decode", help="pretty-print one captured wire message (exit 2 if it is bad)",
                            formatter_class=formatter)
    decode.add_argument("message", metavar="FILE|HEX", help="a file of the message's raw bytes, or its bytes in hex")
    decode.add_argument("--json", action="store_true", help="print one JSON object")
    decode.set_defaults(func=_cmd_decode)

    serve = sub.add_parser("serve", help="serve a realtime match that remote players and spectators join",
                           formatter_class=formatter)
    serve.add_argument("--scene", default="match", help="scene TOML file or bundled scene name (needs a referee)")
    serve.add_argument("--bind", default="tcp://127.0.0.1:0", help="ZeroMQ endpoint; port 0 picks a free port")
    serve.add_argument("--players", type=int, choices=[0, 1, 2], default=1,
                       help="remote players (bat A first); the other bats are played by the AI")
    serve.add_argument("--best-of", type=int, default=None, help="games in the match (default: the scene's)")
    serve.add_argument("--ticks", type=int, default=None, help="stop after this many ticks even if undecided")
    serve.add_argument("--snapshot-hz", type=int, default=100, help="snapshots per second to every client")
    serve.add_argument("--timeout", type=float, default=5.0, help="s, a silent client is dropped after this")
    serve.add_argument("--grace", type=float, default=30.0, help="s, a dropped player's seat waits for its token")
    serve.add_argument("--wait", type=float, default=300.0, help="s, wait for the remote players, then start")
    serve.add_argument("--crash-gateway-at-tick", type=int, default=None, help=argparse.SUPPRESS)
    serve.add_argument("--curve-secret", default=None, metavar="FILE",
                       help="CURVE-encrypt every session with this server secret key file (`pingpong keys DIR`)")
    _add_common(serve)
    serve.set_defaults(func=_cmd_serve)

    join = sub.add_parser("join", help="join a served match as a player or a spectator", formatter_class=formatter)
    join.add_argument("address", help="the server's endpoint, e.g. tcp://127.0.0.1:5555")
    join.add_argument("--as", dest="role", choices=["player", "spectator"], default="spectator")
    join.add_argument("--bot", action="store_true", help="a player played by engine.ai through the network")
    join.add_argument("--skill", choices=["pro", "club", "novice"], default="pro", help="the bot's skill")
    join.add_argument("--slot", choices=["any", "a", "b"], default="any", help="the seat wanted")
    join.add_argument("--name", default="client", help="shown to the other clients")
    join.add_argument("--token", default=None, help="rejoin token (hex) from an earlier session")
    join.add_argument("--seconds", type=float, default=3600.0, help="leave after this long at most")
    join.add_argument("--join-timeout", type=float, default=10.0, help="s to wait for the welcome")
    join.add_argument("--delay-ms", type=float, default=100.0, help="a spectator's view runs this far behind")
    join.add_argument("--curve-server-key", default=None, metavar="FILE",
                      help="the server's public key file: connect CURVE-encrypted (`pingpong keys DIR`)")
    _add_common(join)
    join.set_defaults(func=_cmd_join)

    keys = sub.add_parser("keys", help="make a CURVE key pair for `serve --curve-secret` / `join --curve-server-key`",
                          formatter_class=formatter)
    keys.add_argument("dir", help="directory to write NAME.key (public) and NAME.key_secret into")
    keys.add_argument("--name", default="server", help="file name stem")
    keys.add_argument("--json", action="store_true", help="print one JSON object")
    keys.set_defaults(func=_cmd_keys)

    stress = sub.add_parser("stress", help="stress-test the gateway: load, churn, pulled cables, kills, bad messages",
                            formatter_class=formatter)
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
    stress.set_defaults(func=_cmd_stress)

    tournament.add_parser(sub, formatter)
    sweep.add_parser(sub, formatter)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
