"""`python -m bench.net_friction [--json] [--quick]`: what internal friction in the threads would do to
a struck net's ring, before any kernel carries it.

The net's only loss today is a chosen mass-proportional air damping (NetSpec.air_damping, 5/s),
20-60 times the air's own drag on its threads (NetSpec's comment: Lamb's low-Reynolds drag gives
0.08-0.3/s). A textile loses its energy to friction between fibres and at the crossings (Miguel et
al., "Modeling and Estimation of Internal Friction in Cloth", ACM TOG 32(6), 2013: a Dahl model
fitted to force-deformation loops). This study adds such friction to the match's net (85 x 8,
scenes/match.toml) and strikes it as `pingpong bench ringdown` does: a 20 m/s ball into its middle.

Friction elements (Dahl, P. R. Dahl, "A solid friction model", Aerospace Corp. TOR-0158(3107-18)-1,
1968, in its rate-independent first-order form dF = (F_s u - F) |ds| / e along a path s of
direction u; exact over a straight step, so |F| <= F_s holds at any step):

- bending: at every knot with two neighbours along its row (and along its column), the second
  difference b = x_prev - 2 x + x_next (a hinge; the quadratic bending measure of Bergou et al.,
  "A Quadratic Bending Model for Inextensible Surfaces", SGP 2006, on a regular grid) carries a
  vector friction force z: -z on the two ends, +2 z on the knot. Saturation F_s = M_s / a for a
  friction moment M_s per knot and cell a, presliding e = theta_s a for a presliding angle theta_s.
- stretch: every spring carries a scalar friction force along it, saturating at F_s over e.
- both with the LuGre micro-damping (Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE Trans. Autom.
  Control 40(3), 1995): sigma_1 dz/dt added while the element sticks, so a stuck element's stiff
  presliding spring does not ring on its own; here a time constant beta = sigma_1 / sigma_0.

The magnitudes: no measurement of a net's or a 0.5-1 mm cord's friction was found. KES-FB2 bending
hysteresis of fabrics, 2HB = 0.007-0.124 gf cm/cm (Matsudaira et al., J. Textile Eng. 61(6), 2015,
Table 1), is HB = 3.4e-5 to 6.1e-4 N m/m; spread over a ~4000 yarns/m fabric and scaled to a
0.5-1 mm cord by the cube of its diameter, M_s ~ 2e-6 to 2e-5 N m a knot; the curvature over which
a KES loop reverses, ~0.3 /cm on 0.1 mm yarns, is a presliding angle of ~0.15 rad on a 2.2 cm cell.
KNOT is that estimate (1e-5 N m, 0.15 rad); KNOT_HIGH four times the moment over a presliding angle
thirty times smaller (a sharper, Coulomb-like stick); STRETCH adds a stretch friction of a sixth of
the mesh's tension (a knit returns about half its loading work on unloading, Poincloux et al.,
Phys. Rev. X 8, 021075, 2018, which for a Coulomb element in series with a spring means a friction
force of a sixth of the peak elastic force).

The friction pass runs after each substep of the kernels (operator splitting, first order in the
substep); it is a study, not the engine's model: NetSim's own steps, contact and sleep rule are used
unchanged.
"""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace

import numpy as np
from numba import njit

from net_kernel import NetSim, build_topology
from net_kernel.sim import BALL_MASS, SLEEP_SPEED, SLEEP_TICKS
from net_kernel.topology import AIR_DAMPING_PHYSICAL, grid_spacings, resolution_spec

DT = 1e-3  # s, the engine's tick (scenes/match.toml)
SPEED = 20.0  # m/s, the ball into the middle of the net
AIM = (0.0, 0.10)  # (y, z) m
MARKS_S = (0.25, 0.5, 1.0, 2.0, 4.0)  # s: when the fastest knot's speed is reported
# (name, air damping 1/s, bending: M_s N m and theta_s rad, stretch: F_s N and e m, beta s)
CASES = (
    ("air damping 5/s (the engine today)", 5.0, 0.0, 0.15, 0.0, 1e-4, 1e-4),
    ("physical air drag only", AIR_DAMPING_PHYSICAL, 0.0, 0.15, 0.0, 1e-4, 1e-4),
    ("bending friction, knot estimate (KNOT)", AIR_DAMPING_PHYSICAL, 1e-5, 0.15, 0.0, 1e-4, 1e-4),
    ("bending friction x4, sharp stick (KNOT_HIGH)", AIR_DAMPING_PHYSICAL, 4e-5, 0.005, 0.0, 1e-4, 1e-4),
    ("KNOT_HIGH and stretch friction (STRETCH)", AIR_DAMPING_PHYSICAL, 4e-5, 0.005, 1.0 / 6.0, 1e-4, 1e-4),
)


@njit(cache=True)
def _dahl(z, d, norm, fs, e):
    """z (3,) moved along the step d (3,) of length norm: z <- F_s u + (z - F_s u) exp(-norm / e)."""
    a = math.exp(-norm / e)
    for k in range(3):
        u = d[k] / norm
        z[k] = fs * u + (z[k] - fs * u) * a


@njit(cache=True)
def friction_pass(p, v, inv_m, hinge_b, hinge_z, ij, spring_len, spring_z, fs_b, e_b, fs_s, e_s, beta, h, f):
    """One substep's friction impulse on v (n, 3) from the knots at p (rows, cols, 3) (a copy).

    hinge_b, hinge_z: (2, rows, cols, 3), the last second differences and friction forces of the
    row (0) and column (1) hinges; spring_len, spring_z: (n_springs,) the same for the springs;
    f: (rows, cols, 3) scratch. State is updated in place.
    """
    rows, cols = p.shape[0], p.shape[1]
    f[:] = 0.0
    d = np.empty(3)
    zo = np.empty(3)
    if fs_b > 0.0:
        for axis in range(2):
            for r in range(1 if axis else 0, rows - 1 if axis else rows):
                for c in range(0 if axis else 1, cols if axis else cols - 1):
                    r0, c0, r1, c1 = (r - 1, c, r + 1, c) if axis else (r, c - 1, r, c + 1)
                    for k in range(3):
                        b = p[r0, c0, k] - 2.0 * p[r, c, k] + p[r1, c1, k]
                        d[k] = b - hinge_b[axis, r, c, k]
                        hinge_b[axis, r, c, k] = b
                        zo[k] = hinge_z[axis, r, c, k]
                    norm = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                    z = hinge_z[axis, r, c]
                    if norm > 0.0:
                        _dahl(z, d, norm, fs_b, e_b)
                    for k in range(3):
                        q = z[k] + beta * (z[k] - zo[k]) / h
                        f[r0, c0, k] -= q
                        f[r, c, k] += 2.0 * q
                        f[r1, c1, k] -= q
    pf = p.reshape(-1, 3)
    ff = f.reshape(-1, 3)
    if fs_s > 0.0:
        for s in range(ij.shape[0]):
            i, j = ij[s, 0], ij[s, 1]
            for k in range(3):
                d[k] = pf[j, k] - pf[i, k]
            length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            step = length - spring_len[s]
            spring_len[s] = length
            old = spring_z[s]
            if step != 0.0:
                sign = 1.0 if step > 0.0 else -1.0
                spring_z[s] = fs_s * sign + (old - fs_s * sign) * math.exp(-abs(step) / e_s)
            t = (spring_z[s] + beta * (spring_z[s] - old) / h) / length
            for k in range(3):
                ff[i, k] += t * d[k]
                ff[j, k] -= t * d[k]
    for i in range(v.shape[0]):
        for k in range(3):
            v[i, k] += h * inv_m[i] * ff[i, k]


def strike(air: float, moment: float, angle: float, stretch: float, slip: float, beta: float,
           duration: float) -> dict:
    """A 20 m/s ball into the middle of the 85 x 8 net with the given air damping and friction."""
    spec = replace(resolution_spec(85, 8), air_damping=air)
    topo = build_topology(spec)
    rows, cols = spec.rows, spec.cols
    a, _ = grid_spacings(spec)
    substeps = NetSim(topo, DT).substeps
    h = DT / substeps
    sim = NetSim(topo, h, substeps=1)  # one substep a call: the friction pass runs between them
    p = np.ascontiguousarray(sim.knot_pos).reshape(rows, cols, 3)
    hinge_b = np.zeros((2, rows, cols, 3))
    hinge_b[0, :, 1:-1] = p[:, :-2] - 2.0 * p[:, 1:-1] + p[:, 2:]
    hinge_b[1, 1:-1] = p[:-2] - 2.0 * p[1:-1] + p[2:]
    hinge_z = np.zeros((2, rows, cols, 3))
    ij = topo.spring_ij.astype(np.int64)
    spring_len = np.linalg.norm(topo.rest_pos[ij[:, 1]] - topo.rest_pos[ij[:, 0]], axis=1)
    spring_z = np.zeros(ij.shape[0])
    scratch = np.zeros((rows, cols, 3))
    fs_b, e_b, fs_s = moment / a, angle * a, stretch * spec.mesh_tension
    pos, vel = np.array([-0.05, AIM[0], AIM[1]]), np.array([SPEED, 0.0, 0.0])
    quiet, asleep, marks = 0, math.inf, {}
    for tick in range(round(duration / DT)):
        for _ in range(substeps):
            contact = sim.step(pos, vel)
            pos = pos + vel * h + contact.offset
            vel = vel + contact.impulse / BALL_MASS
            knots = np.ascontiguousarray(sim.knot_pos).reshape(rows, cols, 3)
            knot_vel = np.ascontiguousarray(sim.knot_vel)
            friction_pass(knots, knot_vel, topo.knot_inv_mass, hinge_b, hinge_z, ij, spring_len, spring_z, fs_b,
                          e_b, fs_s, slip, beta, h, scratch)
            sim.knot_vel[:] = knot_vel
            sim.wake()  # the sleep rule is applied per tick below, as NetSim applies it
        top = float(np.sqrt((sim.knot_vel ** 2).sum(axis=1)).max())
        t = (tick + 1) * DT
        for mark in MARKS_S:
            if abs(t - mark) < DT / 2:
                marks[f"{mark:g}"] = top
        quiet = quiet + 1 if top < SLEEP_SPEED else 0
        if quiet >= SLEEP_TICKS and abs(pos[0]) > 0.3:
            asleep = t
            break
    return {"asleep_s": asleep if math.isfinite(asleep) else None, "fastest_knot_m_s": marks,
            "ball_back_m_s": float(-vel[0]),
            "rest_deviation_m": float(np.abs(sim.knot_pos - topo.rest_pos).max()),
            "friction": {"moment_N_m": moment, "presliding_angle_rad": angle, "hinge_saturation_N": fs_b,
                         "hinge_presliding_m": e_b, "stretch_saturation_N": fs_s, "stretch_presliding_m": slip,
                         "micro_damping_s": beta}, "air_damping_per_s": air}


def study(quick: bool = False) -> dict:
    """Every case of CASES over 4 s (quick: the first two over 0.3 s)."""
    cases = CASES[:2] if quick else CASES
    duration = 0.3 if quick else max(MARKS_S)
    return {"speed_m_s": SPEED, "dt_s": DT, "duration_s": duration,
            "cases": {name: strike(*params, duration=duration) for name, *params in cases}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--quick", action="store_true", help="two cases over 0.3 s (a smoke run)")
    parser.add_argument("--case", nargs=4, type=float, metavar=("MOMENT", "ANGLE", "STRETCH", "AIR"),
                        help="one case instead of CASES: bending friction moment N m a knot, presliding angle rad, "
                             "stretch friction as a fraction of the mesh tension, air damping 1/s")
    parser.add_argument("--duration", type=float, default=max(MARKS_S), help="s of ring per case (default 4)")
    args = parser.parse_args(argv)
    if args.case:
        moment, angle, stretch, air = args.case
        if not (moment >= 0 and angle > 0 and stretch >= 0 and air >= 0 and args.duration > 0):
            parser.error(f"--case {' '.join(map(str, args.case))} --duration {args.duration}: the moment, stretch "
                         "and air damping must be >= 0, the angle and the duration > 0")
        name = f"moment {moment:g} N m, angle {angle:g} rad, stretch {stretch:g}, air {air:g}/s"
        result = {"speed_m_s": SPEED, "dt_s": DT, "duration_s": args.duration,
                  "cases": {name: strike(air, moment, angle, stretch, CASES[0][5], CASES[0][6], args.duration)}}
    else:
        result = study(args.quick)
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    for name, case in result["cases"].items():
        speeds = " ".join(f"{t} s {v * 1e3:.0f}" for t, v in case["fastest_knot_m_s"].items())
        asleep = case["asleep_s"]
        sleep = f"asleep at {asleep:.2f} s" if asleep is not None else f"awake at {result['duration_s']:g} s"
        print(f"{name}: {sleep}; fastest knot (mm/s): {speeds}; ball back at {case['ball_back_m_s']:.2f} m/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
