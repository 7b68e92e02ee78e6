"""Near-field corrections of the dipolophoretic pair velocities and stresses, blended into the far field.

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

Stresses (``physics.md`` §4; tables of :mod:`sim.dipolophoresis.near_field_stress`, same method): for
each pair closer than ``r_c``, with the same weight ``w(r)``,

* ICEP: both spheres' stresslets change by ``w (dS^exact - dS^far)``, ``dS^far`` the O(r^-3) pair
  correction the Ewald sum already holds (slot ``icep_pair``);
* DEP force virial: ``-w sym(x (F^exact_alpha - F^far_alpha)) / V`` (slot ``dep_virial``);
* DEP-induced stresslets: ``w S^DEP`` on each sphere, the stresslet a sphere carries because the DEP
  forces move the pair rigidly (``O(r^-6)`` far away, so it has no far-field part; slot
  ``dep_stresslet``).

What is exact: the two-sphere ICEP stresslets (electric problem, slip and Stokes flow of the isolated
pair) and the two-sphere DEP force and its induced stresslets, tabulated to ~1e-6 (their table header).
What is approximated: pairwise additivity (no three-body near-field terms), the blend taper, and for
gaps below 5e-4 a the fitted near-contact forms (ICEP ``f2``, ``f4`` grow weakly, ``~gap^-0.2``).

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
from sim.dipolophoresis.near_field_stress import pair_stress_corrections
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
def add_near_field_corrections(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    e: np.ndarray,
    icep_weight: float,
    dep_weight: float,
    r_cut: float,
    width: float,
    tables,
    velocity: np.ndarray,
    icep_stress: np.ndarray,
    dep_virial: np.ndarray,
    dep_stresslet: np.ndarray,
) -> int:
    """Add the blended near-field corrections of every pair closer than ``r_cut`` (in place).

    Args:
        positions: (N, 3) wrapped positions (units a).
        box_length, offset: box side and Lees–Edwards offset (units a); ``r_cut`` must be below ``L/2``.
        e: (3,) unit field direction.
        icep_weight, dep_weight: the mechanism switch (each 0 or 1).
        r_cut, width: blend cut-off and taper width (units a).
        tables: ``(grid, coefficients, asymptotics, stress_grid, stress_coefficients, stress_asymptotics)``
            of :mod:`sim.dipolophoresis.near_field` and :mod:`sim.dipolophoresis.near_field_stress`.
        velocity: (N, 3) in units U0.
        icep_stress, dep_virial, dep_stresslet: (3, 3) bulk stresses in units ``eps E0^2`` (``a = 1``).

    Returns:
        The number of pairs closer than ``r_cut``.
    """
    grid, coefficients, asymptotics, stress_grid, stress_coefficients, stress_asymptotics = tables
    pairs, separations = build_pair_list(positions, box_length, offset, r_cut)
    volume = box_length**3
    x = np.empty(3)
    xh = np.empty(3)
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        for c in range(3):
            x[c] = -separations[k, c]  # separations are x_j - x_i; alpha = i
        du = pair_correction(x, e, icep_weight, dep_weight, r_cut, width, grid, coefficients, asymptotics)
        for c in range(3):
            velocity[i, c] += du[c]
            velocity[j, c] -= du[c]
        r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
        w = blend_weight(r, r_cut, width)
        if w == 0.0:
            continue
        for c in range(3):
            xh[c] = x[c] / r
        d_icep, s_dep, d_force = pair_stress_corrections(
            xh, e, r, stress_grid, stress_coefficients, stress_asymptotics
        )
        scale = math.pi * w / volume  # table units pi eps a^3 E0^2 (stresslets), pi eps a^2 E0^2 (forces)
        for a in range(3):
            for b in range(3):
                icep_stress[a, b] += icep_weight * 2.0 * scale * d_icep[a, b]
                dep_stresslet[a, b] += dep_weight * 2.0 * scale * s_dep[a, b]
                dep_virial[a, b] -= dep_weight * 0.5 * scale * (x[a] * d_force[b] + x[b] * d_force[a])
    return pairs.shape[0]
