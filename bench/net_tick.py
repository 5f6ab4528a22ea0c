"""µs per net tick (NetSim.step, 1 ms) for several net sizes: awake, ball near, impact; full / culled sweep loop / NetSim.

Run: `python -m bench.net_tick [--ticks 200] [--json]` (tick_costs): a whole NetSim tick, kernels
plus NetSim's Python, as the net worker pays it.
"""
import argparse
import json
import os
import statistics
import time

import numpy as np

from bench.net_costs import REPEATS, TICK_S, moving_state
from net_kernel import kernels
from net_kernel.sim import NetSim
from net_kernel.topology import NetSpec, build_topology

NEAR_BALL_POS = (-0.03, 0.0, 0.08)  # m: 3 cm in front of the net's plane at mid-height: near, not touching
NEAR_BALL_VEL = (0.0, 2.0, 0.0)  # m/s: along the net, so it stays near without contact
IMPACT_BALL_POS = (-0.05, 0.0, 0.08)  # m: bench/net.py's standard impact
IMPACT_BALL_VEL = (15.0, 0.0, 0.0)  # m/s
IMPACT_TICKS = 20
BALL_MASS = 2.7e-3  # kg, ITTF 2.3


def _net_sim(cols: int, rows: int, sweep: str):
    """A perturbed, moving NetSim of a cols x rows default-cloth net (knot_mass = 0.05 kg / knots).

    sweep: "netsim", NetSim as it is; "full" / "culled", NetSim's per-substep loop with
    kernels.collide_ball / collide_ball_near (private hooks set here: a benchmark's baselines,
    whichever contact call NetSim itself makes).
    """
    topo = build_topology(NetSpec(cols=cols, rows=rows, knot_mass=0.05 / (cols * rows)))
    sim = NetSim(topo, dt=TICK_S)
    pos, vel, _, _ = moving_state(topo)
    sim.knot_pos[:] = pos
    sim.knot_vel[:] = vel
    if sweep == "netsim":
        return sim
    passes_near = hasattr(sim, "_near")  # NetSim already hands collide_ball_near its scratch
    sim._step_grid_tick = None  # noqa: SLF001 (the per-substep loop, not a one-call tick)
    if sweep == "culled":
        near = np.zeros(topo.n_knots, dtype=np.int64)
        sim._collide = (kernels.collide_ball_near if passes_near  # noqa: SLF001
                        else lambda *args: kernels.collide_ball_near(*args, near))
    else:
        sim._collide = (lambda *args: kernels.collide_ball(*args[:13])) if passes_near else kernels.collide_ball  # noqa: SLF001
    return sim


def _time_ticks(sim, case: str, ticks: int, clock=time.perf_counter) -> float:
    """s per tick of `ticks` ticks of one case: "awake" (no ball), "near" (ball near, no contact), "impact"."""
    start_state = (sim.knot_pos.copy(), sim.knot_vel.copy())
    if case == "impact":
        total = 0.0
        for _ in range(max(1, ticks // IMPACT_TICKS)):
            sim.knot_pos[:], sim.knot_vel[:] = start_state
            bp, bv = np.array(IMPACT_BALL_POS), np.array(IMPACT_BALL_VEL)
            t0 = clock()
            for _ in range(IMPACT_TICKS):
                contact = sim.step(bp, bv, 0.02, 1.0 / BALL_MASS)
                bp = bp + bv * TICK_S + contact.offset
                bv = bv + contact.impulse / BALL_MASS
            total += clock() - t0
        return total / (max(1, ticks // IMPACT_TICKS) * IMPACT_TICKS)
    bp, bv = np.array(NEAR_BALL_POS), np.array(NEAR_BALL_VEL)
    t0 = clock()
    for _ in range(ticks):
        sim.wake()  # measured awake: the sleep rules are NetSim's
        if case == "near":
            sim.step(bp, bv, 0.02, 1.0 / BALL_MASS)
        else:
            sim.step()
    return (clock() - t0) / ticks


SWEEPS = ("full", "culled", "netsim")


def tick_costs(sizes=((184, 16), (92, 8), (70, 7)), ticks: int = 200, repeats: int = REPEATS,
               clock: str = "thread") -> dict:
    """µs per NetSim tick (1 ms) for each net size: awake with the ball away, ball near, an impact.

    Three ways to sweep the ball's contact (_net_sim): NetSim's per-substep loop with the full
    sweep ("full") or the culled one ("culled"), and NetSim as it is ("netsim").

    clock: "thread" (CPU time of this thread, time.thread_time: what the tick costs its core,
    steadier on a shared machine, where waiting for a core is not the net's cost; NetSim below
    PARALLEL_MIN_KNOTS knots runs on this one thread) or "wall" (time.perf_counter).

    Every case runs `repeats` times, interleaved between the two sweeps, each from the same
    perturbed state after an untimed warm-up run (kernels compiled or loaded first); the median is
    reported. "near": the ball 3 cm in front of the net, running along it (a contact sweep
    every substep, no contact); "impact": bench/net.py's 15 m/s ball into the net's centre,
    IMPACT_TICKS ticks from 5 cm away.
    """
    if clock not in ("thread", "wall"):
        raise ValueError(f"clock {clock!r} is not 'thread' or 'wall'")
    timer = time.thread_time if clock == "thread" else time.perf_counter
    rows_out = []
    for cols, rows in sizes:
        sims = {sweep: _net_sim(cols, rows, sweep) for sweep in SWEEPS}
        entry = {"cols": cols, "rows": rows, "knots": cols * rows, "substeps": sims["full"].substeps}
        for case in ("awake", "near", "impact"):
            runs = {sweep: [] for sweep in SWEEPS}
            for sweep, sim in sims.items():
                state = (sim.knot_pos.copy(), sim.knot_vel.copy())
                _time_ticks(sim, case, min(ticks, IMPACT_TICKS))  # warm-up
                sim.knot_pos[:], sim.knot_vel[:] = state
            for _ in range(repeats):
                for sweep, sim in sims.items():
                    state = (sim.knot_pos.copy(), sim.knot_vel.copy())
                    runs[sweep].append(_time_ticks(sim, case, ticks, timer))
                    sim.knot_pos[:], sim.knot_vel[:] = state
            for sweep in runs:
                entry[f"{case}_{sweep}_us"] = statistics.median(runs[sweep]) * 1e6
        rows_out.append(entry)
    return {"tick_s": TICK_S, "ticks": ticks, "repeats": repeats, "clock": clock, "load_avg": os.getloadavg()[0],
            "rows": rows_out}



def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--ticks", type=int, default=200, help="ticks per timed run")
    parser.add_argument("--sizes", default="184x16,92x8,70x7", help="nets, COLSxROWS, comma-separated")
    parser.add_argument("--clock", choices=("thread", "wall"), default="thread",
                        help="thread: CPU time of the stepping thread; wall: elapsed time")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    report = tick_costs(sizes=sizes, ticks=args.ticks, clock=args.clock)
    if args.json:
        print(json.dumps(report))
        return
    print(f"µs per 1 ms net tick, {report['clock']} clock (median of {report['repeats']} runs of {report['ticks']} "
          f"ticks; load average {report['load_avg']:.2f}); NetSim's substep loop with the full / the culled contact "
          "sweep / NetSim as it is")
    print(f"  {'net':>7} {'knots':>6} {'substeps':>8} {'awake':>20} {'ball near':>20} {'impact':>20}")
    for r in report["rows"]:
        cells = [" / ".join(f"{r[f'{c}_{sweep}_us']:.0f}" for sweep in SWEEPS) for c in ("awake", "near", "impact")]
        print(f"  {r['cols']}x{r['rows']:<3} {r['knots']:>6} {r['substeps']:>8} {cells[0]:>20} {cells[1]:>20} "
              f"{cells[2]:>20}")


if __name__ == "__main__":
    main()
