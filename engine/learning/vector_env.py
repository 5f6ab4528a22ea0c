"""The native vector environment: N tables of engine.learning.env.PingPongEnv stepped in this process.

    import gymnasium
    import engine.learning.env  # registers the ids and their vector entry point

    vector = gymnasium.make_vec("pingpong/Return-v1", num_envs=8, vectorization_mode="vector_entry_point",
                                opponent="novice")
    obs, infos = vector.reset(seed=0)      # table k seeded 0 + k, as Gymnasium's own vector envs do

Gymnasium 1.x's VectorEnv API (gymnasium.vector.VectorEnv): batched observations (N, D) written
in place into one array, actions (N, A), rewards, terminations and truncations (N,), infos as
Gymnasium's vector infos (a key's values in an array, "_key" the mask of the tables that gave it).
Autoreset is Gymnasium's default, AutoresetMode.NEXT_STEP: the step after a table's episode ended
resets that table (its action is ignored) and returns the reset's observation with reward 0 and
neither terminated nor truncated. reset(options={"reset_mask": mask}) resets only the masked
tables. Table k's episodes are those of a single PingPongEnv reset with the same seed, bit for
bit, as they are those of gymnasium.vector.SyncVectorEnv (tests/engine/test_vector_env.py).

Version 1 with `hold` actions (what examples/train_ppo.py trains on) is batched (`batched`;
`batch` is its engine.learning.batch.TableBatch): every table's step, and a drive's lead-in at
its reset, in one numba call, Python only where an AI profile decides a stroke, where an
episode begins (its match is made) and, with the cloth net, where the net may touch the ball
(its ticks there, and the ones it owes). Otherwise (version 0, `target` or `force` actions, a
second agent, pictures kept) the tables are stepped one after another, each one
PingPongEnv.step: its physics one numba call between the referee's and the players' Python work.
"""
from __future__ import annotations

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from engine.learning import agent_frame
from engine.learning.batch import TableBatch
from engine.learning.env import PingPongEnv


class PingPongVectorEnv(VectorEnv):
    """N PingPongEnv tables in this process as one Gymnasium VectorEnv (see the module's docstring).

    Args:
        num_envs: the tables (>= 1). max_episode_steps: as gymnasium.make's (None: none; the
            tables' own max_seconds still truncates). The other keywords are PingPongEnv's, the
            same for every table.
    """

    def __init__(self, num_envs: int, max_episode_steps: int | None = None, **kwargs):
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs: a positive number of tables, got {num_envs!r}")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps: None or a positive number of steps, got {max_episode_steps!r}")
        self.num_envs = int(num_envs)
        self.envs = [PingPongEnv(**kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        for env in self.envs[1:]:
            env.share_scenes(first)  # one compiled scene a first server for all the tables
        self.render_mode = first.render_mode
        self.metadata = {**PingPongEnv.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP}
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.max_episode_steps = max_episode_steps
        self._obs = np.zeros((self.num_envs,) + self.single_observation_space.shape)
        self._rewards = np.zeros(self.num_envs)
        self._terminations = np.zeros(self.num_envs, dtype=np.bool_)
        self._truncations = np.zeros(self.num_envs, dtype=np.bool_)
        self._autoreset = np.zeros(self.num_envs, dtype=np.bool_)
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        first = self.envs[0]
        self.batched = (first.version == 1 and first.action_type == "hold" and first.opponent is not None
                        and not first.record)
        self.batch = TableBatch(self.envs) if self.batched else None
        self._points = np.zeros(self.num_envs, dtype=np.int64)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Reset the tables (or those of options["reset_mask"]); seed None, an int (table k gets
        seed + k) or one seed a table."""
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + k for k in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: a list of one seed per table ({self.num_envs}), got {len(seeds)}")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(self.num_envs, dtype=np.bool_)
        elif not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (self.num_envs,)
                  and mask.any()):
            raise ValueError(f"options['reset_mask']: a numpy bool array of shape ({self.num_envs},) with at least "
                             f"one True, got {mask!r}")
        infos: dict = {}
        if self.batch is None:
            for k in np.flatnonzero(mask):
                self._obs[k], info = self.envs[k].reset(seed=seeds[k], options=options or None)
                infos = self._add_info(infos, info, k)
        else:
            self._begin_episodes(mask, seeds)
            self.batch.lead_in(mask)
            infos = self._end_lead_ins(mask, infos)
        self._terminations[mask] = self._truncations[mask] = self._autoreset[mask] = False
        self._elapsed[mask] = 0
        return self._obs.copy(), infos

    def step(self, actions):
        """One control period of every table; a table whose episode ended at the last step is
        reset instead (AutoresetMode.NEXT_STEP)."""
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != self.action_space.shape:
            raise ValueError(f"actions: shape {self.action_space.shape} (a row a table), got {actions.shape}")
        if self.batch is not None:
            return self._step_batch(actions)
        infos: dict = {}
        for k, env in enumerate(self.envs):
            if self._autoreset[k]:
                self._obs[k], info = env.reset()
                self._rewards[k] = 0.0
                self._terminations[k] = self._truncations[k] = False
                self._elapsed[k] = 0
            else:
                self._obs[k], self._rewards[k], self._terminations[k], truncated, info = env.step(actions[k])
                self._elapsed[k] += 1
                self._truncations[k] = truncated or (self.max_episode_steps is not None
                                                     and self._elapsed[k] >= self.max_episode_steps)
            infos = self._add_info(infos, info, k)
        self._autoreset[:] = self._terminations | self._truncations
        return self._obs.copy(), self._rewards.copy(), self._terminations.copy(), self._truncations.copy(), infos

    def _step_batch(self, actions: np.ndarray):
        """step() of the batched tables: the tables to reset in Python, the others in one numba call."""
        stepping = ~self._autoreset
        clipped = np.zeros_like(actions)
        for k in np.flatnonzero(stepping & ~np.isfinite(actions).all(axis=1)):
            agent_frame.checked_action(actions[k], "hold")  # raises, naming the entries
        np.clip(actions, -1.0, 1.0, out=clipped)
        resetting = self._autoreset.copy()
        self._begin_episodes(resetting, [None] * self.num_envs)
        batch = self.batch
        batch.step(clipped, stepping, resetting)
        infos = self._end_lead_ins(resetting, {})
        self._rewards[resetting] = 0.0
        self._terminations[resetting] = self._truncations[resetting] = False
        self._elapsed[resetting] = 0
        if stepping.any():
            self._obs[stepping] = batch.obs[stepping]
            self._rewards[stepping] = batch.rewards[stepping]
            self._terminations[stepping] = batch.terminated[stepping]
            self._elapsed[stepping] += 1
            truncated = batch.truncated[stepping]
            if self.max_episode_steps is not None:
                truncated = truncated | (self._elapsed[stepping] >= self.max_episode_steps)
            self._truncations[stepping] = truncated
            self._points[:] = batch.rally["points_total"]
            infos["points"] = np.where(stepping, self._points, infos.get("points", 0))
            infos["_points"] = stepping | infos.get("_points", False)
            errors = infos.get("bot_errors", np.full(self.num_envs, None, dtype=object))
            for k in np.flatnonzero(stepping):
                errors[k] = []  # the batch plays only the engine's AI and the checked actions: nothing faults
            infos["bot_errors"], infos["_bot_errors"] = errors, stepping | infos.get("_bot_errors", False)
        self._autoreset[:] = self._terminations | self._truncations
        return self._obs.copy(), self._rewards.copy(), self._terminations.copy(), self._truncations.copy(), infos

    def _begin_episodes(self, mask: np.ndarray, seeds: list) -> None:
        """PingPongEnv.begin_episode of the batched tables of `mask`, each loaded into the batch;
        their lead-ins are the batch's to play (TableBatch.lead_in, or step's `lead`)."""
        for k in np.flatnonzero(mask):
            self.batch.load(k, self.envs[k].begin_episode(seeds[k]))

    def _end_lead_ins(self, mask: np.ndarray, infos: dict) -> dict:
        """After the batch played the lead-ins of `mask`'s tables: their reset observations (the
        batch's, after a lead-in or of the state loaded) and infos."""
        for k in np.flatnonzero(mask):
            env = self.envs[k]
            info = env.episode_info()
            self._obs[k] = self.batch.obs[k] if info["drive"] else self.batch.observe(k)
            env.end_lead_in()
            infos = self._add_info(infos, info, k)
        return infos

    def render(self):
        """Each table's picture (PingPongEnv.render), a tuple; None without render_mode "rgb_array"."""
        if self.render_mode != "rgb_array":
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs):
        self.envs = []
