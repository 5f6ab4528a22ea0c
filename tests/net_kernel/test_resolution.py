"""resolution_spec: coarser and finer grids of the same physical net (statics, sway frequency, continuum)."""
import math
from dataclasses import replace

import numpy as np
import pytest

from net_kernel import NetSim, NetSpec, build_topology, grid_spec
from net_kernel.topology import net_continuum, resolution_spec

DT = 1e-3
REFERENCE = (184, 16)  # the default net
SIZES = [(70, 7), (92, 8), (128, 11)]
SETTLE_DRAG = 3000.0  # 1/s: critically damps the net's slowest in-plane mode (~300 Hz) for the static solve
SETTLE_TICKS = 150


def test_default_grid_is_the_default_net():
    spec = resolution_spec(*REFERENCE)
    base = NetSpec()
    for name in ("knot_mass", "spring_k", "spring_c", "mesh_tension", "cord_k", "cord_tension", "air_damping"):
        assert getattr(spec, name) == pytest.approx(getattr(base, name), rel=1e-12), name  # identity up to rounding


@pytest.mark.parametrize("cols, rows", [(46, 4), (49, 5), (70, 7), (92, 8), (128, 11), (368, 32), (1000, 80)])
def test_every_continuum_constant_the_scaling_keeps_is_kept(cols, rows):
    ref = net_continuum(NetSpec())
    got = net_continuum(resolution_spec(cols, rows))
    for name in ("areal_density", "mesh_prestress", "equibiaxial", "mesh_viscosity", "cord_tension", "cord_stiffness",
                 "wave_speed"):
        assert got[name] == pytest.approx(ref[name], rel=1e-12), name  # exact by construction, rounding only


def test_grid_spec_is_another_cloth_and_resolution_spec_is_not():
    # grid_spec keeps every spring's pretension: on 46 x 4 knots the mesh's prestress is 5x lower.
    ref = net_continuum(NetSpec())
    naive = net_continuum(grid_spec(46, 4))
    assert naive["mesh_prestress"] < 0.25 * ref["mesh_prestress"]
    assert net_continuum(resolution_spec(46, 4))["mesh_prestress"] == pytest.approx(ref["mesh_prestress"], rel=1e-12)


def test_bad_size_names_the_field():
    with pytest.raises(ValueError, match="NetSpec.rows ="):
        resolution_spec(92, 1)
    with pytest.raises(ValueError, match="NetSpec.cols ="):
        resolution_spec(9.5, 8)
    with pytest.raises(ValueError, match="closer to square cells"):
        resolution_spec(1000, 3)  # 1.8 x 76 mm cells: the mesh's pretension would exceed k a


def _settled(spec):
    """(topology, knot_pos): the net at rest under gravity, stepped by the kernel with strong air damping."""
    topo = build_topology(replace(spec, air_damping=SETTLE_DRAG))
    sim = NetSim(topo, DT)
    for _ in range(SETTLE_TICKS):
        sim.step()
    assert np.max(np.abs(sim.knot_vel)) < 1e-9  # m/s: at rest (the static solve converged)
    return build_topology(spec), sim.knot_pos.copy()


def _sag(spec):
    """(cord, mesh) m: downward sag at mid-span of the top cord and of the mesh at mid-height, under gravity."""
    topo, pos = _settled(spec)
    grid = (pos[:, 2] - topo.knot_pos[:, 2]).reshape(spec.rows, spec.cols)
    y = topo.knot_pos[: spec.cols, 1]
    mid_span = np.array([np.interp(0.0, y, row) for row in grid])  # interpolated at y = 0 on every row
    z = topo.knot_pos[:: spec.cols, 2]
    return -mid_span[-1], -np.interp(spec.height / 2, z, mid_span)


def test_static_sag_agrees_across_resolutions():
    cord_ref, mesh_ref = _sag(resolution_spec(*REFERENCE))
    # m: above 1 um (it does sag), below a free cable's W L / (8 T) = 5.6 mm carrying the whole net (the
    # mesh stands partly on the table's row: a few um with linear springs).
    assert 1e-6 < cord_ref < 5.6e-3
    b_ref = 1.0 / (REFERENCE[1] - 1)
    c22_ref = net_continuum(resolution_spec(*REFERENCE))["c22"]
    for cols, rows in SIZES:
        spec = resolution_spec(cols, rows)
        cord, mesh = _sag(spec)
        # Tolerance: two discretisation errors, summed. (1) The edge rows lump half a cell of mesh
        # each (one knot mass for all knots): the sag's relative error is first order in the row
        # spacing, coefficient 1.0 for the cord and 0.63 for the mesh (measured on square grids
        # 37 x 4 ... 373 x 32, where nothing else changes): |b - b_ref| / height. (2) One
        # spring_k for every class keeps the equibiaxial modulus, not c22 (resolution_spec),
        # and a sag under the net's own weight goes as 1 / c22. Plus 2 % for the settle.
        allowed = abs(1.0 / (rows - 1) - b_ref) + abs(c22_ref / net_continuum(spec)["c22"] - 1.0) + 0.02
        assert abs(cord / cord_ref - 1.0) <= allowed, (cols, rows, cord, cord_ref, allowed)
        assert abs(mesh / mesh_ref - 1.0) <= allowed, (cols, rows, mesh, mesh_ref, allowed)


def _sway_shape(spec, topo, amplitude):
    """(n_knots,) m: the mesh's fundamental sway, x = amplitude sin(pi (y/width + 1/2)) sin(pi z / height).

    Out of the plane, in the linear limit, each mesh row is a string pinned at the posts with
    the horizontal pretension; the vertical and shear springs carry no tension (gravity off) and
    pass no transverse force, so every profile across the rows sways at the strings' frequency.
    The sin(pi z / height) profile keeps the cord's row (~30 Hz on its own) and the table's at
    rest without a jump: a jump between rows would stretch the vertical springs, a cubic
    stiffness that at 1 mm outweighs the strings' 10^4-fold (the net is 12x wider than high).
    """
    return amplitude * np.sin(math.pi * (topo.knot_pos[:, 1] / spec.width + 0.5)) * np.sin(
        math.pi * topo.knot_pos[:, 2] / spec.height) * (topo.knot_inv_mass > 0)


def _rayleigh(topo, shape):
    """Hz: the Rayleigh quotient's frequency of `shape` on the built net, linearised.

    Out of the net's plane a spring of tension T and length L acts only through its geometric
    stiffness T / L; the built shape is the equilibrium when gravity is off.
    """
    i, j = topo.spring_ij[:, 0].astype(np.int64), topo.spring_ij[:, 1].astype(np.int64)
    length = np.linalg.norm(topo.knot_pos[j] - topo.knot_pos[i], axis=1)
    tension = topo.spring_k * (length - topo.spring_rest)
    stiffness = np.sum(tension / length * (shape[j] - shape[i]) ** 2)
    return math.sqrt(stiffness / np.sum(topo.knot_mass * shape**2)) / (2 * math.pi)


def _ring_down(spec, amplitude=1e-5, ticks=420):
    """(kernel Hz, Rayleigh Hz): the sway's frequency from a ring-down stepped by the kernel, and its linear estimate.

    Gravity off: under gravity the linear springs' vertical threads carry the mesh's weight in
    compression (about -1 mN each), a negative out-of-plane stiffness that the curvature across
    the 15 cm height makes worth tens of % of the sway's and lets the linear model buckle; that
    belongs to the spring model, not to the resolution this test is about. 10 um: linear. The
    kernel's own ring: no linear tail.
    """
    spec = replace(spec, gravity=0.0, tail_energy=0.0)
    topo = build_topology(spec)
    shape = _sway_shape(spec, topo, amplitude)
    sim = NetSim(topo, DT)
    sim.knot_pos[:, 0] += shape
    weight = topo.knot_mass * shape
    q = np.empty(ticks)
    for t in range(ticks):
        sim.quiet_ticks = 0  # kept awake: a 10 um sway is slower than NetSim's SLEEP_SPEED
        sim.step()
        q[t] = weight @ sim.knot_pos[:, 0] / (weight @ shape)  # the sway's amplitude (mass-weighted projection)
    assert not sim.sleeping
    time = DT * np.arange(1, ticks + 1)
    k = np.flatnonzero(np.sign(q[:-1]) * np.sign(q[1:]) < 0)
    crossing = time[k] - q[k] * DT / (q[k + 1] - q[k])
    assert crossing.size >= 3
    # Air damping g = 5/s shifts a damped mode's frequency by sqrt(1 - (g / 2 w)^2) (0.4 % at 4.7 Hz): undone.
    w_d = math.pi / np.mean(np.diff(crossing))
    return math.sqrt(w_d**2 + (spec.air_damping / 2) ** 2) / (2 * math.pi), _rayleigh(topo, shape)


def test_lowest_transverse_frequency_agrees_across_resolutions():
    f_ref, f_ref_lin = _ring_down(resolution_spec(*REFERENCE))
    # The mesh's rows are strings of tension N_yy b and mass rho a b per knot: f = sqrt(N_yy / rho) / (2 width).
    c = net_continuum(NetSpec())["wave_speed"]
    # 0.2 %: a discrete string's fundamental is low by (pi / (2 (cols - 1)))^2 / 6 (0.01 % at 184 columns); the
    # zero crossings are interpolated between 1 ms samples of a 4.7 Hz sine (< 0.05 %).
    assert f_ref == pytest.approx(c / (2 * NetSpec().width), rel=2e-3)
    assert f_ref == pytest.approx(f_ref_lin, rel=2e-3)  # the kernel against its linearisation, same budget
    for cols, rows in [(46, 4), *SIZES]:
        f, f_lin = _ring_down(resolution_spec(cols, rows))
        # 0.2 %, as above (the discrete string's shift is 0.02 % at 46 columns).
        assert f == pytest.approx(f_ref, rel=2e-3), (cols, rows)
        assert f_lin == pytest.approx(f_ref_lin, rel=2e-3), (cols, rows)


def test_grid_spec_sways_at_another_frequency():
    # The check above can fail: grid_spec's 70 x 7 net keeps the default's 0.5 N per horizontal
    # spring on rows 2.5x farther apart, so its rows' wave speed (and sway) drops by ~sqrt(2.5).
    f_ref, _ = _ring_down(resolution_spec(*REFERENCE))
    f_naive, _ = _ring_down(grid_spec(70, 7))
    assert f_naive < 0.8 * f_ref  # measured 3.11 Hz against 4.69
