"""`pingpong run` and, until the referee and AI exist, `pingpong match`: in-process runs of a scene."""
from __future__ import annotations

import argparse
import json
import sys

from engine.run import run
from engine.scene import SceneError, load_scene, with_overrides
from engine.world import SimulationError


def _load(args: argparse.Namespace):
    scene = load_scene(args.scene)
    changes = {}
    if getattr(args, "dt", None) is not None:
        changes["dt"] = args.dt
    if getattr(args, "integrator", None) is not None:
        changes["integrator"] = args.integrator
    return with_overrides(scene, **changes) if changes else scene


def _print_human(summary: dict) -> None:
    print(f"scene {summary['scene']}: {summary['ticks']} ticks of {summary['dt'] * 1e3:g} ms "
          f"({summary['sim_seconds']:.3f} s simulated in {summary['wall_seconds']:.3f} s wall, "
          f"integrator {summary['integrator']})")
    for ev in summary["events"]:
        x, y, z = ev["pos"]
        print(f"  t={ev['time']:8.4f} s  {ev['body']:<6} at ({x:+.3f}, {y:+.3f}, {z:+.3f}) m, "
              f"approach {ev['normal_speed']:.3f} m/s")
    if summary["bounce_heights_m"]:
        heights = ", ".join(f"{h * 100:.1f}" for h in summary["bounce_heights_m"][:8])
        print(f"  bounce apex heights (cm): {heights}{' ...' if len(summary['bounce_heights_m']) > 8 else ''}")
    ball = summary["final_ball"]
    print(f"  ball at the end: pos {[round(c, 4) for c in ball['pos']]} m, vel {[round(c, 3) for c in ball['vel']]} m/s")


def run_scene_command(args: argparse.Namespace) -> int:
    """Run a scene in-process and print the summary."""
    try:
        scene = _load(args)
        if args.ticks is not None and args.ticks < 0:
            raise SceneError(f"--ticks must be >= 0, got {args.ticks}")
        result = run(scene, args.ticks)
    except (SceneError, SimulationError) as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    summary = result.summary()
    if args.json:
        print(json.dumps(summary))
    else:
        _print_human(summary)
    return 0


def match_command(args: argparse.Namespace) -> int:
    """Run the match scene. Without the referee and bat AI (issue 6) this is the scene's rally."""
    args.dt = None
    args.integrator = None
    return run_scene_command(args)
