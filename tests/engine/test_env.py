"""The Gymnasium environments: the checker, seeded episodes bit for bit, rewards from the referee,
the replay's picture and file, vector environments."""
import json
import multiprocessing
import subprocess
import sys

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import engine.learning.env  # noqa: F401 - registers pingpong/Return-v0 and pingpong/Rally-v0
from engine.learning.env import OBSERVATION_NAMES, RETURN_LANDED, RETURN_STRIKE, PingPongEnv
from engine.play.ai import SKILLS
from engine.play.ai.profile_bot import ProfileBot
from engine.tools.replay import read
from tests.waits import DEADLINE_S


@pytest.mark.parametrize("env_id", ["pingpong/Return-v0", "pingpong/Rally-v0", "pingpong/Return-v1",
                                    "pingpong/Rally-v1"])
def test_the_environments_pass_gymnasiums_checker(env_id):
    from engine.learning import agent_frame

    env = gymnasium.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    names = agent_frame.OBSERVATION_NAMES if env_id.endswith("v1") else OBSERVATION_NAMES
    assert env.observation_space.shape == (len(names),)


def _episode(env, seed: int, steps: int = 400):
    """Observations and rewards of one episode with seeded random actions."""
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    seen, rewards = [obs], []
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        seen.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    return np.array(seen), np.array(rewards), info


@pytest.mark.parametrize("task, action_type", [("return", "hold"), ("rally", "force")])
def test_reset_with_a_seed_gives_the_same_episode_bit_for_bit(task, action_type):
    env = PingPongEnv(task=task, action_type=action_type)
    first = _episode(env, 11)
    _episode(env, 12)  # another episode between them changes nothing
    again = _episode(env, 11)
    assert first[0].tobytes() == again[0].tobytes() and first[1].tobytes() == again[1].tobytes()
    assert len(first[0]) > 10


def _played_by(env: PingPongEnv, skill: str) -> None:
    """Let an AI profile play the agent's end (the agent's stand-in, as in a drive's lead-in)."""
    stand_in = ProfileBot(env.match.model, env.player, SKILLS[skill], skill, seed=5, control_every=env.every)
    agent = env.agent
    stand_in.player, stand_in.end_sign, stand_in.normal = agent.player, agent.end_sign, agent.normal
    agent.stand_in = stand_in


def test_a_return_that_lands_is_rewarded_and_ends_the_episode():
    env = PingPongEnv(task="return", opponent="novice")
    for seed in range(20):
        env.reset(seed=seed)
        _played_by(env, "pro")
        total, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, info = env.step(env.action_space.sample())
            total += reward
            done = terminated or truncated
        if total == pytest.approx(RETURN_STRIKE + RETURN_LANDED):  # struck once, landed once
            assert terminated and info["points"] == 0  # ended by the landing, no point decided yet
            return
    pytest.fail("pro never returned novice's ball onto its court in 20 episodes")


def test_a_rally_ends_with_the_point_and_its_sign():
    env = PingPongEnv(task="rally", opponent="novice", max_seconds=30.0)
    env.reset(seed=2)
    _played_by(env, "pro")
    rewards, done = [], False
    while not done:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        rewards.append(reward)
        done = terminated or truncated
    assert terminated and info["points"] == 1
    point = env.match.referee.points[-1]
    sign = 1.0 if point.winner == env.player else -1.0
    strikes = point.shots // 2  # the opponent served: the agent struck every second ball
    landed = round((sum(rewards) - sign - strikes * RETURN_STRIKE) / RETURN_LANDED)
    assert strikes >= 1 and landed in (strikes - 1, strikes)  # each return landed but perhaps the last
    assert sum(rewards) == pytest.approx(sign + strikes * RETURN_STRIKE + landed * RETURN_LANDED)


def test_render_is_the_replays_picture_and_the_episode_is_a_replay_file(tmp_path):
    env = PingPongEnv(render_mode="rgb_array")
    _episode(env, 3, steps=60)
    picture = env.render()
    assert picture.shape == (700, 900, 3) and picture.dtype == np.uint8 and picture.std() > 0
    env.write_replay(tmp_path / "episode.replay")
    replay = read(tmp_path / "episode.replay")
    assert len(replay.frames) == len(env.frames) > 10
    assert replay.frames[-1].tobytes() == env.frames[-1].tobytes()


def test_the_cloth_net_is_there_when_asked_for():
    env = PingPongEnv(net="cloth")
    assert env.base.net_kind == "cloth" and env.base.cloth is not None
    seen, _, _ = _episode(env, 4, steps=50)
    assert np.isfinite(seen).all()


def test_async_vector_env_steps_the_same_episodes_as_single_environments():
    make = [lambda: gymnasium.make("engine.learning.env:pingpong/Return-v0") for _ in range(2)]  # imports engine.learning.env
    vector = gymnasium.vector.AsyncVectorEnv(make, context="forkserver")
    try:
        obs, _ = vector.reset(seed=[21, 22])
        actions = np.stack([vector.single_action_space.sample() * 0.0 + [1.6, 0.0, 0.2, -1.0, 0.0, 0.2]] * 2)
        for _ in range(5):
            obs, rewards, terminated, truncated, _ = vector.step(actions)
    finally:
        vector.close()
    for k, seed in enumerate((21, 22)):
        single = PingPongEnv()
        expected, _ = single.reset(seed=seed)
        for _ in range(5):
            expected, *_ = single.step(actions[k])
        assert obs[k].tobytes() == expected.tobytes()
    assert multiprocessing.active_children() == []


def test_a_drive_episode_starts_with_the_engine_ais_return_coming_at_the_agent():
    env = PingPongEnv(task="return", opponent="novice")
    kinds = set()
    for seed in range(6):
        _, info = env.reset(seed=seed)
        ref, opponent = env.match.referee, 1 - env.player
        kinds.add(info["drive"])
        assert env.agent.stand_in is None and env.match.ais[opponent].profile  # the engine's AI plays the opponent
        if info["drive"]:  # the opponent's AI struck a return (a drive), the agent's to play
            assert ref.shots >= 2 and ref.striker == opponent and info["server"] == "ab"[env.player]
        else:  # the opponent's AI serves
            assert ref.shots == 0 and info["server"] == "ab"[opponent]
    assert kinds == {True, False}


def test_the_ball_machine_feeds_the_agents_court_within_its_ranges():
    """The curriculum: a machine's ball, drawn within the ranges, whose first bounce is on the
    agent's court (the referee's phase goes from the opponent's shot in the air to bounced)."""
    from engine.play.rules import Phase

    env = gymnasium.make("pingpong/Return-v1", opponent="novice", player=0, ball_speed=(4.0, 7.0),
                         ball_spin=(-60.0, 60.0))
    for seed in range(3):
        _, info = env.reset(seed=seed)
        shot = info["machine"]
        assert 4.0 <= shot["speed"] <= 7.0 and -60.0 <= shot["spin"] <= 60.0
        ref = env.unwrapped.match.referee
        assert (ref.phase, ref.striker) == (Phase.STRUCK, 1)  # the opponent's return, in the air
        while ref.phase == Phase.STRUCK:
            env.step(np.zeros(6))
        assert ref.phase == Phase.BOUNCED and env.unwrapped.match.state.ball[0]["pos"][0] < 0  # on A's court
    with pytest.raises(ValueError, match="ball_speed: must satisfy"):
        gymnasium.make("pingpong/Return-v1", ball_speed=(9.0, 3.0))
    with pytest.raises(ValueError, match="curriculum of the return task"):
        gymnasium.make("pingpong/Rally-v1", ball_spin=(0.0, 10.0))


# In a fresh interpreter, so no earlier test has loaded a kernel the environment's warm-up forgot:
# every numba dispatcher's signatures after the first reset, then after episodes with random
# actions in which the ball meets the cloth net.
_NO_COMPILE_SCRIPT = r"""
import json, sys
import numpy as np
from numba.core.registry import CPUDispatcher
from engine.learning.env import PingPongEnv

def signatures():
    return {f"{name}.{attr}": sorted(map(str, d.signatures)) for name, module in list(sys.modules.items())
            if name.startswith(("engine", "net_kernel")) for attr, d in vars(module).items()
            if isinstance(d, CPUDispatcher)}

env = PingPongEnv(opponent="novice", version=1, net="cloth")
env.reset(seed=0)
before = signatures()
rng = np.random.default_rng(1)
net_woke = False
for _ in range(40):
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1.0, 1.0, 6))
        net_woke = net_woke or not env.match.state.net_sim.sleeping
        done = terminated or truncated
    env.reset()
print(json.dumps({"before": before, "after": signatures(), "net_woke": net_woke}))
"""


def test_a_cloth_environment_loads_every_kernel_at_its_first_reset():
    """No kernel is compiled (or loaded from numba's cache) in the middle of an episode: on a cold
    cache that would stall a step for as long as compiling takes."""
    out = subprocess.run([sys.executable, "-c", _NO_COMPILE_SCRIPT], capture_output=True, text=True,
                         timeout=DEADLINE_S, check=True, stdin=subprocess.DEVNULL)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["net_woke"]  # the ball met the net: its contact kernels ran
    new = {name: sorted(set(sigs) - set(result["before"].get(name, []))) for name, sigs in result["after"].items()}
    assert not any(new.values()), {name: sigs for name, sigs in new.items() if sigs}
