"""`pingpong bench match`: a whole match in worker processes (lockstep) against the in-process
reference, same scene and seed, so the same match: realtime factors, time per worker, the net's
awake and tail shares."""
from __future__ import annotations

import argparse
import statistics
from dataclasses import replace

from bench.study import Study
from bench.study import run as run_study
from engine.match import Match
from engine.scene import SceneError, load_scene
from processes.supervisor import Supervisor


def _scene_of(name: str, args: argparse.Namespace):
    """The scene `name` as benchmarked (best of --best-of games, or one with --quick) and its tick bound;
    raises SceneError for a scene it cannot play."""
    scene = load_scene(name)
    if scene.match is None:
        raise SceneError(f"scene {scene.name!r} has no [match] section (and no referee); "
                         "use a match scene such as 'match', 'match_air' or 'match_rigid'")
    scene = replace(scene, match=replace(scene.match, best_of=args.best_of if not args.quick else 1))
    ticks = args.ticks if args.ticks is not None else scene.ticks if not args.quick else 20_000
    return scene, ticks


def _in_worker_processes(scene, ticks: int, seed: int) -> dict:
    """One headless lockstep match in worker processes: its summary, startup and workers' reports."""
    result = Supervisor(scene, ticks, "lockstep", seed=seed).run()
    multi = result.match_summary(seed)
    return {"summary": multi, "startup_seconds": result.startup_seconds, "workers": result.workers}


def _bench_scene(scene, ticks: int, args: argparse.Namespace, rounds: list[dict]) -> dict:
    """One scene's `pingpong bench match` report: its matches in worker processes (lockstep), one a
    round, and the match in-process (same seed, so the same match). The worker processes' figures
    are those of the round with the median realtime factor (the lower middle one of an even count);
    every round's factor is listed."""
    match = Match(scene, seed=args.seed)
    reference = match.play(max_ticks=ticks).summary()
    net = match.state.net_sim  # the cloth net's awake ticks: what it cost, to set beside the net worker's
    factors = [r["summary"]["realtime_factor"] for r in rounds]
    median = rounds[sorted(range(len(rounds)), key=factors.__getitem__)[(len(rounds) - 1) // 2]]
    multi = median["summary"]
    return {
        "scene": scene.name,
        "net": scene.net_kind,
        "best_of": scene.match.best_of,
        "seed": args.seed,
        "same_match": all(r["summary"]["games"] == reference["games"] and r["summary"]["points"] == reference["points"]
                          for r in rounds),
        "sim_seconds": multi["sim_seconds"],
        "processes": {"wall_seconds": multi["wall_seconds"], "realtime_factor": multi["realtime_factor"],
                      "realtime_factors": factors,
                      "startup_seconds": median["startup_seconds"], "workers": median["workers"],
                      "us_per_tick": 1e6 * multi["wall_seconds"] / max(multi["ticks"], 1)},
        "in_process": {"wall_seconds": reference["wall_seconds"], "realtime_factor": reference["realtime_factor"],
                       "ai_seconds": reference["ai_seconds"],
                       "us_per_tick": 1e6 * reference["wall_seconds"] / max(reference["ticks"], 1),
                       **({"net_awake_ticks": net.awake_ticks,
                           "net_awake_share": net.awake_ticks / max(reference["ticks"], 1),
                           "net_tail_ticks": net.tail_ticks,
                           "net_tail_share": net.tail_ticks / max(reference["ticks"], 1),
                           "net_asleep_share": max(reference["ticks"] - net.awake_ticks - net.tail_ticks, 0)
                           / max(reference["ticks"], 1)} if net is not None else {})},
        "target": "the cloth match in worker processes at >= 0.40 of match_rigid's realtime factor in the same run",
        # The cloth net's chosen damping (NetSpec.air_damping; scenes/match_air.toml: the air's own drag).
        "air_damping_per_s": scene.cloth.air_damping if scene.cloth is not None else None,
        "outcome": {key: multi[key] for key in ("winner", "games", "points", "points_won", "mean_rally_shots",
                                                "point_reasons")},
    }


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--best-of", type=int, default=5, help="games in the benchmarked match")
    parser.add_argument("--scene", default="match",
                        help="scene TOML files or bundled scene names, comma-separated, run back to back "
                             "(match: the cloth net, match_air: it damped by the air alone, match_rigid: the rigid net)")
    parser.add_argument("--seed", type=int, default=0, help="the match's seed")
    parser.add_argument("--ticks", type=int, default=None,
                        help="stop each match after this many ticks (default: the scene's bound; --quick: 20000)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="rounds of the scenes' worker-process matches, each round every scene in turn: each "
                             "figure is the round with the median realtime factor (the lower middle one of an even "
                             "count), each ratio the median of the rounds' ratios (a machine whose speed drifts moves "
                             "a round's scenes together)")


def _run(args: argparse.Namespace, progress=None) -> dict:
    """Headless lockstep matches, their realtime factors and time per worker, against the in-process
    reference in the same run (same seed, so the same match). Several scenes (--scene a,b,...) run
    back to back, --repeat rounds of them: the first scene's report is the top-level object, the
    others go in its "beside" list with their realtime factors as ratios to the first's (the median
    of the rounds' ratios, and each round's). ValueError (SceneError) names a bad flag."""
    names = [name.strip() for name in args.scene.split(",")]
    if not all(names):
        raise ValueError(f"--scene {args.scene!r} has an empty name; give scenes as NAME[,NAME...]")
    if args.ticks is not None and args.ticks < 1:
        raise ValueError(f"--ticks {args.ticks} must be >= 1")
    if args.repeat < 1:
        raise ValueError(f"--repeat {args.repeat} must be >= 1")
    scenes = [_scene_of(name, args) for name in names]
    rounds: list[list[dict]] = [[] for _ in scenes]
    for r in range(args.repeat):
        for k, (scene, ticks) in enumerate(scenes):
            if progress is not None:
                progress(f"{scene.name}: in worker processes (round {r + 1} of {args.repeat})")
            rounds[k].append(_in_worker_processes(scene, ticks, args.seed))
    reports = []
    for (scene, ticks), scene_rounds in zip(scenes, rounds):
        if progress is not None:
            progress(f"{scene.name}: in-process")
        reports.append(_bench_scene(scene, ticks, args, scene_rounds))
    report = reports[0]
    if len(reports) > 1:
        firsts = [r["summary"]["realtime_factor"] for r in rounds[0]]
        for other, other_rounds in zip(reports[1:], rounds[1:]):
            per_round = [o["summary"]["realtime_factor"] / f for o, f in zip(other_rounds, firsts)]
            other["realtime_factor_ratio"] = {
                "processes": statistics.median(per_round), "processes_rounds": per_round,
                "in_process": other["in_process"]["realtime_factor"] / report["in_process"]["realtime_factor"]}
        report["beside"] = reports[1:]
    return report


def _report(report: dict) -> None:
    for one in [report, *report.get("beside", [])]:
        _print_bench(one, report)


def _print_bench(report: dict, first: dict) -> None:
    p, r, o = report["processes"], report["in_process"], report["outcome"]
    air = f", air damping {report['air_damping_per_s']:g}/s" if report["air_damping_per_s"] is not None else ""
    print(f"match {report['scene']} ({report['net']} net{air}), best of {report['best_of']}, seed {report['seed']}: "
          f"{report['sim_seconds']:.1f} s simulated, "
          f"same match in both runs: {report['same_match']}")
    games = ", ".join(f"{a}-{b}" for a, b in o["games"])
    print(f"  outcome: winner {(o['winner'] or '-').upper()}, games {games or '-'}, {o['points']} points, "
          f"rally shots mean {o['mean_rally_shots']:.1f}")
    ratio = report.get("realtime_factor_ratio")
    rounds = p["realtime_factors"]
    beside = f" ({ratio['processes']:.2f}x {first['scene']}'s" if ratio else ""
    if ratio and len(rounds) > 1:
        beside += f", rounds {', '.join(f'{x:.2f}' for x in ratio['processes_rounds'])}"
    beside += ")" if ratio else ""
    median = f", the median of {len(rounds)} rounds ({', '.join(f'{x:.1f}' for x in rounds)})" if len(rounds) > 1 else ""
    print(f"  worker processes (lockstep): {p['wall_seconds']:.2f} s wall, {p['realtime_factor']:.1f}x realtime{beside}, "
          f"{p['us_per_tick']:.1f} us/tick, startup {p['startup_seconds']:.2f} s{median}")
    for kind, info in p["workers"].items():
        awake = info.get("awake_ticks")
        awake_text = f", {awake} ticks awake ({1e6 * info['busy_s'] / awake:.0f} us each)" if awake else ""
        if "tail_ticks" in info:
            awake_text += f", {info['tail_ticks']} in its linear tail"
        if info.get("net_runs"):
            awake_text += f", {info['net_ball_ticks']} ticks near the net in {info['net_runs']} hand-offs"
        split = [f"{who} {info[key]:.2f} s" for who, key in (("net", "handoff_net_s"), ("AI", "handoff_ai_s")) if key in info]
        split_text = f" ({', '.join(split)})" if len(split) == 2 else ""
        print(f"    {kind:<8} own work {info['busy_s']:.2f} s, hand-offs {info['handoff_s']:.2f} s{split_text}{awake_text}")
    share = f", net awake {r['net_awake_share']:.0%} of ticks" if "net_awake_share" in r else ""
    print(f"  in-process reference:        {r['wall_seconds']:.2f} s wall, {r['realtime_factor']:.1f}x realtime, "
          f"{r['us_per_tick']:.1f} us/tick (AI {r['ai_seconds']:.2f} s){share}")


STUDY = Study(run=_run, report=_report, add_arguments=_arguments, quick="a best-of-1 match of at most 20000 ticks")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.match", "match"))
