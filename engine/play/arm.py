"""The arm: the PD law that drives a bat along a planned path or to a pose, and the idle arm's brake."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.physics.dtypes import ACTION_DTYPE, ARM_SEGMENTS, BAT_DTYPE

# One segment of a planned path, a cubic Hermite curve of the bat centre (engine.play.ai.Segment), as
# SEG_WIDTH floats at these offsets: t0, t1 s; p0, v0 m, m/s at t0; p1, v1 at t1.
SEG_T0, SEG_T1, SEG_P0, SEG_V0, SEG_P1, SEG_V1 = 0, 1, 2, 5, 8, 11
SEG_WIDTH = ACTION_DTYPE["segments"].shape[1]  # 14: a player's arm target carries the same rows

# The bat's fields in a BAT_DTYPE record seen as float64 (offsets in numbers).
BAT_POS, BAT_QUAT, BAT_VEL, BAT_ANG_VEL = (BAT_DTYPE.fields[name][1] // 8 for name in ("pos", "quat", "vel", "ang_vel"))
BAT_FLOATS = BAT_DTYPE.itemsize // 8
# What bat_control tracks, in one float64 array (engine.play.ai.BatAI._ctl), at these offsets: the arm
# (mass kg; inertia kg m^2 about a diameter, the face turns about one; kp, kd: (rad/s)^2 and
# rad/s gains of the position loop; k_angle, d_angle: of the face; its limits max_force N,
# max_torque N m, max_speed m/s), the pose to hold without a path (m) and the face normal to
# turn to (unit), the number of segments of the path, what the arm does (CTL_KIND: ARM_TARGET
# tracks the path or holds the pose, ARM_FORCE applies the raw force and torque at CTL_FORCE,
# N and N m, ARM_BRAKE brakes the bat), then the path: up to MAX_SEGMENTS segments.
(CTL_MASS, CTL_INERTIA, CTL_KP, CTL_KD, CTL_K_ANGLE, CTL_D_ANGLE, CTL_MAX_FORCE, CTL_MAX_TORQUE,
 CTL_MAX_SPEED) = range(9)
CTL_HOLD, CTL_NORMAL, CTL_N_SEGMENTS, CTL_KIND, CTL_FORCE, CTL_SEGMENTS = 9, 12, 15, 16, 17, 23
ARM_TARGET, ARM_FORCE, ARM_BRAKE = 0, 1, 2  # engine.play.bot's ACTION_TARGET and ACTION_FORCE, and the idle arm
MAX_SEGMENTS = ARM_SEGMENTS  # backswing, swing, follow-through
CTL_SIZE = CTL_SEGMENTS + MAX_SEGMENTS * SEG_WIDTH


@njit(cache=True, _nrt=False)
def bat_control(now, bat, ctl, out):
    """Force and torque on a bat tracking a planned path, by PD control with feed-forward.

    Args:
        now: s.
        bat: (BAT_FLOATS,) the bat's BAT_DTYPE record as float64: pos m, quat, vel m/s, ang_vel rad/s
            at BAT_POS, BAT_QUAT, BAT_VEL, BAT_ANG_VEL.
        ctl: (CTL_SIZE,) at CTL_*: the arm, the hold pose, the face normal to turn to, and the
            path: cubic Hermite segments (t0, t1, p0, v0, p1, v1) in time order; with none left
            (no segments, or now past the last) the bat holds the hold pose.
        out: (6,) written: force N, torque N m.
    """
    pos, vel = bat[BAT_POS:BAT_POS + 3], bat[BAT_VEL:BAT_VEL + 3]
    quat, ang_vel = bat[BAT_QUAT:BAT_QUAT + 4], bat[BAT_ANG_VEL:BAT_ANG_VEL + 3]
    mass, inertia, kp, kd = ctl[CTL_MASS], ctl[CTL_INERTIA], ctl[CTL_KP], ctl[CTL_KD]
    k_angle, d_angle = ctl[CTL_K_ANGLE], ctl[CTL_D_ANGLE]
    max_force, max_torque, max_speed = ctl[CTL_MAX_FORCE], ctl[CTL_MAX_TORQUE], ctl[CTL_MAX_SPEED]
    hold_pos, normal_ref = ctl[CTL_HOLD:CTL_HOLD + 3], ctl[CTL_NORMAL:CTL_NORMAL + 3]
    n_segments = int(ctl[CTL_N_SEGMENTS])
    k = 0
    while k < n_segments and now > ctl[CTL_SEGMENTS + k * SEG_WIDTH + SEG_T1]:
        k += 1
    on_path = k < n_segments
    seg = ctl[CTL_SEGMENTS + k * SEG_WIDTH:CTL_SEGMENTS + (k + 1) * SEG_WIDTH]
    T = h00 = h10 = h01 = h11 = d00 = d10 = d01 = d11 = a00 = a10 = a01 = a11 = 0.0
    inside = False
    if on_path:
        T = seg[SEG_T1] - seg[SEG_T0]
        s = min(max((now - seg[SEG_T0]) / T, 0.0), 1.0)
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
        a00, a10, a01, a11 = 12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2
        inside = 0.0 < s < 1.0
    speed = math.sqrt(vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2)
    norm = 0.0
    for i in range(3):
        # the reference position, velocity and acceleration along axis i: the segment's cubic
        # Hermite curve, or the hold pose at rest (scalars: this kernel allocates nothing)
        p_ref, v_ref, a_ref = hold_pos[i], 0.0, 0.0
        if on_path:
            p0, p1 = seg[SEG_P0 + i], seg[SEG_P1 + i]
            m0, m1 = seg[SEG_V0 + i] * T, seg[SEG_V1 + i] * T
            p_ref = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
            v_ref = (d00 * p0 + d10 * m0 + d01 * p1 + d11 * m1) / T
            a_ref = (a00 * p0 + a10 * m0 + a01 * p1 + a11 * m1) / (T * T) if inside else 0.0
        if speed > max_speed:  # the arm cannot go faster: brake
            out[i] = -mass * kd * vel[i]
        else:
            out[i] = mass * (a_ref + kp * (p_ref - pos[i]) + kd * (v_ref - vel[i]))
        norm += out[i] * out[i]
    norm = math.sqrt(norm)
    if norm > max_force:
        for i in range(3):
            out[i] *= max_force / norm
    # Face: rotate the current normal (face_normal's, as scalars) onto normal_ref about their
    # common perpendicular.
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    n0, n1, n2 = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)
    ax = n1 * normal_ref[2] - n2 * normal_ref[1]
    ay = n2 * normal_ref[0] - n0 * normal_ref[2]
    az = n0 * normal_ref[1] - n1 * normal_ref[0]
    sin_a = math.sqrt(ax * ax + ay * ay + az * az)
    cos_a = n0 * normal_ref[0] + n1 * normal_ref[1] + n2 * normal_ref[2]
    scale = math.atan2(sin_a, cos_a) / sin_a if sin_a > 1e-12 else 0.0
    rot = (ax * scale, ay * scale, az * scale)
    norm = 0.0
    for i in range(3):
        out[3 + i] = inertia * (k_angle * rot[i] - d_angle * ang_vel[i])
        norm += out[3 + i] ** 2
    norm = math.sqrt(norm)
    if norm > max_torque:
        for i in range(3):
            out[3 + i] *= max_torque / norm


@njit(cache=True, _nrt=False)
def control_bats(now, bats, ctl, players, out):
    """Every controlled bat's force and torque now, from its current state and its ctl row, in one
    call: bat_control for ARM_TARGET, the row's raw force for ARM_FORCE, _brake for ARM_BRAKE.

    Args:
        now: s. bats: (n_bats, BAT_FLOATS) every bat's record as float64. ctl: (n, CTL_SIZE) what
            each controlled bat's arm does. players: (n,) int64, the bat each ctl row drives.
        out: (n_bats, 6) written at the rows of players: force N, torque N m.
    """
    for k in range(players.shape[0]):
        kind = int(ctl[k, CTL_KIND])
        row = out[players[k]]
        if kind == ARM_TARGET:
            bat_control(now, bats[players[k]], ctl[k], row)
        elif kind == ARM_FORCE:
            for i in range(6):
                row[i] = ctl[k, CTL_FORCE + i]
        else:
            _brake(ctl[k, CTL_MASS], bats[players[k], BAT_VEL:BAT_VEL + 3], row)


# An idle arm (its input expired, its player's decision failed, or none has been applied yet)
# stops its bat instead of letting it coast off (a coasting bat leaves the wire's +-8 m and no
# snapshot can be sent any more): force = -mass * BRAKE_PER_S * bat velocity, at most
# BRAKE_MAX_N, no torque, from the bat's velocity when the force is computed. The AI arm's own
# damping and weakest limit; below the clip a tick of dt takes BRAKE_PER_S * dt of the speed
# away (6 % at the bundled scenes' 1 ms).
BRAKE_PER_S = 60.0  # 1/s, engine.play.ai.BatAI.KD
BRAKE_MAX_N = 50.0  # N, the novice arm's max_force_n


@njit(cache=True, inline="always", _nrt=False)
def _brake(mass, vel, out):
    """brake_force inside control_bats: the same law, from the bat's velocity at the control tick."""
    norm = 0.0
    for i in range(3):
        out[i] = -mass * BRAKE_PER_S * vel[i]
        norm += out[i] * out[i]
    norm = math.sqrt(norm)
    if norm > BRAKE_MAX_N:
        for i in range(3):
            out[i] *= BRAKE_MAX_N / norm
    for i in range(3, 6):
        out[i] = 0.0


def brake_force(mass: float, vel, out: np.ndarray) -> np.ndarray:
    """out[0:6] := an idle arm's force (N) on a bat of `mass` kg moving at `vel` (m/s), no torque."""
    out[:] = 0.0
    out[0:3] = vel
    out[0:3] *= -mass * BRAKE_PER_S
    norm = float(np.sqrt(out[0:3] @ out[0:3]))
    if norm > BRAKE_MAX_N:
        out[0:3] *= BRAKE_MAX_N / norm
    return out
