"""`pingpong bench match`: a whole match in worker processes (lockstep) against the in-process
reference, same scene and seed, so the same match, timed back to back in every round: realtime
factors and their ratio, time per worker, the share of the wall time in which two workers
worked at once, the net's awake and tail shares; `--timeline PNG` draws the workers' timeline."""
from __future__ import annotations

import argparse
import statistics
import tempfile
from dataclasses import replace

from bench.study import Study
from bench.study import run as run_study
from engine.physics.scene import SceneError, load_scene
from engine.play.match import Match
from processes.runtime import timeline as timelines
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


def _in_worker_processes(scene, ticks: int, seed: int, speculate: bool | None = None) -> dict:
    """One headless lockstep match in worker processes (speculate: Supervisor's): its summary,
    startup, workers' reports, whether it speculated, the shares of its wall time in which none,
    one and two or more workers worked (processes.runtime.timeline.busy_share) and the workers'
    timelines."""
    with tempfile.TemporaryDirectory(prefix="pingpong-timeline-") as directory:
        supervisor = Supervisor(scene, ticks, "lockstep", seed=seed, timeline_dir=directory, speculate=speculate)
        result = supervisor.run()
        speculate = supervisor.options.speculate
        marks = timelines.load(directory)
    multi = result.match_summary(seed)
    start = float(marks["physics"]["t"][0])
    end = max(float(m["t"][-1]) for m in marks.values())
    beside = timelines.shares_beside(marks, "net", start, end) if "net" in marks else None
    return {"summary": multi, "startup_seconds": result.startup_seconds, "workers": result.workers, "speculate": speculate,
            "working": timelines.busy_share(marks, start, end), "beside_net": beside, "timeline": marks}


def _in_process(scene, ticks: int, seed: int) -> dict:
    """The same match in this process (the reference): its summary and the cloth net's counts."""
    match = Match(scene, seed=seed)
    summary = match.play(max_ticks=ticks).summary()
    net = match.state.net_sim
    return {"summary": summary, "net": None if net is None else (net.awake_ticks, net.tail_ticks)}


def _median_index(values: list[float]) -> int:
    """The index of the median value (the lower middle one of an even count)."""
    return sorted(range(len(values)), key=values.__getitem__)[(len(values) - 1) // 2]


def _bench_scene(scene, args: argparse.Namespace, rounds: list[dict], references: list[dict]) -> dict:
    """One scene's `pingpong bench match` report: its matches in worker processes (lockstep) and
    in-process (same seed, so the same match), one of each a round, back to back. Each side's
    figures are those of its round with the median realtime factor; every round's factors and
    ratio (worker processes / in-process) are listed, and the median of the ratios."""
    factors = [r["summary"]["realtime_factor"] for r in rounds]
    in_factors = [r["summary"]["realtime_factor"] for r in references]
    median = rounds[_median_index(factors)]
    multi = median["summary"]
    one = references[_median_index(in_factors)]
    reference = one["summary"]
    ratios = [f / g for f, g in zip(factors, in_factors)]
    return {
        "scene": scene.name,
        "net": scene.net_kind,
        "best_of": scene.match.best_of,
        "seed": args.seed,
        "same_match": all(r["summary"]["games"] == reference["games"] and r["summary"]["points"] == reference["points"]
                          and r["summary"]["ticks"] == reference["ticks"] for r in [*rounds, *references]),
        "sim_seconds": multi["sim_seconds"],
        "processes": {"wall_seconds": multi["wall_seconds"], "realtime_factor": multi["realtime_factor"],
                      "realtime_factors": factors,
                      "startup_seconds": median["startup_seconds"], "workers": median["workers"],
                      "working": median["working"], "speculate": median["speculate"],
                      **({"beside_net": median["beside_net"]} if median["beside_net"] else {}),
                      "us_per_tick": 1e6 * multi["wall_seconds"] / max(multi["ticks"], 1)},
        "over_in_process": {"median": statistics.median(ratios), "rounds": ratios},
        "in_process": {"wall_seconds": reference["wall_seconds"], "realtime_factor": reference["realtime_factor"],
                       "realtime_factors": in_factors, "ai_seconds": reference["ai_seconds"],
                       "us_per_tick": 1e6 * reference["wall_seconds"] / max(reference["ticks"], 1),
                       **({"net_awake_ticks": one["net"][0],
                           "net_awake_share": one["net"][0] / max(reference["ticks"], 1),
                           "net_tail_ticks": one["net"][1],
                           "net_tail_share": one["net"][1] / max(reference["ticks"], 1),
                           "net_asleep_share": max(reference["ticks"] - one["net"][0] - one["net"][1], 0)
                           / max(reference["ticks"], 1)} if one["net"] is not None else {})},
        "target": "worker processes / in-process >= 1.5 for the cloth match, >= 1.2 for the rigid one; the cloth "
                  "match in worker processes >= 0.70 of the rigid one's realtime factor in the same run",
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
                             "a round's scenes together); each round times every scene in worker processes and in-process, "
                             "back to back")
    parser.add_argument("--timeline", metavar="PNG", default=None,
                        help="draw the first scene's median round as a timeline: per worker, when it works, waits (for "
                             "whom) and idles, over --timeline-seconds of wall time where the physics waited most")
    parser.add_argument("--timeline-seconds", type=float, default=1.5, help="the timeline's span of wall time, s")
    parser.add_argument("--speculate", action=argparse.BooleanOptionalAction, default=None,
                        help="the worker processes of the scenes with a cloth net speculate: the physics steps on past "
                             "its runs near the net before the net has answered them and goes back where the net "
                             "touched the ball; default: wherever the run allows it")


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
    if args.timeline_seconds <= 0:
        raise ValueError(f"--timeline-seconds {args.timeline_seconds} must be > 0")
    scenes = [_scene_of(name, args) for name in names]
    rounds: list[list[dict]] = [[] for _ in scenes]
    references: list[list[dict]] = [[] for _ in scenes]
    for r in range(args.repeat):
        for k, (scene, ticks) in enumerate(scenes):
            if progress is not None:
                progress(f"{scene.name}: in worker processes, then in-process (round {r + 1} of {args.repeat})")
            # --speculate asks it of the scenes with a cloth net; the others run as they must
            speculate = None if args.speculate and scene.cloth is None else args.speculate
            rounds[k].append(_in_worker_processes(scene, ticks, args.seed, speculate))
            references[k].append(_in_process(scene, ticks, args.seed))
    reports = [_bench_scene(scene, args, scene_rounds, scene_references)
               for (scene, _), scene_rounds, scene_references in zip(scenes, rounds, references)]
    if args.timeline is not None:
        first = rounds[0]
        median = first[_median_index([r["summary"]["realtime_factor"] for r in first])]
        reports[0]["timeline"] = draw_timeline(median["timeline"], args.timeline, args.timeline_seconds,
                                               f"{scenes[0][0].name}, seed {args.seed}")
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
    mode = "lockstep, speculating" if p.get("speculate") else "lockstep"
    print(f"  worker processes ({mode}): {p['wall_seconds']:.2f} s wall, {p['realtime_factor']:.1f}x realtime{beside}, "
          f"{p['us_per_tick']:.1f} us/tick, startup {p['startup_seconds']:.2f} s{median}")
    for kind, info in p["workers"].items():
        awake = info.get("awake_ticks")
        awake_text = f", {awake} ticks awake ({1e6 * info['busy_s'] / awake:.0f} us each)" if awake else ""
        if "tail_ticks" in info:
            awake_text += f", {info['tail_ticks']} in its linear tail"
        if info.get("net_runs"):
            awake_text += f", {info['net_ball_ticks']} ticks near the net in {info['net_runs']} hand-offs"
        if "net_rollbacks" in info:
            awake_text += f", speculating: {info['net_rollbacks']} go-backs, {info['net_ticks_again']} ticks stepped again"
        split = [f"{who} {info[key]:.2f} s" for who, key in (("net", "handoff_net_s"), ("AI", "handoff_ai_s")) if key in info]
        split_text = f" ({', '.join(split)})" if len(split) == 2 else ""
        cpu = f" (CPU {info['cpu_s']:.2f} s)" if "cpu_s" in info else ""
        if "switches" in info:
            cpu += f", switches {info['switches'][0]} slept, {info['switches'][1]} preempted"
        print(f"    {kind:<8} own work {info['busy_s']:.2f} s{cpu}, hand-offs {info['handoff_s']:.2f} s{split_text}{awake_text}")
    working = p["working"]
    print(f"    two or more workers at work {working['two']:.0%} of the wall time, one {working['one']:.0%}, "
          f"none {working['none']:.0%}")
    beside = p.get("beside_net")
    if beside:
        others = ", ".join(f"{who.replace('ai', 'AI').replace('+', ' and ')} {share:.0%}" for who, share in
                           sorted(beside.items(), key=lambda item: -item[1]) if who != "net")
        print(f"    the net at work {beside.get('net', 0.0):.0%} of the wall time; while it was not: {others}")
    share = f", net awake {r['net_awake_share']:.0%} of ticks" if "net_awake_share" in r else ""
    in_rounds = r["realtime_factors"]
    in_median = f", the median of {len(in_rounds)} rounds ({', '.join(f'{x:.1f}' for x in in_rounds)})" \
        if len(in_rounds) > 1 else ""
    print(f"  in-process reference:        {r['wall_seconds']:.2f} s wall, {r['realtime_factor']:.1f}x realtime, "
          f"{r['us_per_tick']:.1f} us/tick (AI {r['ai_seconds']:.2f} s){share}{in_median}")
    over = report["over_in_process"]
    rounds_text = f" (rounds {', '.join(f'{x:.2f}' for x in over['rounds'])})" if len(over["rounds"]) > 1 else ""
    print(f"  worker processes / in-process: {over['median']:.2f}x{rounds_text}")
    if "timeline" in report:
        t = report["timeline"]
        print(f"  timeline: {t['path']} ({t['seconds']:.2f} s of wall time from {t['from_s']:.2f} s)")


def draw_timeline(marks: dict, path: str, seconds: float, title: str) -> dict:
    """Draw the workers' timelines over `seconds` of wall time where the physics waited most (a
    window starting at one of its waits) into the PNG `path`; returns what it drew."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start = float(marks["physics"]["t"][0])
    end = max(float(m["t"][-1]) for m in marks.values())
    p_starts, p_lengths, p_states = timelines.intervals(marks["physics"], end)
    waits = (p_states == timelines.WAIT_NET) | (p_states == timelines.WAIT_AI)
    best, best_wait = start, -1.0
    for s in p_starts[waits][:: max(1, int(waits.sum()) // 400)]:  # candidate windows: a few hundred waits
        lo = s - 0.05 * seconds
        inside = waits & (p_starts >= lo) & (p_starts < lo + seconds)
        total = float(p_lengths[inside].sum())
        if total > best_wait:
            best, best_wait = lo, total
    lo, hi = max(best, start), max(best, start) + seconds
    colours = {timelines.WORK: "tab:green", timelines.THINK: "tab:olive", timelines.WAIT_NET: "tab:red",
               timelines.WAIT_AI: "tab:orange"}
    rows = [kind for kind in ("physics", "net", "ai") if kind in marks]
    fig, ax = plt.subplots(figsize=(12, 1.0 + 0.7 * len(rows)))
    for y, kind in enumerate(reversed(rows)):
        starts, lengths, states = timelines.intervals(marks[kind], end)
        keep = (starts + lengths > lo) & (starts < hi)
        for state, colour in colours.items():
            chosen = keep & (states == state)
            spans = [(1e3 * (max(s, lo) - lo), 1e3 * (min(s + n, hi) - max(s, lo)))
                     for s, n in zip(starts[chosen], lengths[chosen])]
            ax.broken_barh(spans, (y - 0.35, 0.7), facecolors=colour, linewidth=0)
    ax.set_yticks(range(len(rows)), list(reversed(rows)))
    ax.set_xlim(0, 1e3 * seconds)
    ax.set_xlabel(f"ms of wall time from {lo - start:.2f} s after the physics started (white: idle)")
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in colours.values()]
    ax.legend(handles, [timelines.STATE_NAMES[s] for s in colours], loc="upper center", ncol=4,
              bbox_to_anchor=(0.5, 1.25), frameon=False)
    ax.set_title(title, loc="left", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {"path": str(path), "from_s": lo - start, "seconds": seconds,
            "working": timelines.busy_share(marks, lo, hi)}


STUDY = Study(run=_run, report=_report, add_arguments=_arguments, quick="a best-of-1 match of at most 20000 ticks")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.match", "match"))
