"""Scenes built in a test from keyword pieces, and a scene run in-process for some ticks."""
from engine.physics.scene import parse_scene
from engine.physics.world import build_model, initial_state, new_events, step


def make_scene(effects, ball, **top):
    """A scene from keyword pieces, validated like a TOML file."""
    data = {"effects": list(effects), "ball": ball, **top}
    return parse_scene(data, "test-scene")


def run_ticks(scene, ticks, dt=None):
    """Run `ticks` ticks; returns (state, list of event records)."""
    model = build_model(scene)
    state = initial_state(scene)
    events = new_events()
    seen = []
    for _ in range(ticks):
        n = step(model, state, None, events, dt)
        seen.extend(events[:n].copy())
    return state, seen
