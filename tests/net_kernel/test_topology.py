"""NetSpec validation, the built net's geometry and CSR, and degenerate springs refused at build time."""
import numpy as np
import pytest

from net_kernel import NetSpec, build_topology, make_topology


def test_default_net_geometry():
    topo = build_topology(NetSpec())
    # ITTF 2.2.2-2.2.3: 1.83 m wide, top 15.25 cm above the surface; exact by construction.
    assert topo.knot_pos[:, 1].min() == pytest.approx(-0.915, abs=1e-12)
    assert topo.knot_pos[:, 1].max() == pytest.approx(0.915, abs=1e-12)
    assert topo.knot_pos[:, 2].max() == pytest.approx(0.1525, abs=1e-12)
    assert np.all(topo.knot_pos[:, 0] == 0.0)
    assert topo.n_knots == 184 * 16
    # ITTF 2.2.4: the bottom "as close as possible to the playing surface": the hem's cord hem_gap above it.
    assert topo.knot_pos[:, 2].min() == pytest.approx(NetSpec().hem_gap, abs=1e-12)
    fixed = topo.knot_inv_mass == 0
    # Fixed: both post columns (the net hangs on its cords; nothing ties it to the table): 2 * 16 knots.
    assert fixed.sum() == 2 * 16
    assert np.all(fixed[::184]) and np.all(fixed[183::184])


def test_a_tied_net_is_fixed_along_the_table():
    topo = build_topology(NetSpec(fix_table=True))
    fixed = topo.knot_inv_mass == 0
    # Both post columns and the table row at z = 0: 2 * 16 + 184 - 2 knots.
    assert fixed.sum() == 2 * 16 + 184 - 2
    assert np.all(fixed[:184]) and np.all(topo.knot_pos[:184, 2] == 0.0)


def test_bottom_cord_carries_its_tension():
    spec = NetSpec()
    topo = build_topology(spec)
    i, j = topo.spring_ij[:, 0], topo.spring_ij[:, 1]
    cord = (topo.knot_pos[i, 2] == spec.hem_gap) & (topo.knot_pos[j, 2] == spec.hem_gap)
    length = np.linalg.norm(topo.knot_pos[j[cord]] - topo.knot_pos[i[cord]], axis=1)
    tension = topo.spring_k[cord] * (length - topo.spring_rest[cord])
    np.testing.assert_allclose(tension, spec.hem_tension, rtol=1e-9)  # T = k (L - L_rest), rounding only


def test_csr_lists_every_spring_twice_in_spring_order():
    topo = build_topology(NetSpec(cols=7, rows=5))
    for i in range(topo.n_knots):
        slots = slice(topo.adj_start[i], topo.adj_start[i + 1])
        springs = topo.adj_spring[slots]
        assert np.all(np.diff(springs) > 0)  # fixed gather order: increasing spring index
        for s, j in zip(springs, topo.adj_knot[slots]):
            assert {i, j} == set(topo.spring_ij[s])
    assert topo.adj_start[-1] == 2 * topo.n_springs


def test_top_cord_carries_its_tension():
    spec = NetSpec()
    topo = build_topology(spec)
    top = topo.knot_pos[topo.spring_ij[:, 0], 2] == spec.height
    level = topo.knot_pos[topo.spring_ij[:, 1], 2] == spec.height
    cord = top & level
    length = np.linalg.norm(topo.knot_pos[topo.spring_ij[cord, 1]] - topo.knot_pos[topo.spring_ij[cord, 0]], axis=1)
    tension = topo.spring_k[cord] * (length - topo.spring_rest[cord])
    np.testing.assert_allclose(tension, spec.cord_tension, rtol=1e-9)  # T = k (L - L_rest), rounding only


@pytest.mark.parametrize("field, value", [
    ("width", 0.0), ("height", -0.1), ("cols", 1), ("rows", 5000), ("cols", 3.5), ("knot_mass", 0.0),
    ("spring_k", float("nan")), ("spring_c", -1.0), ("cord_tension", 1e6), ("solver", "rk4"), ("gravity", -9.81),
])
def test_spec_out_of_range_names_the_field(field, value):
    with pytest.raises(ValueError, match=f"NetSpec.{field} ="):
        build_topology(NetSpec(**{field: value}))


def _two_knots(**override):
    args = dict(knot_pos=[[0.0, 0.0, 0.0], [0.0, 0.01, 0.0]], knot_mass=[1e-3, 1e-3], knot_fixed=[True, False],
                spring_ij=[[0, 1]], spring_rest=[0.01], spring_k=[100.0], spring_c=[0.0])
    args.update(override)
    return make_topology(**args)


def test_well_formed_spring_builds():
    topo = _two_knots()
    # One mass on a spring to a fixed point: w^2 = k / m exactly, so h_max = 2 / w (Lanczos is exact
    # on one free knot; 1e-12 is float rounding).
    assert topo.n_springs == 1 and topo.h_max == pytest.approx(2.0 * np.sqrt(1e-3 / 100.0), rel=1e-12)


@pytest.mark.parametrize("override, message", [
    (dict(spring_ij=[[1, 1]]), "joins knot 1 to itself"),
    (dict(knot_pos=[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), "0 m apart"),
    (dict(spring_rest=[0.0]), "rest length 0 m"),
    (dict(spring_ij=[[0, 2]]), "indices must be in"),
    (dict(spring_ij=[[0, 1], [1, 0]], spring_rest=[0.01, 0.01], spring_k=[1.0, 1.0], spring_c=[0.0, 0.0]),
     "same pair"),
    (dict(spring_k=[-1.0]), "spring_k = -1.0"),
])
def test_degenerate_spring_refused_with_clear_error(override, message):
    with pytest.raises(ValueError, match=message):
        _two_knots(**override)


def test_knots_too_dense_refused():
    # 1.83 m over 4000 columns is fine; 1e-7 m wide is not: spacing below the 1 um minimum.
    with pytest.raises(ValueError, match="NetSpec.cols"):
        build_topology(NetSpec(width=1e-7, cols=200))
