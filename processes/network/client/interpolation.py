"""A spectator's view of the server's snapshots: the state `delay_s` (100 ms) behind its present.

Between the two snapshots around that moment: positions by cubic Hermite interpolation on the
snapshots' own positions and velocities (exact for motion of constant acceleration, such as a
ball's flight without drag), orientations by spherical linear interpolation.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from processes.network.client.prediction import ServerClock

def hermite(t0: float, p0, v0, t1: float, p1, v1, t: float) -> np.ndarray:
    """Cubic Hermite position at time t between (p0, v0) at t0 and (p1, v1) at t1.

    p0, p1: (..., 3) m; v0, v1: m/s; times in s, t0 < t1. Exact for any cubic in time, so for
    constant acceleration; t outside [t0, t1] extrapolates the same cubic.
    """
    span = t1 - t0
    s = (t - t0) / span
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return (h00 * np.asarray(p0) + h10 * span * np.asarray(v0) + h01 * np.asarray(p1)
            + h11 * span * np.asarray(v1))


def slerp(q0, q1, s: float) -> np.ndarray:
    """Unit quaternion a fraction s of the way from q0 to q1 along the shorter arc, (w, x, y, z)."""
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    if float(q0 @ q1) < 0.0:
        q1 = -q1
    # the angle between them from atan2 of the chord and its complement: accurate also for the
    # tiny angles between two snapshots 10 ms apart (acos of a dot product near 1 is not)
    theta = 2.0 * math.atan2(float(np.linalg.norm(q1 - q0)), float(np.linalg.norm(q1 + q0)))
    if theta < 1e-12:
        return q0.copy()
    return (math.sin((1 - s) * theta) * q0 + math.sin(s * theta) * q1) / math.sin(theta)


class Interpolator:
    """A spectator's view: the state `delay_s` behind the server's estimated present.

    Args:
        dt: s, the physics tick (ticks to seconds). delay_s: how far behind the view runs; a
            snapshot lost or late within it costs nothing. capacity: snapshots kept.
    """

    def __init__(self, dt: float, delay_s: float = 0.1, capacity: int = 64):
        self.dt = dt
        self.delay_s = delay_s
        self.clock = ServerClock(dt)
        self._snapshots: deque = deque(maxlen=capacity)  # wire snapshot messages, by tick
        self.counts = {"samples": 0, "between": 0, "held_newest": 0, "held_oldest": 0, "late_dropped": 0,
                       "toss_steps": 0}

    def push(self, snapshot, arrival: float) -> None:
        """A snapshot that arrived at wall time `arrival` (s, time.monotonic)."""
        self.clock.observe(snapshot.tick, arrival)
        if self._snapshots and snapshot.tick <= self._snapshots[-1].tick:
            self.counts["late_dropped"] += 1  # older than one we have: nothing to add
            return
        self._snapshots.append(snapshot)

    def render_tick(self, wall: float) -> float | None:
        """The (fractional) tick shown at wall time `wall`."""
        now = self.clock.tick_at(wall)
        return None if now is None else now - self.delay_s / self.dt

    def sample(self, wall: float) -> dict | None:
        """The state shown at `wall`: tick (fractional), ball_pos, ball_vel, bat_pos (2, 3),
        bat_quat (2, 4), and the newest snapshot at or before it (`snapshot`, for the score)."""
        render = self.render_tick(wall)
        if render is None or not self._snapshots:
            return None
        return self.at(render)

    def at(self, render_tick: float) -> dict:
        """The state at a fractional tick: interpolated between the two snapshots around it,
        held at the oldest or newest snapshot outside their span."""
        self.counts["samples"] += 1
        snaps = self._snapshots
        if render_tick >= snaps[-1].tick:
            self.counts["held_newest"] += 1
            return _still(snaps[-1])
        if render_tick <= snaps[0].tick:
            self.counts["held_oldest"] += 1
            return _still(snaps[0])
        k = len(snaps) - 1
        while snaps[k - 1].tick > render_tick:
            k -= 1
        a, b = snaps[k - 1], snaps[k]
        if a["rally"] != b["rally"]:  # a toss between them: no motion joins the two, show the older
            self.counts["toss_steps"] += 1
            return _still(a)
        self.counts["between"] += 1
        t0, t1, t = a.tick * self.dt, b.tick * self.dt, render_tick * self.dt
        s = (render_tick - a.tick) / (b.tick - a.tick)
        ball_pos = hermite(t0, a["ball_pos"], a["ball_vel"], t1, b["ball_pos"], b["ball_vel"], t)
        span = t1 - t0
        ball_vel = ((6 * s**2 - 6 * s) * (a["ball_pos"] - b["ball_pos"]) / span
                    + (3 * s**2 - 4 * s + 1) * a["ball_vel"] + (3 * s**2 - 2 * s) * b["ball_vel"])
        bat_pos = hermite(t0, a["bat_pos"], a["bat_vel"], t1, b["bat_pos"], b["bat_vel"], t)
        bat_quat = np.array([slerp(a["bat_quat"][i], b["bat_quat"][i], s) for i in range(2)])
        return {"tick": render_tick, "ball_pos": ball_pos, "ball_vel": ball_vel, "bat_pos": bat_pos,
                "bat_quat": bat_quat, "snapshot": a}


def _still(snapshot) -> dict:
    return {"tick": float(snapshot.tick), "ball_pos": np.array(snapshot["ball_pos"]),
            "ball_vel": np.array(snapshot["ball_vel"]), "bat_pos": np.array(snapshot["bat_pos"]),
            "bat_quat": np.array(snapshot["bat_quat"]), "snapshot": snapshot}


__all__ = ["Interpolator", "hermite", "slerp"]
