"""The two-bat environment: PettingZoo's ParallelEnv contract, seeded episodes bit for bit, the
point's rewards to both ends."""
import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from engine.learning.env import RETURN_LANDED, RETURN_STRIKE
from engine.learning.parallel_env import AGENTS, PingPongParallelEnv
from engine.play.ai import SKILLS
from engine.play.ai.profile_bot import ProfileBot


def test_pettingzoos_parallel_api_test_passes():
    parallel_api_test(PingPongParallelEnv(max_seconds=0.5), num_cycles=120)


def _episode(env, seed: int, steps: int = 300):
    observations, infos = env.reset(seed=seed)
    for k, agent in enumerate(AGENTS):
        env.action_space(agent).seed(seed + k)
    seen = [np.concatenate([observations[a] for a in AGENTS])]
    rewards = []
    for _ in range(steps):
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, reward, terminations, truncations, _ = env.step(actions)
        seen.append(np.concatenate([observations[a] for a in AGENTS]))
        rewards.append([reward[a] for a in AGENTS])
        if not env.agents:
            break
    return np.array(seen), np.array(rewards), infos


def test_reset_with_a_seed_gives_the_same_episode_bit_for_bit():
    env = PingPongParallelEnv(action_type="force", max_seconds=1.5)
    first = _episode(env, 3)
    _episode(env, 4)
    again = _episode(env, 3)
    assert first[0].tobytes() == again[0].tobytes() and first[1].tobytes() == again[1].tobytes()
    assert first[2] == again[2] and len(first[0]) > 10
    servers = {_episode(env, seed, steps=1)[2]["a"]["server"] for seed in range(8)}
    assert servers == {"a", "b"}  # the server is drawn from the seed


def test_each_observation_is_its_own_seat():
    env = PingPongParallelEnv()
    observations, _ = env.reset(seed=1)
    own = [env.table.seats[end].view for end in (0, 1)]
    assert observations["a"][1:].tolist() != observations["b"][1:].tolist()
    for end, agent in enumerate(AGENTS):  # the ball's position, its own bat's and the other's
        assert observations[agent][2:5].tolist() == own[end]["ball"]["pos"].tolist()
        assert observations[agent][11:14].tolist() == own[end]["own"]["pos"].tolist()
        assert observations[agent][24:27].tolist() == own[1 - end]["own"]["pos"].tolist()


def test_the_point_ends_both_agents_and_each_end_gets_its_rewards():
    env = PingPongParallelEnv(max_seconds=30.0)
    observations, infos = env.reset(seed=5)
    table = env.table
    for end, skill in ((0, "pro"), (1, "novice")):  # engine AIs play both seats (the agents' stand-ins)
        agent = table.seats[end].bot
        stand_in = ProfileBot(table.match.model, end, SKILLS[skill], skill, seed=9 + end, control_every=table.every)
        stand_in.player, stand_in.end_sign, stand_in.normal = agent.player, agent.end_sign, agent.normal
        agent.stand_in = stand_in
    totals = dict.fromkeys(AGENTS, 0.0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        _, rewards, terminations, truncations, info = env.step(actions)
        for agent in AGENTS:
            totals[agent] += rewards[agent]
    assert all(terminations.values()) and not any(truncations.values()) and info["a"]["points"] == 1
    point = table.match.referee.points[-1]
    assert point.winner in (0, 1)
    server = AGENTS.index(infos["a"]["server"])
    for end, agent in enumerate(AGENTS):
        strikes = (point.shots + 1) // 2 if end == server else point.shots // 2
        sign = 1.0 if point.winner == end else -1.0
        landed = round((totals[agent] - sign - strikes * RETURN_STRIKE) / RETURN_LANDED)
        assert landed in (strikes - 1, strikes) and landed >= 0  # each strike landed but perhaps the last
        assert totals[agent] == pytest.approx(sign + strikes * RETURN_STRIKE + landed * RETURN_LANDED)


def test_steps_out_of_turn_and_bad_actions_are_named():
    env = PingPongParallelEnv()
    with pytest.raises(RuntimeError, match="call reset"):
        env.step({})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="one for each of"):
        env.step({"a": env.action_space("a").sample()})
