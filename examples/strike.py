"""Learn the stroke, keep the footwork: an environment whose one action is how to strike a ball.

Robot table tennis learners commonly split the task where it splits for a player: where and when
to meet the ball follows from its predicted flight, and what is learned is the stroke at that
moment, the racket's orientation and velocity at the hit (a "virtual hitting plane": Gao, Tebbe,
Zell, "Robotic Table Tennis with Model-Free Reinforcement Learning", IROS 2020; Mülling, Kober,
Kroemer, Peters, "Learning to select and generalize striking movements in robot table tennis",
IJRR 2013). Here the footwork is examples/drive.py's (the ball's flight predicted with the
table's own physics, the meeting point at the top of its bounce) and the stroke is the learner's:

- StrikeEnv ("one return a step"): an episode is pingpong/Return-v1 against `novice` (its
  service, or half the time a drive), the agent's bat moved by Drive's footwork. The
  observation is the ball where the bat will meet it, in the agent's own frame
  (engine.learning.agent_frame's) and over OBS_SCALE: position, velocity, spin; 9 numbers in
  [-1, 1].
  The action, 5 numbers in [-1, 1]: the face normal's elevation and azimuth (up to
  MAX_ELEVATION and MAX_AZIMUTH from the line towards the net) and the bat's velocity at the hit
  (BAT_VEL_MID + a * BAT_VEL_HALF m/s, agent frame). The episode then plays to its end (Return-v1's: the
  return lands, the rally is decided, the time limit). The reward: Return-v1's sparse one from
  the action on (RETURN_STRIKE for the strike, RETURN_LANDED for the return landing on the
  opponent's court) less AIM_COST per metre between where the struck ball first comes down
  to the table's height and the middle of the opponent's court (AIM_POINT): a graded signal
  for returns that miss, smaller than a landing's. info["landed"] says whether it landed.
- StrikeBot (`pingpong match --a examples/strike.py:StrikeBot --b novice`): Drive with the
  learned stroke in place of Drive's solved one; the service stays Drive's. It plays the policy
  examples/train_ppo.py --task strike wrote: strike_policy.zip beside this file (trained with
  --steps 100000 --envs 2, seed 0; its curve strike_curve.png), or the one the STRIKE_POLICY
  environment variable names. Needs the `train` extra (`make train`).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import gymnasium
import numpy as np
from gymnasium import spaces

from drive import Drive  # examples/drive.py, beside this file: the footwork and the service
from engine.physics import equipment as eq
from engine.learning.env import PingPongEnv

MAX_ELEVATION = math.radians(60.0)  # the face normal's largest tilt up or down from horizontal
MAX_AZIMUTH = math.radians(45.0)  # its largest turn left or right of the line towards the net
# The bat's velocity at the hit, agent frame, m/s: the middle of each entry's range and its half
# width (towards the net 1..11, across -3..3, up -1.5..4.5: a drive's and a push's, not a smash's)
BAT_VEL_MID = np.array([6.0, 0.0, 1.5])
BAT_VEL_HALF = np.array([5.0, 3.0, 3.0])
# The observation's scales: the ball where it is met, m, m/s, rad/s (entries clipped to [-1, 1])
OBS_SCALE = np.array([2.0, 1.0, 1.0, 15.0, 10.0, 10.0, 300.0, 300.0, 300.0])
OPPONENT = "novice"
AIM_POINT = np.array([eq.TABLE_LENGTH / 4, 0.0])  # m, agent frame: the middle of the opponent's court
AIM_COST = 0.5  # reward per metre from AIM_POINT (at most AIM_COST_MAX_M of them)
AIM_COST_MAX_M = 3.0
POLICY_FILE = Path(__file__).with_name("strike_policy.zip")
POLICY_ENV = "STRIKE_POLICY"  # the policy file StrikeBot plays, if set


def _frame(end_sign: int) -> np.ndarray:
    """World <-> agent frame, per axis (its own inverse): half a turn about z for the end at +x,
    so that in the agent's frame its own court is at negative x (engine.learning.agent_frame)."""
    return np.array([-end_sign, -end_sign, 1.0])


def strike_observation(row: np.ndarray, end_sign: int) -> np.ndarray:
    """The ball at `row` of Drive's predicted path (t, pos, vel, spin) as the 9 observation numbers."""
    turn = np.tile(_frame(end_sign), 3)
    return np.clip(row[1:10] * turn / OBS_SCALE, -1.0, 1.0)


def stroke_from_action(action: np.ndarray, end_sign: int) -> tuple[np.ndarray, np.ndarray]:
    """The action vector (clipped to [-1, 1]) as the world's face normal and bat velocity."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    if a.shape != (5,) or not np.isfinite(a).all():
        raise ValueError(f"action: expected 5 finite numbers in [-1, 1] (elevation, azimuth, velocity x, y, z), "
                         f"got {np.asarray(action).tolist()}")
    elevation, azimuth = a[0] * MAX_ELEVATION, a[1] * MAX_AZIMUTH
    normal = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                       math.sin(elevation)])
    turn = _frame(end_sign)
    return normal * turn, (BAT_VEL_MID + a[2:5] * BAT_VEL_HALF) * turn


class _Footwork(Drive):
    """Drive's footwork, its stroke asked of `stroke_of` (the row of the ball's path -> (normal,
    bat velocity)); `asked` keeps the first row it was asked about."""

    def setup(self, end, scene):
        super().setup(end, scene)
        self.stroke_of = None
        self.asked = None

    def _stroke(self, row):
        if self.asked is None:
            self.asked = row
        return self.stroke_of(row)


class StrikeEnv(gymnasium.Env):
    """One return a step (see the module's docstring). Args: net ("rigid" or "cloth") and the
    time limit of the Return-v1 episode under it (max_seconds)."""

    def __init__(self, net: str = "rigid", max_seconds: float = 3.0):
        self.inner = PingPongEnv(task="return", opponent=OPPONENT, net=net, action_type="hold", version=1,
                                 reward="sparse", max_seconds=max_seconds)
        self.observation_space = spaces.Box(-1.0, 1.0, (9,), dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (5,), dtype=np.float32)
        self.footwork: _Footwork | None = None
        self._ended = True

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        inner_seed = int(self.np_random.integers(0, 2**31 - 1))
        while True:  # until a ball the footwork will meet (one it lets go ends its rally first)
            self.inner.reset(seed=inner_seed)
            inner_seed += 1
            self.periods, self.done = 0, False
            footwork = self._footwork()
            # Until the learner answers, a face towards the net and a still bat (one period of it)
            neutral = stroke_from_action(np.zeros(5), footwork.end_sign)
            footwork.stroke_of = lambda row: neutral
            while footwork.asked is None and not self.done:
                self._play(footwork)
            if footwork.asked is not None and not self.done:
                break
        self.row = footwork.asked
        self._ended = False
        return strike_observation(self.row, footwork.end_sign), {"match_seed": self.inner.seed_of_match}

    def _footwork(self) -> _Footwork:
        """A fresh footwork for the inner episode's agent seat."""
        agent = self.inner.agent
        footwork = _Footwork()
        footwork.player, footwork.end_sign, footwork.normal = agent.player, agent.end_sign, agent.normal
        footwork.rng, footwork.latency = agent.rng, agent.latency
        footwork.setup(self.inner.player, self.inner.match.scene)
        self.footwork = footwork
        return footwork

    def _play(self, footwork: _Footwork) -> tuple[float, bool]:
        """One control period of the inner episode with the footwork's action: the agent's
        reward and whether its return landed; self.done once the episode is over (Return-v1's
        ends: the rally decided, the return landed, the time limit)."""
        inner = self.inner
        inner.agent.action[...] = footwork.act(inner.seat.view)
        rewards, decided, landed = inner.play_period()
        self.periods += 1
        over = self.periods * inner.every * inner.match.model.dt >= inner.max_seconds
        self.done = decided or landed[inner.player] or over or inner.match.over
        return rewards[inner.player], landed[inner.player]

    def step(self, action):
        if self._ended:
            raise RuntimeError("StrikeEnv.step: the episode has ended; call reset()")
        footwork = self.footwork
        normal, bat_v = stroke_from_action(action, footwork.end_sign)
        # The stroke is the learner's for this ball: also where the footwork plans again (the
        # ball left its predicted path, off the net, say), the normal and velocity stay.
        footwork.stroke_of = lambda row: (normal, bat_v)
        footwork.plan = None  # the lead-in's plan held the placeholder stroke: plan again now
        total, landed = 0.0, False
        referee, ball = self.inner.match.referee, self.inner.match.state.ball[0]
        shots, down = referee.shots, None
        turn = _frame(footwork.end_sign)
        while not self.done:
            reward, landed_now = self._play(footwork)
            total += reward
            landed = landed or landed_now
            struck = referee.shots > shots and referee.striker == footwork.player
            if struck and down is None and ball["pos"][2] <= eq.BALL_RADIUS and ball["vel"][2] < 0:
                down = ball["pos"][:2] * turn[:2]  # where it first comes down to the table's height
        if down is None:  # never came down while the episode lasted (or was never struck): where it is
            down = ball["pos"][:2] * turn[:2]
        total -= AIM_COST * min(float(np.linalg.norm(down - AIM_POINT)), AIM_COST_MAX_M)
        self._ended = True
        return strike_observation(self.row, footwork.end_sign), total, True, False, {"landed": landed}


class StrikeBot(Drive):
    """Drive with the learned stroke (see the module's docstring)."""

    budget_s = 0.05  # CPU s a decision may take: Drive's prediction and one small network's forward pass

    def setup(self, end, scene):
        super().setup(end, scene)
        from stable_baselines3 import PPO

        path = Path(os.environ.get(POLICY_ENV) or POLICY_FILE)
        if not path.is_file():
            raise FileNotFoundError(f"StrikeBot: no policy at {path}; train one (python examples/train_ppo.py "
                                    f"--task strike --out DIR) and set {POLICY_ENV}=DIR/strike_policy.zip")
        self.model = PPO.load(path, device="cpu")
        self.model.predict(np.zeros(9), deterministic=True)  # torch builds its kernels here, not in a decision

    def _stroke(self, row):
        action, _ = self.model.predict(strike_observation(row, self.end_sign), deterministic=True)
        return stroke_from_action(action, self.end_sign)
