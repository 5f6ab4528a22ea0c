"""The stability suite: hard cases that try to break the engine, and what "survived" means.

Each case is a scene run tick by tick while the suite measures, after every tick:
- finite: every number of the ball's state stays finite;
- penetration: how far the ball's surface is inside any static body (table, floor, net, posts)
  or any bat (squeeze cases excepted, where the bat is meant to yield);
- tunnelled: the ball's centre changed side of a thin body (bat face, net) within its outline
  without a contact with it;
- energy gain: the largest rise of the ball's mechanical energy (kinetic, rotational,
  potential) over its value at the start, for cases where nothing moves or pushes it.
A case passes when its own expectations hold (events it must see, where the ball must end).
Refused inputs (NaN, zero-length ticks...) are cases too: they must be refused with a message.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from engine import equipment
from engine.bat import face_normal
from engine.geometry import NET_BOX, POST_BOXES, TABLE_BOX, Body, box_sdf, disc_sdf
from engine.scene import SceneError, parse_scene
from engine.world import SimulationError, build_model, initial_state, new_events, step

R = equipment.BALL_RADIUS
PENETRATION_TOL = 1e-6  # m: contacts are resolved to CONTACT_TOL = 1 um
ENERGY_TOL = 1e-9  # relative: round-off over thousands of ticks
ALL = ["gravity", "drag", "magnus", "friction"]


@dataclass
class Case:
    name: str
    scene: dict
    ticks: int
    expect: Callable[["Outcome"], str | None] = lambda o: None  # None = fine, else what failed
    bat_yields: bool = False  # squeeze cases: the bat passing through the ball is the answer
    conserves: bool = False  # nothing moves or pushes the ball: its energy must not rise
    long: bool = False  # run by `make test-long` / `--long`, not in the default suite


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
    max_abs_state: float = 0.0
    events: list = field(default_factory=list)  # body ids of the contacts, in order
    final: np.ndarray | None = None
    wall_s: float = 0.0

    def as_dict(self) -> dict:
        return {"case": self.case, "integrator": self.integrator, "dt": self.dt, "ticks": self.ticks,
                "result": self.result, "finite": self.finite, "tunnelled": self.tunnelled,
                "max_penetration_m": self.max_penetration_m, "energy_gain": self.energy_gain,
                "max_abs_state": self.max_abs_state, "contacts": len(self.events), "wall_s": self.wall_s}


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


def run_case(case: Case) -> Outcome:
    started = time.perf_counter()
    data = dict(case.scene)
    try:
        scene = parse_scene(data, f"stability:{case.name}")
    except SceneError as exc:
        return Outcome(case.name, data.get("integrator", "verlet"), data.get("dt", 0.001), 0, f"refused: {exc}")
    try:
        model = build_model(scene)
    except SceneError as exc:
        return Outcome(case.name, scene.integrator, scene.dt, 0, f"refused: {exc}")
    state, events = initial_state(scene), new_events()
    out = Outcome(case.name, scene.integrator, scene.dt, 0, "stable")
    g = model.gravity or 0.0
    e0 = _energy(state.ball_y, g)
    sides = _thin_side(state, model)
    hit_bodies: set[int] = set()
    normal = np.zeros(3)
    try:
        for tick in range(case.ticks):
            n = step(model, state, None, events)
            out.ticks = tick + 1
            for k in range(n):
                out.events.append(int(events[k]["body"]))
                hit_bodies.add(int(events[k]["body"]))
            y = state.ball_y
            out.max_abs_state = max(out.max_abs_state, float(np.abs(y).max()))
            p = y[0:3]
            gaps = [box_sdf(p, TABLE_BOX, normal) - R] if model.table is not None else []
            if model.net is not None:
                gaps += [box_sdf(p, NET_BOX, normal) - R] + [box_sdf(p, post, normal) - R for post in POST_BOXES]
            if model.floor_z is not None:
                gaps.append(p[2] - model.floor_z - R)
            if not case.bat_yields:
                for b in range(len(state.bats)):
                    axis = np.zeros(3)
                    face_normal(state.bats["quat"][b], axis)
                    gaps.append(disc_sdf(p, state.bats["pos"][b], axis, scene.bats[b].radius,
                                         scene.bats[b].half_thickness, normal) - R)
            if gaps:
                out.max_penetration_m = max(out.max_penetration_m, -min(gaps))
            if case.conserves:
                out.energy_gain = max(out.energy_gain, (_energy(y, g) - e0) / max(abs(e0), 1e-12))
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
    out.final = state.ball_y.copy()
    problems = []
    if out.tunnelled:
        problems.append("tunnelled through a thin body")
    if out.max_penetration_m > PENETRATION_TOL:
        problems.append(f"penetration {out.max_penetration_m:.2e} m > {PENETRATION_TOL:g}")
    if case.conserves and out.energy_gain > ENERGY_TOL:
        problems.append(f"energy gain {out.energy_gain:.2e} > {ENERGY_TOL:g}")
    expectation = case.expect(out)
    if expectation:
        problems.append(expectation)
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
        Case("refused: NaN in the scene", {"effects": ["gravity"], "ball": _ball((0.0, math.nan, 0.3))}, 10),
        Case("refused: a ball starting inside the net", {"effects": ["gravity", "net"], "ball": _ball((0.0, 0.0, 0.1))},
             10),
        Case("refused: infinite speed", {"effects": ["gravity"], "ball": _ball((0.0, 0.0, 0.3), (math.inf, 0.0, 0.0))}, 10),
        Case("long run: 10^6 ticks of bounces", {"effects": ALL + ["table"], "ball": _ball((0.2, 0.0, 0.32)),
                                                  "duration": 1000.0}, 1_000_000,
             _expect_final(lambda y: y[2] == R, "must end at rest on the table"), long=True),
    ]
    return suite
