"""Ball impacts: normal restitution and Coulomb friction with spin for a thin spherical shell.

Model: Nakashima, Ogawa, Kobayashi, Hayakawa, "Modeling of rebound phenomenon of a rigid ball
with friction and elastic effects", Proc. ACC 2010, pp. 1410-1415. The normal impulse is
J_n = -(1 + e) m v_n. The friction impulse opposes the contact point's slip u_t and is the
smaller of the Coulomb limit mu J_n (the ball slides through the impact) and the impulse that
stops the slip, |u_t| / (1/m + r^2/I) = 2/5 m |u_t| for I = 2/3 m r^2 (the ball leaves rolling).
Topspin thus kicks the ball forward and backspin checks it; friction never adds energy in the
frame of the body that is hit.
"""
from numba import njit

from engine.physics.forces import ball_accel


@njit(inline="always", cache=True, _nrt=False)
def impact(vel, spin, normal, body_vel, radius, mass, inertia, restitution, friction, out_vel, out_spin):
    """Velocity and spin after one impact.

    Args:
        vel: (3,) m/s and spin: (3,) rad/s of the ball before the impact.
        normal: (3,) unit, from the body towards the ball centre.
        body_vel: (3,) m/s, velocity of the body's surface point under the ball.
        radius: m. mass: kg. inertia: kg m^2 about a diameter.
        restitution: e in [0, 1]. friction: Coulomb mu >= 0.
        out_vel, out_spin: (3,) written; may alias vel and spin.

    Returns:
        The approach speed along the normal, m/s (positive when approaching).
    """
    rx = vel[0] - body_vel[0]
    ry = vel[1] - body_vel[1]
    rz = vel[2] - body_vel[2]
    v_n = rx * normal[0] + ry * normal[1] + rz * normal[2]
    if v_n >= 0.0:
        for i in range(3):
            out_vel[i] = vel[i]
            out_spin[i] = spin[i]
        return -v_n
    j_n = -(1.0 + restitution) * mass * v_n
    # Contact point at -r n: its velocity relative to the body is rel + spin x (-r n).
    ux = rx - radius * (spin[1] * normal[2] - spin[2] * normal[1])
    uy = ry - radius * (spin[2] * normal[0] - spin[0] * normal[2])
    uz = rz - radius * (spin[0] * normal[1] - spin[1] * normal[0])
    u_n = ux * normal[0] + uy * normal[1] + uz * normal[2]
    ux -= u_n * normal[0]
    uy -= u_n * normal[1]
    uz -= u_n * normal[2]
    slip = (ux * ux + uy * uy + uz * uz) ** 0.5
    jx = jy = jz = 0.0
    if slip > 0.0:
        j_stop = slip / (1.0 / mass + radius * radius / inertia)
        j_t = min(friction * j_n, j_stop)
        jx = -j_t * ux / slip
        jy = -j_t * uy / slip
        jz = -j_t * uz / slip
    # Angular impulse of the friction at the contact point: (-r n) x J_t.
    ax = -radius * (normal[1] * jz - normal[2] * jy)
    ay = -radius * (normal[2] * jx - normal[0] * jz)
    az = -radius * (normal[0] * jy - normal[1] * jx)
    out_vel[0] = vel[0] + (j_n * normal[0] + jx) / mass
    out_vel[1] = vel[1] + (j_n * normal[1] + jy) / mass
    out_vel[2] = vel[2] + (j_n * normal[2] + jz) / mass
    out_spin[0] = spin[0] + ax / inertia
    out_spin[1] = spin[1] + ay / inertia
    out_spin[2] = spin[2] + az / inertia
    return -v_n


@njit(cache=True, _nrt=False)
def supported_advance(y, h, surface_z, gravity, drag_k, magnus_k, radius, mass, inertia, friction, work, out):
    """Advance a ball resting or rolling on a horizontal surface by h.

    Resting contact is non-smooth, so it is integrated as a constraint with impulses (Catto,
    "Iterative dynamics with temporal coherence", GDC 2005): the normal force cancels the pull
    into the surface, the horizontal forces act for h, then one friction impulse, at most mu N h,
    removes as much of the contact point's slip as it can (rolling once it is gone: for a shell
    the friction is then 2/5 of the horizontal force). Semi-implicit Euler, first order; the
    ball's height stays exactly on the surface, so it cannot drift into the table.

    Args:
        y: (9,) pos, vel, spin. h: s. surface_z: m, height of the surface.
        gravity, drag_k, magnus_k: effect parameters or None (engine/physics/forces.py).
        radius: m. mass: kg. inertia: kg m^2. friction: Coulomb mu.
        work: (>=1, 9) scratch. out: (9,) written; may not alias y.
    """
    acc = work[0]
    ball_accel(y[3:6], y[6:9], gravity, drag_k, magnus_k, acc[0:3])
    normal_force = mass * max(-acc[2], 0.0)
    vx = y[3] + h * acc[0]
    vy = y[4] + h * acc[1]
    wx, wy, wz = y[6], y[7], y[8]
    # Slip of the contact point (at -r z): v + w x (-r z) = (vx - r wy, vy + r wx, 0).
    ux = vx - radius * wy
    uy = vy + radius * wx
    slip = (ux * ux + uy * uy) ** 0.5
    if slip > 0.0:
        j_stop = slip / (1.0 / mass + radius * radius / inertia)
        j_t = min(friction * normal_force * h, j_stop)
        jx = -j_t * ux / slip
        jy = -j_t * uy / slip
        vx += jx / mass
        vy += jy / mass
        # (-r z) x J = (r jy, -r jx, 0)
        wx += radius * jy / inertia
        wy -= radius * jx / inertia
    out[0] = y[0] + h * vx
    out[1] = y[1] + h * vy
    out[2] = surface_z + radius
    out[3] = vx
    out[4] = vy
    out[5] = 0.0
    out[6] = wx
    out[7] = wy
    out[8] = wz
