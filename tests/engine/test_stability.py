"""The stability suite (engine/stability.py): every hard case stays stable or is refused."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.stability import ALL, Case, cases, run_case

SUITE = cases()


@pytest.mark.parametrize("case", [c for c in SUITE if not c.long], ids=lambda c: c.name)
def test_case(case):
    out = run_case(case)
    if case.name.startswith("refused"):
        assert out.result.startswith("refused: ")
        assert "must be finite" in out.result or "starts inside the net" in out.result, out.result
        return
    assert out.result == "stable", out.result
    assert out.finite and not out.tunnelled


@pytest.mark.long
@pytest.mark.parametrize("case", [c for c in SUITE if c.long], ids=lambda c: c.name)
def test_long_case(case):
    out = run_case(case)
    assert out.result == "stable", out.result


# ITTF-range shots dropped on the table: speeds to 30 m/s, spins to 150 rev/s.
speeds = st.floats(-30.0, 30.0)
spins = st.floats(-2 * math.pi * 150, 2 * math.pi * 150)


@settings(deadline=None, max_examples=25)
@given(x=st.floats(-1.2, 1.2), y=st.floats(-0.7, 0.7), z=st.floats(0.03, 1.0),
       vx=speeds, vy=st.floats(-5.0, 5.0), vz=st.floats(-15.0, 5.0), wx=spins, wy=spins, wz=spins)
def test_random_shots_stay_finite_and_outside_every_body(x, y, z, vx, vy, vz, wx, wy, wz):
    case = Case("random", {"effects": ALL + ["table", "net", "floor"],
                           "ball": {"pos": [x, y, z], "vel": [vx, vy, vz], "spin": [wx, wy, wz]}}, 400)
    out = run_case(case)
    if out.result.startswith("refused: ") and "starts inside" in out.result:
        return  # a start overlapping a body is refused at the boundary, which is the right answer
    assert out.finite and not out.tunnelled, out.result
    assert out.max_penetration_m <= 1e-6, out.result  # contacts resolve to CONTACT_TOL = 1 um
    assert np.isfinite(out.final).all()
