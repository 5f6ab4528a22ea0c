"""A bot that plays a policy trained by examples/train_ppo.py (stable-baselines3's PPO).

It shows the policy what the environment showed it in training (engine.learning.agent_frame.observe: the
bot's own frame, scaled into [-1, 1]) and plays the policy's action vector as the environment
played it (engine.learning.agent_frame.action_record), so the trained agent plays a match, a tournament or
a served match (`join --bot`) as it played its episodes:

    pingpong match --scene match_rigid --a examples/ppo_bot.py:PPOBot --b novice --best-of 3

The policy is ppo_policy.zip beside this file, or the one the PPO_POLICY environment variable
names; its ppo_policy.json (written beside it) says the action type it was trained with.
Return-v1 never asks its agent to serve, so the service is examples/drive.py's (imported from
beside this file). Needs the `train` extra (`make train`).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from drive import Drive  # examples/drive.py, beside this file: the service
from engine.learning import agent_frame
from engine.play.ai import SKILLS
from engine.play.bot import Bot, new_action
from engine.play.rules import Phase

POLICY_FILE = Path(__file__).with_name("ppo_policy.zip")
POLICY_ENV = "PPO_POLICY"  # the policy file PPOBot plays, if set


class PPOBot(Bot):
    budget_s = 0.05  # CPU s a decision may take: one small network's forward pass, with room for a busy machine

    def setup(self, end, scene):
        from stable_baselines3 import PPO

        path = Path(os.environ.get(POLICY_ENV) or POLICY_FILE)
        self.action_type = json.loads(path.with_suffix(".json").read_text())["action_type"]
        self.model = PPO.load(path, device="cpu")
        self.obs = np.zeros(len(agent_frame.OBSERVATION_NAMES))
        self.action = new_action()
        self.last = None
        arm = SKILLS[self.arm]
        self.limits = arm.max_force_n, arm.max_torque_nm
        self.model.predict(self.obs, deterministic=True)  # the first pass builds torch's kernels: not in a decision
        self.server = Drive()
        self.server.player, self.server.end_sign, self.server.normal = self.player, self.end_sign, self.normal
        self.server.rng, self.server.latency = self.rng, self.latency
        self.server.setup(end, scene)

    def act(self, observation):
        if int(observation["phase"]) == Phase.WAITING_SERVE and int(observation["to_strike"]) == self.player:
            self.last = None
            return self.server.act(observation)
        agent_frame.observe(observation, self.player, self.obs)
        vector, _ = self.model.predict(self.obs, deterministic=True)
        a = agent_frame.checked_action(vector, self.action_type)
        new_path = self.last is None or not np.array_equal(a, self.last)
        agent_frame.action_record(a, self.action_type, self.player, *self.limits, observation, self.action,
                                  new_path=new_path)
        self.last = a
        return self.action
