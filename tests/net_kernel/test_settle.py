"""A net hanging on its two cords settles to rest with the cables' sag, W L / (8 (T_top + T_bottom))."""
import pytest

from net_kernel import NetSim, build_topology, grid_spec

G = 9.81


def _settled_sag(cord_tension):
    # Hung from the posts only, the mesh slack and soft, both cords at the same tension: the soft
    # mesh ties them into one cable of twice the tension that carries the net's weight. The hem
    # hangs 2 cm up, clear of the table under its 5.4 mm sag at 10 N.
    spec = grid_spec(61, 6, mesh_tension=0.0, spring_k=5.0, cord_k=20000.0, cord_tension=cord_tension,
                     hem_tension=cord_tension, hem_gap=0.02, air_damping=20.0, gravity=G)
    topo = build_topology(spec)
    sim = NetSim(topo, dt=1e-3)
    for _ in range(3000):
        sim.step()
        if sim.sleeping:
            break
    top_middle = (spec.rows - 1) * spec.cols + spec.cols // 2
    free_weight = G * topo.knot_mass[topo.knot_inv_mass > 0].sum()
    return sim, topo.knot_pos[top_middle, 2] - sim.knot_pos[top_middle, 2], free_weight * spec.width / (8 * 2 * cord_tension)


@pytest.mark.parametrize("tension", [10.0, 20.0])
def test_hanging_net_settles_with_the_cable_sag(tension):
    sim, sag, cable = _settled_sag(tension)
    assert sim.sleeping  # at rest: every knot below SLEEP_SPEED for SLEEP_TICKS ticks
    # Parabolic cable under a uniform load (Irvine, Cable Structures, 1981, eq. 2.9):
    # d = w L^2 / (8 T). The mesh carries a little weight to the posts itself: 10 %.
    assert sag == pytest.approx(cable, rel=0.10)


def test_sag_halves_when_the_tension_doubles():
    _, sag_low, _ = _settled_sag(10.0)
    _, sag_high, _ = _settled_sag(20.0)
    assert sag_low / sag_high == pytest.approx(2.0, rel=0.05)  # d ~ 1/T; 5 %: the mesh's own share
