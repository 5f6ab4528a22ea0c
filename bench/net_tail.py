"""What the net's cheaper paths cost in accuracy and save in time: seeded strikes, the full float64 kernel against each.

Each strike throws a ball into the default match's net (scenes/match.toml: 85 x 8 knots, the
hanging net) at 5-60 m/s, into the middle, near a post, at the top cord and at the hem, and lets
the net ring until it sleeps; some strikes send a second ball 3 s later, while the struck net is
in its tail, towards the top of the net (over it or into it). Every strike runs with the full
float64 kernel on every awake tick (NetSpec.tail_energy = 0, the reference) and with each cheaper
path (paths()): the linear tail at each energy asked for; the float32 grid kernels
(NetSpec.kernel_precision, with and without kernel_fma) with the tail at the match's energy
(NetSpec.tail_energy), and float32 with FMA without the tail (its rounding alone); and two
yardsticks of the model's own sensitivity to float32's epsilon, the float64 kernel without the
tail with every knot's offset from the built grid scaled by 1 + NUDGE once before the strike (the
state rounded once), and with the mesh's, top cord's and hem's tensions scaled by 1 + NUDGE (the
net's constants rounded: another net for the whole ring, as float32's rounded spring constants
make one). It reports: the knots' largest distance from the reference's over the whole ring of the
strike (sampled every SAMPLE_TICKS ticks, up to a second ball), the second ball's outcome (over
the net or not, its speed after the net, where it comes down to the playing surface's height), the
tick each net falls asleep, the ticks it spent awake and in its tail, and the CPU time per strike
(a run of its own without reading the knots, which would rebuild the tail's state). The budget:
50 um for the knots (a tenth of a knot's radius, net_kernel.sim.KNOT_RADIUS), 1 % for the rebound
speed and 1 mm for the landing point of the second ball. The knots after a second ball are
reported, not budgeted: a struck net amplifies any difference of its state about ten-million-fold
within 0.3 s (float64 against itself with every knot moved by 1 nm differs by millimetres after a
20 m/s ball, tests/net_kernel/test_grid32.py), so what a second ball can be held to is its
outcome. A path that steps the whole strike differently (float32) meets the same amplification
from the first tick: its knot error is shown against each yardstick's on the same strike (the
worst ratio over the strikes it misses the budget on), which says whether it is rounding or a
defect.

    pingpong bench net-tail [--quick] [--json]
    python -m bench.net_tail [--quick] [--energies 20e-6,30e-6,40e-6,50e-6] [--no-float32] [--json]
                             [--readme docs/accuracy.md]
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from bench.study import Study
from bench.study import run as run_study
from engine.physics.scene import load_scene
from net_kernel import NetSim, NetSpec, build_topology
from net_kernel.sim import BALL_MASS, BALL_RADIUS
from net_kernel.topology import FLOAT32, FLOAT64

DT = 1e-3  # s: the match's tick (scenes/match.toml)
GRAVITY = 9.81
SAMPLE_TICKS = 10
MAX_TICKS = 12_000  # 12 s: every net here sleeps well before
SECOND_BALL_TICK = 3000  # 3 s after the strike: every strike's net is in its tail by then
SPEEDS = (5.0, 10.0, 20.0, 30.0, 40.0, 60.0)
MORE_SPEEDS = (15.0, 50.0)  # drawn after SPEEDS' strikes, which keep their seeded aim
# (y, z) m aimed at: the middle of the mesh, near a post, the top cord, the hem
POINTS = {"middle": (0.0, 0.08), "post": (0.8, 0.08), "top cord": (0.1, 0.148), "hem": (-0.2, 0.012)}
ENERGIES = (20e-6, 30e-6, 40e-6, 50e-6)
BUDGET_M = 50e-6
BUDGET_SPEED = 0.01
BUDGET_LANDING_M = 1e-3
# The high-precision reference: the float64 kernel without the tail at this many times the stability
# bound's substeps (and its contact substeps at least). The scheme is of first order in the substep
# (semi-implicit Euler, and the contact split from the springs: net_kernel.sim.CONTACT_TRAVEL), so
# the float64 reference's own distance from it shows what the scheme itself is worth.
HIGH_SUBSTEPS = 4
# A cheaper path is as accurate as float64 when its knot errors against the high-precision reference
# exceed float64's own (or a yardstick's) by at most this share: a chosen bound, a tenth of what the
# scheme itself already misses by, so what a path adds stays small beside what the substep costs.
ACCURACY_SLACK = 0.1
NUDGE = 1e-7  # relative: float32's epsilon (1.19e-7), rounded
TENSIONS = ("mesh_tension", "cord_tension", "hem_tension")  # NetSpec's prestress, scaled by the tension yardstick


def strikes(quick: bool = False, seed: int = 0) -> list[dict]:
    """The seeded strikes: every speed of SPEEDS then of MORE_SPEEDS at every point, aimed within
    5 mm of it, at up to 10 degrees off the table's axis; a second ball for the 10 and 30 m/s
    strikes (20 cm before the net, 0.13-0.17 m high, 8-14 m/s)."""
    rng = np.random.default_rng(seed)
    out = []
    for speeds in (SPEEDS, MORE_SPEEDS):
        for where, (y, z) in POINTS.items():
            for speed in speeds:
                angle = math.radians(rng.uniform(-10.0, 10.0))
                shot = {"point": where, "speed": speed, "pos": [-0.06, y + rng.uniform(-5e-3, 5e-3),
                                                                z + rng.uniform(-5e-3, 5e-3)],
                        "vel": [speed * math.cos(angle), speed * math.sin(angle), 0.0]}
                if speed in (10.0, 30.0):
                    second_speed = rng.uniform(8.0, 14.0)
                    shot["second"] = {"pos": [-0.2, rng.uniform(-0.5, 0.5), rng.uniform(0.13, 0.17)],
                                      "vel": [second_speed, 0.0, 0.5]}
                out.append(shot)
    if quick:
        out = [s for s in out if s["point"] == "middle" and s["speed"] in (10.0, 30.0)]
    return out


def _landing(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """(x, y) m where a ball at pos with vel comes down to the height of its radius above the table (ballistic)."""
    a, b, c = -0.5 * GRAVITY, vel[2], pos[2] - BALL_RADIUS
    t = (-b - math.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a)
    return pos[:2] + vel[:2] * t


def paths(energies, tail_energy: float, float32: bool = True) -> list[dict]:
    """The cheaper paths, each a NetSpec's kernel options and tail energy, and the relative nudges
    of the knots' offsets (nudge) and of the tensions (tension_nudge): the float64 tail at each of
    `energies`; with `float32`, the float32 kernels with the tail at `tail_energy` (without and
    with FMA), float32 with FMA without the tail, and the two yardsticks, float64 without the
    tail, its knots or its tensions nudged by NUDGE."""
    plain = {"nudge": 0.0, "tension_nudge": 0.0}
    out = [{"path": f"float64, tail {e * 1e6:g} uJ", "kernel_precision": FLOAT64, "kernel_fma": False,
            "tail_energy_J": e, **plain} for e in energies]
    if float32:
        out += [{"path": f"float32, tail {tail_energy * 1e6:g} uJ", "kernel_precision": FLOAT32, "kernel_fma": False,
                 "tail_energy_J": tail_energy, **plain},
                {"path": f"float32 + FMA, tail {tail_energy * 1e6:g} uJ", "kernel_precision": FLOAT32,
                 "kernel_fma": True, "tail_energy_J": tail_energy, **plain},
                {"path": "float32 + FMA, no tail", "kernel_precision": FLOAT32, "kernel_fma": True,
                 "tail_energy_J": 0.0, **plain},
                {"path": f"float64, knots nudged {NUDGE:g}, no tail", "kernel_precision": FLOAT64, "kernel_fma": False,
                 "tail_energy_J": 0.0, "nudge": NUDGE, "tension_nudge": 0.0},
                {"path": f"float64, tensions nudged {NUDGE:g}, no tail", "kernel_precision": FLOAT64,
                 "kernel_fma": False, "tail_energy_J": 0.0, "nudge": 0.0, "tension_nudge": NUDGE}]
    return out


def _path_spec(cloth: NetSpec, path: dict) -> NetSpec:
    """The net of `path`: the match's cloth with its kernel options, tail energy and tensions."""
    tensions = {name: getattr(cloth, name) * (1.0 + path["tension_nudge"]) for name in TENSIONS}
    return dataclasses.replace(cloth, tail_energy=path["tail_energy_J"], kernel_precision=path["kernel_precision"],
                               kernel_fma=path["kernel_fma"], **tensions)


def run_strike(topo, shot: dict, trace: bool, nudge: float = 0.0, substeps_factor: int = 1) -> dict:
    """One strike on a net built from `topo`: its sleep tick, ticks awake and in the tail, CPU
    seconds, the second ball's outcome, and with `trace` the sampled knot positions; `nudge`
    scales every free knot's offset from the built grid by 1 + nudge before the strike;
    substeps_factor multiplies the stability bound's substeps."""
    sim = NetSim(topo, DT)
    if substeps_factor != 1:
        sim = NetSim(topo, DT, substeps=sim.substeps * substeps_factor)
    if nudge:
        free = topo.knot_inv_mass > 0
        sim.knot_pos[free] = topo.knot_pos[free] + (sim.knot_pos[free] - topo.knot_pos[free]) * (1.0 + nudge)
        sim.wake()
    balls = [[np.array(shot["pos"], float), np.array(shot["vel"], float), 0]]
    second = shot.get("second")
    samples, sample_ticks = [], []
    outcome = None
    asleep = None
    started = time.process_time()
    for t in range(MAX_TICKS):
        if second is not None and t == SECOND_BALL_TICK:
            balls.append([np.array(second["pos"], float), np.array(second["vel"], float), 0])
        ball = balls[-1] if len(balls) == 2 or t < 400 else None
        if ball is None:
            sim.step_free(1)
        else:
            pos, vel = ball[0], ball[1]
            contact = sim.step(pos, vel)
            pos += vel * DT + contact.offset
            vel += contact.impulse / BALL_MASS
            vel[2] -= GRAVITY * DT
            ball[2] += 1
            if len(balls) == 2 and (pos[0] > 0.25 or pos[0] < -0.25 or pos[2] < BALL_RADIUS):  # past the net, back, or down
                outcome = {"over": bool(pos[0] > 0.0), "speed": float(np.linalg.norm(vel)),
                           "landing": _landing(pos, vel).tolist()}
                balls.pop()
                second = None
        if trace and (t % SAMPLE_TICKS == 0 or len(balls) == 2):
            samples.append(sim.knot_pos.copy())
            sample_ticks.append(t)
        if sim.sleeping and asleep is None and (second is None or t > SECOND_BALL_TICK):
            asleep = t + 1
            if not trace:
                break
        if asleep is not None and trace and t >= asleep + SAMPLE_TICKS and len(balls) < 2:
            break
    return {"sleep_tick": asleep, "awake_ticks": sim.awake_ticks, "tail_ticks": sim.tail_ticks,
            "cpu_s": time.process_time() - started, "second": outcome,
            "samples": np.array(samples) if trace else None, "sample_ticks": sample_ticks}


def _error(ref: dict, run: dict, start: int = 0, end: int = MAX_TICKS) -> float:
    """m: the largest knot distance between two traced runs at the ticks in [start, end) both
    sampled (a net that slept holds its frozen shape: compared as it stands)."""
    ticks = {t: i for i, t in enumerate(run["sample_ticks"])}
    worst = 0.0
    last = None
    for i, t in enumerate(ref["sample_ticks"]):
        if not start <= t < end:
            continue
        j = ticks.get(t)
        if j is None:
            j = last
        if j is None:
            continue
        last = j
        worst = max(worst, float(np.linalg.norm(ref["samples"][i] - run["samples"][j], axis=1).max()))
    return worst


def study(quick: bool = False, energies=ENERGIES, progress=None, float32: bool = True) -> dict:
    """The table: one row per strike and path (paths()), with the reference's sleep tick and CPU."""
    cloth = load_scene("match").cloth
    reference_topo = build_topology(dataclasses.replace(cloth, tail_energy=0.0, kernel_precision=FLOAT64,
                                                        kernel_fma=False))
    chosen = paths(energies, cloth.tail_energy, float32)
    topos = [build_topology(_path_spec(cloth, path)) for path in chosen]
    for topo in topos:  # modes computed or loaded, kernels compiled or loaded, before any timing
        sim = NetSim(topo, DT)
        if sim.tail_refusal is None:
            sim.modes()
        run_strike(topo, strikes(True)[0], False)
    run_strike(reference_topo, strikes(True)[0], False)
    rows = []
    for index, shot in enumerate(strikes(quick)):
        if progress:
            progress(f"{shot['speed']:g} m/s at the {shot['point']}")
        ref_timed = run_strike(reference_topo, shot, False)
        ref = run_strike(reference_topo, shot, True)
        high = run_strike(reference_topo, shot, True, substeps_factor=HIGH_SUBSTEPS)
        end = SECOND_BALL_TICK if "second" in shot else MAX_TICKS
        against_high = {"reference_high_knot_error_m": _error(high, ref, 0, end)}
        if high["second"] is not None:
            against_high["reference_high_second"] = _outcome_error(high["second"], ref["second"])
        for path, topo in zip(chosen, topos):
            timed = run_strike(topo, shot, False, path["nudge"])
            traced = run_strike(topo, shot, True, path["nudge"])
            row = {**path, "strike": index, "point": shot["point"], "speed_m_s": shot["speed"],
                   "knot_error_m": _error(ref, traced, 0, end), "high_knot_error_m": _error(high, traced, 0, end),
                   **against_high,
                   "sleep_tick": timed["sleep_tick"],
                   "reference_sleep_tick": ref_timed["sleep_tick"], "awake_ticks": timed["awake_ticks"],
                   "tail_ticks": timed["tail_ticks"], "reference_awake_ticks": ref_timed["awake_ticks"],
                   "cpu_s": timed["cpu_s"], "reference_cpu_s": ref_timed["cpu_s"]}
            if ref["second"] is not None:
                row["second_ball"] = {"knot_error_m": _error(ref, traced, SECOND_BALL_TICK), "over": ref["second"]["over"],
                                      **_outcome_error(ref["second"], traced["second"])}
            if high["second"] is not None:
                row["high_second"] = _outcome_error(high["second"], traced["second"])
            rows.append(row)
    return {"net": f"{cloth.cols} x {cloth.rows}", "dt_s": DT, "sample_ticks": SAMPLE_TICKS, "nudge": NUDGE,
            "rows": rows, "summary": summarise(rows, chosen), "reference_against_high": reference_against_high(rows)}


def _outcome_error(a: dict, b: dict | None) -> dict:
    """How far second ball b's outcome lies from a's: the same side of the net, the relative speed
    difference, the landing points' distance (m); b None (it never left the net) misses them all."""
    return {"same_side": b is not None and a["over"] == b["over"],
            "speed_error": abs(b["speed"] - a["speed"]) / a["speed"] if b else math.inf,
            "landing_error_m": float(np.hypot(*np.subtract(b["landing"], a["landing"]))) if b else math.inf}


def _against_high(rows: list[dict], prefix: str) -> dict:
    """Worst and median knot error and worst second-ball errors of `rows` against the
    high-precision reference (prefix "": the path's own; "reference_": the float64 reference's)."""
    knots = [r[f"{prefix}high_knot_error_m"] for r in rows]
    balls = [r[f"{prefix}high_second"] for r in rows if f"{prefix}high_second" in r]
    return {"worst_knot_error_m": max(knots), "median_knot_error_m": float(np.median(knots)),
            "second_same_side": all(b["same_side"] for b in balls),
            "worst_speed_error": max((b["speed_error"] for b in balls), default=0.0),
            "worst_landing_error_m": max((b["landing_error_m"] for b in balls), default=0.0)}


def _as_accurate(mine: dict, bounds: list[dict]) -> bool:
    """Is a path's knot error against the high-precision reference (an _against_high dict) within
    ACCURACY_SLACK of the float64 reference's own or a yardstick's (`bounds`), its second balls
    within the outcome budget of theirs, keeping the side wherever theirs do?"""
    slack = 1.0 + ACCURACY_SLACK
    return bool(mine["worst_knot_error_m"] <= slack * max(b["worst_knot_error_m"] for b in bounds)
                and mine["median_knot_error_m"] <= slack * max(b["median_knot_error_m"] for b in bounds)
                and (mine["second_same_side"] or not all(b["second_same_side"] for b in bounds))
                and mine["worst_speed_error"] <= max(b["worst_speed_error"] for b in bounds) + BUDGET_SPEED
                and mine["worst_landing_error_m"] <= max(b["worst_landing_error_m"] for b in bounds)
                + BUDGET_LANDING_M)


def _yardstick(path: dict) -> bool:
    """Is `path` a yardstick (float64 nudged by NUDGE), not a cheaper path?"""
    return path["nudge"] > 0 or path["tension_nudge"] > 0


def _over(mine: list[dict], yardstick: list[dict]) -> float | None:
    """The largest ratio of a path's knot error to a yardstick's on the same strike, over the
    strikes the path misses the budget on (None: it misses none)."""
    by_strike = {r["strike"]: r["knot_error_m"] for r in yardstick}
    ratios = [r["knot_error_m"] / max(by_strike[r["strike"]], 1e-12) for r in mine
              if r["knot_error_m"] > BUDGET_M and r["strike"] in by_strike]
    return max(ratios, default=None)


def summarise(rows: list[dict], chosen: list[dict]) -> list[dict]:
    """Per path: the worst knot error (and its strike), against each yardstick's, the second
    balls' worst errors, the share of awake ticks and of CPU against the reference, the sleep
    tick's shift, whether it keeps every budget."""
    out = []
    yardsticks = [p["path"] for p in chosen if _yardstick(p)]
    bounds = [reference_against_high(rows)] + [_against_high([r for r in rows if r["path"] == y], "")
                                               for y in yardsticks]
    for path in chosen:
        mine = [r for r in rows if r["path"] == path["path"]]
        balls = [r["second_ball"] for r in mine if "second_ball" in r]
        worst_row = max(mine, key=lambda r: r["knot_error_m"])
        worst = worst_row["knot_error_m"]
        speed = max((b["speed_error"] for b in balls), default=0.0)
        landing = max((b["landing_error_m"] for b in balls), default=0.0)
        same = all(b["same_side"] for b in balls)
        after = max((b["knot_error_m"] for b in balls), default=0.0)
        later = [r["sleep_tick"] - r["reference_sleep_tick"] for r in mine]
        high = _against_high(mine, "")
        out.append({**path, "strikes": len(mine), "worst_knot_error_m": worst,
                    "worst_knot_error_strike": f"{worst_row['speed_m_s']:g} m/s at the {worst_row['point']}",
                    "worst_over_yardsticks": {y: _over(mine, [r for r in rows if r["path"] == y])
                                              for y in yardsticks if not _yardstick(path)},
                    "second_balls": len(balls), "second_same_side": same, "worst_speed_error": speed,
                    "worst_landing_error_m": landing, "worst_knot_error_after_second_m": after,
                    "awake_share": sum(r["awake_ticks"] for r in mine) / sum(r["reference_awake_ticks"] for r in mine),
                    "cpu_share": sum(r["cpu_s"] for r in mine) / sum(r["reference_cpu_s"] for r in mine),
                    "sleep_later_ticks_median": float(np.median(later)),
                    "sleep_later_ticks_range": [min(later), max(later)],
                    "within_budget": bool(worst <= BUDGET_M and same and speed <= BUDGET_SPEED
                                          and landing <= BUDGET_LANDING_M),
                    "against_high": high, "as_accurate": _as_accurate(high, bounds)})
    return out


def reference_against_high(rows: list[dict]) -> dict:
    """The float64 reference's own errors against the high-precision reference (_against_high; every
    path's rows carry them, the first path's are taken)."""
    return _against_high([r for r in rows if r["path"] == rows[0]["path"]], "reference_")


def markdown(result: dict) -> str:
    """The summary as a Markdown table."""
    lines = ["| path | strikes | worst knot error over the ring | over budget: x the knots' / tensions' nudge "
             "| second balls: same side, speed, landing | knots after a second ball | awake ticks | CPU "
             "| sleeps later: median (range) | within budget |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for s in result["summary"]:
        ratio = " / ".join("-" if r is None else f"{r:.2g}" for r in s["worst_over_yardsticks"].values()) or "-"
        low, high = (t * DT for t in s["sleep_later_ticks_range"])
        lines.append(f"| {s['path']} | {s['strikes']} | {s['worst_knot_error_m'] * 1e6:.1f} um "
                     f"({s['worst_knot_error_strike']}) | {ratio} | "
                     f"{s['second_balls']}: {'yes' if s['second_same_side'] else 'NO'}, "
                     f"{s['worst_speed_error'] * 100:.3f} %, {s['worst_landing_error_m'] * 1e3:.3f} mm | "
                     f"{s['worst_knot_error_after_second_m'] * 1e3:.1f} mm | "
                     f"{s['awake_share'] * 100:.0f} % | {s['cpu_share'] * 100:.0f} % | "
                     f"{s['sleep_later_ticks_median'] * DT:.2f} s ({low:.2f} to {high:.2f}) | "
                     f"{'yes' if s['within_budget'] else 'no'} |")
    lines += ["", f"Against the high-precision reference (float64 at {HIGH_SUBSTEPS}x the substeps, no tail):", "",
              "| path | worst (median) knot error over the ring | second balls: same side, worst speed, worst landing "
              "| as accurate as float64 |", "|---|---|---|---|"]
    rows = [("float64, full kernel (the reference)", result["reference_against_high"], None)]
    rows += [(s["path"], s["against_high"], s["as_accurate"]) for s in result["summary"]]
    for name, high, verdict in rows:
        lines.append(f"| {name} | {high['worst_knot_error_m'] * 1e3:.2f} mm ({high['median_knot_error_m'] * 1e3:.2f} mm) "
                     f"| {'yes' if high['second_same_side'] else 'NO'}, {high['worst_speed_error'] * 100:.2f} %, "
                     f"{high['worst_landing_error_m'] * 1e3:.1f} mm | {'-' if verdict is None else 'yes' if verdict else 'no'} |")
    return "\n".join(lines)


def text(result: dict) -> str:
    """The summary for a terminal or the README."""
    return (f"Measured by `pingpong bench net-tail`: {len(result['rows']) // max(len(result['summary']), 1)} seeded "
            f"strikes on the {result['net']} net of scenes/match.toml (5-60 m/s into the middle, near a post, the top "
            f"cord and the hem; second balls 3 s later towards the top of the net), the full float64 kernel against "
            f"each path: the linear tail at each energy, the float32 kernels (NetSpec.kernel_precision, with and "
            f"without kernel_fma) with the tail and without it, and two yardsticks of the model's own sensitivity to "
            f"float32's epsilon, float64 with every knot's offset from the built grid, or with the mesh's, cord's and "
            f"hem's tensions, scaled by 1 + {result['nudge']:g}; knots compared "
            f"every {result['sample_ticks']} ms over each strike's ring. Budget: 50 um for the knots, 1 % for a "
            f"second ball's speed after the net, 1 mm for where it comes down; the knots after a second ball are "
            f"shown, not budgeted (a struck net amplifies any difference of its state some ten-million-fold within "
            f"0.3 s, bench/net_tail.py), and a strike's knot error over budget is shown against each "
            f"yardstick's on the same strike (the worst ratio); CPU is the net's alone, each path's against the full "
            f"float64 kernel's in the same run. Then every path, and the float64 reference itself, against a "
            f"high-precision reference, the float64 kernel at {HIGH_SUBSTEPS}x the substeps without the tail: a path is "
            f"as accurate as float64 when its worst and median knot errors against it exceed the float64 "
            f"reference's or a yardstick's by at most {ACCURACY_SLACK:.0%}, and its "
            f"second balls keep their side and come within the outcome budget of theirs.\n\n"
            + markdown(result))


def _arguments(parser) -> None:
    parser.add_argument("--energies", default=",".join(f"{e:g}" for e in ENERGIES),
                        help="tail energies (J) of the float64 paths, comma-separated")
    parser.add_argument("--no-float32", action="store_true",
                        help="only the float64 tail paths (no float32 kernels, no yardsticks)")


def _run(args, progress=None) -> dict:
    """The study at --energies; ValueError names a malformed one."""
    try:
        energies = tuple(float(e) for e in args.energies.split(","))
    except ValueError:
        raise ValueError(f"--energies {args.energies!r}: give numbers in J, e.g. 5e-6,20e-6") from None
    if not energies or any(not (math.isfinite(e) and e > 0) for e in energies):
        raise ValueError(f"--energies {args.energies!r}: every energy must be a finite number of J > 0")
    return study(args.quick, energies, progress=progress, float32=not args.no_float32)


STUDY = Study(run=_run, report=lambda result: print(text(result)), add_arguments=_arguments,
              block=("net-tail", lambda result, _document: text(result)), quick="two strikes (smoke runs)")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.net_tail", "net-tail"))
