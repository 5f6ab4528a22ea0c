"""bench/net_friction.py: its friction element against the analytic Coulomb oscillator, and a smoke run."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

from bench.net_friction import friction_pass
from tests.waits import DEADLINE_S

ROOT = Path(__file__).resolve().parents[2]


def _coulomb_peaks(x0: float, stiffness: float, mass: float, force: float, presliding: float, h: float,
                   duration: float) -> np.ndarray:
    """Successive peaks |x| of a mass on a spring whose other end is fixed, with the study's stretch
    friction on a second spring along the same line (the friction element alone: its stiffness is 0)."""
    p = np.zeros((1, 2, 3))
    p[0, 1, 0] = 1.0 + x0  # the free knot, 1 m from the fixed one, displaced by x0
    v = np.zeros((2, 3))
    inv_m = np.array([0.0, 1.0 / mass])
    ij = np.array([[0, 1]])
    spring_len = np.array([1.0 + x0])
    spring_z = np.zeros(1)
    hinge = np.zeros((2, 1, 2, 3))
    scratch = np.zeros((1, 2, 3))
    peaks, last, rising = [], x0, False
    for _ in range(int(duration / h)):
        v[1, 0] += h * (-stiffness * (p[0, 1, 0] - 1.0) / mass)
        friction_pass(p, v, inv_m, hinge, hinge.copy(), ij, spring_len, spring_z, 0.0, 1.0, force, presliding, 0.0,
                      h, scratch)
        p[0, 1, 0] += h * v[1, 0]
        x = abs(p[0, 1, 0] - 1.0)
        if rising and x < last:
            peaks.append(last)
        rising = x > last
        last = x
    return np.array(peaks)


def test_the_stretch_friction_element_decays_a_spring_mass_as_coulomb_friction_does():
    stiffness, mass, force = 10.0, 1e-3, 1e-3  # N/m, kg, N: 100 rad/s, F / k = 0.1 mm
    x0 = 1.05e-3
    peaks = _coulomb_peaks(x0, stiffness, mass, force, presliding=1e-8, h=1e-6, duration=0.2)
    # Coulomb damping (Den Hartog, "Mechanical Vibrations", 4th ed., 1956, 8.2): each half cycle
    # loses 2 F / k of amplitude, and the mass sticks once |x| < F / k (here after 5 half cycles).
    expected = x0 - 2.0 * force / stiffness * np.arange(1, 6)
    assert peaks.size >= 4
    # 1 % of a half cycle's loss: the presliding length and the split step's O(h) drift
    assert np.allclose(peaks[:4], expected[:4], atol=0.01 * 2.0 * force / stiffness), (peaks[:4], expected[:4])
    assert peaks[-1] < force / stiffness + 1e-6  # stuck within F / k of the rest point


def test_the_bending_friction_element_decays_a_hinged_knot_as_coulomb_friction_does():
    # Three knots in a row, the two ends fixed; the middle one on a spring of its own along x: its
    # hinge's friction force z acts on it twice (+2 z; -z on each end), a Coulomb force of 2 F_s.
    stiffness, mass, force, x0, h = 10.0, 1e-3, 5e-4, 1.05e-3, 1e-6
    p = np.zeros((1, 3, 3))
    p[0, :, 1] = (-0.02, 0.0, 0.02)
    p[0, 1, 0] = x0
    v = np.zeros((3, 3))
    inv_m = np.array([0.0, 1.0 / mass, 0.0])
    hinge_b = np.zeros((2, 1, 3, 3))
    hinge_b[0, 0, 1] = p[0, 0] - 2.0 * p[0, 1] + p[0, 2]
    hinge_z = np.zeros((2, 1, 3, 3))
    no_springs = np.zeros((0, 2), dtype=np.int64)
    scratch = np.zeros((1, 3, 3))
    peaks, last, rising = [], x0, False
    for _ in range(int(0.2 / h)):
        v[1, 0] += h * (-stiffness * p[0, 1, 0] / mass)
        friction_pass(p, v, inv_m, hinge_b, hinge_z, no_springs, np.zeros(0), np.zeros(0), force, 1e-8, 0.0, 1.0,
                      0.0, h, scratch)
        p[0, 1, 0] += h * v[1, 0]
        x = abs(p[0, 1, 0])
        if rising and x < last:
            peaks.append(last)
        rising = x > last
        last = x
    # Coulomb damping (Den Hartog, "Mechanical Vibrations", 4th ed., 1956, 8.2) with a friction force
    # of 2 F_s: 4 F_s / k of amplitude lost each half cycle, stuck within 2 F_s / k.
    loss = 4.0 * force / stiffness
    expected = x0 - loss * np.arange(1, 5)
    assert len(peaks) >= 4
    assert np.allclose(peaks[:4], expected, atol=0.01 * loss), (peaks[:4], expected)  # 1 % of a half cycle's loss
    assert peaks[-1] < 2.0 * force / stiffness + 1e-6


def test_net_friction_quick_json():
    done = subprocess.run([sys.executable, "-m", "bench.net_friction", "--quick", "--json"], capture_output=True,
                          text=True, timeout=DEADLINE_S, stdin=subprocess.DEVNULL, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert len(result["cases"]) == 2
    for case in result["cases"].values():
        speeds = case["fastest_knot_m_s"]
        assert set(speeds) == {"0.25"} and all(math.isfinite(s) and s > 0.0 for s in speeds.values())
        assert case["ball_back_m_s"] > 0.0  # the net throws the ball back
