"""Near-field corrections of the dipolophoretic pair velocities and stresses, blended into the far field.

The time step computes ``U^d`` from the far-field kernels summed over all periodic images (Ewald,
:mod:`sim.dipolophoresis.ewald`). For a pair closer than ``r_c`` the far-field pair kernel is replaced by
the exact two-sphere functions (:mod:`sim.dipolophoresis.near_field`, Saintillan 2008 method, our own
table): with ``x = x_alpha - x_beta``, ``xh = x/r``, ``c = e . xh`` and the differences
``dF = F^exact(r) - F^far(r)`` of the three pair functions,

    dU_alpha = U0 w(r) [ (dF_par c^2 + dF_perp (1 - c^2)) xh + 2 dF_x c (e - c xh) ],   dU_beta = -dU_alpha,

which is the isotropic form of ``docs/model.md#dipolophoresis`` (``sin(2 th) t = 2 c (e - c xh)``).
The weight ``w`` is 1
for ``r <= r_c - width`` and falls to 0 at ``r_c`` with a C1 smoothstep, so the velocity has no jump when a
pair crosses ``r_c``. Only the nearest image of each pair is corrected (``r_c < L/2``); the far field of
all other images is already in the Ewald sum, and their near-field corrections are ``O(r^-5)`` at
``r >= L - r_c``.

Accuracy: what is left out is ``w(r) dF(r)`` for ``r > r_c - width`` plus ``dF`` beyond ``r_c``. For ICEP
``dF_perp`` is 0.006 U0 at ``r = 4`` (10% of ``F_perp``) and 0.003 U0 at ``r = 5`` (5%); DEP's far field is
66% too large at ``r = 4``, but DEP is ``O(r^-4)`` small there (0.0012 U0). The default ``r_c = 4``
follows the paper (§2.1: corrections "typically for ``|R| < 4a``"); a larger ``r_c`` (up to ``L/2``)
reduces the residual at the price of a longer pair list.

Stresses (``docs/model.md#dipolophoresis``; tables of :mod:`sim.dipolophoresis.near_field_stress`,
same method): for
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
from sim.dipolophoresis.near_field import LOG_FORM, near_field_kernel
from sim.dipolophoresis.near_field_stress import (
    ICEP_PAIR_FAR_FIELD,
    dep_force_kernel,
    near_field_stress_kernel,
)
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
def _cubic(coefficients: np.ndarray, function: int, k: int, h: float) -> float:
    """The table spline of ``function`` on interval ``k`` at ``h = ln(r - 2) - s_k``."""
    c = coefficients[function, k]
    return c[0] + h * (c[1] + h * (c[2] + h * c[3]))


@njit(cache=True, inline="always")
def _near_contact_functions(
    gap: float,
    near_code: int,
    want_icep: bool,
    want_dep: bool,
    grid: np.ndarray,
    asymptotics: np.ndarray,
    stress_asymptotics: np.ndarray,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float, float, float]:
    """The 14 outputs of :func:`_pair_functions` below the first table node, from one logarithm.

    The near-contact forms of the tables (gap floored at ``grid[5]``): velocity functions
    ``A xi^p (1 + B xi)`` or ``C + a/L + b/L^2`` with ``L = ln(1/xi)``
    (:func:`sim.dipolophoresis.near_field._near_contact`), stress and DEP-force functions ``c + a xi^p``
    (:func:`sim.dipolophoresis.near_field_stress._evaluate`), here with ``xi^p = exp(p ln xi)`` and
    ``1/L = -1/ln xi`` from a single ``ln xi``, instead of a ``pow`` (or ``log``) per function: the
    kernels spent ~750 ns on each near-contact pair, ~500 of the ~4400 pairs of a step at N = 300
    under a field. Equal to the kernels' values to ~1e-15 relative (``exp(p ln xi)`` rounds
    differently from ``pow``; tested to 1e-13).
    """
    gap = max(gap, grid[5])
    log_gap = math.log(gap)
    inverse_log = -1.0 / log_gap
    first = 0 if near_code != 1 else 3
    last = 6 if near_code != 0 else 3
    e_par = e_perp = e_x = 0.0
    for function in range(first, last):
        parameters = asymptotics[function]
        if parameters[0] == LOG_FORM:
            value = parameters[1] + inverse_log * (parameters[2] + inverse_log * parameters[3])
        else:
            value = parameters[1] * math.exp(parameters[3] * log_gap) * (1.0 + parameters[2] * gap)
        if function % 3 == 0:
            e_par += value
        elif function % 3 == 1:
            e_perp += value
        else:
            e_x += value
    f1 = f2 = f3 = f4 = g1 = g2 = g3 = g4 = f_par = f_perp = f_x = 0.0
    sa = stress_asymptotics
    if want_icep:
        f1 = sa[0, 0] + sa[0, 1] * math.exp(sa[0, 2] * log_gap)
        f2 = sa[1, 0] + sa[1, 1] * math.exp(sa[1, 2] * log_gap)
        f3 = sa[2, 0] + sa[2, 1] * math.exp(sa[2, 2] * log_gap)
        f4 = sa[3, 0] + sa[3, 1] * math.exp(sa[3, 2] * log_gap)
    if want_dep:
        g2 = sa[4, 0] + sa[4, 1] * math.exp(sa[4, 2] * log_gap)
        g3 = sa[5, 0] + sa[5, 1] * math.exp(sa[5, 2] * log_gap)
        g4 = sa[6, 0] + sa[6, 1] * math.exp(sa[6, 2] * log_gap)
        f_par = sa[7, 0] + sa[7, 1] * math.exp(sa[7, 2] * log_gap)
        f_perp = sa[8, 0] + sa[8, 1] * math.exp(sa[8, 2] * log_gap)
        f_x = sa[9, 0] + sa[9, 1] * math.exp(sa[9, 2] * log_gap)
    return e_par, e_perp, e_x, f1, f2, f3, f4, g1, g2, g3, g4, f_par, f_perp, f_x


@njit(cache=True, inline="always")
def _pair_functions(
    r: float, near_code: int, want_icep: bool, want_dep: bool, tables
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float, float, float]:
    """Exact velocity functions (``F_par, F_perp, F_x`` of the mechanism), ICEP stress functions
    ``f1..f4``, DEP stresslet functions ``g1..g4`` and DEP force functions at ``r`` (one pair).

    Both tables share their nodes (uniform in ``ln(r - 2)``, checked on import of
    :mod:`sim.step_parameters`), so on the splines one logarithm and one interval search serve all 16
    functions; the values equal those of :func:`~sim.dipolophoresis.near_field.near_field_kernel`,
    :func:`~sim.dipolophoresis.near_field_stress.near_field_stress_kernel` and
    :func:`~sim.dipolophoresis.near_field_stress.dep_force_kernel` bit for bit (same arithmetic), which
    this falls back to beyond the last node; below the first node (near contact) they come from
    :func:`_near_contact_functions`. Inlined into the caller (numba IR), so that the blend's pair loop
    keeps the 14 values in registers: called, the blend of N = 300 took 0.51 ms, inlined 0.36 ms.
    """
    grid, coefficients, asymptotics, stress_grid, stress_coefficients, stress_asymptotics = tables
    gap = r - 2.0
    f1 = f2 = f3 = f4 = g1 = g2 = g3 = g4 = f_par = f_perp = f_x = 0.0
    if gap < grid[4] and r <= grid[3]:
        return _near_contact_functions(
            gap, near_code, want_icep, want_dep, grid, asymptotics, stress_asymptotics
        )
    if r > grid[3]:
        e_par, e_perp, e_x = near_field_kernel(r, near_code, grid, coefficients, asymptotics)
        if want_icep:
            f1, f2, f3, f4 = near_field_stress_kernel(
                r, 0, stress_grid, stress_coefficients, stress_asymptotics
            )
        if want_dep:
            g1, g2, g3, g4 = near_field_stress_kernel(
                r, 1, stress_grid, stress_coefficients, stress_asymptotics
            )
            f_par, f_perp, f_x = dep_force_kernel(r, stress_grid, stress_coefficients, stress_asymptotics)
        return e_par, e_perp, e_x, f1, f2, f3, f4, g1, g2, g3, g4, f_par, f_perp, f_x
    s = math.log(gap)
    k = min(max(int((s - grid[0]) / grid[1]), 0), int(grid[2]) - 2)
    h = s - (grid[0] + k * grid[1])
    e_par = e_perp = e_x = 0.0
    if near_code != 1:
        e_par += _cubic(coefficients, 0, k, h)
        e_perp += _cubic(coefficients, 1, k, h)
        e_x += _cubic(coefficients, 2, k, h)
    if near_code != 0:
        e_par += _cubic(coefficients, 3, k, h)
        e_perp += _cubic(coefficients, 4, k, h)
        e_x += _cubic(coefficients, 5, k, h)
    if want_icep:
        f1 += _cubic(stress_coefficients, 0, k, h)
        f2 += _cubic(stress_coefficients, 1, k, h)
        f3 += _cubic(stress_coefficients, 2, k, h)
        f4 += _cubic(stress_coefficients, 3, k, h)
    if want_dep:
        g2 += _cubic(stress_coefficients, 4, k, h)
        g3 += _cubic(stress_coefficients, 5, k, h)
        g4 += _cubic(stress_coefficients, 6, k, h)
        f_par = _cubic(stress_coefficients, 7, k, h)
        f_perp = _cubic(stress_coefficients, 8, k, h)
        f_x = _cubic(stress_coefficients, 9, k, h)
    return e_par, e_perp, e_x, f1, f2, f3, f4, g1, g2, g3, g4, f_par, f_perp, f_x


@njit(cache=True, inline="always")
def _accumulate_basis(
    acc: np.ndarray,
    factor: float,
    a1: float,
    a2: float,
    a3: float,
    a4: float,
    x0: float,
    x1: float,
    x2: float,
    c: float,
) -> None:
    """Add one pair's ``factor (a1 T1 + a2 T2 + a3 T3 + a4 T4)`` (:func:`add_basis`) to the sums ``acc``:
    ``A1, P (3), S2, M (xx, xy, xz, yy, yz, zz), R`` of :func:`add_pair_corrections`."""
    b = factor * a2 * c
    m = factor * (a3 + a4 * c * c)
    acc[0] += factor * a1
    acc[1] += b * x0
    acc[2] += b * x1
    acc[3] += b * x2
    acc[4] += b * c
    acc[5] += m * x0 * x0
    acc[6] += m * x0 * x1
    acc[7] += m * x0 * x2
    acc[8] += m * x1 * x1
    acc[9] += m * x1 * x2
    acc[10] += m * x2 * x2
    acc[11] += m


@njit(cache=True)
def _add_accumulated_basis(out: np.ndarray, acc: np.ndarray, e: np.ndarray) -> None:
    """``out += A1 (ee - I/3) + e P + P e - (2/3) S2 I + M - (R/3) I`` from the sums of
    :func:`_accumulate_basis` (``out`` shape ``(3, 3)``)."""
    m = ((acc[5], acc[6], acc[7]), (acc[6], acc[8], acc[9]), (acc[7], acc[9], acc[10]))
    trace = -(acc[0] + 2.0 * acc[4] + acc[11]) / 3.0
    for i in range(3):
        for j in range(3):
            v = acc[0] * e[i] * e[j] + e[i] * acc[1 + j] + acc[1 + i] * e[j] + m[i][j]
            if i == j:
                v += trace
            out[i, j] += v


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

    Nothing is allocated per pair (the loop runs over ~15 N pairs every step).

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
    pairs, separations = build_pair_list(positions, box_length, offset, r_cut)
    return add_pair_corrections(
        pairs,
        separations,
        box_length,
        e,
        icep_weight,
        dep_weight,
        r_cut,
        width,
        tables,
        velocity,
        icep_stress,
        dep_virial,
        dep_stresslet,
    )


@njit(cache=True)
def add_pair_corrections(
    pairs: np.ndarray,
    separations: np.ndarray,
    box_length: float,
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
    """:func:`add_near_field_corrections` for a given list of the pairs closer than ``r_cut``.

    Args:
        pairs: (K, 2) int64 particle indices ``(i, j)``, each pair once, in any order (e.g. the list
            of :func:`sim.dipolophoresis.ewald.dip_far_field_with_pairs`).
        separations: (K, 3) ``x_j - x_i`` of each pair (its image closer than ``L/2``; units a).
        The other arguments as :func:`add_near_field_corrections`.

    Returns:
        K.
    """
    near_code, far_code = mechanism_codes(icep_weight, dep_weight)
    want_icep = icep_weight > 0.0
    want_dep = dep_weight > 0.0
    volume = box_length**3
    e0, e1, e2 = e[0], e[1], e[2]
    # The two stresslet sums in the basis T1..T4 of near_field_stress.add_basis, accumulated in scalars:
    # sum_k (a1 T1 + a2 T2 + (a3 + a4 c^2) T3) = A1 T1 + (e P + P e) - (2/3) S2 I + M - (R/3) I, with
    # A1 = sum a1, P = sum a2 c xh, S2 = sum a2 c^2, M = sum (a3 + a4 c^2) xh xh, R = sum (a3 + a4 c^2).
    # Slot 0 ICEP, slot 1 DEP-induced; the DEP virial in its six independent components.
    basis = np.zeros((2, 12))
    v00 = v01 = v02 = v11 = v12 = v22 = 0.0
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        r = math.sqrt(separations[k, 0] ** 2 + separations[k, 1] ** 2 + separations[k, 2] ** 2)
        w = blend_weight(r, r_cut, width)
        if w == 0.0:
            continue
        x0 = -separations[k, 0] / r  # separations are x_j - x_i; alpha = i, xh from j to i
        x1 = -separations[k, 1] / r
        x2 = -separations[k, 2] / r
        c = e0 * x0 + e1 * x1 + e2 * x2
        # velocity: w (exact - far) in the isotropic form, U_j = -U_i
        (exact_par, exact_perp, exact_x, f1, f2, f3, f4, g1, g2, g3, g4, f_par, f_perp, f_x) = (
            _pair_functions(r, near_code, want_icep, want_dep, tables)
        )
        far_par, far_perp, far_x = far_field_functions(r, far_code)
        radial = (exact_par - far_par) * c * c + (exact_perp - far_perp) * (1.0 - c * c)
        tangential = 2.0 * (exact_x - far_x) * c
        du = w * (radial * x0 + tangential * (e0 - c * x0))
        velocity[i, 0] += du
        velocity[j, 0] -= du
        du = w * (radial * x1 + tangential * (e1 - c * x1))
        velocity[i, 1] += du
        velocity[j, 1] -= du
        du = w * (radial * x2 + tangential * (e2 - c * x2))
        velocity[i, 2] += du
        velocity[j, 2] -= du
        # stresses; table units pi eps a^3 E0^2 (stresslets) and pi eps a^2 E0^2 (forces)
        scale = math.pi * w / volume
        if want_icep:  # exact minus the far-field pair correction (in the Ewald sum; docs/model.md)
            inv_r3 = 1.0 / (r * r * r)
            far1, far2, far3, far4 = ICEP_PAIR_FAR_FIELD
            _accumulate_basis(
                basis[0],
                2.0 * scale,
                f1 - far1 * inv_r3,
                f2 - far2 * inv_r3,
                f3 - far3 * inv_r3,
                f4 - far4 * inv_r3,
                x0,
                x1,
                x2,
                c,
            )
        if want_dep:
            _accumulate_basis(basis[1], 2.0 * scale, g1, g2, g3, g4, x0, x1, x2, c)
            inv_r4 = 1.0 / (r * r * r * r)  # far field F = -3 W / r^4, W = (5c^2 - 1) xh - 2 c e
            force_radial = f_par * c * c + f_perp * (1.0 - c * c) + 3.0 * inv_r4 * (5.0 * c * c - 1.0)
            force_tangential = 2.0 * f_x * c
            # F^exact_alpha - F^far_alpha
            d0 = force_radial * x0 + force_tangential * (e0 - c * x0) - 6.0 * inv_r4 * c * e0
            d1 = force_radial * x1 + force_tangential * (e1 - c * x1) - 6.0 * inv_r4 * c * e1
            d2 = force_radial * x2 + force_tangential * (e2 - c * x2) - 6.0 * inv_r4 * c * e2
            h = 0.5 * scale * r
            v00 += h * (x0 * d0 + x0 * d0)
            v01 += h * (x0 * d1 + x1 * d0)
            v02 += h * (x0 * d2 + x2 * d0)
            v11 += h * (x1 * d1 + x1 * d1)
            v12 += h * (x1 * d2 + x2 * d1)
            v22 += h * (x2 * d2 + x2 * d2)
    if want_icep:
        _add_accumulated_basis(icep_stress, basis[0], e)
    if want_dep:
        _add_accumulated_basis(dep_stresslet, basis[1], e)
        dep_virial[0, 0] -= v00
        dep_virial[1, 1] -= v11
        dep_virial[2, 2] -= v22
        dep_virial[0, 1] -= v01
        dep_virial[1, 0] -= v01
        dep_virial[0, 2] -= v02
        dep_virial[2, 0] -= v02
        dep_virial[1, 2] -= v12
        dep_virial[2, 1] -= v12
    return pairs.shape[0]
