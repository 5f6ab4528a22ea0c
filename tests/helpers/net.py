"""Net states for the net kernel's tests: the built shape perturbed, and the net's energy."""
import numpy as np


def perturbed(topo, seed=0, pos_scale=1e-3, vel_scale=0.1):
    """(knot_pos, knot_vel): the built shape with random offsets and velocities on free knots."""
    rng = np.random.default_rng(seed)
    free = (topo.knot_inv_mass > 0)[:, None]
    pos = topo.knot_pos + free * rng.normal(0.0, pos_scale, topo.knot_pos.shape)
    vel = free * rng.normal(0.0, vel_scale, topo.knot_pos.shape)
    return pos, vel


def net_energy(topo, knot_pos, knot_vel, gravity):
    """J: kinetic + spring + gravitational energy of the free knots (fixed knots do not move)."""
    free = topo.knot_inv_mass > 0
    kinetic = 0.5 * np.sum(topo.knot_mass[free] * np.sum(knot_vel[free] ** 2, axis=1))
    d = knot_pos[topo.spring_ij[:, 1]] - knot_pos[topo.spring_ij[:, 0]]
    stretch = np.linalg.norm(d, axis=1) - topo.spring_rest
    elastic = 0.5 * np.sum(topo.spring_k * stretch**2)
    potential = gravity * np.sum(topo.knot_mass[free] * knot_pos[free, 2])
    return kinetic + elastic + potential
