"""The bat AI's player: BatAI thinks a stroke out and plans the bat's path to it."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from engine.physics import equipment
from engine.physics.collision import ERR_SUBSTEPS, EVENT_ROW, E_BODY, E_POS, E_TIME, MAX_IMPACTS_PER_TICK, SCRATCH_SHAPE
from engine.physics.dtypes import BAT_DTYPE
from engine.physics.geometry import Body
from engine.physics.integrators import ADAPT_SIZE, WORK_SHAPE
from engine.play.ai.aim import shoot, stroke
from engine.play.ai.predict import (HALF_LENGTH, MEMO_SIZE, NO_STRIKE, PAUSED, STOP_EVENTS, STOP_RETURN_STRIKE,
                                    STOP_SERVE_STRIKE, predict_flight, predict_span, reset_memo)
from engine.play.ai.search import NOT_FOUND, search_strokes
from engine.play.ai.skill import Skill
from engine.play.arm import (BAT_FLOATS, BAT_POS, BAT_VEL, CTL_D_ANGLE, CTL_HOLD, CTL_INERTIA, CTL_K_ANGLE, CTL_KD,
                             CTL_KP, CTL_MASS, CTL_MAX_FORCE, CTL_MAX_SPEED, CTL_MAX_TORQUE, CTL_N_SEGMENTS, CTL_NORMAL,
                             CTL_SEGMENTS, CTL_SIZE, MAX_SEGMENTS, SEG_P0, SEG_P1, SEG_T0, SEG_T1, SEG_V0, SEG_V1,
                             SEG_WIDTH, bat_control)

_FLOAT64 = np.dtype(np.float64)


def think_scratch(dt: float) -> tuple:
    """The arrays a BatAI thinks in (BatAI.use_scratch), in engine.play.ai.search's order: the
    integrator's and the ball tick's work, the path (2.5 s of the model's ticks; its rows are
    written before they are read), its events, the prediction's memo, the free flights' and the
    shot solver's. dt: the model's tick, s."""
    n_max = int(round(2.5 / dt))
    return (np.zeros(WORK_SHAPE), np.zeros(SCRATCH_SHAPE), np.zeros(ADAPT_SIZE), np.zeros((MAX_IMPACTS_PER_TICK, EVENT_ROW)),
            np.empty((n_max + 1, 9)), np.zeros((8, EVENT_ROW)), np.zeros(8, np.int64), np.zeros(MEMO_SIZE, np.int64),
            np.empty(3), np.zeros(WORK_SHAPE), np.zeros(ADAPT_SIZE), np.zeros((3, 9)), np.zeros((4, 9)))


@njit(cache=True, _nrt=False)
def stroke_times(now, h, every, due, delay):
    """When a stroke whose turn is due at `due` (s) starts: the first control tick (every `every`
    ticks of h s from now) at or after due that is at least `delay` ticks away; its time, its row
    (ticks from now) and the time it is decided (`delay` ticks before), each in the world clock's
    own arithmetic (a tick's h added at a time)."""
    start_time, first_row = now, 0
    while not (start_time >= due and first_row >= delay):
        for _ in range(every):
            start_time = start_time + h
        first_row += every
    decide_at = now
    for _ in range(first_row - delay):
        decide_at = decide_at + h
    return start_time, first_row, decide_at


@dataclass
class Segment:
    """Cubic Hermite path of the bat centre from (p0, v0) at t0 to (p1, v1) at t1."""

    t0: float
    t1: float
    p0: np.ndarray
    v0: np.ndarray
    p1: np.ndarray
    v1: np.ndarray


@dataclass
class Plan:
    segments: list[Segment]
    normal: np.ndarray  # face normal to hold, unit
    t_hit: float
    target: tuple[float, float]

    def as_array(self) -> np.ndarray:
        """(n, SEG_WIDTH) rows for bat_control."""
        rows = np.zeros((len(self.segments), SEG_WIDTH))
        for row, seg in zip(rows, self.segments):
            row[SEG_T0], row[SEG_T1] = seg.t0, seg.t1
            row[SEG_P0:SEG_P0 + 3], row[SEG_V0:SEG_V0 + 3] = seg.p0, seg.v0
            row[SEG_P1:SEG_P1 + 3], row[SEG_V1:SEG_V1 + 3] = seg.p1, seg.v1
        return rows


class BatAI:
    """Controller of one bat: predicts the ball with the engine itself, aims, solves the stroke,
    drives the bat by force.

    The engine is deterministic, so once the opponent has struck, the ball's path is fixed: the AI
    predicts it with the very kernel the physics runs (engine.play.ai.predict_flight steps ball_tick),
    finds where it will strike after the ball's bounce on its court, picks an aim point on the
    opponent's court, and solves two inverse problems (engine.play.ai.aim):
    - shooting: the outgoing velocity that lands the ball on the aim point over the net, by Newton
      iteration on the engine's own flight (drag and Magnus included);
    - the stroke: the bat face normal and velocity whose impact (engine.physics.contact.impact, friction
      and spin included) gives that outgoing velocity, by fixed-point iteration.
    It then drives the bat there with forces and torques only: a planned path (backswing, swing,
    follow-through, then back to the ready pose) tracked by the arm's PD control with
    feed-forward (engine.play.arm.bat_control), clipped at a human arm's force, torque, speed and
    reach. Skill (reaction delay, aim and face-angle noise, force limits) decides how often that
    goes wrong; the noise comes from a seeded generator, so matches repeat.

    A plan predicts no more than its answer needs: the incoming ball until the strike tick is
    decided, a candidate stroke until its first contact (a service's until its bounce), and a
    candidate's flight after that (free until its next contact) from free steps when they are
    clearly on one side of every limit. The choices are the same, bit for bit, as predicting the
    whole path at the engine's tick (tests/engine/test_ai.py).

    Thinking a stroke out starts when the ball changes hands, from the ball's state then: its path
    is fixed from there on, so the stroke that is played after the reaction time is the one chosen
    as if from the ball's state at that time (the strike looked for from then on, the contacts
    before it unseen). The thinking is a generator of small steps (_think); in-process it runs at
    once, the AI worker spreads it over the time between its turns (think_step), and what is left
    when the stroke is due is done then: the same strokes either way, bit for bit.

    Args:
        model: engine.physics.world.Model of the match scene (geometry, integrator, effects).
        player: 0 (A) or 1 (B); its bat is model bat `player`.
        skill: a Skill. seed: for its random numbers.
        control_every: ticks between the calls of control (the match's AI control period).
        delay: ticks from a decision to the control tick its plan takes effect (the match's
            decision_delay, a whole number of control periods; 0: at once, as control() plays
            it). A stroke is decided `delay` ticks before it is to start, as planned from the
            bat's state then carried forward at its velocity.
        eager: think a stroke out at once when it starts; False leaves it to think_step (the AI
            worker thinks between its turns), finish_thinking doing what is left when it is due.
            Either way the same strokes, bit for bit.
    """

    SWING_S = 0.14  # duration of the forward swing
    SHOOTING_DT = 0.004  # s, step of the free flights the aim is solved on
    # Height a return must clear the net by: players keep a margin, without which face-angle
    # errors put most misses into the net or on the striker's own court.
    NET_MARGIN_M = 0.06
    COURT_MARGIN_M = 0.05  # a stroke is planned to land this far inside the court's edges
    SERVICE_NET_MARGIN_M = 0.01
    # How far from every limit of _lands_well a free flight's verdict must be to stand for the
    # predicted path's: up to the next contact the two differ only by the integrator's error
    # where a tick is split at a contact, far less than this.
    FREE_FLIGHT_TOLERANCE_M = 0.005
    # shoot converges to 1 mm at the aim's x, on a flight that differs from the engine's by well
    # under 1 mm; a flat shot's 1 mm of height is ~1 cm along x, so an aim this far outside the
    # court's margin is not tried: none of its strokes would pass _lands_well.
    AIM_SLACK_M = 0.05
    PREDICT_CHUNK = 32  # ticks of prediction in one think_step (not eager)
    KP = 30.0**2  # (rad/s)^2: position loop natural frequency 30 rad/s, critically damped
    KD = 2 * 30.0
    K_ANGLE = 40.0**2
    D_ANGLE = 2 * 40.0

    def __init__(self, model, player: int, skill: Skill, seed: int, control_every: int = 1, delay: int = 0,
                 eager: bool = True):
        self.model = model
        self.player = player
        self.skill = skill
        self.mass = float(model.bat_mass[player])
        self.inertia = model.bat_inertia[player].copy()
        self.radius = float(model.ball_params[0])
        self.bat_half_thickness = equipment.BAT_HALF_THICKNESS
        self.use_scratch(think_scratch(model.dt))
        self._ready = {sign: self._make_ready(sign) for sign in (-1, 1)}
        self._ctl_start = np.zeros(CTL_SIZE)  # _ctl before the first plan: the arm's constants
        self._ctl_start[[CTL_MASS, CTL_INERTIA, CTL_KP, CTL_KD, CTL_K_ANGLE, CTL_D_ANGLE]] = (
            self.mass, self.inertia[0], self.KP, self.KD, self.K_ANGLE, self.D_ANGLE)
        self._ctl_start[[CTL_MAX_FORCE, CTL_MAX_TORQUE, CTL_MAX_SPEED]] = (skill.max_force_n, skill.max_torque_nm,
                                                                           skill.max_speed)
        self._ctl = np.empty(CTL_SIZE)  # what bat_control tracks; _track writes it when the plan or end changes
        self.control_every = control_every
        self.delay = delay
        self.eager = eager
        # engine.play.ai.search's arguments: the scene, the judgement's limits, the shot solver's
        self._model_args = (float(model.dt), model.method, model.gravity, model.drag_k, model.magnus_k,
                            model.scene.rtol, model.scene.atol, model.table, model.floor_z, model.net, model.posts,
                            model.ball_params, model.materials)
        self._limits = (self.radius, self.COURT_MARGIN_M, self.NET_MARGIN_M, self.SERVICE_NET_MARGIN_M,
                        self.FREE_FLIGHT_TOLERANCE_M, int(round(2.0 / model.dt)), model.table is not None)
        restitution, friction = (float(x) for x in model.materials[Body.BAT_A + player])
        self._shooting = (restitution, friction, self.SHOOTING_DT, int(2.0 / self.SHOOTING_DT))
        self.renew(seed)

    def use_scratch(self, scratch: tuple) -> None:
        """Think in these arrays (think_scratch's, of this model): its own, or, for BatAIs that
        think a stroke out at once (eager) in one thread and so never at the same time, the ones
        they share (a vector environment's tables: one set of arrays stays in the CPU's caches
        where each BatAI's own would come from memory)."""
        if hasattr(self, "scratch") and not self.eager:
            raise ValueError("BatAI.use_scratch: a BatAI that spreads its thinking (eager=False) keeps its own "
                             "arrays: its stroke may be half thought out")
        rows = int(round(2.5 / self.model.dt)) + 1
        if len(scratch) != 13 or scratch[4].shape != (rows, 9):
            raise ValueError(f"BatAI.use_scratch: think_scratch({self.model.dt}) of this model's tick, please "
                             f"(a path of {rows} rows)")
        (self._work, self._scratch, self._adapt, self._tick_events, self._traj, self._events, self._event_ticks,
         self._memo, _, self._free_work, self._free_adapt, self._free_scratch, self._shoot_scratch) = scratch
        self.scratch = self._search_scratch = scratch

    def renew(self, seed: int) -> None:
        """Become the BatAI that BatAI(model, player, skill, seed, ...) makes, keeping this one's
        arrays: a new match's player (engine.play.players.Players.renew)."""
        self.rng = np.random.default_rng(seed)
        self.plan: Plan | None = None
        self._plan_end = -math.inf  # s, end of the plan's last segment
        self._ctl[:] = self._ctl_start
        self._tracking = (None, 0)  # (plan, end_sign) that self._ctl holds
        self.turn_key = None
        self.turn_seen_at = 0.0
        self.planned_key = None
        self._thinking = None  # the generator of _think for _thinking_key, decided at _thinking_due
        self._thinking_key = None
        self._thinking_due = math.inf
        self._thinking_start = math.inf  # s: when the stroke decided at _thinking_due starts (its plan takes effect)
        self._thinking_left = False
        self._thinking_args = None  # _think's arguments, and _thought_state() when it was made (state())
        self._thinking_from = None
        self._thought = None
        # Not eager: the strokes still being thought out when due, and the time their turns spent
        # finishing them (wall clock, so apart from the deterministic stats).
        self.late_thoughts = 0
        self.late_thinking_s = 0.0
        self.stats = {"plans": 0, "no_solution": 0, "let_go": 0}

    def warm_up(self) -> None:
        """Load (or compile) every kernel the AI uses, without touching its state or its RNG."""
        self.predict(np.array([0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), 0.01)
        v_out = self.solve_shot(np.array([1.6, 0.0, 0.2]), np.zeros(3), (-0.8, 0.0), 8.0, 1)
        self.solve_stroke(np.array([5.0, 0.0, 1.0]), np.zeros(3), v_out)
        m = self.model
        ball = np.array([1.6, 0.0, 0.2]), np.array([-5.0, 0.0, 1.0]), np.zeros(3)
        search_strokes(*ball, np.array([[-0.8, 0.0]]), np.array([8.0]), 0, 1, False, 1,
                       self.COURT_MARGIN_M - self.AIM_SLACK_M, self._limits, self._shooting, self._model_args,
                       self._search_scratch, *(np.empty(3) for _ in range(5)))
        memo = reset_memo(np.zeros(MEMO_SIZE, np.int64))  # _think's pieces of prediction (from the ball above)
        predict_span(m.dt, 0, 1, 2, 3, STOP_RETURN_STRIKE, 1, 0, m.method, m.gravity, m.drag_k, m.magnus_k,
                     m.scene.rtol, m.scene.atol, m.table, m.floor_z, m.net, m.posts, m.ball_params, m.materials,
                     self._work, self._scratch, self._adapt, self._tick_events, self._traj, self._events,
                     self._event_ticks, memo)
        bat = np.zeros(1, BAT_DTYPE)
        bat["quat"][0] = (1.0, 0.0, 0.0, 0.0)
        ctl = self._ctl.copy()
        ctl[CTL_NORMAL] = 1.0
        bat_control(0.0, self._bat_floats(bat[0]), ctl, np.zeros(6))  # a record's read-only view
        bat_control(0.0, bat.view(np.float64), ctl, np.zeros(6))  # a float64 row

    # --- prediction ---------------------------------------------------------------------
    def predict(self, y0: np.ndarray, seconds: float, max_events: int = 8, dt: float | None = None):
        """(times, states, events) of the ball's path from y0, without bats, as the physics steps it."""
        m = self.model
        h = m.dt if dt is None else dt
        n_max = min(int(round(seconds / h)), self._traj.shape[0] - 1)
        n, n_ev, _, _ = self._predict(y0, h, n_max, max_events, STOP_EVENTS, 0)
        return np.arange(n + 1) * h, self._traj[: n + 1], self._event_list(n_ev)

    def _predict(self, y0, h: float, n_max: int, max_events: int, stop_rule: int, end_sign: int, resume=None):
        """predict_flight into self._traj, self._events: (ticks, events, strike tick or NO_STRIKE, support).

        resume: (ticks, events) of the prediction in self._traj and self._events, to go on with
        it from its last row exactly as if it had not stopped (y0 is then ignored); n_max and
        max_events count from the start.
        """
        m = self.model
        if resume is None:
            self._adapt[:] = 0.0
            t0, e0 = 0, 0
            y0 = np.ascontiguousarray(y0, dtype=np.float64)
        else:
            t0, e0 = resume
            y0 = self._traj[t0].copy()
        n, n_ev, err, strike, support = predict_flight(
            y0, h, n_max - t0, max_events - e0, stop_rule, end_sign, m.method,
            m.gravity, m.drag_k, m.magnus_k, m.scene.rtol, m.scene.atol, m.table, m.floor_z, m.net, m.posts,
            m.ball_params, m.materials, self._work, self._scratch, self._adapt, self._tick_events, self._traj[t0:],
            self._events[e0:], self._event_ticks[e0:])
        if err == ERR_SUBSTEPS:
            raise RuntimeError("prediction failed: the integrator's substep limit was hit")
        self._event_ticks[e0:e0 + n_ev] += t0
        return t0 + n, e0 + n_ev, strike if strike == NO_STRIKE else t0 + strike, support

    def _event_list(self, n_ev: int) -> list:
        """The first n_ev events of the last prediction as (tick, body, pos, time of impact)."""
        return [(int(self._event_ticks[i]), int(self._events[i, E_BODY]), self._events[i, E_POS:E_POS + 3].copy(),
                 float(self._events[i, E_TIME])) for i in range(n_ev)]

    def solve_shot(self, p: np.ndarray, spin: np.ndarray, target: tuple[float, float], pace: float,
                   end_sign: int, first_on_own_court: bool = False) -> np.ndarray | None:
        """Outgoing velocity from p whose flight reaches `target` (x, y) at table height, or None.

        Solved by `shoot` (numba) on free flights in SHOOTING_DT steps of the scene's integrator;
        the caller checks the real path (net clearance, where it bounces) at the engine's tick.
        """
        m = self.model
        self._adapt[:] = 0.0
        v = np.zeros(3)
        ok = shoot(np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(spin, dtype=np.float64),
                   float(target[0]), float(target[1]), float(pace), self.radius, self.SHOOTING_DT,
                   int(2.0 / self.SHOOTING_DT), m.method, m.gravity, m.drag_k, m.magnus_k, m.scene.rtol, m.scene.atol,
                   self._work, self._adapt, self._shoot_scratch, v)
        return v if ok else None

    def _path(self, p, v, spin, max_events: int = 2):
        """The real path of a struck ball (with the table, net and floor), up to max_events contacts."""
        y0 = np.concatenate([p, v, spin])
        _, traj, events = self.predict(y0, 2.0, max_events=max_events)
        return traj.copy(), events

    def solve_stroke(self, v_in: np.ndarray, spin_in: np.ndarray, v_out: np.ndarray):
        """Bat face normal and velocity whose impact turns (v_in, spin_in) into v_out.

        Frictionless, the impulse is along the normal, so the normal is the direction of
        v_out - v_in and the bat speed along it follows from the restitution; friction then bends
        the result, which a fixed-point iteration on the requested change removes.
        """
        mat = self.model.materials[Body.BAT_A + self.player]
        params = self.model.ball_params
        normal, bat_vel, got_v, got_w = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        stroke(np.ascontiguousarray(v_in, dtype=np.float64), np.ascontiguousarray(spin_in, dtype=np.float64),
               np.ascontiguousarray(v_out, dtype=np.float64), params[0], params[1], params[2], mat[0], mat[1],
               normal, bat_vel, got_v, got_w)
        return normal, bat_vel, got_w

    # --- planning -----------------------------------------------------------------------
    def _think(self, now: float, ball_flat: np.ndarray, end_sign: int, serve: bool, start_time: float, first_row: int):
        """The stroke to play, thought out in steps (a generator: each next() does one piece, none
        much longer than PREDICT_CHUNK ticks of prediction or one candidate stroke's solution and
        judgement; eager, the candidates are searched in one call); the answer is left in
        self._thought: (p, normal, bat_vel, t_hit, target), or None to let the ball go.

        The ball's path is predicted from its state `now`; the stroke is chosen as if from row
        first_row of that path on (at start_time, the time of that row): the strike is looked
        for from there, and contacts before it are not seen (see predict_span). The answer does
        not depend on how the steps are spread over time.
        """
        self._thought = None
        self.stats["plans"] += 1
        m = self.model
        h = m.dt
        n_max = first_row + int(round(2.0 / h))
        if n_max + 1 > self._traj.shape[0]:
            raise ValueError(f"BatAI: thinking {first_row} ticks ahead needs a longer prediction buffer")
        traj, memo = self._traj, self._memo
        traj[0] = ball_flat
        reset_memo(memo)
        self._adapt[:] = 0.0
        rule = STOP_SERVE_STRIKE if serve else STOP_RETURN_STRIKE
        # Eager, the flight is predicted in one call: predict_span's pieces give the same bits
        # however long they are, and each call costs its dispatch.
        chunk = n_max if self.eager else self.PREDICT_CHUNK
        k = 0
        while True:
            k, err, hit = predict_span(h, k, k + chunk, n_max, 3, rule, end_sign, first_row, m.method,
                                       m.gravity, m.drag_k, m.magnus_k, m.scene.rtol, m.scene.atol, m.table,
                                       m.floor_z, m.net, m.posts, m.ball_params, m.materials, self._work,
                                       self._scratch, self._adapt, self._tick_events, traj, self._events,
                                       self._event_ticks, memo)
            if err == ERR_SUBSTEPS:
                raise RuntimeError("prediction failed: the integrator's substep limit was hit")
            if hit != PAUSED:
                break
            yield
        if hit == NO_STRIKE:
            self.stats["let_go"] += 1
            return
        t_hit = start_time + (hit - first_row) * h
        p, v_in, spin_in = traj[hit, 0:3].copy(), traj[hit, 3:6].copy(), traj[hit, 6:9].copy()
        if serve:
            target = (end_sign * self.rng.uniform(0.6, 1.0), self.rng.uniform(-0.4, 0.4))
            fallbacks = [(end_sign * 0.8, 0.0), (end_sign * 0.6, 0.1), (end_sign * 1.0, -0.1)]
            paces = [5.0, 6.0, 4.5, 7.0]
        else:
            target = (-end_sign * self.rng.uniform(0.55, 1.05), self.rng.uniform(-0.5, 0.5))
            fallbacks = [(-end_sign * 0.8, 0.0), (-end_sign * 0.6, 0.2), (-end_sign * 0.6, -0.2)]
            paces = [self.skill.pace, 0.8 * self.skill.pace, 0.6 * self.skill.pace, 0.45 * self.skill.pace]
        noise = self.rng.normal(0, self.skill.aim_noise_m, 2)
        # The chosen aim first, then safer aims, all off by the aim noise; if none of those can be
        # played, the safe aims exactly (a player plays safe rather than not at all). The face
        # angle noise below applies to whichever stroke is played.
        tries = [(aim, noise) for aim in [target] + fallbacks] + [(aim, (0.0, 0.0)) for aim in fallbacks]
        aims = np.array([(aim[0] + off[0], aim[1] + off[1]) for aim, off in tries])
        n_candidates = len(tries) * len(paces)
        chunk = n_candidates if self.eager else 1
        spin_out, shot, normal, bat_vel, got_v = (np.empty(3) for _ in range(5))
        found, c = NOT_FOUND, 0
        while found == NOT_FOUND and c < n_candidates:
            yield
            found, c, err = search_strokes(p, v_in, spin_in, aims, np.array(paces, dtype=np.float64), c,
                                           min(c + chunk, n_candidates), serve, end_sign,
                                           self.COURT_MARGIN_M - self.AIM_SLACK_M, self._limits, self._shooting,
                                           self._model_args, self._search_scratch, spin_out, shot, normal, bat_vel,
                                           got_v)
            if err == ERR_SUBSTEPS:
                raise RuntimeError("prediction failed: the integrator's substep limit was hit")
        if found == NOT_FOUND:
            self.stats["no_solution"] += 1
            return
        target = tries[found // len(paces)][0]
        normal = self._jitter(normal, self.skill.face_noise_rad)
        speed = np.linalg.norm(bat_vel)
        if speed > self.skill.max_speed:
            bat_vel = bat_vel * (self.skill.max_speed / speed)
        self._thought = (p, normal, bat_vel, t_hit, target)

    def _make_plan(self, thought, now: float, bat_pos: np.ndarray, current_vel: np.ndarray) -> Plan | None:
        """The bat's path from its state now to the stroke `thought` (see _think) and through it."""
        if thought is None:
            return None
        p, normal, bat_vel, t_hit, target = thought
        centre = p - (self.radius + self.bat_half_thickness) * normal
        swing = min(self.SWING_S, max(t_hit - now - 0.02, 0.04))
        back = centre - bat_vel * swing / 2  # constant-acceleration swing from rest
        segments = []
        if t_hit - swing > now + 1e-3:  # get to the backswing point, at rest, in time
            segments.append(Segment(now, t_hit - swing, bat_pos.copy(), current_vel.copy(), back, np.zeros(3)))
        segments.append(Segment(t_hit - swing, t_hit, back, np.zeros(3), centre, bat_vel))
        segments.append(Segment(t_hit, t_hit + 0.08, centre, bat_vel, centre + bat_vel * 0.04, np.zeros(3)))
        return Plan(segments, normal, t_hit, target)

    def _jitter(self, normal: np.ndarray, sd: float) -> np.ndarray:
        tilted = normal + self.rng.normal(0.0, sd, 3)
        return tilted / np.linalg.norm(tilted)

    # --- control ------------------------------------------------------------------------
    def ready_pose(self, end_sign: int) -> tuple[np.ndarray, np.ndarray]:
        """Where the bat waits: 40 cm behind its end line, face towards the net."""
        return self._ready[end_sign]

    @staticmethod
    def _make_ready(end_sign: int) -> tuple[np.ndarray, np.ndarray]:
        return np.array([end_sign * (HALF_LENGTH + 0.4), 0.0, 0.15]), np.array([-end_sign, 0.0, 0.0])

    def control(self, now: float, ball_flat: np.ndarray, bat: np.ndarray, rally_key, my_turn: bool,
                serve: bool, end_sign: int, out: np.ndarray | None = None) -> np.ndarray:
        """Force and torque (6,) for the bat now.

        Args:
            now: s. ball_flat: (9,) ball state. bat: one BAT_DTYPE record of this AI's bat, or the
                same bytes as a (BAT_FLOATS,) float64 array (a row of
                bats.view('<f8').reshape(len(bats), BAT_FLOATS)), which is cheaper to pass on.
            rally_key: changes whenever the ball changes hands (new rally or a strike).
            my_turn: the ball is this bat's to strike next. serve: that strike is a service.
            end_sign: -1 if this bat's court is at x < 0.
            out: (6,) written and returned if given.
        """
        floats = self._bat_floats(bat)
        self.decide(now, ball_flat, floats, rally_key, my_turn, serve, end_sign)
        if out is None:
            out = np.zeros(6)
        bat_control(now, floats, self._ctl, out)
        return out

    def decide(self, now: float, ball_flat: np.ndarray, floats: np.ndarray, rally_key, my_turn: bool, serve: bool,
               end_sign: int) -> None:
        """control without the force: bring the plan and what bat_control tracks (self._ctl) up to
        date. floats: the bat as a (BAT_FLOATS,) float64 array (see _bat_floats)."""
        if rally_key != self.turn_key:
            self.turn_key = rally_key
            self.turn_seen_at = now
        if my_turn and self.planned_key != rally_key:
            self._start_thinking(now, ball_flat, rally_key, end_sign, serve)
        if self._thinking is not None and now >= self._thinking_due:
            if self._thinking_left:  # not thought out in time: the turn waits for the rest
                started = time.perf_counter()
                self.finish_thinking()
                self.late_thinking_s += time.perf_counter() - started
                self.late_thoughts += 1
            if self._thinking_key == rally_key and my_turn:
                start, vel = self._thinking_start, floats[BAT_VEL:BAT_VEL + 3].copy()
                self.plan = self._make_plan(self._thought, start, floats[BAT_POS:BAT_POS + 3] + vel * (start - now), vel)
                self._plan_end = self.plan.segments[-1].t1 if self.plan is not None else -math.inf
            self._thinking = None
        if self.plan is not None and now > self._plan_end:
            self.plan = None
        if self.plan is not self._tracking[0] or end_sign != self._tracking[1]:
            self._track(self.plan, end_sign)

    def wakes(self) -> tuple[float, float]:
        """When decide() next changes anything (its plan, what bat_control tracks, its thinking,
        its random draws) if it is called again with the same rally_key, my_turn and serve as
        at its last call: at the first `now >= due` (the stroke being thought out is played) or
        the first `now > end` (the plan runs out). Until then every such decide() is a no-op and
        the force is bat_control(now, bat, ctl) alone: the AI worker publishes these two with its
        ctl rows so that the physics worker computes the force itself in between.

        Returns:
            (due, end) s, world clock; inf for none.
        """
        due = self._thinking_due if self._thinking is not None else math.inf
        end = self._plan_end if self.plan is not None else math.inf
        return due, end

    def _start_thinking(self, now: float, ball_flat: np.ndarray, rally_key, end_sign: int, serve: bool) -> None:
        """Start thinking out the stroke for rally_key from the ball's state now; it is played from
        the first control tick after the reaction time (none for a service) that is at least the
        decision delay away, as if thought out there (see _think), and decided `delay` ticks
        before: the ball's path from now on is known, so the thinking can start now and be spread
        over the control ticks in between (think_step)."""
        self.finish_thinking()  # one still unfinished: its random draws come first
        self.planned_key = rally_key
        due = self.turn_seen_at + (0.0 if serve else self.skill.reaction_s)
        start_time, first_row, decide_at = stroke_times(now, float(self.model.dt), self.control_every, due,
                                                        self.delay)
        self._thinking_args = (now, np.array(ball_flat, dtype=np.float64), end_sign, serve, start_time, first_row)
        self._thinking_from = self._thought_state()
        self._thinking = self._think(*self._thinking_args)
        self._thinking_key = rally_key
        self._thinking_due, self._thinking_start = decide_at, start_time
        self._thinking_left = True
        if self.eager:
            self.finish_thinking()

    @property
    def thinking(self) -> bool:
        """Whether a stroke is still being thought out (think_step has work to do)."""
        return self._thinking is not None and self._thinking_left

    def think_step(self) -> bool:
        """One step of the stroke being thought out; whether more remain."""
        if self._thinking is None or not self._thinking_left:
            return False
        try:
            next(self._thinking)
        except StopIteration:
            self._thinking_left = False
        return self._thinking_left

    def finish_thinking(self) -> None:
        """Think the stroke being thought out to its end."""
        while self.think_step():
            pass

    def _thought_state(self) -> dict:
        """What thinking a stroke out changes: its random draws, its stats and its answer."""
        return {"rng": self.rng.bit_generator.state, "stats": dict(self.stats), "late_thoughts": self.late_thoughts,
                "thought": self._thought}

    def state(self) -> dict:
        """Everything its decisions depend on, as plain data (picklable), for load_state.

        A stroke still being thought out is kept as its generator's arguments and the state it
        started from (random draws, stats): load_state makes the generator again, and since the
        strokes do not depend on how the thinking is spread, it thinks the same stroke.
        """
        live = self._thinking is not None and self._thinking_left
        thinking = None if self._thinking is None else ("live" if live else "done")
        return {**(self._thinking_from if live else self._thought_state()),
                "thinking": thinking, "thinking_args": self._thinking_args if live else None,
                "thinking_key": self._thinking_key, "thinking_due": self._thinking_due,
                "thinking_start": self._thinking_start,
                "plan": self.plan, "plan_end": self._plan_end, "tracking": self._tracking, "ctl": self._ctl.copy(),
                "turn_key": self.turn_key, "turn_seen_at": self.turn_seen_at, "planned_key": self.planned_key,
                "late_thinking_s": self.late_thinking_s}

    def load_state(self, state: dict) -> None:
        """Become the BatAI whose state() this is (the same model, skill and player)."""
        self.rng.bit_generator.state = state["rng"]
        self.stats = dict(state["stats"])
        self.late_thoughts, self.late_thinking_s = state["late_thoughts"], state["late_thinking_s"]
        self._thought = state["thought"]
        self.plan, self._plan_end, self._tracking = state["plan"], state["plan_end"], state["tracking"]
        self._ctl[:] = state["ctl"]
        self.turn_key, self.turn_seen_at, self.planned_key = state["turn_key"], state["turn_seen_at"], state["planned_key"]
        self._thinking_key, self._thinking_due = state["thinking_key"], state["thinking_due"]
        self._thinking_start = state["thinking_start"]
        self._thinking_args = self._thinking_from = None
        self._thinking, self._thinking_left = None, False
        if state["thinking"] == "live":
            self._thinking_args = state["thinking_args"]
            self._thinking_from = self._thought_state()
            self._thinking, self._thinking_left = self._think(*self._thinking_args), True
        elif state["thinking"] == "done":
            self._thinking = iter(())  # thought out: decide() plays self._thought when it is due

    def _track(self, plan: Plan | None, end_sign: int) -> None:
        """Write into self._ctl the plan's path and face normal, or the ready pose of end_sign without one."""
        ctl = self._ctl
        ready_pos, ready_normal = self._ready[end_sign]
        ctl[CTL_HOLD:CTL_HOLD + 3] = ready_pos
        ctl[CTL_NORMAL:CTL_NORMAL + 3] = ready_normal if plan is None else plan.normal
        rows = plan.as_array() if plan is not None else np.zeros((0, SEG_WIDTH))
        if len(rows) > MAX_SEGMENTS:
            raise ValueError(f"a plan has {len(rows)} segments, bat_control tracks at most MAX_SEGMENTS = {MAX_SEGMENTS}")
        ctl[CTL_N_SEGMENTS] = len(rows)
        ctl[CTL_SEGMENTS:CTL_SEGMENTS + rows.size] = rows.ravel()
        self._tracking = (plan, end_sign)

    @staticmethod
    def _bat_floats(bat) -> np.ndarray:
        """The bat as a (BAT_FLOATS,) float64 array, no copy: a float64 row as it is, a BAT_DTYPE
        record (numpy.void or 0-d array) as a read-only view of its bytes."""
        kind = type(bat)
        if kind is np.ndarray and bat.dtype is _FLOAT64 and bat.shape == (BAT_FLOATS,) and bat.flags.c_contiguous:
            return bat  # the cheapest for numba to take: no view to make, writable
        if kind is np.void and bat.dtype is BAT_DTYPE:
            return np.frombuffer(bat, np.float64)  # read-only
        if not isinstance(bat, (np.void, np.ndarray)) or bat.dtype != BAT_DTYPE or bat.shape != ():
            raise TypeError(f"BatAI.control: bat must be one engine.physics.dtypes.BAT_DTYPE record (e.g. bats[player]) or "
                            f"its ({BAT_FLOATS},) float64 view (bats.view('<f8').reshape(len(bats), {BAT_FLOATS})"
                            f"[player]), got {kind.__name__} of dtype {getattr(bat, 'dtype', None)} and shape "
                            f"{getattr(bat, 'shape', None)}")
        floats = np.frombuffer(bat, np.float64)
        floats.flags.writeable = False  # as a record's: one numba specialisation
        return floats
