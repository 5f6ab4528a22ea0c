"""Scenes: TOML files naming the bodies and effects to simulate, validated into a frozen Scene."""
from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import tomli_w

from engine.physics import equipment
from engine.physics.integrators import METHODS
from net_kernel.sim import SAFETY
from net_kernel.topology import (
    PRECISIONS,
    SEMI_IMPLICIT,
    SOLVERS,
    NetSpec,
    build_topology,
    resolution_spec,
    validate_spec,
)

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"

# Effects a scene can list: each an optional piece of physics, not computed when absent. Those this
# version cannot simulate yet are refused by name.
EFFECTS = ("gravity", "drag", "magnus", "friction", "table", "floor", "net", "bats", "ai", "referee", "remote")
PLANNED_EFFECTS = ("recording",)
SKILL_NAMES = ("pro", "club", "novice")
NET_KINDS = ("rigid", "cloth")
# [net] keys for a cloth net: the fields of net_kernel.NetSpec (validated there).
CLOTH_FLOATS = ("knot_mass", "spring_k", "spring_c", "mesh_tension", "cord_k", "cord_tension", "hem_tension", "hem_gap",
                "air_damping", "tail_energy")
CLOTH_INTS = ("cols", "rows")
# [net] resolution = [cols, rows]: the net the other [net] keys describe, on that grid of knots
# (net_kernel.topology.resolution_spec keeps its continuum: mass per area, prestress, stiffness).
CLOTH_RESOLUTION = "resolution"
BAT_NAMES = ("a", "b")
MATERIAL_BODIES = ("table", "floor", "net", "bat")
# Explicit net substeps per tick beyond which a scene is refused: each is a full pass over the
# net, and the default 184 x 16 net needs 25, so 1000 already makes a tick 40 times as costly.
MAX_NET_SUBSTEPS = 1000
MAX_DT = 0.05  # s: the longest tick a scene may ask for (the wire's welcome.dt bound says the same)


class SceneError(ValueError):
    """A scene that cannot be simulated; the message names the file, the key and what is allowed."""


@dataclass(frozen=True)
class Material:
    restitution: float
    friction: float


@dataclass(frozen=True)
class BallSpec:
    pos: tuple[float, float, float]
    vel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    spin: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class BatSpec:
    name: str
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    vel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ang_vel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mass: float = equipment.BAT_MASS
    radius: float = equipment.BAT_RADIUS
    half_thickness: float = equipment.BAT_HALF_THICKNESS
    skill: str | None = None  # the player driving this bat (effect "ai"): an AI profile or a bot spec; None = none
    remote: bool = False  # played by a remote client through the gateway (effect "remote")


@dataclass(frozen=True)
class MatchSpec:
    """How a match is played (effect "referee")."""

    best_of: int = 5
    first_server: str = "a"
    ai_hz: float = 100.0  # control rate of the AI (scenes/match.toml says why); forces are held between its updates
    # s from a player's decision to the control tick its plan takes effect, in whole control
    # periods, at least one (engine.physics.compiled.CompiledScene.decision_delay). Half the
    # fastest profile's reaction time (pro 0.10 s, engine.play.ai.skill): within a human's
    # visuomotor delay of 100-200 ms, so a stroke starts when its reaction time says, and long
    # enough for the AI worker to think while the physics steps on.
    decision_latency: float = 0.05
    max_rally_s: float = 10.0  # a rally still undecided after this long is judged out of play
    toss_speed: float = 2.6  # m/s upwards: the toss rises ~34 cm (ITTF 2.6.2: at least 16 cm)


@dataclass(frozen=True)
class Scene:
    """Static description of a run. Derived numbers (drag factor, inertia...) are computed in
    engine.physics.world.build_model, never here."""

    name: str
    source: str
    effects: frozenset[str]
    ball: BallSpec
    dt: float = 0.001
    duration: float = 2.0
    integrator: str = "verlet"
    rtol: float = 1e-6
    atol: float = 1e-9
    description: str = ""
    bats: tuple[BatSpec, ...] = ()
    net_kind: str = "rigid"
    cloth: NetSpec | None = None  # the cloth net's description when net_kind is "cloth"
    gravity: float = equipment.GRAVITY
    air_density: float = equipment.AIR_DENSITY
    drag_coefficient: float = equipment.DRAG_COEFFICIENT
    magnus_coefficient: float = equipment.MAGNUS_COEFFICIENT
    # (body, Material) pairs: a tuple keeps the scene immutable and picklable (sent to workers).
    materials: tuple[tuple[str, Material], ...] = ()
    match: MatchSpec | None = None

    def material(self, body: str) -> Material:
        """The material of `body` (table, floor, net, bat)."""
        return dict(self.materials).get(body, DEFAULT_MATERIALS[body])

    @property
    def ticks(self) -> int:
        """Ticks in the scene's duration."""
        return int(round(self.duration / self.dt))


DEFAULT_MATERIALS = {
    "table": Material(equipment.TABLE_RESTITUTION, equipment.TABLE_FRICTION),
    "floor": Material(equipment.FLOOR_RESTITUTION, equipment.FLOOR_FRICTION),
    "net": Material(equipment.NET_RESTITUTION, equipment.NET_FRICTION),
    "bat": Material(equipment.BAT_RESTITUTION, equipment.BAT_FRICTION),
}


class _Reader:
    """Reads values out of a parsed TOML table, naming the file and key path in every error."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, message: str) -> SceneError:
        return SceneError(f"{self.source}: {key}: {message}")

    def table(self, data: Any, key: str, allowed: tuple[str, ...]) -> dict:
        if not isinstance(data, dict):
            raise self.fail(key, f"must be a table, got {type(data).__name__}")
        unknown = sorted(set(data) - set(allowed))
        if unknown:
            raise self.fail(f"{key}.{unknown[0]}" if key else unknown[0],
                            f"unknown key; allowed here: {', '.join(allowed)}")
        return data

    def number(self, data: dict, key: str, path: str, default: float | None = None, *,
               low: float = -math.inf, high: float = math.inf, low_open: bool = False) -> float:
        if key not in data:
            if default is None:
                raise self.fail(path, "is required")
            return default
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f"must be a number, got {type(value).__name__} {value!r}")
        value = float(value)
        bracket = "(" if low_open else "["
        if not math.isfinite(value):
            raise self.fail(path, f"must be finite, got {value}")
        if value < low or (low_open and value == low) or value > high:
            raise self.fail(path, f"must be in {bracket}{low}, {high}], got {value}")
        return value

    def vector(self, data: dict, key: str, path: str, default: tuple | None = None, *,
               size: int = 3, bound: float = 1e3) -> tuple:
        if key not in data:
            if default is None:
                raise self.fail(path, "is required")
            return default
        value = data[key]
        if not isinstance(value, list) or len(value) != size:
            raise self.fail(path, f"must be a list of {size} numbers, got {value!r}")
        return tuple(self.number({"v": v}, "v", f"{path}[{i}]", low=-bound, high=bound)
                     for i, v in enumerate(value))

    def string(self, data: dict, key: str, path: str, default: str, choices: tuple[str, ...] | None = None) -> str:
        value = data.get(key, default)
        if not isinstance(value, str):
            raise self.fail(path, f"must be a string, got {type(value).__name__} {value!r}")
        if choices is not None and value not in choices:
            raise self.fail(path, f"must be one of {', '.join(choices)}; got {value!r}")
        return value


def _quat_from_normal(normal: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """Shortest-arc unit quaternion turning the bat's local z axis onto `normal`."""
    nx, ny, nz = normal
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    if nz < -1.0 + 1e-12:
        return (0.0, 1.0, 0.0, 0.0)  # half turn about x
    w = 1.0 + nz  # z x n = (-ny, nx, 0); q = (1 + z.n, z x n), normalised
    qx, qy = -ny, nx
    s = math.sqrt(w * w + qx * qx + qy * qy)
    return (w / s, qx / s, qy / s, 0.0)


def _read_cloth(r: _Reader, data: dict) -> NetSpec:
    """A cloth net's NetSpec from [net]; its ranges are the net kernel's (net_kernel.validate_spec)."""
    fields: dict[str, Any] = {}
    for key in CLOTH_FLOATS:
        if key in data:
            fields[key] = r.number(data, key, f"net.{key}", low=0.0)
    for key in CLOTH_INTS:
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, int):
                raise r.fail(f"net.{key}", f"must be a whole number, got {value!r}")
            fields[key] = value
    if "solver" in data:
        fields["solver"] = r.string(data, "solver", "net.solver", "", SOLVERS)
    if "kernel_precision" in data:
        fields["kernel_precision"] = r.string(data, "kernel_precision", "net.kernel_precision", "", PRECISIONS)
    if "kernel_fma" in data:
        if not isinstance(data["kernel_fma"], bool):
            raise r.fail("net.kernel_fma", f"must be true or false, got {data['kernel_fma']!r}")
        fields["kernel_fma"] = data["kernel_fma"]
    spec = NetSpec(**fields)
    try:
        validate_spec(spec)
    except ValueError as exc:
        field, _, rest = str(exc).partition(" = ")
        raise r.fail(f"net.{field.removeprefix('NetSpec.')}", rest) from None
    if CLOTH_RESOLUTION in data:
        spec = _regrid(r, data, spec)
    return spec


def _regrid(r: _Reader, data: dict, spec: NetSpec) -> NetSpec:
    """[net] resolution = [cols, rows]: the net `spec` describes, on that grid (resolution_spec)."""
    value = data[CLOTH_RESOLUTION]
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise r.fail("net.resolution", f"must be [cols, rows], two whole numbers, got {value!r}")
    given = [key for key in CLOTH_INTS if key in data]
    if given:
        raise r.fail(f"net.{given[0]}", "is set by net.resolution = [cols, rows]; give one or the other")
    try:
        return resolution_spec(value[0], value[1], spec)
    except ValueError as exc:
        raise r.fail("net.resolution", str(exc)) from None


def _check_net_substeps(r: _Reader, cloth: NetSpec, dt: float) -> None:
    """Refuse a cloth net whose explicit solver would need more than MAX_NET_SUBSTEPS substeps a tick."""
    h_max = build_topology(cloth).h_max
    if cloth.solver != SEMI_IMPLICIT or h_max == math.inf:
        return
    substeps = dt / (SAFETY * h_max)
    if not substeps <= MAX_NET_SUBSTEPS:  # NaN too
        raise r.fail("net", f"the explicit net solver would need {substeps:.3g} substeps a tick (tick "
                            f"{dt:g} s, stability bound h_max = {h_max:.3g} s), more than {MAX_NET_SUBSTEPS}; use "
                            'solver = "implicit", softer springs (spring_k, cord_k), heavier knots (knot_mass) or a '
                            "shorter dt")


def _read_bat(r: _Reader, name: str, data: Any) -> BatSpec:
    path = f"bats.{name}"
    keys = ("pos", "normal", "quat", "vel", "ang_vel", "force", "torque", "mass", "radius", "half_thickness", "skill",
            "remote")
    data = r.table(data, path, keys)
    if "normal" in data and "quat" in data:
        raise r.fail(path, "give either normal or quat, not both")
    if "quat" in data:
        quat = r.vector(data, "quat", f"{path}.quat", size=4, bound=1.0)
        norm = math.sqrt(sum(c * c for c in quat))
        if abs(norm - 1.0) > 1e-6:
            raise r.fail(f"{path}.quat", f"must be a unit quaternion (w, x, y, z), its norm is {norm}")
    else:
        normal = r.vector(data, "normal", f"{path}.normal", default=(1.0 if name == "a" else -1.0, 0.0, 0.0))
        if math.sqrt(sum(c * c for c in normal)) < 1e-9:
            raise r.fail(f"{path}.normal", "must not be the zero vector")
        quat = _quat_from_normal(normal)
    return BatSpec(
        name=name,
        pos=r.vector(data, "pos", f"{path}.pos", bound=10.0),
        quat=quat,
        vel=r.vector(data, "vel", f"{path}.vel", (0.0, 0.0, 0.0), bound=50.0),
        ang_vel=r.vector(data, "ang_vel", f"{path}.ang_vel", (0.0, 0.0, 0.0), bound=200.0),
        force=r.vector(data, "force", f"{path}.force", (0.0, 0.0, 0.0), bound=1e3),
        torque=r.vector(data, "torque", f"{path}.torque", (0.0, 0.0, 0.0), bound=1e2),
        mass=r.number(data, "mass", f"{path}.mass", equipment.BAT_MASS, low=0.05, high=1.0),
        radius=r.number(data, "radius", f"{path}.radius", equipment.BAT_RADIUS, low=0.03, high=0.15),
        half_thickness=r.number(data, "half_thickness", f"{path}.half_thickness",
                                equipment.BAT_HALF_THICKNESS, low=0.001, high=0.02),
        skill=_read_skill(r, data, path) if "skill" in data else None,
        remote=_flag(r, data, "remote", f"{path}.remote"),
    )


def is_bot_spec(player: str) -> bool:
    """Whether a player name is a bot spec ("FILE.py:Class" or "module:Class", engine.play.bot),
    not an AI profile: a scene names its players, the match loads them."""
    return ":" in player


def _read_skill(r: _Reader, data: dict, path: str) -> str:
    """bats.X.skill: an AI profile (SKILL_NAMES) or a bot ("FILE.py:Class", "module:Class"; loaded
    when the match starts, engine.play.bot.load_bot)."""
    skill = r.string(data, "skill", f"{path}.skill", "")
    if skill not in SKILL_NAMES and not is_bot_spec(skill):
        raise r.fail(f"{path}.skill", f"must be one of {', '.join(SKILL_NAMES)} or a bot (FILE.py:Class or "
                                      f"module:Class); got {skill!r}")
    return skill


def _flag(r: _Reader, data: dict, key: str, path: str) -> bool:
    value = data.get(key, False)
    if not isinstance(value, bool):
        raise r.fail(path, f"must be true or false, got {type(value).__name__} {value!r}")
    return value


TOP_KEYS = ("name", "description", "effects", "dt", "duration", "integrator", "rtol", "atol", "ball", "bats", "net",
            "air", "materials", "match")


def parse_scene(data: dict, source: str) -> Scene:
    """Validate a parsed TOML document into a Scene; every error names `source` and the key.

    The sections are read in a fixed order (effects, ball, bats, net, players, match, air and
    materials, then the top-level numbers), so a document with several errors names the same one first.
    """
    r = _Reader(source)
    data = r.table(data, "", TOP_KEYS)
    effects = _read_effects(r, data.get("effects"))
    ball = _read_ball(r, data.get("ball", {}))
    bats = _read_bats(r, data, effects)
    net_kind, cloth = _read_net(r, data, effects)
    _check_players(r, bats, effects)
    match = _read_match(r, data, effects, bats)
    air = r.table(data.get("air", {}), "air", ("density", "drag_coefficient", "magnus_coefficient", "gravity"))
    materials = _read_materials(r, data.get("materials", {}))
    dt = r.number(data, "dt", "dt", 0.001, low=0.0, high=MAX_DT, low_open=True)
    if cloth is not None:
        _check_net_substeps(r, cloth, dt)
    return Scene(
        name=r.string(data, "name", "name", Path(source).stem),
        source=source,
        description=r.string(data, "description", "description", ""),
        effects=effects,
        ball=ball,
        dt=dt,
        duration=r.number(data, "duration", "duration", 2.0, low=0.0, high=3600.0),
        integrator=r.string(data, "integrator", "integrator", "verlet", tuple(METHODS)),
        rtol=r.number(data, "rtol", "rtol", 1e-6, low=1e-14, high=1e-1),
        atol=r.number(data, "atol", "atol", 1e-9, low=1e-16, high=1e-1),
        bats=bats,
        net_kind=net_kind,
        cloth=cloth,
        **_read_air(r, air),
        materials=materials,
        match=match,
    )


def _read_effects(r: _Reader, effects_raw: Any) -> frozenset[str]:
    """effects = [...]: every name known and simulated by this version."""
    if not isinstance(effects_raw, list) or not all(isinstance(e, str) for e in effects_raw):
        raise r.fail("effects", f"is required: a list of effect names out of {', '.join(EFFECTS)}")
    for effect in effects_raw:
        if effect in PLANNED_EFFECTS:
            raise r.fail("effects", f"effect {effect!r} is not supported by this version of the engine; "
                                    f"supported: {', '.join(EFFECTS)}")
        if effect not in EFFECTS:
            raise r.fail("effects", f"unknown effect {effect!r}; known: {', '.join(EFFECTS)}")
    return frozenset(effects_raw)


def _read_ball(r: _Reader, data: Any) -> BallSpec:
    """[ball]: its initial position (required), velocity and spin."""
    ball_data = r.table(data, "ball", ("pos", "vel", "spin"))
    return BallSpec(
        pos=r.vector(ball_data, "pos", "ball.pos", bound=10.0),
        vel=r.vector(ball_data, "vel", "ball.vel", (0.0, 0.0, 0.0), bound=equipment.BALL_SPEED_MAX),
        # 200 rev/s is beyond the fastest measured loops (~150 rev/s).
        spin=r.vector(ball_data, "spin", "ball.spin", (0.0, 0.0, 0.0), bound=2 * math.pi * 200),
    )


def _read_bats(r: _Reader, data: dict, effects: frozenset[str]) -> tuple[BatSpec, ...]:
    """[bats.a], [bats.b]: present exactly when the effect "bats" is listed."""
    bats: list[BatSpec] = []
    if "bats" in data:
        if "bats" not in effects:
            raise r.fail("bats", "bats are described but the effect 'bats' is not listed in effects; add it or remove [bats]")
        for name, bat_data in r.table(data["bats"], "bats", BAT_NAMES).items():
            bats.append(_read_bat(r, name, bat_data))
    if "bats" in effects and not bats:
        raise r.fail("effects", "effect 'bats' needs at least one [bats.a] or [bats.b] table")
    return tuple(bats)


def _read_net(r: _Reader, data: dict, effects: frozenset[str]) -> tuple[str, NetSpec | None]:
    """[net]: the net's kind, and a cloth net's NetSpec (None for the rigid net)."""
    if "net" not in data:
        return "rigid", None
    if "net" not in effects:
        raise r.fail("net", "a net is described but the effect 'net' is not listed in effects; add it or remove [net]")
    net_data = r.table(data["net"], "net", ("kind", "solver", "kernel_precision", "kernel_fma", CLOTH_RESOLUTION)
                       + CLOTH_FLOATS + CLOTH_INTS)
    net_kind = r.string(net_data, "kind", "net.kind", "rigid", NET_KINDS)
    cloth = _read_cloth(r, net_data) if net_kind == "cloth" else None
    if net_kind == "rigid" and len(net_data) > ("kind" in net_data):
        extra = sorted(set(net_data) - {"kind"})[0]
        raise r.fail(f"net.{extra}", "describes a cloth net; set kind = \"cloth\" or remove it")
    return net_kind, cloth


def _check_players(r: _Reader, bats: tuple[BatSpec, ...], effects: frozenset[str]) -> None:
    """Each bat is played by the AI (skill, effect "ai"), remotely (effect "remote") or by nobody."""
    ai_bats = [b.name for b in bats if b.skill is not None]
    if ai_bats and "ai" not in effects:
        raise r.fail(f"bats.{ai_bats[0]}.skill", "a skill is given but the effect 'ai' is not listed in effects")
    remote_bats = [b.name for b in bats if b.remote]
    both = [b.name for b in bats if b.remote and b.skill is not None]
    if both:
        raise r.fail(f"bats.{both[0]}.remote", "a bat is played either by the AI (skill) or remotely, not both")
    if remote_bats and "remote" not in effects:
        raise r.fail(f"bats.{remote_bats[0]}.remote", "a remote bat needs the effect 'remote' in effects")
    if "ai" in effects and not ai_bats:
        raise r.fail("effects", "effect 'ai' needs a bat with a skill (bats.a.skill = \"pro\", \"club\" or \"novice\")")


def _read_match(r: _Reader, data: dict, effects: frozenset[str], bats: tuple[BatSpec, ...]) -> MatchSpec | None:
    """[match] of a scene with the effect "referee" (None without it), which needs the whole table."""
    if "referee" not in effects:
        if "match" in data:
            raise r.fail("match", "a [match] table needs the effect 'referee'")
        if "remote" in effects:
            raise r.fail("effects", "effect 'remote' (a match served to network clients) needs the effect 'referee'")
        return None
    missing = [e for e in ("table", "net", "floor", "bats") if e not in effects]
    if missing or len(bats) != 2:
        raise r.fail("effects", f"effect 'referee' needs the table, net, floor and both bats; missing: "
                                f"{', '.join(missing) or 'a second bat'}")
    m = r.table(data.get("match", {}), "match", ("best_of", "first_server", "ai_hz", "decision_latency", "max_rally_s",
                                                   "toss_speed"))
    best_of = r.number(m, "best_of", "match.best_of", 5, low=1, high=9)
    if best_of != int(best_of) or int(best_of) % 2 == 0:
        raise r.fail("match.best_of", f"must be an odd whole number, got {best_of}")
    return MatchSpec(
        best_of=int(best_of),
        first_server=r.string(m, "first_server", "match.first_server", "a", BAT_NAMES),
        ai_hz=r.number(m, "ai_hz", "match.ai_hz", 100.0, low=10.0, high=2000.0),
        decision_latency=r.number(m, "decision_latency", "match.decision_latency", 0.05, low=0.0, high=0.3),
        max_rally_s=r.number(m, "max_rally_s", "match.max_rally_s", 10.0, low=1.0, high=120.0),
        toss_speed=r.number(m, "toss_speed", "match.toss_speed", 2.6, low=1.8, high=5.0),
    )


def _read_materials(r: _Reader, data: Any) -> tuple[tuple[str, Material], ...]:
    """[materials.BODY]: restitution and friction, each defaulting to the body's (DEFAULT_MATERIALS)."""
    materials = dict(DEFAULT_MATERIALS)
    for body, mat in r.table(data, "materials", MATERIAL_BODIES).items():
        mat = r.table(mat, f"materials.{body}", ("restitution", "friction"))
        base = materials[body]
        materials[body] = Material(
            restitution=r.number(mat, "restitution", f"materials.{body}.restitution", base.restitution, low=0.0, high=1.0),
            friction=r.number(mat, "friction", f"materials.{body}.friction", base.friction, low=0.0, high=2.0),
        )
    return tuple(sorted(materials.items()))


def _read_air(r: _Reader, air: dict) -> dict[str, float]:
    """[air] (already checked for unknown keys): Scene's gravity, air_density and the two coefficients."""
    return {
        "gravity": r.number(air, "gravity", "air.gravity", equipment.GRAVITY, low=0.0, high=100.0),
        "air_density": r.number(air, "density", "air.density", equipment.AIR_DENSITY, low=0.0, high=10.0),
        "drag_coefficient": r.number(air, "drag_coefficient", "air.drag_coefficient", equipment.DRAG_COEFFICIENT,
                                     low=0.0, high=2.0),
        "magnus_coefficient": r.number(air, "magnus_coefficient", "air.magnus_coefficient",
                                       equipment.MAGNUS_COEFFICIENT, low=0.0, high=5.0),
    }


def load_scene(name_or_path: str | Path, overrides: dict[str, Any] | None = None) -> Scene:
    """Load a scene from a TOML path, or a bundled scene by name (`drop`, `serve`, `rally`).

    overrides: dotted keys set in the TOML document before it is validated, so they are checked
    like the file's own keys: {"match.ai_hz": 50, "integrator": "rk4"} (`pingpong sweep --set`).
    """
    path = Path(name_or_path)
    if not path.exists() and not path.suffix:
        bundled = SCENES_DIR / f"{path.name}.toml"
        if bundled.exists():
            path = bundled
    if not path.exists():
        names = ", ".join(sorted(p.stem for p in SCENES_DIR.glob("*.toml")))
        raise SceneError(f"{name_or_path}: no such scene file; bundled scenes: {names}")
    return scene_from_toml(path.read_text(), str(path), overrides)


def scene_from_toml(text: str, source: str, overrides: dict[str, Any] | None = None) -> Scene:
    """The Scene of a TOML document `text` (load_scene's, and scene_toml's inverse); errors name `source`."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: not valid TOML: {exc}") from exc
    for key, value in (overrides or {}).items():
        _set_key(data, key, value, source)
    return parse_scene(data, source)


def _set_key(data: dict, key: str, value: Any, source: str) -> None:
    """data[a][b][c] = value for key "a.b.c", making the tables a and a.b where they are missing."""
    *tables, last = key.split(".")
    node = data
    for depth, name in enumerate(tables):
        node = node.setdefault(name, {})
        if not isinstance(node, dict):
            raise SceneError(f"{source}: {'.'.join(tables[:depth + 1])}: is a value, not a table, so {key} "
                             "cannot be set")
    node[last] = value


def scene_digest(scene: Scene) -> str:
    """16 hex digits of sha256 over what a scene simulates (every field but the file it came from):
    equal digests, equal matches for equal seeds and code."""
    fields = asdict(replace(scene, source=""))
    text = json.dumps(fields, sort_keys=True, default=sorted)  # default: the effects' frozenset, sorted
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def scene_toml(scene: Scene) -> str:
    """The scene as a TOML document that scene_from_toml reads back into an equal Scene (every
    field but `source`; the same scene_digest): what a served match sends its clients and a
    replay keeps, whatever file, --set or --a/--b the scene was made from. Every value is
    written out, defaults too, so the document means the same to a later version with other
    defaults. Raises SceneError for a scene that no TOML document describes (a cloth net whose
    width, height, posts or gravity differ from NetSpec's: a scene file cannot set them)."""
    data: dict[str, Any] = {
        "name": scene.name, "description": scene.description, "effects": sorted(scene.effects), "dt": scene.dt,
        "duration": scene.duration, "integrator": scene.integrator, "rtol": scene.rtol, "atol": scene.atol,
        "ball": {"pos": list(scene.ball.pos), "vel": list(scene.ball.vel), "spin": list(scene.ball.spin)},
        "air": {"gravity": scene.gravity, "density": scene.air_density, "drag_coefficient": scene.drag_coefficient,
                "magnus_coefficient": scene.magnus_coefficient},
        "materials": {body: {"restitution": m.restitution, "friction": m.friction} for body, m in scene.materials},
    }
    if scene.bats:
        data["bats"] = {bat.name: _bat_data(bat) for bat in scene.bats}
    if "net" in scene.effects:
        data["net"] = {"kind": scene.net_kind} if scene.cloth is None else _cloth_data(scene)
    if scene.match is not None:
        data["match"] = asdict(scene.match)
    return tomli_w.dumps(data)


def _bat_data(bat: BatSpec) -> dict[str, Any]:
    out: dict[str, Any] = {key: list(getattr(bat, key)) for key in ("pos", "quat", "vel", "ang_vel", "force", "torque")}
    out.update(mass=bat.mass, radius=bat.radius, half_thickness=bat.half_thickness, remote=bat.remote)
    if bat.skill is not None:
        out["skill"] = bat.skill
    return out


def _cloth_data(scene: Scene) -> dict[str, Any]:
    spec = scene.cloth
    written = set(CLOTH_FLOATS + CLOTH_INTS) | {"solver", "kernel_precision", "kernel_fma"}
    default = NetSpec()
    fixed = [f.name for f in fields(NetSpec) if f.name not in written
             and getattr(spec, f.name) != getattr(default, f.name)]
    if fixed:
        raise SceneError(f"{scene.source}: net.{fixed[0]}: {getattr(spec, fixed[0])!r} is not NetSpec's "
                         f"{getattr(default, fixed[0])!r}, and a scene file cannot set it")
    return {"kind": "cloth", **{key: getattr(spec, key) for key in sorted(written)}}


def with_skills(scene: Scene, skill_a: str, skill_b: str) -> Scene:
    """The scene with bat A played by skill_a and bat B by skill_b: AI profiles (SKILL_NAMES) or
    bot specs ("FILE.py:Class", "module:Class"; engine.play.bot.load_bot)."""
    if len(scene.bats) != 2:
        raise SceneError(f"{scene.source}: two AI players need both bats; the scene has {len(scene.bats)}")
    for name, skill in zip(BAT_NAMES, (skill_a, skill_b)):
        if not isinstance(skill, str) or (skill not in SKILL_NAMES and not is_bot_spec(skill)):
            raise SceneError(f"bats.{name}.skill: must be one of {', '.join(SKILL_NAMES)} or a bot "
                             f"(FILE.py:Class or module:Class); got {skill!r}")
    bats = tuple(replace(bat, skill=skill, remote=False) for bat, skill in zip(scene.bats, (skill_a, skill_b)))
    return replace(scene, bats=bats, effects=(scene.effects - {"remote"}) | {"ai"})


def with_overrides(scene: Scene, **changes: Any) -> Scene:
    """A copy of the scene with some fields changed and re-validated (CLI --dt, --integrator)."""
    if "integrator" in changes and changes["integrator"] not in METHODS:
        raise SceneError(f"{scene.source}: integrator: must be one of {', '.join(METHODS)}; got {changes['integrator']!r}")
    if "dt" in changes and not (math.isfinite(changes["dt"]) and 0.0 < changes["dt"] <= MAX_DT):
        raise SceneError(f"{scene.source}: dt: must be in (0.0, {MAX_DT}] s, got {changes['dt']}")
    return replace(scene, **changes)


def with_remote_players(scene: Scene, players: int) -> Scene:
    """The scene served to network clients (effect "remote"): bat A remote if players >= 1, bat B
    too if players == 2; the other bats keep their AI. `pingpong serve --players N`."""
    if players not in (0, 1, 2):
        raise SceneError(f"players: must be 0, 1 or 2, got {players}")
    if scene.match is None:
        raise SceneError(f"{scene.source}: serving a scene needs the effect 'referee' (a match)")
    bats = tuple(replace(bat, remote=True, skill=None) if i < players else bat for i, bat in enumerate(scene.bats))
    if any(not bat.remote and bat.skill is None for bat in bats):
        missing = next(bat.name for bat in bats if not bat.remote and bat.skill is None)
        raise SceneError(f"{scene.source}: bats.{missing} has no skill: with {players} remote players it would "
                         "have nobody to play it")
    effects = set(scene.effects) | {"remote"}
    if not any(bat.skill is not None for bat in bats):
        effects.discard("ai")
    return replace(scene, bats=bats, effects=frozenset(effects))
