"""Exact two-sphere dipolophoresis functions: table loader, splines and the ``pair_functions`` contract.

For a pair of equal ideally polarisable spheres at centre distance ``r`` (units of the radius ``a``),
``x = x_alpha - x_beta``, ``xh = x/r``, field ``E0 e`` at angle ``th`` to ``xh`` and ``t`` the unit
vector of ``e`` perpendicular to ``xh``, the velocity of sphere ``alpha`` is (docs/model.md#dipolophoresis)

    U_alpha = U0 [ (F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t ],   U0 = eps a E0^2/eta,

separately for induced-charge electrophoresis (ICEP) and dielectrophoresis (DEP); ``dip`` is their
sum. This module serves the isolated two-sphere problem (no periodic images, no blending):

* ``2.0005 <= r <= r_end`` (``r_end = 10``): cubic splines (not-a-knot, :func:`not_a_knot_spline`) in
  ``s = ln(r - 2)`` through the table ``tables/near_field.txt``, computed offline by
  ``scripts/generate_near_field_table.py`` with the twin-multipole solvers of
  :mod:`sim.dipolophoresis.two_sphere` (Saintillan 2008 method: electric problem of insulating spheres,
  Lamb's solution for the Stokes problems). The table's nodes are
  uniform in ``s`` (dense near contact); its header states the truncation orders and the estimated
  error per ``r``. Spline error: see :data:`SPLINE_ERROR_NOTE`.
* ``r > r_end``: the far-field forms of Saintillan (2008) / the paper (eqs 2.3-2.4):
  ICEP ``F_par = -9/(4r^2) + 11/(2r^4)``, ``F_perp = 9/(8r^2) - 11/(4r^4)``, ``F_x = -11/(4r^4)``;
  DEP ``F_par = -1/r^4``, ``F_perp = F_x = 1/(2r^4)``. The exact functions differ from these by
  ``O(r^-5)`` (``r^5`` times the difference tends to ``-27/4, 27/4, 0`` for ICEP and ``3/2, -3/4, -3/8``
  for DEP -- the last three are the Oseen corrections ``1 - 3/(2r)``, ``1 - 3/(4r)`` of the relative
  mobilities), so ``pair_functions`` jumps at ``r_end = 10`` by at most 6.6e-5 U0 (ICEP: 0.3 % and
  0.6 % of ``F_par``, ``F_perp``; DEP: 1.5e-5 U0, which is 15 % of the small DEP value there).
* ``2 <= r < 2.0005`` (gap ``xi = r - 2`` below the first node ``xi_0 = 5e-4``): near-contact forms
  fitted exactly through the nodes at ``xi_0``, ``~2 xi_0``, ``~4 xi_0`` (continuous at ``xi_0``;
  :func:`~sim.dipolophoresis.two_sphere.tabulation.fit_near_contact`): ``F = A xi^p (1 + B xi)`` for
  ICEP ``F_par, F_perp, F_x`` and DEP ``F_par, F_perp``, and ``F = C + a/L + b/L^2`` (``L = ln(1/xi)``)
  for DEP ``F_x``. The fitted exponents are physical: the ``F_par`` (ICEP, DEP) and DEP ``F_perp``
  vanish linearly (squeeze lubrication, ``p = 1.00, 1.00, 0.97``); ICEP ``F_perp`` vanishes like
  ``xi^0.41`` and ICEP ``F_x`` grows like ``xi^-0.22``, because the transverse field in the thin gap
  between insulating spheres is singular (the thin-film potential behaves like ``rho^(sqrt 2 - 1)``,
  ``sqrt 2 - 1 = 0.414``); DEP ``F_x`` tends to a constant. Against exact solutions at
  ``xi = 1e-4 .. 3e-4`` the forms are within 0.25 % (ICEP ``F_perp``), 0.07 % (ICEP ``F_x``, ``F_par``),
  0.05 % (DEP ``F_x``, 6e-6 U0) and 2e-7 U0 (DEP ``F_par``, ``F_perp``); see the table header. ``xi`` is
  floored at :data:`GAP_FLOOR` = 1e-6, where ICEP ``F_x = -3.09`` (-0.78 at the first node).
* ``r < 2``: :class:`ValueError` (overlapping spheres are not a two-sphere state).

Two evaluators share the same coefficient arrays: :func:`pair_functions` (numpy, vectorised, the
public contract) and the numba kernels :func:`near_field_kernel` (arrays passed in: safe with numba's
on-disk cache) and :func:`near_field_functions` (module-level arrays frozen at compile time; the
numba cache key must then change when the table changes -- see ``sim/numba_cache.py``).

References:
    D. Saintillan, Phys. Fluids 20, 067104 (2008); Mirfendereski & Park, J. Fluid Mech. (2024), eqs 2.3-2.4.
    D. J. Jeffrey & Y. Onishi, J. Fluid Mech. 139, 261 (1984); S. Kim & S. J. Karrila (1991).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final, overload

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from sim.dipolophoresis.two_sphere.tabulation import (
    LOG_FORM,
    NEAR_CONTACT_FORMS,
    NearFieldTable,
    fit_near_contact,
    log_gap_grid,
    near_contact_points,
    packaged_table_text,
    read_table_text,
)

FloatArray = NDArray[np.float64]

MECHANISMS: Final = {"icep": 0, "dep": 1, "dip": 2}
"""Mechanism name -> code of :func:`near_field_functions` (``dip`` = ``icep`` + ``dep``)."""

GAP_FLOOR: Final = 1e-6
"""Smallest gap ``r - 2`` used by the near-contact forms (ICEP ``F_x`` diverges weakly at contact)."""

SPLINE_ERROR_NOTE: Final = (
    "cubic not-a-knot spline in ln(r-2), 486 nodes, ds = 0.02; interpolation error estimated by re-splining "
    "every second node and dividing the error at the skipped nodes by 16: < 1e-9 U0 (measured 6e-10), "
    "tested < 1e-8; fresh exact solves between nodes agree to < 5e-9 U0 (tests/test_near_field.py)"
)


def load_table() -> NearFieldTable:
    """Read the packaged table ``sim/dipolophoresis/tables/near_field.txt`` (package data)."""
    return read_table_text(packaged_table_text("near_field.txt"))


def not_a_knot_spline(values: FloatArray, spacing: float) -> FloatArray:
    """Cubic not-a-knot spline through values on a uniform grid (de Boor 1978, ch. IV).

    The second derivatives ``M_k`` solve ``M_{k-1} + 4 M_k + M_{k+1} = 6 (y_{k+1} - 2 y_k + y_{k-1})/h^2``
    at interior nodes, with continuous third derivatives at the second and the last-but-one nodes
    (``M_0 - 2 M_1 + M_2 = 0`` and the mirror condition).

    Args:
        values: shape ``(n,)``, ``n >= 4``, function values at the nodes.
        spacing: the uniform node spacing ``h``.

    Returns:
        shape ``(n - 1, 4)``: on interval ``k`` the cubic ``c0 + c1 t + c2 t^2 + c3 t^3``, ``t = s - s_k``.
    """
    y = np.asarray(values, dtype=float)
    n = y.shape[0]
    h = float(spacing)
    system = np.zeros((n, n))
    rhs = np.zeros(n)
    rows = np.arange(1, n - 1)
    system[rows, rows - 1] = 1.0
    system[rows, rows] = 4.0
    system[rows, rows + 1] = 1.0
    rhs[1:-1] = 6.0 * (y[2:] - 2.0 * y[1:-1] + y[:-2]) / h**2
    system[0, :3] = (1.0, -2.0, 1.0)
    system[-1, -3:] = (1.0, -2.0, 1.0)
    second = np.linalg.solve(system, rhs)
    coefficients = np.empty((n - 1, 4))
    coefficients[:, 0] = y[:-1]
    coefficients[:, 1] = (y[1:] - y[:-1]) / h - h * (2.0 * second[:-1] + second[1:]) / 6.0
    coefficients[:, 2] = 0.5 * second[:-1]
    coefficients[:, 3] = (second[1:] - second[:-1]) / (6.0 * h)
    return coefficients


def spline_coefficients(values: FloatArray, spacing: float) -> FloatArray:
    """:func:`not_a_knot_spline` of every row of ``values`` (shape ``(n_functions, n)``).

    Returns:
        shape ``(n_functions, n - 1, 4)``, C-contiguous: ascending powers of ``s - s_k`` on interval ``k``.
    """
    coefficients = np.empty((values.shape[0], values.shape[1] - 1, 4))
    for k in range(values.shape[0]):
        coefficients[k] = not_a_knot_spline(values[k], spacing)
    return np.ascontiguousarray(coefficients)


def build_coefficients(table: NearFieldTable) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Spline coefficients and the parameters of the evaluators.

    Returns:
        ``(grid, coefficients, asymptotics)``:

        * ``grid``: shape ``(6,)``: ``s_0 = ln(xi_0)``, ``ds``, number of nodes, ``r_end``, ``xi_0``,
          :data:`GAP_FLOOR`;
        * ``coefficients``: shape ``(6, n - 1, 4)``, ascending powers of ``s - s_k`` on interval ``k``
          (:func:`not_a_knot_spline`);
        * ``asymptotics``: shape ``(6, 4)``: form code (:data:`NEAR_CONTACT_FORMS`) and its three
          parameters (:func:`fit_near_contact`).

    Raises:
        ValueError: if the nodes are not uniform in ``ln(r - 2)``.
    """
    grid = log_gap_grid(table.r, GAP_FLOOR, "near-field table")
    coefficients = spline_coefficients(table.values, grid[1])
    asymptotics = np.empty((6, 4))
    fit_nodes = near_contact_points(table.r)
    for k in range(6):
        form = NEAR_CONTACT_FORMS[k]
        asymptotics[k, 0] = form
        asymptotics[k, 1:] = fit_near_contact(table.r[fit_nodes] - 2.0, table.values[k, fit_nodes], form)
    return grid, coefficients, asymptotics


TABLE: Final = load_table()
NEAR_FIELD_GRID, NEAR_FIELD_COEFFICIENTS, NEAR_FIELD_ASYMPTOTICS = build_coefficients(TABLE)
R_TABLE_MIN: Final = float(TABLE.r[0])
"""First table node (``2.0005``); below it the near-contact forms are used."""
R_TABLE_MAX: Final = float(TABLE.r[-1])
"""Last table node; beyond it the far-field forms are used."""


@njit(cache=True)
def _far_field(r: float, function: int) -> float:
    """Far-field forms of docs/model.md#dipolophoresis (function index as in FUNCTION_NAMES)."""
    r2 = r * r
    r4 = r2 * r2
    if function == 0:
        return -9.0 / (4.0 * r2) + 11.0 / (2.0 * r4)
    if function == 1:
        return 9.0 / (8.0 * r2) - 11.0 / (4.0 * r4)
    if function == 2:
        return -11.0 / (4.0 * r4)
    if function == 3:
        return -1.0 / r4
    return 0.5 / r4


@njit(cache=True)
def _near_contact(gap: float, parameters: FloatArray) -> float:
    """Near-contact form: power ``A xi^p (1 + B xi)`` (code 0) or ``C + a/L + b/L^2``, ``L = ln(1/xi)``."""
    if parameters[0] == LOG_FORM:
        inverse_log = 1.0 / math.log(1.0 / gap)
        return parameters[1] + inverse_log * (parameters[2] + inverse_log * parameters[3])
    return parameters[1] * gap ** parameters[3] * (1.0 + parameters[2] * gap)


@njit(cache=True)
def _accumulate(
    out0: float, out1: float, out2: float, index: int, value: float
) -> tuple[float, float, float]:
    """Add ``value`` to component ``index`` of a 3-tuple (the kernels allocate nothing per call)."""
    if index == 0:
        return out0 + value, out1, out2
    if index == 1:
        return out0, out1 + value, out2
    return out0, out1, out2 + value


@njit(cache=True)
def near_field_kernel(
    r: float, mechanism_code: int, grid: FloatArray, coefficients: FloatArray, asymptotics: FloatArray
) -> tuple[float, float, float]:
    """``(F_par, F_perp, F_x)`` at centre distance ``r >= 2`` for one mechanism (compiled).

    One logarithm and one interval search per call, then a cubic per function (ICEP: functions 0-2,
    DEP: 3-5, DIP: their sums).

    Args:
        r: centre distance ``r/a``; values below 2 are treated as contact (gap floored at
            :data:`GAP_FLOOR`; callers should not pass overlaps).
        mechanism_code: 0 ICEP, 1 DEP, 2 DIP (sum).
        grid, coefficients, asymptotics: :data:`NEAR_FIELD_GRID`, :data:`NEAR_FIELD_COEFFICIENTS`,
            :data:`NEAR_FIELD_ASYMPTOTICS` (from :func:`build_coefficients`).

    Returns:
        ``(F_par, F_perp, F_x)`` in units of ``U0``.
    """
    first = 0 if mechanism_code != 1 else 3
    last = 6 if mechanism_code != 0 else 3
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    gap = r - 2.0
    if r > grid[3]:
        for function in range(first, last):
            value = _far_field(r, function)
            out0, out1, out2 = _accumulate(out0, out1, out2, function % 3, value)
    elif gap < grid[4]:
        gap = max(gap, grid[5])
        for function in range(first, last):
            value = _near_contact(gap, asymptotics[function])
            out0, out1, out2 = _accumulate(out0, out1, out2, function % 3, value)
    else:
        s = math.log(gap)
        k = min(max(int((s - grid[0]) / grid[1]), 0), int(grid[2]) - 2)
        h = s - (grid[0] + k * grid[1])
        for function in range(first, last):
            c = coefficients[function, k]
            value = c[0] + h * (c[1] + h * (c[2] + h * c[3]))
            out0, out1, out2 = _accumulate(out0, out1, out2, function % 3, value)
    return out0, out1, out2


@njit(cache=True)
def near_field_functions(r: float, mechanism_code: int) -> tuple[float, float, float]:
    """:func:`near_field_kernel` with the module-level coefficient arrays (frozen at compile time)."""
    return near_field_kernel(
        r, mechanism_code, NEAR_FIELD_GRID, NEAR_FIELD_COEFFICIENTS, NEAR_FIELD_ASYMPTOTICS
    )


def evaluate_piecewise(
    r: FloatArray,
    grid: FloatArray,
    coefficients: FloatArray,
    far_field: Callable[[FloatArray], FloatArray],
    near_contact: Callable[[FloatArray], FloatArray],
) -> FloatArray:
    """Numpy evaluation of one tabulated function in its three regimes (the compiled kernels' twin).

    Args:
        r: shape ``(n_points,)``, centre distances ``>= 2``.
        grid: as :func:`~sim.dipolophoresis.two_sphere.tabulation.log_gap_grid` returns it.
        coefficients: shape ``(n - 1, 4)``, the function's spline (:func:`not_a_knot_spline`).
        far_field: the far-field form at ``r > r_end`` (given those ``r``).
        near_contact: the near-contact form at gaps ``xi < xi_0`` (given ``max(xi, gap floor)``).

    Returns:
        shape ``(n_points,)``; between the first and the last node the cubic in ``s - s_k`` on the interval
        ``k`` of ``s = ln(r - 2)`` (clipped to the first and the last interval).
    """
    out = np.empty_like(r)
    far = r > grid[3]
    near = (r - 2.0) < grid[4]
    inside = ~(far | near)
    out[far] = far_field(r[far])
    out[near] = near_contact(np.maximum(r[near] - 2.0, grid[5]))
    s = np.log(r[inside] - 2.0)
    k = np.clip(((s - grid[0]) / grid[1]).astype(np.int64), 0, int(grid[2]) - 2)
    h = s - (grid[0] + k * grid[1])
    coeff = coefficients[k]
    out[inside] = coeff[:, 0] + h * (coeff[:, 1] + h * (coeff[:, 2] + h * coeff[:, 3]))
    return out


def mechanism_code(mechanism: str) -> int:
    """The code of a mechanism name in :data:`MECHANISMS`.

    Raises:
        ValueError: if ``mechanism`` is unknown.
    """
    if mechanism not in MECHANISMS:
        raise ValueError(f"mechanism must be one of {sorted(MECHANISMS)}, got {mechanism!r}")
    return MECHANISMS[mechanism]


def validate_separations(r: ArrayLike) -> tuple[bool, FloatArray]:
    """``(is_scalar, r as a float array)`` of the evaluators' argument.

    Raises:
        ValueError: if any ``r`` is below 2 (overlapping spheres) or not finite.
    """
    scalar = np.ndim(r) == 0
    r_array = np.asarray(r, dtype=float)
    if not np.all(np.isfinite(r_array)) or np.any(r_array < 2.0):
        bad = r_array[~(np.isfinite(r_array) & (r_array >= 2.0))]
        raise ValueError(f"r must be finite and >= 2 (touching spheres); got r = {bad.ravel()[:5]}")
    return scalar, r_array


def _evaluate_numpy(r: FloatArray, function: int) -> FloatArray:
    """Vectorised twin of :func:`near_field_kernel` for one function (same coefficients)."""
    form, first, second, third = NEAR_FIELD_ASYMPTOTICS[function]

    def far_field(r_far: FloatArray) -> FloatArray:
        r2 = r_far**2
        far_values = (
            -9.0 / (4.0 * r2) + 11.0 / (2.0 * r2**2),
            9.0 / (8.0 * r2) - 11.0 / (4.0 * r2**2),
            -11.0 / (4.0 * r2**2),
            -1.0 / r2**2,
            0.5 / r2**2,
            0.5 / r2**2,
        )
        return far_values[function]

    def near_contact(gap: FloatArray) -> FloatArray:
        if form == LOG_FORM:
            return first + second / np.log(1.0 / gap) + third / np.log(1.0 / gap) ** 2
        return first * gap**third * (1.0 + second * gap)

    return evaluate_piecewise(r, NEAR_FIELD_GRID, NEAR_FIELD_COEFFICIENTS[function], far_field, near_contact)


@overload
def pair_functions(r: float, mechanism: str = "icep") -> tuple[float, float, float]: ...


@overload
def pair_functions(r: ArrayLike, mechanism: str = "icep") -> tuple[FloatArray, FloatArray, FloatArray]: ...


def pair_functions(
    r: ArrayLike, mechanism: str = "icep"
) -> tuple[float, float, float] | tuple[FloatArray, ...]:
    """Exact isolated two-sphere functions ``(F_par, F_perp, F_x)`` in units of ``U0 = eps a E0^2/eta``.

    Defined as in docs/model.md#dipolophoresis: the velocity of sphere ``alpha`` is
    ``U0 [(F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t]`` with ``xh`` from ``beta`` to ``alpha``.
    No periodic images and no blending with the far field are applied.

    Args:
        r: centre distance(s) ``r/a`` (float or array of any shape), ``r >= 2``.
        mechanism: ``"icep"``, ``"dep"`` or ``"dip"`` (= ICEP + DEP).

    Returns:
        Three floats for a scalar ``r``, else three arrays shaped like ``r``.

    Raises:
        ValueError: if ``mechanism`` is unknown, or if ``r`` < 2 or is not finite.
    """
    code = mechanism_code(mechanism)
    scalar, r_array = validate_separations(r)
    flat = r_array.ravel()
    functions = range(3) if code == 0 else range(3, 6) if code == 1 else range(6)
    results = [np.zeros_like(flat) for _ in range(3)]
    for function in functions:
        results[function % 3] += _evaluate_numpy(flat, function)
    if scalar:
        return float(results[0][0]), float(results[1][0]), float(results[2][0])
    shaped = tuple(result.reshape(r_array.shape) for result in results)
    return shaped[0], shaped[1], shaped[2]
