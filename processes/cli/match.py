"""`pingpong match` and `pingpong replay`: a whole match in worker processes, scoreboard, replay file."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from processes.cli.common import FORMATTER, add_common, add_players, bot_budget_s, with_players

FRAME_EVERY = 10  # replay frames every 10 ms at 1 kHz


def _scene(args):
    from dataclasses import replace

    from engine.physics.scene import SceneError, load_scene

    scene = load_scene(args.scene)
    if scene.match is None:
        raise SceneError(f"{scene.source}: scene {scene.name!r} has no referee; `pingpong match` needs a scene "
                         "with the effect 'referee' (the bundled one is `match`)")
    if args.best_of is not None:
        if args.best_of < 1 or args.best_of % 2 == 0:
            raise SceneError(f"--best-of must be an odd number >= 1, got {args.best_of}")
        scene = replace(scene, match=replace(scene.match, best_of=args.best_of))
    return with_players(scene, args)


class _Scoreboard:
    """Live score in the terminal (rich), refreshed from the physics snapshot."""

    def __init__(self, scene):
        from rich.live import Live

        self.scene = scene
        self.live = Live(self._render(None), refresh_per_second=4, transient=False)

    def _render(self, record):
        from rich.table import Table

        table = Table(title=f"pingpong: {self.scene.name}, best of {self.scene.match.best_of}")
        for column in ("player", "games", "points", "serving"):
            table.add_column(column)
        if record is None:
            table.caption = "starting workers..."
            return table
        rally = record["rally"]
        for player in (0, 1):
            table.add_row("AB"[player], str(int(rally["games_won"][player])), str(int(rally["score"][player])),
                          "*" if int(rally["server"]) == player else "")
        table.caption = f"t = {float(record['world']['time']):.1f} s, rally {int(rally['rally']) + 1}"
        return table

    def update(self, record):
        self.live.update(self._render(record))


def _print_summary(summary: dict) -> None:
    winner = summary["winner"]
    games = ", ".join(f"{a}-{b}" for a, b in summary["games"])
    unfinished = "" if winner else f"   current game: {summary['score_in_game'][0]}-{summary['score_in_game'][1]}"
    print(f"{'winner: ' + winner.upper() if winner else 'no winner yet'}   games: {games or '-'}{unfinished}")
    print(f"points {summary['points']} (lets {summary['lets']}), won A {summary['points_won'][0]} / "
          f"B {summary['points_won'][1]}; rally shots mean {summary['mean_rally_shots']:.1f}, "
          f"max {summary['max_rally_shots']}; serves returned {summary['serves_returned']:.0%}")
    reasons = ", ".join(f"{k} {v}" for k, v in summary["point_reasons"].items())
    print(f"points ended by: {reasons or '-'}")
    factor = summary["realtime_factor"]
    print(f"simulated {summary['sim_seconds']:.1f} s in {summary['wall_seconds']:.2f} s wall"
          f" ({factor:.1f}x realtime)" if factor else "")
    # each fault once: the one that stopped the match is said by "match stopped"
    for error in (summary.get("bot_errors") or [])[:-1 if summary.get("stopped") else None]:
        print(f"bot error: {error['bot']} (player {error['player'].upper()}) at tick {error['tick']}: "
              f"{error['fault']}: {error['detail']}")
    if summary.get("stopped"):
        print(f"match stopped: {summary['stopped']}")
    for kind, info in (summary.get("workers") or {}).items():
        print(f"  worker {kind}: busy {info['busy_s']:.2f} s, restarts {info['restarts']}, late ticks {info['late_ticks']}")


def match_command(args: argparse.Namespace) -> int:
    import numpy as np

    from engine.physics.scene import SceneError
    from engine.physics.world import SimulationError
    from engine.play.match import Match, point_row
    from engine.tools import replay as replay_file

    try:
        scene = _scene(args)
        ticks = scene.ticks if args.ticks is None else args.ticks
        if ticks < 0:
            raise SceneError(f"--ticks must be >= 0, got {args.ticks}")
        frame_every = FRAME_EVERY if args.replay else 0
        if args.in_process:
            match = Match(scene, seed=args.seed, on_bot_error=args.on_bot_error, budget_s=bot_budget_s(args))
            frames = []
            from engine.physics.dtypes import physics_snapshot_dtype

            record = np.zeros(1, physics_snapshot_dtype(len(scene.bats)))
            events = []

            def keep(m, tick):
                if frame_every and tick % frame_every == 0:
                    m.save(record)
                    frames.append(record[0].copy())

            # A per-tick callback makes play() advance one tick a call, not in chunks: only for frames.
            # A bot no interrupt reaches ends the command with one line (status 3), not a hang.
            from processes.runtime.watchdog import DecisionWatchdog

            with DecisionWatchdog(lambda reason: print(f"pingpong: {reason}", file=sys.stderr, flush=True)):
                result = match.play(max_ticks=ticks, on_tick=keep if frame_every else None, events_out=events)
            summary = result.summary()
            summary.update(mode="in-process", processes=False)
            points = np.array([point_row(p, 0) for p in match.referee.points]) if match.referee.points else None
            frame_array = np.array(frames) if frames else np.zeros(0, record.dtype)
            event_array = np.array(events) if events else None
        else:
            from processes.supervisor import Supervisor

            board = _Scoreboard(scene) if not args.json and sys.stdout.isatty() else None
            supervisor = Supervisor(scene, ticks, args.mode, seed=args.seed, frame_every=frame_every,
                                    on_bot_error=args.on_bot_error, bot_budget_s=bot_budget_s(args),
                                    speculate=args.speculate)
            if board is not None:
                with board.live:
                    result = supervisor.run(progress=board.update)
            else:
                result = supervisor.run()
            summary = result.match_summary(args.seed)
            points, frame_array, event_array = result.points, result.frames, result.events
    except (SceneError, SimulationError, ValueError) as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    if args.replay:
        from engine.physics.dtypes import CONTACT_DTYPE, POINT_DTYPE
        from engine.physics.scene import scene_toml

        replay_file.write(args.replay, scene_name=scene.name, scene_text=scene_toml(scene), seed=args.seed,
                          dt=scene.dt, frame_every=frame_every, frames=frame_array,
                          events=event_array if event_array is not None else np.zeros(0, CONTACT_DTYPE),
                          points=points if points is not None else np.zeros(0, POINT_DTYPE), summary=summary)
        summary["replay"] = str(args.replay)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_summary(summary)
        if args.replay:
            print(f"replay written to {args.replay}")
    return 1 if summary.get("stopped") else 0  # --on-bot-error stop: a match a bot's fault ended


def _best_of(header: dict) -> int:
    """The recorded match's best_of, from the scene text the replay carries (engine.physics.scene.scene_toml:
    the scene as played, --a/--b and --set included)."""
    from engine.physics.scene import SceneError, scene_from_toml

    try:
        scene = scene_from_toml(header.get("scene_toml", ""), header["scene"])
    except (SceneError, KeyError):
        return 5
    return scene.match.best_of if scene.match is not None else 5


def replay_command(args: argparse.Namespace) -> int:
    from engine.physics.geometry import Body
    from engine.play.rules import REASONS
    from engine.tools import replay as replay_file

    try:
        data = replay_file.read(args.file)
    except replay_file.ReplayError as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    h = data.header
    points = data.points
    decided = points[points["winner"] >= 0] if len(points) else points
    reasons: dict[str, int] = {}
    for row in decided:
        name = REASONS[int(row["reason"])].value
        reasons[name] = reasons.get(name, 0) + 1
    contacts: dict[str, int] = {}
    for ev in data.events:
        name = Body(int(ev["body"])).name.lower()
        contacts[name] = contacts.get(name, 0) + 1
    last = data.frames[-1] if len(data.frames) else None
    summary = {
        "file": str(args.file),
        "version": h["version"],
        "scene": h["scene"],
        "seed": h["seed"],
        "frames": int(len(data.frames)),
        "frame_every_ticks": h["frame_every"],
        "sim_seconds": float(last["world"]["time"]) if last is not None else 0.0,
        "points": int(len(decided)),
        "lets": int(len(points) - len(decided)),
        "points_won": [int((decided["winner"] == k).sum()) for k in (0, 1)] if len(decided) else [0, 0],
        "point_reasons": dict(sorted(reasons.items(), key=lambda kv: -kv[1])),
        "mean_rally_shots": float(decided["shots"].mean()) if len(decided) else 0.0,
        "contacts": contacts,
        "winner": h["summary"].get("winner"),
        "games": h["summary"].get("games"),
    }
    title = f"{h['scene']}, seed {h['seed']}: winner {summary['winner'] or '-'}, games {summary['games']}"
    if args.png or args.gif:
        from engine.tools import render

        if args.png:
            render.png(data.frames, data.events, args.png, title)
            summary["png"] = args.png
        if args.gif:
            render.gif(data.frames, args.gif, title)
            summary["gif"] = args.gif
    if args.html:
        from processes.network.web.replay import replay_messages, replay_page

        messages = replay_messages(data, _best_of(h))
        Path(args.html).write_text(replay_page(messages, title), encoding="utf-8")
        summary["html"] = args.html
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{summary['file']}: scene {summary['scene']}, seed {summary['seed']}, "
              f"{summary['sim_seconds']:.1f} s in {summary['frames']} frames")
        print(f"winner {summary['winner'] or '-'}, games {summary['games']}, points {summary['points']} "
              f"(A {summary['points_won'][0]}, B {summary['points_won'][1]}), lets {summary['lets']}, "
              f"mean rally {summary['mean_rally_shots']:.1f} shots")
        print("points ended by: " + ", ".join(f"{k} {v}" for k, v in summary["point_reasons"].items()))
        print("contacts: " + ", ".join(f"{k} {v}" for k, v in summary["contacts"].items()))
        for kind in ("png", "gif", "html"):
            if kind in summary:
                print(f"{kind} written to {summary[kind]}")
    return 0


def add_commands(sub) -> None:
    """`pingpong match` and `pingpong replay`."""
    match = sub.add_parser("match", help="play a match (AI or bots: --a, --b) in worker processes",
                           formatter_class=FORMATTER)
    match.add_argument("--scene", default="match", help="scene TOML file or bundled scene name")
    match.add_argument("--best-of", type=int, default=None, help="games in the match (default: the scene's)")
    match.add_argument("--mode", choices=["lockstep", "realtime"], default="lockstep",
                       help="lockstep (deterministic, flat out) or realtime (wall-clock paced)")
    match.add_argument("--ticks", type=int, default=None, help="stop after this many ticks even if undecided")
    match.add_argument("--replay", default=None, help="write a replay file here")
    match.add_argument("--in-process", action="store_true", help="run the in-process reference instead of workers")
    match.add_argument("--speculate", action=argparse.BooleanOptionalAction, default=None,
                       help="the physics steps on past the ball's runs near the cloth net before the net worker "
                            "has answered them, and goes back where the net touched the ball (a lockstep match with "
                            "a cloth net and AI profiles, no replay); default: wherever the run allows it")
    add_players(match)
    add_common(match)
    match.set_defaults(func=match_command)

    replay = sub.add_parser("replay", help="summarise a replay file", formatter_class=FORMATTER)
    replay.add_argument("file", help="a file written by `pingpong match --replay`")
    replay.add_argument("--json", action="store_true", help="print one JSON object")
    replay.add_argument("--png", default=None, help="draw side and top views of the last rally to this PNG")
    replay.add_argument("--gif", default=None, help="animate the last seconds to this GIF")
    replay.add_argument("--html", default=None,
                        help="write one self-contained HTML page that plays the match in 3D, offline")
    replay.set_defaults(func=replay_command)
