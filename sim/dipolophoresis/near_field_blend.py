"""Near-field correction of the dipolophoretic pair velocities, blended into the periodic far field.

The time step computes ``U^d`` from the far-field kernels summed over all periodic images (Ewald,
:mod:`sim.dipolophoresis.ewald`). For a pair closer than ``r_c`` the far-field pair kernel is replaced by
the exact two-sphere functions (:mod:`sim.dipolophoresis.near_field`, Saintillan 2008 method, our own
table): with ``x = x_alpha - x_beta``, ``xh = x/r``, ``c = e . xh`` and the differences
``dF = F^exact(r) - F^far(r)`` of the three pair functions,

    dU_alpha = U0 w(r) [ (dF_par c^2 + dF_perp (1 - c^2)) xh + 2 dF_x c (e - c xh) ],   dU_beta = -dU_alpha,

which is the isotropic form of ``physics.md`` §4 (``sin(2 th) t = 2 c (e - c xh)``). The weight ``w`` is 1
for ``r <= r_c - width`` and falls to 0 at ``r_c`` with a C1 smoothstep, so the velocity has no jump when a
pair crosses ``r_c``. Only the nearest image of each pair is corrected (``r_c < L/2``); the far field of
all other images is already in the Ewald sum, and their near-field corrections are ``O(r^-5)`` at
``r >= L - r_c``.

Accuracy: what is left out is ``w(r) dF(r)`` for ``r > r_c - width`` plus ``dF`` beyond ``r_c``. For ICEP
``dF_perp`` is 0.006 U0 at ``r = 4`` (10% of ``F_perp``) and 0.003 U0 at ``r = 5`` (5%); DEP's far field is
66% too large at ``r = 4``, but DEP is ``O(r^-4)`` small there (0.0012 U0). The default ``r_c = 4``
follows the paper (§2.1: corrections "typically for ``|R| < 4a``"); a larger ``r_c`` (up to ``L/2``)
reduces the residual at the price of a longer pair list.

References:
    Saintillan, D. (2008) Phys. Fluids 20, 067104; Park, J. S. & Saintillan, D. (2010) J. Fluid Mech.
    662, 66-90; Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §2.1.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.dipolophoresis.far_field import MECHANISM_DEP, MECHANISM_DIP, MECHANISM_ICEP, far_field_functions
from sim.dipolophoresis.near_field import near_field_kernel
from sim.geometry.neighbors import build_pair_list


@njit(cache=True)
def blend_weight(r: float, r_cut: float, width: float) -> float:
    """1 for ``r <= r_cut - width``, 0 for ``r >= r_cut``, ``1 - 3u^2 + 2u^3`` in between (C1)."""
    if r >= r_cut:
        return 0.0
    start = r_cut - width
    if r <= start:
        return 1.0
    u = (r - start) / width
    return 1.0 - u * u * (3.0 - 2.0 * u)


@njit(cache=True)
def mechanism_codes(icep_weight: float, dep_weight: float) -> tuple[int, int]:
    """Codes of (near_field_kernel, far_field_functions) for the mechanism switch (weights 0 or 1)."""
    if icep_weight > 0.0 and dep_weight > 0.0:
        return 2, MECHANISM_DIP
    if icep_weight > 0.0:
        return 0, MECHANISM_ICEP
    return 1, MECHANISM_DEP


@njit(cache=True)
def pair_correction(
    x: np.ndarray,
    e: np.ndarray,
    icep_weight: float,
    dep_weight: float,
    r_cut: float,
    width: float,
    grid,
    coefficients,
    asymptotics,
) -> np.ndarray:
    """``dU_alpha / U0`` (3,) for one pair with ``x = x_alpha - x_beta`` (units a); zero beyond ``r_cut``.

    ``icep_weight``, ``dep_weight``: the mechanism switch (each 0 or 1, not both 0).
    """
    out = np.zeros(3)
    r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    w = blend_weight(r, r_cut, width)
    if w == 0.0:
        return out
    near_code, far_code = mechanism_codes(icep_weight, dep_weight)
    exact_par, exact_perp, exact_x = near_field_kernel(r, near_code, grid, coefficients, asymptotics)
    far_par, far_perp, far_x = far_field_functions(r, far_code)
    d_par = exact_par - far_par
    d_perp = exact_perp - far_perp
    d_x = exact_x - far_x
    c = (e[0] * x[0] + e[1] * x[1] + e[2] * x[2]) / r
    radial = d_par * c * c + d_perp * (1.0 - c * c)
    for k in range(3):
        xh = x[k] / r
        out[k] = w * (radial * xh + 2.0 * d_x * c * (e[k] - c * xh))
    return out


@njit(cache=True)
def add_near_field_velocities(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    e: np.ndarray,
    icep_weight: float,
    dep_weight: float,
    r_cut: float,
    width: float,
    grid,
    coefficients,
    asymptotics,
    velocity: np.ndarray,
) -> int:
    """Add the blended near-field correction (units U0) of every pair closer than ``r_cut`` to ``velocity``.

    Args:
        positions: (N, 3) wrapped positions (units a).
        box_length, offset: box side and Lees–Edwards offset (units a); ``r_cut`` must be below ``L/2``.
        e: (3,) unit field direction.
        icep_weight, dep_weight: the mechanism switch (each 0 or 1).
        r_cut, width: blend cut-off and taper width (units a).
        grid, coefficients, asymptotics: the table arrays of :mod:`sim.dipolophoresis.near_field`.
        velocity: (N, 3) updated in place.

    Returns:
        The number of pairs closer than ``r_cut``.
    """
    pairs, separations = build_pair_list(positions, box_length, offset, r_cut)
    x = np.empty(3)
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        for c in range(3):
            x[c] = -separations[k, c]  # separations are x_j - x_i; alpha = i
        du = pair_correction(x, e, icep_weight, dep_weight, r_cut, width, grid, coefficients, asymptotics)
        for c in range(3):
            velocity[i, c] += du[c]
            velocity[j, c] -= du[c]
    return pairs.shape[0]
