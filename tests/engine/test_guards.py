"""Guards at the boundary and after each tick: bad numbers are refused, never propagated."""
import numpy as np
import pytest

from engine.physics.scene import SceneError, parse_scene
from engine.physics.world import SimulationError, build_model, initial_state, new_events, step
from tests.helpers.scenes import make_scene

BATS = {"a": {"pos": [-1.5, 0.0, 0.2]}, "b": {"pos": [1.5, 0.0, 0.2]}}


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_bat_input_is_refused_and_changes_nothing(bad):
    scene = make_scene(["gravity", "bats"], {"pos": [0.0, 0.0, 0.5]}, bats=BATS)
    model, state, events = build_model(scene), initial_state(scene), new_events()
    inputs = np.zeros((2, 6))
    inputs[1, 4] = bad
    before = (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes())
    with pytest.raises(ValueError, match=r"bat b torque\[1\] is .*; inputs must be finite"):
        step(model, state, inputs, events)
    assert (state.ball.tobytes(), state.bats.tobytes(), state.world.tobytes()) == before


def test_wrong_input_shape_is_refused():
    scene = make_scene(["bats"], {"pos": [0.0, 0.0, 0.5]}, bats=BATS)
    with pytest.raises(ValueError, match=r"shape \(2, 6\)"):
        step(build_model(scene), initial_state(scene), np.zeros((1, 6)), new_events())


def test_a_tick_that_would_go_non_finite_raises_and_keeps_the_state():
    scene = make_scene(["gravity", "drag"], {"pos": [0.0, 0.0, 0.5]})
    model, state, events = build_model(scene), initial_state(scene), new_events()
    state.ball["vel"][0] = [1e200, 0.0, 0.0]  # drag on this overflows to inf
    before = state.ball.tobytes()
    with pytest.raises(SimulationError, match=r"tick 0: the ball's (pos|vel)\[x\] would become non-finite"):
        step(model, state, None, events)
    assert state.ball.tobytes() == before


# Degenerate cloth nets (issue 10): each refused when the scene is loaded, naming the key and the limit.
FAR = {"pos": [-1.0, 0.0, 0.5]}


@pytest.mark.parametrize("net, message", [
    ({"knot_mass": 0.0}, r"net.knot_mass: 0.0 is out of range: a finite number > 0"),
    ({"knot_mass": 1e-310}, r"net.knot_mass: 1e-310 is out of range: a mass whose inverse 1/knot_mass is finite"),
    ({"knot_mass": float("inf")}, r"net.knot_mass: must be finite, got inf"),
    ({"spring_k": 0.0}, r"net.spring_k: 0.0 is out of range: a finite number > 0"),
    ({"cord_k": 0.0}, r"net.cord_k: 0.0 is out of range: a finite number > 0"),
    ({"spring_k": float("nan")}, r"net.spring_k: must be finite, got nan"),
    ({"spring_c": float("-inf")}, r"net.spring_c: must be finite, got -inf"),
    ({"air_damping": -1.0}, r"net.air_damping: must be in \[0.0, inf\], got -1.0"),
    # Pretension T >= k x spacing leaves a rest length <= 0: a zero-length spring.
    ({"cord_tension": 50.0}, r"net.cord_tension: 50.0 is out of range: < cord_k \* column spacing = 50 N"),
    ({"mesh_tension": 20.0}, r"net.mesh_tension: 20.0 is out of range: < spring_k \* column spacing = 20 N"),
    ({"cols": 2.5}, r"net.cols: must be a whole number, got 2.5"),
    ({"cols": 1}, r"net.cols: 1 is out of range: an integer in \[2, 4000\]"),
    ({"solver": "rk4"}, r"net.solver: must be one of semi_implicit, implicit; got 'rk4'"),
    ({"spring_k": 2e11}, r"net: the explicit net solver would need 2.09e\+05 substeps a tick .*h_max = 5.33e-09 s.*"
                         r"more than 1000; use solver = \"implicit\""),
])
def test_degenerate_cloth_net_refused_at_scene_load(net, message):
    with pytest.raises(SceneError, match=message):
        parse_scene({"effects": ["net"], "ball": FAR, "net": {"kind": "cloth", **net}}, "net.toml")


def test_a_stiff_net_the_explicit_solver_cannot_afford_is_accepted_with_the_implicit_solver():
    scene = parse_scene({"effects": ["net"], "ball": FAR, "net": {"kind": "cloth", "spring_k": 2e11, "solver": "implicit"}},
                        "net.toml")
    assert scene.cloth.spring_k == 2e11


def test_the_substep_limit_follows_the_tick():
    # 2e6 N/m (1000x the default) needs ~660 substeps at 1 ms (accepted) and ~1,320 at 2 ms (refused).
    net = {"kind": "cloth", "spring_k": 2e6}
    parse_scene({"effects": ["net"], "ball": FAR, "net": net, "dt": 0.001}, "net.toml")
    with pytest.raises(SceneError, match=r"net: the explicit net solver would need 1.3\de\+03 substeps a tick \(tick 0.002 s"):
        parse_scene({"effects": ["net"], "ball": FAR, "net": net, "dt": 0.002}, "net.toml")
