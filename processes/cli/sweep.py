"""`pingpong sweep SCENE --set KEY=V1,V2 ...`: a grid over scene keys, each cell a tournament.

Any key the scene's TOML may hold can be swept (`match.ai_hz=50,100,250`, `integrator=verlet,rk4`,
`net.resolution=[92,8],[184,16]`): each cell's values are set in the scene's TOML document and
validated by engine.physics.scene like the file's own keys, so a bad key or value is refused with the
validator's message before any match runs. Each cell's matches are tasks like a tournament's,
in the same DIR/matches.jsonl (keyed by the cell's scene, so a rerun resumes).
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
from pathlib import Path

from processes.cli import tournament
from processes.cli.common import FORMATTER

CELLS_FILE = "cells.jsonl"


def parse_values(text: str) -> list:
    """V1,V2,...: TOML values (numbers, booleans, arrays, quoted strings), or bare words as strings."""
    import tomllib

    try:
        values = tomllib.loads(f"v = [{text}]")["v"]
    except tomllib.TOMLDecodeError:
        values = []
        for piece in text.split(","):
            try:
                values.append(tomllib.loads(f"v = {piece}")["v"])
            except tomllib.TOMLDecodeError:
                values.append(piece.strip())
    if not values or any(v == "" for v in values):
        raise ValueError(f"--set: values must be V1,V2,... with none empty; got {text!r}")
    return values


def parse_sets(sets: list[str]) -> dict[str, list]:
    """--set KEY=V1,V2 options as {KEY: [V1, V2]}, in the order given."""
    grid: dict[str, list] = {}
    for item in sets:
        key, equals, values = item.partition("=")
        key = key.strip()
        if not equals or not key or any(not part for part in key.split(".")):
            raise ValueError(f"--set: must be KEY=V1,V2 with a dotted scene key (match.ai_hz=50,100); got {item!r}")
        if key in grid:
            raise ValueError(f"--set: {key} is given twice")
        grid[key] = parse_values(values)
    if not grid:
        raise ValueError("--set: give at least one KEY=V1,V2")
    return grid


def cells_of(grid: dict[str, list]) -> list[dict]:
    """Every combination of the grid's values, the last key varying fastest."""
    return [dict(zip(grid, values)) for values in itertools.product(*grid.values())]


def cell_summary(cell: dict, records: list[dict], profiles: list[str]) -> dict:
    """A cell's standings, with its overrides and its mean rally length over all its points."""
    from processes.cli import standings

    table = standings.standings(records, profiles)
    points = sum(sum(r["points"]) for r in records)
    shots = sum(r["mean_rally_shots"] * sum(r["points"]) for r in records)
    return {"cell": cell, "matches": len(records), "mean_rally_shots": shots / points if points else None, **table}


def _write_cells(path: Path, cells: list[dict]) -> None:
    """The whole file written aside, then renamed over the old one: never half a table."""
    partial = path.with_suffix(".jsonl.partial")
    partial.write_text("".join(json.dumps(cell) + "\n" for cell in cells))
    os.replace(partial, path)


def _print_cells(cells: list[dict], multi: bool) -> None:
    from rich.console import Console
    from rich.table import Table

    grid = Table(title="sweep")
    columns = ["cell", "matches", "end A wins [95 %]", "mean rally shots", "realtime factor", "points lost by"]
    if multi:
        columns.insert(3, "Elo [95 %]")
    for column in columns:
        grid.add_column(column)
    for cell in cells:
        a = cell["end_a"]
        wins = "-" if a["rate"] is None else f"{a['rate']:.2f} [{a['low']:.2f}, {a['high']:.2f}]"
        lost: dict[str, int] = {}
        for row in cell["profiles"].values():
            for reason, n in row["lost_by"].items():
                lost[reason] = lost.get(reason, 0) + n
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(lost.items(), key=lambda kv: -kv[1])[:3])
        rally, factor = cell["mean_rally_shots"], cell["realtime_factor"]
        row = [", ".join(f"{k}={v}" for k, v in cell["cell"].items()), str(cell["matches"]), wins,
               "-" if rally is None else f"{rally:.2f}", "-" if factor is None else f"{factor:.0f}x", reasons or "-"]
        if multi:
            row.insert(3, "; ".join(f"{p} {r['elo']:.0f} [{r['low']:.0f}, {r['high']:.0f}]"
                                    for p, r in cell["ratings"].items() if r is not None) or "-")
        grid.add_row(*row)
    Console().print(grid)


def sweep_command(args: argparse.Namespace) -> int:
    """Validate every cell's scene, run all cells' matches as one run, summarise each cell.

    Returns:
        0; 2 for a bad --set, option or scene (before any match runs); 130 after Ctrl-C, 1
        after a failed task.
    """
    from engine.physics.scene import SceneError, load_scene
    from processes.cli import standings

    try:
        tournament.check_run_options(args)
        cells = cells_of(parse_sets(args.set))
        scenes = [load_scene(args.scene, overrides=cell) for cell in cells]
        if args.skills is None:
            skills_of = [tuple(bat.skill for bat in scene.bats) for scene in scenes]
            if any(len(pair) != 2 or None in pair for pair in skills_of):
                raise ValueError(f"{args.scene}: its bats have no AI skills to play each other; give --skills")
            pairs = [[pair] for pair in skills_of]
        else:
            skills = tournament.parse_skills(args.skills)
            pairs = [tournament.pairs_of(skills)] * len(cells)
        plans = [tournament.plan(scene, cell_pairs, args.seeds, args.best_of, args.ticks, cell, args.on_bot_error,
                                 args.bot_budget_ms / 1000.0)
                 for scene, cell_pairs, cell in zip(scenes, pairs, cells)]
    except (SceneError, ValueError) as exc:
        print(f"pingpong sweep: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    tasks = [task for cell_tasks in plans for task in cell_tasks]
    report = tournament.run_tasks(tasks, out, args.cluster, args.workers,
                                  show_progress=not args.json and sys.stderr.isatty())
    finished = {tournament.record_key(r): r for r in report.records}
    summaries = []
    for cell, cell_tasks, cell_pairs in zip(cells, plans, pairs):
        records = [finished[task.key] for task in cell_tasks if task.key in finished]
        profiles = list(dict.fromkeys(p for pair in cell_pairs for p in pair))
        summaries.append(cell_summary(cell, records, profiles))
    _write_cells(out / CELLS_FILE, summaries)
    standings.sweep_png(summaries, out / "sweep.png", f"{scenes[0].name}: sweep over {', '.join(cells[0])}, "
                                                      f"{args.seeds} seeds a pairing")
    run = tournament.run_summary(report, args.cluster, args.workers)
    if args.json:
        for summary in summaries:
            print(json.dumps(summary))
        print(json.dumps({"run": run, "cells": str(out / CELLS_FILE), "png": str(out / "sweep.png")}))
    else:
        _print_cells(summaries, multi=any(len(p) > 1 for p in pairs))
        pace = run["matches_per_minute"]
        print(f"{report.played} matches played, {report.skipped} found in {out / tournament.MATCHES_FILE}"
              + (f"; {pace:.1f} matches/min on {args.cluster}" if pace else ""))
        print(f"cells written to {out / CELLS_FILE}, plot to {out / 'sweep.png'}")
    return tournament.stopped("sweep", report, out)


def add_commands(sub) -> None:
    """`pingpong sweep`."""
    parser = sub.add_parser("sweep", help="a grid over scene keys, each cell's matches on a local pool or Ray",
                            formatter_class=FORMATTER)
    parser.add_argument("scene", help="scene TOML file or bundled scene name (needs a referee)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2",
                        help="a scene key and its values (repeat for a grid): match.ai_hz=50,100,250")
    parser.add_argument("--skills", default=None,
                        help="comma-separated players to pit in every cell, AI profiles and bots (FILE.py:Class) "
                             "(default: the scene's bats' skills)")
    tournament.add_run_options(parser, out="sweep")
    parser.set_defaults(func=sweep_command)
