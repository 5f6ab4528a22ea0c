"""Bat dynamics: a rigid disc driven only by the force and torque inputs of its player or AI.

The player's arm holds the bat's weight, so gravity is not applied: the inputs are what the
arm adds beyond holding it. Inputs are held constant over a tick (zero-order hold), so a
higher-order integrator would buy nothing: semi-implicit Euler for the linear and angular
velocity, then the exact rotation by the tick's angular velocity (exponential map).
"""
import math

import numpy as np
from numba import njit

from engine.collision import BAT_ANG_VEL, BAT_AXIS0, BAT_AXIS1, BAT_POS0, BAT_POS1
from engine.dtypes import BAT_DTYPE


def _offset(field: str) -> int:
    return BAT_DTYPE.fields[field][1] // 8


# Offsets of the fields in a bat record viewed as float64 (engine.world writes inputs through them).
POS_AT, QUAT_AT, VEL_AT, ANG_VEL_AT, FORCE_AT, TORQUE_AT = (
    _offset(f) for f in ("pos", "quat", "vel", "ang_vel", "force", "torque")
)
BAT_WIDTH = BAT_DTYPE.itemsize // 8


def disc_inertia(mass: float, radius: float) -> np.ndarray:
    """Principal moments of a thin disc, kg m^2, bat frame (x, y in the face, z the face normal)."""
    return np.array([0.25 * mass * radius**2, 0.25 * mass * radius**2, 0.5 * mass * radius**2])


@njit(inline="always", cache=True)
def rotate(q, v, out):
    """out = q v q*, for a unit quaternion q = (w, x, y, z); out may alias v."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    # t = 2 (u x v); v' = v + w t + u x t
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    ox = v[0] + w * tx + (y * tz - z * ty)
    oy = v[1] + w * ty + (z * tx - x * tz)
    oz = v[2] + w * tz + (x * ty - y * tx)
    out[0], out[1], out[2] = ox, oy, oz


@njit(inline="always", cache=True)
def face_normal(q, out):
    """The bat's face normal in the world: its local z axis rotated by q."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0] = 2.0 * (x * z + w * y)
    out[1] = 2.0 * (y * z - w * x)
    out[2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True)
def bat_step(bats, h, mass, inertia, motion, tmp):
    """Advance every bat by h and record its motion over the tick for collision detection.

    Args:
        bats: (n_bats, BAT_WIDTH) float64 view of BAT_DTYPE records; updated in place.
        h: s. mass: (n_bats,) kg. inertia: (n_bats, 3) principal moments, kg m^2, bat frame.
        motion: (n_bats, collision.BAT_ROW) written: poses at the start and end, angular velocity.
        tmp: (3, 3) scratch.
    """
    w_body = tmp[1]
    alpha = tmp[2]
    for b in range(bats.shape[0]):
        if h == 0.0:
            # A zero step changes nothing, not even the quaternion's last bit by renormalising.
            face_normal(bats[b, QUAT_AT:QUAT_AT + 4], motion[b, BAT_AXIS0:BAT_AXIS0 + 3])
            for i in range(3):
                motion[b, BAT_POS0 + i] = bats[b, POS_AT + i]
                motion[b, BAT_POS1 + i] = bats[b, POS_AT + i]
                motion[b, BAT_AXIS1 + i] = motion[b, BAT_AXIS0 + i]
                motion[b, BAT_ANG_VEL + i] = bats[b, ANG_VEL_AT + i]
            continue
        bat = bats[b]
        q = bat[QUAT_AT:QUAT_AT + 4]
        for i in range(3):
            motion[b, BAT_POS0 + i] = bat[POS_AT + i]
        face_normal(q, motion[b, BAT_AXIS0:BAT_AXIS0 + 3])
        for i in range(3):
            bat[VEL_AT + i] += h * bat[FORCE_AT + i] / mass[b]
            bat[POS_AT + i] += h * bat[VEL_AT + i]
        # Euler's equations in the bat frame: I dw/dt = tau - w x (I w).
        _rotate_conj(q, bat[ANG_VEL_AT:ANG_VEL_AT + 3], w_body)
        _rotate_conj(q, bat[TORQUE_AT:TORQUE_AT + 3], alpha)
        inert = inertia[b]
        lx, ly, lz = inert[0] * w_body[0], inert[1] * w_body[1], inert[2] * w_body[2]
        alpha[0] = (alpha[0] - (w_body[1] * lz - w_body[2] * ly)) / inert[0]
        alpha[1] = (alpha[1] - (w_body[2] * lx - w_body[0] * lz)) / inert[1]
        alpha[2] = (alpha[2] - (w_body[0] * ly - w_body[1] * lx)) / inert[2]
        rotate(q, alpha, alpha)
        for i in range(3):
            bat[ANG_VEL_AT + i] += h * alpha[i]
        # Exact rotation by the (new) angular velocity over h, applied on the left (world frame).
        wx, wy, wz = bat[ANG_VEL_AT], bat[ANG_VEL_AT + 1], bat[ANG_VEL_AT + 2]
        rate = math.sqrt(wx * wx + wy * wy + wz * wz)
        if rate > 0.0:
            half = 0.5 * rate * h
            s = math.sin(half) / rate
            dw, dx, dy, dz = math.cos(half), s * wx, s * wy, s * wz
            w0, x0, y0, z0 = q[0], q[1], q[2], q[3]
            q[0] = dw * w0 - dx * x0 - dy * y0 - dz * z0
            q[1] = dw * x0 + dx * w0 + dy * z0 - dz * y0
            q[2] = dw * y0 - dx * z0 + dy * w0 + dz * x0
            q[3] = dw * z0 + dx * y0 - dy * x0 + dz * w0
            norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            for i in range(4):
                q[i] /= norm
        for i in range(3):
            motion[b, BAT_POS1 + i] = bat[POS_AT + i]
            motion[b, BAT_ANG_VEL + i] = bat[ANG_VEL_AT + i]
        face_normal(q, motion[b, BAT_AXIS1:BAT_AXIS1 + 3])


@njit(inline="always", cache=True)
def _rotate_conj(q, v, out):
    """out = q* v q: a world vector in the bat frame."""
    w, x, y, z = q[0], -q[1], -q[2], -q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)
