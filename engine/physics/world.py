"""The in-process world: derived model built once from a scene, state arrays, and the tick.

This single-process world is the reference the multi-process run must reproduce bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from engine.physics import equipment
from engine.physics.bat import BAT_WIDTH, FORCE_AT, TORQUE_AT, disc_inertia, face_normal
from engine.physics.collision import (
    BAT_HALF_THICKNESS,
    BAT_RADIUS,
    BAT_ROW,
    CONTACT_TOL,
    ERR_IMPACTS,
    ERR_NONFINITE,
    ERR_SUBSTEPS,
    EVENT_ROW,
    MAX_IMPACTS_PER_TICK,
    N_PARAMS,
    P_INERTIA,
    P_MASS,
    P_RADIUS,
    P_REST_SPEED,
    SCRATCH_SHAPE,
)
from engine.physics.dtypes import BAT_DTYPE, CONTACT_DTYPE, physics_snapshot_dtype
from engine.physics.forces import drag_factor, magnus_factor
from engine.physics.geometry import FLOOR_Z, NET_BOX, POST_BOXES, TABLE_BOX, Body, box_sdf, disc_sdf
from engine.physics.integrators import METHODS, WORK_SHAPE
from engine.physics.scene import Scene, SceneError
from engine.physics.tick import (
    ERR_BATS_AFTER,
    ERR_BATS_BEFORE,
    STOP_EVENT,
    STOP_LIMIT,
    STOP_NET,
    STOP_WATCH,
    advance_run,
    advance_ticks,
)
from net_kernel import NO_CONTACT, NetContact, NetSim, NetTopology, build_topology
from net_kernel.sim import KNOT_RADIUS, NET_REACH, WAKE_MARGIN

# The most ticks near the net the engine steps the ball ahead of the net (_run_near_net); a
# worker's net answers them in one hand-off. A match's run also ends at each AI control tick.
NET_RUN_TICKS = 16


class SimulationError(RuntimeError):
    """The engine could not advance the state (it says which check failed and at which tick)."""


@dataclass(frozen=True)
class Model:
    """Every derived number of a scene, computed once here and nowhere else.

    An absent effect is None, which compiles it out of the kernels (engine/physics/forces.py).
    """

    scene: Scene
    dt: float
    method: int
    gravity: float | None
    drag_k: float | None
    magnus_k: float | None
    table: np.ndarray | None
    floor_z: float | None
    net: np.ndarray | None
    posts: np.ndarray | None
    ball_params: np.ndarray  # (N_PARAMS,), see engine.physics.collision.P_*
    materials: np.ndarray  # (len(Body), 2): restitution, friction per body id
    bat_mass: np.ndarray  # (n_bats,) kg
    bat_inertia: np.ndarray  # (n_bats, 3) kg m^2
    cloth_watch: np.ndarray | None = None  # (6,) box around a cloth net: inside it, tick by tick
    cloth_reach: np.ndarray | None = None  # (6,) box beyond which the ball cannot touch even an awake cloth net

    @property
    def flight(self) -> tuple:
        """The ball's flight model as engine.physics.collision.ball_tick takes it: (method, gravity,
        drag_k, magnus_k, rtol, atol)."""
        return (self.method, self.gravity, self.drag_k, self.magnus_k, self.scene.rtol, self.scene.atol)

    @property
    def geometry(self) -> tuple:
        """The static bodies as engine.physics.collision.ball_tick takes them: (table, floor_z, net, posts)."""
        return (self.table, self.floor_z, self.net, self.posts)


def build_model(scene: Scene) -> Model:
    """Derive the model of a scene: effect factors, geometry, ball and bat parameters."""
    fx = scene.effects
    mass, radius = equipment.BALL_MASS, equipment.BALL_RADIUS
    params = np.zeros(N_PARAMS)
    params[P_RADIUS] = radius
    params[P_MASS] = mass
    params[P_INERTIA] = equipment.BALL_INERTIA_FACTOR * mass * radius**2
    params[P_REST_SPEED] = equipment.REST_SPEED
    materials = np.zeros((len(Body), 2))
    for body, name in ((Body.TABLE, "table"), (Body.FLOOR, "floor"), (Body.NET, "net"), (Body.POST, "net"),
                       (Body.BAT_A, "bat"), (Body.BAT_B, "bat")):
        mat = scene.material(name)
        # Without the friction effect the contact is frictionless: no spin in contact.
        materials[body] = (mat.restitution, mat.friction if "friction" in fx else 0.0)
    model = Model(
        scene=scene,
        dt=scene.dt,
        method=METHODS[scene.integrator],
        gravity=scene.gravity if "gravity" in fx else None,
        drag_k=drag_factor(scene.drag_coefficient, scene.air_density, radius, mass) if "drag" in fx else None,
        magnus_k=magnus_factor(scene.magnus_coefficient, scene.air_density, radius, mass) if "magnus" in fx else None,
        table=TABLE_BOX.copy() if "table" in fx else None,
        floor_z=FLOOR_Z if "floor" in fx else None,
        net=NET_BOX.copy() if "net" in fx and scene.net_kind == "rigid" else None,
        posts=POST_BOXES.copy() if "net" in fx else None,
        ball_params=params,
        materials=materials,
        bat_mass=np.array([b.mass for b in scene.bats]),
        bat_inertia=np.array([disc_inertia(b.mass, b.radius) for b in scene.bats]).reshape(len(scene.bats), 3),
        cloth_watch=_cloth_watch(scene, radius) if "net" in fx and scene.net_kind == "cloth" else None,
        cloth_reach=_cloth_reach(scene, radius) if "net" in fx and scene.net_kind == "cloth" else None,
    )
    _check_start(model)
    return model


def _cloth_box(scene: Scene, reach: float) -> np.ndarray:
    """(6,) lo and hi corners of the box the cloth net is built in, grown by `reach` m."""
    half_width = scene.cloth.width / 2
    return np.array([-reach, -half_width - reach, -reach, reach, half_width + reach, scene.cloth.height + reach])


def _cloth_watch(scene: Scene, radius: float) -> np.ndarray:
    """The box in which the ball is stepped tick by tick with the cloth net: the net's own box
    grown by the ball's radius, the net's wake margin and two ticks at the fastest speed a
    scene allows, so no tick can carry the ball from outside it through the net."""
    return _cloth_box(scene, radius + WAKE_MARGIN + 2 * equipment.BALL_SPEED_MAX * scene.dt)


def _cloth_reach(scene: Scene, radius: float) -> np.ndarray:
    """The box out of which the ball cannot touch the cloth net within a tick, asleep or awake:
    no knot leaves the built box by more than NET_REACH (NetSim checks it every tick), the awake
    net's contact test reaches WAKE_MARGIN beyond its knots' box, and a tick carries the ball at
    most BALL_SPEED_MAX dt."""
    return _cloth_box(scene, radius + KNOT_RADIUS + WAKE_MARGIN + NET_REACH + equipment.BALL_SPEED_MAX * scene.dt)


def _check_start(model: Model) -> None:
    """Refuse a ball that starts inside a body: no physics can say which way it should leave."""
    scene = model.scene
    p = np.array(scene.ball.pos, dtype=float)
    radius = float(model.ball_params[P_RADIUS])
    n = np.zeros(3)
    bodies = []
    if model.table is not None:
        bodies.append(("the table", box_sdf(p, model.table, n)))
    if model.floor_z is not None:
        bodies.append(("the floor", p[2] - model.floor_z))
    if model.net is not None:
        bodies.append(("the net", box_sdf(p, model.net, n)))
        bodies += [("a net post", box_sdf(p, post, n)) for post in model.posts]
    for bat in scene.bats:
        axis = np.zeros(3)
        face_normal(np.array(bat.quat, dtype=float), axis)
        bodies.append((f"bat {bat.name}", disc_sdf(p, np.array(bat.pos, dtype=float), axis, bat.radius,
                                                   bat.half_thickness, n)))
    for name, distance in bodies:
        if distance - radius < -1e-9:
            raise SceneError(f"{scene.source}: ball.pos: the ball starts inside {name} (overlap "
                             f"{radius - distance:.4f} m); move it out")


class NetStepper(Protocol):
    """The cloth net as the engine steps it (_advance_with_cloth): net_kernel.NetSim, or a
    stand-in that does the same in another process and gives the same bits (the physics
    worker's, which asks the net worker). Any object with these members fits."""

    @property
    def sleeping(self) -> bool:
        """Asleep after the ticks done: its knots do not move until the ball touches it."""

    @property
    def in_tail(self) -> bool:
        """In its linear tail after the ticks done: its knots stay within the box it rings in."""

    def step_run(self, ball: np.ndarray, ball_radius: float, ball_inv_mass: float,
                 free_outside: np.ndarray) -> tuple[int, NetContact]:
        """A run of ticks with the ball near, up to the first that touches it (ball[j]: the (2, 3)
        position m and velocity m/s at tick j's start; radius m, 1/kg), each as step() or, while
        the net sleeps or rings in its tail and the ball lies outside `free_outside`, as
        step_free(1): NetSim.step_run's contract. Returns (ticks stepped, the last one's contact)."""

    def step_free(self, ticks: int) -> None:
        """`ticks` ticks of the net without the ball, which stayed out of its reach in them."""


@dataclass
class State:
    """Dynamic state: structured arrays (engine/physics/dtypes.py) plus the tick's preallocated scratch.

    ball, bats and world are views into one physics_snapshot_dtype record, `record`: the state
    is the snapshot, so publishing or tracing it is a single copy of bytes.
    """

    record: np.ndarray  # (1,) physics_snapshot_dtype
    ball: np.ndarray  # (1,) BALL_DTYPE view
    bats: np.ndarray  # (n_bats,) BAT_DTYPE view
    world: np.ndarray  # (1,) WORLD_DTYPE view
    ball_flat: np.ndarray  # (9,) float64 view of the ball: pos m, vel m/s, spin rad/s (the integrators' y)
    # Scratch, allocated once: a tick allocates nothing.
    bat_flat: np.ndarray
    bat_motion: np.ndarray
    work: np.ndarray
    scratch: np.ndarray
    adapt: np.ndarray
    event_rows: np.ndarray
    bat_tmp: np.ndarray
    # The cloth net (a scene with net kind "cloth"): a NetSim (initial_state), or a stand-in.
    net_sim: NetStepper | None = None
    # A run of ticks near the net (_advance_with_cloth): the ball at each tick's start, the state after each.
    run_ball: np.ndarray | None = None  # (NET_RUN_TICKS, 2, 3) m, m/s
    run_records: np.ndarray | None = None  # (NET_RUN_TICKS,) physics_snapshot_dtype
    record_bytes: np.ndarray | None = None  # (record's bytes,) uint8 view of `record`, for the run kernel
    run_bytes: np.ndarray | None = None  # (NET_RUN_TICKS, record's bytes) uint8 view of run_records


def initial_record(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """initial_state's physics record (a physics_snapshot_dtype array of one) and the bats'
    motion rows (n_bats, BAT_ROW), from the scene's initial conditions."""
    record = np.zeros(1, physics_snapshot_dtype(len(scene.bats)))
    ball = record["ball"]
    ball["pos"][0] = scene.ball.pos
    ball["vel"][0] = scene.ball.vel
    ball["spin"][0] = scene.ball.spin
    bats = record["bats"][0]
    for i, spec in enumerate(scene.bats):
        for field in ("pos", "quat", "vel", "ang_vel", "force", "torque"):
            bats[field][i] = getattr(spec, field)
    motion = np.zeros((len(scene.bats), BAT_ROW))
    for i, spec in enumerate(scene.bats):
        motion[i, BAT_RADIUS] = spec.radius
        motion[i, BAT_HALF_THICKNESS] = spec.half_thickness
    return record, motion


def initial_state(scene: Scene, topology: NetTopology | None = None,
                  start: tuple[np.ndarray, np.ndarray] | None = None) -> State:
    """State at tick 0 from the scene's initial conditions (start: initial_record(scene), made
    once, copied here); its cloth net (a NetSim, if the scene steps one) from `topology`, built
    from scene.cloth if None (engine.physics.compiled.CompiledScene.initial_state passes the run's)."""
    record, motion = initial_record(scene) if start is None else (start[0].copy(), start[1].copy())
    ball = record["ball"]
    bats = record["bats"][0]
    world = record["world"]
    net_sim = None
    if scene.cloth is not None and "net" in scene.effects:
        net_sim = NetSim(build_topology(scene.cloth) if topology is None else topology, scene.dt)
    state = State(
        record=record,
        ball=ball,
        bats=bats,
        world=world,
        ball_flat=ball.view("<f8"),
        bat_flat=bats.view("<f8").reshape(len(scene.bats), BAT_WIDTH),
        bat_motion=motion,
        work=np.zeros(WORK_SHAPE),
        scratch=np.zeros(SCRATCH_SHAPE),
        adapt=world["ball_adapt"][0],  # a view: dopri5 updates the world record in place
        event_rows=np.zeros((MAX_IMPACTS_PER_TICK, EVENT_ROW)),
        bat_tmp=np.zeros((3, 3)),
        net_sim=net_sim,
        run_ball=np.zeros((NET_RUN_TICKS, 2, 3)) if net_sim is not None else None,
    )
    if net_sim is not None:
        state.run_records = np.zeros(NET_RUN_TICKS, record.dtype)
        state.record_bytes = record.view(np.uint8)
        state.run_bytes = state.run_records.view(np.uint8).reshape(NET_RUN_TICKS, -1)
    return state


def copy_record(src: np.ndarray, dst: np.ndarray, index: int = 0) -> None:
    """dst[index] = src[0], byte for byte (numpy copies nested structured records field by field,
    which is far slower)."""
    dst.view(np.uint8).reshape(len(dst), -1)[index] = src.view(np.uint8)


def new_events() -> np.ndarray:
    """An events buffer large enough for any tick."""
    return np.zeros(MAX_IMPACTS_PER_TICK, CONTACT_DTYPE)


def _check_inputs(inputs: np.ndarray, n_bats: int) -> None:
    """Refuse malformed bat inputs before they touch the state."""
    if inputs.shape != (n_bats, 6):
        raise ValueError(f"bat inputs must have shape ({n_bats}, 6): force N and torque N m per bat; got {inputs.shape}")
    # One reduction: a sum is finite exactly when every term is (inf - inf is nan), unless finite
    # terms overflow it, in which case the precise check below runs and finds nothing wrong.
    if not math.isfinite(float(inputs.sum())) and not np.isfinite(inputs).all():
        bat, column = np.argwhere(~np.isfinite(inputs))[0]
        quantity = "force" if column < 3 else "torque"
        raise ValueError(f"bat {'ab'[bat]} {quantity}[{column % 3}] is {inputs[bat, column]}; inputs must be finite")


_BAT_FIELDS = tuple((name, BAT_DTYPE.fields[name][1] // 8, BAT_DTYPE.fields[name][0].shape[0])
                    for name in BAT_DTYPE.names)


def _check_bats(model: Model, state: State, when: str, verb: str, detail: str) -> None:
    """Raise SimulationError naming the first non-finite number of the bats' records (state,
    force, torque): called when engine.physics.tick.advance_ticks found one."""
    flat = state.bat_flat
    bat, column = np.argwhere(~np.isfinite(flat))[0]
    for name, start, size in _BAT_FIELDS:
        if start <= column < start + size:
            axis = ("w", "x", "y", "z")[column - start] if name == "quat" else "xyz"[column - start]
            quantity = f"{name}[{axis}]"
            break
    row = state.bats[bat]
    raise SimulationError(f"{when}: bat {model.scene.bats[bat].name}'s {quantity} {verb} {flat[bat, column]} "
                          f"{detail} (pos {row['pos'].tolist()}, vel {row['vel'].tolist()}, ang_vel "
                          f"{row['ang_vel'].tolist()}, force {row['force'].tolist()}, torque "
                          f"{row['torque'].tolist()}); inputs must be finite")


def step(model: Model, state: State, inputs: np.ndarray | None, events: np.ndarray, dt: float | None = None) -> int:
    """Advance the world by one tick, in place.

    Args:
        model: from build_model. state: from initial_state; mutated.
        inputs: (n_bats, 6) force N and torque N m per bat held over the tick, or None to keep
            the bats' current inputs.
        events: CONTACT_DTYPE array of at least MAX_IMPACTS_PER_TICK; the tick's impacts are written
            to its first n records.
        dt: tick length in s; the model's by default. 0 leaves the state unchanged.

    Returns:
        n, the number of contact events written.
    """
    ticks, n, _ = advance(model, state, 1, inputs, events, dt=dt)
    return n


def advance(model: Model, state: State, n_max: int, inputs: np.ndarray | None, events: np.ndarray,
            dt: float | None = None, gone_radius: float = math.inf, gone_z: float = -math.inf,
            deadline: float = math.inf, watch: np.ndarray | None = None) -> tuple[int, int, int]:
    """Advance up to n_max ticks in one kernel call (engine/physics/tick.py); stop after a tick with
    contact events, with the ball beyond gone_radius (m, horizontal) or below gone_z, with its
    support changed, or past the deadline (s of simulated time).

    Returns:
        (ticks done, events of the last tick written to `events`, the engine.physics.tick.STOP_* reason).
    """
    h = model.dt if dt is None else dt
    if state.net_sim is not None and h > 0.0:
        return _advance_with_cloth(model, state, n_max, inputs, events, h, gone_radius, gone_z, deadline)
    if h == 0.0 and watch is None and model.cloth_watch is not None:
        # A zero-length tick compiles (or loads) the kernels: with a cloth net, the watched
        # variant too, which a worker would otherwise compile mid-run, silent for as long as
        # that takes (tens of seconds on a loaded machine: the supervisor took it for a stall).
        advance(model, state, n_max, None, events, h, gone_radius, gone_z, deadline, model.cloth_watch)
        if state.run_bytes is not None:
            _advance_run_kernel(model, state, 0, h, gone_radius, gone_z, deadline)  # a run of no ticks
    return _advance_kernel(model, state, n_max, inputs, events, h, gone_radius, gone_z, deadline, watch)


def _advance_kernel(model: Model, state: State, n_max: int, inputs: np.ndarray | None, events: np.ndarray, h: float,
                    gone_radius: float, gone_z: float, deadline: float, watch: np.ndarray | None) -> tuple[int, int, int]:
    """advance()'s kernel call for the ball and bats alone (a cloth net, if any, is the caller's to step)."""
    has_bats = len(state.bats) > 0
    _apply_inputs(state, inputs)
    tick = int(state.world[0]["tick"])
    # The bats' records may be written around _check_inputs (a restored record, a worker's
    # mailbox): the kernel refuses to step from a non-finite one (ERR_BATS_BEFORE, the state
    # untouched) and checks them again after its run (ERR_BATS_AFTER); _check_bats names it.
    ticks, n, reason, error = advance_ticks(
        n_max, h, state.world, state.bat_flat if has_bats else None, model.bat_mass, model.bat_inertia,
        state.bat_motion if has_bats else None, state.bat_tmp, state.ball_flat[0:9], model.method, model.gravity,
        model.drag_k, model.magnus_k, model.scene.rtol, model.scene.atol, model.table, model.floor_z, model.net,
        model.posts, model.ball_params, model.materials, state.work, state.scratch, state.adapt, state.event_rows,
        gone_radius * gone_radius, gone_z, deadline, watch)
    if error:
        _raise_advance(error, tick, ticks, model, state)
    if n:
        _copy_events(state, events, n, int(state.world[0]["tick"]) - 1)
    return ticks, n, reason


def _apply_inputs(state: State, inputs: np.ndarray | None) -> None:
    """The bats' force and torque for the ticks to come (checked first); None keeps what they hold."""
    if inputs is not None and len(state.bats) > 0:
        _check_inputs(inputs, len(state.bats))
        state.bat_flat[:, FORCE_AT:FORCE_AT + 3] = inputs[:, 0:3]
        state.bat_flat[:, TORQUE_AT:TORQUE_AT + 3] = inputs[:, 3:6]


def _raise_advance(error: int, tick: int, ticks: int, model: Model, state: State) -> None:
    """Raise SimulationError for a tick kernel's error code, after `ticks` ticks from `tick`."""
    if error == ERR_BATS_BEFORE:
        _check_bats(model, state, f"tick {tick}", "is", "before the tick; nothing was stepped")
    elif error == ERR_BATS_AFTER:
        _check_bats(model, state, f"ticks {tick}..{tick + ticks}", "became", "during the kernel's run")
    _raise(error, tick + ticks, model, state)


def _advance_with_cloth(model: Model, state: State, n_max: int, inputs, events, h: float, gone_radius: float,
                        gone_z: float, deadline: float) -> tuple[int, int, int]:
    """advance() with a cloth net: the ball's ticks by the kernel, and near the net (or while the
    net is awake) a tick at a time in runs, the net stepping each with the ball's contact
    (net_kernel.NetSim.step_run: the net moves the ball by `offset` and gives it `impulse`). The net
    cannot press the ball into the table, and a bat that presses the ball into the net is stopped
    by it (the bats do not collide with the cloth itself; _bats_pressing, _stop_bat).

    Out of the net's reach (model.cloth_reach) the ball's ticks run in one kernel call and the net
    is then stepped as many ticks without it (NetSim.step_free): neither depends on the other
    there, so a worker's net may do them while the physics goes on. Near the net it steps runs of
    ticks (_run_near_net) and returns after every run the net was stepped with the ball (STOP_NET,
    unless another reason): a caller that publishes its state after each call then always has a
    state the net's agrees with, which a restarted net or physics worker resumes from exactly.
    `state.net_sim` is a NetSim, or a stand-in with its contract (NetStepper: the physics
    worker's, which asks the net worker).
    """
    net: NetStepper = state.net_sim
    y = state.ball_flat
    mass = float(model.ball_params[P_MASS])
    radius = float(model.ball_params[P_RADIUS])
    done = 0
    while done < n_max:
        if not _in_box(model.cloth_reach, y):
            ticks, n, reason = _advance_kernel(model, state, n_max - done, inputs, events, h, gone_radius, gone_z,
                                               deadline, model.cloth_reach)
            inputs = None
            done += ticks
            net.step_free(ticks)
            if reason != STOP_WATCH:
                return done, n, reason
            continue
        w = model.cloth_watch
        if (net.sleeping or net.in_tail) and not _in_box(w, y):
            # Far from a sleeping net, or from one whose ring is in closed form (its knots stay
            # within the watched box): nothing to do for it but count the ticks (a sleeping net
            # ignores them); run until the ball comes near.
            ticks, n, reason = _advance_kernel(model, state, n_max - done, inputs, events, h, gone_radius, gone_z,
                                               deadline, w)
            inputs = None
            done += ticks
            net.step_free(ticks)
            if reason != STOP_WATCH:
                return done, n, reason
            continue
        taken, n, reason, contact = _run_near_net(model, state, min(n_max - done, NET_RUN_TICKS), inputs, events, h,
                                                  gone_radius, gone_z, deadline)
        inputs = None
        done += taken
        if contact.toi != NO_CONTACT:
            p0, v0 = state.run_ball[taken - 1]
            pressing = _bats_pressing(model, state, events[:n], y[0:3], radius, contact.impulse)
            if pressing:
                # Squeezed between a bat and the cloth net, the ball takes the net's path alone (its
                # straight path plus the net's offset), not the bat's push, and stops the bat (below):
                # the net holds the ball as the table or the rigid net do (engine.physics.collision._project_out).
                y[0:3] = p0 + v0 * h
                y[3:6] = v0
            y[0:3] += contact.offset
            y[3:6] += contact.impulse / mass
            if model.table is not None:
                _out_of_table(model.table, y, radius)
            for b in pressing:
                _stop_bat(model, state, b, y[0:3], radius)
            _net_event(state, events, n, p0, v0, contact, h)
            n += 1
            reason = STOP_EVENT
        return done, n, STOP_NET if reason == STOP_LIMIT else reason
    return done, 0, STOP_LIMIT


def _run_near_net(model: Model, state: State, n_max: int, inputs, events: np.ndarray, h: float, gone_radius: float,
                  gone_z: float, deadline: float) -> tuple[int, int, int, NetContact]:
    """_advance_with_cloth's ticks near the net: the ball's ticks without the net, up to n_max (at
    most NET_RUN_TICKS), a tick that needs the caller (an event, any STOP_* but the limit), or the
    ball leaving the net's reach, in one kernel call (engine.physics.tick.advance_run, which keeps the
    ball at each tick's start and the state after each tick); then the net's run over them
    (NetStepper.step_run), which stops at the first tick that touches the ball. The ticks after
    that one are undone (back to the state kept after it), so the result is the same bits as a
    tick at a time: only the ball's ticks before a touch are stepped without the net, and those a
    tick at a time would step so too. A worker's net answers the whole run in one hand-off.

    Returns:
        (ticks kept, events of the last kept tick in `events`, its STOP_* reason, the net's contact
        in it, or one with NO_CONTACT).
    """
    records = state.run_records
    _apply_inputs(state, inputs)
    tick = int(state.world[0]["tick"])
    k, n, reason, error = _advance_run_kernel(model, state, n_max, h, gone_radius, gone_z, deadline)
    if error:
        _raise_advance(error, tick, k, model, state)
    if n:
        _copy_events(state, events, n, tick + k - 1)
    mass = float(model.ball_params[P_MASS])
    taken, contact = state.net_sim.step_run(state.run_ball[:k], float(model.ball_params[P_RADIUS]), 1.0 / mass,
                                            model.cloth_watch)
    if taken < k:  # the net touched the ball before the run's last tick: back to the state after that tick
        copy_record(records[taken - 1:taken], state.record)
        n, reason = 0, STOP_LIMIT
    return taken, n, reason, contact


def _advance_run_kernel(model: Model, state: State, n_max: int, h: float, gone_radius: float, gone_z: float,
                        deadline: float) -> tuple[int, int, int, int]:
    """engine.physics.tick.advance_run on the state's arrays: (ticks, events, STOP_* reason, error code)."""
    has_bats = len(state.bats) > 0
    return advance_run(
        n_max, h, state.world, state.bat_flat if has_bats else None, model.bat_mass, model.bat_inertia,
        state.bat_motion if has_bats else None, state.bat_tmp, state.ball_flat[0:9], model.method, model.gravity,
        model.drag_k, model.magnus_k, model.scene.rtol, model.scene.atol, model.table, model.floor_z, model.net,
        model.posts, model.ball_params, model.materials, state.work, state.scratch, state.adapt, state.event_rows,
        gone_radius * gone_radius, gone_z, deadline, model.cloth_reach, state.record_bytes, state.run_ball,
        state.run_bytes)


def _bats_pressing(model: Model, state: State, events: np.ndarray, ball_pos: np.ndarray, radius: float,
                   impulse: np.ndarray) -> list[int]:
    """The bats that press the ball into the cloth net: each struck the ball in this tick (`events`,
    the tick's contacts) or touches it at ball_pos (m; within CONTACT_TOL) at its end, while the
    net's impulse (N s) pushes the ball back towards it (against its outward normal)."""
    pressing = []
    axis, normal = np.zeros(3), np.zeros(3)
    for b in range(len(state.bats)):
        struck = any(ev["body"] == Body.BAT_A + b and float(impulse @ ev["normal"]) < 0.0 for ev in events)
        face_normal(state.bats["quat"][b], axis)
        bat = model.scene.bats[b]
        gap = disc_sdf(ball_pos, state.bats["pos"][b], axis, bat.radius, bat.half_thickness, normal) - radius
        if struck or (gap <= CONTACT_TOL and float(impulse @ normal) < 0.0):
            pressing.append(b)
    return pressing


def _stop_bat(model: Model, state: State, b: int, ball_pos: np.ndarray, radius: float) -> None:
    """Bat b, pressing the ball at ball_pos (m) into the cloth net, is stopped there in place: moved
    back along its outward normal at the ball until it just touches it, its velocity towards the
    ball taken away (a player's bat pressed against a net is held by it)."""
    axis, normal = np.zeros(3), np.zeros(3)
    face_normal(state.bats["quat"][b], axis)
    bat = model.scene.bats[b]
    gap = disc_sdf(ball_pos, state.bats["pos"][b], axis, bat.radius, bat.half_thickness, normal) - radius
    if gap < 0.0:
        state.bats["pos"][b] += gap * normal
    towards = float(state.bats["vel"][b] @ normal)
    if towards > 0.0:
        state.bats["vel"][b] -= towards * normal


def _out_of_table(table: np.ndarray, y: np.ndarray, radius: float) -> None:
    """Move the ball (y: its flat state) out of the table along the surface's normal and take away
    its velocity into it, in place: the cloth net's knots stop on the playing surface
    (net_kernel/kernels/table.py) and cannot press the ball into it either (the tick kernel's
    static-body projection, engine.physics.collision._project_once)."""
    normal = np.zeros(3)
    gap = box_sdf(y[0:3], table, normal) - radius
    if gap < 0.0:
        y[0:3] -= gap * normal
        inward = float(y[3:6] @ normal)
        if inward < 0.0:
            y[3:6] -= inward * normal


def _in_box(box: np.ndarray, y: np.ndarray) -> bool:
    """Is the ball's centre (y[0:3]) inside the (6,) lo, hi box (the tick kernel's watch test)?"""
    x, y1, z = y[0:3].tolist()  # Python floats: the same doubles, cheaper comparisons
    lo_x, lo_y, lo_z, hi_x, hi_y, hi_z = box.tolist()
    return lo_x <= x <= hi_x and lo_y <= y1 <= hi_y and lo_z <= z <= hi_z


def _net_event(state: State, events: np.ndarray, k: int, p0, v0, contact, h: float) -> None:
    """Record the cloth net's contact as event k of the tick that just ended."""
    world = state.world[0]
    world["n_events"] += 1
    world["events_total"] += 1
    impulse = np.asarray(contact.impulse)
    strength = float(np.linalg.norm(impulse))
    normal = impulse / strength if strength > 0 else np.zeros(3)
    ev = events[k]
    ev["tick"] = int(world["tick"]) - 1
    ev["time"] = float(world["time"]) - h + contact.toi * h
    ev["body"] = Body.NET
    ev["pos"] = p0 + v0 * contact.toi * h
    ev["normal"] = normal
    ev["vel_in"] = v0
    ev["vel_out"] = state.ball_flat[3:6]
    ev["spin_in"] = state.ball_flat[6:9]
    ev["spin_out"] = state.ball_flat[6:9]
    ev["normal_speed"] = max(0.0, -float(v0 @ normal))


def _raise(error: int, tick: int, model: Model, state: State) -> None:
    if error == ERR_SUBSTEPS:
        raise SimulationError(f"tick {tick}: the adaptive integrator needed more than its substep limit; "
                              f"loosen rtol/atol (now {model.scene.rtol}, {model.scene.atol}) or shorten dt")
    if error == ERR_IMPACTS:
        raise SimulationError(f"tick {tick}: more than {MAX_IMPACTS_PER_TICK} impacts in one tick "
                              "(the ball is trapped between bodies); shorten dt")
    if error == ERR_NONFINITE:
        index = int(state.scratch[7, 0])
        quantity = f"{('pos', 'vel', 'spin')[index // 3]}[{'xyz'[index % 3]}]"
        raise SimulationError(f"tick {tick}: the ball's {quantity} would become non-finite (from pos "
                              f"{state.ball['pos'][0].tolist()}, vel {state.ball['vel'][0].tolist()}); "
                              "the state was left as it was before the tick")
    raise SimulationError(f"tick {tick}: the tick kernel failed with code {error}")


def _copy_events(state: State, events: np.ndarray, n: int, tick: int) -> None:
    """The last tick's event rows into CONTACT_DTYPE records (rare: a few per second)."""
    for k in range(n):
        row = state.event_rows[k]
        ev = events[k]
        ev["tick"] = tick
        ev["time"] = row[0]
        ev["body"] = int(row[1])
        ev["pos"] = row[2:5]
        ev["normal"] = row[5:8]
        ev["vel_in"] = row[8:11]
        ev["vel_out"] = row[11:14]
        ev["spin_in"] = row[14:17]
        ev["spin_out"] = row[17:20]
        ev["normal_speed"] = row[20]
