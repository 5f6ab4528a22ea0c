"""The two-bat environment: both ends of a match as agents, behind PettingZoo's ParallelEnv API.

    from engine.learning.parallel_env import PingPongParallelEnv

    env = PingPongParallelEnv()                     # agents "a" and "b", the rigid net
    observations, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

An episode is one rally of an engine.learning.env.PingPongEnv match whose two seats are both agents
(engine.learning.env.Agent), its server drawn from the seed: each step is one control period, each
agent's action vector is played as in Rally-v0 (its own seat, checked as a bot's) and its
observation is its own seat's record, flattened (engine.learning.env.OBSERVATION_NAMES). Rewards come
from the referee as in Rally-v0, for each end: RETURN_STRIKE a strike, RETURN_LANDED a return
bouncing on the other court, +1 the point won and -1 the point lost. The point terminates both
agents; max_seconds of simulated time truncates both; then `agents` is empty (PettingZoo's
convention). reset(seed) gives the same episode bit for bit.
"""
from __future__ import annotations

import functools

from pettingzoo import ParallelEnv

from engine.learning.env import PingPongEnv

AGENTS = ("a", "b")  # the agents, by their end


class PingPongParallelEnv(ParallelEnv):
    """Both bats of a match as the two agents of a PettingZoo ParallelEnv (see the module's docstring).

    Args: net, action_type, max_seconds, render_mode: as engine.learning.env.PingPongEnv's.
    """

    metadata = {"name": "pingpong_rally_v0", "render_modes": ["rgb_array"],
                "render_fps": PingPongEnv.metadata["render_fps"], "is_parallelizable": True}

    def __init__(self, net: str = "rigid", action_type: str = "hold", max_seconds: float = 20.0,
                 render_mode: str | None = None):
        self.table = PingPongEnv(task="rally", opponent=None, player=0, net=net, action_type=action_type,
                                 max_seconds=max_seconds, render_mode=render_mode)
        self.render_mode = render_mode
        self.possible_agents = list(AGENTS)
        self.agents: list[str] = []

    @functools.lru_cache(maxsize=None)  # PettingZoo: the same space object for the same agent
    def observation_space(self, agent: str):
        return self.table.observation_space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str):
        return self.table.action_space

    def reset(self, seed: int | None = None, options: dict | None = None):
        _, info = self.table.reset(seed=seed)
        self.agents = list(AGENTS)
        info = {"server": info["server"], "match_seed": info["match_seed"]}
        return self._observations(), {agent: dict(info) for agent in self.agents}

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("PingPongParallelEnv.step: the episode is over (or not begun); call reset()")
        missing = [agent for agent in self.agents if agent not in actions]
        if missing or set(actions) - set(self.agents):
            raise ValueError(f"actions: one for each of {self.agents}, got {sorted(actions)}")
        table = self.table
        for end, agent in enumerate(AGENTS):
            table.act(end, actions[agent])
        rewards, decided, _ = table.play_period()
        table.steps += 1
        truncated = not decided and table.steps * table.every * table.match.model.dt >= table.max_seconds
        observations = self._observations()
        ref = table.match.referee
        info = {"points": len(ref.points), "bot_errors": list(table.match.bot_errors)}
        out = ({agent: rewards[end] for end, agent in enumerate(AGENTS)},
               {agent: decided for agent in AGENTS}, {agent: truncated for agent in AGENTS},
               {agent: dict(info) for agent in AGENTS})
        if decided or truncated:
            self.agents = []
        return (observations, *out)

    def _observations(self) -> dict:
        return {agent: self.table.observation(end) for end, agent in enumerate(AGENTS)}

    def render(self):
        return self.table.render()

    def write_replay(self, path) -> None:
        """The episode so far as a replay file (engine.learning.env.PingPongEnv.write_replay)."""
        self.table.write_replay(path)

    def close(self):
        self.table.close()
