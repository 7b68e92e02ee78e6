"""Format of the near-field table and the near-contact fit shared by its generator and its loader.

The table ``sim/dipolophoresis/tables/near_field.txt`` (written by
``scripts/generate_near_field_table.py``, read by :mod:`sim.dipolophoresis.near_field`) has comment
lines starting with ``#`` (provenance), one column line
``r icep_F_par icep_F_perp icep_F_x dep_F_par dep_F_perp dep_F_x order error_icep error_dep`` and one row
per node; nodes are uniform in ``s = ln(r - 2)``. Function values are in units of
``U0 = eps a E0^2/eta``; ``order`` is the truncation degree; the errors are estimates (units ``U0``).

Below the first node (gap ``xi_0``) the loader uses the forms of :data:`NEAR_CONTACT_FORMS` fitted exactly
through the nodes at ``xi_0``, ``~2 xi_0`` and ``~4 xi_0`` (:func:`fit_near_contact`).

Also shared with the stress table (``tables/near_field_stress.txt``, read by
:mod:`sim.dipolophoresis.near_field_stress`): the nodes (:func:`node_separations`), reading a packaged table
(:func:`packaged_table_text`) and the parameters of the uniform ``ln(r - 2)`` grid that the loaders'
evaluators take (:func:`log_gap_grid`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

FUNCTION_NAMES: Final = ("icep_F_par", "icep_F_perp", "icep_F_x", "dep_F_par", "dep_F_perp", "dep_F_x")
COLUMNS: Final = ("r", *FUNCTION_NAMES, "order", "error_icep", "error_dep")


@dataclass(frozen=True)
class NearFieldTable:
    """The tabulated exact functions.

    Attributes:
        r: shape ``(n,)``, centre distances ``r/a`` (``ln(r - 2)`` uniformly spaced).
        values: shape ``(6, n)``, rows in the order of :data:`FUNCTION_NAMES`, units ``U0``.
        order: shape ``(n,)``, truncation degree of the tabulated solution.
        error_icep, error_dep: shape ``(n,)``, estimated truncation error (max over the three functions
            of the mechanism, difference from a lower truncation order: a conservative bound), units ``U0``.
        header: the comment lines of the file (provenance).
    """

    r: FloatArray
    values: FloatArray
    order: FloatArray
    error_icep: FloatArray
    error_dep: FloatArray
    header: tuple[str, ...]


def read_table_text(text: str) -> NearFieldTable:
    """Parse the text of a near-field table file.

    Raises:
        ValueError: if the column line differs from :data:`COLUMNS`.
    """
    header, data = split_table_text(text, COLUMNS, "near-field table")
    return NearFieldTable(
        r=data[:, 0].copy(),
        values=np.ascontiguousarray(data[:, 1:7].T),
        order=data[:, 7].copy(),
        error_icep=data[:, 8].copy(),
        error_dep=data[:, 9].copy(),
        header=header,
    )


def split_table_text(
    text: str, columns: tuple[str, ...], table_name: str
) -> tuple[tuple[str, ...], FloatArray]:
    """The comment lines and the numbers of a table file (also used for ``near_field_stress.txt``).

    Args:
        text: the file's text: comment lines starting with ``#``, one column line, one row per node.
        columns: the expected column line.
        table_name: named in the error.

    Returns:
        ``(header, data)``: the comment lines and shape ``(n_nodes, n_columns)``.

    Raises:
        ValueError: if the column line differs from ``columns``.
    """
    lines = text.splitlines()
    header = tuple(line for line in lines if line.startswith("#"))
    rows = [line.split() for line in lines if line.strip() and not line.startswith("#")]
    if tuple(rows[0]) != columns:
        raise ValueError(f"{table_name}: unexpected columns {rows[0]}, expected {list(columns)}")
    return header, np.array(rows[1:], dtype=float)


def node_separations(gap_min: float, r_max: float, spacing: float) -> FloatArray:
    """Nodes ``r = 2 + exp(s)`` with ``s`` uniform on ``[ln gap_min, ln(r_max - 2)]``, step <= ``spacing``."""
    s0, s1 = math.log(gap_min), math.log(r_max - 2.0)
    n_intervals = math.ceil((s1 - s0) / spacing)
    nodes = 2.0 + np.exp(np.linspace(s0, s1, n_intervals + 1))
    nodes[0], nodes[-1] = 2.0 + gap_min, r_max  # exact end points
    return nodes


def packaged_table_text(filename: str) -> str:
    """Text of the table ``sim/dipolophoresis/tables/<filename>`` (package data)."""
    return resources.files("sim.dipolophoresis").joinpath("tables", filename).read_text()


def log_gap_grid(r: FloatArray, gap_floor: float, table_name: str) -> FloatArray:
    """Parameters of the uniform grid in ``s = ln(r - 2)`` of a table's nodes, as the evaluators take them.

    Args:
        r: shape ``(n,)``, the nodes (increasing, uniform in ``ln(r - 2)``).
        gap_floor: smallest gap ``r - 2`` the near-contact forms are evaluated at.
        table_name: named in the error.

    Returns:
        shape ``(6,)``: ``s_0 = ln(xi_0)``, ``ds``, number of nodes, ``r_end`` (last node), ``xi_0`` (first
        gap), ``gap_floor``.

    Raises:
        ValueError: if the nodes are not uniform in ``ln(r - 2)`` (to ``1e-9 ds``).
    """
    s = np.log(r - 2.0)
    ds = (s[-1] - s[0]) / (s.shape[0] - 1)
    if np.abs(np.diff(s) - ds).max() > 1e-9 * ds:
        raise ValueError(f"{table_name}: nodes are not uniform in ln(r - 2)")
    return np.array([s[0], ds, float(s.shape[0]), r[-1], r[0] - 2.0, gap_floor])


def near_contact_points(r: FloatArray) -> NDArray[np.int64]:
    """Indices ``(0, j, 2j)`` of the nodes used by :func:`fit_near_contact` (``j`` ~ a factor 2 in gap)."""
    spacing = math.log(r[1] - 2.0) - math.log(r[0] - 2.0)
    j = max(1, round(math.log(2.0) / spacing))
    return np.array([0, j, 2 * j])


POWER_FORM: Final = 0
"""``F = A xi^p (1 + B xi)``: parameters ``(A, B, p)``."""
LOG_FORM: Final = 1
"""``F = C + a/L + b/L^2`` with ``L = ln(1/xi)``: parameters ``(C, a, b)``."""
NEAR_CONTACT_FORMS: Final = (POWER_FORM, POWER_FORM, POWER_FORM, POWER_FORM, POWER_FORM, LOG_FORM)
"""Form used below the table for each of :data:`FUNCTION_NAMES`.

Power law for the functions that vanish (``F_par``, ``F_perp``: squeeze lubrication, ``p ~ 1``; ICEP
``F_perp`` has ``p ~ sqrt(2) - 1`` because the transverse field in the thin gap behaves like
``rho^(sqrt 2 - 1)``) or diverge weakly (ICEP ``F_x``, ``p ~ -0.22``); DEP ``F_x`` tends to a constant
with the inverse-logarithm corrections typical of tangential two-sphere mobilities near contact.
"""


def fit_near_contact(gaps: ArrayLike, values: ArrayLike, form: int) -> tuple[float, float, float]:
    """Fit a near-contact form exactly through three points at geometrically spaced gaps.

    Args:
        gaps: shape ``(3,)``, ``xi_0 < xi_1 < xi_2`` with ``xi_1/xi_0 = xi_2/xi_1 = q``.
        values: shape ``(3,)``, the function at those gaps.
        form: :data:`POWER_FORM` or :data:`LOG_FORM`.

    Returns:
        The three parameters of the form. For the power form, with ``r1 = F_1/F_0``, ``r2 = F_2/F_0``,
        ``u = B xi_0`` solves ``q^2 d u^2 - [(q-1)^2 - 2 q d] u + d = 0`` (root -> 0 as ``d -> 0``) with
        ``d = r2/r1^2 - 1``; then ``q^p = r1 (1 + u)/(1 + q u)`` and ``A = F_0/(xi_0^p (1 + u))``.

    Raises:
        ValueError: if the gaps are not geometric, or the power form has no real solution (values of
        mixed sign, or ``(q-1)^2 - 2 q d`` too small).
    """
    xi = np.asarray(gaps, dtype=float)
    f = np.asarray(values, dtype=float)
    q = xi[1] / xi[0]
    if not (q > 1.0 and abs(xi[2] / xi[1] - q) < 1e-9 * q):
        raise ValueError(f"gaps must be geometric and increasing, got {xi}")
    if form == LOG_FORM:
        inverse_log = 1.0 / np.log(1.0 / xi)
        matrix = np.stack([np.ones(3), inverse_log, inverse_log**2], axis=1)
        c, a, b = np.linalg.solve(matrix, f)
        return float(c), float(a), float(b)
    if form != POWER_FORM:
        raise ValueError(f"unknown near-contact form {form}")
    r1, r2 = f[1] / f[0], f[2] / f[0]
    if not (r1 > 0.0 and r2 > 0.0):
        raise ValueError(f"power form needs values of one sign, got {f}")
    d = r2 / r1**2 - 1.0
    b_coefficient = (q - 1.0) ** 2 - 2.0 * q * d
    discriminant = b_coefficient**2 - 4.0 * q**2 * d**2
    if not (b_coefficient > 0.0 and discriminant >= 0.0):
        raise ValueError(f"power form has no real solution for {f}")
    u = 2.0 * d / (b_coefficient + math.sqrt(discriminant))
    p = math.log(r1 * (1.0 + u) / (1.0 + q * u)) / math.log(q)
    a = f[0] / (xi[0] ** p * (1.0 + u))
    return float(a), float(u / xi[0]), float(p)


def near_contact_value(gap: float, form: int, parameters: ArrayLike) -> float:
    """Evaluate a near-contact form (reference implementation for tests and the table header)."""
    first, second, third = (float(x) for x in np.asarray(parameters, dtype=float))
    if form == LOG_FORM:
        inverse_log = 1.0 / math.log(1.0 / gap)
        return first + second * inverse_log + third * inverse_log**2
    return first * gap**third * (1.0 + second * gap)
