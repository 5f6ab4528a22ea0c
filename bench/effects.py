"""`pingpong bench effects`: what each effect costs per simulated second, by toggling it in a scene.

Physics effects (gravity, drag, magnus, friction, table, floor, net, bats) are timed in a numba
loop over the engine's own kernels (engine.physics.bat.bat_step and engine.physics.collision.ball_tick, as
engine.physics.world.step calls them) on the bundled `rally` scene, replayed from its start until the
loop covers the simulated time asked for; the per-tick cost through engine.physics.world.step is given
beside it. Each cost is the ratio of the scene with the effect to the same scene without it,
measured in the same run, interleaved round by round. The AI and the referee live in Python
(engine/play/match.py) and a match needs both, so they are timed inside the in-process match on the
bundled `match` scene (the AIs' own clock, the referee's calls wrapped) instead of toggled.

An absent effect is a None argument: numba compiles a specialisation without its code. Two checks
show it costs nothing measurable: the baseline timed twice (A/A, the noise floor), and drag and
Magnus present with a zero coefficient (their code runs and adds nothing) against absent.
"""
from __future__ import annotations

import statistics
import time
import tomllib

import numpy as np
from numba import njit

from bench.study import Study, quick_only
from bench.study import run as run_study
from engine.physics.bat import bat_step
from engine.physics.collision import EVENT_ROW, MAX_IMPACTS_PER_TICK, ball_tick
from engine.physics.scene import EFFECTS, NET_KINDS, PLANNED_EFFECTS, SCENES_DIR, Scene, parse_scene
from engine.physics.world import build_model, initial_state, new_events, step
from engine.play.match import Match

PHYSICS_EFFECTS = ("gravity", "drag", "magnus", "friction", "table", "floor", "net", "bats")
# --quick toggles fewer effects: each toggled scene is one more specialisation to compile (~15 s
# each on a cold numba cache), and the smoke test should stay short.
QUICK_EFFECTS = ("drag", "bats")
# Effects a scene may ask for that this engine cannot simulate yet: reported, never faked.
NOT_AVAILABLE = {
    **({} if "cloth" in NET_KINDS else {"cloth net": "the net kernel is not coupled to the ball engine yet"}),
    **{name: "not supported by this version of the engine (scene.PLANNED_EFFECTS)" for name in PLANNED_EFFECTS},
}
# Which argument of _rally_loop carries each effect (None when the scene does not ask for it).
LOOP_ARG = {"gravity": 5, "drag": 6, "magnus": 7, "table": 10, "floor": 11, "net": 12, "bats": 1}


@njit(cache=True)
def _rally_loop(ball0, bats0, n_ticks, h, method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z, net, posts,
                bat_mass, bat_inertia, motion0, params, materials, work, scratch, adapt, events, replay_every):
    """Tick the ball (and the bats, if any) n_ticks times, restarting the scene every replay_every ticks.

    Returns the total number of impacts, so the work cannot be optimised away.
    """
    ball = ball0.copy()
    bats = bats0.copy() if bats0 is not None else None
    motion = motion0.copy() if motion0 is not None else None
    tmp = np.zeros((3, 3))
    support = 0
    impacts = 0
    for tick in range(n_ticks):
        if tick % replay_every == 0:
            ball[:] = ball0
            support = 0
            adapt[:] = 0.0
            if bats is not None:
                bats[:] = bats0
        if bats is not None:
            bat_step(bats, h, bat_mass, bat_inertia, motion, tmp)
        n, support = ball_tick(ball, h, support, (method, gravity, drag_k, magnus_k, rtol, atol),
                               (table, floor_z, net, posts), motion, params, materials, work, scratch, adapt, events)
        if n < 0:
            return n
        impacts += n
    return impacts


def _scene_data(name: str) -> dict:
    return tomllib.loads((SCENES_DIR / f"{name}.toml").read_text())


def toggled(data: dict, drop: str | None = None, **air) -> Scene:
    """The scene of `data` without the effect `drop` (and the tables that only it needs)."""
    data = {**data, "effects": [e for e in data["effects"] if e != drop]}
    if drop == "bats":
        data.pop("bats", None)
    if drop == "ai":
        data["bats"] = {k: {kk: vv for kk, vv in v.items() if kk != "skill"} for k, v in data["bats"].items()}
    if drop == "referee":
        data.pop("match", None)
    if air:
        data["air"] = {**data.get("air", {}), **air}
    return parse_scene(data, f"bench/effects.py:{data['name']}-{drop or 'all'}")


class _PhysicsRun:
    """A scene's kernels and state, ready for the timed loop."""

    def __init__(self, scene: Scene, n_ticks: int):
        self.scene = scene
        self.model = m = build_model(scene)
        state = initial_state(scene)
        self.n_ticks = n_ticks
        has_bats = len(scene.bats) > 0
        self.args = (
            state.ball_flat[0:9].copy(), state.bat_flat.copy() if has_bats else None, n_ticks, m.dt, m.method,
            m.gravity, m.drag_k, m.magnus_k, scene.rtol, scene.atol, m.table, m.floor_z, m.net, m.posts,
            m.bat_mass, m.bat_inertia, state.bat_motion.copy() if has_bats else None, m.ball_params, m.materials,
            state.work, state.scratch, state.adapt.copy(), np.zeros((MAX_IMPACTS_PER_TICK, EVENT_ROW)), scene.ticks,
        )

    def compile(self) -> float:
        start = time.perf_counter()
        _rally_loop(*self.args[:2], 1, *self.args[3:])
        return time.perf_counter() - start

    def __call__(self) -> int:
        return _rally_loop(*self.args)


def _interleaved(runs: dict, repeats: int) -> dict:
    """Median wall time per run, the runs interleaved round by round so that machine load drifts
    hit them all alike; also each run's spread (max - min) / median."""
    times = {k: [] for k in runs}
    for _ in range(repeats):
        for key, fn in runs.items():
            start = time.perf_counter()
            fn()
            times[key].append(time.perf_counter() - start)
    out = {}
    for key, ts in times.items():
        med = statistics.median(ts)
        out[key] = (med, (max(ts) - min(ts)) / med, min(ts))
    return out


def _step_us_per_tick(scene: Scene, n_ticks: int) -> float:
    model = build_model(scene)
    state = initial_state(scene)
    events = new_events()
    step(model, state, None, events, dt=0.0)
    start = time.perf_counter()
    for tick in range(n_ticks):
        if tick and tick % scene.ticks == 0:
            state = initial_state(scene)
        step(model, state, None, events)
    return (time.perf_counter() - start) / n_ticks * 1e6


def _compiled_out(run: "_PhysicsRun", effect: str) -> bool | None:
    """True if the loop compiled for the scene without the effect types the effect's argument None,
    i.e. that specialisation has no code for it (None when the effect has no argument of its own)."""
    index = LOOP_ARG.get(effect)
    if index is None:
        return None
    return run.args[index] is None and any(str(sig[index]) == "none" for sig in _rally_loop.signatures)


def _match_split(scene: Scene, ticks: int, repeats: int) -> dict:
    """Wall seconds per tick of the in-process match, and the part of it spent in the AIs
    (Match.ai_seconds) and in the referee (its methods timed in place), median over repeats.

    A match needs both (no referee: no match; no AI: nobody returns a serve and it is a different
    game), so these two effects are measured inside one run instead of by toggling.
    """
    Match(scene, seed=0).play(max_ticks=2)  # compile or load the kernels and warm the AI up
    samples = []
    for _ in range(repeats):
        match = Match(scene, seed=0)
        spent = [0.0]
        for name in ("on_contact", "ball_out_of_play", "next_rally"):
            method = getattr(match.referee, name)

            def timed(*args, _method=method):
                start = time.perf_counter()
                try:
                    return _method(*args)
                finally:
                    spent[0] += time.perf_counter() - start

            setattr(match.referee, name, timed)
        result = match.play(max_ticks=ticks)
        n = max(result.ticks, 1)
        samples.append((result.wall_seconds / n, result.ai_seconds / n, spent[0] / n))
    total = statistics.median(s[0] for s in samples)
    return {"total_s_per_tick": total, "ai_s_per_tick": statistics.median(s[1] for s in samples),
            "referee_s_per_tick": statistics.median(s[2] for s in samples),
            "spread": (max(s[0] for s in samples) - min(s[0] for s in samples)) / total}


def study(quick: bool = False, repeats: int | None = None, progress=None) -> dict:
    """Time every effect on and off; returns a JSON-ready dict."""
    say = progress or (lambda _msg: None)
    repeats = repeats or (3 if quick else 7)
    # ~1 us a tick: 240 s of rally (100 replays) is ~0.25 s of wall time per measurement.
    sim_seconds = 24.0 if quick else 240.0
    effects = QUICK_EFFECTS if quick else PHYSICS_EFFECTS
    data = _scene_data("rally")
    base = toggled(data)
    n_ticks = int(round(sim_seconds / base.dt))
    say("compiling the kernels for every toggled scene")
    runs = {"all": _PhysicsRun(base, n_ticks), "all (A/A)": _PhysicsRun(base, n_ticks)}
    for effect in effects:
        runs[f"-{effect}"] = _PhysicsRun(toggled(data, effect), n_ticks)
    runs["drag C_D=0"] = _PhysicsRun(toggled(data, None, drag_coefficient=0.0), n_ticks)
    if "magnus" in effects:
        runs["magnus C_M=0"] = _PhysicsRun(toggled(data, None, magnus_coefficient=0.0), n_ticks)
    compile_seconds = sum(run.compile() for run in runs.values())
    say(f"timing {len(runs)} scenes, {repeats} rounds")
    timed = _interleaved(runs, repeats)
    per_sim = {k: v[0] / sim_seconds for k, v in timed.items()}
    # The fastest round is the least disturbed by the other processes on the machine: its ratios
    # are given beside the medians' (timeit's advice for CPU-bound code under interference).
    best = {k: v[2] / sim_seconds for k, v in timed.items()}
    spread = statistics.median(v[1] for v in timed.values())
    step_ticks = 600 if quick else 2400
    say("per-tick cost through engine.physics.world.step")
    step_us = {"all": _step_us_per_tick(base, step_ticks)}
    rows = []
    for effect in effects:
        without = per_sim[f"-{effect}"]
        # Through engine.physics.world.step each toggled scene is one more specialisation of the tick
        # kernel to compile (~15-25 s cold): --quick, a smoke run, measures the kernel loop only.
        step_us[f"-{effect}"] = None if quick else _step_us_per_tick(runs[f"-{effect}"].scene, step_ticks)
        note = {
            "gravity": "without gravity the ball flies straight and meets other bodies: the trajectory changes",
            "table": "without the table the ball falls to the floor: the trajectory changes",
            "floor": "the rally ends before the floor matters: the floor's cost is its gap test",
            "friction": "without friction the contact is frictionless (same code, mu = 0): impacts still happen",
            "bats": "without bats the drive is never returned: the trajectory changes",
            "net": "the rigid net and its posts: two boxes in the gap test",
        }.get(effect, "same trajectory up to the effect's own change")
        rows.append({"effect": effect, "available": True, "without_s_per_sim_s": without,
                     "with_s_per_sim_s": per_sim["all"], "ratio": per_sim["all"] / without,
                     "ratio_fastest_rounds": best["all"] / best[f"-{effect}"],
                     "step_us_per_tick_without": step_us[f"-{effect}"], "step_us_per_tick_with": step_us["all"],
                     "compiled_out": _compiled_out(runs[f"-{effect}"], effect), "note": note})

    match_scene = parse_scene(_scene_data("match"), "scenes/match.toml")
    match_ticks = 1000 if quick else 6000
    say("the in-process match: time in the AIs and in the referee")
    split = _match_split(match_scene, match_ticks, 1 if quick else 3)
    dt = match_scene.dt
    total, ai, referee = split["total_s_per_tick"], split["ai_s_per_tick"], split["referee_s_per_tick"]
    rows.append({"effect": "ai", "available": True, "without_s_per_sim_s": (total - ai) / dt,
                 "with_s_per_sim_s": total / dt, "ratio": total / (total - ai), "compiled_out": None,
                 "note": f"two pro AIs at {match_scene.match.ai_hz:g} Hz (Python around numba predictions), timed inside the match"})
    rows.append({"effect": "referee", "available": True, "without_s_per_sim_s": (total - ai - referee) / dt,
                 "with_s_per_sim_s": (total - ai) / dt, "ratio": (total - ai) / (total - ai - referee),
                 "compiled_out": None, "note": "the referee's calls (Python, on contact events only), timed inside the match"})
    if "cloth" in NET_KINDS:
        if quick:
            rows.append({"effect": "cloth net", "available": True, "skipped": True, "note": "not measured with --quick"})
        else:
            # The cloth net runs in Python around the net kernel (net_kernel.NetSim): timed through
            # engine.physics.world.step, against the same scene with the rigid net, one rally each.
            say("the cloth net against the rigid net, through engine.physics.world.step")
            cloth = toggled({**data, "net": {"kind": "cloth"}})
            rigid_us = _step_us_per_tick(base, base.ticks)
            cloth_us = _step_us_per_tick(cloth, base.ticks)
            rows.append({"effect": "cloth net", "available": True, "without_s_per_sim_s": rigid_us * 1e-6 / base.dt,
                         "with_s_per_sim_s": cloth_us * 1e-6 / base.dt, "ratio": cloth_us / rigid_us,
                         "compiled_out": None,
                         "note": "cloth (net_kernel.NetSim, default 184 x 16 knots) vs rigid net, through "
                                 "engine.physics.world.step over one rally"})
    for effect in PHYSICS_EFFECTS:
        if effect not in effects:
            rows.append({"effect": effect, "available": True, "skipped": True, "note": "not toggled with --quick"})
    for name, why in NOT_AVAILABLE.items():
        rows.append({"effect": name, "available": False, "note": why})

    absent = {
        "aa_ratio": per_sim["all (A/A)"] / per_sim["all"],
        "aa_ratio_fastest_rounds": best["all (A/A)"] / best["all"],
        "drag_zero_vs_absent_fastest_rounds": best["drag C_D=0"] / best["-drag"],
        "drag_zero_vs_absent": per_sim["drag C_D=0"] / per_sim["-drag"],
        "magnus_zero_vs_absent": per_sim["magnus C_M=0"] / per_sim["-magnus"] if "magnus" in effects else None,
    }
    absent["text"] = (f"the same scene timed twice differs by a factor {absent['aa_ratio']:.3f} (the noise); drag "
                      f"present with C_D = 0 costs {absent['drag_zero_vs_absent']:.3f}x drag absent"
                      + (f", Magnus with C_M = 0 {absent['magnus_zero_vs_absent']:.3f}x Magnus absent"
                         if absent["magnus_zero_vs_absent"] is not None else "")
                      + " (fastest rounds: A/A "
                      f"{absent['aa_ratio_fastest_rounds']:.3f}, drag C_D = 0 vs absent "
                      f"{absent['drag_zero_vs_absent_fastest_rounds']:.3f}); an absent effect's argument is None, "
                      "so its specialisation has no code for it")
    return {
        "scene": base.name,
        "effects_in_scene": sorted(base.effects),
        "known_effects": list(EFFECTS),
        "sim_seconds": sim_seconds,
        "repeats": repeats,
        "compile_seconds": compile_seconds,
        "noise": {"aa_ratio": absent["aa_ratio"], "spread": spread},
        "per_sim_s": per_sim,
        "step_us_per_tick": step_us,
        "match": {"max_ticks": match_ticks, **split},
        "per_sim_s_fastest_rounds": best,
        "effects": rows,
        "absent_check": absent,
        "quick": quick,
    }


def _report(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]Effect costs[/bold], scene {result['scene']}: numba tick loop over {result['sim_seconds']:g} "
                  f"simulated s, median of {result['repeats']} interleaved rounds; kernels compiled in "
                  f"{result['compile_seconds']:.1f} s, apart. Same-run A/A check of the baseline: "
                  f"{result['noise']['aa_ratio']:.3f} (median spread between rounds {result['noise']['spread'] * 100:.0f} %).")
    table = Table("effect", "without s/sim s", "with s/sim s", "with / without", "fastest rounds", "absent compiled out")
    notes = []
    for row in result["effects"]:
        if not row["available"] or row.get("skipped"):
            table.add_row(row["effect"], "-", "-", "-", "-", "-")
            notes.append(f"{row['effect']}: {'not available: ' if not row['available'] else ''}{row['note']}")
            continue
        fastest = row.get("ratio_fastest_rounds")
        compiled = {True: "yes", False: "no", None: "-"}[row.get("compiled_out")]
        table.add_row(row["effect"], f"{row['without_s_per_sim_s']:.2e}", f"{row['with_s_per_sim_s']:.2e}",
                      f"{row['ratio']:.2f}", "-" if fastest is None else f"{fastest:.2f}", compiled)
        notes.append(f"{row['effect']}: {row['note']}")
    console.print(table)
    for note in notes:
        console.print(f"  {note}")
    if result.get("absent_check"):
        console.print(f"absent costs nothing: {result['absent_check']['text']}")


STUDY = Study(run=quick_only(study), report=_report, quick="a shorter simulated time and one round")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.effects", "effects"))
