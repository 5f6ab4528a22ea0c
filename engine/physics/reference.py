"""Numpy twins of the engine's numba kernels, same signatures, written for clarity not speed.

Tests hold the numba kernels to these (tests/engine/test_integrators.py). Where a kernel is
scalar code with nothing to vectorise (the collision search), its twin is the kernel's own
Python function run by the interpreter (`kernel.py_func`), which checks the compiled code
against the source semantics.
"""
import numpy as np

from engine.physics.integrators import DOPRI5, EXPLICIT_EULER, MAX_SUBSTEPS, RK4, SEMI_IMPLICIT_EULER, VERLET


def ball_accel(vel, spin, gravity, drag_k, magnus_k, out):
    """Twin of engine.physics.forces.ball_accel."""
    acc = np.zeros(3)
    if gravity is not None:
        acc[2] -= gravity
    if drag_k is not None:
        acc -= drag_k * np.linalg.norm(vel) * vel
    if magnus_k is not None:
        acc += magnus_k * np.cross(spin, vel)
    out[:] = acc


def _deriv(y, gravity, drag_k, magnus_k):
    acc = np.empty(3)
    ball_accel(y[3:6], y[6:9], gravity, drag_k, magnus_k, acc)
    return np.concatenate([y[3:6], acc, np.zeros(3)])


# Butcher tableau of Dormand-Prince 5(4) (Hairer, Norsett, Wanner, Solving ODEs I, table 5.2).
_DP_A = [
    [],
    [1 / 5],
    [3 / 40, 9 / 40],
    [44 / 45, -56 / 15, 32 / 9],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
]
_DP_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])


def advance(y, h, method, gravity, drag_k, magnus_k, rtol, atol, work, adapt, out):
    """Twin of engine.physics.integrators.advance."""
    f = lambda state: _deriv(state, gravity, drag_k, magnus_k)  # noqa: E731
    y = np.asarray(y, dtype=float)
    if h == 0.0:
        out[:] = y
        return 0
    if method == EXPLICIT_EULER:
        out[:] = y + h * f(y)
    elif method == SEMI_IMPLICIT_EULER:
        vel = y[3:6] + h * f(y)[3:6]
        out[:] = np.concatenate([y[0:3] + h * vel, vel, y[6:9]])
    elif method == VERLET:
        a0 = f(y)[3:6]
        predicted = y.copy()
        predicted[3:6] = y[3:6] + h * a0
        a1 = f(predicted)[3:6]
        out[:] = np.concatenate([y[0:3] + h * y[3:6] + 0.5 * h * h * a0, y[3:6] + 0.5 * h * (a0 + a1), y[6:9]])
    elif method == RK4:
        k1 = f(y)
        k2 = f(y + 0.5 * h * k1)
        k3 = f(y + 0.5 * h * k2)
        k4 = f(y + h * k3)
        out[:] = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    elif method == DOPRI5:
        cur = y.copy()
        t = 0.0
        h_try = adapt[0] if adapt[0] > 0.0 else h
        n_sub = 0
        while t < h:
            n_sub += 1
            if n_sub > MAX_SUBSTEPS:
                return -1
            s = min(h_try, h - t)
            k = [f(cur)]
            for row in _DP_A[1:]:
                k.append(f(cur + s * sum(a * ki for a, ki in zip(row, k))))
            trial = cur + s * sum(a * ki for a, ki in zip(_DP_A[6], k))
            err_vec = s * sum(e * ki for e, ki in zip(_DP_E, k))
            scale = atol + rtol * np.maximum(np.abs(cur), np.abs(trial))
            err = np.sqrt(np.mean((err_vec / scale) ** 2))
            factor = 10.0 if err == 0.0 else min(10.0, max(0.2, 0.9 * err ** -0.2))
            if err <= 1.0:
                t = h if s == h - t else t + s
                cur = trial
                adapt[1] += 1
                h_try = s * factor if s == h_try else max(h_try, s * factor)
            else:
                adapt[2] += 1
                h_try = s * factor
        adapt[0] = h_try
        out[:] = cur
        return n_sub
    else:
        raise ValueError(f"unknown integrator id {method}")
    return 1
