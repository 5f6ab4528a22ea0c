"""The examples: the learning example's return rises over a short seeded run."""
import importlib.util
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _cem():
    spec = importlib.util.spec_from_file_location("cem_example", EXAMPLES / "cem.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_cross_entropy_method_raises_the_return_over_a_short_seeded_run():
    result = _cem().train(iterations=4, population=12, elite=3, episodes=6, seed=1, validation=4, test=6)
    first, last = result["curve"][0], result["curve"][-1]
    # seed 1 (the same on every run of this code): the population's mean return 0.067 -> 0.244
    assert last["population_mean"] > 2.0 * first["population_mean"] > 0.0
    assert last["elite_mean"] > first["elite_mean"]
    assert result["training_score"] >= last["elite_mean"]
    held_out = result["held_out"]  # scored on seeds no candidate trained or was chosen on
    assert held_out["episodes"] == 6 and set(held_out) == {"episodes", "trained", "untrained"}


def test_the_learned_bot_plays_the_parameters_it_is_pointed_at(tmp_path, monkeypatch):
    from engine.play.bot import load_bot

    params = tmp_path / "cem_params.json"
    params.write_text('{"params": [1.2, 3.0, 0.5, 0.1]}')
    monkeypatch.setenv("CEM_PARAMS", str(params))
    bot = load_bot(f"{EXAMPLES / 'cem.py'}:Learned")()
    bot.end_sign = 1
    bot.setup(1, None)
    assert (bot.policy.line, bot.policy.pace, bot.policy.lift, bot.policy.tilt) == (1.2, 3.0, 0.5, 0.1)


def _train_ppo():
    spec = importlib.util.spec_from_file_location("train_ppo_example", EXAMPLES / "train_ppo.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ppos_batched_tables_are_stable_baselines3s_vec_env_of_single_environments():
    """train_ppo.py's tables of the batched vector env behind stable-baselines3's VecEnv API give,
    bit for bit, what its DummyVecEnv of single Return-v1 environments seeded alike gives: the
    same observations, rewards and dones, an ended episode's table reset in the step that ended
    it, the last observation in its info."""
    import gymnasium
    from stable_baselines3.common.vec_env import DummyVecEnv

    train_ppo = _train_ppo()
    n, steps = 2, 600
    ours = train_ppo.tables_vec_env(n, seed=11)
    theirs = DummyVecEnv([lambda: gymnasium.make(train_ppo.ENV_ID, opponent="novice", reward="dense")] * n)
    theirs.seed(11)
    assert ours.reset().tobytes() == theirs.reset().tobytes()
    actions = np.random.default_rng(2).uniform(-1.0, 1.0, size=(steps, n, 6))
    ended = 0
    for action in actions:
        got, expected = ours.step(action), theirs.step(action)
        for a, b in zip(got[:3], expected[:3], strict=True):
            assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
        for k in np.flatnonzero(got[2]):
            assert got[3][k]["terminal_observation"].tobytes() == expected[3][k]["terminal_observation"].tobytes()
            assert got[3][k]["TimeLimit.truncated"] == expected[3][k]["TimeLimit.truncated"]
            ended += 1
    assert ended >= 2  # episodes ended and their tables went on


def _smoke_train(out: Path, task: str, steps: int, policy: str) -> None:
    """examples/train_ppo.py's smoke run of `task`: it trains `steps` steps, writes the policy,
    its curve and the summary into `out`, and the bot that loads the policy plays a whole game."""
    summary = _train_ppo().train(steps=steps, envs=1, out=out, seed=0, eval_episodes=2, best_of=1, task=task)
    assert summary["steps"] >= steps and summary["held_out"]["episodes"] == 2
    for name in (f"{policy}.zip", f"{policy}.json", "ppo_curve.png", "ppo_summary.json"):
        assert (out / name).stat().st_size > 0, name
    match = summary["match_against_novice"]
    assert match["winner"] in ("a", "b") and sum(match["points"]) >= 11  # a whole game was played


def test_ppo_trains_saves_and_its_saved_bot_plays_a_match(tmp_path):
    """The smoke run of examples/train_ppo.py (the `train` extra, `make train`) on Return-v1."""
    _smoke_train(tmp_path, "return", 2048, "ppo_policy")


def test_ppo_learns_the_stroke_saves_and_its_strike_bot_plays_a_match(tmp_path):
    """The smoke run of examples/train_ppo.py --task strike (examples/strike.py: the stroke
    learned, the footwork examples/drive.py's); StrikeBot plays the game."""
    _smoke_train(tmp_path, "strike", 256, "strike_policy")


def test_the_shipped_strike_policy_beats_novice(monkeypatch):
    """examples/strike_policy.zip, the policy StrikeBot plays by default (train_ppo.py --task
    strike --steps 100000 --envs 2, seed 0): a seeded best-of-3 against novice from each end
    (the same matches on every run of this code)."""
    from engine.physics.scene import load_scene
    from engine.play.match import match_record

    monkeypatch.delenv("STRIKE_POLICY", raising=False)
    strike, scene = f"{EXAMPLES / 'strike.py'}:StrikeBot", load_scene("match_rigid")
    as_a = match_record(scene, 200, strike, "novice", best_of=3)
    as_b = match_record(scene, 201, "novice", strike, best_of=3)  # the other end: the frame mirrored
    assert (as_a["winner"], as_b["winner"]) == ("a", "b"), (as_a["games"], as_b["games"])
    assert as_a["bot_errors"] == as_b["bot_errors"] == []


def test_the_strike_environment_takes_one_stroke_an_episode_and_refuses_bad_ones():
    import sys

    import numpy as np
    import pytest

    sys.path.insert(0, str(EXAMPLES))
    try:
        from strike import StrikeEnv, stroke_from_action
    finally:
        sys.path.remove(str(EXAMPLES))
    env = StrikeEnv()
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    with pytest.raises(ValueError, match=r"action: expected 5 finite numbers"):
        env.step(np.zeros(4))
    obs, reward, terminated, truncated, info = env.step(np.zeros(5, np.float32))
    assert terminated and not truncated and isinstance(info["landed"], bool)
    with pytest.raises(RuntimeError, match="the episode has ended; call reset"):
        env.step(np.zeros(5))
    # The action's frame is the agent's: the two ends strike mirror images of each other.
    a = np.array([0.3, -0.5, 0.8, 0.2, 0.1])
    normal_a, vel_a = stroke_from_action(a, -1)
    normal_b, vel_b = stroke_from_action(a, 1)
    np.testing.assert_allclose(normal_b, normal_a * [-1, -1, 1], atol=1e-15)  # half a turn about z
    np.testing.assert_allclose(vel_b, vel_a * [-1, -1, 1], atol=1e-15)
    assert np.linalg.norm(normal_a) == pytest.approx(1.0, abs=1e-12)  # a unit normal by construction


def test_the_drive_example_beats_novice_from_either_end():
    """examples/drive.py, the hand-written bot the README offers as the one to read: a seeded
    best-of-3 against novice from each end (the same matches on every run of this code)."""
    from engine.physics.scene import load_scene
    from engine.play.match import match_record

    drive = f"{EXAMPLES / 'drive.py'}:Drive"
    scene = load_scene("match_rigid")
    as_a = match_record(scene, 200, drive, "novice", best_of=3)
    as_b = match_record(scene, 200, "novice", drive, best_of=3)
    assert (as_a["winner"], as_b["winner"]) == ("a", "b"), (as_a["games"], as_b["games"])
    assert as_a["bot_errors"] == as_b["bot_errors"] == []
