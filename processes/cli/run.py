"""`pingpong run` and `pingpong stability`: in-process runs of a scene and the stability suite."""
from __future__ import annotations

import argparse
import json
import sys

from processes.cli.common import FORMATTER, add_common


def _load(args: argparse.Namespace):
    from engine.physics.scene import load_scene, with_overrides

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


def _process_summary(result, reference=None) -> dict:
    from engine.physics.geometry import Body
    from processes.supervisor import first_difference

    world = result.final["world"]
    summary = {
        "scene": result.scene.name,
        "integrator": result.scene.integrator,
        "dt": result.scene.dt,
        "processes": True,
        "mode": result.mode,
        "ticks": result.ticks,
        "sim_seconds": result.ticks * result.scene.dt,
        "wall_seconds": result.wall_seconds,
        "startup_seconds": result.startup_seconds,
        "realtime_factor": result.ticks * result.scene.dt / result.wall_seconds if result.wall_seconds > 0 else None,
        "workers": result.workers,
        "events": [
            {"tick": int(ev["tick"]), "time": float(ev["time"]), "body": Body(int(ev["body"])).name.lower(),
             "pos": [float(c) for c in ev["pos"]], "normal_speed": float(ev["normal_speed"]),
             "vel_out": [float(c) for c in ev["vel_out"]], "spin_out": [float(c) for c in ev["spin_out"]]}
            for ev in result.events
        ],
        "events_total": result.events_total,
        "bounce_heights_m": [],
        "final_ball": {k: [float(c) for c in result.final["ball"][k]] for k in ("pos", "vel", "spin")},
        "compile_seconds": None,
    }
    if reference is not None:
        diff = first_difference(result.trace, reference.trace)
        summary["reference"] = {"bitwise_equal": diff is None, "first_different_tick": diff,
                                "ticks_compared": len(reference.trace)}
    del world
    return summary


def run_scene_command(args: argparse.Namespace) -> int:
    """Run a scene in-process, or in worker processes with --processes, and print the summary."""
    from engine.physics.scene import SceneError
    from engine.physics.world import SimulationError
    from engine.tools.run import run

    try:
        scene = _load(args)
        if args.ticks is not None and args.ticks < 0:
            raise SceneError(f"--ticks must be >= 0, got {args.ticks}")
        if getattr(args, "processes", False):
            from processes.supervisor import Supervisor

            ticks = scene.ticks if args.ticks is None else args.ticks
            check = args.check_reference
            supervisor = Supervisor(scene, ticks, args.mode, trace=check, crash_at_tick=args.crash_at_tick)
            result = supervisor.run()
            reference = run(scene, ticks, trace=True) if check else None
            summary = _process_summary(result, reference)
        else:
            if getattr(args, "check_reference", False):
                raise SceneError("--check-reference compares a --processes run with the in-process one; add --processes")
            summary = run(scene, args.ticks).summary()
    except (SceneError, SimulationError) as exc:
        print(f"pingpong: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(summary))
    else:
        _print_human(summary)
        if "reference" in summary:
            ref = summary["reference"]
            verdict = "bitwise equal" if ref["bitwise_equal"] else f"DIFFERENT from tick {ref['first_different_tick']}"
            print(f"  in-process reference: {verdict} over {ref['ticks_compared']} ticks")
        if "workers" in summary:
            for kind, info in summary["workers"].items():
                print(f"  worker {kind}: busy {info['busy_s']:.3f} s, restarts {info['restarts']}, "
                      f"late ticks {info['late_ticks']}")
    if "reference" in summary and not summary["reference"]["bitwise_equal"]:
        return 1
    return 0


def stability_command(args: argparse.Namespace) -> int:
    """Run the stability suite; exit 1 if any case failed other than the known failures it lists."""
    from engine.tools.stability import cases, run_case

    chosen = [c for c in cases() if (args.long or not c.long) and (args.case is None or args.case in c.name)]
    if not chosen:
        print(f"pingpong: no stability case matches {args.case!r}", file=sys.stderr)
        return 2
    failed = 0
    if not args.json:
        print(f"{'case':<64} {'integrator':<30} {'dt s':>8} {'result':<8} {'penetr. m':>9} {'energy +':>9} "
              f"{'energy Δ':>9} {'max|y|':>8}")
    for case in chosen:
        out = run_case(case)
        known = getattr(case, "known", "")
        unexpected = out.result.startswith("failed") and not known
        failed += unexpected
        if args.json:
            print(json.dumps(out.as_dict() | {"known_failure": known or None}))
            continue
        verdict = out.result.split(":")[0]
        if verdict == "failed" and known:
            verdict = "known"
        print(f"{out.case:<64} {out.integrator:<30} {out.dt:8.2e} {verdict:<8} {out.max_penetration_m:9.1e} "
              f"{out.energy_gain:9.1e} {out.energy_change:+9.1e} {out.max_abs_state:8.3g}")
        if verdict != "stable":
            print(f"    {out.result}")
        if known:
            print(f"    known failure: {known}")
    return 1 if failed else 0


def add_commands(sub) -> None:
    """`pingpong run` and `pingpong stability`."""
    run = sub.add_parser("run", help="run a scene in-process", formatter_class=FORMATTER)
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
    add_common(run)
    run.set_defaults(func=run_scene_command)

    stability = sub.add_parser("stability", help="run the stability suite's hard cases", formatter_class=FORMATTER)
    stability.add_argument("--long", action="store_true", help="also the long runs (10^6 ticks)")
    stability.add_argument("--case", default=None, help="only cases whose name contains this text")
    stability.add_argument("--json", action="store_true", help="one JSON object per case, one per line")
    stability.set_defaults(func=stability_command)
