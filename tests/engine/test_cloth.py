"""The cloth net coupled to the ball (net_kernel.NetSim inside engine.physics.world.advance)."""
import numpy as np
import pytest

from engine.physics.geometry import Body
from engine.physics.scene import SceneError, parse_scene
from engine.physics.world import build_model, initial_state, new_events, step
from net_kernel import NetSpec
from net_kernel.topology import resolution_spec
from tests.helpers.scenes import make_scene, run_ticks

CLOTH = {"kind": "cloth"}
# A coarse net (fewer, heavier knots) settles and sleeps within a few hundred ticks.
COARSE = {"kind": "cloth", "cols": 24, "rows": 4, "knot_mass": 0.05 / 96}


def test_a_20_m_per_s_ball_is_stopped_and_thrown_back_by_the_cloth_net():
    scene = make_scene(["gravity", "drag", "net", "table", "floor"],
                       {"pos": [-0.6, 0.1, 0.08], "vel": [20.0, 0.0, 0.0]}, net=CLOTH)
    state, events = run_ticks(scene, 300)
    bodies = [int(e["body"]) for e in events]
    assert bodies and bodies[0] == Body.NET
    assert state.ball["pos"][0][0] < 0.0  # thrown back: never got through
    assert state.ball["vel"][0][0] < 0.0
    assert max(float(e["pos"][0]) for e in events if int(e["body"]) == Body.NET) < 0.05  # the bulge, a few cm


def test_a_far_ball_leaves_a_sleeping_net_untouched():
    scene = make_scene(["gravity", "net", "table"], {"pos": [-1.0, 0.0, 0.3]}, net=COARSE)
    model, state, events = build_model(scene), initial_state(scene), new_events()
    for _ in range(5000):  # the net settles and falls asleep while the ball bounces far away
        step(model, state, None, events)
        if state.net_sim.sleeping:
            break
    assert state.net_sim.sleeping
    calls = state.net_sim.kernel_calls
    for _ in range(200):
        step(model, state, None, events)
    assert state.net_sim.kernel_calls == calls  # a sleeping net costs no kernel call


def test_cloth_fields_are_validated_with_their_key():
    with pytest.raises(SceneError, match=r"net.cols: 1 is out of range: an integer in \[2, 4000\]"):
        parse_scene({"effects": ["net"], "ball": {"pos": [-0.5, 0, 0.3]}, "net": {"kind": "cloth", "cols": 1}}, "x")
    with pytest.raises(SceneError, match=r"net.spring_k: describes a cloth net"):
        parse_scene({"effects": ["net"], "ball": {"pos": [-0.5, 0, 0.3]}, "net": {"spring_k": 10.0}}, "x")


def test_the_rigid_net_scene_has_no_cloth():
    scene = make_scene(["net"], {"pos": [-0.5, 0.0, 0.3]})
    assert initial_state(scene).net_sim is None and build_model(scene).net is not None
    np.testing.assert_array_equal(build_model(scene).cloth_watch is None, True)


def test_net_resolution_regrids_the_net_the_other_keys_describe():
    scene = parse_scene({"effects": ["net"], "ball": {"pos": [-0.5, 0, 0.3]},
                         "net": {"kind": "cloth", "resolution": [85, 8], "cord_tension": 15.0}}, "x")
    assert scene.cloth == resolution_spec(85, 8, NetSpec(cord_tension=15.0))


@pytest.mark.parametrize("net, named", [({"resolution": [85]}, "net.resolution"),
                                        ({"resolution": [85, 8], "cols": 85}, "net.cols"),
                                        ({"resolution": [1000, 3]}, "net.resolution")])
def test_a_bad_net_resolution_is_refused_naming_the_key(net, named):
    with pytest.raises(SceneError, match=named):
        parse_scene({"effects": ["net"], "ball": {"pos": [-0.5, 0, 0.3]}, "net": {"kind": "cloth", **net}}, "x")


# The tape test of ITTF Technical Leaflet T2: a ball hitting the top of the net should fall back
# on the hitter's side or bounce forward, not dribble over (which needs the top cord far tighter
# than the mesh). Balls just in front of the default match's net, the centre at the top
# (`above` = 0), half a radius above it or 0.8 of a radius above (the tape's top edge clips the
# ball's lower half), at a push's and a drive's speed.
TAPE = {"kind": "cloth", "resolution": [85, 8]}
NET_TOP = 0.1525  # m, ITTF 2.2.3


@pytest.mark.parametrize("speed", [2.0, 8.0])
@pytest.mark.parametrize("above", [0.0, 0.5, 0.8])
def test_a_ball_into_the_tape_falls_back_or_bounces_forward(speed, above):
    radius = 0.02
    scene = make_scene(["gravity", "drag", "net", "table", "floor"],
                       {"pos": [-0.026, 0.2, NET_TOP + above * radius], "vel": [speed, 0.0, 0.0]}, net=TAPE)
    _, events = run_ticks(scene, 1000)
    assert any(int(e["body"]) == Body.NET for e in events)  # it met the tape
    landing = next(float(e["pos"][0]) for e in events if int(e["body"]) == Body.TABLE)
    # It lands back on the hitter's side, or forward: a dribble, a ball rolling off the tape at
    # under 0.5 m/s, lands within v sqrt(2 h / g) = 0.09 m of the net (h = 0.17 m, the ball's
    # bottom at the tape); 0.1 m past it means the ball bounced forward (0.8 radius above the
    # tape at 2 m/s lands at 0.19 m, untouched it would at 0.32 m).
    assert landing < 0.0 or landing > 0.1, landing
