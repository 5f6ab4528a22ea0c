"""The engine's AI as a bot: BatAI behind the bot API's observation and action."""
from __future__ import annotations

import numpy as np

from engine.play.bot import A_HOLD, A_SEGMENTS, ACTION_FLOATS, ACTION_TARGET, Bot, new_action
from engine.physics.dtypes import OBSERVATION_DTYPE
from engine.play.ai.player import BatAI
from engine.play.ai.skill import Skill
from engine.play.arm import CTL_HOLD, CTL_N_SEGMENTS, CTL_SEGMENTS
from engine.play.rules import Phase

_BALL = OBSERVATION_DTYPE.fields["ball"][1]
_OWN = OBSERVATION_DTYPE.fields["own"][1]


class ProfileBot(Bot):
    """An AI profile (engine.play.ai.SKILLS) playing as a bot: at each decision BatAI.decide on the
    observation, and its arm's target (the hold pose, face normal and planned path that
    bat_control tracks) as the action. The same doubles cross as when BatAI drove the bat
    directly, so the strokes are the same bit for bit.

    Args:
        model: engine.physics.world.Model of the match scene (BatAI predicts the ball with it).
        player: 0 or 1. skill: the profile. name: its name ("pro" ...). seed, control_every,
            delay, eager: BatAI's.
    """

    budget_s = None  # the engine's own AI thinks as long as a stroke takes (BatAI spreads it)

    def __init__(self, model, player: int, skill: Skill, name: str, seed: int, control_every: int = 1,
                 delay: int = 0, eager: bool = True):
        self.ai = BatAI(model, player, skill, seed=seed, control_every=control_every, delay=delay, eager=eager)
        self.arm = name
        self._obs = None
        self._action = new_action()
        self._action["kind"] = ACTION_TARGET
        self._action_floats = self._action.reshape(1).view(np.uint8)[:ACTION_FLOATS * 8].view(np.float64)

    def renew(self, seed: int) -> None:
        """Become the ProfileBot made with this seed (BatAI.renew): a new match's player."""
        self.ai.renew(seed)
        self.rng = self.ai.rng  # a profile draws only through its BatAI

    def _views(self, observation) -> None:
        """Float64 views of the observation's ball (9,) and own bat (13,), as BatAI reads them."""
        raw = observation.reshape(1).view(np.uint8)
        self._ball = raw[_BALL:_BALL + 72].view(np.float64)
        self._own = raw[_OWN:_OWN + 104].view(np.float64)
        self._obs = observation

    def act(self, observation) -> np.ndarray:
        if observation is not self._obs:
            self._views(observation)
        ai = self.ai
        ai.decide(float(observation["time"]), self._ball, self._own, (int(observation["rally"]), int(observation["shots"])),
                  int(observation["to_strike"]) == self.player, int(observation["phase"]) == Phase.WAITING_SERVE,
                  self.end_sign)
        ctl, floats = ai._ctl, self._action_floats
        floats[A_HOLD:A_HOLD + 6] = ctl[CTL_HOLD:CTL_HOLD + 6]  # hold, then normal
        floats[A_SEGMENTS:] = ctl[CTL_SEGMENTS:]
        self._action["n_segments"] = int(ctl[CTL_N_SEGMENTS])
        return self._action

    def wakes(self) -> tuple[float, float]:
        """BatAI.wakes: until then its decisions change nothing (the match asks only when one may)."""
        return self.ai.wakes()
