"""`pingpong bench ringdown`: how a struck cloth net rings down, the hanging net beside the tied one.

Balls at 5, 10, 20 and 40 m/s into the middle of the default match's net (85 x 8 knots, scenes/
match.toml) and near a post. For each: the ticks until the net falls asleep (NetSim's sleep rule),
the peak deflection of any knot out of the net's plane, the energy the net took from the ball
(its kinetic energy in less out), and the ring's damping ratio: measured from the decay of the
struck point's out-of-plane motion (successive peaks of x after the ball has left) against the
model's, zeta = air_damping / (2 w) for the mass-proportional air damping at the measured
frequency w (the axial dashpots add little to the slow sway). The same shots into the net tied
to the table (NetSpec.fix_table, the net before it was hung on two cords) in the same run, and
into the hanging net damped by the air's own drag alone (AIR_DAMPING_PHYSICAL, 0.2/s, against the
chosen 5/s: what the unmeasured constant costs and changes). Each shot's cost is the net's own:
its awake ticks and the CPU time of its NetSim.step calls.

The ball is the net harness's: a straight path bent by the net's impulses and by gravity, no
table, no drag (net_kernel.NetSim's contract); the engine is not in the loop.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from net_kernel import NetSim, build_topology
from bench.study import Study, quick_only
from bench.study import run as run_study
from net_kernel.sim import BALL_MASS, compile_kernels
from net_kernel.topology import AIR_DAMPING_PHYSICAL, resolution_spec

DT = 1e-3  # s, the engine's tick (scenes/match.toml)
SPEEDS = (5.0, 10.0, 20.0, 40.0)  # m/s
POINTS = {"middle": (0.0, 0.10), "near a post": (0.80, 0.10)}  # (y, z) m of the ball's aim
MAX_TICKS = 8000  # 8 s: longer than any net at 5/s takes to fall asleep
# The net damped by the air alone rings for about a minute (its out-of-plane modes decay at
# 0.1/s); --quick stops it at MAX_TICKS, awake.
MAX_TICKS_AIR = 150_000
GRAVITY = 9.81


def _peaks(signal: np.ndarray) -> np.ndarray:
    """Indices of the local maxima of |signal| (successive half-periods' amplitudes)."""
    a = np.abs(signal)
    return np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:])) + 1


def _damping(trace: np.ndarray, rest: float) -> tuple[float, float]:
    """(zeta, frequency Hz) of the decay of trace - rest: log decrement over its peaks."""
    x = trace - rest
    peaks = _peaks(x)
    peaks = peaks[np.abs(x[peaks]) > 1e-6]  # above the sleep rule's noise floor
    if peaks.size < 4:
        return math.nan, math.nan
    # Peaks of |x| come every half period; the decay per half period is the log decrement / 2.
    half_period = float(np.mean(np.diff(peaks))) * DT
    slope = np.polyfit(peaks * DT, np.log(np.abs(x[peaks])), 1)[0]  # -sigma, 1/s
    w = math.pi / half_period
    sigma = -slope
    return sigma / math.hypot(sigma, w), w / (2 * math.pi)


def _shot(topo, speed: float, y: float, z: float, max_ticks: int = MAX_TICKS) -> dict:
    spec = topo.spec
    sim = NetSim(topo, DT)
    pos, vel = np.array([-0.05, y, z]), np.array([speed, 0.0, 0.0])
    energy_in = 0.5 * BALL_MASS * speed * speed
    aim = int(np.argmin(np.hypot(topo.rest_pos[:, 1] - y, topo.rest_pos[:, 2] - z)))
    rest_x = float(topo.rest_pos[aim, 0])
    trace = np.zeros(max_ticks)
    peak = 0.0
    left = None
    ticks = max_ticks
    cpu = 0.0
    for t in range(max_ticks):
        start = time.process_time()
        contact = sim.step(pos, vel)
        cpu += time.process_time() - start
        pos = pos + vel * DT + contact.offset
        vel = vel + contact.impulse / BALL_MASS
        vel[2] -= GRAVITY * DT
        trace[t] = sim.knot_pos[aim, 0]
        peak = max(peak, float(np.abs(sim.knot_pos[:, 0] - topo.rest_pos[:, 0]).max()))
        if left is None and contact.toi < 0 and abs(pos[0]) > 0.1:
            left = t  # the ball is gone: from here the net rings on its own
        if sim.sleeping:
            ticks = t + 1
            break
    energy_out = 0.5 * BALL_MASS * float(vel @ vel) + BALL_MASS * GRAVITY * (pos[2] - z)  # kinetic + potential
    zeta, freq = _damping(trace[left:ticks], rest_x) if left is not None else (math.nan, math.nan)
    model = spec.air_damping / (4 * math.pi * freq) if math.isfinite(freq) else math.nan
    return {"speed_m_s": speed, "sleep_s": ticks * DT if sim.sleeping else math.inf, "peak_deflection_m": peak,
            "energy_absorbed_J": energy_in - energy_out, "energy_in_J": energy_in, "ring_frequency_hz": freq,
            "damping_ratio": zeta, "damping_ratio_model": model, "thrown_back": bool(vel[0] < 0),
            "stepped_s": ticks * DT, "awake_ticks": sim.awake_ticks,
            "tail_ticks": sim.tail_ticks, "net_cpu_s": cpu}


def study(quick: bool = False, progress=None) -> dict:
    """The ring-downs of the hanging net, of the tied one and of the hanging net at the air's own drag.

    quick: 10 and 40 m/s into the middle, the air-damped net stopped at MAX_TICKS.
    """
    hanging = resolution_spec(85, 8)
    # The default net; tied to the table; damped by the air alone.
    nets = {"hanging": (hanging, MAX_TICKS), "tied": (replace(hanging, fix_table=True), MAX_TICKS),
            "hanging_air": (replace(hanging, air_damping=AIR_DAMPING_PHYSICAL), MAX_TICKS if quick else MAX_TICKS_AIR)}
    speeds = (10.0, 40.0) if quick else SPEEDS
    points = {"middle": POINTS["middle"]} if quick else POINTS
    result = {"dt_s": DT, "nets": {}, "compile_s": 0.0}
    for name, (spec, max_ticks) in nets.items():
        topo = build_topology(spec)
        start = time.perf_counter()
        compile_kernels(topo, DT)  # compiled (or loaded from the cache) before any shot's CPU is counted
        result["compile_s"] += time.perf_counter() - start
        shots = []
        for where, (y, z) in points.items():
            for speed in speeds:
                if progress:
                    progress(f"{name}: {speed:g} m/s, {where}")
                shots.append({"point": where, **_shot(topo, speed, y, z, max_ticks)})
        result["nets"][name] = {"air_damping_per_s": spec.air_damping, "max_s": max_ticks * DT, "shots": shots}
    result["air_against_chosen"] = _compare(result["nets"]["hanging"], result["nets"]["hanging_air"])
    return result


def _compare(chosen: dict, air: dict) -> dict:
    """The air-damped net's shots against the same shots at the chosen damping: ratios, mean over the shots."""
    pairs = list(zip(chosen["shots"], air["shots"]))

    def mean_ratio(key):
        return float(np.mean([b[key] / a[key] for a, b in pairs]))

    return {"air_damping_per_s": [chosen["air_damping_per_s"], air["air_damping_per_s"]],
            "asleep": [sum(math.isfinite(s["sleep_s"]) for s in net["shots"]) for net in (chosen, air)],
            "shots": len(pairs), "awake_ticks_ratio": mean_ratio("awake_ticks"), "net_cpu_ratio": mean_ratio("net_cpu_s"),
            "peak_deflection_ratio": mean_ratio("peak_deflection_m"),
            "energy_absorbed_ratio": mean_ratio("energy_absorbed_J")}


def summary_lines(result: dict) -> list[str]:
    """One line per net (mean time to sleep, net CPU per shot, measured against the model's damping
    ratio), then the air-damped net against the chosen damping."""
    lines = []
    for name, net in result["nets"].items():
        shots = net["shots"]
        sleep = [s["sleep_s"] for s in shots if math.isfinite(s["sleep_s"])]
        zeta = [s["damping_ratio"] for s in shots if math.isfinite(s["damping_ratio"])]
        model = [s["damping_ratio_model"] for s in shots if math.isfinite(s["damping_ratio_model"])]
        asleep = (f"asleep after {np.mean(sleep):.2f} s on average ({len(sleep)} of {len(shots)} shots)" if sleep
                  else f"none of {len(shots)} shots asleep within {net['max_s']:g} s")
        lines.append(f"{name} (air damping {net['air_damping_per_s']:g}/s): {asleep}, net CPU "
                     f"{np.mean([s['net_cpu_s'] for s in shots]):.2f} s a shot, damping ratio "
                     f"{np.mean(zeta) if zeta else math.nan:.4f} measured, {np.mean(model) if model else math.nan:.4f} "
                     "model")
    c = result["air_against_chosen"]
    chosen, air = c["air_damping_per_s"]
    lines.append(f"air drag alone ({air:g}/s) against the chosen {chosen:g}/s, mean over {c['shots']} shots: "
                 f"{c['awake_ticks_ratio']:.1f}x the awake ticks, {c['net_cpu_ratio']:.1f}x the net's CPU, "
                 f"{c['peak_deflection_ratio']:.2f}x the peak deflection, {c['energy_absorbed_ratio']:.2f}x the "
                 f"energy absorbed ({c['asleep'][1]} of {c['shots']} asleep, against {c['asleep'][0]})")
    return lines


def _report(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(Console().width, 140))  # twelve columns: wider than a pipe's default 80
    table = Table("net", "air 1/s", "point", "m/s", "asleep s", "awake ticks", "net CPU s", "peak mm", "absorbed mJ",
                  "ring Hz", "zeta", "zeta model")
    for name, net in result["nets"].items():
        for shot in net["shots"]:
            asleep = f"{shot['sleep_s']:.2f}" if math.isfinite(shot["sleep_s"]) else f"> {shot['stepped_s']:g}"
            table.add_row(name, f"{net['air_damping_per_s']:g}", shot["point"], f"{shot['speed_m_s']:g}", asleep,
                          str(shot["awake_ticks"]), f"{shot['net_cpu_s']:.2f}",
                          f"{shot['peak_deflection_m'] * 1e3:.1f}", f"{shot['energy_absorbed_J'] * 1e3:.1f}",
                          f"{shot['ring_frequency_hz']:.1f}", f"{shot['damping_ratio']:.4f}",
                          f"{shot['damping_ratio_model']:.4f}")
    console.print(table)
    console.print(f"kernels compiled or loaded in {result['compile_s']:.1f} s, apart from every shot's net CPU")
    for line in summary_lines(result):
        console.print(f"- {line}")


STUDY = Study(run=quick_only(study), report=_report, quick="fewer shots, the air-damped net stopped awake")

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.ringdown", "ringdown"))
