"""The impact model: spin kick and check, rolling exit, energy never gained (Nakashima et al. 2010)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.physics import equipment
from engine.physics.contact import impact

R = equipment.BALL_RADIUS
M = equipment.BALL_MASS
I = equipment.BALL_INERTIA_FACTOR * M * R * R
UP = np.array([0.0, 0.0, 1.0])
STILL = np.zeros(3)


def bounce(vel, spin, e=0.9, mu=0.25, normal=UP, body_vel=STILL):
    v_out, w_out = np.zeros(3), np.zeros(3)
    speed = impact(np.array(vel, float), np.array(spin, float), normal, body_vel, R, M, I, e, mu, v_out, w_out)
    return v_out, w_out, speed


def test_topspin_kicks_forward_and_backspin_checks():
    # At 3 m/s and 45 degrees a spinless ball stops slipping inside the impact (leaves rolling
    # at 3 - 2/5 * 3 = 1.8 m/s); heavy spin makes it slide through, at the Coulomb limit of
    # mu (1 + e) |v_n| = 1.425 m/s either way.
    incoming = [3.0, 0.0, -3.0]
    plain, _, _ = bounce(incoming, [0.0, 0.0, 0.0])
    top, _, _ = bounce(incoming, [0.0, 600.0, 0.0])  # omega_y > 0 is topspin for a ball going +x
    back, _, _ = bounce(incoming, [0.0, -600.0, 0.0])
    assert plain[0] == pytest.approx(3.0 - 0.4 * 3.0, rel=1e-14)  # the formulas, to round-off
    assert top[0] == pytest.approx(3.0 + 0.25 * 1.9 * 3.0, rel=1e-14)  # kicked forward
    assert back[0] == pytest.approx(3.0 - 0.25 * 1.9 * 3.0, rel=1e-14)  # checked


def test_no_spin_ball_leaves_with_topspin():
    _, spin, _ = bounce([5.0, 0.0, -3.0], [0.0, 0.0, 0.0])
    assert spin[1] > 0.0


def test_normal_restitution():
    v, w, speed = bounce([0.0, 0.0, -2.0], [0.0, 0.0, 0.0], e=0.8)
    np.testing.assert_allclose(v, [0.0, 0.0, 1.6], atol=1e-15)  # v_n' = -e v_n, exactly
    assert speed == 2.0


def test_grazing_ball_with_high_friction_leaves_rolling():
    # Slip stops inside the impact when mu (1 + e) |v_n| > 2/5 |u_t| (Nakashima's rolling case).
    v, w, _ = bounce([3.0, 1.0, -1.0], [0.0, 0.0, 0.0], mu=2.0)
    slip = v + np.cross(w, -R * UP)
    np.testing.assert_allclose(slip[:2], 0.0, atol=1e-12)  # rolling: contact point at rest


def test_sliding_case_takes_the_coulomb_limit():
    e, mu = 0.9, 0.1
    v, _, _ = bounce([8.0, 0.0, -1.0], [0.0, 0.0, 0.0], e=e, mu=mu)
    # Sliding through the impact: the tangential impulse is mu (1 + e) m |v_n|, exactly.
    assert v[0] == pytest.approx(8.0 - mu * (1 + e) * 1.0, rel=1e-14)


def kinetic_energy(vel, spin, body_vel):
    rel = vel - body_vel
    return 0.5 * M * rel @ rel + 0.5 * I * spin @ spin


vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).map(np.array)


@settings(deadline=None, max_examples=300)
@given(
    vel=vectors.map(lambda v: 40.0 * v),
    spin=vectors.map(lambda w: 1000.0 * w),
    normal=vectors.filter(lambda n: np.linalg.norm(n) > 0.1).map(lambda n: n / np.linalg.norm(n)),
    body_vel=vectors.map(lambda v: 20.0 * v),
    e=st.floats(0.0, 1.0),
    mu=st.floats(0.0, 2.0),
)
def test_energy_never_increases_in_a_contact(vel, spin, normal, body_vel, e, mu):
    v, w, _ = bounce(vel, spin, e, mu, normal, body_vel)
    before = kinetic_energy(vel, spin, body_vel)
    after = kinetic_energy(v, w, body_vel)
    # In the frame of the body hit, restitution <= 1 and friction up to stick only dissipate;
    # 1e-12 relative is round-off.
    assert after <= before * (1 + 1e-12) + 1e-15
