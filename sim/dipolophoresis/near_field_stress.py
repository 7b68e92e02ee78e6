"""Exact two-sphere stresslets and DEP force: table loader, splines and compiled tensor helpers.

For a pair of equal ideally polarisable spheres at centre distance ``r`` (units of the radius ``a``),
``x = x_alpha - x_beta`` (from beta to alpha), ``xh = x/r``, field ``E0 e``, ``c = e . xh``, every stresslet
below is (Batchelor 1970 sign convention, units ``pi eps a^3 E0^2``)

    S = f1 T1 + f2 T2 + f3 T3 + f4 T4,
    T1 = ee - I/3,  T2 = c (e xh + xh e) - (2/3) c^2 I,  T3 = xh xh - I/3,  T4 = c^2 (xh xh - I/3),

the general symmetric traceless tensor quadratic in ``e`` (derivation, completeness and the m = 0, 1, 2
superposition: :mod:`sim.dipolophoresis.two_sphere.stresslet`). Two mechanisms:

* ``icep``: ``(f1, f2, f3, f4)`` of the ICEP pair correction ``dS = S_alpha - S0`` of ONE sphere
  (``S0 = 9 (ee - I/3)``; force- and torque-free spheres with the induced-charge slip; ``S_beta = S_alpha``).
  Far field (docs/model.md#dipolophoresis, confirmed by the exact solution): ``(9, -36, -45/2, 225/2)/r^3``,
  exact minus far field ``~ -(57/2)(1, -5, -5/2, 35/2)/r^5``.
* ``dep``: ``(g1, g2, g3, g4)`` of the stresslet of ONE sphere moving rigidly under the exact Maxwell forces
  ``+-F`` (``g1 = 0``: no ``cos 2 phi`` forcing); far field ``(0, 8/r^8, 15/(2 r^6), -45/(2 r^6)``.
* ``dip``: the sum.

and the exact DEP force on alpha (units ``pi eps a^2 E0^2``; beta feels ``-F_alpha``):

    F_alpha = (F_par c^2 + F_perp (1 - c^2)) xh + F_x sin(2 th) t
            = (F_par c^2 + F_perp (1 - c^2)) xh + 2 F_x c (e - c xh),

far field ``(F_par, F_perp, F_x) = (-6, 3, 3)/r^4`` (``F = -3 W/r^4``, docs/model.md#dipolophoresis).

Bulk stress of a pair (what the time step needs; docs/model.md#dip-stress and #bulk-stress). The ICEP part
of ``n <S^d>`` gets ``S0`` per sphere plus ``dS`` for each sphere of every pair; the DEP part is the pair
virial ``-x F_alpha`` (symmetrised) plus the DEP-induced stresslets of both spheres. The far field (Ewald)
already holds the O(r^-3) ``dS`` of docs/model.md#icep-pair-stresslet and the virial of ``-3 W/r^4``; for
pairs with ``r < r_c`` add
``(exact - far field)`` for both spheres (:func:`pair_stress_corrections`) and the virial correction
``-sym(x (F_exact - F_far))``. The DEP-induced stresslet has no far-field counterpart (O(r^-6)) and is added
whole. What is exact and what is approximated: the two-sphere values are exact (to the table accuracy below)
for an isolated pair; the suspension stress assumes pairwise additivity of these corrections (three-body
effects neglected, as for the velocities) and the blend to the far field at ``r_c`` is the caller's.

Regimes (as :mod:`sim.dipolophoresis.near_field`):

* ``2.0005 <= r <= 10``: cubic not-a-knot splines in ``s = ln(r - 2)`` through
  ``tables/near_field_stress.txt`` (the nodes of ``near_field.txt``), written by
  ``scripts/generate_near_field_stress_table.py``. Accuracy: truncation (``L = 14 + 10/sqrt(r - 2)``,
  checked against ``c = 14``) <= 2e-6 for ICEP (at r = 2.0005, where f4 = -16.6), 3e-7 at r = 2.005,
  2e-8 at 2.02, < 1e-13 beyond 2.5; DEP stresslet <= 2e-8, force <= 3e-10 (the table's stored
  ``error_*`` columns, ``c = 10`` vs ``c = 8``, are ~30x larger: conservative); spline interpolation
  < 5e-9 absolute (:data:`SPLINE_ERROR_NOTE`);
* ``r > 10``: the far-field forms above (jump at ``r = 10``: see :data:`FAR_FIELD_JUMP_NOTE`);
* gap ``xi = r - 2 < 5e-4``: ``F = C + A xi^p`` fitted exactly through the nodes at ``xi_0``, ``~1.19 xi_0``,
  ``~1.42 xi_0`` (:func:`~sim.dipolophoresis.two_sphere.stresslet.fit_shifted_power`), ``xi`` floored at
  :data:`~sim.dipolophoresis.near_field.GAP_FLOOR`. ``f2, f4`` (and ``f3``) diverge weakly (``p ~ -0.21,
  -0.16``) through the singular transverse field in the gap, like ICEP ``F_x``; the others tend to finite
  contact values. Against exact solutions (L up to 1014, in the table header) the forms are off at
  ``xi = 1e-4`` by 0.2 % (f2), 0.3 % (f3), 0.6 % (f4), 1e-5 relative (f1), <= 0.09 % (DEP ``g``), 0.01 %
  (force), and at ``xi = 3e-4`` by 10x less. Below ``xi ~ 1e-4`` the divergent ``f2, f3, f4`` are
  extrapolations (at the floor ``xi = 1e-6``: ``f2 = 29.7``, ``f4 = -59.2``; uncertain by tens of percent).
* ``r < 2``: :class:`ValueError`.

Two evaluators share the coefficient arrays: numpy (:func:`pair_stress_functions`,
:func:`dep_force_functions`) and numba (:func:`near_field_stress_kernel`, :func:`dep_force_kernel`,
:func:`pair_stress_tensors`, :func:`pair_stress_corrections`), which take the arrays as arguments (safe
with numba's on-disk cache).

References:
    G. K. Batchelor, J. Fluid Mech. 41, 545 (1970); D. Saintillan, Phys. Fluids 20, 067104 (2008);
    S. Kim & S. J. Karrila, Microhydrodynamics (1991); D. J. Jeffrey, Phys. Fluids A 4, 16 (1992).
"""

from __future__ import annotations

import math
from typing import Final, overload

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from sim.dipolophoresis.near_field import (
    GAP_FLOOR,
    MECHANISMS,
    evaluate_piecewise,
    mechanism_code,
    spline_coefficients,
    validate_separations,
)
from sim.dipolophoresis.two_sphere.stresslet import (
    STRESS_FUNCTION_NAMES,
    StressTable,
    fit_shifted_power,
    near_contact_nodes,
    read_stress_table_text,
)
from sim.dipolophoresis.two_sphere.tabulation import log_gap_grid, packaged_table_text

FloatArray = NDArray[np.float64]

__all__ = [
    "FAR_FIELD_JUMP_NOTE",
    "SPLINE_ERROR_NOTE",
    "MECHANISMS",
    "R_STRESS_TABLE_MAX",
    "R_STRESS_TABLE_MIN",
    "STRESS_ASYMPTOTICS",
    "STRESS_COEFFICIENTS",
    "STRESS_GRID",
    "STRESS_TABLE",
    "build_stress_coefficients",
    "dep_force_functions",
    "dep_force_kernel",
    "load_stress_table",
    "near_field_stress_kernel",
    "pair_stress_corrections",
    "pair_stress_functions",
    "pair_stress_tensors",
]

N_FUNCTIONS: Final = len(STRESS_FUNCTION_NAMES)
"""10 tabulated functions: ICEP ``f1..f4`` (0-3), DEP ``g2..g4`` (4-6), force ``F_par, F_perp, F_x`` (7-9)."""

FAR_FIELD_JUMP_NOTE: Final = (
    "at r = 10 the exact functions differ from the far-field forms by 2.8e-4 (f1), 1.5e-3 (f2), 5.8e-4 (f3), "
    "4.8e-3 (f4) [3 % of the O(r^-3) values: the r^-5 residual -(57/2)(1, -5, -5/2, 35/2)/r^5], 1.1e-7 for "
    "the DEP stresslet (g4) and 1.2e-6 for the DEP force (F_par, 0.2 %)"
)
"""The discontinuity of the isolated-pair functions at the last node (the caller blends at ``r_c <= 10``)."""

SPLINE_ERROR_NOTE: Final = (
    "cubic not-a-knot spline in ln(r-2), 486 nodes, ds = 0.02; error estimated by re-splining every second "
    "node and dividing by 16: < 3e-9 absolute (ICEP f4 near contact), < 2.5e-7 relative; fresh exact solves "
    "between nodes agree to 1e-7 relative (tests/test_near_field_stress.py)"
)


def load_stress_table() -> StressTable:
    """Read the packaged table ``sim/dipolophoresis/tables/near_field_stress.txt``."""
    return read_stress_table_text(packaged_table_text("near_field_stress.txt"))


def build_stress_coefficients(table: StressTable) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Spline coefficients and near-contact parameters.

    Returns:
        ``(grid, coefficients, asymptotics)``: ``grid`` shape ``(6,)`` (``s_0 = ln xi_0``, ``ds``, number of
        nodes, ``r_end``, ``xi_0``, gap floor); ``coefficients`` shape ``(10, n - 1, 4)`` (ascending powers of
        ``s - s_k``); ``asymptotics`` shape ``(10, 3)``: ``(C, A, p)`` of ``C + A xi^p``.

    Raises:
        ValueError: if the nodes are not uniform in ``ln(r - 2)``.
    """
    grid = log_gap_grid(table.r, GAP_FLOOR, "near-field stress table")
    coefficients = spline_coefficients(table.values, grid[1])
    asymptotics = np.empty((N_FUNCTIONS, 3))
    nodes = near_contact_nodes(table.r)
    for k in range(N_FUNCTIONS):
        asymptotics[k] = fit_shifted_power(table.r[nodes] - 2.0, table.values[k, nodes])
    return grid, coefficients, asymptotics


STRESS_TABLE: Final = load_stress_table()
STRESS_GRID, STRESS_COEFFICIENTS, STRESS_ASYMPTOTICS = build_stress_coefficients(STRESS_TABLE)
R_STRESS_TABLE_MIN: Final = float(STRESS_TABLE.r[0])
"""First node (``2.0005``); below it the near-contact forms."""
R_STRESS_TABLE_MAX: Final = float(STRESS_TABLE.r[-1])
"""Last node (``10``); beyond it the far-field forms."""


@njit(cache=True)
def _far_field(r: float, function: int) -> float:
    """Far-field form of function ``function`` (order of ``STRESS_FUNCTION_NAMES``)."""
    r3 = r * r * r
    if function == 0:
        return 9.0 / r3
    if function == 1:
        return -36.0 / r3
    if function == 2:
        return -22.5 / r3
    if function == 3:
        return 112.5 / r3
    r4 = r3 * r
    r6 = r3 * r3
    if function == 4:
        return 8.0 / (r6 * r * r)
    if function == 5:
        return 7.5 / r6
    if function == 6:
        return -22.5 / r6
    if function == 7:
        return -6.0 / r4
    return 3.0 / r4


@njit(cache=True)
def _evaluate(
    r: float, function: int, grid: FloatArray, coefficients: FloatArray, asymptotics: FloatArray
) -> float:
    """One tabulated function at ``r`` (spline, near-contact form or far field)."""
    gap = r - 2.0
    if r > grid[3]:
        return _far_field(r, function)
    if gap < grid[4]:
        gap = max(gap, grid[5])
        return asymptotics[function, 0] + asymptotics[function, 1] * gap ** asymptotics[function, 2]
    s = math.log(gap)
    k = min(max(int((s - grid[0]) / grid[1]), 0), int(grid[2]) - 2)
    h = s - (grid[0] + k * grid[1])
    c = coefficients[function, k]
    return c[0] + h * (c[1] + h * (c[2] + h * c[3]))


@njit(cache=True)
def near_field_stress_kernel(
    r: float, mechanism_code: int, grid: FloatArray, coefficients: FloatArray, asymptotics: FloatArray
) -> tuple[float, float, float, float]:
    """``(f1, f2, f3, f4)`` at centre distance ``r`` for one mechanism (compiled).

    Args:
        r: centre distance ``r/a`` (below 2 treated as contact; callers should not pass overlaps).
        mechanism_code: 0 ICEP pair correction, 1 DEP-induced stresslet, 2 their sum
            (:data:`~sim.dipolophoresis.near_field.MECHANISMS`).
        grid, coefficients, asymptotics: :data:`STRESS_GRID`, :data:`STRESS_COEFFICIENTS`,
            :data:`STRESS_ASYMPTOTICS`.

    Returns:
        The four scalar functions, units ``pi eps a^3 E0^2``.
    """
    f1 = f2 = f3 = f4 = 0.0
    if mechanism_code != 1:
        f1 += _evaluate(r, 0, grid, coefficients, asymptotics)
        f2 += _evaluate(r, 1, grid, coefficients, asymptotics)
        f3 += _evaluate(r, 2, grid, coefficients, asymptotics)
        f4 += _evaluate(r, 3, grid, coefficients, asymptotics)
    if mechanism_code != 0:
        f2 += _evaluate(r, 4, grid, coefficients, asymptotics)
        f3 += _evaluate(r, 5, grid, coefficients, asymptotics)
        f4 += _evaluate(r, 6, grid, coefficients, asymptotics)
    return f1, f2, f3, f4


@njit(cache=True)
def dep_force_kernel(
    r: float, grid: FloatArray, coefficients: FloatArray, asymptotics: FloatArray
) -> tuple[float, float, float]:
    """Exact DEP force functions ``(F_par, F_perp, F_x)`` (units ``pi eps a^2 E0^2``), compiled."""
    return (
        _evaluate(r, 7, grid, coefficients, asymptotics),
        _evaluate(r, 8, grid, coefficients, asymptotics),
        _evaluate(r, 9, grid, coefficients, asymptotics),
    )


ICEP_PAIR_FAR_FIELD: Final = (9.0, -36.0, -22.5, 112.5)
"""``r^3 (f1, f2, f3, f4)`` of docs/model.md#dip-far-field's far-field ICEP pair correction
``dS = r^-3 [9 ee - 36 c (e xh + xh e) + (225/2 c^2 - 45/2) xh xh + (9/2 - 27/2 c^2) I]`` in this basis."""


@njit(cache=True)
def add_basis(
    out: FloatArray, factor: float, f1: float, f2: float, f3: float, f4: float, xh: FloatArray, e: FloatArray
) -> None:
    """``out += factor (f1 T1 + f2 T2 + f3 T3 + f4 T4)``, ``out`` shape ``(3, 3)``, with ``T1 = ee - I/3``,
    ``T2 = c (e xh + xh e) - (2/3) c^2 I``, ``T3 = xh xh - I/3``, ``T4 = c^2 (xh xh - I/3)``, ``c = e.xh``."""
    c = e[0] * xh[0] + e[1] * xh[1] + e[2] * xh[2]
    radial = f3 + f4 * c * c
    trace = -(f1 + 2.0 * f2 * c * c + radial) / 3.0
    for i in range(3):
        for j in range(3):
            v = f1 * e[i] * e[j] + f2 * c * (e[i] * xh[j] + xh[i] * e[j]) + radial * xh[i] * xh[j]
            if i == j:
                v += trace
            out[i, j] += factor * v


@njit(cache=True)
def _assemble(f1: float, f2: float, f3: float, f4: float, xh: FloatArray, e: FloatArray) -> FloatArray:
    """``f1 T1 + f2 T2 + f3 T3 + f4 T4``, shape ``(3, 3)`` (:func:`add_basis`)."""
    out = np.zeros((3, 3))
    add_basis(out, 1.0, f1, f2, f3, f4, xh, e)
    return out


@njit(cache=True)
def pair_stress_tensors(
    xh: FloatArray,
    e: FloatArray,
    r: float,
    grid: FloatArray,
    coefficients: FloatArray,
    asymptotics: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exact pair tensors of one pair (compiled).

    Args:
        xh: shape ``(3,)``, unit vector from beta to alpha.
        e: shape ``(3,)``, unit field direction.
        r: centre distance ``r/a`` (>= 2).
        grid, coefficients, asymptotics: :data:`STRESS_GRID`, :data:`STRESS_COEFFICIENTS`,
            :data:`STRESS_ASYMPTOTICS`.

    Returns:
        ``(icep_correction, dep_stresslet, dep_force)``: the ICEP pair correction ``dS`` of ONE sphere and
        the DEP-induced stresslet of ONE sphere (each ``(3, 3)``, units ``pi eps a^3 E0^2``, the same for
        alpha and beta), and the exact DEP force on alpha (``(3,)``, units ``pi eps a^2 E0^2``; beta feels
        its negative).
    """
    c = e[0] * xh[0] + e[1] * xh[1] + e[2] * xh[2]
    f1, f2, f3, f4 = near_field_stress_kernel(r, 0, grid, coefficients, asymptotics)
    icep = _assemble(f1, f2, f3, f4, xh, e)
    g1, g2, g3, g4 = near_field_stress_kernel(r, 1, grid, coefficients, asymptotics)
    dep = _assemble(g1, g2, g3, g4, xh, e)
    f_par, f_perp, f_x = dep_force_kernel(r, grid, coefficients, asymptotics)
    radial = f_par * c * c + f_perp * (1.0 - c * c)
    force = np.empty(3)
    for i in range(3):
        force[i] = radial * xh[i] + 2.0 * f_x * c * (e[i] - c * xh[i])
    return icep, dep, force


@njit(cache=True)
def pair_stress_corrections(
    xh: FloatArray,
    e: FloatArray,
    r: float,
    grid: FloatArray,
    coefficients: FloatArray,
    asymptotics: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exact minus far field, for the near-field correction of the bulk stress (compiled).

    Same arguments and units as :func:`pair_stress_tensors`. Returns ``(dS_exact - dS_far, S_dep, F_exact -
    F_far)`` with docs/model.md#dip-far-field's far fields ``dS_far = r^-3 [9 T1 - 36 T2 - (45/2) T3 +
    (225/2) T4]`` and
    ``F_far = -3 W/r^4`` (``W = (5c^2 - 1) xh - 2 c e``); ``S_dep`` is returned whole (no far-field term).
    Multiply stresslets by ``pi eps a^3 E0^2`` and forces by ``pi eps a^2 E0^2``.
    """
    icep, dep, force = pair_stress_tensors(xh, e, r, grid, coefficients, asymptotics)
    c = e[0] * xh[0] + e[1] * xh[1] + e[2] * xh[2]
    inv_r3 = 1.0 / (r * r * r)
    f1, f2, f3, f4 = ICEP_PAIR_FAR_FIELD
    far = _assemble(f1 * inv_r3, f2 * inv_r3, f3 * inv_r3, f4 * inv_r3, xh, e)
    inv_r4 = inv_r3 / r
    for i in range(3):
        force[i] += 3.0 * inv_r4 * ((5.0 * c * c - 1.0) * xh[i] - 2.0 * c * e[i])
        for j in range(3):
            icep[i, j] -= far[i, j]
    return icep, dep, force


def _evaluate_numpy(r: FloatArray, function: int) -> FloatArray:
    """Vectorised twin of the compiled evaluator for one function."""
    c_fit, a_fit, p_fit = STRESS_ASYMPTOTICS[function]

    def far_field(rf: FloatArray) -> FloatArray:
        far_values = (
            9.0 / rf**3, -36.0 / rf**3, -22.5 / rf**3, 112.5 / rf**3,
            8.0 / rf**8, 7.5 / rf**6, -22.5 / rf**6,
            -6.0 / rf**4, 3.0 / rf**4, 3.0 / rf**4,
        )  # fmt: skip
        return far_values[function]

    def near_contact(gap: FloatArray) -> FloatArray:
        return c_fit + a_fit * gap**p_fit

    return evaluate_piecewise(r, STRESS_GRID, STRESS_COEFFICIENTS[function], far_field, near_contact)


@overload
def pair_stress_functions(r: float, mechanism: str = "icep") -> tuple[float, float, float, float]: ...


@overload
def pair_stress_functions(
    r: ArrayLike, mechanism: str = "icep"
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]: ...


def pair_stress_functions(
    r: ArrayLike, mechanism: str = "icep"
) -> tuple[float, float, float, float] | tuple[FloatArray, ...]:
    """Scalar functions ``(f1, f2, f3, f4)`` of the exact two-sphere stresslet, units ``pi eps a^3 E0^2``.

    ``S = f1 (ee - I/3) + f2 [c (e xh + xh e) - (2/3) c^2 I] + f3 (xh xh - I/3) + f4 c^2 (xh xh - I/3)`` for
    ONE sphere of an isolated pair (no images, no blending), ``xh`` from beta to alpha, ``c = e . xh``.

    Args:
        r: centre distance(s) ``r/a`` (float or array of any shape), ``r >= 2``.
        mechanism: ``"icep"`` (pair correction ``S_alpha - 9 (ee - I/3)``), ``"dep"`` (stresslet induced by
            the rigid motion under the exact DEP forces; ``f1 = 0``) or ``"dip"`` (their sum).

    Returns:
        Four floats for a scalar ``r``, else four arrays shaped like ``r``.

    Raises:
        ValueError: if ``mechanism`` is unknown, or if ``r`` < 2 or is not finite.
    """
    code = mechanism_code(mechanism)
    scalar, r_array = validate_separations(r)
    flat = r_array.ravel()
    results = [np.zeros_like(flat) for _ in range(4)]
    if code != 1:
        for k in range(4):
            results[k] += _evaluate_numpy(flat, k)
    if code != 0:
        for k in range(1, 4):
            results[k] += _evaluate_numpy(flat, k + 3)
    if scalar:
        return float(results[0][0]), float(results[1][0]), float(results[2][0]), float(results[3][0])
    shaped = tuple(result.reshape(r_array.shape) for result in results)
    return shaped[0], shaped[1], shaped[2], shaped[3]


@overload
def dep_force_functions(r: float) -> tuple[float, float, float]: ...


@overload
def dep_force_functions(r: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]: ...


def dep_force_functions(r: ArrayLike) -> tuple[float, float, float] | tuple[FloatArray, ...]:
    """Exact Maxwell (DEP) force functions ``(F_par, F_perp, F_x)`` on alpha, units ``pi eps a^2 E0^2``.

    ``F_alpha = (F_par c^2 + F_perp (1 - c^2)) xh + F_x sin(2 th) t``, ``t`` the unit vector of ``e - c xh``;
    beta feels ``-F_alpha``. Far field ``(-6, 3, 3)/r^4``.

    Args:
        r: centre distance(s) ``r/a`` (float or array), ``r >= 2``.

    Returns:
        Three floats for a scalar ``r``, else three arrays shaped like ``r``.

    Raises:
        ValueError: if ``r`` < 2 or is not finite.
    """
    scalar, r_array = validate_separations(r)
    flat = r_array.ravel()
    results = [_evaluate_numpy(flat, k) for k in (7, 8, 9)]
    if scalar:
        return float(results[0][0]), float(results[1][0]), float(results[2][0])
    shaped = tuple(result.reshape(r_array.shape) for result in results)
    return shaped[0], shaped[1], shaped[2]
