"""The stability suite: hard cases that try to break the engine, and what "survived" means.

Each case is a scene run tick by tick while the suite measures, after every tick:
- finite: every number of the ball's state (and the cloth net's knots) stays finite;
- penetration: how far the ball's surface is inside any static body (table, floor, net, posts),
  any bat (squeeze cases excepted, where the bat is meant to yield) or any knot of a cloth net;
- tunnelled: the ball's centre changed side of a thin body (bat face, rigid net, the cloth
  net's sheet where the ball is) within its outline without a contact with it;
- energy: the mechanical energy of the ball (kinetic, rotational, potential) plus, with a
  cloth net, the net's (kinetic, spring, gravity) above its rest state; the gain is its largest
  rise over the start, checked for cases where nothing moves or pushes the ball, the change is
  end minus start; both relative to the start's value.
A case passes when its own expectations hold (events it must see, where the ball must end).
Refused inputs (NaN, zero-length ticks, degenerate nets...) are cases too: they must be refused
with a message.

Stiff-net cases (NetCase) step the cloth net alone, kicked out of its rest shape, at ticks of a
given multiple of the explicit stability bound h_max (net_kernel.topology.stability_bound):
through a scene, where the engine derives the substeps or uses the implicit solver, or with one
step per tick forced (net_kernel.NetSim(substeps=1)), which must be refused above the bound.
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from engine.physics import equipment
from engine.physics.bat import face_normal
from engine.physics.geometry import NET_BOX, POST_BOXES, TABLE_BOX, Body, box_sdf, disc_sdf
from engine.physics.scene import SceneError, parse_scene
from engine.physics.world import Model, SimulationError, State, build_model, initial_state, new_events, step
from net_kernel import IMPLICIT, NetSim, NetSpec, NetTopology, build_topology
from net_kernel.sim import KNOT_RADIUS
from net_kernel.topology import grid_spacings

R = equipment.BALL_RADIUS
PENETRATION_TOL = 1e-6  # m: contacts are resolved to CONTACT_TOL = 1 um
ENERGY_TOL = 1e-9  # relative: round-off over thousands of ticks
# m/s: the fastest ball a scene allows. The cloth's contact projects knots onto the ball's surface
# once per substep h; in between, the springs carry a struck knot at most about this fast into
# the ball, so a knot inside it by more than FASTEST_BALL * h is a failure.
FASTEST_BALL = equipment.BALL_SPEED_MAX
# Symplectic Euler keeps a modified energy; the true one oscillates about it (at most 19x for a
# mode at 0.9 of the bound in linear theory, observed 1.05 E0: tests/net_kernel/test_stability.py
# holds 10 %, and so does the suite).
NET_EXPLICIT_ENERGY_TOL = 0.10
# Backward Euler dissipates; the slack covers the CG solve's stop at a 1e-8 relative residual.
NET_IMPLICIT_ENERGY_TOL = 1e-9
# m: a net put to sleep (20 ticks with every knot under 1 mm/s) keeps the shape it had then: for its
# slowest sway (~5 Hz) that is within A w^2 x 10 ms < 1 mm/s of a turning point, A < 0.1 mm; a
# settled shape more than 0.5 mm further off the rest shape than the first settled one is drift.
REST_DRIFT_TOL = 5e-4
# A net tied to the table (NetSpec.fix_table) has more rest shapes than the flat one it is built
# in: the columns' springs take the net's weight in compression near the table and buckle into a
# zig-zag of the lowest rows, up to 2.4 mm (184 x 16) or 3 mm (64 x 8) either way, in patterns
# that differ from hit to hit. So drift is measured as the growth of the settled net's offset
# from the rest shape over the first settled offset, and the distinct shapes are counted; the
# hanging net (the default) has one rest shape and returns to it.
ALL = ["gravity", "drag", "magnus", "friction"]


@dataclass
class Case:
    name: str
    scene: dict
    ticks: int
    expect: Callable[["Outcome"], str | None] = lambda o: None  # None = fine, else what failed
    bat_yields: bool = False  # squeeze cases: the bat yields (through the ball, or stopped by the cloth net holding it)
    conserves: bool = False  # nothing moves or pushes the ball: its energy must not rise
    long: bool = False  # run by `make test-long` / `--long`, not in the default suite
    ci: bool = True  # in the suite's tests (tests/engine/test_stability.py); False: the CLI only (slow)
    loop: int = 0  # > 0: every `loop` ticks the ball and bats start over, the net keeps its state
    settles: bool = False  # a cloth net must be at rest (asleep) at the end (of every loop)
    known: str = ""  # a failure reported and not fixed yet: why (the CLI and the tests expect it)


# Modes of a stiff-net case.
SUBSTEPPED = "substepped"  # the scene's tick; the engine derives the substeps from h_max
FIXED = "fixed"  # one explicit step per tick forced: refused above h_max
IMPLICIT_MODE = "implicit"  # the scene asks for the implicit solver (backward Euler, CG)


@dataclass
class NetCase:
    """A cloth net kicked out of its rest shape and stepped at `factor` times its explicit bound."""

    name: str
    net: dict  # the scene's [net] fields (kind = "cloth" is added)
    factor: float  # tick / h_max
    mode: str  # SUBSTEPPED, FIXED or IMPLICIT_MODE
    ticks: int
    kick: float = 0.5  # m/s, peak knot speed of the initial bulge
    long: bool = False
    ci: bool = True


@dataclass
class Outcome:
    case: str
    integrator: str
    dt: float
    ticks: int
    result: str  # "stable", "refused: ...", "failed: ..."
    finite: bool = True
    tunnelled: bool = False
    max_penetration_m: float = 0.0
    energy_gain: float = 0.0
    energy_change: float = 0.0
    max_abs_state: float = 0.0
    # Cloth net: max knot displacement of the settled net from its flat rest shape; for loop cases
    # (the net settles after every loop) how far that grew past the first loop's (drift), and the
    # number of settled shapes more than REST_DRIFT_TOL apart (the net has several, see above).
    rest_offset_m: float | None = None
    rest_drift_m: float | None = None
    rest_shapes: int = 0
    first_offset_m: float = 0.0
    events: list = field(default_factory=list)  # body ids of the contacts, in order
    final: np.ndarray | None = None
    wall_s: float = 0.0

    def as_dict(self) -> dict:
        return {"case": self.case, "integrator": self.integrator, "dt": self.dt, "ticks": self.ticks,
                "result": self.result, "finite": self.finite, "tunnelled": self.tunnelled,
                "max_penetration_m": self.max_penetration_m, "energy_gain": self.energy_gain,
                "energy_change": self.energy_change, "max_abs_state": self.max_abs_state,
                "rest_offset_m": self.rest_offset_m, "rest_drift_m": self.rest_drift_m,
                "rest_shapes": self.rest_shapes, "contacts": len(self.events), "wall_s": self.wall_s}


def _energy(y: np.ndarray, g: float) -> float:
    m = equipment.BALL_MASS
    inertia = equipment.BALL_INERTIA_FACTOR * m * R * R
    return 0.5 * m * float(y[3:6] @ y[3:6]) + 0.5 * inertia * float(y[6:9] @ y[6:9]) + m * g * float(y[2])


def _thin_side(state, model) -> list[float]:
    """Signed distance of the ball's centre to each thin body's mid-plane, NaN outside its outline."""
    p = state.ball["pos"][0]
    sides = []
    for b in range(len(state.bats)):
        axis = np.zeros(3)
        face_normal(state.bats["quat"][b], axis)
        d = p - state.bats["pos"][b]
        along = float(d @ axis)
        lateral = np.linalg.norm(d - along * axis)
        sides.append(along if lateral < model.scene.bats[b].radius else math.nan)
    if model.net is not None:
        inside = abs(p[1]) < NET_BOX[4] and 0.0 < p[2] < 2 * NET_BOX[5]
        sides.append(float(p[0]) if inside else math.nan)
    return sides


def net_energy(topo: NetTopology, knot_pos: np.ndarray, knot_vel: np.ndarray, gravity: float) -> float:
    """J: kinetic + spring + gravitational energy of the free knots (fixed knots never move).

    knot_pos, knot_vel: (n_knots, 3) m, m/s. Springs store 0.5 k (|L| - L_rest)^2, the potential of
    the kernel's spring force; the dashpots store nothing.
    """
    free = topo.knot_inv_mass > 0
    kinetic = 0.5 * float(np.sum(topo.knot_mass[free] * np.sum(knot_vel[free] ** 2, axis=1)))
    d = knot_pos[topo.spring_ij[:, 1]] - knot_pos[topo.spring_ij[:, 0]]
    stretch = np.sqrt(np.einsum("ij,ij->i", d, d)) - topo.spring_rest
    elastic = 0.5 * float(np.sum(topo.spring_k * stretch * stretch))
    potential = gravity * float(np.sum(topo.knot_mass[free] * knot_pos[free, 2]))
    return kinetic + elastic + potential


@functools.lru_cache(maxsize=16)
def rest_state(spec: NetSpec) -> tuple[np.ndarray, float]:
    """(knot_pos (n_knots, 3) m, energy J) of the net hanging at rest: its static equilibrium.

    A hanging net's is the one its topology was built with (NetTopology.rest_pos, where NetSim
    starts it). A net tied to the table is settled here with the implicit solver at 10 ms steps
    (backward Euler's fixed point is the equilibrium whatever the step; it gets there in a few
    steps where explicit substeps need a second of simulated sway), until no knot moves faster
    than 1 nm/s.
    """
    topo = build_topology(replace(spec, solver=IMPLICIT))
    if not spec.fix_table:
        return topo.rest_pos, net_energy(topo, topo.rest_pos, np.zeros_like(topo.rest_pos), spec.gravity)
    sim = NetSim(topo, 0.01)
    for _ in range(1000):
        sim.step()
        if np.abs(sim.knot_vel).max() < 1e-9:
            pos = sim.knot_pos.copy()
            pos.flags.writeable = False
            return pos, net_energy(topo, pos, np.zeros_like(pos), spec.gravity)
    raise RuntimeError(f"the net {spec} did not settle in 10 s of implicit steps")


def _kick(topo: NetTopology, speed: float) -> np.ndarray:
    """(n_knots, 3) m/s: a bulge along x, `speed` at the middle, zero at the fixed edges."""
    spec = topo.spec
    y = (topo.knot_pos[:, 1] + spec.width / 2) / spec.width
    z = topo.knot_pos[:, 2] / spec.height
    vel = np.zeros_like(topo.knot_pos)
    vel[:, 0] = speed * np.sin(math.pi * y) * np.sin(math.pi * np.clip(z, 0.0, 1.0) / 2) * (topo.knot_inv_mass > 0)
    return vel


def _settled_shape(out: Outcome, shapes: list, knot_pos: np.ndarray, rest_pos: np.ndarray) -> None:
    """Book the net's settled shape: its offset from the flat rest shape, the growth of that offset
    over the first settled one (drift), and whether it is a new shape (past REST_DRIFT_TOL from all
    in `shapes`)."""
    offset = float(np.abs(knot_pos - rest_pos).max())
    if not shapes:
        out.first_offset_m = offset
    out.rest_offset_m = max(out.rest_offset_m, offset)
    out.rest_drift_m = max(out.rest_drift_m, offset - out.first_offset_m)
    if min((float(np.abs(knot_pos - s).max()) for s in shapes), default=math.inf) > REST_DRIFT_TOL:
        shapes.append(knot_pos.copy())
    out.rest_shapes = len(shapes)


def _cloth_side(p: np.ndarray, knot_pos: np.ndarray, spec: NetSpec) -> float:
    """Signed x distance of the ball's centre from the cloth's sheet where the ball is (the mean
    of the knots within one mesh cell of it in y and z), NaN outside the net's outline."""
    if not (abs(p[1]) < spec.width / 2 and 0.0 < p[2] < spec.height):
        return math.nan
    col_spacing, row_spacing = grid_spacings(spec)
    near = (np.abs(knot_pos[:, 1] - p[1]) <= col_spacing) & (np.abs(knot_pos[:, 2] - p[2]) <= row_spacing)
    if not near.any():
        return math.nan
    return float(p[0] - knot_pos[near, 0].mean())


def _full_kernel(data: dict) -> dict:
    """A case's scene with its cloth net stepped by the full kernel on every awake tick: the suite
    proves the kernel in hard cases. The linear tail that takes over a quiet net's ring
    (NetSpec.tail_energy) is a closed form whose every mode decays (net_kernel/modes.py); a case
    that sets tail_energy keeps it."""
    net = data.get("net")
    if isinstance(net, dict) and net.get("kind") == "cloth" and "tail_energy" not in net:
        data["net"] = {**net, "tail_energy": 0.0}
    return data


def run_case(case: Case | NetCase) -> Outcome:
    """Run one case and judge it (Outcome.result)."""
    if isinstance(case, NetCase):
        return _run_net_case(case)
    started = time.perf_counter()
    data = _full_kernel(dict(case.scene))
    try:
        scene = parse_scene(data, f"stability:{case.name}")
        model = build_model(scene)
    except SceneError as exc:
        return Outcome(case.name, data.get("integrator", "verlet"), data.get("dt", 0.001), 0, f"refused: {exc}")
    state, events = initial_state(scene), new_events()
    start = state.record.copy()
    out = Outcome(case.name, scene.integrator, scene.dt, 0, "stable")
    g = model.gravity or 0.0
    net = state.net_sim
    if net is not None:
        out.integrator += f" + net {'implicit' if net.implicit else 'explicit'} x{net.substeps}"
        rest_pos, e_rest = rest_state(scene.cloth)
        net.knot_pos[:] = rest_pos  # the net starts hanging at rest
        knot_reach = R + net.knot_radius
        out.rest_offset_m = out.rest_drift_m = 0.0

    asleep = [math.nan]  # the net's energy while it sleeps (its knots do not move then)

    def energy() -> float:
        e = _energy(state.ball_flat, g)
        if net is not None:
            if not net.sleeping:
                asleep[0] = math.nan
                return e + net_energy(net.topo, net.knot_pos, net.knot_vel, net.gravity) - e_rest
            if math.isnan(asleep[0]):
                asleep[0] = net_energy(net.topo, net.knot_pos, net.knot_vel, net.gravity) - e_rest
            e += asleep[0]
        return e

    e0 = energy()
    knot_penetration = 0.0
    shapes, unsettled = [], []  # loop cases: the distinct shapes the net settled to; loops it was awake at the end
    sides = _thin_side(state, model)
    cloth_side = _cloth_side(state.ball_flat[0:3], net.knot_pos, scene.cloth) if net is not None else math.nan
    hit_bodies: set[int] = set()
    normal = np.zeros(3)
    try:
        for tick in range(case.ticks):
            if case.loop and tick and tick % case.loop == 0:
                if net is not None:
                    if case.settles and not net.sleeping:
                        unsettled.append(tick // case.loop)
                    _settled_shape(out, shapes, net.knot_pos, rest_pos)
                state.ball[0] = start["ball"][0]
                state.bats[:] = start["bats"][0]
                state.world["ball_support"] = start["world"]["ball_support"]
                state.world["ball_adapt"] = start["world"]["ball_adapt"]
                hit_bodies.clear()
                sides = _thin_side(state, model)
                cloth_side = _cloth_side(state.ball_flat[0:3], net.knot_pos, scene.cloth) if net is not None else math.nan
            n = step(model, state, None, events)
            out.ticks = tick + 1
            for k in range(n):
                out.events.append(int(events[k]["body"]))
                hit_bodies.add(int(events[k]["body"]))
            y = state.ball_flat
            out.max_abs_state = max(out.max_abs_state, float(np.abs(y).max()))
            p = y[0:3]
            gaps = _body_gaps(model, state, p, normal, with_bats=not case.bat_yields)
            if gaps:
                out.max_penetration_m = max(out.max_penetration_m, -min(gaps))
            if net is not None:
                kp = net.knot_pos
                if not net.sleeping:  # asleep, the knots keep their place and the ball is far
                    d = kp - p
                    knot_gap = math.sqrt(float(np.einsum("ij,ij->i", d, d).min())) - knot_reach
                    knot_penetration = max(knot_penetration, -knot_gap)
                    out.max_abs_state = max(out.max_abs_state, float(np.abs(kp).max()), float(np.abs(net.knot_vel).max()))
                # The centre on the other side of the sheet from one tick to the next: through the net.
                now = _cloth_side(p, kp, scene.cloth)
                if not math.isnan(cloth_side) and not math.isnan(now) and cloth_side * now < 0:
                    out.tunnelled = True
                cloth_side = now
            if case.conserves or case.loop:
                # Loop cases: each loop starts the ball over, the net from where it settled (at or
                # below its rest energy), so no tick may hold more energy than the first loop's start.
                out.energy_gain = max(out.energy_gain, (energy() - e0) / max(abs(e0), 1e-12))
            now = _thin_side(state, model)
            for k, (before, after) in enumerate(zip(sides, now)):
                body = Body.BAT_A + k if k < len(state.bats) else Body.NET
                if not math.isnan(before) and not math.isnan(after) and before * after < 0 and body not in hit_bodies:
                    out.tunnelled = True
            sides = now
    except SimulationError as exc:
        out.finite = "non-finite" not in str(exc)
        out.result = f"refused: {exc}"
        out.wall_s = time.perf_counter() - started
        return out
    except FloatingPointError as exc:  # the net's own finiteness check (net_kernel.NetSim.step)
        out.finite = False
        out.result = f"failed: tick {out.ticks}: {exc}"
        out.wall_s = time.perf_counter() - started
        return out
    out.energy_change = (energy() - e0) / max(abs(e0), 1e-12)
    out.final = state.ball_flat.copy()
    if net is not None:
        _settled_shape(out, shapes, net.knot_pos, rest_pos)
    _judge(out, case, net, knot_penetration, unsettled)
    out.wall_s = time.perf_counter() - started
    return out


def _body_gaps(model: Model, state: State, p: np.ndarray, normal: np.ndarray, with_bats: bool) -> list[float]:
    """Gaps (m, negative inside) between the ball at p and each rigid body of the model, the bats'
    faces too when with_bats; normal: (3,) scratch."""
    gaps = [box_sdf(p, TABLE_BOX, normal) - R] if model.table is not None else []
    if model.net is not None:
        gaps.append(box_sdf(p, NET_BOX, normal) - R)
    if model.posts is not None:
        gaps += [box_sdf(p, post, normal) - R for post in POST_BOXES]
    if model.floor_z is not None:
        gaps.append(p[2] - model.floor_z - R)
    if with_bats:
        for b in range(len(state.bats)):
            axis = np.zeros(3)
            face_normal(state.bats["quat"][b], axis)
            gaps.append(disc_sdf(p, state.bats["pos"][b], axis, model.scene.bats[b].radius,
                                 model.scene.bats[b].half_thickness, normal) - R)
    return gaps


def _judge(out: Outcome, case: Case, net: NetSim | None, knot_penetration: float, unsettled: list[int]) -> None:
    """Set out.result from a finished case's measures: "stable", or "failed: " and each problem."""
    problems = []
    if out.max_penetration_m > PENETRATION_TOL:
        problems.append(f"penetration {out.max_penetration_m:.2e} m > {PENETRATION_TOL:g}")
    if net is not None:
        knot_tol = FASTEST_BALL * net.h
        if knot_penetration > knot_tol:
            problems.append(f"a knot {knot_penetration:.2e} m inside the ball > {knot_tol:.2g} (60 m/s x substep)")
        out.max_penetration_m = max(out.max_penetration_m, knot_penetration)
        if case.settles and not net.sleeping:
            unsettled.append(case.ticks // max(case.loop, 1))
        if unsettled:
            problems.append(f"the cloth net still moves at the end of loop(s) {unsettled[:5]}")
        if out.rest_drift_m > REST_DRIFT_TOL:
            problems.append(f"the settled net drifted: {out.rest_offset_m:.2e} m off its rest shape, "
                            f"{out.first_offset_m:.2e} after the first loop (> {REST_DRIFT_TOL:g} more)")
        if case.loop and out.energy_gain > ENERGY_TOL:
            problems.append(f"energy rose {out.energy_gain:.2e} above a loop's start (> {ENERGY_TOL:g})")
    if out.tunnelled:
        problems.append("tunnelled through a thin body")
    if case.conserves and out.energy_gain > ENERGY_TOL:
        problems.append(f"energy gain {out.energy_gain:.2e} > {ENERGY_TOL:g}")
    expectation = case.expect(out)
    if expectation:
        problems.append(expectation)
    if problems:
        out.result = "failed: " + "; ".join(problems)


_BALL_FAR = (-1.0, 0.0, R)  # m: at rest on the table, out of the net's reach


def _run_net_case(case: NetCase) -> Outcome:
    """Kick the net out of its rest shape and step it `case.ticks` ticks; judge energy and finiteness."""
    started = time.perf_counter()
    net = {"kind": "cloth", **case.net}
    if case.mode == IMPLICIT_MODE:
        net["solver"] = IMPLICIT
    data = _full_kernel({"effects": ["gravity", "net", "table"], "ball": _ball(_BALL_FAR), "net": net})
    label = "net implicit" if case.mode == IMPLICIT_MODE else "net explicit"
    source = f"stability:{case.name}"
    try:
        spec = parse_scene(data, source).cloth
    except SceneError as exc:
        return Outcome(case.name, label, 0.0, 0, f"refused: {exc}")
    topo = build_topology(spec)
    dt = case.factor * topo.h_max
    out = Outcome(case.name, label, dt, 0, "stable")
    try:
        if case.mode == FIXED:
            sim = NetSim(topo, dt, substeps=1)
            advance_one = sim.step
        else:
            scene = parse_scene({**data, "dt": dt}, source)
            model, state, events = build_model(scene), initial_state(scene), new_events()
            sim = state.net_sim
            def advance_one():
                step(model, state, None, events)
    except (SceneError, ValueError) as exc:
        out.result = f"refused: {exc}"
        if case.factor <= 1.0 or "h_max" not in str(exc):
            out.result = f"failed: refused without naming the bound h_max: {exc}"
        out.wall_s = time.perf_counter() - started
        return out
    out.integrator += f" x{sim.substeps}"
    rest_pos, e_rest = rest_state(spec)
    sim.knot_pos[:] = rest_pos
    sim.knot_vel[:] = _kick(topo, case.kick)
    e0 = net_energy(topo, sim.knot_pos, sim.knot_vel, spec.gravity) - e_rest
    previous, rise = e0, 0.0
    try:
        for tick in range(case.ticks):
            advance_one()
            out.ticks = tick + 1
            e = net_energy(topo, sim.knot_pos, sim.knot_vel, spec.gravity) - e_rest
            out.energy_gain = max(out.energy_gain, (e - e0) / e0)
            rise = max(rise, (e - previous) / e0)
            previous = e
            out.max_abs_state = max(out.max_abs_state, float(np.abs(sim.knot_pos).max()),
                                    float(np.abs(sim.knot_vel).max()))
    except FloatingPointError as exc:
        out.finite = False
        out.result = f"failed: tick {out.ticks}: {exc}"
        out.wall_s = time.perf_counter() - started
        return out
    out.energy_change = (previous - e0) / e0
    problems = []
    if case.mode == FIXED and case.factor > 1.0:
        problems.append(f"one step of {dt:.3g} s per tick above h_max = {topo.h_max:.3g} s was not refused")
    if case.mode == IMPLICIT_MODE and rise > NET_IMPLICIT_ENERGY_TOL:
        problems.append(f"energy rose by {rise:.2e} of the start's in one tick (implicit Euler must only lose it)")
    if case.mode != IMPLICIT_MODE and out.energy_gain > NET_EXPLICIT_ENERGY_TOL:
        problems.append(f"energy gain {out.energy_gain:.2e} > {NET_EXPLICIT_ENERGY_TOL:g}")
    if out.energy_change >= 0.0:
        problems.append(f"energy change {out.energy_change:+.2e}: the damped net must end with less than it started")
    if problems:
        out.result = "failed: " + "; ".join(problems)
    out.wall_s = time.perf_counter() - started
    return out


def _ball(pos, vel=(0.0, 0.0, 0.0), spin=(0.0, 0.0, 0.0)):
    return {"pos": list(pos), "vel": list(vel), "spin": list(spin)}


def _expect_events(*bodies: Body) -> Callable[[Outcome], str | None]:
    def check(out: Outcome) -> str | None:
        seen = [Body(b).name.lower() for b in out.events[: len(bodies)]]
        want = [b.name.lower() for b in bodies]
        return None if seen == want else f"contacts {seen}, expected {want}"
    return check


def _expect_final(test: Callable[[np.ndarray], bool], what: str) -> Callable[[Outcome], str | None]:
    return lambda out: None if test(out.final) else f"{what} (ball ends at {np.round(out.final[0:3], 4).tolist()})"


def _both(*checks):
    def check(out):
        for c in checks:
            problem = c(out)
            if problem:
                return problem
        return None
    return check


TOPSPIN_150 = 2 * math.pi * 150  # rad/s, 150 rev/s: the fastest loops measured


def cases() -> list[Case]:
    """The suite. Extend it where you find a new way to break the engine."""
    bat_a = {"pos": [-1.0, 0.0, 0.3], "normal": [1.0, 0.0, 0.0]}
    suite = [
        Case("rest on the table", {"effects": ALL + ["table"], "ball": _ball((0.3, 0.1, R)), "duration": 3.0}, 3000,
             _expect_final(lambda y: y[2] == R and not y[3:6].any(), "must stay exactly on the surface, still"),
             conserves=True),
        Case("rest on a bat held still", {"effects": ALL + ["bats"], "ball": _ball((0.0, 0.0, 0.5)),
                                          "bats": {"a": {"pos": [0.0, 0.0, 0.4], "normal": [0.0, 0.0, 1.0]}}}, 3000,
             _expect_final(lambda y: abs(y[2] - (0.4 + equipment.BAT_HALF_THICKNESS + R)) < 2e-6 and abs(y[5]) < 1e-9,
                           "must settle on the face"), conserves=True),
        Case("roll along the table", {"effects": ALL + ["table", "floor"],
                                      "ball": _ball((-1.0, 0.0, R), (0.8, 0.0, 0.0), (0.0, 0.8 / R, 0.0))}, 1500,
             _expect_final(lambda y: y[2] == R and 0.0 < y[3] < 0.8, "must roll on, slowed by drag only")),
        Case("at rest at the start of a step", {"effects": ["gravity", "table"], "ball": _ball((0.0, 0.3, R))}, 100,
             _expect_final(lambda y: y[2] == R, "must not sink"), conserves=True),
        Case("drop, verlet, 1 ms", {"effects": ["gravity", "table"], "ball": _ball((0.0, 0.0, 0.32))}, 6000,
             conserves=True),
        Case("drop, explicit euler, 10 ms", {"effects": ["gravity", "table"], "ball": _ball((0.0, 0.0, 0.32)),
                                             "integrator": "explicit_euler", "dt": 0.01}, 600),
        Case("drop, dopri5, 20 ms", {"effects": ["gravity", "drag", "table"], "ball": _ball((0.0, 0.0, 0.32)),
                                     "integrator": "dopri5", "dt": 0.02}, 300, conserves=True),
        Case("40 m/s smash with 150 rev/s topspin into a bat, 1 ms",
             {"effects": ALL + ["bats"], "ball": _ball((-0.6, 0.0, 0.3), (-40.0, 0.0, 0.0), (0.0, -TOPSPIN_150, 0.0)),
              "bats": {"a": bat_a}}, 100, _expect_events(Body.BAT_A)),
        Case("40 m/s smash with 150 rev/s topspin into a bat, 10 ms",
             {"effects": ALL + ["bats"], "ball": _ball((-0.6, 0.0, 0.3), (-40.0, 0.0, 0.0), (0.0, -TOPSPIN_150, 0.0)),
              "bats": {"a": bat_a}, "dt": 0.01}, 20, _expect_events(Body.BAT_A)),
        Case("34 m/s into the rim of a bat, 5 ms",
             {"effects": ALL + ["bats"], "ball": _ball((-0.6, 0.09, 0.3), (-34.0, 0.0, 0.0)), "bats": {"a": bat_a},
              "dt": 0.005}, 40, _expect_events(Body.BAT_A)),
        Case("40 m/s into the net, 10 ms", {"effects": ALL + ["net"], "ball": _ball((-0.8, 0.2, 0.08), (40.0, 0.0, 0.0)),
                                            "dt": 0.01}, 30,
             _both(_expect_events(Body.NET), _expect_final(lambda y: y[0] < 0, "must stay on its side of the net"))),
        Case("into a net post", {"effects": ALL + ["net"], "ball": _ball((-0.3, 0.925, 0.07), (20.0, 0.0, 0.0))}, 60,
             _expect_events(Body.POST)),
        Case("40 m/s at the table's end face, 5 ms",
             {"effects": ALL + ["table"], "ball": _ball((2.5, 0.0, -0.01), (-40.0, 0.0, 0.0)), "dt": 0.005}, 20,
             _both(_expect_events(Body.TABLE), _expect_final(lambda y: y[0] > 1.37, "must bounce off the end face"))),
        Case("table edge", {"effects": ["gravity", "table"], "ball": _ball((2.0, 0.0, 0.012), (-20.0, 0.0, 0.0))}, 60,
             _expect_events(Body.TABLE)),
        Case("table corner", {"effects": ["table"], "ball": _ball((2.37, 1.7625, 1.0), (-20.0, -20.0, -20.0)),
                              "dt": 0.005}, 20, _expect_events(Body.TABLE)),
        Case("grazing incidence (0.1 degree)",
             {"effects": ["table"], "ball": _ball((-1.3, 0.0, R + 1e-4), (20.0, 0.0, -20.0 * math.tan(math.radians(0.1))))},
             100, _expect_events(Body.TABLE), conserves=True),
        Case("two impacts in one step: table then bat, 10 ms",
             {"effects": ["table", "bats"], "ball": _ball((-1.10, 0.0, 0.06), (-10.0, 0.0, -10.0)), "dt": 0.01,
              "bats": {"a": {"pos": [-1.22, 0.0, 0.06], "normal": [1.0, 0.0, 0.0]}}}, 5,
             _expect_events(Body.TABLE, Body.BAT_A)),
        Case("squeeze: the bat presses the ball onto the table",
             {"effects": ALL + ["table", "bats"], "ball": _ball((0.3, 0.0, R)),
              "bats": {"a": {"pos": [0.3, 0.0, 0.2], "normal": [0.0, 0.0, -1.0], "vel": [0.0, 0.0, -1.0]}}}, 400,
             _expect_final(lambda y: abs(y[2] - R) < 1e-9, "must stay on the table"), bat_yields=True),
        Case("squeeze: the ball pinned between the bat and the net",
             {"effects": ALL + ["table", "net", "bats"], "ball": _ball((-0.05, 0.0, 0.08)),
              "bats": {"a": {"pos": [-0.3, 0.0, 0.08], "normal": [1.0, 0.0, 0.0], "vel": [1.0, 0.0, 0.0]}}}, 400,
             _expect_final(lambda y: y[0] < 0, "must stay on its side of the net"), bat_yields=True),
        Case("squeeze: the ball between a still bat and the cloth net",
             {"effects": CLOTH_EFFECTS, "ball": _ball((-_PIN_GAP, 0.0, 0.08)), "net": CLOTH_CI,
              "bats": {"a": {"pos": [-_PIN_GAP - R - equipment.BAT_HALF_THICKNESS, 0.0, 0.08],
                             "normal": [1.0, 0.0, 0.0]}}}, 600,
             _expect_final(lambda y: y[0] < 0, "must stay on its side of the net"), conserves=True),
        *[Case(f"squeeze: the bat drives the ball into the cloth net ({label}) at 1 m/s",
               {"effects": CLOTH_EFFECTS, "ball": _ball((-0.05, 0.0, 0.08)), "net": net,
                "bats": {"a": {"pos": [-0.3, 0.0, 0.08], "normal": [1.0, 0.0, 0.0], "vel": [1.0, 0.0, 0.0]}}}, 400,
               bat_yields=True, ci=ci)
          for net, label, ci in ((CLOTH_CI, "64x8", True), (CLOTH, "184x16", False))],
        # The ball rolled along the table into the hanging net's hem and the bat behind it: the hem
        # swings forward over the surface (no knot goes below it) and must not let the ball through:
        # pressed between the bat and the net, the ball stays where the net holds it and stops the bat.
        Case("squeeze: the bat drives the ball resting on the table into the hem of the cloth net (64x8) at 1 m/s",
             {"effects": CLOTH_EFFECTS, "ball": _ball((-_PIN_GAP, 0.0, R)), "net": CLOTH_CI,
              "bats": {"a": {"pos": [-0.3, 0.0, R], "normal": [1.0, 0.0, 0.0], "vel": [1.0, 0.0, 0.0]}}}, 400,
             _expect_final(lambda y: y[0] < 0, "must stay on its side of the net"), bat_yields=True),
        *[Case(f"{speed:.0f} m/s smash with 150 rev/s topspin into the cloth net ({label})",
               {"effects": CLOTH_EFFECTS, "net": net, "bats": _BAT_FAR,
                "ball": _ball((-0.6, 0.1, 0.08), (speed, 0.0, 0.0), (0.0, -TOPSPIN_150, 0.0))}, 4000,
               _both(_expect_events(Body.NET), _expect_final(lambda y: y[0] < 0, "must be thrown back")),
               ci=ci, settles=True)
          for speed in (34.0, 40.0) for net, label, ci in ((CLOTH_CI, "64x8", True), (CLOTH, "184x16", False))],
        Case("net shots into the cloth net (64x8) every 4 s, 3 loops",
             _NET_SHOT | {"net": CLOTH_CI}, 12_000, _expect_events(Body.NET), loop=4000, settles=True),
        *_stiff_cases(),
        Case("refused: NaN in the scene", {"effects": ["gravity"], "ball": _ball((0.0, math.nan, 0.3))}, 10),
        Case("refused: a ball starting inside the net", {"effects": ["gravity", "net"], "ball": _ball((0.0, 0.0, 0.1))},
             10),
        Case("refused: infinite speed", {"effects": ["gravity"], "ball": _ball((0.0, 0.0, 0.3), (math.inf, 0.0, 0.0))}, 10),
        *[Case(f"refused: cloth net with {what}", {"effects": ["net"], "ball": _ball(_BALL_FAR),
                                                   "net": {"kind": "cloth", **bad}}, 10)
          for what, bad in _DEGENERATE_NETS],
        Case("long run: 10^6 ticks of bounces", {"effects": ALL + ["table"], "ball": _ball((0.2, 0.0, 0.32)),
                                                  "duration": 1000.0}, 1_000_000,
             _expect_final(lambda y: y[2] == R, "must end at rest on the table"), long=True),
        Case("long run: 10^6 ticks, a net shot every 4 s into the cloth net (184x16)",
             _NET_SHOT | {"net": CLOTH}, 1_000_000, _expect_events(Body.NET), loop=4000, settles=True, long=True),
    ]
    return suite


# The cloth net of the CI cases: 64 x 8 knots, cell diagonal 36 mm, below the 41 mm that keeps a
# ball from passing between knots (net_kernel.kernels.collide_ball), and ~20x cheaper than the
# default 184 x 16 net (11 substeps of 512 knots a tick against 25 of 2,944).
CLOTH_CI = {"kind": "cloth", "cols": 64, "rows": 8, "knot_mass": 0.05 / 512}
CLOTH = {"kind": "cloth"}
# One effect combination for every ball-and-cloth case: one numba specialisation of the tick to compile.
CLOTH_EFFECTS = ALL + ["table", "floor", "net", "bats"]
_BAT_FAR = {"b": {"pos": [3.0, 0.0, 0.3]}}  # out of play: the cases without a bat still have the effect
# m: the pinned ball's centre from the net's plane: just clear of the knots (radius 0.5 mm).
_PIN_GAP = R + KNOT_RADIUS + 1e-4
# A drive into the net from A's court; the net stops it, it falls back onto A's court and away.
_NET_SHOT = {"effects": CLOTH_EFFECTS, "duration": 1000.0, "bats": _BAT_FAR,
             "ball": _ball((-1.2, 0.05, 0.12), (12.0, 0.0, -0.5), (0.0, -200.0, 0.0))}
# Degenerate [net] sections, each refused at scene load with the key named.
_DEGENERATE_NETS = [
    ("zero knot mass", {"knot_mass": 0.0}),
    ("zero-stiffness springs", {"spring_k": 0.0}),
    ("a zero-stiffness top cord", {"cord_k": 0.0}),
    ("zero-length top cord springs (tension = k x spacing)", {"cord_tension": 50.0}),
    ("zero-length mesh springs (tension = k x spacing)", {"mesh_tension": 20.0}),
    ("a NaN spring stiffness", {"spring_k": math.nan}),
    ("an infinite knot mass", {"knot_mass": math.inf}),
    ("a knot mass whose inverse overflows", {"knot_mass": 1e-310}),
    ("springs so stiff the explicit solver needs 10^5 substeps a tick", {"spring_k": 2e11}),
]


def _stiff_cases() -> list[NetCase]:
    """k_s, k_d (and the top cord's k) at 1x, 10x, 100x the default, ticks at 0.5, 0.9, 1.1 and 10 times
    the explicit bound, each substepped by the engine, forced to one step a tick, and implicit.
    A 24 x 4 net (no ball touches it here): each case costs milliseconds."""
    base = NetSpec()
    suite = []
    for scale in (1, 10, 100):
        fields = {"cols": 24, "rows": 4, "knot_mass": 0.05 / 96, "spring_k": base.spring_k * scale,
                  "spring_c": base.spring_c * scale, "cord_k": base.cord_k * scale}
        for factor in (0.5, 0.9, 1.1, 10.0):
            for mode in (SUBSTEPPED, FIXED, IMPLICIT_MODE):
                suite.append(NetCase(f"stiff net: {scale}x k_s and k_d, tick {factor}x h_max, {mode}", fields, factor,
                                     mode, 300))
    return suite
