"""Second-order Adams–Bashforth position update (explicit Euler on the first step), fixed or variable step.

    x_{n+1} = x_n + dt (3/2 U_n - 1/2 U_{n-1}),      x_1 = x_0 + dt U_0            (fixed step)
    x_{n+1} = x_n + dt_n [(1 + w/2) U_n - (w/2) U_{n-1}],   w = dt_n / dt_{n-1}       (variable step)

The variable-step form integrates the linear interpolant of ``U`` through ``(t_{n-1}, U_{n-1})`` and
``(t_n, U_n)`` over ``[t_n, t_{n+1}]``; it is second order for smoothly varying step ratios and reduces
to the fixed-step form at ``w = 1`` (Hairer, Nørsett & Wanner 1993, §III.5).

Local error O(dt^3), global O(dt^2) for smooth velocity fields (Hairer, Nørsett & Wanner 1993, §III.1).
The velocity of step n-1 must refer to the same periodic image as x_n: when a particle is wrapped across
the Lees–Edwards y-boundary its stored velocity is shifted by ``-n L gammadot`` in x (see
:func:`shift_crossed_velocities`).

References:
    Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §2.3.
    Hairer, E., Nørsett, S. P. & Wanner, G. (1993) Solving Ordinary Differential Equations I, Springer.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def variable_step_adams_bashforth(
    positions: np.ndarray,
    velocity: np.ndarray,
    previous_velocity: np.ndarray,
    has_previous: bool,
    dt: float,
    previous_dt: float,
) -> None:
    """Advance ``positions`` (N, 3) in place by one variable-step AB2 (or Euler) step of size ``dt``.

    ``previous_dt`` is the size of the step that led from ``U_{n-1}``'s configuration to ``U_n``'s.
    """
    n = positions.shape[0]
    if has_previous and previous_dt > 0.0:
        half_ratio = 0.5 * dt / previous_dt
        for p in range(n):
            for c in range(3):
                positions[p, c] += dt * (
                    (1.0 + half_ratio) * velocity[p, c] - half_ratio * previous_velocity[p, c]
                )
    else:
        for p in range(n):
            for c in range(3):
                positions[p, c] += dt * velocity[p, c]


@njit(cache=True)
def shift_crossed_velocities(
    velocity: np.ndarray, crossings: np.ndarray, box_length: float, shear_rate: float
) -> None:
    """Give wrapped particles the velocity of their new image: ``u_x -= n L gammadot`` (in place)."""
    for p in range(velocity.shape[0]):
        if crossings[p] != 0:
            velocity[p, 0] -= crossings[p] * box_length * shear_rate
