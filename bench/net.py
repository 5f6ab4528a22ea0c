"""The net's part of the accuracy study: explicit substepped cloth against the implicit solver.

A standard ball impact: a 15 m/s ball, no spin, straight at the centre of the default net
(net_kernel.NetSpec: 184 x 16 knots), coupled as net_kernel.NetSim.step asks (the ball moves in a
straight line over the tick, bent by the net's impulses). The quantity is the net's deflection:
the x displacement of the knot nearest the impact point over the first DURATION seconds. The
reference is the semi-implicit (symplectic Euler) solver at REFERENCE_SUBSTEPS substeps a tick,
8x more than its stability bound needs. Errors: the peak deflection's, and the largest
difference over time. Cost: wall seconds per simulated second of NetSim.step, the kernels
compiled first (one warm-up tick), one timed run each (the implicit runs take seconds).
"""
from __future__ import annotations

import time

import numpy as np

from net_kernel import IMPLICIT, SEMI_IMPLICIT, NetSim, NetSpec, build_topology

DT = 1e-3  # s: the engine's match tick
DURATION = 0.02  # s: the ball meets the net after ~3 ms and the bulge peaks within ~10 ms
BALL_POS = (-0.05, 0.0, 0.08)  # m: 5 cm in front of the net, at mid-height
BALL_VEL = (15.0, 0.0, 0.0)  # m/s
BALL_MASS = 2.7e-3  # kg (ITTF 2.3)
REFERENCE_SUBSTEPS = 200
CONFIGS = ((SEMI_IMPLICIT, None), (SEMI_IMPLICIT, 50), (SEMI_IMPLICIT, 100), (IMPLICIT, 1), (IMPLICIT, 4),
           (IMPLICIT, 64))


def impact(solver: str, substeps: int | None, duration: float = DURATION) -> dict:
    """One standard impact: (n_ticks + 1,) deflection m, wall s of the ticks, substeps, CG iterations."""
    topo = build_topology(NetSpec(solver=solver))
    centre = int(np.argmin(np.linalg.norm(topo.knot_pos - [0.0, BALL_POS[1], BALL_POS[2]], axis=1)))
    NetSim(topo, DT, substeps).step(np.array(BALL_POS), np.array(BALL_VEL))  # compile or load the kernels
    sim = NetSim(topo, DT, substeps)
    ball_pos, ball_vel = np.array(BALL_POS), np.array(BALL_VEL)
    n = int(round(duration / DT))
    x0 = float(sim.knot_pos[centre, 0])
    deflection = np.zeros(n + 1)
    start = time.perf_counter()
    for k in range(n):
        contact = sim.step(ball_pos, ball_vel)
        ball_pos = ball_pos + ball_vel * DT + contact.offset
        ball_vel = ball_vel + contact.impulse / BALL_MASS
        deflection[k + 1] = sim.knot_pos[centre, 0] - x0
    wall = time.perf_counter() - start
    return {"deflection": deflection, "wall": wall, "substeps": sim.substeps, "cg_iterations": sim.cg_iterations,
            "ball_vel_x_after": float(ball_vel[0])}


def study(progress=None) -> dict:
    """Every configuration against the reference; JSON-ready."""
    say = progress or (lambda _msg: None)
    say(f"net: reference, semi-implicit at {REFERENCE_SUBSTEPS} substeps a tick")
    ref = impact(SEMI_IMPLICIT, REFERENCE_SUBSTEPS)
    rows = []
    for solver, substeps in CONFIGS:
        say(f"net: {solver}, substeps {substeps or 'from the stability bound'}")
        run = impact(solver, substeps)
        rows.append({
            "solver": solver, "substeps": run["substeps"], "auto_substeps": substeps is None,
            "peak_deflection_m": float(run["deflection"].max()),
            "peak_error_m": float(abs(run["deflection"].max() - ref["deflection"].max())),
            "max_error_m": float(np.max(np.abs(run["deflection"] - ref["deflection"]))),
            "wall_s_per_sim_s": run["wall"] / DURATION, "cg_iterations": run["cg_iterations"],
            "ball_vel_x_after": run["ball_vel_x_after"],
        })
    return {"dt": DT, "duration": DURATION, "ball_vel": BALL_VEL, "reference_substeps": REFERENCE_SUBSTEPS,
            "reference_peak_m": float(ref["deflection"].max()), "reference_wall_s_per_sim_s": ref["wall"] / DURATION,
            "rows": rows}


def markdown(result: dict) -> str:
    lines = [f"Net: a {result['ball_vel'][0]:g} m/s ball into the centre of the default net (184 x 16 knots), "
             f"{result['dt'] * 1e3:g} ms ticks, {result['duration'] * 1e3:g} ms; reference semi-implicit at "
             f"{result['reference_substeps']} substeps a tick (peak deflection {result['reference_peak_m'] * 1e3:.1f} mm). "
             "One timed run each, kernels compiled first.", "",
             "| solver | substeps a tick | peak deflection mm | peak error mm | largest error over time mm | "
             "wall s per sim s | ball's x velocity after, m/s |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for row in result["rows"]:
        subs = f"{row['substeps']}" + (" (stability bound)" if row["auto_substeps"] else "")
        lines.append(f"| {row['solver']} | {subs} | {row['peak_deflection_m'] * 1e3:.2f} | {row['peak_error_m'] * 1e3:.2f} | "
                     f"{row['max_error_m'] * 1e3:.2f} | {row['wall_s_per_sim_s']:.2f} | {row['ball_vel_x_after']:.2f} |")
    return "\n".join(lines)
