"""The net's linear modes: its discrete scheme linearised about the rest shape, for the ringing tail.

A struck net's late motion is small, and around its rest shape x0 the scheme NetSim steps
(semi-implicit Euler, substep h, air damping g per unit mass) is then a linear map of the
state. With u = x - x0 and S, C the stiffness and damping matrices of the springs at x0
(S = -dF/dx, C = -dF/dv; both symmetric), one substep is

    v' = v - h (M^-1 S u + (M^-1 C + g) v),    u' = u + h v'.

The rest shape of a hanging net lies in the plane x = 0, so every spring is in that plane at
rest: the out-of-plane motion (the knots' x) decouples exactly from the in-plane motion (y, z)
to first order, the springs' dashpots act on it not at all (their rate is along the spring),
and its stiffness is the springs' tension over their length alone. In the mass-normalised
eigenvectors of M^-1/2 S_xx M^-1/2 (eigenvalues lam) each out-of-plane mode is then a scalar
oscillator q'' = -lam q - g q', whose substep is the 2 x 2 matrix

    A = [[1 - h^2 lam, h (1 - h g)], [-h lam, 1 - h g]]    on (q, q'),

det A = 1 - h g for every mode. A tick of s substeps is A^s and n ticks A^(s n); its eigenvalue
mu (one of a complex pair) gives the closed form q(n) = 2 Re(c mu^n), q'(n) = 2 Re(c e mu^n),
with (1, e) the eigenvector. The in-plane motion keeps the dashpots, which couple its modes:
its lowest IN_PLANE_MODES undamped modes are kept (Galerkin), their substep matrix (2K x 2K)
raised to the tick's s and diagonalised once (numpy.linalg.eig). What is left out (the faster
in-plane modes) is stiff and strongly damped by the dashpots; the tail starts only below an
energy that bounds what they can carry.

The pretensioned mesh stiffens as it rings: a spring whose ends part by a out of plane is
stretched by a^2 / 2L, and its tension k a^2 / 2L stiffens every out-of-plane mode (the
geometric nonlinearity of a string, Kirchhoff-Carrier; Nayfeh & Mook, Nonlinear Oscillations,
1979, ch. 4 and 7), the more so as the mesh's pre-strain T / kL is ~1e-4. So each out-of-plane
mode's frequency is corrected for the amplitudes at the switch, to first order (Lindstedt-
Poincare averaging over independent phases). With s_j = a_j^2 / 2L_j per spring and the
in-plane displacement at its static response to those stretches, the motion's quartic energy
is V4 = 1/2 s.Q.s, Q = diag(kappa) - kappa D S_yz^-1 D^T kappa (kappa = k - T/L per spring, D
the springs' in-plane directions); averaged over the phases, mode m's stiffness rises by

    d lam_m = (M a)_m + 1/2 M_mm a_m + 2 sum_(n != m) P_mn a_n,    a_n = A_n^2 (A_n its amplitude),

M_mn = sum_jl G_jm^2 Q_jl G_ln^2 / 4 L_j L_l, P_mn = sum_jl G_jm G_jn Q_jl G_lm G_ln / 4 L_j L_l, G_jm
the stretch of spring j out of plane in mode m. P is computed for the DETUNED_MODES lowest
modes (which hold a ring's large amplitudes) and left out between the others. The shift in the
scheme's own angle per tick is s h^2 / (2 sqrt(det A) sin theta_sub) d lam (theta_sub the
substep's angle); it decays with the amplitude squared, at |mu|^2 a tick (kernels.modal).
What it leaves out: energy exchange between modes of nearly equal frequency (the mesh's lowest
ones are 0.5 Hz apart) and the in-plane motion's own dynamics: the match's net's lowest in-plane
mode is near twice some of its lowest out-of-plane ones, a 2:1 internal resonance where first-
order averaging does not hold (Nayfeh & Mook, ch. 6). `pingpong bench net-tail` measures what
the tail errs on that net against the full kernel.

These are the sim's own scheme's modes, not the continuous system's (expm of the ODE drifts
further from what NetSim steps). They are computed once per (net, tick, substeps) on one BLAS
thread (LAPACK's bits depend on the thread count) and kept in memory and on disk beside
numba's cache, so every process of a run uses the same bytes.
"""
from __future__ import annotations

import hashlib
import math
import os
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from net_kernel.kernels.modal import potential_energy
from net_kernel.kernels.table import TABLE_Z
from net_kernel.topology import SEMI_IMPLICIT, NetTopology

# In-plane modes kept: the lowest of the undamped in-plane problem. A struck net's in-plane
# motion below the tail's energy lives in a few tens of them (`pingpong bench net-tail`'s tail
# rows measure what is lost).
IN_PLANE_MODES = 64
# The modes need dense matrices of the free knots' degrees of freedom (an eigh of n_free and
# one of 2 n_free): above this many free knots a net has no linear tail and rings in the full
# kernel until it sleeps.
LINEAR_MAX_FREE_KNOTS = 1500
# N: the largest force left on a knot at the rest shape (F(x0) - M g) that the tail accepts.
# topology.hanging_shape settles the net to a few pN, whose static offset (force over the
# stiffness, ~1000 N/m) is far below a nanometre; a larger residual is a net not at rest.
_REST_FORCE_TOL = 1e-9
# m: a rest shape whose knots leave the plane x = 0 by more than this is not flat (a buckled or
# custom net): its planes couple at first order, and it gets no tail.
_FLAT_TOL = 1e-12
# Out-of-plane modes, the lowest, whose pairwise detuning P_mn (see the module's docstring) is
# computed (the pairs cost a quadratic form in the springs each; between others it is left out).
DETUNED_MODES = 100
_CACHE_VERSION = 5


@dataclass(frozen=True, eq=False)
class NetModes:
    """The linearised scheme of one net at one tick and substep count, in closed form.

    Attributes:
        rest_pos: (n_knots, 3) m, the rest shape x0 the scheme is linearised about (topology.rest_pos).
        free: (n_free,) int64, the free knots (inverse mass > 0), in knot order.
        rest_energy: J, the potential energy (springs and gravity) at rest_pos (kernels.modal).
        out_shape: (n_out, n_free) m per unit modal coordinate, mode-major: u_x = out_shape.T @ q.
        out_proj: (n_free, n_out), knot-major: q = out_proj.T @ u_x (the mass-weighted inverse of out_shape.T).
        out_log_r, out_theta: (n_out,) ln |mu| and arg mu of each out-of-plane mode's tick eigenvalue.
        out_e: (n_out,) complex, the eigenvector's velocity component (its position component is 1).
        out_detune: (n_out, n_out) rad per tick per m^2, by the mode whose amplitude acts: mode m's
            angle a tick rises by sum_n out_detune[n, m] |c_n|^2 for coefficients c (the amplitude
            correction, above); rows, so that kernels.modal.modal_detuning adds one after another.
        out_rate: (n_out,) rad, each mode's angle a tick as the substeps turn it (not aliased).
        in_proj: (2 n_free, K), knot-major: a = in_proj.T @ u_yz, u_yz the (y, z) of each free knot in turn.
        in_pos, in_vel: (2, 2K, 2 n_free), the real and imaginary parts of the in-plane shapes P and
            V, mode-major: u_yz(n) = Re(P.T @ (w mu^n)), v_yz likewise; in_pos_abs, in_vel_abs
            (2K, 2 n_free) their absolute values.
        in_inverse: (2K, 2K) complex: w = in_inverse @ (a, a') at the start.
        in_log_r, in_theta: (2K,) ln |mu| and arg mu of the in-plane tick eigenvalues.
        compliance: (3,) m/N, the largest diagonal entry, over the free knots, of the inverse of
            the linearised stiffness along x (out of plane) and along y and z (in plane): a knot
            displaced by u from the rest shape along one axis holds at least u^2 / (2
            compliance) of elastic energy in the linear model, so while the net's energy above
            rest is E no knot is farther than sqrt(2 E compliance) from it along that axis.
        dt, substeps: the tick (s) and its substeps these modes step.
    """

    rest_pos: np.ndarray
    free: np.ndarray
    rest_energy: float
    out_shape: np.ndarray
    out_proj: np.ndarray
    out_log_r: np.ndarray
    out_theta: np.ndarray
    out_e: np.ndarray
    out_detune: np.ndarray
    out_rate: np.ndarray
    in_proj: np.ndarray
    in_pos: np.ndarray
    in_vel: np.ndarray
    in_pos_abs: np.ndarray
    in_vel_abs: np.ndarray
    in_inverse: np.ndarray
    in_log_r: np.ndarray
    in_theta: np.ndarray
    compliance: np.ndarray
    dt: float
    substeps: int

    @property
    def out_freq_hz(self) -> np.ndarray:
        """(n_out,) Hz, the out-of-plane modes' frequencies as the scheme rings them (aliased above the tick's Nyquist)."""
        return self.out_theta / (2 * math.pi * self.dt)


_MODES: dict[str, NetModes | str] = {}  # by _key: the modes, or why a net has none
# linear_tail_refusal's answers by topology (a frozen dataclass, hashed by identity)
_REFUSALS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def linear_tail_refusal(topo: NetTopology) -> str | None:
    """Why `topo`'s net can have no linear tail, or None when it can (found once a topology: a
    NetSim asks at its construction, an environment's every episode)."""
    if topo not in _REFUSALS:
        _REFUSALS[topo] = _tail_refusal(topo)
    return _REFUSALS[topo]


def _tail_refusal(topo: NetTopology) -> str | None:
    spec = topo.spec
    if spec is None:
        return "the net was built from raw arrays (no NetSpec)"
    if spec.solver != SEMI_IMPLICIT:
        return f"solver {spec.solver!r}: the tail is the semi-implicit scheme's"
    n_free = int(np.count_nonzero(topo.knot_inv_mass))
    if n_free > LINEAR_MAX_FREE_KNOTS:
        return f"{n_free} free knots, above LINEAR_MAX_FREE_KNOTS = {LINEAR_MAX_FREE_KNOTS}"
    if float(np.abs(topo.rest_pos[:, 0]).max()) > _FLAT_TOL:
        return "the rest shape is not flat (x = 0): its planes couple at first order"
    free = topo.knot_inv_mass > 0
    if free.any() and float(topo.rest_pos[free, 2].min()) <= TABLE_Z:
        return "a free knot rests on the table (its contact is not linear)"
    residual = _residual(topo, topo.rest_pos, np.flatnonzero(free))
    if residual > _REST_FORCE_TOL:
        return f"the rest shape is not at rest ({residual:.3g} N left on a knot)"
    return None


def net_modes(topo: NetTopology, dt: float, substeps: int) -> NetModes:
    """The modes of `topo`'s net stepped at dt s in `substeps` substeps: from memory, the disk
    cache, or computed (about a second for the match's 85 x 8 net).

    Raises:
        ValueError: the net can have no tail (linear_tail_refusal), or a mode is not an
            underdamped oscillation of the scheme (the closed form needs complex eigenvalues).
    """
    reason = linear_tail_refusal(topo)
    if reason is not None:
        raise ValueError(f"no linear tail for this net: {reason}")
    key = _key(topo, dt, substeps)
    modes = _MODES.get(key)
    if modes is None:
        path = _cache_path(key)
        modes = _load(path, dt, substeps) if path is not None else None
        if modes is None:
            try:
                # One BLAS thread: LAPACK's results depend on how many threads share the work, and
                # every process of a run must hold the same bits.
                with threadpool_limits(limits=1, user_api="blas"):
                    modes = build_modes(topo, dt, substeps)
            except ValueError as exc:
                modes = str(exc)
            if path is not None and not isinstance(modes, str):
                _save(path, modes)
        _MODES[key] = modes
    if isinstance(modes, str):
        raise ValueError(modes)
    return modes


def build_modes(topo: NetTopology, dt: float, substeps: int) -> NetModes:
    """Compute the modes (net_modes without the caches)."""
    free = np.flatnonzero(topo.knot_inv_mass > 0)
    x0 = topo.rest_pos
    stiff, damp = spring_jacobians(topo, x0, free)
    mass = topo.knot_mass[free]
    root = np.sqrt(mass)
    h = dt / substeps
    g = topo.spec.air_damping
    nf = free.size
    # Out of plane: S_xx mass-normalised; C_xx is zero at a flat rest shape.
    lam, phi = np.linalg.eigh(stiff[:, 0, :, 0] / np.outer(root, root))
    tr = 2.0 - h * h * lam - h * g
    det = 1.0 - h * g
    disc = tr * tr - 4.0 * det
    if (disc >= 0).any():
        lowest = float(lam.min())
        raise ValueError("an out-of-plane mode of the scheme is not an oscillation " + (
            f"(stiffness {lowest:.3g} /s^2 < 0: springs in compression buckle the flat rest shape)" if lowest <= 0
            else "(the substep is too long for its frequency)"))
    mu = (tr + 1j * np.sqrt(-disc)) / 2.0
    out_e = (mu - (1.0 - h * h * lam)) / (h * (1.0 - h * g))
    mu_tick = mu ** substeps
    out_shape = (phi / root[:, None]).T
    theta_sub = np.angle(mu)
    # d(angle a tick)/d lam: cos theta_sub = tr / (2 sqrt(det)), differentiated
    dtheta = substeps * h * h / (2.0 * math.sqrt(det) * np.sin(theta_sub))
    # In plane: the lowest K modes of S_yz, the dashpots projected onto them.
    s_yz = stiff[:, 1:, :, 1:].reshape(2 * nf, 2 * nf)
    c_yz = damp[:, 1:, :, 1:].reshape(2 * nf, 2 * nf)
    root2 = np.repeat(root, 2)
    lam_in, psi = np.linalg.eigh(s_yz / np.outer(root2, root2))
    out_detune = dtheta[:, None] * detuning(topo, x0, free, out_shape, lam, lam_in, psi)
    k = min(IN_PLANE_MODES, 2 * nf)
    psi = psi[:, :k]
    lam_in = lam_in[:k]
    # The compliance diagonal, sum over modes of shape^2 / eigenvalue (mass-normalised shapes).
    # An in-plane mode without stiffness (none in a tensioned net) would leave the bound infinite.
    in_plane = ((psi / root2[:, None]) ** 2 / lam_in).sum(axis=1).reshape(nf, 2).max(axis=0) \
        if lam_in.min() > 0 else np.full(2, np.inf)
    compliance = np.array([float(((phi / root[:, None]) ** 2 / lam).sum(axis=1).max()), *in_plane])
    d = psi.T @ (c_yz / np.outer(root2, root2)) @ psi + g * np.eye(k)
    eye = np.eye(k)
    step = np.block([[eye - h * h * np.diag(lam_in), h * (eye - h * d)], [-h * np.diag(lam_in), eye - h * d]])
    vals, vecs = np.linalg.eig(np.linalg.matrix_power(step, substeps))
    in_shape = psi / root2[:, None]
    in_pos, in_vel = (in_shape @ vecs[:k]).T, (in_shape @ vecs[k:]).T  # (2K, 2 n_free) complex
    return NetModes(
        rest_pos=_read_only(x0), free=_read_only(free),
        rest_energy=float(potential_energy(x0, topo.knot_mass, topo.knot_inv_mass, topo.spring_ij, topo.spring_rest,
                                           topo.spring_k, topo.spec.gravity)),
        out_shape=_read_only(out_shape), out_proj=_read_only(phi * root[:, None]),
        out_log_r=_read_only(np.log(np.abs(mu_tick))), out_theta=_read_only(np.angle(mu_tick)),
        out_e=_read_only(out_e), out_detune=_read_only(np.ascontiguousarray(out_detune.T)), out_rate=_read_only(substeps * theta_sub),
        in_proj=_read_only(psi * root2[:, None]),
        in_pos=_read_only(np.stack([in_pos.real, in_pos.imag])), in_vel=_read_only(np.stack([in_vel.real, in_vel.imag])),
        in_pos_abs=_read_only(np.abs(in_pos)),
        in_vel_abs=_read_only(np.abs(in_vel)),
        in_inverse=_read_only(np.linalg.inv(vecs)), in_log_r=_read_only(np.log(np.abs(vals))),
        in_theta=_read_only(np.angle(vals)), compliance=_read_only(compliance), dt=float(dt), substeps=int(substeps))


def detuning(topo: NetTopology, pos: np.ndarray, free: np.ndarray, out_shape: np.ndarray, lam: np.ndarray,
              in_lam: np.ndarray, in_psi: np.ndarray) -> np.ndarray:
    """(n_out, n_out) 1/s^2 per m^2: mode m's stiffness d lam_m = sum_n detuning[m, n] |c_n|^2 for
    modal coefficients c (amplitude A_n = 2 |c_n|), by the averaged quartic energy of the module's
    docstring. out_shape (n_out, n_free): the mass-normalised out-of-plane shapes, lam their
    stiffnesses (the lowest DETUNED_MODES get their pairs); in_lam, in_psi: every in-plane mode
    of the mass-normalised S_yz (its inverse, M^-1/2 psi lam^-1 psi^T M^-1/2, relaxes the plane)."""
    if float(in_lam.min()) <= 0.0:
        raise ValueError(f"the in-plane stiffness is not positive (lowest {float(in_lam.min()):.3g} /s^2)")
    index, i, j, length, unit = _spring_frame(topo, pos, free)
    kappa = topo.spring_k - topo.spring_k * (length - topo.spring_rest) / length
    shape = np.zeros((out_shape.shape[0], topo.n_knots))
    shape[:, free] = out_shape
    stretch = (shape[:, j] - shape[:, i]).T  # G: (springs, modes), a spring's out-of-plane stretch per mode
    # The in-plane force per unit G_j G_l on the free knots' (y, z), mass-normalised: each degree of
    # freedom sums its springs' kappa / 2L along their directions (a spring's ends pull apart).
    dof_spring, dof_weight = [[] for _ in range(2 * free.size)], [[] for _ in range(2 * free.size)]
    root = np.sqrt(topo.knot_mass)
    for spring in range(length.size):
        for knot, sign in ((j[spring], 1.0), (i[spring], -1.0)):
            if index[knot] >= 0:
                for axis in range(2):
                    dof_spring[2 * index[knot] + axis].append(spring)
                    dof_weight[2 * index[knot] + axis].append(
                        sign * unit[spring, 1 + axis] * kappa[spring] / (2.0 * length[spring]) / root[knot])
    width = max(len(row) for row in dof_spring)
    springs = np.array([row + [0] * (width - len(row)) for row in dof_spring])
    weights = np.array([row + [0.0] * (width - len(row)) for row in dof_weight])
    relax = in_psi.T / np.sqrt(in_lam)[:, None]

    def quadratic(y):
        """Per column of y (springs, pairs): y.Q~.y with Q~ = Q / 4 L L, Q of the module's docstring."""
        force = sum(weights[:, k, None] * y[springs[:, k]] for k in range(width))
        relaxed = relax @ force
        return (kappa / (4.0 * length * length)) @ (y * y) - np.einsum("kp,kp->p", relaxed, relaxed)

    sq = stretch * stretch
    force = sum(weights[:, k, None] * sq[springs[:, k]] for k in range(width))
    relaxed = relax @ force
    m = sq.T @ ((kappa / (4.0 * length * length))[:, None] * sq) - relaxed.T @ relaxed
    low = np.argsort(lam)[:DETUNED_MODES]
    pair_m, pair_n = np.triu_indices(low.size, 1)
    p = np.zeros_like(m)
    for chunk in range(0, pair_m.size, 1024):
        a, b = low[pair_m[chunk:chunk + 1024]], low[pair_n[chunk:chunk + 1024]]
        p[a, b] = quadratic(stretch[:, a] * stretch[:, b])
    p += p.T
    # d lam = (M a) + 1/2 diag(M) a + 2 P a with a = A^2 = 4 |c|^2
    return 4.0 * (m + 0.5 * np.diag(np.diag(m)) + 2.0 * p)


def spring_jacobians(topo: NetTopology, pos: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S, C): (n_free, 3, n_free, 3) N/m and N s/m, -dF/dx and -dF/dv of the spring forces on
    the free knots at `pos` with the knots at rest (the kernels' spring model: tension
    k (L - rest) and dashpot c (dL/dt) along the spring)."""
    index, i, j, length, unit = _spring_frame(topo, pos, free)
    outer = unit[:, :, None] * unit[:, None, :]
    tension = topo.spring_k * (length - topo.spring_rest)
    k_e = topo.spring_k[:, None, None] * outer + (tension / length)[:, None, None] * (np.eye(3) - outer)
    c_e = topo.spring_c[:, None, None] * outer
    nf = free.size
    axes = np.arange(3)
    out = []
    for block in (k_e, c_e):
        flats, values = [], []
        for a, b, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
            keep = (index[a] >= 0) & (index[b] >= 0)
            # flat index of (knot a, axis r, knot b, axis c) in an (nf, 3, nf, 3) array
            flats.append((((index[a][keep, None, None] * 3 + axes[None, :, None]) * nf + index[b][keep, None, None]) * 3
                          + axes[None, None, :]).ravel())
            values.append(sign * block[keep].ravel())
        mat = np.bincount(np.concatenate(flats), weights=np.concatenate(values), minlength=9 * nf * nf)
        out.append(mat.reshape(nf, 3, nf, 3))
    return out[0], out[1]


def _spring_frame(topo: NetTopology, pos: np.ndarray, free: np.ndarray):
    """(index, i, j, length, unit): each knot's place among the free ones (-1: fixed), the springs'
    ends, their lengths (m) and unit directions from i to j at `pos`."""
    index = np.full(topo.n_knots, -1)
    index[free] = np.arange(free.size)
    i, j = topo.spring_ij[:, 0].astype(np.int64), topo.spring_ij[:, 1].astype(np.int64)
    d = pos[j] - pos[i]
    length = np.sqrt((d * d).sum(axis=1))
    return index, i, j, length, d / length[:, None]


def static_forces(topo: NetTopology, pos: np.ndarray) -> np.ndarray:
    """(n_knots, 3) N: spring tensions plus gravity on each knot at rest at `pos`."""
    i, j = topo.spring_ij[:, 0].astype(np.int64), topo.spring_ij[:, 1].astype(np.int64)
    d = pos[j] - pos[i]
    length = np.sqrt((d * d).sum(axis=1))
    t = (topo.spring_k * (length - topo.spring_rest) / length)[:, None] * d
    f = np.zeros_like(pos)
    np.add.at(f, i, t)
    np.add.at(f, j, -t)
    f[:, 2] -= topo.knot_mass * topo.spec.gravity
    return f


def _residual(topo: NetTopology, pos: np.ndarray, free: np.ndarray) -> float:
    return float(np.abs(static_forces(topo, pos)[free]).max())


def _read_only(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


def _key(topo: NetTopology, dt: float, substeps: int) -> str:
    """A digest of everything the modes depend on: the net's arrays, the tick, the substeps."""
    digest = hashlib.sha256(f"{_CACHE_VERSION} {dt!r} {substeps} {IN_PLANE_MODES} {DETUNED_MODES} {topo.spec!r}".encode())
    for a in (topo.rest_pos, topo.knot_mass, topo.knot_inv_mass, topo.spring_ij, topo.spring_rest, topo.spring_k,
              topo.spring_c):
        digest.update(np.ascontiguousarray(a).tobytes())
    return digest.hexdigest()[:24]


def _cache_path(key: str) -> Path | None:
    """The modes' file beside numba's cache (net_kernel.jit_cache keys that folder on the sources,
    so a change to the code that computes them starts afresh); None: no cache folder."""
    folder = os.environ.get("NUMBA_CACHE_DIR")
    return Path(folder) / f"net_modes_{key}.npz" if folder else None


def _load(path: Path, dt: float, substeps: int) -> NetModes | None:
    try:
        with np.load(path) as data:
            fields = {name: _read_only(data[name]) for name in data.files if name != "rest_energy"}
            return NetModes(rest_energy=float(data["rest_energy"]), dt=float(dt), substeps=int(substeps),
                            **{k: v for k, v in fields.items() if k not in ("dt", "substeps")})
    except (OSError, KeyError, ValueError, TypeError):
        return None


def _save(path: Path, modes: NetModes) -> None:
    """Write atomically (a temporary file renamed), so a reader never sees half a file."""
    arrays = {name: getattr(modes, name) for name in NetModes.__dataclass_fields__ if name not in ("dt", "substeps")}
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
    try:
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
