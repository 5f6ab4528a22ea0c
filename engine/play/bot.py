"""The bot API: a player as a Python class, what it sees (an observation) and what it answers (an action).

A bot is told its end and the scene once (`setup`), then at its control rate (the scene's
match.ai_hz) gets an engine.physics.dtypes.OBSERVATION_DTYPE record and returns an
engine.physics.dtypes.ACTION_DTYPE record: the arm's target, which engine.play.arm's PD law turns into force
and torque within the arm's limits, or the force and torque themselves within the same limits.
That is all that crosses: the observation is a read-only copy made for the bot (no engine
state, no view into it), and the action drives the bot's own bat only, through its arm.

    from engine.play.bot import Bot, hold

    class Wall(Bot):
        def act(self, obs):
            ball = obs["ball"]
            return hold((self.end_sign * 1.6, ball["pos"][1], 0.15), self.normal)

The engine's own AI plays through this same door (engine.play.ai.profile_bot.ProfileBot), so whatever it plays
proves the API. A bot is named by a spec, "path/to/file.py:ClassName" or "package.module:ClassName"
(load_bot), wherever a profile name ("pro", "club", "novice") is accepted.
"""
from __future__ import annotations

import hashlib
import importlib
import math
import sys
import types
from pathlib import Path

import numpy as np

from engine.physics.dtypes import ACTION_DTYPE, ARM_SEGMENTS, OBSERVATION_DTYPE

ACTION_TARGET, ACTION_FORCE = 0, 1
ACTION_FLOATS = ACTION_DTYPE.fields["n_segments"][1] // 8  # the float64 words at the start of an action
# Offsets (in float64 words) of an action's fields.
A_FORCE, A_TORQUE, A_HOLD, A_NORMAL, A_SEGMENTS = (ACTION_DTYPE.fields[name][1] // 8
                                                  for name in ("force", "torque", "hold", "normal", "segments"))
# What can go wrong with a decision: FAULTS[code] (0 = nothing). engine.physics.dtypes.ai_answer_dtype's
# "fault" carries the code from the AI worker to the match.
FAULTS = ("none", "raised", "malformed", "non_finite", "oversized", "overran")
FAULT_CODES = {name: code for code, name in enumerate(FAULTS)}
NORMAL_TOLERANCE = 1e-6  # an arm target's face normal must be unit within this (|n| - 1)
# What the match does when a bot's decision goes wrong: the point goes to the other player, or
# the match stops there.
ON_BOT_ERROR = ("point", "stop")


class BotError(Exception):
    """A bot's decision went wrong: which bot, at which tick, what."""

    def __init__(self, bot: str, player: int, tick: int, fault: str, detail: str):
        self.bot, self.player, self.tick, self.fault, self.detail = bot, player, tick, fault, detail
        super().__init__(f"bot {bot} (player {'AB'[player]}) at tick {tick}: {fault}: {detail}")


class Bot:
    """A player: subclass it and define act().

    Attributes set before setup() is called:
        player: 0 (A, at x < 0) or 1 (B, at x > 0). end_sign: -1 for A, +1 for B.
        normal: (3,) the face normal towards the other end, (-end_sign, 0, 0).
        rng: a numpy Generator seeded from the match's seed and the player, for repeatable play.
        latency: s from an observation to the control tick from which the action decided on it
            is played (the scene's match.decision_latency in whole control periods,
            engine.physics.compiled.CompiledScene.decision_delay): a player's visuomotor delay.
            The action is played until a later one takes effect; its arm target is tracked by
            the arm's PD law on the bat's state at each control tick, so plan a path for when it
            takes effect.
    Class attributes a bot may set:
        arm: the AI profile ("pro", "club", "novice") whose arm limits (force, torque, speed)
            drive this bot's bat.
        budget_s: CPU seconds one act() may take (None: the match's --bot-budget-ms).
    """

    arm = "pro"
    budget_s: float | None = None
    latency: float
    player: int
    end_sign: int
    normal: np.ndarray
    rng: np.random.Generator

    def setup(self, end: int, scene) -> None:
        """Called once before the first act(): end 0 (A) or 1 (B), the match's engine.physics.scene.Scene
        (frozen: the table, the bats' sizes, the effects, dt, the control rate)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action (an ACTION_DTYPE record) for the OBSERVATION_DTYPE record `observation`.

        The observation is read-only and is rewritten for the next decision: copy what must be
        kept. The action returned is read at once, so the bot may return the same record each time.
        """
        raise NotImplementedError(f"{type(self).__name__}.act: a bot must define act(observation) -> action")


def new_action() -> np.ndarray:
    """A zeroed ACTION_DTYPE record (0-d array): kind ACTION_TARGET, no path, normal +x."""
    action = np.zeros((), ACTION_DTYPE)
    action["normal"] = (1.0, 0.0, 0.0)
    return action


def hold(pos, normal, out: np.ndarray | None = None) -> np.ndarray:
    """An arm target without a path: the PD law pulls the bat to `pos` (m) and turns its face to
    `normal` (normalised here); the arm's gains settle it in about 0.15 s."""
    action = new_action() if out is None else out
    n = np.asarray(normal, dtype=np.float64)
    action["kind"] = ACTION_TARGET
    action["hold"] = pos
    # The squares summed in order, as numba's batched environment does (engine.learning.batch), not
    # by a BLAS dot product, whose fused multiply-adds give other last bits.
    action["normal"] = n / math.sqrt(float(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]))
    action["n_segments"] = 0
    return action


def target(observation, pos, normal, vel=(0.0, 0.0, 0.0), at: float | None = None, then=None,
           out: np.ndarray | None = None) -> np.ndarray:
    """An arm target with a path: from the bat's state now to `pos` (m) moving at `vel` (m/s) at
    time `at` (s, world clock; default 0.1 s after the observation's time), one cubic Hermite
    segment, the face turned to `normal`; then hold `then` (default `pos`).

    Return the same path at the following decisions to play it: the PD law's feed-forward acts
    inside a segment, so a path planned anew from the bat's state at every decision does not move it.
    """
    action = hold(pos if then is None else then, normal, out)
    now = float(observation["time"])
    at = now + 0.1 if at is None else float(at)
    own = observation["own"]
    action["n_segments"] = 1 if at > now else 0
    seg = action["segments"][0]
    seg[0], seg[1] = now, at
    seg[2:5], seg[5:8], seg[8:11], seg[11:14] = own["pos"], own["vel"], pos, vel
    return action


def force(force_n, torque_nm=(0.0, 0.0, 0.0), out: np.ndarray | None = None) -> np.ndarray:
    """A raw action: hold force `force_n` (N) and torque `torque_nm` (N m) until the next decision."""
    action = new_action() if out is None else out
    action["kind"] = ACTION_FORCE
    action["force"], action["torque"] = force_n, torque_nm
    return action


def check_action(action, max_force: float, max_torque: float) -> tuple[str, str] | None:
    """What is wrong with an action, as (fault, detail), or None when it can be played.

    malformed: not one ACTION_DTYPE record, an unknown kind, n_segments outside 0..ARM_SEGMENTS,
    a segment that does not end after it starts, a face normal that is not unit; non_finite:
    any NaN or infinity in the fields its kind uses; oversized: a raw force or torque beyond the
    arm's limits (max_force N, max_torque N m).
    """
    if not isinstance(action, (np.ndarray, np.void)) or action.dtype != ACTION_DTYPE or action.shape != ():
        what = f"{type(action).__name__} of dtype {getattr(action, 'dtype', None)}, shape {getattr(action, 'shape', None)}"
        return "malformed", (f"returned {what}; act() must return one engine.physics.dtypes.ACTION_DTYPE record "
                             "(engine.play.bot.new_action(), target() or force())")
    floats = np.frombuffer(action, np.float64, ACTION_FLOATS) if isinstance(action, np.void) else \
        action.reshape(1).view(np.uint8)[:ACTION_FLOATS * 8].view(np.float64)
    kind = int(action["kind"])
    if kind == ACTION_FORCE:
        f, t = floats[A_FORCE:A_FORCE + 3], floats[A_TORQUE:A_TORQUE + 3]
        if not (np.isfinite(f).all() and np.isfinite(t).all()):
            return "non_finite", f"force {f.tolist()} N, torque {t.tolist()} N m"
        f_norm, t_norm = math.sqrt(float(f @ f)), math.sqrt(float(t @ t))
        if f_norm > max_force:
            return "oversized", f"|force| {f_norm:.6g} N beyond the arm's {max_force:g} N"
        if t_norm > max_torque:
            return "oversized", f"|torque| {t_norm:.6g} N m beyond the arm's {max_torque:g} N m"
        return None
    if kind != ACTION_TARGET:
        return "malformed", f"kind {kind}: must be {ACTION_TARGET} (arm target) or {ACTION_FORCE} (force)"
    return target_problem(floats[A_HOLD:A_SEGMENTS], floats[A_SEGMENTS:], int(action["n_segments"]))


def target_problem(pose: np.ndarray, segments: np.ndarray, n_segments: int) -> tuple[str, str] | None:
    """check_action's verdict on an arm target: pose (6,) the hold position and face normal,
    segments the path's rows (14 floats each, t0 and t1 first), n_segments of them used."""
    if not 0 <= n_segments <= ARM_SEGMENTS:
        return "malformed", f"n_segments {n_segments}: must be in 0 .. {ARM_SEGMENTS}"
    used = segments[:n_segments * 14]
    if not (np.isfinite(pose).all() and np.isfinite(used).all()):
        return "non_finite", f"arm target with NaN or infinity: hold, normal, segments {pose.tolist() + used.tolist()}"
    normal = pose[3:6]
    norm = math.sqrt(float(normal @ normal))
    if abs(norm - 1.0) > NORMAL_TOLERANCE:
        return "malformed", f"face normal {normal.tolist()} has length {norm:.9g}, must be unit"
    for k in range(n_segments):
        t0, t1 = segments[14 * k], segments[14 * k + 1]
        if not t1 > t0:
            return "malformed", f"segment {k} runs from t0 = {t0!r} to t1 = {t1!r} s: it must end after it starts"
    return None


def bot_name(spec: str) -> str:
    """A bot spec's short name for messages and tables: its class name and file."""
    where, _, cls = spec.rpartition(":")
    return f"{cls} ({Path(where).name if where.endswith('.py') else where})"


_LOADED: dict[str, type] = {}  # spec -> class, so a file is executed once per process
_SOURCES: dict[str, str] = {}  # spec -> its file's text, shipped with a task to another machine's process


def bot_source(spec: str) -> str | None:
    """The source text of a file bot ("FILE.py:Class"): the one shipped here (register_sources),
    else the file's; None for a module bot (it comes with its package)."""
    where = spec.rpartition(":")[0]
    if not where.endswith(".py"):
        return None
    if spec in _SOURCES:
        return _SOURCES[spec]
    try:
        return Path(where).read_text()
    except OSError as exc:
        raise ValueError(f"bot {spec!r}: cannot read {where}: {exc}") from exc


def register_sources(sources: dict[str, str]) -> None:
    """Make file bots loadable from their text where their files are not (a Ray worker elsewhere):
    {spec: source}, as bot_source gave them on the machine that planned the matches."""
    for spec, text in sources.items():
        if _SOURCES.get(spec) != text:
            _SOURCES[spec] = text
            _LOADED.pop(spec, None)


def load_bot(spec: str) -> type[Bot]:
    """The Bot subclass a spec names: "path/to/file.py:ClassName" (the file is run as a module of
    its own, its folder added to sys.path, so that it may import the modules beside it, unless
    their names are taken already) or "package.module:ClassName" (imported).

    Raises:
        ValueError: naming what is wrong with the spec and how to write one.
    """
    if spec in _LOADED:
        return _LOADED[spec]
    where, sep, cls_name = spec.rpartition(":")
    if not sep or not where or not cls_name.isidentifier():
        raise ValueError(f"bot {spec!r}: a bot is named FILE.py:ClassName or module:ClassName "
                         "(e.g. examples/block.py:Block)")
    if where.endswith(".py"):
        path = Path(where)
        if spec not in _SOURCES and not path.is_file():
            raise ValueError(f"bot {spec!r}: no file {where} (a path relative to the working directory or absolute)")
        source = bot_source(spec)
        module_name = f"pingpong_bot_{path.stem}_{hashlib.sha256(spec.encode()).hexdigest()[:12]}"
        module = types.ModuleType(module_name)
        module.__file__ = str(path)
        sys.modules[module_name] = module  # dataclasses and pickling look their module up here
        folder = str(path.resolve().parent)
        if folder not in sys.path:
            # Last, not first as for a script: a folder holding a package of the engine's name
            # (tests/ holds processes/) must not shadow the engine in this process or its children.
            sys.path.append(folder)  # its own modules, imported now or when it plays
        try:
            exec(compile(source, str(path), "exec"), module.__dict__)  # noqa: S102 - running the bot is the point
        except Exception as exc:
            del sys.modules[module_name]
            raise ValueError(f"bot {spec!r}: {where} raised while loading: {type(exc).__name__}: {exc}") from exc
    else:
        try:
            module = importlib.import_module(where)
        except ImportError as exc:
            raise ValueError(f"bot {spec!r}: cannot import {where}: {exc}") from exc
    cls = getattr(module, cls_name, None)
    if not (isinstance(cls, type) and issubclass(cls, Bot)):
        found = "nothing" if cls is None else repr(cls)
        raise ValueError(f"bot {spec!r}: {where} defines {found} named {cls_name}; it must be a subclass of "
                         "engine.play.bot.Bot")
    _LOADED[spec] = cls
    return cls


def new_observation() -> np.ndarray:
    """A zeroed OBSERVATION_DTYPE record (0-d array)."""
    return np.zeros((), OBSERVATION_DTYPE)
