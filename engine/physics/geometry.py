"""Bodies the ball can hit and their signed distance functions (SDF), in the world frame.

An SDF returns the distance from a point to the body's surface (negative inside) and writes the
unit normal at the closest surface point, pointing away from the body. The ball of radius r
touches a body where sdf(centre) = r. Box SDFs round edges and corners exactly as a sphere
swept over a box sees them, so the table's edges and corners need no special case.
"""
import enum
import math

import numpy as np
from numba import njit

from engine.physics import equipment


class Body(enum.IntEnum):
    """Ids of the bodies; 0 means none (as every id of the project: bats, players and slots too)."""

    NONE = 0
    TABLE = 1
    FLOOR = 2
    NET = 3  # the net, rigid slab or cloth
    POST = 4  # either net post
    BAT_A = 5
    BAT_B = 6


# Static boxes as rows (centre xyz, half extents xyz), built once from the equipment.
TABLE_BOX = np.array(
    [0.0, 0.0, -equipment.TABLE_THICKNESS / 2,
     equipment.TABLE_LENGTH / 2, equipment.TABLE_WIDTH / 2, equipment.TABLE_THICKNESS / 2]
)
FLOOR_Z = -equipment.TABLE_HEIGHT
NET_BOX = np.array(
    [0.0, 0.0, equipment.NET_HEIGHT / 2,
     equipment.NET_THICKNESS / 2, equipment.NET_HALF_WIDTH, equipment.NET_HEIGHT / 2]
)
# The posts clamp the net's ends: 2 cm square uprights from the table top to the net's top.
_POST_HALF = 0.01
POST_BOXES = np.array(
    [[0.0, side * (equipment.NET_HALF_WIDTH + _POST_HALF), equipment.NET_HEIGHT / 2,
      _POST_HALF, _POST_HALF, equipment.NET_HEIGHT / 2] for side in (-1.0, 1.0)]
)


@njit(inline="always", cache=True, _nrt=False)
def box_sdf(p, box, normal):
    """Signed distance from p (3,) to an axis-aligned box (6,): centre, half extents; m."""
    qx = abs(p[0] - box[0]) - box[3]
    qy = abs(p[1] - box[1]) - box[4]
    qz = abs(p[2] - box[2]) - box[5]
    ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
    outside = math.sqrt(ox * ox + oy * oy + oz * oz)
    if outside > 0.0:
        normal[0] = math.copysign(ox, p[0] - box[0]) / outside
        normal[1] = math.copysign(oy, p[1] - box[1]) / outside
        normal[2] = math.copysign(oz, p[2] - box[2]) / outside
        return outside
    # Inside: the nearest face is the one with the largest (least negative) q.
    normal[0] = 0.0
    normal[1] = 0.0
    normal[2] = 0.0
    if qx >= qy and qx >= qz:
        normal[0] = math.copysign(1.0, p[0] - box[0])
        return qx
    if qy >= qz:
        normal[1] = math.copysign(1.0, p[1] - box[1])
        return qy
    normal[2] = math.copysign(1.0, p[2] - box[2])
    return qz


@njit(inline="always", cache=True, _nrt=False)
def disc_sdf(p, centre, axis, radius, half_thickness, normal):
    """Signed distance from p to a disc of given radius and half thickness with a rounded rim, m.

    centre: (3,) m; axis: (3,) unit face normal. The rim is the flat disc inflated by the half
    thickness, which is how a 14 mm thick bat's edge looks to a ball.
    """
    dx = p[0] - centre[0]
    dy = p[1] - centre[1]
    dz = p[2] - centre[2]
    d_n = dx * axis[0] + dy * axis[1] + dz * axis[2]
    qx = dx - d_n * axis[0]
    qy = dy - d_n * axis[1]
    qz = dz - d_n * axis[2]
    rho = math.sqrt(qx * qx + qy * qy + qz * qz)
    if rho <= radius:
        sign = 1.0 if d_n >= 0.0 else -1.0
        normal[0] = sign * axis[0]
        normal[1] = sign * axis[1]
        normal[2] = sign * axis[2]
        return abs(d_n) - half_thickness
    # Nearest point of the flat disc is on its rim.
    s = radius / rho
    vx = dx - qx * s
    vy = dy - qy * s
    vz = dz - qz * s
    dist = math.sqrt(vx * vx + vy * vy + vz * vz)
    normal[0] = vx / dist
    normal[1] = vy / dist
    normal[2] = vz / dist
    return dist - half_thickness
