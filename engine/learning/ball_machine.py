"""A ball machine: the curriculum's balls, shot from the opponent's end at the agent's court.

A learner that must first return a hard service rarely touches the ball, and learns nothing from
the episodes in which it does not; a coach's robot feeds balls of a chosen speed and spin
instead, and widens the ranges as the player improves. launch() draws one such ball: from behind
the opponent's end line, at a horizontal speed and a topspin (+) or backspin (-) drawn from the
given ranges, aimed drag-free at a point drawn in the middle of the agent's court. Drag and spin
bend it away from that point: lands_on() flies it with the engine (rigid net, bats standing) and
the environment keeps only a ball whose first contact is the agent's court (engine.learning.env.PingPongEnv).
"""
from __future__ import annotations

import numpy as np

from engine.physics import equipment
from engine.physics.geometry import Body
from engine.physics.world import advance

LAUNCH_X = equipment.TABLE_LENGTH / 2 + 0.2  # m from the net: behind the opponent's end line
LAUNCH_Y, LAUNCH_Z = 0.3, 0.3  # m: the launch's half-width of spread, and its height over the table
TARGET_X = (0.45, 1.1)  # m from the net on the agent's court: where the drag-free arc comes down
TARGET_Y = 0.55  # m: half-width of the target's spread


def check_range(name: str, values, low: float, high: float) -> tuple[float, float]:
    """(lo, hi) of a range argument, refused (ValueError naming it) unless low <= lo <= hi <= high."""
    try:
        lo, hi = (float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: a (low, high) pair of numbers, got {values!r}") from None
    if not (low <= lo <= hi <= high):
        raise ValueError(f"{name}: must satisfy {low} <= low <= high <= {high}, got ({lo}, {hi})")
    return lo, hi


def launch(rng: np.random.Generator, agent_sign: int, speed: tuple[float, float],
           spin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One ball: (pos m, vel m/s, spin rad/s) in world axes, towards the agent at the end of sign
    agent_sign (-1: A at x < 0, +1: B). speed: horizontal m/s range; spin: rad/s range, + topspin."""
    pos = np.array([-agent_sign * LAUNCH_X, rng.uniform(-LAUNCH_Y, LAUNCH_Y), LAUNCH_Z])
    aim = np.array([agent_sign * rng.uniform(*TARGET_X), rng.uniform(-TARGET_Y, TARGET_Y)])
    d = aim - pos[:2]
    dist = float(np.hypot(*d))
    v_h = rng.uniform(*speed)
    t = dist / v_h
    v_z = (equipment.BALL_RADIUS - LAUNCH_Z) / t + 0.5 * equipment.GRAVITY * t  # drag-free: down on the aim
    u = d / dist
    vel = np.array([v_h * u[0], v_h * u[1], v_z])
    # Topspin turns about z x u (the ball's top moving forwards), backspin the other way.
    spin_axis = np.array([-u[1], u[0], 0.0])
    return pos, vel, rng.uniform(*spin) * spin_axis


def lands_on(model, state, events, pos, vel, spin, agent_sign: int, max_ticks: int = 3000) -> bool:
    """Flown by the engine from (pos, vel, spin) in `state` (a scene with table, net and floor,
    the bats standing), is the ball's first contact the table on the agent's court?"""
    ball = state.ball[0]
    ball["pos"], ball["vel"], ball["spin"] = pos, vel, spin
    state.world[0]["ball_support"] = 0
    done = 0
    while done < max_ticks:
        ticks, n_events, _ = advance(model, state, max_ticks - done, None, events)
        done += ticks
        if n_events:
            first = events[0]
            return int(first["body"]) == Body.TABLE and float(first["pos"][0]) * agent_sign > 0
        if ticks == 0:
            return False
    return False
