"""Ball integrators in numba: explicit Euler, semi-implicit Euler, velocity Verlet, RK4, Dormand-Prince 5(4).

The ball's state is a flat float64 vector y = (pos, vel, spin) of 9 numbers, the view of one
BALL_DTYPE record. Spin is constant in flight: the air torque on a 40 mm ball costs it about
1 % of its spin over a whole flight (Lee, Ozaki, Goh, Int. J. Racket Sports Sci. 1(1), 2019),
well below every other error here. Forces do not depend on position, which the integrators
below use (one acceleration evaluation serves both halves of a stage).

Every function has a numpy twin with the same signature in engine/physics/reference.py.
"""
import math

from numba import njit

from engine.physics.forces import ball_accel

EXPLICIT_EULER = 0
SEMI_IMPLICIT_EULER = 1
VERLET = 2
RK4 = 3
DOPRI5 = 4

METHODS = {
    "explicit_euler": EXPLICIT_EULER,
    "semi_implicit_euler": SEMI_IMPLICIT_EULER,
    "verlet": VERLET,
    "rk4": RK4,
    "dopri5": DOPRI5,
}
# Global order of convergence on smooth flight; dopri5 is tolerance-controlled.
ORDERS = {"explicit_euler": 1, "semi_implicit_euler": 1, "verlet": 2, "rk4": 4, "dopri5": 5}

WORK_SHAPE = (9, 9)  # scratch rows: seven stages, a trial state, an error estimate
ADAPT_SIZE = 3  # dopri5 bookkeeping: next trial substep (s), accepted, rejected substeps
MAX_SUBSTEPS = 100_000

# Dormand & Prince, "A family of embedded Runge-Kutta formulae", J. Comp. Appl. Math. 6 (1980);
# coefficients as in Hairer, Norsett, Wanner, Solving ODEs I, table 5.2.
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
# Difference between the 5th- and the embedded 4th-order weights.
_E1, _E3, _E4, _E5, _E6, _E7 = 71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40


@njit(inline="always", cache=True, _nrt=False)
def _deriv(y, gravity, drag_k, magnus_k, out):
    """dy/dt of the flat ball state: (vel, accel, 0)."""
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    ball_accel(y[3:6], y[6:9], gravity, drag_k, magnus_k, out[3:6])
    out[6] = 0.0
    out[7] = 0.0
    out[8] = 0.0


@njit(cache=True, _nrt=False)
def _dopri5(y, h, gravity, drag_k, magnus_k, rtol, atol, work, adapt, out):
    """Adaptive Dormand-Prince 5(4) over [0, h], local extrapolation, ends exactly at h."""
    k1, k2, k3, k4, k5, k6, k7, trial, cur = work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7], work[8]
    for i in range(9):
        cur[i] = y[i]
    t = 0.0
    h_try = adapt[0] if adapt[0] > 0.0 else h
    _deriv(cur, gravity, drag_k, magnus_k, k1)
    n_sub = 0
    while t < h:
        n_sub += 1
        if n_sub > MAX_SUBSTEPS:
            return -1
        s = min(h_try, h - t)
        for i in range(9):
            trial[i] = cur[i] + s * _A21 * k1[i]
        _deriv(trial, gravity, drag_k, magnus_k, k2)
        for i in range(9):
            trial[i] = cur[i] + s * (_A31 * k1[i] + _A32 * k2[i])
        _deriv(trial, gravity, drag_k, magnus_k, k3)
        for i in range(9):
            trial[i] = cur[i] + s * (_A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i])
        _deriv(trial, gravity, drag_k, magnus_k, k4)
        for i in range(9):
            trial[i] = cur[i] + s * (_A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i])
        _deriv(trial, gravity, drag_k, magnus_k, k5)
        for i in range(9):
            trial[i] = cur[i] + s * (_A61 * k1[i] + _A62 * k2[i] + _A63 * k3[i] + _A64 * k4[i] + _A65 * k5[i])
        _deriv(trial, gravity, drag_k, magnus_k, k6)
        for i in range(9):
            trial[i] = cur[i] + s * (_B1 * k1[i] + _B3 * k3[i] + _B4 * k4[i] + _B5 * k5[i] + _B6 * k6[i])
        _deriv(trial, gravity, drag_k, magnus_k, k7)
        err_sq = 0.0
        for i in range(9):
            e = s * (_E1 * k1[i] + _E3 * k3[i] + _E4 * k4[i] + _E5 * k5[i] + _E6 * k6[i] + _E7 * k7[i])
            scale = atol + rtol * max(abs(cur[i]), abs(trial[i]))
            err_sq += (e / scale) ** 2
        err = math.sqrt(err_sq / 9.0)
        # Standard step-size controller with safety factor 0.9 and growth limits (Hairer I, II.4).
        factor = 10.0 if err == 0.0 else min(10.0, max(0.2, 0.9 * err ** -0.2))
        if err <= 1.0:
            t = h if s == h - t else t + s
            for i in range(9):
                cur[i] = trial[i]
                k1[i] = k7[i]  # first same as last
            adapt[1] += 1
            if s == h_try:
                h_try = s * factor
            else:
                # A substep cut short to land on h says nothing about the step size to try next.
                h_try = max(h_try, s * factor)
        else:
            adapt[2] += 1
            h_try = s * factor
    adapt[0] = h_try
    for i in range(9):
        out[i] = cur[i]
    return n_sub


@njit(cache=True, _nrt=False)
def advance(y, h, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, out):
    """Advance the ball in flight by h.

    Args:
        y: (9,) pos m, vel m/s, spin rad/s. h: s, >= 0.
        method: one of the integer ids in METHODS.
        gravity, drag_k, magnus_k: effect parameters, or None for an absent effect (engine/physics/forces.py).
        rtol, atol: dopri5's relative and absolute error tolerance per substep; ignored by the others.
        work: WORK_SHAPE float64 scratch. adapt: (ADAPT_SIZE,) float64 dopri5 bookkeeping.
        out: (9,) written; may not alias y.

    Returns:
        Substeps taken (1 for the fixed-step methods), or -1 if dopri5 exceeded MAX_SUBSTEPS.
    """
    if h == 0.0:
        for i in range(9):
            out[i] = y[i]
        return 0
    k1, k2 = work[0], work[1]
    if method == EXPLICIT_EULER:
        _deriv(y, gravity, drag_k, magnus_k, k1)
        for i in range(9):
            out[i] = y[i] + h * k1[i]
    elif method == SEMI_IMPLICIT_EULER:
        _deriv(y, gravity, drag_k, magnus_k, k1)
        for i in range(3):
            out[3 + i] = y[3 + i] + h * k1[3 + i]
            out[i] = y[i] + h * out[3 + i]
            out[6 + i] = y[6 + i]
    elif method == VERLET:
        # Velocity Verlet with a predicted velocity for the velocity-dependent forces (Groot &
        # Warren, J. Chem. Phys. 107, 4423 (1997), with lambda = 1 so the scheme stays second
        # order); for forces that do not depend on velocity it is exactly velocity Verlet.
        _deriv(y, gravity, drag_k, magnus_k, k1)
        for i in range(9):
            k2[i] = y[i]
        for i in range(3):
            k2[3 + i] = y[3 + i] + h * k1[3 + i]  # predicted velocity at the end of the step
        ball_accel(k2[3:6], k2[6:9], gravity, drag_k, magnus_k, k2[0:3])
        for i in range(3):
            out[i] = y[i] + h * y[3 + i] + 0.5 * h * h * k1[3 + i]
            out[3 + i] = y[3 + i] + 0.5 * h * (k1[3 + i] + k2[i])
            out[6 + i] = y[6 + i]
    elif method == RK4:
        k3, k4, tmp = work[2], work[3], work[7]
        _deriv(y, gravity, drag_k, magnus_k, k1)
        for i in range(9):
            tmp[i] = y[i] + 0.5 * h * k1[i]
        _deriv(tmp, gravity, drag_k, magnus_k, k2)
        for i in range(9):
            tmp[i] = y[i] + 0.5 * h * k2[i]
        _deriv(tmp, gravity, drag_k, magnus_k, k3)
        for i in range(9):
            tmp[i] = y[i] + h * k3[i]
        _deriv(tmp, gravity, drag_k, magnus_k, k4)
        for i in range(9):
            out[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    else:
        return _dopri5(y, h, gravity, drag_k, magnus_k, rtol, atol, work, adapt, out)
    return 1
