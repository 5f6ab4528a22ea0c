"""`pingpong serve`, `relay` and `keys`: a match that remote players and spectators join, a relay of
its spectator feed, and the CURVE key pair that encrypts its sessions."""
from __future__ import annotations

import argparse
import json
import os
import sys

from processes.cli.common import FORMATTER, add_common, add_players

# processes.workers.PLAYERS_TIMEOUT_S and processes.supervisor's restart budget, spelled out: the
# parser imports no run machinery (tests/processes/cli/test_cli.py checks they agree).
PLAYERS_TIMEOUT_S = 300.0
RESTART_BUDGET = 3
RESTART_WINDOW_S = 600.0



def serve_command(args: argparse.Namespace) -> int:
    """`pingpong serve`: a match in realtime worker processes, served through the gateway.

    SIGINT (Ctrl-C) and SIGTERM both stop it cleanly, in the foreground or not: every client is
    told goodbye shutdown, the workers and their memory go, and it prints its summary."""
    import signal
    import tempfile
    from dataclasses import replace

    from engine.physics.scene import SceneError, load_scene, with_remote_players
    from engine.physics.world import SimulationError
    from processes.cli.common import bot_budget_s, with_players
    from processes.network.client.client import load_curve_key
    from processes.network.server.config import GatewayConfig
    from processes.runtime.stops import ignore_stop_signals
    from processes.supervisor import Supervisor, WorkerFailed, WorkerRefused

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
                                   grace_s=args.grace, stats_path=stats_path, coalesce_inputs=args.coalesce_inputs,
                                   max_sessions_per_address=args.max_sessions_per_address,
                                   hellos_per_s_per_address=args.hellos_per_s_per_address,
                                   **curve)
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
            # (Supervisor.run turns SIGTERM into SystemExit(143), SIGINT into KeyboardInterrupt).
            signal.signal(signal.SIGINT, signal.default_int_handler)
            try:
                result = supervisor.run(on_ready=ready)
            except (KeyboardInterrupt, SystemExit) as stop:
                ignore_stop_signals()  # stopping: a second Ctrl-C or kill must not lose the counters
                name = "SIGINT" if isinstance(stop, KeyboardInterrupt) else "SIGTERM"
                _interrupted(args, stats_path, name)
                return 130 if name == "SIGINT" else 143
            except WorkerRefused:
                raise  # the run's input refused before it started: one line, status 2, below
            except WorkerFailed as exc:
                first = str(exc).splitlines()[0]
                if args.json:
                    print(json.dumps({"failed": first}), flush=True)
                print(f"pingpong serve: the match failed: {exc}\nevery client was told goodbye server_error",
                      file=sys.stderr)
                return 1
            finally:
                ignore_stop_signals()
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


def add_commands(sub) -> None:
    """`pingpong serve`, `relay` and `keys`."""
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
    serve.add_argument("--max-sessions-per-address", type=int, default=0, metavar="N",
                       help="sessions one IP address may hold at once (0: no limit; clients behind one NAT share one)")
    serve.add_argument("--hellos-per-s-per-address", type=float, default=0.0, metavar="R",
                       help="hellos a second one IP address may send (0: no limit)")
    serve.add_argument("--no-coalesce-inputs", dest="coalesce_inputs", action="store_false",
                       help="decode and post every input of a player (default: of a player's inputs that arrive "
                            "together only the newest, so a flooding player cannot slow the feed)")
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
