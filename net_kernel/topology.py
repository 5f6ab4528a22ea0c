"""The net's topology: knots, springs and the CSR adjacency, built once from a NetSpec.

Frame (the project's: origin at the centre of the playing surface, x along the table, z up):
the net hangs in the plane x = 0 and spans y in [-width/2, width/2], z in [hem_gap, height]
(z in [0, height] when its bottom row is tied to the table). Knots sit on a regular grid of
`cols` columns (along y) by `rows` rows (along z), numbered row-major from the bottom row:
knot = row * cols + col. Springs are structural (horizontal, vertical) and
shear (both diagonals) spring-dampers; the top row's horizontal springs are the tensioned top
cord, the bottom row's the bottom cord. Springs between two fixed knots are left out (they
could never move anything).

The net is hung as ITTF Laws 2.2.2-2.2.4 and Technical Leaflet T2 describe a real one: the
mesh hangs from a cord tied to the two posts; its bottom band carries a second cord, tied to
the posts too, that keeps the bottom edge taut just above the playing surface; nothing holds
it from below, so a struck net settles back onto one rest shape (the net tied to the table,
fix_table, buckles into several). The springs still bear compression as well as tension (a
real net's threads go slack): at rest a third of the 85 x 8 net's shear and vertical springs
carry up to 0.07 N in compression against the 0.49 N the whole net weighs.
"""
import math
from dataclasses import dataclass, field, replace

import numpy as np

from net_kernel.kernels import GRID_CLASSES, GRID_CORD, GRID_HEM, GRID_MESH, GRID_SHEAR, GRID_VERTICAL, step_knots_implicit

# ITTF Laws of Table Tennis 2.2.2-2.2.3: the net's top is 15.25 cm above the playing surface
# and its ends are 15.25 cm outside the side lines of the 1.525 m wide table: 1.83 m overall.
NET_WIDTH = 1.83
NET_HEIGHT = 0.1525

# Solvers a NetSpec may name.
SEMI_IMPLICIT = "semi_implicit"  # symplectic Euler, substepped under the stability bound
IMPLICIT = "implicit"  # backward Euler, one Newton step solved by conjugate gradients
SOLVERS = (SEMI_IMPLICIT, IMPLICIT)

# Arithmetic of the grid kernels a NetSpec may name (kernel_precision): float64 (kernels.grid), or
# float32 on offsets from the built grid (kernels.grid32), with multiply-adds fused if kernel_fma.
FLOAT64 = "float64"
FLOAT32 = "float32"
PRECISIONS = (FLOAT64, FLOAT32)

# Knot counts accepted by the builder: 2 per side is the smallest grid with a spring; a
# million knots (1000 x 1000) is the profiling size the issue asks for, 4000 leaves headroom.
_MIN_KNOTS, _MAX_KNOTS = 2, 4000
# A spring shorter than this (m) at rest or as built is degenerate: its direction L/|L| is
# undefined and its force blows up; 1 um is far below any real mesh spacing.
MIN_SPRING_LENGTH = 1e-6


# 1/s: the air's own drag on a net's threads as a mass-proportional damping, within the
# 0.08-0.3/s that Lamb's low-Reynolds drag on a thin cylinder gives (NetSpec.air_damping's
# comment): a net damped by the air alone. scenes/match_air.toml plays the default match with it.
AIR_DAMPING_PHYSICAL = 0.2


@dataclass(frozen=True)
class NetSpec:
    """Static description of the cloth net; the plain field names mirror the scene's [net].

    Attributes:
        width: m, along y (ITTF 2.2.3: 1.83).
        height: m, along z (ITTF 2.2.2: 0.1525).
        cols: knots along y (>= 2).
        rows: knots along z (>= 2).
        knot_mass: kg per knot.
        spring_k: N/m, stiffness of each mesh spring (k_s).
        spring_c: N s/m, axial dashpot of each mesh spring (k_d).
        mesh_tension: N, pretension of the horizontal mesh springs at the built shape (the posts
            hold it; vertical springs get none, else they would pull the top cord down).
        cord_k: N/m, stiffness of each top-cord segment.
        cord_tension: N, tension of the top cord at the built shape.
        hem_tension: N, tension of the bottom cord at the built shape (its stiffness is cord_k:
            the same cord).
        hem_gap: m, height of the bottom cord above the playing surface as built (a hanging
            net's bottom row; it sags from there under the net's weight).
        air_damping: 1/s, linear drag per unit mass on every free knot (damps the sway that
            axial dashpots cannot reach): a chosen constant, not a measurement (no free decay of
            a struck sports net is published); the air's own drag on the threads is far weaker,
            AIR_DAMPING_PHYSICAL. It sets how long a struck net rings and so what it costs: the
            out-of-plane modes decay at air_damping / 2 (`pingpong bench ringdown` and `bench
            match --scene match,match_air` show 5/s beside the air's own drag).
        tail_energy: J, the energy of the net's motion (kinetic plus potential above rest) below
            which its ring is held as modes of the linearised scheme and advanced in closed form
            (net_kernel/tail.py) instead of stepped; 0 steps every awake tick.
        fix_posts: the first and last columns are tied to the posts.
        fix_table: the bottom row is tied to the table (at z = 0) instead of hanging on the
            bottom cord: a net held up by its columns in compression, which buckles.
        solver: "semi_implicit" (substepped symplectic Euler) or "implicit" (backward Euler, CG).
        gravity: m/s^2, along -z.
        kernel_precision: the grid kernels' arithmetic, "float64" (kernels.step_grid) or "float32"
            (kernels.step_grid32: offsets from the built grid, 8 lanes a ymm register); the
            semi-implicit solver only. Its error against float64 is measured, not assumed
            (tests/net_kernel/test_grid32.py).
        kernel_fma: float32 only: fused multiply-adds (kernels.GRID32_FMA); the last bits then
            depend on the machine's FMA, lockstep on one machine stays bit for bit.
    """

    width: float = NET_WIDTH
    height: float = NET_HEIGHT
    cols: int = 184
    rows: int = 16
    # A real net weighs some tens of grams; 50 g over the default 2,944 knots.
    knot_mass: float = 0.05 / (184 * 16)
    # Chosen, not cited: stiff enough that a 20 m/s ball bulges the default net by a few cm.
    spring_k: float = 2000.0
    spring_c: float = 2e-3
    mesh_tension: float = 0.5
    # The net gauge's: 100 g hung at the middle of the top may sink it at most 10 mm
    # (net_kernel.gauge.GAUGE_LOAD), and a real net is tightened until it passes. Under that load
    # the columns below it are in compression and buckle out of plane, so the cord carries most of
    # it (alone, a cord of tension T across the width w would sink m g w / 4 T: 22 mm at 20 N,
    # 11 mm at 40 N). 40 N, with the mesh's share, passes on the 46 x 4, 85 x 8 and 184 x 16 grids
    # (tests/net_kernel/test_ittf.py). Under the net's own weight the top then sags ~1.7 mm at
    # mid-span on 85 x 8 (ITTF 2.2.3: the top 15.25 cm above the playing surface).
    cord_k: float = 5000.0
    cord_tension: float = 40.0
    # Chosen: a twentieth of the top cord's, enough to keep the hem from swinging like a curtain
    # (the ITTF asks only that the bottom be as close to the surface as possible).
    hem_tension: float = 2.0
    # Chosen: the hem sags ~1.7 mm under the net's weight at mid-span, so it rests ~2.3 mm above
    # the playing surface (ITTF 2.2.4: "as close as possible").
    hem_gap: float = 0.004
    # Chosen, not measured: a hanging net's slowest sway (~5 Hz) loses most of its amplitude within
    # a second. The mesh modes a ball excites (tens of Hz at the struck point) then ring with a
    # damping ratio below 0.01, and a struck 85 x 8 net falls asleep a few seconds after the touch
    # (`pingpong bench ringdown` measures both). The air's own drag on the threads is far smaller:
    # Lamb's low-Reynolds drag on a cylinder (Lamb, Hydrodynamics, 6th ed., 1932, art. 343),
    # F / L = 4 pi mu U / (1/2 - gamma - ln(Re / 8)), on 0.5 mm threads at 0.01-0.1 m/s (Re 0.3-3,
    # the upper end an extrapolation), ~200 m of thread per m^2 of a 1 cm mesh and 0.18 kg/m^2,
    # gives 0.08-0.3 /s. A real net loses its energy to friction in its yarns and knots
    # (Miguel et al., "Modeling and Estimation of Internal Friction in Cloth", SIGGRAPH Asia 2013),
    # which the model lacks: no measurement of a net's or a cord's friction is published, and Dahl
    # friction at the magnitudes fabric measurements support (bench/net_friction.py) leaves the
    # net's slowest motion, the mesh swinging about its top cord, which bends no knot and stretches
    # no thread to first order, ringing longer than this damping does. It stands until a struck
    # net's free decay is measured. What it changes, against AIR_DAMPING_PHYSICAL: how long a struck
    # net rings before it falls asleep (the net's awake ticks, the match's CPU and realtime factor),
    # how far the bulge's waves carry its knots (the peak deflection), where the net is when the
    # next ball arrives, and so the match's outcome.
    air_damping: float = 5.0
    # Chosen from `pingpong bench net-tail`'s tail rows: seeded strikes at 5-60 m/s stay within the
    # 50 um budget (a tenth of a knot's radius) of the full kernel over their whole ring.
    tail_energy: float = 30e-6
    fix_posts: bool = True
    fix_table: bool = False
    solver: str = SEMI_IMPLICIT
    gravity: float = 9.81
    kernel_precision: str = FLOAT64
    kernel_fma: bool = False


@dataclass(frozen=True, eq=False)
class NetTopology:
    """Arrays of a built net (structure of arrays: float64 values, unsigned indices).

    Indices are unsigned: uint32 for knots and springs (half the bytes of int64 in the
    kernel's stream; 2^32 is far beyond a million knots), uint64 for CSR starts. Unsigned
    because numba indexes with them without the negative-index wraparound test, which
    slows the gather.

    Attributes:
        spec: the NetSpec it was built from (None when built from raw arrays).
        knot_pos: (n_knots, 3) m, the built (unloaded) shape, world frame.
        knot_mass: (n_knots,) kg.
        knot_inv_mass: (n_knots,) 1/kg, 0 for fixed knots.
        spring_ij: (n_springs, 2) uint32 knot indices, sorted by first knot (one sweep over memory).
        spring_rest: (n_springs,) m, rest length.
        spring_k: (n_springs,) N/m.
        spring_c: (n_springs,) N s/m.
        adj_start: (n_knots + 1,) uint64 CSR row starts: knot i's springs are slots adj_start[i]:adj_start[i+1].
        adj_knot: (2 n_springs,) uint32, the other knot of each slot.
        adj_spring: (2 n_springs,) uint32, the spring of each slot; slots of a knot in increasing spring order.
        h_max: s, the semi-implicit Euler stability bound (see stability_bound).
        rest_pos: (n_knots, 3) m, the shape the net hangs in at rest under gravity (hanging_shape),
            where a NetSim starts; knot_pos for a net tied to the table, whose built shape is its
            rest shape, and for nets built from raw arrays.
        grid_params: (GRID_CLASSES, 3) k N/m, c N s/m, rest length m of each spring class
            (kernels.GRID_MESH, GRID_VERTICAL, GRID_SHEAR, GRID_CORD) when the net is
            build_topology's regular spec.rows x spec.cols grid, whose every spring takes its
            class's values (the grid kernels need nothing else); None for other nets.
    """

    spec: NetSpec | None
    knot_pos: np.ndarray
    knot_mass: np.ndarray
    knot_inv_mass: np.ndarray
    spring_ij: np.ndarray
    spring_rest: np.ndarray
    spring_k: np.ndarray
    spring_c: np.ndarray
    adj_start: np.ndarray
    adj_knot: np.ndarray
    adj_spring: np.ndarray
    h_max: float = field(default=math.inf)
    rest_pos: np.ndarray | None = None
    grid_params: np.ndarray | None = None

    @property
    def n_knots(self) -> int:
        return self.knot_pos.shape[0]

    @property
    def n_springs(self) -> int:
        return self.spring_ij.shape[0]


def _fail(name: str, value, allowed: str) -> ValueError:
    return ValueError(f"NetSpec.{name} = {value!r} is out of range: {allowed}")


def validate_spec(spec: NetSpec) -> None:
    """Raise ValueError naming the first field of `spec` outside its allowed range."""
    for name in ("width", "height", "knot_mass", "spring_k", "cord_k"):
        value = getattr(spec, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise _fail(name, value, "a finite number > 0")
    for name in ("spring_c", "mesh_tension", "cord_tension", "hem_tension", "hem_gap", "air_damping", "tail_energy",
                 "gravity"):
        value = getattr(spec, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise _fail(name, value, "a finite number >= 0")
    if not math.isfinite(1.0 / spec.knot_mass):  # the kernels divide by nothing else
        raise _fail("knot_mass", spec.knot_mass, "a mass whose inverse 1/knot_mass is finite (not subnormal)")
    for name in ("cols", "rows"):
        value = getattr(spec, name)
        if isinstance(value, bool) or not isinstance(value, int) or not _MIN_KNOTS <= value <= _MAX_KNOTS:
            raise _fail(name, value, f"an integer in [{_MIN_KNOTS}, {_MAX_KNOTS}]")
    if spec.solver not in SOLVERS:
        raise _fail("solver", spec.solver, f"one of {', '.join(SOLVERS)}")
    if spec.kernel_precision not in PRECISIONS:
        raise _fail("kernel_precision", spec.kernel_precision, f"one of {', '.join(PRECISIONS)}")
    if spec.kernel_precision == FLOAT32 and spec.solver != SEMI_IMPLICIT:
        raise _fail("kernel_precision", spec.kernel_precision,
                    f"{FLOAT64} with solver = {spec.solver!r} (float32 grid kernels step the semi_implicit solver only)")
    if not isinstance(spec.kernel_fma, bool):
        raise _fail("kernel_fma", spec.kernel_fma, "True or False")
    if spec.kernel_fma and spec.kernel_precision != FLOAT32:
        raise _fail("kernel_fma", spec.kernel_fma, f"False unless kernel_precision = {FLOAT32!r} (only the float32 "
                    "grid kernels fuse multiply-adds)")
    if not spec.fix_table and spec.hem_gap >= spec.height:
        raise _fail("hem_gap", spec.hem_gap, f"< height = {spec.height} (the bottom cord below the top cord)")
    col_spacing, row_spacing = grid_spacings(spec)
    if min(col_spacing, row_spacing) < MIN_SPRING_LENGTH:
        raise _fail("cols" if col_spacing < row_spacing else "rows", spec.cols if col_spacing < row_spacing else spec.rows,
                    f"knot spacing {min(col_spacing, row_spacing):.3g} m is below the {MIN_SPRING_LENGTH} m minimum spring length")
    # A pretension T on a spring of stiffness k and length s means rest length s - T/k > 0.
    if spec.cord_tension >= spec.cord_k * col_spacing:
        raise _fail("cord_tension", spec.cord_tension,
                    f"< cord_k * column spacing = {spec.cord_k * col_spacing:.4g} N (else the cord's rest length is <= 0)")
    if spec.hem_tension >= spec.cord_k * col_spacing:
        raise _fail("hem_tension", spec.hem_tension,
                    f"< cord_k * column spacing = {spec.cord_k * col_spacing:.4g} N (else the bottom cord's rest length is <= 0)")
    if spec.mesh_tension >= spec.spring_k * col_spacing:
        raise _fail("mesh_tension", spec.mesh_tension,
                    f"< spring_k * column spacing = {spec.spring_k * col_spacing:.4g} N "
                    "(else a horizontal mesh spring's rest length is <= 0)")
    if not (spec.fix_posts or spec.fix_table):
        raise _fail("fix_posts", spec.fix_posts, "True unless fix_table is True (a net with no fixed knot falls)")


def build_topology(spec: NetSpec) -> NetTopology:
    """Knots and springs of the net that `spec` describes; the one builder of derived values.

    Raises:
        ValueError: a field of `spec` is outside its range (the message names it), or a
            spring comes out degenerate.
    """
    validate_spec(spec)
    cols, rows = spec.cols, spec.rows
    col = np.tile(np.arange(cols), rows)
    row = np.repeat(np.arange(rows), cols)
    col_spacing, row_spacing = grid_spacings(spec)
    knot_pos = np.zeros((cols * rows, 3))
    knot_pos[:, 1] = -spec.width / 2 + col * col_spacing
    knot_pos[:, 2] = _bottom(spec) + row * row_spacing
    fixed = np.zeros(cols * rows, dtype=bool)
    if spec.fix_posts:
        fixed |= (col == 0) | (col == cols - 1)
    if spec.fix_table:
        fixed |= row == 0
    knot_mass = np.full(cols * rows, float(spec.knot_mass))

    idx = np.arange(cols * rows).reshape(rows, cols)
    pairs = [
        (idx[:, :-1], idx[:, 1:], 0),  # horizontal
        (idx[:-1, :], idx[1:, :], 1),  # vertical
        (idx[:-1, :-1], idx[1:, 1:], 2),  # shear /
        (idx[:-1, 1:], idx[1:, :-1], 2),  # shear \
    ]
    spring_ij = np.concatenate([np.stack([a.ravel(), b.ravel()], axis=1) for a, b, _ in pairs])
    kind = np.concatenate([np.full(a.size, k) for a, _, k in pairs])
    kind = np.array([GRID_MESH, GRID_VERTICAL, GRID_SHEAR])[kind]
    kind[(kind == GRID_MESH) & (row[spring_ij[:, 0]] == rows - 1)] = GRID_CORD  # the top row's horizontals
    kind[(kind == GRID_MESH) & (row[spring_ij[:, 0]] == 0)] = GRID_HEM  # the bottom row's
    # One value per spring class, so the grid kernels need no per-spring arrays: the rest
    # length is the built length less the pretension's stretch T / k.
    grid_params = np.zeros((GRID_CLASSES, 3))
    grid_params[GRID_MESH] = spec.spring_k, spec.spring_c, col_spacing - spec.mesh_tension / spec.spring_k
    grid_params[GRID_VERTICAL] = spec.spring_k, spec.spring_c, row_spacing
    grid_params[GRID_SHEAR] = spec.spring_k, spec.spring_c, math.hypot(col_spacing, row_spacing)
    grid_params[GRID_CORD] = spec.cord_k, spec.spring_c, col_spacing - spec.cord_tension / spec.cord_k
    grid_params[GRID_HEM] = spec.cord_k, spec.spring_c, col_spacing - spec.hem_tension / spec.cord_k
    spring_k = grid_params[kind, 0]
    spring_c = grid_params[kind, 1]
    spring_rest = grid_params[kind, 2]
    keep = ~(fixed[spring_ij[:, 0]] & fixed[spring_ij[:, 1]])
    # Springs in order of their first knot, then second: the per-spring pass then sweeps the
    # knot arrays once instead of once per spring kind.
    order = np.lexsort((spring_ij[:, 1], spring_ij[:, 0]))
    order = order[keep[order]]
    topo = make_topology(knot_pos, knot_mass, fixed, spring_ij[order], spring_rest[order], spring_k[order],
                         spring_c[order], spec=spec)
    object.__setattr__(topo, "grid_params", grid_params)
    if not spec.fix_table:
        shape_key = replace(spec, kernel_precision=FLOAT64, kernel_fma=False)  # the kernels do not settle it
        rest = _REST_SHAPES.get(shape_key)
        if rest is None:
            rest = _REST_SHAPES[shape_key] = hanging_shape(topo)
        object.__setattr__(topo, "rest_pos", rest)
    return topo


# Rest shapes already settled, by spec (a frozen dataclass): the same spec builds the same net, and
# settling the default 184 x 16 net takes seconds. Read-only arrays, shared by the topologies.
_REST_SHAPES: dict[NetSpec, np.ndarray] = {}


def _bottom(spec: NetSpec) -> float:
    """m, the height of the net's bottom row as built: on the table when tied to it, else the hem's gap."""
    return 0.0 if spec.fix_table else spec.hem_gap


def grid_spacings(spec: NetSpec) -> tuple[float, float]:
    """(a, b) m: column spacing along y and row spacing along z of `spec`'s grid as built."""
    return spec.width / (spec.cols - 1), (spec.height - _bottom(spec)) / (spec.rows - 1)


# Static equilibrium by backward Euler at long steps: for h -> inf a step is one Newton step on
# f(x) = 0 (Baraff & Witkin 1998 with M/h^2 a regularising term), so a few dozen steps reach the
# rest shape where explicit steps would need seconds of simulated sway. Above _LANCZOS_MAX_KNOTS
# (the million-knot profiling nets) the built shape stands in: there it would take minutes.
_SETTLE_STEP = 1.0  # s
_SETTLE_STEPS = 100
_SETTLE_SPEED = 1e-10  # m/s: a knot slower than this over a step of _SETTLE_STEP moves < 0.1 nm
_SETTLE_CG_TOL = 1e-10


def hanging_shape(topo: NetTopology) -> np.ndarray:
    """(n_knots, 3) m, the static equilibrium of `topo`'s net under gravity (spec.gravity), read-only.

    Backward Euler steps of _SETTLE_STEP from the built shape until every knot is slower than
    _SETTLE_SPEED; the built shape for nets above _LANCZOS_MAX_KNOTS knots or without a spec.

    Raises:
        RuntimeError: the net did not settle in _SETTLE_STEPS steps.
    """
    if topo.spec is None or topo.n_knots > _LANCZOS_MAX_KNOTS:
        return topo.knot_pos
    n, m = topo.n_knots, topo.n_springs
    pos, vel = topo.knot_pos.copy(), np.zeros((n, 3))
    out_pos, out_vel = np.zeros((n, 3)), np.zeros((n, 3))
    knot_work, spring_work = np.zeros((4, n, 3)), np.zeros((m, 7))
    for _ in range(_SETTLE_STEPS):
        step_knots_implicit(pos, vel, topo.knot_inv_mass, topo.adj_start, topo.adj_knot, topo.adj_spring,
                            topo.spring_ij, topo.spring_rest, topo.spring_k, topo.spring_c, topo.spec.gravity,
                            topo.spec.air_damping, _SETTLE_STEP, _SETTLE_CG_TOL, 10 * n, knot_work, spring_work,
                            out_pos, out_vel)
        pos, out_pos, vel, out_vel = out_pos, pos, out_vel, vel
        if np.abs(vel).max() < _SETTLE_SPEED:
            pos.flags.writeable = False
            return pos
    raise RuntimeError(f"the net {topo.spec} did not settle in {_SETTLE_STEPS} backward Euler steps")


def make_topology(knot_pos, knot_mass, knot_fixed, spring_ij, spring_rest, spring_k, spring_c,
                  spec: NetSpec | None = None) -> NetTopology:
    """Validate raw knot and spring arrays and build the CSR adjacency.

    Args:
        knot_pos: (n_knots, 3) m, world frame.
        knot_mass: (n_knots,) kg, > 0.
        knot_fixed: (n_knots,) bool, True for knots tied to the posts or the table.
        spring_ij: (n_springs, 2) int knot indices, i != j, each pair at most once.
        spring_rest: (n_springs,) m, >= MIN_SPRING_LENGTH.
        spring_k: (n_springs,) N/m, >= 0.
        spring_c: (n_springs,) N s/m, >= 0.
        spec: the NetSpec these came from, if any.

    Raises:
        ValueError: naming the first degenerate spring or bad array.
    """
    knot_pos = np.ascontiguousarray(knot_pos, dtype="<f8")
    n = knot_pos.shape[0]
    if knot_pos.ndim != 2 or knot_pos.shape[1] != 3 or not np.all(np.isfinite(knot_pos)):
        raise ValueError("knot_pos must be a finite (n_knots, 3) array")
    knot_mass = np.ascontiguousarray(knot_mass, dtype="<f8")
    if knot_mass.shape != (n,) or not np.all(np.isfinite(knot_mass) & (knot_mass > 0)):
        raise ValueError("knot_mass must be (n_knots,) with every mass finite and > 0")
    knot_fixed = np.asarray(knot_fixed, dtype=bool)
    spring_ij = np.asarray(spring_ij)
    m = spring_ij.shape[0]
    if spring_ij.ndim != 2 or spring_ij.shape[1] != 2:
        raise ValueError("spring_ij must be (n_springs, 2)")
    arrays = {}
    for name, arr in (("spring_rest", spring_rest), ("spring_k", spring_k), ("spring_c", spring_c)):
        arr = np.ascontiguousarray(arr, dtype="<f8")
        if arr.shape != (m,) or not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be a finite (n_springs,) array")
        arrays[name] = arr
    bad = np.flatnonzero((spring_ij < 0).any(axis=1) | (spring_ij >= n).any(axis=1))
    if bad.size:
        raise ValueError(f"spring {bad[0]} joins knots {tuple(spring_ij[bad[0]])}: indices must be in [0, {n})")
    bad = np.flatnonzero(spring_ij[:, 0] == spring_ij[:, 1])
    if bad.size:
        raise ValueError(f"degenerate spring {bad[0]}: it joins knot {spring_ij[bad[0], 0]} to itself")
    length = np.linalg.norm(knot_pos[spring_ij[:, 0]] - knot_pos[spring_ij[:, 1]], axis=1)
    bad = np.flatnonzero(length < MIN_SPRING_LENGTH)
    if bad.size:
        raise ValueError(f"degenerate spring {bad[0]} between knots {tuple(spring_ij[bad[0]])}: its knots are "
                         f"{length[bad[0]]:.3g} m apart, below the {MIN_SPRING_LENGTH} m minimum (zero-length springs "
                         "have no direction)")
    bad = np.flatnonzero(arrays["spring_rest"] < MIN_SPRING_LENGTH)
    if bad.size:
        raise ValueError(f"degenerate spring {bad[0]} between knots {tuple(spring_ij[bad[0]])}: rest length "
                         f"{arrays['spring_rest'][bad[0]]:.3g} m is below the {MIN_SPRING_LENGTH} m minimum")
    for name in ("spring_k", "spring_c"):
        bad = np.flatnonzero(arrays[name] < 0)
        if bad.size:
            raise ValueError(f"spring {bad[0]}: {name} = {arrays[name][bad[0]]} must be >= 0")
    spring_ij = np.ascontiguousarray(spring_ij, dtype=np.uint32)
    key = np.sort(spring_ij, axis=1)
    if m and np.unique(key, axis=0).shape[0] != m:
        raise ValueError("spring_ij lists the same pair of knots twice")

    # CSR: each knot's slots in increasing spring order, so every gather sums in a fixed order.
    ends = np.concatenate([spring_ij[:, 0], spring_ij[:, 1]])
    other = np.concatenate([spring_ij[:, 1], spring_ij[:, 0]])
    spring = np.concatenate([np.arange(m), np.arange(m)])
    order = np.lexsort((spring, ends))
    adj_start = np.zeros(n + 1, dtype=np.uint64)
    np.cumsum(np.bincount(ends, minlength=n), out=adj_start[1:])
    knot_inv_mass = np.where(knot_fixed, 0.0, 1.0 / knot_mass)
    topo = NetTopology(spec, knot_pos, knot_mass, knot_inv_mass, spring_ij, arrays["spring_rest"],
                       arrays["spring_k"], arrays["spring_c"], adj_start,
                       np.ascontiguousarray(other[order], dtype=np.uint32),
                       np.ascontiguousarray(spring[order], dtype=np.uint32))
    object.__setattr__(topo, "h_max", stability_bound(topo))
    object.__setattr__(topo, "rest_pos", knot_pos)
    return topo


# The largest eigenvalue of a net's stiffness by Lanczos (Golub & Van Loan, "Matrix Computations",
# 4th ed., 10.1): 100 steps bring the top Ritz value of the nets here to ~1e-9 of it. Beyond
# _LANCZOS_MAX_KNOTS (the million-knot profiling nets) the Gershgorin bound stands: there
# Lanczos would take seconds of build time.
_LANCZOS_STEPS = 100
_LANCZOS_MAX_KNOTS = 50_000


def stability_bound(topo: NetTopology) -> float:
    """s, the largest step semi-implicit Euler may take on `topo`'s net, dashpots included.

    Per mode of stiffness w^2 and damping g (per unit mass), symplectic Euler's amplification
    matrix has det = 1 - h g and trace = 2 - h g - h^2 w^2; the Jury conditions give
    h^2 w^2 + 2 h g < 4, i.e. h < (sqrt(g^2 + 4 w^2) - g) / w^2 (= 2/w undamped), which falls as
    w or g grows: the bound takes the largest of each.

    The largest w^2 holds for every shape the net can take: a spring's stiffness block
    k_s n n^T + (T/L) (I - n n^T) has its transverse part T/L = k_s (1 - rest/L) below k_s, so
    the net's stiffness is at most L_k (x) I3, L_k the graph Laplacian of the springs weighted by
    k_s, and w^2 <= the largest eigenvalue of M^-1/2 L_k M^-1/2 over the free knots (likewise g
    with k_d, plus air damping). That eigenvalue comes from Lanczos, plus its residual bound,
    capped by Gershgorin's max_i 2 K_i / m_i (K_i the sum of k_s over knot i's springs). On a
    long chain the two agree (w^2 -> 4k/m); on the grid nets, whose shear springs close
    triangles, the eigenvalue is ~3/4 of Gershgorin's: 85 x 8 takes 10 substeps a 1 ms tick
    instead of 12. Exact for proportional damping; for other dashpots it is the per-mode estimate.
    """
    n = topo.n_knots
    ends = topo.spring_ij.ravel()
    stiff = np.bincount(ends, weights=np.repeat(topo.spring_k, 2), minlength=n)
    damp = np.bincount(ends, weights=np.repeat(topo.spring_c, 2), minlength=n)
    air = topo.spec.air_damping if topo.spec is not None else 0.0
    free = (topo.knot_inv_mass > 0) & (stiff > 0)
    if not free.any():
        return math.inf
    w2 = _laplacian_top(topo, topo.spring_k, float(np.max(2.0 * stiff[free] * topo.knot_inv_mass[free])))
    g = _laplacian_top(topo, topo.spring_c, float(np.max(2.0 * damp[free] * topo.knot_inv_mass[free]))) + air
    return float((math.sqrt(g * g + 4.0 * w2) - g) / w2)


def _laplacian_top(topo: NetTopology, weight: np.ndarray, gershgorin: float) -> float:
    """An upper bound on the largest eigenvalue of M^-1/2 L M^-1/2, L the Laplacian of the springs
    weighted by `weight`, over the free knots: Lanczos's top Ritz value plus its residual norm
    (an eigenvalue lies within it), at most `gershgorin`. Seeded: the same net, the same bound."""
    n = topo.n_knots
    if gershgorin <= 0.0 or n > _LANCZOS_MAX_KNOTS:
        return gershgorin
    # D = M^-1/2 is 0 on fixed knots, so D L D is the free knots' operator padded with zeros.
    scale = np.sqrt(topo.knot_inv_mass)
    i = topo.spring_ij[:, 0].astype(np.int64)
    j = topo.spring_ij[:, 1].astype(np.int64)

    def apply(x: np.ndarray) -> np.ndarray:
        z = scale * x
        f = weight * (z[i] - z[j])
        return scale * (np.bincount(i, weights=f, minlength=n) - np.bincount(j, weights=f, minlength=n))

    steps = min(_LANCZOS_STEPS, int(np.count_nonzero(scale)))
    basis = np.zeros((steps, n))
    alpha = np.zeros(steps)
    beta = np.zeros(steps)
    q = np.random.default_rng(0).standard_normal(n) * (scale > 0)
    q /= np.linalg.norm(q)
    m = 0
    for m in range(steps):
        basis[m] = q
        w = apply(q)
        alpha[m] = w @ q
        w -= basis[: m + 1].T @ (basis[: m + 1] @ w)  # full reorthogonalisation: no ghost copies
        beta[m] = np.linalg.norm(w)
        if beta[m] <= 1e-12 * abs(alpha[m]) or m == steps - 1:
            break
        q = w / beta[m]
    size = m + 1
    ritz, vectors = np.linalg.eigh(np.diag(alpha[:size]) + np.diag(beta[: size - 1], 1) + np.diag(beta[: size - 1], -1))
    residual = beta[m] * abs(vectors[-1, -1])  # |A y - theta y| of the top Ritz pair
    return min(float(ritz[-1] + residual), gershgorin)


def grid_spec(cols: int, rows: int, **fields) -> NetSpec:
    """A NetSpec for a cols x rows grid of the default net's cloth (for profiling any size).

    The knot mass scales so the whole net weighs what the default net weighs.
    """
    fields.setdefault("knot_mass", 0.05 / (cols * rows))
    base = NetSpec()
    spacing = fields.get("width", base.width) / (cols - 1)
    # Fine grids have short springs: keep the pretensions below k * spacing (half of it at most).
    fields.setdefault("mesh_tension", min(base.mesh_tension, 0.5 * fields.get("spring_k", base.spring_k) * spacing))
    fields.setdefault("cord_tension", min(base.cord_tension, 0.5 * fields.get("cord_k", base.cord_k) * spacing))
    fields.setdefault("hem_tension", min(base.hem_tension, 0.5 * fields.get("cord_k", base.cord_k) * spacing))
    return NetSpec(cols=cols, rows=rows, **fields)


def net_continuum(spec: NetSpec) -> dict:
    """The continuum that `spec`'s lattice stands for (small strain about the built shape).

    See resolution_spec for the derivation. Returns a dict of floats:
        areal_density: kg/m^2, knot mass over the cell area a b.
        mesh_prestress: N/m, horizontal stress resultant N_yy = mesh_tension / b.
        c11, c22, c12: N/m, membrane stiffness (stress resultant per unit strain) along y,
            along z and the cross term (= the shear term c66 for a central-force lattice).
        equibiaxial: N/m, c11 + c22 + 2 c12 = 3 spring_k (a/b + b/a).
        mesh_viscosity: N s/m, the dashpots' equibiaxial counterpart, 3 spring_c (a/b + b/a).
        cord_tension: N; cord_stiffness: N, EA = cord_k a; cord_line_density: kg/m, top-row
            knot mass per unit length.
        wave_speed: m/s, sqrt(N_yy / areal_density), the speed of transverse waves along y.
        h_max_scale: s, sqrt(knot_mass / spring_k), the mesh's part of the stability bound.
    """
    a, b = grid_spacings(spec)
    d2 = a * a + b * b
    k = spec.spring_k
    rho = spec.knot_mass / (a * b)
    prestress = spec.mesh_tension / b
    return {
        "areal_density": rho,
        "mesh_prestress": prestress,
        "c11": k * a / b + 2.0 * k * a**3 / (b * d2),
        "c22": k * b / a + 2.0 * k * b**3 / (a * d2),
        "c12": 2.0 * k * a * b / d2,
        "equibiaxial": 3.0 * k * (a / b + b / a),
        "mesh_viscosity": 3.0 * spec.spring_c * (a / b + b / a),
        "cord_tension": spec.cord_tension,
        "cord_stiffness": spec.cord_k * a,
        "cord_line_density": spec.knot_mass / a,
        "wave_speed": math.sqrt(prestress / rho),
        "h_max_scale": math.sqrt(spec.knot_mass / k),
    }


def resolution_spec(cols: int, rows: int, base: NetSpec | None = None) -> NetSpec:
    """The same physical net as `base` (default NetSpec()) on a cols x rows grid of knots.

    grid_spec only spreads the net's mass over the new knots; every spring keeps its stiffness,
    pretension and dashpot, so a coarser grid built that way is another cloth (on 46 x 4 knots
    the mesh's prestress drops 5x and its transverse waves run at half speed). Here each field
    scales with the column spacing a = width / (cols - 1) and the row spacing b =
    height / (rows - 1) (base: a0, b0) so that the continuum the lattice stands for stays put.

    Derivation (a lattice of cells a x b: one horizontal spring k_h of length a, one vertical
    k_v of length b and two diagonals k_d of length d = sqrt(a^2 + b^2) per cell; net_continuum
    evaluates the result):

    - Areal density rho = knot_mass / (a b): knot_mass ~ a b.
    - Membrane prestress: a cut of unit length along z crosses 1/b horizontal springs, so the
      horizontal stress resultant is N_yy = T_h / b: mesh_tension ~ b. Vertical and shear
      springs carry none (as in build_topology). With rho fixed, the transverse wave speed
      sqrt(N_yy / rho) and so the net's sway frequencies stay put.
    - Sheet stiffness: a homogeneous strain e stretches a spring of length L along n by
      L n.e.n, storing k L^2 (n.e.n)^2 / 2 in a cell of area a b. Summed over a cell's springs:
      c11 = k_h a/b + 2 k_d a^3/(b d^2), c22 = k_v b/a + 2 k_d b^3/(a d^2),
      c12 = c66 = 2 k_d a b / d^2 (N/m). NetSpec has one spring_k for all three classes
      (k_h = k_v = k_d = k); then the tensor depends on a and b only through the aspect ratio
      a/b, and for square cells it is k (2, 2, 1) at any size. For other aspect ratios no
      single k keeps every entry; the one kept is the equibiaxial modulus
      c11 + c22 + 2 c12 = 3 k (a/b + b/a), the stiffness a round bulge (a ball pushing
      the net) works against: spring_k ~ 1 / (a/b + b/a). c11 and c22 then move with a/b
      (net_continuum): the default's a/b = 0.98; 70 x 7 (1.04), 92 x 8 (0.92), 128 x 11 (0.94)
      and 368 x 32 (1.01) keep them within 10 % of the default's, 46 x 4 (a/b = 0.80) is
      29 % softer along y and 32 % stiffer along z; (12 (rows - 1) + 1) x rows grids have
      square cells, for which every entry is kept.
    - Dashpots: a dashpot along a spring gives viscous stress resultants of the same form, with
      spring_c for k: spring_c ~ 1 / (a/b + b/a), as spring_k. NetSpec's one spring_c also
      damps the top cord, whose line dashpot (c a) then grows as a; it acts along the cord
      only, on its axial waves, which the ball hardly excites.
    - Top cord, a 1-D line of segments of length a: the segment's stiffness is EA / a:
      cord_k ~ 1 / a (cord_k a = EA fixed); its tension is a force: cord_tension fixed. The
      bottom cord likewise (hem_tension fixed).
      The top row's knots carry the mesh's mass per unit length rho b (NetSpec has one knot
      mass), a lumped edge mass that shrinks with b: a discretisation error of order b / height.
    - Air damping is per unit mass (the kernels apply -air_damping v to every free knot): fixed.
      Gravity and the solver: fixed.
    - Stability bound: w^2 ~ K_i / m_i (stability_bound) with K_i ~ k (mesh) and m_i ~ a b, so h_max ~
      sqrt(a b / k) ~ a for square cells (the top row's cord: K ~ 1/a, h_max ~ a sqrt(b)).
      NetSim derives its substeps from the built net's bound: a grid 2x coarser takes about
      half the substeps on a quarter of the knots, ~1/8 of the work per tick.

    Args:
        cols, rows: knots along y and z (validated by build_topology's rules).
        base: the net to reproduce (its width, height, cols and rows set a0, b0).

    Returns:
        A NetSpec with cols, rows and the scaled knot_mass, spring_k, spring_c, mesh_tension,
        cord_k; every other field as in base.

    Raises:
        ValueError: cols or rows outside build_topology's range (the message names it), or
            cells so far from square that a scaled pretension exceeds its spring's k a.
    """
    base = NetSpec() if base is None else base
    validate_spec(base)
    for name, value in (("cols", cols), ("rows", rows)):
        if isinstance(value, bool) or not isinstance(value, int) or not _MIN_KNOTS <= value <= _MAX_KNOTS:
            raise _fail(name, value, f"an integer in [{_MIN_KNOTS}, {_MAX_KNOTS}]")
    a0, b0 = grid_spacings(base)
    a, b = grid_spacings(replace(base, cols=cols, rows=rows))
    sheet = (a0 / b0 + b0 / a0) / (a / b + b / a)
    spec = replace(base, cols=cols, rows=rows,
                   knot_mass=base.knot_mass * (a * b) / (a0 * b0),
                   mesh_tension=base.mesh_tension * b / b0,
                   spring_k=base.spring_k * sheet,
                   spring_c=base.spring_c * sheet,
                   cord_k=base.cord_k * a0 / a)
    try:
        validate_spec(spec)
    except ValueError as err:
        raise ValueError(f"resolution_spec({cols}, {rows}): the scaled net cannot be built ({err}); its cells are "
                         f"{a * 1e3:.3g} x {b * 1e3:.3g} mm (a/b = {a / b:.3g}): choose cols and rows closer to square "
                         f"cells, cols - 1 ~ {base.width / base.height:.3g} (rows - 1)") from None
    return spec
