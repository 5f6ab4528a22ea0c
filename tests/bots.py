"""Bots that misbehave on purpose, for the tests of the bot API (each fails from its FAIL_AT-th decision)."""
import math
import signal
import time
from pathlib import Path

import numpy as np

from engine.play.bot import Bot, force, hold, new_action

FILE = str(Path(__file__).resolve())
FAIL_AT = 30  # the decision (counted from 1) at which each one first fails


def spec(name: str) -> str:
    """The bot spec of one of this module's bots."""
    return f"{FILE}:{name}"


class _Failing(Bot):
    """Holds its ready pose, then fails at every decision from FAIL_AT on."""

    def setup(self, end, scene):
        self.decisions = 0

    def act(self, obs):
        self.decisions += 1
        if self.decisions >= FAIL_AT:
            return self.fail(obs)
        return hold((self.end_sign * 1.7, 0.0, 0.15), self.normal)


class Raises(_Failing):
    def fail(self, obs):
        raise RuntimeError("no idea what to do")


class NotANumber(_Failing):
    def fail(self, obs):
        return force((math.nan, 0.0, 0.0))


class Oversized(_Failing):
    def fail(self, obs):
        return force((1e4, 0.0, 0.0))  # the pro arm's limit is 120 N


class Malformed(_Failing):
    def fail(self, obs):
        return None


class Overruns(_Failing):
    """Uses about 60 ms of CPU: beyond the tests' 5 ms budget."""

    def fail(self, obs):
        end = time.thread_time() + 0.06
        while time.thread_time() < end:
            pass
        return hold((self.end_sign * 1.7, 0.0, 0.15), self.normal)


class Hangs(_Failing):
    """Never returns (a busy loop: only an interrupt ends it)."""

    def fail(self, obs):
        while True:
            pass


class BlocksSignals(_Failing):
    """Blocks SIGALRM, then sleeps: no interrupt reaches it (as a bot stuck in C code would be)."""

    def fail(self, obs):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
        time.sleep(3600.0)


class Writes(Bot):
    """Tries to move the ball through its observation (read-only: it raises)."""

    def act(self, obs):
        obs["ball"]["pos"][0] = 0.0
        return new_action()


class Steady(Bot):
    """Pushes its bat across with a fixed raw force (well inside every arm's limits)."""

    def act(self, obs):
        return force((0.0, 0.5, 0.0))


class NotABot:
    pass


class SetupFails(Bot):
    """Raises in setup(): the match never starts."""

    def setup(self, end, scene):
        raise RuntimeError("no table today")

    def act(self, obs):
        return force((0.0, 0.0, 0.0))


class Spy(Bot):
    """Keeps a copy of what it was shown."""

    def setup(self, end, scene):
        self.seen = []

    def act(self, obs):
        self.seen.append(np.array(obs, copy=True))
        return hold((self.end_sign * 1.7, 0.0, 0.15), self.normal)
