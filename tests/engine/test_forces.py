"""Aerodynamic forces: directions and magnitudes against the formulas they cite."""
import math

import numpy as np
import pytest

from engine.physics import equipment
from engine.physics.forces import ball_accel, drag_factor, magnus_factor

K_DRAG = drag_factor(equipment.DRAG_COEFFICIENT)
K_MAGNUS = magnus_factor(equipment.MAGNUS_COEFFICIENT)


def accel(vel, spin, gravity=None, drag=None, magnus=None):
    out = np.zeros(3)
    ball_accel(np.array(vel, float), np.array(spin, float), gravity, drag, magnus, out)
    return out


def test_drag_magnitude_is_half_rho_cd_a_v_squared():
    v = 20.0
    expected = 0.5 * equipment.AIR_DENSITY * equipment.DRAG_COEFFICIENT * math.pi * equipment.BALL_RADIUS**2 * v**2
    a = accel([v, 0.0, 0.0], [0.0, 0.0, 0.0], drag=K_DRAG)
    assert -a[0] * equipment.BALL_MASS == pytest.approx(expected, rel=1e-12)  # the formula, to round-off
    assert a[1] == a[2] == 0.0


@pytest.mark.parametrize(
    "spin, direction",
    [
        ([0.0, 100.0, 0.0], [0.0, 0.0, -1.0]),  # topspin on a ball going +x dips
        ([0.0, -100.0, 0.0], [0.0, 0.0, 1.0]),  # backspin floats
        ([0.0, 0.0, 100.0], [0.0, 1.0, 0.0]),  # sidespin about +z curves towards +y
    ],
)
def test_magnus_direction(spin, direction):
    a = accel([10.0, 0.0, 0.0], spin, magnus=K_MAGNUS)
    np.testing.assert_allclose(a / np.linalg.norm(a), direction, atol=1e-15)  # exact directions


def test_magnus_vanishes_for_spin_along_velocity():
    a = accel([10.0, 0.0, 0.0], [50.0, 0.0, 0.0], magnus=K_MAGNUS)
    np.testing.assert_array_equal(a, 0.0)


def test_absent_effects_are_compiled_out():
    # An absent effect is a None argument: numba prunes its branch, so that specialisation has
    # no code for it at all. A fresh, uncached probe lets us read the generated LLVM IR.
    from numba import njit

    @njit
    def probe(vel, spin, gravity, drag, magnus, out):
        ball_accel(vel, spin, gravity, drag, magnus, out)

    v, w, out = np.ones(3), np.ones(3), np.zeros(3)
    probe(v, w, 9.81, None, None, out)
    probe(v, w, 9.81, K_DRAG, None, out)
    ir = {str(sig[3]): probe.inspect_llvm(sig) for sig in probe.signatures}
    assert "llvm.sqrt" in ir["float64"]  # drag needs |v|
    assert "llvm.sqrt" not in ir["none"]  # without drag there is no code computing it
