"""`pingpong serve`, `join`, `relay`, `keys` and `decode`: a match that remote players and spectators
join, a relay of its spectator feed, its CURVE keys, and a captured wire message pretty-printed."""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from processes.cli.common import FORMATTER, add_common, add_players

if TYPE_CHECKING:
    from processes.network import wire
    from processes.network.client.client import Client
    from processes.network.wire import Slot

# processes.workers.PLAYERS_TIMEOUT_S and processes.supervisor's restart budget, spelled out: the
# parser imports no run machinery (tests/processes/cli/test_cli.py checks they agree).
PLAYERS_TIMEOUT_S = 300.0
RESTART_BUDGET = 3
RESTART_WINDOW_S = 600.0


def keys_command(args: argparse.Namespace) -> int:
    """`pingpong keys DIR`: a server key pair for CURVE (server.key to give clients,
    server.key_secret to keep)."""
    import zmq.auth

    os.makedirs(args.dir, exist_ok=True)
    public_file, secret_file = zmq.auth.create_certificates(args.dir, args.name)
    os.chmod(secret_file, 0o600)
    if args.json:
        print(json.dumps({"public": public_file, "secret": secret_file}))
    else:
        print(f"public key (give it to clients): {public_file}\nsecret key (keep it): {secret_file}\n"
              f"pingpong serve --curve-secret {secret_file}   pingpong join ADDRESS --curve-server-key {public_file}")
    return 0




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


def join_command(args: argparse.Namespace) -> int:
    """`pingpong join ADDRESS --as player|spectator [--bot]`."""
    from processes.network.client.client import Client, Rejected, curve_client_options
    from processes.network.wire import NO_TOKEN
    from processes.network.wire import Slot

    keyboard = args.role == "player" and not args.bot
    if keyboard and not sys.stdin.isatty():
        print("pingpong join: keyboard play needs a terminal (stdin is not a TTY); join a player with --bot, "
              "or --as spectator", file=sys.stderr)
        return 2
    slot = {"any": Slot.NONE, "a": Slot.A, "b": Slot.B}[args.slot]
    try:
        token = bytes.fromhex(args.token) if args.token else NO_TOKEN
        socket_options = curve_client_options(getattr(args, "curve_server_key", None))
    except (ValueError, OSError) as err:
        print(f"pingpong join: {err}", file=sys.stderr)
        return 2
    if args.role == "player":
        if not args.json:
            print("loading the engine's kernels (compiled on a first run) ...", file=sys.stderr, flush=True)
        _warm_up(args.skill)  # before the hello: a cold numba cache compiles for minutes, no heartbeats meanwhile
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
        summary.update(slot=client.slot.name.lower(), scene=welcome["scene"], token=client.token.hex(),
                       snapshot_hz=welcome["snapshot_hz"])
        if not args.json and not keyboard:
            print(f"joined {welcome['scene']} as {'player ' + client.slot.name if client.slot else 'spectator'}"
                  f" (best of {welcome['best_of']}, {welcome['snapshot_hz']} snapshots/s)", flush=True)
        summary.update(_play(client, welcome, args, keyboard))
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
        if "prediction" in summary:
            prediction, stale = summary["prediction"], summary["prediction"]["without_prediction"]
            print(_error_line("prediction error at the snapshots' ticks, ball", prediction["ball"]))
            print(_error_line("prediction error at the snapshots' ticks, own bat", prediction["bat"]))
            print(_error_line("without prediction (the previous snapshot), ball", stale["ball"]))
            print(_error_line("without prediction (the previous snapshot), own bat", stale["bat"]))
    return 1 if summary["goodbye"] == "server_lost" else 0


def _warm_up(skill: str) -> None:
    """Load (or compile) every kernel a player's client runs, with the bundled match scene: the
    kernels depend on types, not on the scene, so the served scene's objects build at once later."""
    from engine.scene import load_scene
    from processes.network.client.bot import BotBrain
    from processes.network.client.prediction import Predictor
    from processes.network.wire import Slot

    Predictor(load_scene("match"), Slot.A).advance_to(0)
    BotBrain("match", Slot.A, skill)


def _play(client: Client, welcome: wire.Message, args: argparse.Namespace, keyboard: bool) -> dict:
    """The session of `pingpong join` once welcomed: bot, keyboard or spectator."""
    from engine.scene import load_scene
    from processes.network.client.bot import BotBrain
    from processes.network.client.interpolation import Interpolator
    from processes.network.client.keyboard import KeyboardPilot, TerminalKeys
    from processes.network.client.prediction import Predictor
    from processes.network.client.session import run_session
    from processes.network.wire import Slot

    if client.slot == Slot.NONE:
        view = Interpolator(welcome["dt"], args.delay_ms / 1000.0)

        def show(summary, frame):
            print(_score_line(frame["snapshot"], frame["ball_pos"], frame["ball_vel"], frame["tick"]), flush=True)

        return run_session(client, welcome, view=view, seconds=args.seconds, show=None if args.json else show)
    scene = load_scene(welcome["scene"])
    predictor = Predictor(scene, client.slot)
    if not keyboard:
        brain = BotBrain(welcome["scene"], client.slot, args.skill, args.seed)
        return run_session(client, welcome, brain=brain, predictor=predictor, seconds=args.seconds)
    from rich.console import Console
    from rich.live import Live
    from rich.text import Text

    pilot = KeyboardPilot(predictor.model, client.slot, args.skill)
    with TerminalKeys(sys.stdin.fileno()) as keys, Live(Text("joining ..."), console=Console(),
                                                        auto_refresh=False, transient=False) as live:
        def show(summary, frame):
            live.update(Text(keyboard_screen(summary, frame, client.slot, predictor)), refresh=True)

        return run_session(client, welcome, pilot=pilot, keys=keys, predictor=predictor, seconds=args.seconds,
                           show=show, show_every_s=0.05)


def serve_command(args: argparse.Namespace) -> int:
    """`pingpong serve`: a match in realtime worker processes, served through the gateway.

    SIGINT (Ctrl-C) and SIGTERM both stop it cleanly, in the foreground or not: every client is
    told goodbye shutdown, the workers and their memory go, and it prints its summary."""
    import signal
    import tempfile
    from dataclasses import replace

    from engine.scene import SceneError, load_scene, with_remote_players
    from engine.world import SimulationError
    from processes.cli.common import bot_budget_s, with_players
    from processes.network.client.client import load_curve_key
    from processes.network.server.gateway import GatewayConfig
    from processes.supervisor import Supervisor, WorkerFailed

    try:
        for end, player in (("a", args.a), ("b", args.b)):
            if player is not None and "ab".index(end) < args.players:
                raise SceneError(f"--{end}: bat {end.upper()} is played remotely with --players {args.players}; "
                                 f"give the AI seats' players only")
        scene = with_remote_players(with_players(load_scene(args.scene), args), args.players)
        if args.best_of is not None:
            if args.best_of < 1 or args.best_of % 2 == 0:
                raise SceneError(f"--best-of must be an odd number >= 1, got {args.best_of}")
            scene = replace(scene, match=replace(scene.match, best_of=args.best_of))
        ticks = scene.ticks if args.ticks is None else args.ticks
        curve = {}
        if getattr(args, "curve_secret", None):
            public, secret = load_curve_key(args.curve_secret, secret=True)
            curve = {"curve_public_key": public, "curve_secret_key": secret}
        with tempfile.TemporaryDirectory(prefix="pingpong-serve-") as tmp:
            stats_path = os.path.join(tmp, "gateway.json")  # the counters of a gateway stopped by Ctrl-C
            config = GatewayConfig(bind=args.bind, snapshot_hz=args.snapshot_hz, timeout_s=args.timeout,
                                   grace_s=args.grace, stats_path=stats_path, **curve)
            fault = _fault(args)
            supervisor = Supervisor(scene, ticks, "realtime", seed=args.seed, gateway=config,
                                    players_timeout=args.wait, restart_budget=args.restart_budget,
                                    on_bot_error=args.on_bot_error, bot_budget_s=bot_budget_s(args), **fault)

            bridges: list = []

            def ready(reports: dict) -> None:
                endpoint = reports["gateway"]["endpoint"]
                if args.json:
                    print(json.dumps({"listening": endpoint, "feed": reports["gateway"]["feed"],
                                      "run_id": supervisor.arena.run_id, "players": args.players}), flush=True)
                else:
                    print(_serving_line(scene.name, endpoint, args.players), flush=True)
                if args.web:
                    bridges.append(_web_bridge(endpoint, args))

            # A shell starts a background job with SIGINT ignored: listen to it all the same
            # (Supervisor.run turns SIGTERM into SystemExit(143)).
            signal.signal(signal.SIGINT, signal.default_int_handler)
            try:
                result = supervisor.run(on_ready=ready)
            except (KeyboardInterrupt, SystemExit) as stop:
                name = "SIGINT" if isinstance(stop, KeyboardInterrupt) else "SIGTERM"
                _interrupted(args, stats_path, name)
                return 130 if name == "SIGINT" else 143
            except WorkerFailed as exc:
                first = str(exc).splitlines()[0]
                if args.json:
                    print(json.dumps({"failed": first}), flush=True)
                print(f"pingpong serve: the match failed: {exc}\nevery client was told goodbye server_error",
                      file=sys.stderr)
                return 1
            finally:
                for bridge in bridges:
                    _stop_process(bridge)
    except (SceneError, SimulationError, ValueError) as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    summary = result.match_summary(args.seed)
    summary["gateway"] = result.workers.get("gateway", {}).get("gateway", {})
    if args.json:
        print(json.dumps(summary))
    else:
        games = ", ".join(f"{a}-{b}" for a, b in summary["games"]) or "-"
        winner = summary["winner"]
        print(f"{'winner: ' + winner.upper() if winner else 'no winner'}  games: {games}  ticks {summary['ticks']}")
        print("gateway: " + ", ".join(f"{k} {v}" for k, v in summary["gateway"].items()))
    return 0


def _fault(args: argparse.Namespace) -> dict:
    """The Supervisor's fault injection from --fault WORKER:KIND:TICK (or --crash-gateway-at-tick)."""
    if args.fault is None:
        tick = getattr(args, "crash_gateway_at_tick", None)
        return {"crash_at_tick": tick, "crash_worker": "gateway"}
    try:
        worker, kind, tick = args.fault.split(":")
        return {"crash_worker": worker, "crash_kind": kind, "crash_at_tick": int(tick)}
    except ValueError:
        raise ValueError(f"--fault must be WORKER:KIND:TICK (e.g. physics:raise:500), got {args.fault!r}") from None


def _web_bridge(endpoint: str, args: argparse.Namespace):
    """`pingpong watch ENDPOINT --web HOST:PORT` as a process of its own beside the served match:
    a gateway client like any other. Its stderr is ours; its first line (the URL) is printed."""
    import subprocess
    import threading

    command = [sys.executable, "-m", "processes.cli", "watch", endpoint, "--web", args.web, "--json",
               "--join-timeout", "60"]  # the gateway answers once the run is under way, on a busy machine later
    if getattr(args, "curve_secret", None):
        command += ["--curve-server-key", _public_key_file(args.curve_secret)]
    bridge = subprocess.Popen(command, stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)

    def announce() -> None:  # not in on_ready: the gateway answers the bridge only once it runs
        line = bridge.stdout.readline()  # bounded by the bridge's own join timeout
        try:
            url = json.loads(line)["url"]
        except (ValueError, KeyError, TypeError):
            return
        print(json.dumps({"web": url}) if args.json else f"watch in a browser: {url}", flush=True)

    threading.Thread(target=announce, name="web-bridge-url", daemon=True).start()
    return bridge


def _public_key_file(secret_file: str) -> str:
    """The public key file beside a `pingpong keys` secret one (NAME.key_secret -> NAME.key)."""
    return secret_file[:-len("_secret")] if secret_file.endswith(".key_secret") else secret_file


def _stop_process(process) -> None:
    """End a child we started (SIGINT, so it says goodbye; then SIGKILL), bounded."""
    import signal
    import subprocess

    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(10)
    if process.stdout is not None:
        process.stdout.close()


def _serving_line(scene_name: str, endpoint: str, players: int) -> str:
    """What `pingpong serve` prints once it listens: who plays, and how to join."""
    if players == 0:
        return (f"serving {scene_name} on {endpoint}: the AI plays both bats; "
                f"watch with `pingpong join {endpoint} --as spectator`")
    return (f"serving {scene_name} on {endpoint}: {players} remote player(s), {2 - players} AI; "
            f"join with `pingpong join {endpoint} --as player --bot` (or --as spectator); the match "
            f"starts once every remote seat is taken")


def _interrupted(args: argparse.Namespace, stats_path: str, signal_name: str) -> None:
    """SIGINT or SIGTERM on `pingpong serve`: the gateway's last counters (written as it stopped)."""
    try:
        with open(stats_path) as f:
            stats = json.load(f)
    except (OSError, ValueError):
        stats = {}
    if args.json:
        print(json.dumps({"interrupted": True, "signal": signal_name, "gateway": stats}), flush=True)
    elif stats:
        print("gateway: " + ", ".join(f"{k} {v}" for k, v in stats.items()))
    print(f"pingpong serve: stopped by {signal_name}; every client was told goodbye", file=sys.stderr)


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


def relay_command(args: argparse.Namespace) -> int:
    """`pingpong relay UPSTREAM --bind ENDPOINT`: re-publish a gateway's feed (processes.network.server.relay)."""
    import threading

    import zmq

    from processes.network.client.client import curve_client_options
    from processes.network.server.relay import Relay

    try:
        socket_options = curve_client_options(getattr(args, "curve_server_key", None))
    except (ValueError, OSError) as err:
        print(f"pingpong relay: {err}", file=sys.stderr)
        return 2
    relay = Relay(args.upstream, args.bind, socket_options=socket_options)
    try:
        try:
            endpoint = relay.start()
        except zmq.ZMQError as err:
            print(f"pingpong relay: {err}", file=sys.stderr)
            return 2
        if args.json:
            print(json.dumps({"relaying": args.upstream, "listening": endpoint}), flush=True)
        else:
            print(f"relaying the feed {args.upstream} on {endpoint}; subscribers connect a SUB socket there",
                  flush=True)
        try:
            threading.Event().wait(args.seconds)  # the proxy runs in its thread; Ctrl-C ends the wait
        except KeyboardInterrupt:
            pass
    finally:
        relay.stop()
    return 0


def _read_capture(source: str) -> bytes:
    try:
        is_file = Path(source).is_file()
    except OSError:  # a long hex string is too long for a file name
        is_file = False
    if is_file:
        return Path(source).read_bytes()
    text = "".join(source.split()).replace(":", "")
    if text[:2].lower() == "0x":
        text = text[2:]
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise ValueError(f"{source!r} is neither a file nor a hex string") from None


def _human(message: wire.Message) -> str:
    from processes.network import wire

    lines = [f"{message.kind.name.lower()}  seq {message.seq}  tick {message.tick}  flags 0x{message.flags:02x}  "
             f"({wire.SIZES[message.kind]} bytes, protocol {wire.PROTOCOL_VERSION})"]
    for name, value in message.to_dict().items():
        if name in ("kind", "seq", "tick", "flags"):
            continue
        if isinstance(value, float) or (isinstance(value, list) and value and isinstance(value[0], float)):
            value = json.dumps(value)
        elif isinstance(value, str) and name in wire.SPECS[message.kind].text:
            value = json.dumps(value, ensure_ascii=False)
        lines.append(f"  {name:<12} {value}")
    return "\n".join(lines)


def decode_command(args: argparse.Namespace) -> int:
    """`pingpong decode FILE|HEX`: pretty-print one captured message; exit 2 if it is bad."""
    from processes.network import wire

    try:
        data = _read_capture(args.message)
    except (ValueError, OSError) as err:
        print(f"pingpong decode: {err}", file=sys.stderr)
        return 2
    try:
        message = wire.decode(data)
    except wire.WireError as err:
        if args.json:
            print(json.dumps({"ok": False, "reason": err.reason, "detail": str(err), "bytes": len(data)}))
        print(f"pingpong decode: bad message: {err.reason}: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"ok": True, **message.to_dict()}, ensure_ascii=False))
    else:
        print(_human(message))
    return 0


def add_commands(sub) -> None:
    """`pingpong serve`, `join`, `relay`, `keys` and `decode`."""
    serve = sub.add_parser("serve", help="serve a realtime match that remote players and spectators join",
                           formatter_class=FORMATTER)
    serve.add_argument("--scene", default="match", help="scene TOML file or bundled scene name (needs a referee)")
    add_players(serve)
    serve.add_argument("--bind", default="tcp://127.0.0.1:0", help="ZeroMQ endpoint; port 0 picks a free port")
    serve.add_argument("--players", type=int, choices=[0, 1, 2], default=1,
                       help="remote players (bat A first); the other bats are played by the AI")
    serve.add_argument("--best-of", type=int, default=None, help="games in the match (default: the scene's)")
    serve.add_argument("--ticks", type=int, default=None, help="stop after this many ticks even if undecided")
    serve.add_argument("--snapshot-hz", type=int, default=100, help="snapshots per second to every client")
    serve.add_argument("--timeout", type=float, default=5.0, help="s, a silent client is dropped after this")
    serve.add_argument("--grace", type=float, default=30.0, help="s, a dropped player's seat waits for its token")
    serve.add_argument("--wait", type=float, default=PLAYERS_TIMEOUT_S, help="s, wait this long for every remote player before the first serve, then start anyway "
                            "(and play on when a seat empties)")
    serve.add_argument("--crash-gateway-at-tick", type=int, default=None, help=argparse.SUPPRESS)
    # fault injection for tests and `pingpong stress`: WORKER:KIND:TICK, e.g. physics:raise:500
    serve.add_argument("--fault", default=None, help=argparse.SUPPRESS)
    serve.add_argument("--restart-budget", type=int, default=RESTART_BUDGET,
                       help=f"restarts of one worker allowed within {RESTART_WINDOW_S:.0f} s; one more failure ends "
                            "the match (clients are told goodbye server_error)")
    serve.add_argument("--web", default=None, metavar="HOST:PORT",
                       help="also show the match in the browser: a web bridge (`pingpong watch`) serves it there")
    serve.add_argument("--curve-secret", default=None, metavar="FILE",
                       help="CURVE-encrypt every session with this server secret key file (`pingpong keys DIR`)")
    add_common(serve)
    serve.set_defaults(func=serve_command)

    join = sub.add_parser("join", help="join a served match as a player or a spectator", formatter_class=FORMATTER)
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
    add_common(join)
    join.set_defaults(func=join_command)

    watch = sub.add_parser("watch", help="watch a served match in the browser, in 3D (a web bridge)",
                           formatter_class=FORMATTER)
    watch.add_argument("address", help="the server's endpoint, e.g. tcp://127.0.0.1:5555")
    watch.add_argument("--web", default="127.0.0.1:8080", metavar="HOST:PORT",
                       help="where the page is served; port 0 picks a free one")
    watch.add_argument("--seconds", type=float, default=24 * 3600.0, help="stop after this long at most")
    watch.add_argument("--linger", type=float, default=5.0, help="s the page stays up after the match ends")
    watch.add_argument("--join-timeout", type=float, default=10.0, help="s to wait for the welcome")
    watch.add_argument("--curve-server-key", default=None, metavar="FILE",
                       help="the server's public key file: connect CURVE-encrypted (`pingpong keys DIR`)")
    watch.add_argument("--json", action="store_true", help="print JSON: the URL, then the summary")
    watch.set_defaults(func=watch_command)

    relay = sub.add_parser("relay", help="re-publish a served match's spectator feed (a ZeroMQ XSUB/XPUB proxy)",
                           formatter_class=FORMATTER)
    relay.add_argument("upstream", help="the gateway's feed endpoint (the 'feed' of `pingpong serve --json`)")
    relay.add_argument("--bind", default="tcp://127.0.0.1:0", help="where subscribers connect; port 0 picks one")
    relay.add_argument("--seconds", type=float, default=24 * 3600.0, help="stop after this long at most")
    relay.add_argument("--curve-server-key", default=None, metavar="FILE",
                       help="the upstream server's public key file, if its feed is CURVE-encrypted")
    relay.add_argument("--json", action="store_true", help="print one JSON object when listening")
    relay.set_defaults(func=relay_command)

    keys = sub.add_parser("keys", help="make a CURVE key pair for `serve --curve-secret` / `join --curve-server-key`",
                          formatter_class=FORMATTER)
    keys.add_argument("dir", help="directory to write NAME.key (public) and NAME.key_secret into")
    keys.add_argument("--name", default="server", help="file name stem")
    keys.add_argument("--json", action="store_true", help="print one JSON object")
    keys.set_defaults(func=keys_command)

    decode = sub.add_parser("decode", help="pretty-print one captured wire message (exit 2 if it is bad)",
                            formatter_class=FORMATTER)
    decode.add_argument("message", metavar="FILE|HEX", help="a file of the message's raw bytes, or its bytes in hex")
    decode.add_argument("--json", action="store_true", help="print one JSON object")
    decode.set_defaults(func=decode_command)
