"""The net's linear tail in closed form: energy, modal coordinates, the state at any tick, sleep.

net_kernel/modes.py derives the modes; these kernels use them. Symbols: n_out out-of-plane
modes, each with tick eigenvalue mu = exp(log_r + i theta) and eigenvector (1, e) on
(q, q'), its state after n ticks q(n) = 2 Re(c mu^n e^(i phi(n))), q'(n) = 2 Re(c e' mu^n e^(i phi(n))),
where the amplitude correction (modes.py) turns the angle by delta = sum_k out_detune[k, m] |c_k|^2
more a tick at the switch, decaying with the amplitudes squared: delta |mu|^(2k) at tick k, so
phi(n) = delta (1 - |mu|^(2n)) / (1 - |mu|^2), and e' is e with its imaginary part (the
frequency's) scaled by 1 + delta |mu|^(2n) / rate (rate the mode's angle a tick); 2K in-plane
eigenvalues mu_k with coefficients w_k, the in-plane state u_yz(n) = Re(P (w mu^n)),
v_yz(n) = Re(V (w mu^n)). Shapes are stored mode-major ((modes, dofs), C order) so each
mode adds a contiguous row. Serial loops in a fixed order, fastmath off: the same bits in every
process. No kernel allocates.
"""
import math

from numba import njit

from net_kernel.kernels.grid import FREE_AWAKE, step_grid_free
from net_kernel.kernels.grid32 import step_grid32_free


@njit(cache=True, fastmath=False, _nrt=False)
def potential_energy(knot_pos, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity):
    """J: sum of 0.5 k (|L| - L_rest)^2 over the springs plus m g z over the free knots.

    knot_pos: (n_knots, 3) m (any strides). Serial, in spring then knot order.
    """
    e = 0.0
    for s in range(spring_ij.shape[0]):
        i, j = spring_ij[s, 0], spring_ij[s, 1]
        d0 = knot_pos[j, 0] - knot_pos[i, 0]
        d1 = knot_pos[j, 1] - knot_pos[i, 1]
        d2 = knot_pos[j, 2] - knot_pos[i, 2]
        stretch = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - spring_rest[s]
        e += 0.5 * spring_k[s] * stretch * stretch
    for i in range(knot_pos.shape[0]):
        if knot_inv_mass[i] != 0.0:
            e += knot_mass[i] * gravity * knot_pos[i, 2]
    return e


@njit(cache=True, fastmath=False, _nrt=False)
def motion_energy(knot_pos, knot_vel, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity,
                  rest_energy, limit):
    """J: kinetic energy plus potential energy above `rest_energy`, the energy of the net's motion.

    The kinetic part is summed first: when it alone exceeds `limit` (J) the potential part is
    not computed and the kinetic part is returned (the caller asks "is it below limit?").
    """
    kinetic = 0.0
    for i in range(knot_pos.shape[0]):
        if knot_inv_mass[i] != 0.0:
            kinetic += 0.5 * knot_mass[i] * (knot_vel[i, 0] * knot_vel[i, 0] + knot_vel[i, 1] * knot_vel[i, 1]
                                             + knot_vel[i, 2] * knot_vel[i, 2])
    if kinetic > limit:
        return kinetic
    return kinetic + potential_energy(knot_pos, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k,
                                      gravity) - rest_energy


@njit(inline="always")
def _add_rows(acc_a, acc_b, rows, w_a, w_b):
    """acc_a[j] += sum_i rows[i, j] w_a[i] and acc_b[j] += sum_i rows[i, j] w_b[i], i in order,
    four rows a pass over the accumulators: each sum adds its terms in the order a row at a time
    would (the same bits), for a quarter of the accumulators' loads and stores; every row is read
    once for both."""
    n_rows, n = rows.shape[0], acc_a.shape[0]
    i = 0
    while i + 4 <= n_rows:
        r0, r1, r2, r3 = rows[i], rows[i + 1], rows[i + 2], rows[i + 3]
        a0, a1, a2, a3 = w_a[i], w_a[i + 1], w_a[i + 2], w_a[i + 3]
        b0, b1, b2, b3 = w_b[i], w_b[i + 1], w_b[i + 2], w_b[i + 3]
        for j in range(n):
            acc_a[j] = (((acc_a[j] + r0[j] * a0) + r1[j] * a1) + r2[j] * a2) + r3[j] * a3
            acc_b[j] = (((acc_b[j] + r0[j] * b0) + r1[j] * b1) + r2[j] * b2) + r3[j] * b3
        i += 4
    while i < n_rows:
        row, a, b = rows[i], w_a[i], w_b[i]
        for j in range(n):
            acc_a[j] += row[j] * a
            acc_b[j] += row[j] * b
        i += 1


@njit(inline="always")
def _add_complex_rows(acc, re_rows, im_rows, xr, xm):
    """acc[j] += sum_i re_rows[i, j] xr[i] - im_rows[i, j] xm[i] (the real part of a complex
    row times a complex weight), i in order, four rows a pass (the same bits as one a pass)."""
    n_rows, n = re_rows.shape[0], acc.shape[0]
    i = 0
    while i + 4 <= n_rows:
        p0, p1, p2, p3 = re_rows[i], re_rows[i + 1], re_rows[i + 2], re_rows[i + 3]
        q0, q1, q2, q3 = im_rows[i], im_rows[i + 1], im_rows[i + 2], im_rows[i + 3]
        r0, r1, r2, r3 = xr[i], xr[i + 1], xr[i + 2], xr[i + 3]
        m0, m1, m2, m3 = xm[i], xm[i + 1], xm[i + 2], xm[i + 3]
        for j in range(n):
            acc[j] = ((((acc[j] + (p0[j] * r0 - q0[j] * m0)) + (p1[j] * r1 - q1[j] * m1)) + (p2[j] * r2 - q2[j] * m2))
                      + (p3[j] * r3 - q3[j] * m3))
        i += 4
    while i < n_rows:
        pr, qr, r, m = re_rows[i], im_rows[i], xr[i], xm[i]
        for j in range(n):
            acc[j] += pr[j] * r - qr[j] * m
        i += 1


@njit(cache=True, fastmath=False, _nrt=False)
def _gather(knot_pos, knot_vel, rest_pos, free, dofs):
    """The free knots' displacement and velocity into dofs (4, 2 n_free): rows u_x, v_x (first
    n_free columns), u_yz, v_yz ((y, z) of each free knot in turn)."""
    for a in range(free.shape[0]):
        j = free[a]
        dofs[0, a] = knot_pos[j, 0] - rest_pos[j, 0]
        dofs[1, a] = knot_vel[j, 0]
        for axis in range(2):
            dofs[2, 2 * a + axis] = knot_pos[j, 1 + axis] - rest_pos[j, 1 + axis]
            dofs[3, 2 * a + axis] = knot_vel[j, 1 + axis]


@njit(cache=True, fastmath=False, _nrt=False)
def modal_coefficients(knot_pos, knot_vel, rest_pos, free, out_proj, out_e, in_proj, in_inverse, out_c, in_w, q, p,
                       in_scratch, dofs):
    """The modal coefficients of a state: out_c (n_out,) complex and in_w (2K,) complex, written.

    knot_pos, knot_vel: (n_knots, 3) m, m/s. out_proj: (n_free, n_out) knot-major; in_proj:
    (2 n_free, K); in_inverse: (2K, 2K) complex. Scratch: q, p (n_out,), in_scratch (2K,),
    dofs (4, 2 n_free). Each knot adds its row in turn (a contiguous pass over the modes).
    """
    n_free, n_out = out_proj.shape
    k = in_proj.shape[1]
    _gather(knot_pos, knot_vel, rest_pos, free, dofs)
    q[:] = 0.0
    p[:] = 0.0
    _add_rows(q, p, out_proj, dofs[0, :n_free], dofs[1, :n_free])
    for m in range(n_out):
        e = out_e[m]
        re = 0.5 * q[m]
        out_c[m] = complex(re, (re * e.real - 0.5 * p[m]) / e.imag)
    in_scratch[:] = 0.0
    _add_rows(in_scratch[:k], in_scratch[k:], in_proj, dofs[2], dofs[3])
    for r in range(2 * k):
        acc = 0j
        for m in range(2 * k):
            acc += in_inverse[r, m] * in_scratch[m]
        in_w[r] = acc


@njit(cache=True, fastmath=False, _nrt=False)
def modal_detuning(out_detune, out_c, out_shift):
    """Each out-of-plane mode's angle correction a tick at the switch, into out_shift (n_out,) rad:
    the sum over modes k of out_detune[k] (NetModes: k's row, its effect on every mode) times |c_k|^2
    of the coefficients out_c, k after k, four rows a pass (each mode's sum in the same order)."""
    n_rows, n = out_detune.shape[0], out_shift.shape[0]
    for m in range(n):
        out_shift[m] = 0.0
    k = 0
    while k + 4 <= n_rows:
        c0, c1, c2, c3 = out_c[k], out_c[k + 1], out_c[k + 2], out_c[k + 3]
        a0, a1 = c0.real * c0.real + c0.imag * c0.imag, c1.real * c1.real + c1.imag * c1.imag
        a2, a3 = c2.real * c2.real + c2.imag * c2.imag, c3.real * c3.real + c3.imag * c3.imag
        r0, r1, r2, r3 = out_detune[k], out_detune[k + 1], out_detune[k + 2], out_detune[k + 3]
        for m in range(n):
            out_shift[m] = (((out_shift[m] + r0[m] * a0) + r1[m] * a1) + r2[m] * a2) + r3[m] * a3
        k += 4
    while k < n_rows:
        c = out_c[k]
        a = c.real * c.real + c.imag * c.imag
        row = out_detune[k]
        for m in range(n):
            out_shift[m] += row[m] * a
        k += 1


@njit(cache=True, fastmath=False, _nrt=False)
def _detuned_phase(ticks, log_r, shift):
    """(phi, delta now): the correction's angle summed over `ticks` ticks, and its rate at that tick (rad)."""
    if log_r == 0.0:
        return shift * ticks, shift
    return shift * (math.expm1(2.0 * ticks * log_r) / math.expm1(2.0 * log_r)), shift * math.exp(2.0 * ticks * log_r)


@njit(cache=True, fastmath=False, _nrt=False)
def _powers(ticks, out_c, out_e, out_log_r, out_theta, out_shift, out_rate, in_w, in_log_r, in_theta, q, p, xi):
    """Modal state after `ticks` ticks: q, p (n_out,) float and xi (2, 2K) float (real, imaginary), written."""
    for m in range(out_c.shape[0]):
        r = math.exp(ticks * out_log_r[m])
        phi, now = _detuned_phase(ticks, out_log_r[m], out_shift[m])
        angle = ticks * out_theta[m] + phi
        z = out_c[m] * complex(r * math.cos(angle), r * math.sin(angle))
        e = out_e[m]
        q[m] = 2.0 * z.real
        p[m] = 2.0 * (z * complex(e.real, e.imag * (1.0 + now / out_rate[m]))).real
    for m in range(in_w.shape[0]):
        r = math.exp(ticks * in_log_r[m])
        angle = ticks * in_theta[m]
        z = in_w[m] * complex(r * math.cos(angle), r * math.sin(angle))
        xi[0, m] = z.real
        xi[1, m] = z.imag


@njit(cache=True, fastmath=False, _nrt=False)
def modal_state(ticks, rest_pos, free, out_shape, out_c, out_e, out_log_r, out_theta, out_shift, out_rate, in_pos,
                in_vel, in_w, in_log_r, in_theta, q, p, xi, dofs, knot_pos, knot_vel):
    """The linear state `ticks` ticks after the coefficients' state, into knot_pos and knot_vel.

    out_shape: (n_out, n_free) m; out_shift (n_out,) rad: modal_detuning's; in_pos, in_vel: (2, 2K, 2 n_free), the real and imaginary
    parts of the in-plane shapes (mode-major). Scratch: q, p (n_out,), xi (2, 2K), dofs
    (4, 2 n_free). Each mode adds its contiguous row in turn. Fixed knots get their rest place
    and no velocity.
    """
    _powers(ticks, out_c, out_e, out_log_r, out_theta, out_shift, out_rate, in_w, in_log_r, in_theta, q, p, xi)
    n_free = free.shape[0]
    dofs[:] = 0.0
    _add_rows(dofs[0, :n_free], dofs[1, :n_free], out_shape, q, p)
    _add_complex_rows(dofs[2], in_pos[0], in_pos[1], xi[0], xi[1])
    _add_complex_rows(dofs[3], in_vel[0], in_vel[1], xi[0], xi[1])
    for j in range(knot_pos.shape[0]):
        for axis in range(3):
            knot_pos[j, axis] = rest_pos[j, axis]
            knot_vel[j, axis] = 0.0
    for a in range(n_free):
        j = free[a]
        knot_pos[j, 0] += dofs[0, a]
        knot_vel[j, 0] += dofs[1, a]
        for axis in range(2):
            knot_pos[j, 1 + axis] += dofs[2, 2 * a + axis]
            knot_vel[j, 1 + axis] += dofs[3, 2 * a + axis]


@njit(cache=True, fastmath=False, _nrt=False)
def modal_bounds(out_shape, out_c, out_e, out_shift, out_rate, in_pos_abs, in_vel_abs, in_w, disp, speed):
    """Per axis and free knot, bounds on the tail's displacement (disp) and velocity (speed) at
    the coefficients' tick, (3, n_free) m and m/s, written: sums of |shape| |coefficient| over
    the modes (the triangle inequality; a mode's velocity with the largest frequency correction,
    the switch's). Every mode decays (|mu| <= 1), so a bound times the slowest mode's decay after
    n ticks bounds the motion from then on. out_shape: NetModes' (its absolute values taken here);
    in_*_abs (2K, 2 n_free): the in-plane shapes' absolute values (NetModes). Each mode adds its
    contiguous row to every knot's bounds in turn."""
    n_free = disp.shape[1]
    disp[:] = 0.0
    speed[:] = 0.0
    disp_x, speed_x = disp[0], speed[0]
    for m in range(out_shape.shape[0]):
        e = out_e[m]
        cq = 2.0 * abs(out_c[m])
        cp = cq * abs(complex(e.real, e.imag * (1.0 + abs(out_shift[m]) / out_rate[m])))
        row = out_shape[m]
        for a in range(n_free):
            shape = abs(row[a])
            disp_x[a] += shape * cq
            speed_x[a] += shape * cp
    disp_y, disp_z, speed_y, speed_z = disp[1], disp[2], speed[1], speed[2]
    for m in range(in_w.shape[0]):
        w = abs(in_w[m])
        pos_abs, vel_abs = in_pos_abs[m], in_vel_abs[m]
        for a in range(n_free):
            disp_y[a] += pos_abs[2 * a] * w
            disp_z[a] += pos_abs[2 * a + 1] * w
            speed_y[a] += vel_abs[2 * a] * w
            speed_z[a] += vel_abs[2 * a + 1] * w


@njit(cache=True, fastmath=False, _nrt=False)
def quiet_from(sleep_speed, max_ticks, out_log_r, in_log_r, speed):
    """The first tick n >= 1 (after the coefficients' state) from which no knot of the tail can be
    as fast as sleep_speed again, by the bounds (speed: modal_bounds' (3, n_free) m/s, decaying
    at the slowest mode's rate of each plane), found by bisection; max_ticks if not before it.
    """
    r_out = -math.inf
    for m in range(out_log_r.shape[0]):
        r_out = max(r_out, out_log_r[m])
    r_in = -math.inf
    for m in range(in_log_r.shape[0]):
        r_in = max(r_in, in_log_r[m])
    r_out = min(r_out, 0.0)
    r_in = min(r_in, 0.0)
    limit2 = sleep_speed * sleep_speed
    lo, hi = 0, 1  # bound(lo) loud or lo = 0; probe hi
    while True:
        if not _loud(speed, math.exp(hi * r_out), math.exp(hi * r_in), limit2):
            break
        if hi >= max_ticks:
            return max_ticks
        lo, hi = hi, min(2 * hi, max_ticks)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _loud(speed, math.exp(mid * r_out), math.exp(mid * r_in), limit2):
            lo = mid
        else:
            hi = mid
    return hi


@njit(cache=True, fastmath=False, _nrt=False)
def _loud(speed, decay_out, decay_in, limit2):
    """Can any knot be as fast as sqrt(limit2) m/s, its bounds decayed by these factors?"""
    for a in range(speed.shape[1]):
        bx = speed[0, a] * decay_out
        by = speed[1, a] * decay_in
        bz = speed[2, a] * decay_in
        if bx * bx + by * by + bz * bz >= limit2:
            return True
    return False


# step_grid_free_tail's status beyond kernels.grid's FREE_*: the motion's energy fell to the tail's.
FREE_TAIL = 4


@njit(inline="always")
def _free_tail(free, knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks, sleep_speed,
               sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k,
               rest_energy, tail_energy):
    """`free` (a step_grid_free kernel) tick by tick, stopping also after a tick whose motion energy is at most tail_energy."""
    n = knot_state.shape[2] * knot_state.shape[3]
    pos = knot_state[0].reshape(3, n).T
    vel = knot_state[1].reshape(3, n).T
    taken = 0
    while taken < ticks:
        t, quiet_ticks, status = free(knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, 1,
                                      sleep_speed, sleep_ticks, quiet_ticks, reach, box)
        taken += t
        if status != FREE_AWAKE:
            return taken, quiet_ticks, status
        if motion_energy(pos, vel, knot_mass, knot_inv_mass, spring_ij, spring_rest, spring_k, gravity, rest_energy,
                         tail_energy) <= tail_energy:
            return taken, quiet_ticks, FREE_TAIL
    return taken, quiet_ticks, FREE_AWAKE


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid_free_tail(knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks,
                        sleep_speed, sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij,
                        spring_rest, spring_k, rest_energy, tail_energy):
    """kernels.grid.step_grid_free, tick by tick, stopping also after the first tick whose motion
    energy (motion_energy) is at most tail_energy J (status FREE_TAIL): the same ticks and bits.

    Args beyond step_grid_free's: knot_mass, knot_inv_mass (n_knots,) kg, 1/kg in knot order;
    spring_ij, spring_rest, spring_k: the topology's springs; rest_energy: J (NetModes).

    Returns:
        (ticks taken, quiet_ticks after them, FREE_* or FREE_TAIL status).
    """
    return _free_tail(step_grid_free, knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work,
                      ticks, sleep_speed, sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij,
                      spring_rest, spring_k, rest_energy, tail_energy)


@njit(cache=True, fastmath=False, error_model="numpy", _nrt=False)
def step_grid32_free_tail(knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work, ticks,
                          sleep_speed, sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij,
                          spring_rest, spring_k, rest_energy, tail_energy):
    """step_grid_free_tail with kernels.grid32.step_grid32_free's ticks (a float32 net). Args and returns as it."""
    return _free_tail(step_grid32_free, knot_state, grid_inv_mass, grid_params, gravity, drag, h, substeps, grid_work,
                      ticks, sleep_speed, sleep_ticks, quiet_ticks, reach, box, knot_mass, knot_inv_mass, spring_ij,
                      spring_rest, spring_k, rest_energy, tail_energy)
