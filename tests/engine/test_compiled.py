"""The compiled scene (engine.physics.compiled): every number a run derives from its scene, built
once, handed to the workers as one pickled object, and the same match whoever built it."""
import pickle

import numpy as np

from engine.physics.compiled import CompiledScene, compile_scene, duration_ticks
from engine.physics.scene import load_scene, scene_digest
from engine.play.match import Match

CLOTH = load_scene("match")


def test_the_derived_numbers_follow_the_scene():
    compiled = compile_scene(load_scene("match_rigid", {"match.ai_hz": 50, "match.decision_latency": 0.07}))
    assert compiled.control_period == 20  # 1 / 50 Hz at dt 1 ms
    assert compiled.decision_delay == 80  # 0.07 s is 3.5 periods of 20 ms: rounded to whole periods, 4
    assert compiled.topology is None and compiled.model.cloth_watch is None  # a rigid net
    assert compile_scene(CLOTH).topology.n_knots == CLOTH.cloth.cols * CLOTH.cloth.rows
    assert compile_scene(load_scene("drop")).control_period is None  # no match, no control ticks


def test_a_duration_in_ticks_is_the_nearest_whole_tick_and_at_least_one():
    assert duration_ticks(0.1, 0.001) == 100
    assert duration_ticks(0.00149, 0.001) == 1 and duration_ticks(0.00151, 0.001) == 2
    assert duration_ticks(0.0, 0.001) == 1  # the tick an input is applied for, at least
    assert compile_scene(CLOTH).ticks(0.1) == 100


def test_compiling_a_compiled_scene_returns_it_and_the_digest_is_the_scenes():
    compiled = compile_scene(CLOTH)
    assert compile_scene(compiled) is compiled
    assert compiled.digest == scene_digest(CLOTH)


def test_a_pickled_compiled_scene_plays_the_same_match_bit_for_bit():
    """What a worker is handed (a pickled copy, as the supervisor sends it) plays what the scene
    plays in-process: the model, the net's topology and the control ticks all travel."""
    copy = pickle.loads(pickle.dumps(compile_scene(CLOTH)))
    assert isinstance(copy, CompiledScene) and copy.digest == scene_digest(CLOTH)
    reference, worker = Match(CLOTH, seed=1), Match(copy, seed=1)
    reference.play(max_ticks=1500)  # 1.5 s: the first serve crosses the cloth net
    worker.play(max_ticks=1500)
    assert np.array_equal(reference.state.record.view(np.uint8), worker.state.record.view(np.uint8))
    assert reference.state.net_sim.awake_ticks == worker.state.net_sim.awake_ticks > 0
