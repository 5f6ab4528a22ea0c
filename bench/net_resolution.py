"""`pingpong bench net-resolution`: what the cloth net's resolution costs in accuracy, and what it saves in time.

Every net here is the same physical net (net_kernel.topology.resolution_spec: areal density,
prestress, sheet stiffness, cord tension and stiffness, air damping kept) on a grid of cols x rows
knots. A fixed, seeded set of match-like impacts (5-30 m/s; centre into the cord's top 2 cm, mid-net
or low; up to 45 deg off the net's normal; anywhere across the table's width) is fired into each
net, stepped as the engine couples ball and net (engine.physics.world._advance_with_cloth,
processes.workers.net): per 1 ms tick the ball flies straight under gravity, NetSim.step sees it
at the tick's start and the ball then takes the net's offset and impulse. No table, drag or spin:
the same for every net, so the comparison sees only the net.

Per net against the finest one: the outcome (over the cord, through the mesh, under the bottom
cord, back, caught), the ball's velocity and position 150 ms after the shot (exit velocity, direction, where it is), the
first contact's duration and the net's largest bulge; the CPU time (the stepping thread's) per
impact, per awake tick of the ringing net and per ring-down until the net sleeps; whether the ball
can pass between knots (cell diagonal against 2 (ball radius + knot radius), and shots at 20-60 m/s
into the middle of a cell). Beside them, the model's own sensitivity: the finest net's answers to
the same shots moved by 1 mm. recommend() names the coarsest net within the stated tolerances.

Run: `pingpong bench net-resolution [--json] [--quick]` or `.venv/bin/python bench/net_resolution.py`.
"""
from __future__ import annotations

import math
import os
import statistics
import time
from dataclasses import dataclass

import numpy as np

from bench.study import Study
from bench.study import run as run_study
from net_kernel import NO_CONTACT, NetSim, NetSpec, build_topology
from net_kernel.sim import BALL_MASS, BALL_RADIUS, KNOT_RADIUS
from net_kernel.topology import net_continuum, resolution_spec

DT = 1e-3  # s, the engine's tick (scenes/match.toml)
SIZES = [(46, 4), (70, 7), (85, 8), (92, 8), (128, 11), (184, 16), (368, 32)]  # the last is the reference; 85 x 8 has square cells
QUICK_SIZES = [(46, 4), (70, 7), (92, 8)]
IMPACTS = 24  # 8 per height band
QUICK_IMPACTS = 3
SEED = 0
FLIGHT_S = 0.150  # s after the shot at which the ball's state is compared
LEAD_S = 0.003  # s of flight before the ball's centre reaches the net's plane
RING_CAP_S = 8.0  # s: a ring-down is cut here (reported as such) if the net has not slept
QUICK_RING_CAP_S = 0.3
RING_DOWNS = 3  # impacts per net whose ring-down to sleep is timed (one per band), full run
BANDS = ("cord", "mid", "low")
# Ball centre heights (m) where its straight path meets the net's plane: into the cord's top 2 cm
# (the centre from 2 cm below the top to 1.5 cm above, where the ball's underside still clips it),
# mid-net, and low (a ball just above the table's surface).
BAND_Z = {"cord": (NetSpec().height - 0.02, NetSpec().height + 0.015), "mid": (0.05, 0.10), "low": (0.025, 0.045)}
MAX_ANGLE_DEG = 45.0
SPEED = (5.0, 30.0)  # m/s
ACROSS = 0.6  # m, |y| of the aim point (within the table's 0.76 m half width)
CONTACT_GAP = 2  # ticks: a pause this long or shorter within a contact does not end it
# The model's own sensitivity: the finest net's answer to the same shots moved by this much (m)
# in y and z, far less than any aim (the AI's aim noise is centimetres).
FLOOR_SHIFT = 1e-3
# Tunnelling stress: head-on shots at the middle of a cell at mid-height (m/s), and one at the fastest
# STRESS_OBLIQUE_DEG off the normal.
STRESS_SPEEDS = (20.0, 40.0, 60.0)  # 60: the fastest ball a scene allows (engine.physics.world._cloth_watch)
STRESS_OBLIQUE_DEG = 30.0
# Tolerances of the recommendation (see recommend()).
TOL_OUTCOME_CHANGES = 0
TOL_SPEED_BIAS = 0.75  # m/s, |mean(|v| - |v_ref|)| over the impacts
TOL_CONTACT_MS = 5.0  # ms, |mean contact duration - the reference's|
TOL_BULGE_MM = 5.0  # mm, |mean largest bulge - the reference's|


@dataclass(frozen=True)
class Impact:
    """One shot: the ball's start (m) and velocity (m/s) and the band it aims at."""

    index: int
    band: str
    speed: float
    angle_deg: float
    pos: tuple
    vel: tuple


OUTCOMES = ("over", "through", "under", "back", "caught")  # where a fired ball ends (run_impact)

def impacts(n: int, seed: int = SEED, height: float = NetSpec().height) -> list[Impact]:
    """n seeded match-like impacts from x < 0 toward +x, the bands in turn."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        band = BANDS[k % len(BANDS)]
        speed = float(rng.uniform(*SPEED))
        # Directions uniform over the cone's solid angle up to MAX_ANGLE_DEG off +x.
        cos_max = math.cos(math.radians(MAX_ANGLE_DEG))
        cos_t = float(rng.uniform(cos_max, 1.0))
        phi = float(rng.uniform(0.0, 2 * math.pi))
        sin_t = math.sqrt(1.0 - cos_t * cos_t)
        d = np.array([cos_t, sin_t * math.cos(phi), sin_t * math.sin(phi)])
        lo, hi = BAND_Z[band]
        aim = np.array([0.0, float(rng.uniform(-ACROSS, ACROSS)), float(rng.uniform(lo, hi))])
        # Start so the centre crosses x = -radius (the ball's front reaches the net's plane) LEAD_S later.
        start = aim - d * (speed * LEAD_S + BALL_RADIUS / cos_t)
        out.append(Impact(k, band, speed, math.degrees(math.acos(cos_t)), tuple(start), tuple(speed * d)))
    return out


def shifted(shots: list[Impact], d: float) -> list[Impact]:
    """The same shots moved by d (m) along y and z."""
    return [Impact(s.index, s.band, s.speed, s.angle_deg, (s.pos[0], s.pos[1] + d, s.pos[2] + d), s.vel)
            for s in shots]


def stress_shots(spec: NetSpec) -> list[Impact]:
    """Shots at the middle of a cell at mid-height (where a ball best fits between knots) of `spec`'s grid:
    head-on at STRESS_SPEEDS and one at the fastest, STRESS_OBLIQUE_DEG off the normal along y."""
    a = spec.width / (spec.cols - 1)
    b = spec.height / (spec.rows - 1)
    col = (spec.cols - 1) // 2
    row = max(0, (spec.rows - 1) // 2 - 1) if spec.rows > 3 else 0
    aim = np.array([0.0, -spec.width / 2 + (col + 0.5) * a, (row + 0.5) * b])
    aim[2] = max(aim[2], BALL_RADIUS + 1e-3)  # the ball stays above the table
    out = []
    dirs = [(speed, 0.0) for speed in STRESS_SPEEDS] + [(STRESS_SPEEDS[-1], STRESS_OBLIQUE_DEG)]
    for k, (speed, angle) in enumerate(dirs):
        t = math.radians(angle)
        d = np.array([math.cos(t), math.sin(t), 0.0])
        start = aim - d * (speed * LEAD_S + BALL_RADIUS / math.cos(t))
        out.append(Impact(k, "stress", speed, angle, tuple(start), tuple(speed * d)))
    return out


def _cord_z(sim: NetSim, cols: int, rows: int, y: float) -> float:
    """m: the cord's height at y now (linear between its knots)."""
    top = sim.knot_pos[(rows - 1) * cols:]
    return float(np.interp(y, top[:, 1], top[:, 2]))


def _under_hem(sim: NetSim, cols: int, p: np.ndarray) -> bool:
    """Is the ball's centre p (m) below the bottom cord and in front of it (smaller x), at its y now?"""
    hem = sim.knot_pos[:cols]
    return p[2] < float(np.interp(p[1], hem[:, 1], hem[:, 2])) and p[0] < float(np.interp(p[1], hem[:, 1], hem[:, 0]))


def run_impact(topo, imp: Impact, flight_s: float = FLIGHT_S) -> tuple[dict, NetSim]:
    """Fire one impact into a fresh net; returns its record and the net (awake or asleep) after it."""
    spec = topo.spec
    sim = NetSim(topo, DT)
    mass, radius = BALL_MASS, BALL_RADIUS
    g = np.array([0.0, 0.0, -spec.gravity])
    p = np.array(imp.pos, dtype=float)
    v = np.array(imp.vel, dtype=float)
    touched = []  # ticks with a contact
    crossings = []  # (z of the centre, z of the cord) each time the centre passes x = 0 going +x
    under = False  # the ball, after a touch, was below the bottom cord and in front of it on the far side
    bulge = 0.0
    ticks = int(round(flight_s / DT))
    t0 = time.thread_time()
    for t in range(ticks):
        contact = sim.step(p, v, radius, 1.0 / mass)
        p1 = p + v * DT + 0.5 * g * DT * DT
        v1 = v + g * DT
        if contact.toi != NO_CONTACT:
            p1 += contact.offset
            v1 += contact.impulse / mass
            touched.append(t)
        if p[0] < 0.0 <= p1[0]:
            crossings.append((float(p1[2]), _cord_z(sim, spec.cols, spec.rows, float(p1[1]))))
        if touched and not under and p1[0] > 0.0 and _under_hem(sim, spec.cols, p1):
            under = True  # caught, then out below the bottom cord that the bulge has swung up
        p, v = p1, v1
        bulge = max(bulge, float(np.max(np.abs(sim.knot_pos[:, 0]))))
    cpu = time.thread_time() - t0
    # Where the ball is at the end: clear of the net on its far side (over the cord or through the
    # mesh, by where it last crossed the net's plane, or under the bottom cord, which a deep bulge
    # swings up and back: a caught ball can drop out below it), back on its own side, or still in the net.
    gap = float(np.min(np.linalg.norm(sim.knot_pos - p, axis=1))) - radius - KNOT_RADIUS
    if p[0] < 0.0 and (gap > 0.005 or v[0] < 0.0):
        outcome = "back"
    elif p[0] > 0.0 and gap > 0.005 and crossings:
        z_ball, z_cord = crossings[-1]
        outcome = "over" if z_ball >= z_cord else "under" if under else "through"
    else:
        outcome = "caught"
    # The first contact: from the first touching tick until CONTACT_GAP ticks pass without one; a
    # later touch (the ball dropping back onto the net, riding its bulge) is a retouch.
    end = 0
    while end + 1 < len(touched) and touched[end + 1] - touched[end] <= CONTACT_GAP:
        end += 1
    return {
        "impact": imp.index,
        "band": imp.band,
        "outcome": outcome,
        "touched": bool(touched),
        "contact_ms": 0.0 if not touched else (touched[end] - touched[0] + 1) * DT * 1e3,
        "retouched": len(touched) > end + 1,
        "bulge_mm": bulge * 1e3,
        "pos": p.tolist(),
        "vel": v.tolist(),
        "cpu_s": cpu,
        "ticks": ticks,
    }, sim


def ring_down(sim: NetSim, cap_s: float) -> dict:
    """Step a net after its impact, ball gone, until it sleeps (or cap_s): sim seconds and CPU time."""
    t0 = time.thread_time()
    ticks = 0
    cap = int(round(cap_s / DT))
    while not sim.sleeping and ticks < cap:
        sim.step()
        ticks += 1
    cpu = time.thread_time() - t0
    return {"ticks": ticks, "sim_s": ticks * DT, "cpu_s": cpu, "slept": bool(sim.sleeping),
            "cpu_us_per_tick": cpu / ticks * 1e6 if ticks else None}


def _compile(topo) -> float:
    """s: compile (or load from numba's cache) every kernel NetSim calls: awake, ball near, asleep."""
    t0 = time.perf_counter()
    sim = NetSim(topo, DT)
    sim.step(np.array([-0.5, 0.0, 0.1]), np.array([1.0, 0.0, 0.0]))  # far: the whole-tick grid step
    sim.step(np.array([-0.021, 0.0, 0.1]), np.array([10.0, 0.0, 0.0]))  # near and touching
    sim.sleeping = True
    sim.touches(np.array([-0.021, 0.0, 0.1]), np.array([10.0, 0.0, 0.0]), BALL_RADIUS, 1.0 / BALL_MASS)
    return time.perf_counter() - t0


def geometry(spec: NetSpec) -> dict:
    """Cell size and whether the ball fits between knots (its centre through a cell's middle)."""
    a = spec.width / (spec.cols - 1)
    b = spec.height / (spec.rows - 1)
    diagonal = math.hypot(a, b)
    need = 2.0 * (BALL_RADIUS + KNOT_RADIUS)
    return {"a_mm": a * 1e3, "b_mm": b * 1e3, "diagonal_mm": diagonal * 1e3, "ball_needs_mm": need * 1e3,
            "ball_fits_through": diagonal > need}


def _angle_deg(u, w) -> float:
    nu, nw = np.linalg.norm(u), np.linalg.norm(w)
    if nu == 0.0 or nw == 0.0:
        return 0.0
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(u, w) / (nu * nw))))))


def _pct(values, q):
    return float(np.percentile(values, q)) if len(values) else None


def compare(runs: list[dict], ref: list[dict]) -> dict:
    """Errors of one net's impacts against the reference net's, impact by impact."""
    dv, ddir, dpos, dcontact, dbulge, dspeed = [], [], [], [], [], []
    changes = []
    for run, r in zip(runs, ref):
        dspeed.append(float(np.linalg.norm(run["vel"]) - np.linalg.norm(r["vel"])))
        dv.append(float(np.linalg.norm(np.subtract(run["vel"], r["vel"]))))
        ddir.append(_angle_deg(run["vel"], r["vel"]))
        dpos.append(float(np.linalg.norm(np.subtract(run["pos"], r["pos"]))) * 1e3)
        dcontact.append(run["contact_ms"] - r["contact_ms"])
        dbulge.append(run["bulge_mm"] - r["bulge_mm"])
        if run["outcome"] != r["outcome"]:
            changes.append(f"#{run['impact']} ({run['band']}): {r['outcome']} -> {run['outcome']}")
    return {
        "exit_velocity_error_median": _pct(dv, 50), "exit_velocity_error_p90": _pct(dv, 90),
        "exit_velocity_error_max": max(dv),
        "direction_error_deg_median": _pct(ddir, 50), "direction_error_deg_max": max(ddir),
        "position_error_mm_median": _pct(dpos, 50), "position_error_mm_max": max(dpos),
        "contact_ms_diff_median": _pct(dcontact, 50), "contact_ms_diff_max_abs": max(abs(x) for x in dcontact),
        "bulge_mm_diff_median": _pct(dbulge, 50), "bulge_mm_diff_max_abs": max(abs(x) for x in dbulge),
        "speed_bias_mean": statistics.fmean(dspeed),
        "speed_bias_se": statistics.stdev(dspeed) / math.sqrt(len(dspeed)) if len(dspeed) > 1 else None,
        "contact_ms_mean_diff": statistics.fmean(dcontact), "bulge_mm_mean_diff": statistics.fmean(dbulge),
        "outcome_changes": len(changes), "outcome_change_list": changes,
        "per_band_exit_velocity_error_median": {
            band: _pct([d for d, run in zip(dv, runs) if run["band"] == band], 50) for band in BANDS},
    }


def study(quick: bool = False, sizes=None, n_impacts: int | None = None, progress=None) -> dict:
    """Run the study; returns a JSON-ready dict (rows finest last; errors against the finest net)."""
    sizes = list(sizes or (QUICK_SIZES if quick else SIZES))
    sizes.sort(key=lambda s: s[0] * s[1])
    n = n_impacts or (QUICK_IMPACTS if quick else IMPACTS)
    shots = impacts(n)
    ring_cap = QUICK_RING_CAP_S if quick else RING_CAP_S
    ring_shots = 1 if quick else RING_DOWNS
    say = progress or (lambda msg: None)
    rows = []
    compile_s = 0.0
    for cols, rows_ in sizes:
        spec = resolution_spec(cols, rows_)
        topo = build_topology(spec)
        compile_s += _compile(topo)
        runs, rings = [], []
        for imp in shots:
            record, sim = run_impact(topo, imp)
            runs.append(record)
            if imp.index < ring_shots:
                rings.append({"impact": imp.index, **ring_down(sim, ring_cap)})
        stress = [run_impact(topo, imp)[0] for imp in stress_shots(spec)]
        awake_ticks = sum(r["ticks"] for r in rings)
        row = {
            "cols": cols, "rows": rows_, "knots": topo.n_knots,
            "substeps": NetSim(topo, DT).substeps,
            "spec": {k: getattr(spec, k) for k in ("knot_mass", "spring_k", "spring_c", "mesh_tension", "cord_k",
                                                   "cord_tension", "air_damping")},
            "continuum": net_continuum(spec),
            "geometry": geometry(spec),
            "impacts": runs,
            "stress": [{"speed": imp.speed, "angle_deg": imp.angle_deg, "outcome": r["outcome"]}
                       for imp, r in zip(stress_shots(spec), stress)],
            "stress_through": sum(r["outcome"] == "through" for r in stress),
            "ring_downs": rings,
            "cpu_ms_per_impact": 1e3 * statistics.median(r["cpu_s"] for r in runs),
            "cpu_us_per_impact_tick": 1e6 * sum(r["cpu_s"] for r in runs) / sum(r["ticks"] for r in runs),
            "cpu_us_per_awake_tick": (1e6 * sum(r["cpu_s"] for r in rings) / awake_ticks) if awake_ticks else None,
            "ring_down_s": statistics.median(r["sim_s"] for r in rings) if rings else None,
            "ring_down_cpu_s": statistics.median(r["cpu_s"] for r in rings) if rings else None,
            "ring_downs_slept": all(r["slept"] for r in rings),
            "outcomes": {o: sum(r["outcome"] == o for r in runs) for o in OUTCOMES},
            "retouched": sum(r["retouched"] for r in runs),
        }
        rows.append(row)
        say(f"{cols}x{rows_}: {row['cpu_ms_per_impact']:.0f} ms CPU per impact, ring-down {row['ring_down_s']} s, "
            f"outcomes {row['outcomes']}")
    ref = rows[-1]
    ref_topo = build_topology(resolution_spec(ref["cols"], ref["rows"]))
    floor = compare([run_impact(ref_topo, imp)[0] for imp in shifted(shots, FLOOR_SHIFT)], ref["impacts"])
    say(f"floor ({ref['cols']}x{ref['rows']}, shots moved {FLOOR_SHIFT * 1e3:g} mm): exit velocity change median "
        f"{floor['exit_velocity_error_median']:.2f} m/s")
    for row in rows:
        row["errors"] = compare(row["impacts"], ref["impacts"])
        row["cost_vs_default"] = None
    default = next((r for r in rows if (r["cols"], r["rows"]) == (NetSpec().cols, NetSpec().rows)), None)
    if default is not None:
        for row in rows:
            row["cost_vs_default"] = {
                "impact": row["cpu_ms_per_impact"] / default["cpu_ms_per_impact"],
                "awake_tick": (row["cpu_us_per_awake_tick"] / default["cpu_us_per_awake_tick"]
                               if row["cpu_us_per_awake_tick"] and default["cpu_us_per_awake_tick"] else None),
            }
    result = {
        "reference": f"{ref['cols']}x{ref['rows']}",
        "impacts": [vars(s) for s in shots],
        "n_impacts": n,
        "seed": SEED,
        "flight_s": FLIGHT_S,
        "ring_cap_s": ring_cap,
        "quick": quick,
        "compile_s": compile_s,
        "load_avg": os.getloadavg()[0],
        "rows": rows,
        "floor": {"shift_m": FLOOR_SHIFT, **floor},
        "tolerance": {"outcome_changes": TOL_OUTCOME_CHANGES, "speed_bias_m_s": TOL_SPEED_BIAS,
                      "contact_ms": TOL_CONTACT_MS, "bulge_mm": TOL_BULGE_MM, "through_in_stress": 0,
                      "ball_must_not_fit_between_knots": True},
    }
    result["recommendation"] = recommend(result)
    return result


def recommend(result: dict) -> dict | None:
    """The coarsest net (fewest knots) within tolerance against the reference, the reference excluded.

    Match-relevant tolerance. Per ball, the exit velocity is not a fair target: moving the shots by
    FLOOR_SHIFT (1 mm, far below any aim) changes the finest net's own answer by about as much
    as a coarser grid does (result["floor"]), so the ball's fate and the net's statistics are:
    - the ball cannot pass between knots: the cell's diagonal is below 2 (ball + knot radius),
      and no stress shot (20-40 m/s at a cell's middle) goes through;
    - no impact changes its outcome (over the cord / through / back / caught: the point);
    - the mean exit speed within TOL_SPEED_BIAS (0.75 m/s, 16 % of the mean 4.6 m/s rebound)
      of the reference's: where balls dropped off the net go (the default net: +0.51 +- 0.13;
      the reference against its own shots moved 1 mm: +0.24 +- 0.11);
    - the mean contact duration within TOL_CONTACT_MS and the mean largest bulge within
      TOL_BULGE_MM of the reference's: what the net does to the ball in time and space (the
      default 184 x 16 net: -1.3 ms and -1.2 mm against the 368 x 32 net; the contact's
      duration is the first contact's).
    """
    for row in result["rows"][:-1]:  # fewest knots first
        e = row["errors"]
        if (not row["geometry"]["ball_fits_through"] and row["stress_through"] == 0
                and e["outcome_changes"] <= TOL_OUTCOME_CHANGES and abs(e["speed_bias_mean"]) <= TOL_SPEED_BIAS
                and abs(e["contact_ms_mean_diff"]) <= TOL_CONTACT_MS and abs(e["bulge_mm_mean_diff"]) <= TOL_BULGE_MM):
            return {"net": f"{row['cols']}x{row['rows']}", "cols": row["cols"], "rows": row["rows"],
                    "spec": row["spec"], "errors": {k: v for k, v in e.items() if k != "outcome_change_list"},
                    "cost_vs_default": row["cost_vs_default"]}
    return None


def _se(e: dict) -> str:
    return "-" if e["speed_bias_se"] is None else f"{e['speed_bias_se']:.2f}"


def markdown_table(result: dict) -> str:
    """The per-net table (errors against the reference, costs) as Markdown."""
    head = ("| net | knots | substeps | cell mm (diag) | ball fits through | outcomes over/through/under/back/caught | "
            "outcome changes | stress shots through | exit speed bias m/s (SE) | exit v error m/s median / p90 / max | "
            "direction error deg median / max | "
            "position error at 150 ms mm median | first contact ms mean diff | bulge mm mean diff | "
            "CPU ms per impact | CPU µs per awake tick | ring-down s (CPU s) |")
    lines = [head, "|" + " --- |" * (head.count("|") - 1)]
    for row in result["rows"]:
        e = row["errors"]
        g = row["geometry"]
        o = row["outcomes"]
        awake = row["cpu_us_per_awake_tick"]
        ring = "-" if row["ring_down_s"] is None else (
            f"{row['ring_down_s']:.2f}{'' if row['ring_downs_slept'] else '+'} ({row['ring_down_cpu_s']:.2f})")
        lines.append(
            f"| {row['cols']}x{row['rows']} | {row['knots']} | {row['substeps']} | "
            f"{g['a_mm']:.1f} x {g['b_mm']:.1f} ({g['diagonal_mm']:.0f}) | {'yes' if g['ball_fits_through'] else 'no'} | "
            f"{o['over']}/{o['through']}/{o['under']}/{o['back']}/{o['caught']} | {e['outcome_changes']} | "
            f"{row['stress_through']}/{len(row['stress'])} | {e['speed_bias_mean']:+.2f} ({_se(e)}) | "
            f"{e['exit_velocity_error_median']:.3f} / {e['exit_velocity_error_p90']:.3f} / "
            f"{e['exit_velocity_error_max']:.3f} | {e['direction_error_deg_median']:.1f} / "
            f"{e['direction_error_deg_max']:.1f} | {e['position_error_mm_median']:.1f} | "
            f"{e['contact_ms_mean_diff']:+.1f} | {e['bulge_mm_mean_diff']:+.1f} | "
            f"{row['cpu_ms_per_impact']:.1f} | {'-' if awake is None else f'{awake:.0f}'} | {ring} |")
    return "\n".join(lines)


COMPACT_COLUMNS = ("net", "knots", "sub", "diag mm", "stress thru", "outc chg", "speed bias m/s", "exit err m/s",
                   "contact ms", "bulge mm", "µs/awake tick", "ring CPU s")


def compact_rows(result: dict) -> list[tuple[str, ...]]:
    """The table's main columns (COMPACT_COLUMNS) as strings, for a terminal: "sub" the substeps a tick,
    "!" a cell the ball fits through, errors against the reference (median exit velocity error; mean
    differences of speed, first contact and bulge)."""
    out = []
    for row in result["rows"]:
        e = row["errors"]
        g = row["geometry"]
        awake = row["cpu_us_per_awake_tick"]
        out.append((f"{row['cols']}x{row['rows']}", str(row["knots"]), str(row["substeps"]),
                    f"{g['diagonal_mm']:.0f}{'!' if g['ball_fits_through'] else ''}",
                    f"{row['stress_through']}/{len(row['stress'])}", str(e["outcome_changes"]),
                    f"{e['speed_bias_mean']:+.2f}±{_se(e)}", f"{e['exit_velocity_error_median']:.2f}",
                    f"{e['contact_ms_mean_diff']:+.1f}", f"{e['bulge_mm_mean_diff']:+.1f}",
                    "-" if awake is None else f"{awake:.0f}",
                    "-" if row["ring_down_cpu_s"] is None else f"{row['ring_down_cpu_s']:.2f}"))
    return out


def summary_lines(result: dict) -> list[str]:
    """Plain-language findings under the table."""
    out = [f"Reference: {result['reference']}; {result['n_impacts']} impacts (seed {result['seed']}), ball state "
           f"compared {result['flight_s'] * 1e3:.0f} ms after the shot; CPU time of the stepping thread, load average "
           f"{result['load_avg']:.1f}; kernels compiled or loaded in {result['compile_s']:.1f} s, apart. "
           f"A ring-down marked + did not sleep within {result['ring_cap_s']:g} s."]
    for row in result["rows"]:
        changes = row["errors"]["outcome_change_list"]
        if changes:
            kinds = {}
            for change in changes:
                kind = change.split(": ", 1)[1]
                kinds[kind] = kinds.get(kind, 0) + 1
            out.append(f"{row['cols']}x{row['rows']}: {len(changes)} of {result['n_impacts']} impacts change their "
                       f"outcome ({', '.join(f'{k} {n}' for k, n in kinds.items())}; impacts "
                       f"{', '.join(c.split(' ', 1)[0] for c in changes)})")
    f = result["floor"]
    out.append(f"The model's own sensitivity: the same shots moved {f['shift_m'] * 1e3:g} mm on the {result['reference']} "
               f"net change its exit velocity by {f['exit_velocity_error_median']:.2f} m/s median "
               f"({f['exit_velocity_error_p90']:.2f} p90, {f['exit_velocity_error_max']:.2f} max), its outcome "
               f"{f['outcome_changes']} times, its mean exit speed by {f['speed_bias_mean']:+.2f} m/s: per ball, "
               "errors of that size say nothing about the resolution.")
    rec = result["recommendation"]
    tol = result["tolerance"]
    criteria = (f"ball cannot pass between knots and no stress shot goes through, no outcome changes, mean exit "
                f"speed within {tol['speed_bias_m_s']} m/s, mean contact within {tol['contact_ms']:g} ms and mean "
                f"bulge within {tol['bulge_mm']:g} mm of the reference's")
    if rec is None:
        out.append(f"No net coarser than the reference is within tolerance ({criteria}).")
    else:
        e = rec["errors"]
        cost = rec["cost_vs_default"]
        cost_text = "" if cost is None or cost["awake_tick"] is None else (
            f"; its awake tick costs {cost['awake_tick']:.2f}x the default net's, an impact {cost['impact']:.2f}x")
        out.append(f"Coarsest within tolerance ({criteria}): {rec['net']}: mean exit speed "
                   f"{e['speed_bias_mean']:+.2f} m/s, contact {e['contact_ms_mean_diff']:+.1f} ms, bulge "
                   f"{e['bulge_mm_mean_diff']:+.1f} mm; per ball exit velocity error median "
                   f"{e['exit_velocity_error_median']:.2f} m/s{cost_text}.")
    return out


def _parse_sizes(text: str | None):
    """[(cols, rows), ...] from "COLSxROWS,..." or None; a bad entry exits with a message naming it."""
    if text is None:
        return None
    sizes = []
    for item in text.split(","):
        parts = item.strip().lower().split("x")
        if len(parts) != 2 or not all(p.isdigit() for p in parts) or min(int(p) for p in parts) < 2:
            raise ValueError(f"--sizes entry {item!r} is not COLSxROWS with "
                             "integers >= 2 (e.g. --sizes 70x7,92x8,184x16)")
        sizes.append((int(parts[0]), int(parts[1])))
    if len(sizes) < 2:
        raise ValueError("--sizes needs at least two nets (the finest is the reference)")
    return sizes


def _arguments(parser) -> None:
    parser.add_argument("--sizes", default=None,
                        help="nets as COLSxROWS, comma-separated (the finest is the reference)")
    parser.add_argument("--impacts", type=int, default=None, help="number of impacts")


def _run(args, progress=None) -> dict:
    """The study for --sizes and --impacts; ValueError names a bad flag (or a net that cannot build)."""
    sizes = _parse_sizes(args.sizes)
    if args.impacts is not None and args.impacts < 1:
        raise ValueError(f"--impacts {args.impacts} must be >= 1")
    return study(quick=args.quick, sizes=sizes, n_impacts=args.impacts, progress=progress)


def _report(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]Net resolution: accuracy against cost[/bold] (the same physical net on each grid, "
                  f"net_kernel.topology.resolution_spec; errors against {result['reference']}; every column in "
                  "--json and in bench/net_resolution.py's Markdown table; sub: substeps a tick, !: the ball fits through a "
                  "cell; errors: median exit velocity error, mean differences of speed, first contact and bulge)")
    table = Table(*COMPACT_COLUMNS)
    for cells in compact_rows(result):
        table.add_row(*cells)
    console.print(table)
    for line in summary_lines(result):
        console.print(f"- {line}")


STUDY = Study(run=_run, report=_report, add_arguments=_arguments,
              quick="three coarse nets, three impacts, short ring-downs")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.net_resolution", "net-resolution"))
