"""The accuracy study's shots and runs: each shot's DOP853 reference trajectory and the engine's
run of it with one integrator configuration, compared, and timed.

For a shot (bench.accuracy.SHOTS) through two bounces, reference_shot integrates the ball's
equations with scipy's DOP853, locating every impact by event detection and resolving it by the
engine's own contact model (engine.physics.contact.impact), then restarting; run_case runs the engine's
tick (engine.physics.collision.ball_tick, impacts located inside the tick, or for contrast at its end)
and samples it like the reference; compare measures landing, apex, smooth-flight and final
errors and the energy drift. time_cases and step_cost time the configurations (compiled first).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from engine.physics import reference as engine_reference
from engine.physics.collision import (
    E_BODY,
    E_POS,
    E_TIME,
    E_VEL_IN,
    E_VEL_OUT,
    EVENT_ROW,
    MAX_IMPACTS_PER_TICK,
    P_INERTIA,
    P_MASS,
    P_RADIUS,
    SCRATCH_SHAPE,
    ball_tick,
)
from engine.physics.contact import impact
from engine.physics.geometry import Body
from engine.physics.integrators import ADAPT_SIZE, METHODS, WORK_SHAPE, advance
from engine.physics.scene import Scene, parse_scene, with_overrides
from engine.physics.world import Model, build_model, initial_state, new_events, step

EFFECTS = ("gravity", "drag", "magnus", "friction", "table", "floor")
DOPRI5_ATOL_PER_RTOL = 1e-3  # atol = 1e-3 rtol: 1 mm per unit of rtol on a metre-sized state
REFERENCE_TOL = 1e-12  # issue 9: DOP853 at rtol = atol ~ 1e-12
AFTER_LAST_BOUNCE = 0.1  # s of flight after the second bounce that every run also covers
GRID = 0.04  # s: sample times are multiples of this, so every tick size of the study divides them
MISSED = math.inf  # an impact or apex that a run does not have at all


@dataclass(frozen=True)
class Shot:
    """A standard shot: the ball's initial state, world frame, SI units."""

    name: str
    description: str
    pos: tuple[float, float, float]
    vel: tuple[float, float, float]
    spin: tuple[float, float, float]


# Initial conditions chosen so that each shot really bounces twice (checked by the reference,
# see tests/engine/test_accuracy.py): spin about +y is topspin for a ball travelling along +x.
SHOTS = (
    Shot("drop", "dropped from 30 cm: two table bounces (ITTF 2.1.3)", (0.5, 0.2, 0.32), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    Shot("topspin_loop", "7.6 m/s, 150 rad/s topspin from behind A's end: B's court, then the floor",
         (-1.6, 0.1, 0.30), (7.2, -0.3, 2.4), (0.0, 150.0, 0.0)),
    Shot("backspin_push", "3.4 m/s, 120 rad/s backspin from near the net: twice on B's court",
         (-0.55, 0.0, 0.12), (3.2, 0.2, 1.2), (0.0, -120.0, 0.0)),
    Shot("smash", "30 m/s, light topspin, hit down from 80 cm: B's court, then the floor",
         (-1.0, 0.1, 0.80), (28.0, -1.5, -10.6), (0.0, 40.0, 0.0)),
)


def shot_scene(shot: Shot, integrator: str = "verlet", dt: float = 0.001, rtol: float = 1e-6,
               atol: float = 1e-9) -> Scene:
    """The scene of a shot: gravity, drag, Magnus, friction, the table and the floor; no net, no bats."""
    data = {"name": shot.name, "effects": list(EFFECTS), "integrator": integrator, "dt": dt,
            "rtol": rtol, "atol": atol,
            "ball": {"pos": list(shot.pos), "vel": list(shot.vel), "spin": list(shot.spin)}}
    return parse_scene(data, f"bench/trajectories.py:{shot.name}")


def energy(y: np.ndarray, model: Model) -> float:
    """Mechanical energy of the ball, J: translational + rotational + potential (z = 0 at the table)."""
    mass, inertia = model.ball_params[P_MASS], model.ball_params[P_INERTIA]
    return float(0.5 * mass * y[3:6] @ y[3:6] + 0.5 * inertia * y[6:9] @ y[6:9] + mass * (model.gravity or 0.0) * y[2])


# ---------------------------------------------------------------------------------------------
# The reference
# ---------------------------------------------------------------------------------------------

@dataclass
class Trajectory:
    """What a run of a shot produced.

    impacts: (n, 8) time s, body id, centre pos (3,) m, vel_in z and vel_out z m/s, unused 0.
    apexes: (n, 2) time s, centre height m. smooth: (9,) state at t_smooth. final: (9,) at t_end.
    """

    impacts: np.ndarray
    apexes: np.ndarray
    smooth: np.ndarray
    final: np.ndarray
    t_smooth: float
    t_end: float


def reference_shot(shot: Shot, tol: float = REFERENCE_TOL, t_smooth: float | None = None,
                   t_end: float | None = None) -> Trajectory:
    """The shot by scipy's DOP853 at rtol = atol = tol, every impact located by event detection.

    Flight uses the engine's forces (engine.physics.reference.ball_accel, the numpy twin); impacts on the
    table's top and the floor use engine.physics.contact.impact with the scene's materials on the exact
    state at contact (gap 0), then the integration restarts. A crossing of the table's plane
    outside its footprint is no impact (the ball falls past the table's end). Without t_end the
    shot runs until AFTER_LAST_BOUNCE after its second bounce, rounded up to GRID.
    """
    from scipy.integrate import solve_ivp

    model = build_model(shot_scene(shot))
    radius = float(model.ball_params[P_RADIUS])
    half_x, half_y = float(model.table[3]), float(model.table[4])
    top = float(model.table[2] + model.table[5])

    def rhs(_t, y):
        acc = np.empty(3)
        engine_reference.ball_accel(y[3:6], y[6:9], model.gravity, model.drag_k, model.magnus_k, acc)
        return np.concatenate([y[3:6], acc, np.zeros(3)])

    def table_plane(_t, y):
        return y[2] - radius - top

    def floor_plane(_t, y):
        return y[2] - radius - model.floor_z

    def apex(_t, y):
        return y[5]

    for event in (table_plane, floor_plane):
        event.terminal, event.direction = True, -1
    apex.direction = -1

    horizon = 3.0 if t_end is None else t_end
    t, y = 0.0, np.concatenate([shot.pos, shot.vel, shot.spin]).astype(float)
    impacts, apexes = [], []
    samples: dict[float, np.ndarray] = {}
    table_live = True
    while t < horizon:
        events = [table_plane, floor_plane, apex] if table_live else [floor_plane, apex]
        wanted = [s for s in (t_smooth, t_end) if s is not None and t <= s <= horizon]
        sol = solve_ivp(rhs, (t, horizon), y, method="DOP853", rtol=tol, atol=tol, events=events,
                        dense_output=True)
        seg_end = sol.t[-1]
        for s in wanted:
            if s <= seg_end:
                samples[s] = sol.sol(s)
        for t_apex, y_apex in zip(sol.t_events[-1], sol.y_events[-1]):
            if t_apex > 1e-9:  # a ball released at rest starts at an apex; the engine does not see it
                apexes.append((t_apex, y_apex[2]))
        if sol.status != 1:
            break
        which = 0 if (table_live and len(sol.t_events[0])) else (1 if table_live else 0)
        t, y = float(sol.t_events[which][0]), sol.y_events[which][0].copy()
        if table_live and which == 0:
            if abs(y[0] - model.table[0]) > half_x or abs(y[1] - model.table[1]) > half_y:
                table_live = False  # past the table's end or side: only the floor is left below
                continue
            body = Body.TABLE
        else:
            body = Body.FLOOR
        vel_in = y[3:6].copy()
        vel, spin = y[3:6].copy(), y[6:9].copy()
        impact(vel, spin, np.array([0.0, 0.0, 1.0]), np.zeros(3), radius, float(model.ball_params[P_MASS]),
               float(model.ball_params[P_INERTIA]), float(model.materials[body, 0]),
               float(model.materials[body, 1]), vel, spin)
        y[3:6], y[6:9] = vel, spin
        impacts.append((t, int(body), *y[0:3], vel_in[2], vel[2], 0.0))
        if t_end is None and len(impacts) == 2:
            horizon = math.ceil((t + AFTER_LAST_BOUNCE) / GRID) * GRID
    impacts_arr = np.array(impacts, dtype=float).reshape(-1, 8)
    if t_end is None:
        first = impacts_arr[0, 0]
        t_smooth = math.floor(0.9 * first / GRID) * GRID
        # Second pass: the same integration, now sampling the smooth-flight and final states.
        return reference_shot(shot, tol, t_smooth, horizon)
    return Trajectory(impacts=impacts_arr, apexes=np.array(apexes, dtype=float).reshape(-1, 2),
                      smooth=samples[t_smooth], final=samples[t_end], t_smooth=t_smooth, t_end=t_end)


# ---------------------------------------------------------------------------------------------
# The engine's runs (numba loops: the per-tick Python overhead of step would hide the kernels)
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def _simulate(y0, h, n_ticks, smooth_tick, method, gravity, drag_k, magnus_k, rtol, atol, table, floor_z,
              params, materials, impacts, apexes, smooth_out, record):
    """Run the engine's tick n_ticks times from y0; y0 is overwritten with the final state.

    With record, impacts, apexes and the state after smooth_tick ticks are written; apexes are
    located on the integrator's own step: bisection on the vertical velocity of advance(state at
    the tick's start, tau), to round-off. Without record the loop is the engine's tick and
    nothing else (the timed loop; one compiled function serves both, which halves compile time).
    Returns (error code or 0, impacts, apexes).
    """
    y = y0.copy()
    prev = np.zeros(9)
    trial = np.zeros(9)
    work = np.zeros(WORK_SHAPE)
    scratch = np.zeros(SCRATCH_SHAPE)
    adapt = np.zeros(ADAPT_SIZE)
    adapt_prev = np.zeros(ADAPT_SIZE)
    adapt_try = np.zeros(ADAPT_SIZE)
    events = np.zeros((MAX_IMPACTS_PER_TICK, EVENT_ROW))
    support = 0
    n_imp = 0
    n_apex = 0
    for tick in range(n_ticks):
        if record:
            prev[:] = y
            adapt_prev[:] = adapt
        n, support = ball_tick(y, h, support, (method, gravity, drag_k, magnus_k, rtol, atol), (table, floor_z, None, None),
                               None, params, materials, work, scratch, adapt, events)
        if n < 0:
            return n, n_imp, n_apex
        if not record:
            continue
        for k in range(n):
            if n_imp < impacts.shape[0]:
                row = impacts[n_imp]
                row[0] = tick * h + events[k, E_TIME]
                row[1] = events[k, E_BODY]
                row[2] = events[k, E_POS]
                row[3] = events[k, E_POS + 1]
                row[4] = events[k, E_POS + 2]
                row[5] = events[k, E_VEL_IN + 2]
                row[6] = events[k, E_VEL_OUT + 2]
            n_imp += 1
        if n == 0 and support == 0 and prev[5] > 0.0 and y[5] <= 0.0 and n_apex < apexes.shape[0]:
            lo = 0.0
            hi = h
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                adapt_try[:] = adapt_prev
                advance(prev, mid, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt_try, trial)
                if trial[5] > 0.0:
                    lo = mid
                else:
                    hi = mid
            adapt_try[:] = adapt_prev
            advance(prev, lo, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt_try, trial)
            apexes[n_apex, 0] = tick * h + lo
            apexes[n_apex, 1] = trial[2]
            n_apex += 1
        if tick + 1 == smooth_tick:
            smooth_out[:] = y
    y0[:] = y
    return 0, n_imp, n_apex


@njit(cache=True)
def _simulate_tick_end(y0, h, n_ticks, smooth_tick, method, gravity, drag_k, magnus_k, table, floor_z,
                       params, materials, impacts, smooth_out):
    """The textbook contrast: integrate the whole tick, and if the ball ended it inside the table's
    top or the floor, put it back on the surface and apply the impact there (no location in the tick).
    """
    y = y0.copy()
    out = np.zeros(9)
    work = np.zeros(WORK_SHAPE)
    adapt = np.zeros(ADAPT_SIZE)
    normal = np.array([0.0, 0.0, 1.0])
    still = np.zeros(3)
    radius = params[0]
    top = table[2] + table[5]
    n_imp = 0
    for tick in range(n_ticks):
        advance(y, h, method, gravity, drag_k, magnus_k, 1e-6, 1e-9, work, adapt, out)
        body = 0
        surface = 0.0
        over_table = abs(out[0] - table[0]) <= table[3] and abs(out[1] - table[1]) <= table[4]
        if over_table and out[2] - radius < top and y[2] - radius >= top:
            body = 1
            surface = top
        elif out[2] - radius < floor_z:
            body = 2
            surface = floor_z
        if body != 0 and out[5] < 0.0:
            vz_in = out[5]
            out[2] = surface + radius
            impact(out[3:6], out[6:9], normal, still, radius, params[1], params[2], materials[body, 0],
                   materials[body, 1], out[3:6], out[6:9])
            if n_imp < impacts.shape[0]:
                row = impacts[n_imp]
                row[0] = (tick + 1) * h
                row[1] = body
                row[2] = out[0]
                row[3] = out[1]
                row[4] = out[2]
                row[5] = vz_in
                row[6] = out[5]
            n_imp += 1
        y[:] = out
        if tick + 1 == smooth_tick:
            smooth_out[:] = y
    y0[:] = y
    return n_imp


@dataclass
class Case:
    """One integrator configuration of the study."""

    method: str
    h: float
    rtol: float = 1e-6
    tick_end: bool = False  # the contrast run: impacts at the end of the tick

    @property
    def label(self) -> str:
        if self.method == "dopri5":
            return f"dopri5 tick {self.h * 1e3:g} ms"
        return self.method + (" (impact at tick end)" if self.tick_end else "")

    @property
    def atol(self) -> float:
        return self.rtol * DOPRI5_ATOL_PER_RTOL


def _model_args(model: Model):
    return (model.gravity, model.drag_k, model.magnus_k)


def run_case(case: Case, shot: Shot, ref: Trajectory) -> Trajectory:
    """The engine's run of one shot with one configuration, sampled like the reference."""
    model = build_model(shot_scene(shot))
    n_ticks = int(round(ref.t_end / case.h))
    smooth_tick = int(round(ref.t_smooth / case.h))
    y = np.concatenate([shot.pos, shot.vel, shot.spin]).astype(float)
    impacts = np.full((16, 8), np.nan)
    apexes = np.full((16, 2), np.nan)
    smooth = np.full(9, np.nan)
    method = METHODS[case.method]
    if case.tick_end:
        n_imp = _simulate_tick_end(y, case.h, n_ticks, smooth_tick, method, *_model_args(model), model.table,
                                   model.floor_z, model.ball_params, model.materials, impacts, smooth)
        n_apex = 0
    else:
        code, n_imp, n_apex = _simulate(y, case.h, n_ticks, smooth_tick, method, *_model_args(model), case.rtol,
                                        case.atol, model.table, model.floor_z, model.ball_params, model.materials,
                                        impacts, apexes, smooth, True)
        if code < 0:
            y[:] = np.nan
    return Trajectory(impacts=impacts[:min(n_imp, 16)], apexes=apexes[:min(n_apex, 16)], smooth=smooth, final=y,
                      t_smooth=ref.t_smooth, t_end=ref.t_end)


def compare(run: Trajectory, ref: Trajectory, model: Model) -> dict:
    """Errors of a run against the reference: landing (worst impact), apex (worst), energy drift,
    smooth-flight position error, final position error; m unless named otherwise."""
    n_ref = len(ref.impacts)
    if len(run.impacts) < n_ref or not np.all(run.impacts[:n_ref, 1] == ref.impacts[:, 1]):
        landing = MISSED
    else:
        landing = float(np.max(np.linalg.norm(run.impacts[:n_ref, 2:5] - ref.impacts[:, 2:5], axis=1)))
    apexes = ref.apexes[ref.apexes[:, 0] < ref.t_end]
    if len(run.apexes) < len(apexes):
        apex = MISSED
    else:
        apex = float(np.max(np.abs(run.apexes[:len(apexes), 1] - apexes[:, 1]))) if len(apexes) else 0.0
    e0 = energy(ref_initial(ref, model), model)
    radius = float(model.ball_params[P_RADIUS])
    surface = np.where(run.impacts[:, 1] == int(Body.FLOOR), model.floor_z, model.table[2] + model.table[5])
    gaps = run.impacts[:, 4] - radius - surface
    return {
        "max_impact_gap_m": float(np.max(gaps)) if len(gaps) else None,
        "landing_m": landing,
        "apex_m": apex,
        "energy_drift": (energy(run.final, model) - energy(ref.final, model)) / e0 if np.all(np.isfinite(run.final)) else MISSED,
        "smooth_m": float(np.linalg.norm(run.smooth[0:3] - ref.smooth[0:3])),
        "final_m": float(np.linalg.norm(run.final[0:3] - ref.final[0:3])),
        "impacts": int(len(run.impacts)),
    }


def ref_initial(ref: Trajectory, model: Model) -> np.ndarray:
    """The shot's initial state (kept on the model's scene)."""
    ball = model.scene.ball
    return np.concatenate([ball.pos, ball.vel, ball.spin]).astype(float)


def _timed(fn, repeats: int) -> tuple[float, float]:
    """Median wall time of fn() over repeats, and the spread (max - min) / median."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    med = statistics.median(times)
    return med, (max(times) - min(times)) / med if med > 0 else 0.0


def _timing_runs(case: Case, shots, refs):
    """One closure per shot that runs the engine's tick loop over the shot, and the simulated seconds."""
    out = []
    for shot in shots:
        model = build_model(shot_scene(shot))
        n_ticks = int(round(refs[shot.name].t_end / case.h))
        y = np.concatenate([shot.pos, shot.vel, shot.spin]).astype(float)
        buffers = (np.zeros((16, 8)), np.zeros((16, 2)), np.zeros(9))
        args = (case.h, n_ticks, 0, METHODS[case.method], *_model_args(model), case.rtol, case.atol, model.table,
                model.floor_z, model.ball_params, model.materials, *buffers, False)
        out.append((lambda y=y, args=args: _simulate(y.copy(), *args), n_ticks * case.h))
    return out


MIN_SAMPLE_S = 0.05


def time_cases(cases, shots, refs, repeats: int) -> dict[int, tuple[float, float]]:
    """Wall seconds per simulated second of each case's tick loop over all shots, and its spread
    (max - min) / median over the repeats. The cases are timed round by round, interleaved, so a
    drift in the machine's load hits them all alike and the ratios between them stay fair."""
    runs = {i: _timing_runs(case, shots, refs) for i, case in enumerate(cases)}
    # A sample shorter than the scheduler's time slice measures the other engineers' processes:
    # each sample repeats the case's runs until it lasts at least MIN_SAMPLE_S.
    loops = {}
    for i, shot_runs in runs.items():
        start = time.perf_counter()
        for fn, _sim in shot_runs:
            fn()
        loops[i] = max(1, math.ceil(MIN_SAMPLE_S / max(time.perf_counter() - start, 1e-6)))
    times: dict[int, list[float]] = {i: [] for i in runs}
    for _ in range(repeats):
        for i, shot_runs in runs.items():
            start = time.perf_counter()
            for _loop in range(loops[i]):
                for fn, _sim in shot_runs:
                    fn()
            times[i].append((time.perf_counter() - start) / loops[i])
    out = {}
    for i, ts in times.items():
        sim = sum(s for _fn, s in runs[i])
        med = statistics.median(ts)
        out[i] = (med / sim, (max(ts) - min(ts)) / med if med > 0 else 0.0)
    return out


def compile_kernels() -> float:
    """Compile (or load from cache) every kernel the study times; returns the seconds it took."""
    start = time.perf_counter()
    shot = SHOTS[0]
    model = build_model(shot_scene(shot))
    y = np.concatenate([shot.pos, shot.vel, shot.spin]).astype(float)
    _simulate(y.copy(), 1e-3, 1, 1, 0, *_model_args(model), 1e-6, 1e-9, model.table, model.floor_z,
              model.ball_params, model.materials, np.zeros((16, 8)), np.zeros((16, 2)), np.zeros(9), True)
    _simulate_tick_end(y.copy(), 1e-3, 1, 1, 0, *_model_args(model), model.table, model.floor_z,
                       model.ball_params, model.materials, np.zeros((16, 8)), np.zeros(9))
    state = initial_state(model.scene)
    step(model, state, None, new_events(), dt=0.0)
    return time.perf_counter() - start


def step_cost(shot: Shot, methods, dt: float, repeats: int) -> dict:
    """Per-tick cost through engine.physics.world.step (Python orchestration included), µs per tick."""
    out = {}
    events = new_events()
    for name in methods:
        scene = with_overrides(shot_scene(shot), integrator=name, dt=dt)
        model = build_model(scene)
        n_ticks = int(round(2.0 / dt))

        def one_run():
            state = initial_state(scene)
            for _ in range(n_ticks):
                step(model, state, None, events)

        step(model, initial_state(scene), None, events, dt=0.0)  # compile or load first
        med, spread = _timed(one_run, repeats)
        out[name] = {"us_per_tick": med / n_ticks * 1e6, "s_per_sim_s": med / (n_ticks * dt), "spread": spread}
    return out
