"""The net simulation: owns the knot state, substeps under the stability bound, rings down in closed form, sleeps and wakes."""
import math
from typing import NamedTuple

import numba
import numpy as np

from net_kernel import kernels, reference
from net_kernel.kernels import (
    FREE_ASLEEP,
    FREE_NOT_FINITE,
    FREE_OUT_OF_REACH,
    GRID32_EXACT,
    GRID32_FMA,
    KNOT_WORK_ROWS,
    NO_CONTACT,
    SPRING_WORK_COLS,
    STEP_WORK_ROWS,
    TICK_BALL_ROWS,
    grid_work,
)
from net_kernel.bound import NetBoundError, knot_bound, out_of_bound
from net_kernel.kernels.modal import FREE_TAIL
from net_kernel.modes import NetModes, linear_tail_refusal, net_modes
from net_kernel.tail import LinearTail
from net_kernel.topology import FLOAT32, IMPLICIT, NetTopology

# One switch picks the backend; both modules expose the same kernel names and signatures.
BACKENDS = {"numba": kernels, "reference": reference}

# Substeps aim at this fraction of the stability bound, so rounding of the bound (it is an
# estimate for non-proportional dashpots) never puts a step right at the edge.
SAFETY = 0.9
# Below this many knots the serial kernel is used: on a 2-core machine shared with the
# physics worker, waking the pool for a ~3,000-knot net gains little and costs a core
# (`pingpong profile-net` shows both side by side; the results are the same bits).
PARALLEL_MIN_KNOTS = 20_000
# Sleep: the net falls asleep after SLEEP_TICKS ticks with every knot slower than
# SLEEP_SPEED, and the ball farther than WAKE_MARGIN plus one tick's travel from the net's box.
# A sleeping net is frozen; only the ball's touch wakes it (a ball passing close by does not).
SLEEP_SPEED = 1e-3  # m/s
SLEEP_TICKS = 20
# An awake net's knots move within the tick: the ball counts as near when it comes this close to
# the box of their positions at the tick's start (a 20 m/s ball bulges the default net by a few cm).
WAKE_MARGIN = 0.05  # m
# No knot leaves the box the net was built in by more than this (checked after every tick, like
# finiteness), so a knot out that far means the net blew up. The hanging net's hem swings with the
# mesh: balls at 60 m/s (the scene's speed bound) low into the middle of the 85 x 8 net bulge it
# up to 16 cm along x and lift the top cord 4 cm; 25 cm leaves half as much again. It bounds where
# an awake net can be without looking at it, which lets the engine step the net without the ball
# while the ball is out of that reach (step_free).
NET_REACH = 0.25  # m
# m: a linear tail's box (every knot's place from the switch on) stays within this of the built
# box: the engine steps the ball tick by tick near a tail or a sleeping net only within the built
# box grown by WAKE_MARGIN (engine.physics.world's cloth_watch), so a tail reaching farther stays awake.
TAIL_BOX_MARGIN = 0.5 * WAKE_MARGIN
NOT_FINITE = "a knot position or velocity is not finite after the net's tick"
# Ball-knot contact defaults: a net thread is about 1 mm thick; the cloth's give comes from
# its springs, so each knot-ball impact is taken as perfectly inelastic.
KNOT_RADIUS = 0.5e-3  # m
NET_RESTITUTION = 0.0
MAX_HITS = 8
# m: with the ball near, a tick takes enough substeps that ball and knots close in by at most this
# far in one (contact_substeps). Within a substep the contact and the springs are split (struck
# knots ride with the ball, the springs pull at the step): an error of first order in the substep
# that decides whether a fast shot goes through the mesh, and the stability bound alone does not
# keep it small. 1 mm stops head-on shots at the scene's speed bound (engine.physics.equipment.BALL_SPEED_MAX)
# on the match's 85 x 8 net (tests/net_kernel/test_ball.py, bench net-resolution's stress shots);
# slow strokes, such as the AI's, already meet it at the bound's substeps and pay nothing more.
CONTACT_TRAVEL = 1e-3
# m/s: the closing speed the contact substeps follow at most (twice the ball's bound, 60 m/s:
# engine.physics.equipment.BALL_SPEED_MAX, which net_kernel may not import), so a net that went wrong
# cannot ask for unbounded work; NET_REACH and finiteness catch it.
CONTACT_SPEED_MAX = 120.0
CG_TOL = 1e-8
CG_MAX_ITER = 200
# The ITTF ball (engine/physics/equipment.py): 40 mm, 2.7 g (the defaults of NetSim.step).
BALL_RADIUS = 0.02
BALL_MASS = 2.7e-3


def _checked_substeps(topo: NetTopology, dt: float, substeps: int | None, implicit: bool) -> int:
    """NetSim's substeps per tick: `substeps`, or (None) the fewest the stability bound allows
    (1 for the implicit solver); ValueError for a count that is no integer >= 1 or whose
    substep exceeds the bound."""
    if substeps is None:
        substeps = 1 if implicit else max(1, math.ceil(dt / (SAFETY * topo.h_max)))
    if not isinstance(substeps, int) or substeps < 1:
        raise ValueError(f"substeps = {substeps!r} must be an integer >= 1")
    h = dt / substeps
    if not implicit and h >= topo.h_max:
        need = math.ceil(dt / (SAFETY * topo.h_max))
        raise ValueError(
            f"substep h = {h:.4g} s is above the semi-implicit Euler stability bound h_max = {topo.h_max:.4g} s "
            "(h^2 w^2 + 2 h g < 4, w^2 and g the net's largest stiffness and damping per unit mass: "
            "net_kernel.topology.stability_bound); "
            f"use substeps >= {need} (or substeps=None), or solver='implicit'")
    return substeps


class NetContact(NamedTuple):
    """What the net did to the ball in one tick (see NetSim.step)."""

    toi: float
    impulse: np.ndarray
    offset: np.ndarray


class NetSim:
    """A cloth net stepped tick by tick: knots, substeps, sleeping, ball contact.

    A net on build_topology's regular grid is stepped by the grid kernels (kernels.step_grid:
    structure of arrays stepped in place, all of a tick's substeps in one call while the ball
    is away), any other net by the CSR kernels, whose state lives in two preallocated buffers
    that they ping-pong between; both give the same bits. `knot_pos`/`knot_vel` always name
    the current state. `kernel_calls` counts every kernel invocation (steps, rest checks, contact
    sweeps), so a sleeping net can be shown to cost none; `awake_ticks` counts the ticks it was
    stepped (awake), which is what a match pays for the net.

    Three states (each switch decided from the state): awake, the full kernel substep by
    substep; the linear tail (`tail`, net_kernel/tail.py), entered at the end of a tick with
    the ball far once the motion's energy is at most NetSpec.tail_energy, in which the knots
    are modal coordinates advanced in closed form (`tail_ticks` counts those ticks) and are
    rebuilt when someone reads knot_pos or knot_vel, or exactly at the tick the ball comes
    within the tail's box, from where the full kernel goes on; asleep, frozen.
    """

    def __init__(self, topo: NetTopology, dt: float, substeps: int | None = None, backend: str = "numba",
                 parallel: bool | None = None, grid: bool | None = None):
        """Validate the tick against the stability bound and allocate everything once.

        Args:
            topo: the built net.
            dt: s, the tick.
            substeps: steps per tick; None derives the count from the stability bound (implicit
                solver: 1). An explicit count whose substep exceeds the bound is refused.
            backend: "numba" or "reference".
            parallel: numba backend: parallel knot loop (None: only for nets above
                PARALLEL_MIN_KNOTS knots). Both variants give the same bits.
            grid: step with the grid kernels (None: whenever the topology has grid_params
                and the solver is semi-implicit); False forces the CSR kernels (same bits).

        Raises:
            ValueError: dt <= 0, an unknown backend, substeps too few for the bound, or
                grid=True for a net without grid_params or with the implicit solver.
        """
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt = {dt!r} must be a finite number of seconds > 0")
        if backend not in BACKENDS:
            raise ValueError(f"backend {backend!r} is not one of {', '.join(BACKENDS)}")
        self.topo = topo
        self.dt = float(dt)
        self.backend = backend
        self.implicit = topo.spec is not None and topo.spec.solver == IMPLICIT
        self.substeps = _checked_substeps(topo, self.dt, substeps, self.implicit)
        self.h = h = self.dt / self.substeps
        spec = topo.spec
        self.gravity = spec.gravity if spec is not None else 9.81
        self.drag = spec.air_damping if spec is not None else 0.0
        mod = BACKENDS[backend]
        if parallel is None:
            parallel = topo.n_knots >= PARALLEL_MIN_KNOTS
        if grid is None:
            grid = topo.grid_params is not None and not self.implicit
        if not grid and spec is not None and spec.kernel_precision == FLOAT32:
            raise ValueError("kernel_precision = 'float32' needs the grid kernels: use grid=None or True")
        if grid and (topo.grid_params is None or self.implicit):
            raise ValueError("grid=True needs a net built by build_topology (grid_params) and the semi-implicit "
                             "solver; use grid=None to pick the kernels from the net")
        self.grid = bool(grid)
        self._step = mod.step_knots if parallel else mod.step_knots_serial
        self._step_grid = mod.step_grid if parallel else mod.step_grid_serial
        self._implicit = mod.step_knots_implicit
        self._speed = mod.knot_speed_max
        self._collide = mod.collide_ball_near
        # A grid net's tick with the ball near, all of it in one call (one thread: the grid kernels
        # give the same bits on any number).
        self._step_grid_tick = mod.step_grid_tick if self.grid else None
        self._motion_energy = mod.motion_energy
        self._grid_knots = mod.grid_knots
        # Free ticks in one call, on one thread (a parallel net steps them one step() at a time).
        self._step_grid_free = mod.step_grid_free if self.grid and not parallel else None
        n = topo.n_knots
        if self.grid:
            rows, cols = topo.spec.rows, topo.spec.cols
            # [position | velocity, axis, row, column], stepped in place; knot_pos/knot_vel are (n, 3)
            # views (both "buffers" name the one state).
            self._state = np.zeros((2, 3, rows, cols))
            self._state[0] = topo.rest_pos.T.reshape(3, rows, cols)
            self._pos = [self._state[0].reshape(3, n).T] * 2
            self._vel = [self._state[1].reshape(3, n).T] * 2
            self._grid_inv_mass = topo.knot_inv_mass.reshape(rows, cols)
            # Row blocks a parallel step runs (one a thread); their count changes no bit (kernels.step_grid).
            blocks = min(rows, max(1, numba.get_num_threads())) if parallel and backend == "numba" else 1
            self._grid_work = grid_work(rows, cols, blocks)
            if spec.kernel_precision == FLOAT32:  # the float32 grid kernels (kernels.grid32), the same calls
                self._step_grid = mod.step_grid32 if parallel else mod.step_grid32_serial
                self._step_grid_tick = mod.step_grid32_tick
                self._step_grid_free = mod.step_grid32_free if not parallel else None
                self._grid_work = mod.grid32_work(topo.knot_pos.T.reshape(3, rows, cols).copy(), self._grid_inv_mass,
                                                  blocks, GRID32_FMA if spec.kernel_fma else GRID32_EXACT)
        else:
            self._pos = [topo.rest_pos.copy(), topo.rest_pos.copy()]
            self._vel = [np.zeros((n, 3)), np.zeros((n, 3))]
        self._cur = 0
        self._knot_work = np.zeros((KNOT_WORK_ROWS, n, 3)) if self.implicit else np.zeros((KNOT_WORK_ROWS, 0, 3))
        self._spring_work = np.zeros((topo.n_springs if self.implicit else 0, SPRING_WORK_COLS))
        self._step_work = np.zeros((STEP_WORK_ROWS, 0 if self.grid else topo.n_springs))
        self._impulse = np.zeros(3)
        self._offset = np.zeros(3)
        self._hit_impulse = np.zeros(3)
        # ball position, velocity, position after a sweep, scratch; the tick's start position and velocity
        self._ball = np.zeros((TICK_BALL_ROWS, 3))
        # What a tick without contact returns (read-only zeros: a caller cannot spoil the next one).
        self._no_contact = NetContact(NO_CONTACT, np.zeros(3), np.zeros(3))
        self._no_contact.impulse.setflags(write=False)
        self._no_contact.offset.setflags(write=False)
        self._near = np.zeros(n, dtype=np.int64)  # the contact sweep's list of knots within reach
        # (2, 3) m, lo and hi corners of the knots' box: of the shape it froze in while the net
        # sleeps, of the tick's start shape while it is awake (net_box).
        self.box = net_box(topo.rest_pos)
        self._built = self.box.copy()
        self._reach = self.box + np.array([[-NET_REACH], [NET_REACH]])  # (2, 3) m, the built box grown
        self.bound: np.ndarray | None = None  # (2, 3) m, bound_box's while it holds (the free ticks check it)
        self._rest_box: np.ndarray | None = None  # (2, 3) m, the box of the modes' rest shape
        self._probe = (np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(3), np.zeros(3))
        self.kernel_calls = 0
        self.cg_iterations = 0
        self.awake_ticks = 0
        self.sleeping = False
        self.quiet_ticks = 0  # ticks in a row with every knot below SLEEP_SPEED (state: a restart restores it)
        self.knot_radius = KNOT_RADIUS
        self.restitution = NET_RESTITUTION
        # The linear tail: on for a net whose spec asks for it and whose modes exist
        # (net_kernel.modes.linear_tail_refusal); its modes are computed at the first switch.
        self.tail_energy = spec.tail_energy if spec is not None else 0.0
        self.tail_refusal = linear_tail_refusal(topo) if self.tail_energy > 0 else "NetSpec.tail_energy is 0"
        self._tail_holder: LinearTail | None = None
        self.tail: LinearTail | None = None  # the linear state, while it holds the net
        self._shown = -1  # the tail tick whose state knot_pos and knot_vel hold (-1: none)
        self.tail_ticks = 0
        free_tail = mod.step_grid32_free_tail if spec is not None and spec.kernel_precision == FLOAT32 else \
            mod.step_grid_free_tail
        self._step_free_tail = free_tail if self._step_grid_free is not None and self.tail_refusal is None else None

    @property
    def knot_pos(self) -> np.ndarray:
        """(n_knots, 3) m, the current knot positions (a view; valid until the next step). In the
        linear tail they are rebuilt from the modes on reading; a caller that moves a knot then
        calls wake()."""
        self._show_tail()
        return self._pos[self._cur]

    @property
    def knot_vel(self) -> np.ndarray:
        """(n_knots, 3) m/s, the current knot velocities (rebuilt in the tail, as knot_pos)."""
        self._show_tail()
        return self._vel[self._cur]

    @property
    def in_tail(self) -> bool:
        """True while the linear tail holds the net (its ticks cost a count, as a sleeping net's cost nothing)."""
        return self.tail is not None

    def load_state(self, knot_pos, knot_vel, sleeping: bool, quiet_ticks: int, tail_ticks: int = -1) -> None:
        """Take a saved state (a restart): knot_pos, knot_vel (n_knots, 3) m, m/s; with
        tail_ticks >= 0, they are the switch state of a linear tail that has run that many ticks
        (quiet_ticks its sleep count at the switch)."""
        self.tail = None
        self.bound = None
        self._pos[self._cur][:] = knot_pos
        self._vel[self._cur][:] = knot_vel
        self.sleeping = bool(sleeping)
        self.quiet_ticks = int(quiet_ticks)
        net_box(self._pos[self._cur], out=self.box)
        if tail_ticks >= 0:
            self.resume_tail(quiet_ticks, tail_ticks)

    def copy_state(self, knot_pos: np.ndarray, knot_vel: np.ndarray) -> None:
        """The current knot positions and velocities (as knot_pos, knot_vel) into the given (n_knots, 3)
        arrays (a snapshot's fields, say): for a grid net one kernel call instead of numpy's strided copy."""
        self._show_tail()
        if self.grid:
            self._grid_knots(self._state, knot_pos, knot_vel)
        else:
            knot_pos[:] = self._pos[self._cur]
            knot_vel[:] = self._vel[self._cur]

    def _show_tail(self) -> None:
        tail = self.tail
        if tail is not None and self._shown != tail.ticks:
            tail.state(tail.ticks, self._pos[self._cur], self._vel[self._cur])
            self._shown = tail.ticks

    def ball_far(self, ball_pos, ball_vel, ball_radius: float) -> bool:
        """True when the ball cannot touch the net within this tick (ball_far_from_box on self.box;
        the tail's box holds all its knots' motion, so it needs no margin, as a frozen net's)."""
        return ball_far_from_box(self.box, self.sleeping or self.tail is not None, self.knot_radius, self.dt, ball_pos,
                                 ball_vel, ball_radius)

    def touches(self, ball_pos, ball_vel, ball_radius: float, ball_inv_mass: float) -> bool:
        """Would the ball, moving straight over this tick, touch the net frozen as it is now?

        The sweep (kernels.collide_ball_near over the whole tick, knots at rest) runs on a copy, so
        the net is left exactly as it was: a sleeping net stays asleep, bit for bit, unless the
        ball really reaches it.
        """
        pos, vel, impulse, end = self._probe
        pos[:] = self.knot_pos
        vel[:] = 0.0
        hit = self._collide(pos, vel, self.topo.knot_inv_mass, np.asarray(ball_pos, dtype=float),
                            np.asarray(ball_vel, dtype=float), float(ball_radius), float(ball_inv_mass),
                            self.knot_radius, self.restitution, self.dt, 1, impulse, end, self._near)
        self.kernel_calls += 1
        return hit != NO_CONTACT

    def bound_box(self) -> np.ndarray | None:
        """(2, 3) m: lo and hi corners of a box that holds every knot from now on, for as long as
        nothing touches the net (net_kernel.bound.knot_bound), within the built box grown by
        NET_REACH; None for a net without modes (no linear tail). The free ticks stepped from now
        on check it (a knot outside raises NetBoundError), until the ball next comes near.

        A caller that knows the ball stays farther from this box than an awake net's reach may
        step those ticks without the ball (step_free): NetSim.step takes them so too (ball_far
        on the knots' own box, which lies inside), the same bits.
        """
        if self.tail_refusal is not None:
            return None
        modes = self.modes()
        if self._rest_box is None:
            self._rest_box = net_box(modes.rest_pos)
        self.bound = knot_bound(self.topo, modes, self.knot_pos, self.knot_vel, self._rest_box, self._reach)
        return self.bound

    def wake(self) -> None:
        """Wake the net (contact, or the caller moved a knot): out of sleep or the tail, into the full kernel."""
        if self.tail is not None:
            self._leave_tail()
        self.sleeping = False
        self.quiet_ticks = 0

    def step(self, ball_pos=None, ball_vel=None, ball_radius: float = BALL_RADIUS,
             ball_inv_mass: float = 1.0 / BALL_MASS) -> NetContact:
        """Advance the net one tick (all substeps) with the ball's contact, unless it sleeps.

        The contact is resolved at every substep (kernels.collide_ball over h), so the knots
        move little between two sweeps; with the ball near, the tick takes more substeps than the
        stability bound's when ball and knots would close in by more than CONTACT_TRAVEL in one
        (contact_substeps). The ball is taken to move in a straight line over the tick, bent only
        by the net's impulses; forces on the ball are the engine's business.

        Contract for the engine: integrate the ball's tick without the net, then add
        `offset` to its position and `impulse * ball_inv_mass` to its velocity.

        Args:
            ball_pos: (3,) m, ball centre at the tick's start, or None for no ball.
            ball_vel: (3,) m/s.
            ball_radius: m.
            ball_inv_mass: 1/kg.

        Returns:
            NetContact(toi, impulse, offset): fraction of the tick at the first contact or
            NO_CONTACT, the (3,) N s impulse on the ball, the (3,) m change of the ball's end
            position. Views of preallocated arrays, valid until the next step.

        Raises:
            FloatingPointError: a knot position or velocity stopped being finite (the cheap
                invariant checked after every tick).
        """
        far = self.ball_far(ball_pos, ball_vel, ball_radius)
        if not far:
            self.bound = None  # the ball may touch: a bound of before no longer holds
        if self.tail is not None:
            if far:
                self._advance_tail(1)
                return self._no_contact
            self._leave_tail()  # the ball within the tail's box: the full kernel from this tick's state
            far = self.ball_far(ball_pos, ball_vel, ball_radius)
        if self.sleeping:
            if far or not self.touches(ball_pos, ball_vel, ball_radius, ball_inv_mass):
                return self._no_contact
            self.wake()
        if far and self._step_grid_free is not None:
            self._free_run(1)  # no contact to sweep: the tick as step_free takes it (the same bits)
            return self._no_contact
        if not far and self._step_grid_tick is not None:
            return self._ball_tick(ball_pos, ball_vel, float(ball_radius), float(ball_inv_mass))
        self._impulse[:] = 0.0
        self._offset[:] = 0.0
        topo = self.topo
        toi = NO_CONTACT
        self.awake_ticks += 1
        substeps, h = self.substeps, self.h
        if not far:
            bp = self._ball[0]
            bv = self._ball[1]
            bp[:] = ball_pos
            bv[:] = ball_vel
            substeps = contact_substeps(bv, self._speed(self.knot_pos, self.knot_vel), self.dt, self.substeps)
            h = self.dt / substeps
            self.kernel_calls += 1
        if far and self.grid:
            # No contact to sweep between substeps: the whole tick in one call.
            self._step_grid(self._state, self._grid_inv_mass, topo.grid_params, self.gravity, self.drag, self.h,
                            self.substeps, self._grid_work)
            self.kernel_calls += 1
        else:
            for k in range(substeps):
                if not far:
                    hit = self._collide(self._pos[self._cur], self._vel[self._cur], topo.knot_inv_mass, bp, bv,
                                        float(ball_radius), float(ball_inv_mass), self.knot_radius, self.restitution,
                                        h, MAX_HITS, self._hit_impulse, self._ball[2], self._near)
                    self.kernel_calls += 1
                    if hit != NO_CONTACT:
                        if toi == NO_CONTACT:
                            toi = (k + hit) / substeps
                        self._impulse += self._hit_impulse
                        bv += self._hit_impulse * ball_inv_mass
                    bp[:] = self._ball[2]
                src, dst = self._cur, 1 - self._cur
                if self.grid:
                    self._step_grid(self._state, self._grid_inv_mass, topo.grid_params, self.gravity, self.drag,
                                    h, 1, self._grid_work)
                elif self.implicit:
                    self.cg_iterations += self._implicit(
                        self._pos[src], self._vel[src], topo.knot_inv_mass, topo.adj_start, topo.adj_knot,
                        topo.adj_spring, topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, self.gravity,
                        self.drag, h, CG_TOL, CG_MAX_ITER, self._knot_work, self._spring_work, self._pos[dst],
                        self._vel[dst])
                else:
                    self._step(self._pos[src], self._vel[src], topo.knot_inv_mass, topo.adj_start, topo.adj_knot,
                               topo.adj_spring, topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c,
                               self.gravity, self.drag, h, self._step_work, self._pos[dst], self._vel[dst])
                self._cur = dst
                self.kernel_calls += 1
        if toi != NO_CONTACT:
            # Where the ball ended minus where it would have ended without the net.
            np.subtract(bp, ball_pos, out=self._offset)
            np.multiply(ball_vel, self.dt, out=self._hit_impulse)  # scratch: the free path's travel
            self._offset -= self._hit_impulse
            self.wake()
        speed = self._speed(self.knot_pos, self.knot_vel)
        self.kernel_calls += 1
        if not math.isfinite(speed):
            raise FloatingPointError(NOT_FINITE)
        self.quiet_ticks = self.quiet_ticks + 1 if speed < SLEEP_SPEED else 0
        if self.quiet_ticks >= SLEEP_TICKS and far:
            self.sleeping = True
            self.knot_vel[:] = 0.0
        box = net_box(self.knot_pos, out=self.box)
        if (box[0] < self._reach[0]).any() or (box[1] > self._reach[1]).any():
            raise FloatingPointError(self._out_of_reach())
        if far and not self.sleeping and self.tail_refusal is None and self._has_modes() and self._calm():
            self._start_tail()
        return NetContact(toi, self._impulse, self._offset)

    def _ball_tick(self, ball_pos, ball_vel, ball_radius: float, ball_inv_mass: float) -> NetContact:
        """step() of an awake grid net with the ball near: the whole tick in one kernel call
        (kernels.step_grid_tick: the same bits as the per-substep loop of step(), which
        bench.net_tick times against it)."""
        self.awake_ticks += 1
        ball = self._ball
        ball[4] = ball_pos
        ball[5] = ball_vel
        topo = self.topo
        toi, substeps, self.quiet_ticks, status = self._step_grid_tick(
            self._state, self._grid_inv_mass, topo.grid_params, self.gravity, self.drag, self.dt, self.substeps,
            self._grid_work, ball, ball_radius, ball_inv_mass, self.knot_radius, self.restitution, MAX_HITS,
            self._near, CONTACT_TRAVEL, CONTACT_SPEED_MAX, self.quiet_ticks, SLEEP_SPEED, self._reach, self.box,
            self._impulse, self._offset)
        self.kernel_calls += 2 * substeps + 2  # as the loop counts: speed, a sweep and a step a substep, speed
        if status == FREE_NOT_FINITE:
            raise FloatingPointError(NOT_FINITE)
        if status == FREE_OUT_OF_REACH:
            raise FloatingPointError(self._out_of_reach())
        return NetContact(toi, self._impulse, self._offset)

    def _calm(self) -> bool:
        """Is the motion's energy at most tail_energy (kernels.modal.motion_energy)?"""
        topo = self.topo
        self.kernel_calls += 1
        return self._motion_energy(self.knot_pos, self.knot_vel, topo.knot_mass, topo.knot_inv_mass, topo.spring_ij,
                                   topo.spring_rest, topo.spring_k, self.gravity, self.modes().rest_energy,
                                   self.tail_energy) <= self.tail_energy

    def _has_modes(self) -> bool:
        """Are the net's modes there (computed or loaded now if need be)? A net whose scheme has a
        mode that is not an oscillation (net_modes) gets no tail from then on: tail_refusal says why."""
        if self._tail_holder is None:
            try:
                self.modes()
            except ValueError as exc:
                self.tail_refusal = str(exc)
                self._step_free_tail = None
                return False
        return True

    def modes(self) -> NetModes:
        """The net's modes (net_kernel.modes.net_modes), computed or loaded at the first call; ValueError
        if the net has no tail (tail_refusal)."""
        if self._tail_holder is None:
            self._tail_holder = LinearTail(net_modes(self.topo, self.dt, self.substeps), BACKENDS[self.backend])
        return self._tail_holder.modes

    def _start_tail(self, quiet_ticks: int | None = None, ticks: int = 0) -> bool:
        """Hand the net over to the linear tail from its current state (quiet_ticks: the sleep count
        at the switch, default the current one; ticks: already since the switch, for a restart).
        False, and still awake, when the tail's bounds let a knot reach the table."""
        self.modes()
        tail = self._tail_holder
        self.kernel_calls += 1
        if not tail.start(self.knot_pos, self.knot_vel, self.quiet_ticks if quiet_ticks is None else quiet_ticks,
                          SLEEP_SPEED, SLEEP_TICKS):
            return False
        if (tail.box[0] < self._built[0] - TAIL_BOX_MARGIN).any() or (tail.box[1] > self._built[1] + TAIL_BOX_MARGIN).any():
            return False  # the engine watches the ball tick by tick within WAKE_MARGIN of the built box
        self.tail = tail
        self._shown = 0
        self.box[:] = tail.box
        if ticks:
            self._advance_tail(ticks)
        return True

    def resume_tail(self, quiet_ticks: int, ticks: int) -> None:
        """A restart: the tail that started from the current knot state (the switch state, with
        that sleep count) `ticks` ticks ago. Raises RuntimeError if it cannot hold it."""
        if not self._start_tail(quiet_ticks, ticks):
            raise RuntimeError("the linear tail cannot hold this state (its bounds reach the table)")

    def _advance_tail(self, ticks: int) -> None:
        """`ticks` ticks in the tail: nothing but a count, unless the net falls asleep in them."""
        tail = self.tail
        ahead = min(ticks, tail.sleep_at - tail.ticks)
        tail.ticks += ahead
        self.tail_ticks += ahead
        if tail.ticks >= tail.sleep_at:
            self._show_tail()
            self.tail = None
            self._vel[self._cur][:] = 0.0
            self.sleeping = True
            self.quiet_ticks = tail.sleep_quiet
            net_box(self._pos[self._cur], out=self.box)

    def _leave_tail(self) -> None:
        """Out of the tail into the full kernel, from the tail's state at this tick (the sleep
        count starts again: the tail knows no tick's speeds)."""
        self._show_tail()
        self.tail = None
        self.quiet_ticks = 0
        net_box(self._pos[self._cur], out=self.box)

    def _out_of_reach(self) -> str:
        return (f"a knot of the net is more than NET_REACH = {NET_REACH} m outside the box it was built in (knots now "
                f"span {self.box.tolist()} m): the net blew up")

    def _out_of_bound(self) -> str:
        return out_of_bound(self.bound, self.box)

    def step_run(self, ball: np.ndarray, ball_radius: float, ball_inv_mass: float,
                 free_outside: np.ndarray) -> tuple[int, NetContact]:
        """A run of ticks with the ball near, up to the first that touches it: tick j as step() with
        the ball at ball[j] (its (2, 3) position m and velocity m/s at the tick's start), or, while
        the net sleeps or rings in its tail and the ball's centre lies outside the (6,) lo, hi box
        `free_outside`, as step_free(1) (the engine steps those ticks so; the same bits as a tick at
        a time). The caller steps the ball's ticks first, without the net; it keeps the ticks up to
        the one that touched and goes back to the state after it.

        Returns:
            (ticks stepped, that last tick's NetContact): the contact, or NO_CONTACT after all of them.
        """
        for j in range(len(ball)):
            pos = ball[j, 0]
            if (self.sleeping or self.tail is not None) and not (
                    free_outside[0] <= pos[0] <= free_outside[3] and free_outside[1] <= pos[1] <= free_outside[4]
                    and free_outside[2] <= pos[2] <= free_outside[5]):
                self.step_free(1)
                continue
            contact = self.step(pos, ball[j, 1], ball_radius, ball_inv_mass)
            if contact.toi != NO_CONTACT:
                return j + 1, contact
        return len(ball), self._no_contact

    def step_free(self, ticks: int) -> None:
        """Advance `ticks` ticks with the ball out of the net's reach: the same bits as as many step()
        calls without a ball (a sleeping net stays as it is, an awake one may fall asleep).

        The caller vouches that the ball stays out of reach: farther from the box the net was built
        in than NET_REACH plus the awake net's margin (WAKE_MARGIN and the radii) over every tick.
        """
        ticks = int(ticks)
        while ticks > 0 and not self.sleeping:
            if self.tail is not None:
                self._advance_tail(ticks)
                return
            if self._step_grid_free is None:
                self.step()
                ticks -= 1
                continue
            ticks -= self._free_run(ticks)

    def _free_run(self, ticks: int) -> int:
        """Up to `ticks` free ticks of an awake grid net in one kernel call (step_free's); returns the ticks taken."""
        topo = self.topo
        reach = self._reach if self.bound is None else self.bound  # the bound promised lies within the reach
        if self._step_free_tail is not None and self._has_modes():
            taken, self.quiet_ticks, status = self._step_free_tail(
                self._state, self._grid_inv_mass, topo.grid_params, self.gravity, self.drag, self.h,
                self.substeps, self._grid_work, ticks, SLEEP_SPEED, SLEEP_TICKS, self.quiet_ticks, reach,
                self.box, topo.knot_mass, topo.knot_inv_mass, topo.spring_ij, topo.spring_rest, topo.spring_k,
                self.modes().rest_energy, self.tail_energy)
        else:
            taken, self.quiet_ticks, status = self._step_grid_free(
                self._state, self._grid_inv_mass, topo.grid_params, self.gravity, self.drag, self.h,
                self.substeps, self._grid_work, ticks, SLEEP_SPEED, SLEEP_TICKS, self.quiet_ticks, reach,
                self.box)
        self.kernel_calls += 1
        self.awake_ticks += taken
        if status == FREE_NOT_FINITE:
            raise FloatingPointError(NOT_FINITE)
        if status == FREE_OUT_OF_REACH:
            if self.bound is not None and not (self._reach[0] > self.box[0]).any() \
                    and not (self.box[1] > self._reach[1]).any():
                raise NetBoundError(self._out_of_bound())
            raise FloatingPointError(self._out_of_reach())
        if status == FREE_ASLEEP:
            self.sleeping = True
        elif status == FREE_TAIL:
            self._start_tail()  # a tick that cannot start it (its bounds reach the table) stays awake
        return taken


def contact_substeps(ball_vel, knot_speed: float, dt: float, substeps: int) -> int:
    """Substeps for a tick of dt s with the ball near: `substeps` (the stability bound's), or more so
    that ball and knots close in by at most CONTACT_TRAVEL in one. They close in at most at the sum
    of their speeds (a struck net's knots outrun the ball they have just slowed), taken up to
    CONTACT_SPEED_MAX; knot_speed: m/s, the fastest knot's (kernels.knot_speed_max)."""
    v0, v1, v2 = float(ball_vel[0]), float(ball_vel[1]), float(ball_vel[2])
    closing = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2) + float(knot_speed)  # kernels.step_grid_tick's arithmetic
    travel = min(closing, CONTACT_SPEED_MAX) * dt
    return max(substeps, math.ceil(travel / CONTACT_TRAVEL))


def compile_kernels(topo: NetTopology, dt: float) -> None:
    """Compile (or load from numba's cache) every kernel a NetSim of `topo` calls in a match, on a
    throwaway NetSim: a tick with the ball within reach, one without it, a run of free ticks of
    a moving net, the linear tail's start, rebuild and end (its modes computed or loaded), and
    the probe of a sleeping net. A worker calls it before it says it is ready: a kernel compiled
    mid-run would leave it silent for as long as that takes (tens of seconds on a loaded
    machine), which the supervisor takes for a stall."""
    sim = NetSim(topo, dt)
    ball, still = topo.knot_pos[0], np.zeros(3)
    sim.step(ball, still)
    sim.wake()
    sim.knot_vel[:] = (topo.knot_inv_mass > 0)[:, None]  # 1 m/s: far above any tail's energy
    sim.step()
    sim.step_free(1)
    if sim.tail_refusal is None:
        sim.knot_pos[:] = sim.modes().rest_pos
        sim.knot_vel[:] = 0.0
        sim.step()  # at rest: the tail takes over
        sim.step_free(1)
        sim.knot_pos  # noqa: B018  (the tail's rebuild)
        sim.step(ball, still)  # the ball within the tail's box: back to the full kernel
    sim.touches(ball, still, BALL_RADIUS, 1.0 / BALL_MASS)


def net_box(knot_pos: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(2, 3) m: the lo and hi corners of the box around the knots (in `out` if given)."""
    if out is None:
        out = np.empty((2, 3))
    knot_pos.min(axis=0, out=out[0])
    knot_pos.max(axis=0, out=out[1])
    return out


def ball_far_from_box(box: np.ndarray, sleeping: bool, knot_radius: float, dt: float, ball_pos, ball_vel,
                      ball_radius: float) -> bool:
    """True when the ball cannot touch a net whose knots lie in `box` within a tick of dt s.

    A sleeping net's knots stay where they are: the ball is far when the box around its straight
    path over the tick stays farther than ball_radius + knot_radius from the knots' box. An awake
    net's knots move within the tick, so the reach grows by WAKE_MARGIN. No ball (None) is
    always far.
    """
    if ball_pos is None:
        return True
    reach = ball_radius + knot_radius + (0.0 if sleeping else WAKE_MARGIN)
    for i in range(3):
        start = float(ball_pos[i])
        end = start + float(ball_vel[i]) * dt
        if min(start, end) > box[1, i] + reach or max(start, end) < box[0, i] - reach:
            return True
    return False
