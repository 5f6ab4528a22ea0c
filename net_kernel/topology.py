"""The net's topology: knots, springs and the CSR adjacency, built once from a NetSpec.

Frame (DESIGN.md): the net hangs in the plane x = 0 and spans y in [-width/2, width/2],
z in [0, height]. Knots sit on a regular grid of `cols` columns (along y) by `rows` rows
(along z), numbered row-major from the bottom row: knot = row * cols + col. Springs are
structural (horizontal, vertical) and shear (both diagonals) spring-dampers; the top row's
horizontal springs are the tensioned top cord. Springs between two fixed knots are left out
(they could never move anything).
"""
import math
from dataclasses import dataclass, field

import numpy as np

from net_kernel.kernels import GRID_CLASSES, GRID_CORD, GRID_MESH, GRID_SHEAR, GRID_VERTICAL

# ITTF Laws of Table Tennis 2.2.2-2.2.3: the net's top is 15.25 cm above the playing surface
# and its ends are 15.25 cm outside the side lines of the 1.525 m wide table: 1.83 m overall.
NET_WIDTH = 1.83
NET_HEIGHT = 0.1525

# Solvers a NetSpec may name.
SEMI_IMPLICIT = "semi_implicit"  # symplectic Euler, substepped under the stability bound
IMPLICIT = "implicit"  # backward Euler, one Newton step solved by conjugate gradients
SOLVERS = (SEMI_IMPLICIT, IMPLICIT)

# Knot counts accepted by the builder: 2 per side is the smallest grid with a spring; a
# million knots (1000 x 1000) is the profiling size the issue asks for, 4000 leaves headroom.
_MIN_KNOTS, _MAX_KNOTS = 2, 4000
# A spring shorter than this (m) at rest or as built is degenerate: its direction L/|L| is
# undefined and its force blows up; 1 um is far below any real mesh spacing.
MIN_SPRING_LENGTH = 1e-6


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
        air_damping: 1/s, linear air drag per unit mass on every free knot (damps the sway
            that axial dashpots cannot reach).
        fix_posts: the first and last columns are tied to the posts.
        fix_table: the bottom row is tied to the table's edge.
        solver: "semi_implicit" (substepped symplectic Euler) or "implicit" (backward Euler, CG).
        gravity: m/s^2, along -z.
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
    # Chosen: the top cord sags a few mm under the net's weight (W L / (8 T) = 5.6 mm for a
    # free cable) while its stability bound still allows ~60 us substeps.
    cord_k: float = 5000.0
    cord_tension: float = 20.0
    # Chosen: a hanging net's slowest sway (~5 Hz) loses most of its amplitude within a second.
    air_damping: float = 5.0
    fix_posts: bool = True
    fix_table: bool = True
    solver: str = SEMI_IMPLICIT
    gravity: float = 9.81


@dataclass(frozen=True, eq=False)
class NetTopology:
    """Arrays of a built net (structure of arrays: float64 values, unsigned indices).

    Indices are unsigned: uint32 for knots and springs (half the bytes of int64 in the
    kernel's stream; 2^32 is far beyond a million knots), uint64 for CSR starts. Unsigned
    because numba indexes with them without the negative-index wraparound test, which
    measured 1.3-3x slower in the gather (184 x 16 net, 2-core EPYC, see the commit).

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
    for name in ("spring_c", "mesh_tension", "cord_tension", "air_damping", "gravity"):
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
    col_spacing = spec.width / (spec.cols - 1)
    row_spacing = spec.height / (spec.rows - 1)
    if min(col_spacing, row_spacing) < MIN_SPRING_LENGTH:
        raise _fail("cols" if col_spacing < row_spacing else "rows", spec.cols if col_spacing < row_spacing else spec.rows,
                    f"knot spacing {min(col_spacing, row_spacing):.3g} m is below the {MIN_SPRING_LENGTH} m minimum spring length")
    # A pretension T on a spring of stiffness k and length s means rest length s - T/k > 0.
    if spec.cord_tension >= spec.cord_k * col_spacing:
        raise _fail("cord_tension", spec.cord_tension,
                    f"< cord_k * column spacing = {spec.cord_k * col_spacing:.4g} N (else the cord's rest length is <= 0)")
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
    knot_pos = np.zeros((cols * rows, 3))
    knot_pos[:, 1] = -spec.width / 2 + col * (spec.width / (cols - 1))
    knot_pos[:, 2] = row * (spec.height / (rows - 1))
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
    # One value per spring class, so the grid kernels need no per-spring arrays: the rest
    # length is the built length less the pretension's stretch T / k.
    col_spacing = spec.width / (cols - 1)
    row_spacing = spec.height / (rows - 1)
    grid_params = np.zeros((GRID_CLASSES, 3))
    grid_params[GRID_MESH] = spec.spring_k, spec.spring_c, col_spacing - spec.mesh_tension / spec.spring_k
    grid_params[GRID_VERTICAL] = spec.spring_k, spec.spring_c, row_spacing
    grid_params[GRID_SHEAR] = spec.spring_k, spec.spring_c, math.hypot(col_spacing, row_spacing)
    grid_params[GRID_CORD] = spec.cord_k, spec.spring_c, col_spacing - spec.cord_tension / spec.cord_k
    spring_k = grid_params[kind, 0]
    spring_c = grid_params[kind, 1]
    spring_rest = grid_params[kind, 2]
    keep = ~(fixed[spring_ij[:, 0]] & fixed[spring_ij[:, 1]])
    # Springs in order of their first knot, then second: the per-spring pass then sweeps the
    # knot arrays once instead of once per spring kind (measured on 1000 x 1000).
    order = np.lexsort((spring_ij[:, 1], spring_ij[:, 0]))
    order = order[keep[order]]
    topo = make_topology(knot_pos, knot_mass, fixed, spring_ij[order], spring_rest[order], spring_k[order],
                         spring_c[order], spec=spec)
    object.__setattr__(topo, "grid_params", grid_params)
    return topo


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
    return topo


def stability_bound(topo: NetTopology) -> float:
    """s, the largest step semi-implicit Euler may take on `topo`'s net, dashpots included.

    Per mode of stiffness w^2 and damping g (per unit mass), symplectic Euler's amplification
    matrix has det = 1 - h g and trace = 2 - h g - h^2 w^2; the Jury conditions give
    h^2 w^2 + 2 h g < 4, i.e. h < (sqrt(g^2 + 4 w^2) - g) / w^2 (= 2/w undamped). The Rayleigh
    quotient of a spring network bounds w^2 <= max_i 2 K_i / m_i and g <= max_i 2 C_i / m_i, with
    K_i, C_i the sums of k_s, k_d over knot i's springs (air damping adds to g) (a pretensioned spring's transverse
    stiffness T/L is below k_s). The bound is tight for a long chain (w^2 -> 4k/m).
    Exact for proportional damping; for other dashpots it is the per-mode estimate.
    """
    n = topo.n_knots
    ends = topo.spring_ij.ravel()
    stiff = np.bincount(ends, weights=np.repeat(topo.spring_k, 2), minlength=n)
    damp = np.bincount(ends, weights=np.repeat(topo.spring_c, 2), minlength=n)
    air = topo.spec.air_damping if topo.spec is not None else 0.0
    free = (topo.knot_inv_mass > 0) & (stiff > 0)
    if not free.any():
        return math.inf
    w2 = 2.0 * stiff[free] * topo.knot_inv_mass[free]
    g = 2.0 * damp[free] * topo.knot_inv_mass[free] + air
    return float(np.min((np.sqrt(g * g + 4.0 * w2) - g) / w2))


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
    return NetSpec(cols=cols, rows=rows, **fields)
