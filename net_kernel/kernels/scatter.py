"""The textbook knot step, a per-spring scatter loop: the baseline `pingpong profile-net` measures against.

Most mass-spring cloth codes start this way (NVIDIA Warp's eval_springs, for one, with atomic
adds on the GPU): one loop over springs computes each spring's force and adds it into both
knots' force accumulators, then one loop over knots integrates.
The scatter is a race under parallel threads, so it runs on one thread; its sums arrive in
spring order, not in the CSR slot order of step_knots, so its bits differ from step_knots'
(same model, same step). NetSim does not use it.
"""
import math

from numba import njit

from net_kernel.kernels.table import TABLE_Z


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_knots_scatter(knot_pos, knot_vel, knot_inv_mass, spring_ij, spring_rest, spring_k, spring_c, gravity, drag, h,
                       knot_force, out_pos, out_vel):
    """One semi-implicit Euler step of every knot by a per-spring scatter of forces, one thread.

    Args:
        knot_pos, knot_vel, knot_inv_mass, spring_ij, spring_rest, spring_k, spring_c, gravity,
            drag, h, out_pos, out_vel: as step_knots.
        knot_force: (n_knots, 3) N scratch, written: the springs' force on each knot.
    """
    knot_force[:] = 0.0
    for s in range(spring_ij.shape[0]):
        i = spring_ij[s, 0]
        j = spring_ij[s, 1]
        d0 = knot_pos[j, 0] - knot_pos[i, 0]
        d1 = knot_pos[j, 1] - knot_pos[i, 1]
        d2 = knot_pos[j, 2] - knot_pos[i, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        inv_len = 1.0 / length
        n0 = d0 * inv_len
        n1 = d1 * inv_len
        n2 = d2 * inv_len
        rate = ((knot_vel[j, 0] - knot_vel[i, 0]) * n0 + (knot_vel[j, 1] - knot_vel[i, 1]) * n1
                + (knot_vel[j, 2] - knot_vel[i, 2]) * n2)
        f = spring_k[s] * (length - spring_rest[s]) + spring_c[s] * rate
        knot_force[i, 0] += f * n0
        knot_force[i, 1] += f * n1
        knot_force[i, 2] += f * n2
        knot_force[j, 0] -= f * n0
        knot_force[j, 1] -= f * n1
        knot_force[j, 2] -= f * n2
    for i in range(knot_pos.shape[0]):
        w = knot_inv_mass[i]
        for c in range(3):
            if w == 0.0:
                out_vel[i, c] = knot_vel[i, c]
                out_pos[i, c] = knot_pos[i, c]
            else:
                g = gravity if c == 2 else 0.0
                nv = knot_vel[i, c] + h * (w * knot_force[i, c] - drag * knot_vel[i, c] - g)
                x = knot_pos[i, c] + h * nv
                if c == 2 and x < TABLE_Z:  # the playing surface (net_kernel/kernels/table.py)
                    x = TABLE_Z
                    nv = max(nv, 0.0)
                out_vel[i, c] = nv
                out_pos[i, c] = x
