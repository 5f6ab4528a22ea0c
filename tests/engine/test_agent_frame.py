"""What a learner sees and does (engine.learning.agent_frame, the environments' version 1): the same game
for A and B in their own frames, every entry in [-1, 1], actions mapped onto the arm."""
import gymnasium
import numpy as np
import pytest

from engine.learning import agent_frame
import engine.learning.env  # noqa: F401 - registers the ids
from engine.play.bot import new_action, new_observation
from engine.physics.dtypes import ACTION_DTYPE
from engine.play.rules import Phase


def _turned(q):
    """The quaternion (w, x, y, z) after half a turn about z: (0, 0, 0, 1) * q."""
    w, x, y, z = q
    return np.array([-z, -y, x, w])


def _state(rng, player):
    obs = new_observation()
    obs["ball"]["pos"], obs["ball"]["vel"], obs["ball"]["spin"] = rng.normal(0, 0.5, 3), rng.normal(0, 5, 3), \
        rng.normal(0, 200, 3)
    for bat in ("own", "other"):
        q = rng.normal(size=4)
        obs[bat]["pos"], obs[bat]["quat"] = rng.normal(0, 0.8, 3), q / np.linalg.norm(q)
        obs[bat]["vel"], obs[bat]["ang_vel"] = rng.normal(0, 3, 3), rng.normal(0, 20, 3)
    obs["phase"], obs["server"], obs["to_strike"], obs["shots"] = Phase.STRUCK, player, 1 - player, 3
    obs["score"], obs["games_won"] = (7, 4) if player == 0 else (4, 7), (1, 0) if player == 0 else (0, 1)
    return obs


def test_a_and_b_see_the_same_game_in_their_own_frames(rng):
    a = _state(rng, 0)
    b = _state(rng, 1)  # the same game from B's end: turned half a turn about z, the ends swapped
    for field in ("pos", "vel", "spin"):
        b["ball"][field] = a["ball"][field] * (-1, -1, 1)
    for bat in ("own", "other"):
        for field in ("pos", "vel", "ang_vel"):
            b[bat][field] = a[bat][field] * (-1, -1, 1)
        b[bat]["quat"] = _turned(a[bat]["quat"])
    seen_a = agent_frame.observe(a, 0, np.zeros(len(agent_frame.OBSERVATION_NAMES)))
    seen_b = agent_frame.observe(b, 1, np.zeros(len(agent_frame.OBSERVATION_NAMES)))
    np.testing.assert_allclose(seen_a, seen_b, atol=1e-12)  # rounding of the turned quaternion's products
    assert np.abs(seen_a).max() <= 1.0
    names = agent_frame.OBSERVATION_NAMES
    assert seen_a[names.index("to_strike.other")] == 1.0 and seen_a[names.index("serving")] == 1.0
    assert seen_a[names.index("points.me")] == pytest.approx(7 / 11)


def test_actions_map_onto_the_own_half_and_the_arms_limits_for_either_end():
    view = new_observation()
    for player, sign in ((0, 1.0), (1, -1.0)):
        out = new_action()
        agent_frame.action_record(np.array([-1.0, 1.0, 1.0, 0.0, 0.0, 0.0]), "hold", player, 120.0, 4.0, view, out)
        np.testing.assert_allclose(out["hold"], np.array([-3.0, 1.5, 1.0]) * (sign, sign, 1.0))
        np.testing.assert_allclose(out["normal"], (sign, 0.0, 0.0))  # zero normal: towards the net
        agent_frame.action_record(np.ones(6), "force", player, 120.0, 4.0, view, out)
        assert np.linalg.norm(out["force"]) == pytest.approx(120.0) and np.linalg.norm(out["torque"]) == pytest.approx(4.0)
        assert out.dtype == ACTION_DTYPE
    with pytest.raises(ValueError, match=r"expected shape \(10,\)"):
        agent_frame.checked_action(np.zeros(6), "target")
    with pytest.raises(ValueError, match=r"entries \[1\] are not finite"):
        agent_frame.checked_action([0.0, np.nan, 0, 0, 0, 0], "hold")
    np.testing.assert_array_equal(agent_frame.checked_action([5.0, -5.0, 0, 0, 0, 0], "hold")[:2], (1.0, -1.0))


@pytest.mark.parametrize("env_id", ["pingpong/Return-v1", "pingpong/Rally-v1"])
def test_version_1_is_bounded_time_limited_and_refuses_what_gymnasium_refuses(env_id):
    env = gymnasium.make(env_id, opponent="novice")
    assert env.spec.max_episode_steps == {"pingpong/Return-v1": 300, "pingpong/Rally-v1": 2000}[env_id]
    obs, _ = env.reset(seed=3)
    env.action_space.seed(3)
    done = False
    while not done:
        assert obs.shape == env.observation_space.shape and np.abs(obs).max() <= 1.0
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    with pytest.raises(RuntimeError, match="the episode has ended"):
        env.step(env.action_space.sample())
    env.reset(seed=4)
    with pytest.raises(ValueError, match=r"expected shape \(6,\)"):
        env.step(np.zeros(7))


def test_the_dense_reward_shapes_the_same_game():
    """Dense and sparse rewards play the same episode (the reward changes nothing of the game);
    a point lost costs -1 in the dense Return."""
    runs = {}
    for reward in ("sparse", "dense"):
        env = gymnasium.make("pingpong/Return-v1", opponent="novice", reward=reward)
        obs, _ = env.reset(seed=5)
        seen, rewards, done = [obs], [], False
        while not done:
            obs, r, terminated, truncated, info = env.step(np.zeros(6))  # stands still: loses the point
            seen.append(obs)
            rewards.append(r)
            done = terminated or truncated
        runs[reward] = (np.array(seen), rewards, terminated)
    np.testing.assert_array_equal(runs["sparse"][0], runs["dense"][0])
    assert runs["sparse"][2] and runs["sparse"][1][-1] == 0.0 and runs["dense"][1][-1] == -1.0
    assert any(r != 0.0 for r in runs["dense"][1][:-1])  # the approach term while it was to strike
