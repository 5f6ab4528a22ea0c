"""The drop test: a ball dropped on the table, against the analytic apexes and the ITTF rule."""
import numpy as np
import pytest

from engine.physics import equipment
from engine.tools.run import run
from tests.helpers.scenes import make_scene

H0 = 0.30  # m, drop height of the ball's bottom (ITTF rule 2.1.3)


@pytest.mark.parametrize("integrator", ["verlet", "rk4", "dopri5"])
def test_apexes_follow_e_squared_without_drag(integrator):
    e = equipment.TABLE_RESTITUTION
    scene = make_scene(["gravity", "table"], {"pos": [0.3, 0.1, H0 + equipment.BALL_RADIUS]},
                       integrator=integrator, duration=2.5)
    heights = run(scene).bounce_heights_m
    expected = [H0 * e ** (2 * n) for n in range(1, len(heights) + 1)]
    assert len(heights) >= 5
    # Impacts are applied within CONTACT_TOL = 1 um of the surface; that shifts each apex by
    # about a micrometre per bounce, so 10 um bounds the first five.
    np.testing.assert_allclose(heights[:5], expected[:5], rtol=0, atol=1e-5)


def test_ittf_bounce_with_drag():
    scene = make_scene(["gravity", "drag", "table"], {"pos": [0.3, 0.1, H0 + equipment.BALL_RADIUS]},
                       integrator="rk4", dt=1e-4, duration=0.8)
    first = run(scene).bounce_heights_m[0]
    assert first == pytest.approx(0.23, abs=0.01)  # ITTF rule 2.1.3: "about 23 cm" from 30 cm


def test_drop_comes_to_rest_on_the_table_without_drift():
    scene = make_scene(["gravity", "drag", "table", "friction"], {"pos": [0.3, 0.1, H0 + equipment.BALL_RADIUS]},
                       duration=8.0)
    result = run(scene)
    ball = result.state.ball[0]
    assert int(result.state.world[0]["ball_support"]) == 1  # resting on the table
    # Resting contact keeps the ball exactly on the surface: no sinking over thousands of ticks.
    assert ball["pos"][2] == equipment.BALL_RADIUS
    np.testing.assert_array_equal(ball["vel"], 0.0)
    heights = result.bounce_heights_m
    assert all(b < a for a, b in zip(heights, heights[1:]))  # each bounce lower: no energy gain
