"""The stability suite (engine/tools/stability.py): every hard case stays stable or is refused."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.tools.stability import (
    ALL,
    CLOTH_EFFECTS,
    FIXED,
    IMPLICIT_MODE,
    Case,
    SUBSTEPPED,
    NetCase,
    cases,
    run_case,
)
from net_kernel import NetSpec

SUITE = cases()


def _params(chosen):
    """Known failures (reported, not fixed yet) are expected to fail: xfail(strict) flags a fix."""
    return [pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=c.known)) if getattr(c, "known", "") else c
            for c in chosen]


@pytest.mark.parametrize("case", _params([c for c in SUITE if not c.long and c.ci and isinstance(c, Case)]),
                         ids=lambda c: c.name)
def test_case(case):
    out = run_case(case)
    if case.name.startswith("refused"):
        assert out.result.startswith("refused: ")
        assert any(why in out.result for why in ("must be finite", "starts inside the net", "is out of range",
                                                 "substeps a tick")), out.result
        return
    assert out.result == "stable", out.result
    assert out.finite and not out.tunnelled


@pytest.mark.parametrize("case", [c for c in SUITE if isinstance(c, NetCase) and not c.long and c.ci],
                         ids=lambda c: c.name)
def test_stiff_net_case(case):
    out = run_case(case)
    if case.mode == FIXED and case.factor > 1.0:
        # One explicit step per tick above the bound: refused up front, naming the bound.
        assert out.result.startswith("refused: ") and "stability bound h_max" in out.result, out.result
        return
    assert out.result == "stable", out.result
    assert out.finite and out.ticks == case.ticks
    assert out.energy_change < 0.0  # the damped net loses energy (run_case also checks it)
    if case.mode == IMPLICIT_MODE:
        assert out.integrator == "net implicit x1"
        assert out.energy_gain <= 1e-9  # backward Euler never gains (slack: the CG stop at 1e-8 residual)
    else:
        assert out.energy_gain <= 0.10  # symplectic Euler's true energy oscillates; 10 %, as tests/net_kernel
        # The engine derived the substeps from the bound: the substep is at most 0.9 h_max.
        substeps = int(out.integrator.rsplit("x", 1)[1])
        assert substeps == max(1, math.ceil(case.factor / 0.9))


def test_the_stiff_net_matrix_is_complete():
    stiff = [c for c in SUITE if isinstance(c, NetCase)]
    assert sorted({c.factor for c in stiff}) == [0.5, 0.9, 1.1, 10.0]
    default = NetSpec()
    for field in ("spring_k", "spring_c", "cord_k"):  # k_s, k_d and the top cord's k_s
        assert sorted({c.net[field] / getattr(default, field) for c in stiff}) == pytest.approx([1.0, 10.0, 100.0])
    assert sorted({c.mode for c in stiff}) == sorted([FIXED, IMPLICIT_MODE, SUBSTEPPED])
    assert len(stiff) == 4 * 3 * 3


def test_a_ball_through_a_net_too_coarse_to_hold_it_is_caught_tunnelling():
    # 24 x 4 knots: 80 mm cells, wider than the 41 mm that keeps a ball out (kernels.collide_ball), so
    # a ball aimed at a cell's middle passes between the knots: the suite must say so.
    coarse = {"kind": "cloth", "cols": 24, "rows": 4, "knot_mass": 0.05 / 96}
    out = run_case(Case("through a coarse net", {"effects": CLOTH_EFFECTS, "net": coarse, "bats": {"b": {"pos": [3.0, 0.0, 0.3]}},
                                                 "ball": {"pos": [-0.3, 0.0, 0.076], "vel": [10.0, 0.0, 0.0]}}, 100))
    assert out.tunnelled and "tunnelled" in out.result


def test_the_cloth_net_returns_to_its_rest_shape_after_a_smash():
    # The hanging net has one rest shape (net_kernel.topology): after a 34 m/s smash it settles
    # back onto it; 0.1 mm is the bound, far below the 3 mm of a tied net's buckled shapes.
    case = next(c for c in SUITE if c.name.startswith("34 m/s smash") and "64x8" in c.name)
    out = run_case(case)
    assert out.result == "stable", out.result
    assert out.rest_offset_m <= 1e-4, out.rest_offset_m


@pytest.mark.long
@pytest.mark.parametrize("case", _params([c for c in SUITE if c.long]), ids=lambda c: c.name)
def test_long_case(case):  # the cloth one: ~45 min on a loaded 2-core machine
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
