"""Bat dynamics: a rigid disc driven only by the force and torque inputs of its player or AI.

The player's arm holds the bat's weight, so gravity is not applied: the inputs are what the
arm adds beyond holding it. Inputs are held constant over a tick (zero-order hold), so a
higher-order integrator would buy nothing: semi-implicit Euler for the linear and angular
velocity, then the exact rotation by the tick's angular velocity (exponential map).

An arm can move a bat only so fast and so far, so every tick ends with the bat inside those
limits (an input that asks for more gets the limit: the arm saturates, as the AI's own
controller does with its max_force and max_speed):

- speed at most BAT_MAX_SPEED, spin (|angular velocity|) at most BAT_MAX_SPIN;
- the centre inside the hall (HALL_LO..HALL_HI): a wall stops the bat (the velocity component
  into it becomes 0).

The spin limit also bounds a defect of the explicit gyroscopic term: a disc spinning about a
tilted axis (w_z != 0 in the bat frame) gains |w_xy| by a factor sqrt(1 + (w_z h)^2) every tick,
so without a bound a bat left spinning by a valid input (50 N m held 0.1 s is ~2e4 rad/s) grew
to overflow and NaN within half a second. The AI's bats stay far inside every limit (full
matches of seeds 0-3: at most 24.5 m/s, 30.2 rad/s, |x| <= 2.2 m, |y| <= 1.4 m, z <= 0.77 m),
so no limit ever acts in their matches, which are unchanged bit for bit.
"""
import math

import numpy as np
from numba import njit

from engine.physics.collision import BAT_ANG_VEL, BAT_AXIS0, BAT_AXIS1, BAT_POS0, BAT_POS1
from engine.physics.dtypes import BAT_DTYPE
from engine.physics.geometry import FLOOR_Z

# m/s: 1.4x the AI's fastest stroke (24.5 m/s) and as fast as a bat may go for
# the ball it strikes to stay within the wire's 100 m/s (processes.network.wire MAX_SPEED_MS): a bat
# at v returns a ball arriving at u at about (1 + e) v + e u, e = 0.85 (equipment.BAT_RESTITUTION),
# so 35 m/s against a 30 m/s smash gives 90 m/s.
BAT_MAX_SPEED = 35.0
# rad/s: the fastest human joint rotation measured is the shoulder's internal rotation in
# baseball pitching, about 7000 deg/s = 120 rad/s (Fleisig et al. 1995, "Kinetics of baseball
# pitching", Am J Sports Med 23(2)); a bat's spin sums the rates of trunk, shoulder, elbow and
# wrist, bounded here by 200 rad/s (~11,500 deg/s, 6.6x the AI's fastest 30.2 rad/s), well
# within the wire's 1000 rad/s (MAX_BAT_ANG_VEL_RADS).
BAT_MAX_SPIN = 200.0
# m, world frame, the bat's centre: the hall is the ITTF's playing space for international
# competitions ("rectangular and not less than 14m long, 7m wide and 5m high", ITTF Handbook,
# Regulations for International Competitions), centred on the table, from the floor up; inside
# the wire's +-8 m (MAX_POS_M).
HALL_LO_X, HALL_LO_Y, HALL_LO_Z = -7.0, -3.5, FLOOR_Z
HALL_HI_X, HALL_HI_Y, HALL_HI_Z = 7.0, 3.5, FLOOR_Z + 5.0


def _offset(field: str) -> int:
    return BAT_DTYPE.fields[field][1] // 8


# Offsets of the fields in a bat record viewed as float64 (engine.physics.world writes inputs through them).
POS_AT, QUAT_AT, VEL_AT, ANG_VEL_AT, FORCE_AT, TORQUE_AT = (
    _offset(f) for f in ("pos", "quat", "vel", "ang_vel", "force", "torque")
)
BAT_WIDTH = BAT_DTYPE.itemsize // 8


def disc_inertia(mass: float, radius: float) -> np.ndarray:
    """Principal moments of a thin disc, kg m^2, bat frame (x, y in the face, z the face normal)."""
    return np.array([0.25 * mass * radius**2, 0.25 * mass * radius**2, 0.5 * mass * radius**2])


@njit(inline="always", cache=True, _nrt=False)
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


@njit(inline="always", cache=True, _nrt=False)
def face_normal(q, out):
    """The bat's face normal in the world: its local z axis rotated by q."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0] = 2.0 * (x * z + w * y)
    out[1] = 2.0 * (y * z - w * x)
    out[2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True, _nrt=False)
def bat_step(bats, h, mass, inertia, motion, tmp):
    """Advance every bat by h and record its motion over the tick for collision detection.

    Args:
        bats: (n_bats, BAT_WIDTH) float64 view of BAT_DTYPE records; updated in place.
        h: s. mass: (n_bats,) kg. inertia: (n_bats, 3) principal moments, kg m^2, bat frame.
        motion: (n_bats, collision.BAT_ROW) written: poses at the start and end, angular velocity.
        tmp: (3, 3) scratch.

    Each bat ends the tick within the arm's limits (BAT_MAX_SPEED, BAT_MAX_SPIN, the hall).
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
        _at_most(bat, VEL_AT, BAT_MAX_SPEED)
        for i in range(3):
            bat[POS_AT + i] += h * bat[VEL_AT + i]
        _in_hall(bat, 0, HALL_LO_X, HALL_HI_X)
        _in_hall(bat, 1, HALL_LO_Y, HALL_HI_Y)
        _in_hall(bat, 2, HALL_LO_Z, HALL_HI_Z)
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
        _at_most(bat, ANG_VEL_AT, BAT_MAX_SPIN)
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


@njit(inline="always", cache=True, _nrt=False)
def _at_most(bat, at, limit):
    """Scale the 3-vector bat[at:at + 3] down to norm `limit` if it is longer (the arm's limit).

    Within the limit nothing is written (the same bits). Beyond it, a vector with a component
    beyond the limit is first scaled by that component, so its norm cannot overflow (a huge
    finite force); a non-finite vector stays non-finite, for the engine's check to name.
    """
    x, y, z = bat[at], bat[at + 1], bat[at + 2]
    if x * x + y * y + z * z > limit * limit:
        big = max(abs(x), abs(y), abs(z))
        if big > limit:
            # (an inf component gives nan here: left for the engine's check to name)
            x, y, z = x / big * limit, y / big * limit, z / big * limit
        norm = math.sqrt(x * x + y * y + z * z)
        bat[at], bat[at + 1], bat[at + 2] = x / norm * limit, y / norm * limit, z / norm * limit


@njit(inline="always", cache=True, _nrt=False)
def _in_hall(bat, i, low, high):
    """Keep the bat's centre inside the hall along axis i: a wall stops it (no bounce)."""
    p = bat[POS_AT + i]
    if p < low:
        bat[POS_AT + i] = low
        if bat[VEL_AT + i] < 0.0:
            bat[VEL_AT + i] = 0.0
    elif p > high:
        bat[POS_AT + i] = high
        if bat[VEL_AT + i] > 0.0:
            bat[VEL_AT + i] = 0.0


@njit(inline="always", cache=True, _nrt=False)
def _rotate_conj(q, v, out):
    """out = q* v q: a world vector in the bat frame."""
    w, x, y, z = q[0], -q[1], -q[2], -q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)
