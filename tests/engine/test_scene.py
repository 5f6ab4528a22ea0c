"""Scenes: bundled scenes load; every bad scene is refused with the file, the key and what is allowed."""
from dataclasses import replace

import pytest

from engine.physics.compiled import compile_scene
from engine.physics.scene import (SCENES_DIR, SceneError, load_scene, scene_digest, scene_from_toml, scene_toml,
                                  with_overrides, with_remote_players, with_skills)
from net_kernel.topology import AIR_DAMPING_PHYSICAL


@pytest.mark.parametrize("name", ["drop", "serve", "rally"])
def test_bundled_scenes_load(name):
    scene = load_scene(name)
    assert scene.name == name and scene.ticks > 0


def test_match_air_is_the_default_match_with_the_airs_own_drag():
    match, air = load_scene("match"), load_scene("match_air")
    assert air.cloth.air_damping == AIR_DAMPING_PHYSICAL
    same = {"name": match.name, "description": match.description, "source": match.source,
            "cloth": replace(air.cloth, air_damping=match.cloth.air_damping)}
    assert replace(air, **same) == match  # everything else as scenes/match.toml has it


def write(tmp_path, text):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    return path


GOOD = 'effects = ["gravity", "bats"]\n[ball]\npos = [0, 0, 0.3]\n[bats.a]\npos = [-1.5, 0, 0.2]\n'


@pytest.mark.parametrize(
    "text, key, hint",
    [
        ("mass_of_ball = 3\n" + GOOD, "mass_of_ball", "unknown key"),
        (GOOD.replace("pos = [-1.5, 0, 0.2]", "pos = [-1.5, 0, 0.2]\nmas = 0.2"), "bats.a.mas", "allowed here: pos"),
        (GOOD.replace("pos = [-1.5, 0, 0.2]", "pos = [-1.5, 0, 0.2]\nmass = -1"), "bats.a.mass", "must be in [0.05, 1.0]"),
        (GOOD.replace("pos = [-1.5, 0, 0.2]", 'pos = [-1.5, 0, 0.2]\nmass = "heavy"'), "bats.a.mass", "must be a number"),
        (GOOD.replace("[0, 0, 0.3]", "[0, nan, 0.3]"), "ball.pos[1]", "must be finite"),
        (GOOD.replace("[0, 0, 0.3]", "[0, inf, 0.3]"), "ball.pos[1]", "must be finite"),
        (GOOD.replace("[0, 0, 0.3]", "[0, 0]"), "ball.pos", "list of 3 numbers"),
        (GOOD.replace('"gravity"', '"gravity", "recording"'), "effects", "not supported"),
        (GOOD.replace('"gravity"', '"gravity", "ai"'), "effects", "needs a bat with a skill"),
        (GOOD.replace('"gravity"', '"gravty"'), "effects", "unknown effect 'gravty'"),
        (GOOD.replace('"gravity", "bats"', '"gravity"'), "bats", "not listed in effects"),
        ("dt = 0\n" + GOOD, "dt", "must be in (0.0, 0.05]"),
        ('integrator = "leapfrog"\n' + GOOD, "integrator", "must be one of explicit_euler"),
        (GOOD + "[materials.table]\nrestitution = 1.5\n", "materials.table.restitution", "must be in [0.0, 1.0]"),
        (GOOD.replace("[bats.a]\npos = [-1.5, 0, 0.2]", "[bats.a]\npos = [-1.5, 0, 0.2]\nnormal = [0, 0, 0]"),
         "bats.a.normal", "zero vector"),
        (GOOD + "[net]\nkind = \"rope\"\n", "net", "not listed in effects"),
    ],
)
def test_bad_scene_errors_name_file_key_and_allowed(tmp_path, text, key, hint):
    path = write(tmp_path, text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {key}:"), message
    assert hint in message, message


def test_not_toml(tmp_path):
    path = write(tmp_path, "effects = [\n")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(path)


def test_missing_file_lists_bundled_scenes():
    with pytest.raises(SceneError, match="bundled scenes: .*drop"):
        load_scene("no_such_scene")


def test_overrides_are_validated():
    scene = load_scene(SCENES_DIR / "drop.toml")
    with pytest.raises(SceneError, match="integrator: must be one of"):
        with_overrides(scene, integrator="euler")
    with pytest.raises(SceneError, match=r"dt: must be in \(0.0, 0.05\]"):
        with_overrides(scene, dt=float("nan"))
    assert with_overrides(scene, dt=0.002).ticks == 2500


def test_the_decision_latency_is_checked_and_counts_in_whole_control_periods():
    with pytest.raises(SceneError, match=r"match.decision_latency: must be in \[0.0, 0.3\], got 0.5"):
        load_scene("match_rigid", {"match.decision_latency": 0.5})
    with pytest.raises(SceneError, match="match.decision_latency: must be a number"):
        load_scene("match_rigid", {"match.decision_latency": "soon"})
    assert compile_scene(load_scene("match_rigid")).decision_delay == 50  # 0.05 s at dt 1 ms: five control periods of 10 ticks
    assert compile_scene(load_scene("match_rigid", {"match.decision_latency": 0.0})).decision_delay == 10  # at least one period
    assert compile_scene(load_scene("match_rigid", {"match.decision_latency": 0.1, "match.ai_hz": 50})).decision_delay == 100


SERVED_AND_PLAYED = [  # scenes as a run makes them from files: served to remote players, played by bots
    lambda: with_remote_players(load_scene("match"), 1),
    lambda: with_skills(load_scene("match_rigid"), "examples/attack.py:Attack", "novice"),
    lambda: with_overrides(load_scene("rally"), dt=0.0005, integrator="rk4"),
]


@pytest.mark.parametrize("make", [*(lambda p=p: load_scene(p) for p in sorted(SCENES_DIR.glob("*.toml"))),
                                  *SERVED_AND_PLAYED])
def test_scene_toml_reads_back_as_the_same_scene(make):
    scene = make()
    back = scene_from_toml(scene_toml(scene), "sent")
    assert back.source == "sent" and replace(back, source=scene.source) == scene  # every field, to the bit
    assert scene_digest(back) == scene_digest(scene)


def test_a_scene_no_file_describes_is_refused_by_scene_toml():
    scene = load_scene("match")
    wide = replace(scene, cloth=replace(scene.cloth, width=2.0))
    with pytest.raises(SceneError, match="net.width: 2.0 is not NetSpec's 1.83"):
        scene_toml(wide)


def test_a_bat_may_be_played_by_a_bot_named_in_the_file(tmp_path):
    text = (SCENES_DIR / "match_rigid.toml").read_text().replace('skill = "pro"', 'skill = "bots.py:Mine"', 1)
    assert load_scene(write(tmp_path, text)).bats[0].skill == "bots.py:Mine"
    with pytest.raises(SceneError, match=r"bats.a.skill: must be one of pro, club, novice or a bot"):
        load_scene(write(tmp_path, text.replace("bots.py:Mine", "grandmaster")))
