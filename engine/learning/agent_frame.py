"""What a learner sees and does (the environments' version 1): the agent's own frame, bounded
scaled observations and symmetric normalised actions.

The agent's frame: its end is always at x < 0 and it plays towards +x. For the bat at x > 0 (B)
the world is turned half a turn about the vertical axis, (x, y, z) -> (-x, -y, z): a rotation,
not a mirror, so spin and the Magnus force keep their sense and A and B see the same game.

The observation vector (OBSERVATION_NAMES), every entry in [-1, 1]: positions over POS_SCALE,
velocities over VEL_SCALE, the ball's spin over SPIN_SCALE, a bat's angular velocity over
ANG_VEL_SCALE (each clipped); a bat's orientation as its face normal and its local x axis (the
rotation's first and third columns: continuous, where a quaternion's sign flips); the rally's
phase and who strikes next as one-hots; whether the agent serves; points and games over their
game and match lengths; the rally's strikes over MAX_SHOTS. No tick, no clock: nothing grows
without bound.

The action vector, every entry in [-1, 1] (values beyond are clipped; a wrong shape or a
non-finite value is a ValueError):
- hold: the pose to hold (x, y, z mapped onto HOLD_LOW..HOLD_HIGH in the agent's frame: its
  own half of the playing space) and the face normal (3, normalised; zero: towards the net);
- target: hold's six, then the velocity to reach the pose with (x TARGET_SPEED m/s) and when,
  (a + 1) / 2 * TARGET_MAX_S s after the observation (engine.play.bot.target);
- force: force and torque, each component times the arm's limit over sqrt(3), so that every
  vector is within the arm's limits (engine.play.ai.skill.SKILLS).
"""
from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from numba import njit

from engine.physics.bat import face_normal, rotate
from engine.play.bot import force, hold, target
from engine.play.match import OUT_OF_PLAY_DISTANCE
from engine.play.rules import Phase

POS_SCALE = OUT_OF_PLAY_DISTANCE  # m: a ball farther from the table's centre is out of play
VEL_SCALE = 40.0  # m/s: beyond the fastest recorded smash (~31 m/s)
SPIN_SCALE = 1000.0  # rad/s: beyond top players' ~150 rev/s (940 rad/s)
ANG_VEL_SCALE = 200.0  # rad/s: a bat's turn rate in a stroke stays well below
POINTS_SCALE = 11.0  # points in a game (ITTF 2.11)
GAMES_SCALE = 5.0  # games won in a best of 9, the longest match a scene allows
MAX_SHOTS = 20  # strikes in a rally counted before the entry saturates
HOLD_LOW = np.array([-3.0, -1.5, -0.2])  # m, agent frame: the pose an action can ask for, own half
HOLD_HIGH = np.array([-0.2, 1.5, 1.0])
TARGET_SPEED = 20.0  # m/s, the velocity entries' scale
TARGET_MAX_S = 1.0  # s, the latest a target pose can be asked for

_OVER, _WAITING_SERVE = int(Phase.OVER), int(Phase.WAITING_SERVE)
_TURN = np.array([-1.0, -1.0, 1.0])  # half a turn about z, as a per-axis sign
_X_AXIS = np.array([1.0, 0.0, 0.0])


def _observation_names() -> tuple[str, ...]:
    xyz = ("x", "y", "z")
    names = [f"ball.{q}.{a}" for q in ("pos", "vel", "spin") for a in xyz]
    names += [f"own.{q}.{a}" for q in ("pos", "vel", "normal", "x_axis", "ang_vel") for a in xyz]
    names += [f"other.{q}.{a}" for q in ("pos", "vel", "normal") for a in xyz]
    names += [f"phase.{p.name.lower()}" for p in Phase]
    names += ["to_strike.me", "to_strike.other", "to_strike.nobody", "serving", "points.me", "points.other",
              "games.me", "games.other", "shots"]
    return tuple(names)


OBSERVATION_NAMES = _observation_names()
ACTION_SIZES = {"hold": 6, "target": 10, "force": 6}


def observation_space() -> spaces.Box:
    """len(OBSERVATION_NAMES) entries, each in [-1, 1]."""
    n = len(OBSERVATION_NAMES)
    return spaces.Box(-np.ones(n), np.ones(n), dtype=np.float64)


def action_space(action_type: str) -> spaces.Box:
    """ACTION_SIZES[action_type] entries, each in [-1, 1]."""
    n = ACTION_SIZES[action_type]
    return spaces.Box(-np.ones(n), np.ones(n), dtype=np.float64)


def _quat_axes(q) -> tuple[np.ndarray, np.ndarray]:
    """(local z = face normal, local x) of the unit quaternion (w, x, y, z) in world axes."""
    normal, x_axis = np.empty(3), np.empty(3)
    face_normal(q, normal)
    rotate(q, _X_AXIS, x_axis)
    return normal, x_axis


def observe(record, player: int, out: np.ndarray) -> np.ndarray:
    """The observation vector of the bot observation `record` (engine.physics.dtypes.OBSERVATION_DTYPE, the
    seat of `player`) into `out` (len(OBSERVATION_NAMES),), in the agent's frame."""
    turn = _TURN if player == 1 else np.ones(3)
    ball, own, other = record["ball"], record["own"], record["other"]
    parts = [ball["pos"] * turn / POS_SCALE, ball["vel"] * turn / VEL_SCALE, ball["spin"] * turn / SPIN_SCALE]
    own_normal, own_x = _quat_axes(own["quat"])
    parts += [own["pos"] * turn / POS_SCALE, own["vel"] * turn / VEL_SCALE, own_normal * turn, own_x * turn,
              own["ang_vel"] * turn / ANG_VEL_SCALE]
    parts += [other["pos"] * turn / POS_SCALE, other["vel"] * turn / VEL_SCALE, _quat_axes(other["quat"])[0] * turn]
    phase = np.zeros(len(Phase))
    phase[int(record["phase"])] = 1.0
    to_strike = int(record["to_strike"])
    strike = np.array([to_strike == player, to_strike == 1 - player, to_strike < 0], dtype=np.float64)
    score, games = record["score"], record["games_won"]
    rest = [float(int(record["server"]) == player), score[player] / POINTS_SCALE, score[1 - player] / POINTS_SCALE,
            games[player] / GAMES_SCALE, games[1 - player] / GAMES_SCALE, min(int(record["shots"]), MAX_SHOTS) / MAX_SHOTS]
    out[:] = np.concatenate(parts + [phase, strike, np.array(rest)])
    np.clip(out, -1.0, 1.0, out=out)
    return out


def checked_action(action, action_type: str) -> np.ndarray:
    """The action vector as float64, clipped to [-1, 1]; ValueError naming the expected shape, or
    the entries that are not finite."""
    a = np.asarray(action, dtype=np.float64)
    shape = (ACTION_SIZES[action_type],)
    if a.shape != shape:
        raise ValueError(f"action: expected shape {shape} (a {action_type} action, each entry in [-1, 1]), "
                         f"got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"action: entries {np.flatnonzero(~np.isfinite(a)).tolist()} are not finite: {a.tolist()}")
    return np.clip(a, -1.0, 1.0)


def action_record(a: np.ndarray, action_type: str, player: int, max_force: float, max_torque: float, view,
                  out: np.ndarray, new_path: bool = True) -> np.ndarray:
    """The checked action vector `a` (checked_action) as the seat's ACTION_DTYPE record `out`, in
    world axes. view: the observation record the agent answers (a target's clock); new_path: a
    target action plans its path anew (False: the path planned when it was first given stays)."""
    turn = _TURN if player == 1 else np.ones(3)
    if action_type == "force":
        scale = 1.0 / math.sqrt(3.0)
        return force(a[0:3] * max_force * scale * turn, a[3:6] * max_torque * scale * turn, out)
    pos = (HOLD_LOW + (a[0:3] + 1.0) / 2.0 * (HOLD_HIGH - HOLD_LOW)) * turn
    normal = a[3:6] * turn if np.linalg.norm(a[3:6]) > 1e-9 else np.array([1.0, 0.0, 0.0]) * turn
    if action_type == "hold":
        return hold(pos, normal, out)
    if new_path:
        target(view, pos, normal, vel=a[6:9] * TARGET_SPEED * turn,
               at=float(view["time"]) + (a[9] + 1.0) / 2.0 * TARGET_MAX_S, out=out)
    return out


@njit(cache=True, _nrt=False)
def next_striker(r):
    """engine.play.rules.next_striker of the rally record (RALLY_DTYPE), compiled."""
    phase = r['phase']
    if phase == _OVER:
        return -1
    if phase == _WAITING_SERVE:
        return r['server']
    return 1 - r['striker']


@njit(cache=True, _nrt=False)
def hold_plans(actions, player, out):
    """The checked hold actions (N, 6) in [-1, 1] as action_record and engine.play.bot.hold make them, compiled:
    out[k] = the hold pose (3, m, world axes) and the unit face normal (3)."""
    turn = -1.0 if player == 1 else 1.0
    for k in range(actions.shape[0]):
        a = actions[k]
        for i in range(3):
            sign = 1.0 if i == 2 else turn
            out[k, i] = (HOLD_LOW[i] + (a[i] + 1.0) / 2.0 * (HOLD_HIGH[i] - HOLD_LOW[i])) * sign
        n0, n1, n2 = a[3] * turn, a[4] * turn, a[5]
        if math.sqrt(a[3] * a[3] + a[4] * a[4] + a[5] * a[5]) <= 1e-9:
            n0, n1, n2 = 1.0 * turn, 0.0 * turn, 0.0
        norm = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        out[k, 3], out[k, 4], out[k, 5] = n0 / norm, n1 / norm, n2 / norm


@njit(cache=True, _nrt=False)
def observe_state(ball, bats, r, player, axis, out):
    """observe of the state, compiled: ball (9,) and bats (2, BAT_FLOATS) flat, the rally record r,
    the agent at `player`, into out (len(OBSERVATION_NAMES),); axis: (3, 3) scratch whose row 2 is
    the bat's local x axis (1, 0, 0)."""
    turn = -1.0 if player == 1 else 1.0
    j = 0
    for scale, at in ((POS_SCALE, 0), (VEL_SCALE, 3), (SPIN_SCALE, 6)):
        out[j] = ball[at] * turn / scale
        out[j + 1] = ball[at + 1] * turn / scale
        out[j + 2] = ball[at + 2] * 1.0 / scale
        j += 3
    for who in (player, 1 - player):
        bat = bats[who]
        for scale, at in ((POS_SCALE, 0), (VEL_SCALE, 7)):
            out[j] = bat[at] * turn / scale
            out[j + 1] = bat[at + 1] * turn / scale
            out[j + 2] = bat[at + 2] * 1.0 / scale
            j += 3
        face_normal(bat[3:7], axis[0])
        rotate(bat[3:7], axis[2], axis[1])
        out[j], out[j + 1], out[j + 2] = axis[0, 0] * turn, axis[0, 1] * turn, axis[0, 2] * 1.0
        j += 3
        if who == player:
            out[j], out[j + 1], out[j + 2] = axis[1, 0] * turn, axis[1, 1] * turn, axis[1, 2] * 1.0
            out[j + 3] = bat[10] * turn / ANG_VEL_SCALE
            out[j + 4] = bat[11] * turn / ANG_VEL_SCALE
            out[j + 5] = bat[12] * 1.0 / ANG_VEL_SCALE
            j += 6
    for p in range(_OVER + 1):
        out[j + p] = 1.0 if r['phase'] == p else 0.0
    j += _OVER + 1
    to_strike = next_striker(r)
    out[j] = 1.0 if to_strike == player else 0.0
    out[j + 1] = 1.0 if to_strike == 1 - player else 0.0
    out[j + 2] = 1.0 if to_strike < 0 else 0.0
    out[j + 3] = 1.0 if r['server'] == player else 0.0
    out[j + 4] = r['score'][player] / POINTS_SCALE
    out[j + 5] = r['score'][1 - player] / POINTS_SCALE
    out[j + 6] = r['games_won'][player] / GAMES_SCALE
    out[j + 7] = r['games_won'][1 - player] / GAMES_SCALE
    out[j + 8] = min(r['shots'], MAX_SHOTS) / MAX_SHOTS
    for i in range(out.shape[0]):
        out[i] = min(max(out[i], -1.0), 1.0)
