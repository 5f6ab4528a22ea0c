"""Forces on the ball in flight, per unit mass: gravity, quadratic drag, Magnus lift.

Each effect's parameter is a float when the scene asks for the effect and None when it does
not. Numba compiles one specialisation per combination and prunes the `is not None` branches at
compile time, so an absent effect has no code in the compiled step (see tests/engine/test_forces.py).
"""
import math

from numba import njit

from engine.physics import equipment


def drag_factor(drag_coefficient: float, air_density: float = equipment.AIR_DENSITY,
                radius: float = equipment.BALL_RADIUS, mass: float = equipment.BALL_MASS) -> float:
    """k_drag, 1/m: a_drag = -k_drag |v| v from F = 1/2 rho C_D A |v| v."""
    area = math.pi * radius**2
    return 0.5 * air_density * drag_coefficient * area / mass


def magnus_factor(magnus_coefficient: float, air_density: float = equipment.AIR_DENSITY,
                  radius: float = equipment.BALL_RADIUS, mass: float = equipment.BALL_MASS) -> float:
    """k_magnus, dimensionless: a_magnus = k_magnus (omega x v) from F = 1/2 rho A r C_M (omega x v)."""
    area = math.pi * radius**2
    return 0.5 * air_density * area * radius * magnus_coefficient / mass


@njit(inline="always", cache=True, _nrt=False)
def ball_accel(vel, spin, gravity, drag_k, magnus_k, out):
    """Acceleration of the ball in flight.

    Args:
        vel: (3,) m/s. spin: (3,) rad/s.
        gravity: g, m/s^2, pulling along -z, or None. drag_k: 1/m, or None. magnus_k: or None.
        out: (3,) m/s^2, written.
    """
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if gravity is not None:
        out[2] -= gravity
    if drag_k is not None:
        speed = math.sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2])
        out[0] -= drag_k * speed * vel[0]
        out[1] -= drag_k * speed * vel[1]
        out[2] -= drag_k * speed * vel[2]
    if magnus_k is not None:
        out[0] += magnus_k * (spin[1] * vel[2] - spin[2] * vel[1])
        out[1] += magnus_k * (spin[2] * vel[0] - spin[0] * vel[2])
        out[2] += magnus_k * (spin[0] * vel[1] - spin[1] * vel[0])
