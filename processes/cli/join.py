"""`pingpong join` and `watch`: a served match played (bot or keyboard) or watched, in the terminal
or, through a web bridge, in the browser."""
from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

from processes.cli.common import (BOT_BUDGET_MS, FORMATTER, add_common, add_session_options, bot_budget_s,
                                  check_players)

if TYPE_CHECKING:
    from processes.network import wire
    from processes.network.client.client import Client
    from processes.network.wire import Slot



def join_command(args: argparse.Namespace) -> int:
    """`pingpong join ADDRESS --as player|spectator [--bot [PLAYER]]`."""
    from engine.physics.scene import is_bot_spec
    from engine.physics.scene import SceneError
    from processes.network.client.client import Client, Rejected, curve_client_options
    from processes.network.wire import NO_TOKEN
    from processes.network.wire import Slot

    keyboard = args.role == "player" and args.bot is None
    if args.bot == "":  # --bot without a player: the --skill profile
        args.bot = args.skill
    if keyboard and not sys.stdin.isatty():
        print("pingpong join: keyboard play needs a terminal (stdin is not a TTY); join a player with --bot, "
              "or --as spectator", file=sys.stderr)
        return 2
    slot = {"any": Slot.NONE, "a": Slot.A, "b": Slot.B}[args.slot]
    try:
        token = bytes.fromhex(args.token) if args.token else NO_TOKEN
        socket_options = curve_client_options(getattr(args, "curve_server_key", None))
        if args.bot is not None:
            bot_budget_s(args)
            check_players([args.bot])  # a bad spec or file is told before the hello
    except (ValueError, OSError) as err:
        print(f"pingpong join: {err}", file=sys.stderr)
        return 2
    if args.role == "player":
        if not args.json:
            print("loading the engine's kernels (compiled on a first run) ...", file=sys.stderr, flush=True)
        # before the hello: a cold numba cache compiles for minutes, no heartbeats meanwhile
        _warm_up(args.skill if args.bot is None or is_bot_spec(args.bot) else args.bot)
    client = Client(args.address, args.role, args.name, slot, token, socket_options=socket_options)
    summary = {"address": args.address, "role": args.role, "snapshots": 0, "events": [], "inputs_sent": 0}
    try:
        try:
            welcome = client.join(args.join_timeout)
        except Rejected as err:
            summary.update(rejected=err.reason.name.lower(), detail=err.detail)
            print(json.dumps(summary) if args.json else f"pingpong join: {err}", file=sys.stdout if args.json else sys.stderr)
            return 3
        except TimeoutError as err:
            print(f"pingpong join: {err}", file=sys.stderr)
            return 4
        summary.update(slot=client.slot.name.lower(), scene=welcome["scene"], scene_digest=welcome["scene_digest"].hex(),
                       token=client.token.hex(), snapshot_hz=welcome["snapshot_hz"])
        if not args.json and not keyboard:
            print(f"joined {welcome['scene']} as {'player ' + client.slot.name if client.slot else 'spectator'}"
                  f" (best of {welcome['best_of']}, {welcome['snapshot_hz']} snapshots/s)", flush=True)
        summary.update(_play(client, welcome, args, keyboard))
    except (TimeoutError, ValueError) as err:  # no scene came, or not the welcome's (SceneError); a bot refused
        client.leave()
        print(f"pingpong join: {err}", file=sys.stderr)
        return 4 if isinstance(err, TimeoutError) else 1 if isinstance(err, SceneError) else 2
    except KeyboardInterrupt:
        client.leave()
        summary["goodbye"] = "interrupted"
    finally:
        client.close()
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"session ended: {summary['goodbye']}; {summary['snapshots']} snapshots, "
              f"{len(summary['events'])} events")
        for error in summary.get("bot_errors", []):  # as a match names them
            print(f"bot error: {error['bot']} (player {error['player'].upper()}) at tick {error['tick']}: "
                  f"{error['fault']}: {error['detail']}")
        if "prediction" in summary:
            prediction, stale = summary["prediction"], summary["prediction"]["without_prediction"]
            print(_error_line("prediction error at the snapshots' ticks, ball", prediction["ball"]))
            print(_error_line("prediction error at the snapshots' ticks, own bat", prediction["bat"]))
            print(_error_line("without prediction (the previous snapshot), ball", stale["ball"]))
            print(_error_line("without prediction (the previous snapshot), own bat", stale["bat"]))
    return 1 if summary["goodbye"] == "server_lost" else 0


def _warm_up(skill: str) -> None:
    """Load (or compile) every kernel a player's client runs, with the bundled match scene and the
    AI profile `skill`: the kernels depend on types, not on the scene or the player, so the
    served scene's objects and a bot build at once later."""
    from engine.physics.scene import load_scene
    from processes.network.client.brain import BotBrain
    from processes.network.client.prediction import Predictor
    from processes.network.wire import Slot

    scene = load_scene("match")
    Predictor(scene, Slot.A).advance_to(0)
    BotBrain(scene, Slot.A, skill)


def _play(client: Client, welcome: wire.Message, args: argparse.Namespace, keyboard: bool) -> dict:
    """The session of `pingpong join` once welcomed: bot, keyboard or spectator."""
    from processes.network.client.brain import BotBrain
    from processes.network.client.interpolation import Interpolator
    from processes.network.client.keyboard import KeyboardPilot, TerminalKeys
    from processes.network.client.prediction import Predictor
    from processes.network.client.scenes import served_scene
    from processes.network.client.session import SessionOptions, run_session
    from processes.network.wire import Slot

    if client.slot == Slot.NONE:
        view = Interpolator(welcome["dt"], args.delay_ms / 1000.0)

        def show(summary, frame):
            print(_score_line(frame["snapshot"], frame["ball_pos"], frame["ball_vel"], frame["tick"]), flush=True)

        return run_session(client, welcome, SessionOptions(view=view, seconds=args.seconds,
                                                            show=None if args.json else show))
    scene = served_scene(client, args.join_timeout)
    predictor = Predictor(scene, client.slot)
    if not keyboard:
        brain = BotBrain(scene, client.slot, args.bot, args.seed, bot_budget_s(args))
        summary = run_session(client, welcome, SessionOptions(brain=brain, predictor=predictor, seconds=args.seconds))
        errors = [{"player": "ab"[e.player], "bot": e.bot, "tick": e.tick, "fault": e.fault, "detail": e.detail}
                  for e in brain.errors]
        return {**summary, "bot": brain.stats, "bot_errors": errors}
    from rich.console import Console
    from rich.live import Live
    from rich.text import Text

    pilot = KeyboardPilot(predictor.model, client.slot, args.skill)
    with TerminalKeys(sys.stdin.fileno()) as keys, Live(Text("joining ..."), console=Console(),
                                                        auto_refresh=False, transient=False) as live:
        def show(summary, frame):
            live.update(Text(keyboard_screen(summary, frame, client.slot, predictor)), refresh=True)

        return run_session(client, welcome, SessionOptions(pilot=pilot, keys=keys, predictor=predictor,
                                                            seconds=args.seconds, show=show, show_every_s=0.05))


def keyboard_screen(summary: dict, frame: dict, slot: Slot, predictor=None) -> str:
    """The keyboard player's screen: score, top view, keys, prediction error so far."""
    from processes.network.client.keyboard import top_view

    lines = [f"pingpong - you play {slot.name} (+ is your target)",
             _score_line(frame["snapshot"], frame["ball_pos"], frame["ball_vel"], frame["tick"]), ""]
    lines += top_view(frame["ball_pos"], frame["bat_pos"], frame["target"])
    lines += ["", "w/s or up/down: forward/back   a/d or left/right: sideways   r/f: up/down   space: stroke   "
                  "q: leave"]
    if predictor is not None:
        stats = predictor.stats()
        lines += [_error_line("prediction error, ball", stats["ball"]), _error_line("prediction error, bat ", stats["bat"])]
    lines.append(f"inputs sent {summary['inputs_sent']}  snapshots {summary['snapshots']}")
    return "\n".join(lines)


def _score_line(snapshot: wire.Message, ball_pos=None, ball_vel=None, tick=None) -> str:
    import numpy as np

    s, g = snapshot["score"], snapshot["games_won"]
    b = snapshot["ball_pos"] if ball_pos is None else ball_pos
    v = snapshot["ball_vel"] if ball_vel is None else ball_vel
    tick = snapshot.tick if tick is None else tick
    return (f"tick {tick:>9.1f}  games {g[0]}-{g[1]}  points {s[0]}-{s[1]}  rally {snapshot['rally']}  "
            f"ball ({b[0]:+.2f}, {b[1]:+.2f}, {b[2]:+.2f}) m  |v| {float(np.linalg.norm(v)):.1f} m/s")


def _error_line(name: str, stats: dict) -> str:
    if not stats["n"]:
        return f"{name}: no samples"
    return (f"{name}: mean {stats['mean_mm']:.2f}  p50 {stats['p50_mm']:.2f}  p99 {stats['p99_mm']:.2f}  "
            f"max {stats['max_mm']:.2f} mm  ({stats['n']} snapshots)")


def watch_command(args: argparse.Namespace) -> int:
    """`pingpong watch ADDRESS --web HOST:PORT`: the match in the browser (processes.network.web.bridge)."""
    import threading

    from processes.network.client.client import Rejected, curve_client_options
    from processes.network.web.bridge import WebBridge

    try:
        socket_options = curve_client_options(getattr(args, "curve_server_key", None))
        bridge = WebBridge(args.address, args.web, socket_options=socket_options)
    except (ValueError, OSError) as err:
        print(f"pingpong watch: {err}", file=sys.stderr)
        return 2
    try:
        try:
            url = bridge.start(args.join_timeout)
        except Rejected as err:
            print(f"pingpong watch: {err}", file=sys.stderr)
            return 3
        except TimeoutError as err:
            print(f"pingpong watch: {err}", file=sys.stderr)
            return 4
        except OSError as err:
            print(f"pingpong watch: {args.web}: {err}", file=sys.stderr)
            return 2
        if args.json:
            print(json.dumps({"url": url, "watching": args.address}), flush=True)
        else:
            print(f"open {url} in a browser to watch {bridge.counts['scene']} (Ctrl-C stops)", flush=True)
        try:
            bridge.ended.wait(args.seconds)  # the session thread sets it when the match or the server ends
            if bridge.ended.is_set():
                threading.Event().wait(args.linger)  # the page keeps showing the end a little longer
        except KeyboardInterrupt:
            pass
    finally:
        bridge.stop()
    summary = {"url": bridge.url, "end": bridge.end_reason or "stopped", **bridge.counts}
    print(json.dumps(summary) if args.json else f"session ended: {summary['end']}; "
          f"{summary['snapshots']} snapshots, {summary['browsers']} browser(s)")
    return 0


def add_commands(sub) -> None:
    """`pingpong join` and `watch`."""
    join = sub.add_parser("join", help="join a served match as a player or a spectator", formatter_class=FORMATTER)
    join.add_argument("address", help="the server's endpoint, e.g. tcp://127.0.0.1:5555")
    join.add_argument("--as", dest="role", choices=["player", "spectator"], default="spectator")
    join.add_argument("--bot", nargs="?", const="", default=None, metavar="PLAYER",
                      help="a player played by a program: an AI profile (pro, club, novice) or a bot of the bot "
                           "API, FILE.py:Class or module:Class, as `pingpong match --a` takes (without PLAYER: "
                           "the --skill profile); without --bot a player plays on the keyboard")
    join.add_argument("--skill", choices=["pro", "club", "novice"], default="pro",
                      help="the profile of --bot without PLAYER, and the keyboard player's arm")
    join.add_argument("--bot-budget-ms", type=float, default=BOT_BUDGET_MS,
                      help="CPU milliseconds a bot's decision may take (a bot's own budget_s wins)")
    join.add_argument("--slot", choices=["any", "a", "b"], default="any", help="the seat wanted")
    join.add_argument("--name", default="client", help="shown to the other clients")
    join.add_argument("--token", default=None, help="rejoin token (hex) from an earlier session")
    join.add_argument("--seconds", type=float, default=3600.0, help="leave after this long at most")
    join.add_argument("--delay-ms", type=float, default=100.0, help="a spectator's view runs this far behind")
    add_session_options(join)
    add_common(join)
    join.set_defaults(func=join_command)

    watch = sub.add_parser("watch", help="watch a served match in the browser, in 3D (a web bridge)",
                           formatter_class=FORMATTER)
    watch.add_argument("address", help="the server's endpoint, e.g. tcp://127.0.0.1:5555")
    watch.add_argument("--web", default="127.0.0.1:8080", metavar="HOST:PORT",
                       help="where the page is served; port 0 picks a free one")
    watch.add_argument("--seconds", type=float, default=24 * 3600.0, help="stop after this long at most")
    watch.add_argument("--linger", type=float, default=5.0, help="s the page stays up after the match ends")
    add_session_options(watch)
    watch.add_argument("--json", action="store_true", help="print JSON: the URL, then the summary")
    watch.set_defaults(func=watch_command)
