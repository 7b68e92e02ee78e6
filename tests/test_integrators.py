"""AB2 convergence order on an analytic problem, and the Lees–Edwards velocity shift."""

from __future__ import annotations

import numpy as np

from sim.integrators import adams_bashforth_update, shift_crossed_velocities


def _integrate(dt: float, t_end: float = 2.0) -> np.ndarray:
    """Solve dx/dt = A x (rotation + decay), x(0) = (1, 0, 0.5), with the AB2 kernel."""
    a = np.array([[-0.3, -1.0, 0.0], [1.0, -0.3, 0.0], [0.0, 0.0, -0.5]])
    x = np.array([[1.0, 0.0, 0.5]])
    prev = np.zeros((1, 3))
    has_prev = False
    for _ in range(round(t_end / dt)):
        v = x @ a.T
        adams_bashforth_update(x, v, prev, has_prev, dt)
        prev = v
        has_prev = True
    return x[0]


def test_second_order_convergence() -> None:
    """Halving dt divides the error by ~4: observed order within 0.15 of 2 (exact answer = expm)."""
    from scipy.linalg import expm

    a = np.array([[-0.3, -1.0, 0.0], [1.0, -0.3, 0.0], [0.0, 0.0, -0.5]])
    exact = expm(2.0 * a) @ np.array([1.0, 0.0, 0.5])
    errors = [np.linalg.norm(_integrate(dt) - exact) for dt in (0.02, 0.01, 0.005)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.15), orders


def test_crossed_velocity_shift() -> None:
    v = np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    shift_crossed_velocities(v, np.array([1, -1], dtype=np.int64), 10.0, 1.0)
    np.testing.assert_array_equal(v[:, 0], [-9.0, 12.0])
