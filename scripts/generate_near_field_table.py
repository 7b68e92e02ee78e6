#!/usr/bin/env python
"""Generate ``sim/dipolophoresis/tables/near_field.txt``: exact two-sphere ICEP and DEP pair functions.

The table is data; this script is its source. For every node ``r = 2 + exp(s)``, ``s`` uniform between
``ln(gap_min)`` and ``ln(r_max - 2)``, it solves (``sim.dipolophoresis.two_sphere``):

1. the electric problem of two insulating spheres in a uniform field by twin multipole expansion
   (``m = 0`` and ``m = 1``), giving the induced zeta potential and the surface field;
2. the force- and torque-free Stokes problems with the ICEP slip ``u_s = zeta grad_s(phi)``
   (Lamb's solution about each centre, Galerkin on both surfaces; ``m = 0`` for ``F_par``, ``F_perp``,
   ``m = 1`` for ``F_x``);
3. the Maxwell force on each sphere times the exact two-sphere mobility (DEP);

at truncation degree ``L = 14 + c/sqrt(r - 2)`` with ``c = 10``, and again with ``c = 8``; the largest
difference of the three functions of a mechanism is stored as its error estimate (a conservative
bound: the error falls by ~20x from ``c = 8`` to ``c = 10``).

Work is resumable: every finished node is appended (one JSON line) to a work file (default
``runs/near_field_table/work.jsonl``, git-ignored); rerun the same command to continue, or use
``--chunk N`` to do N nodes per call. Nodes are computed from large to small ``r`` (cheap first); the
driver is shared with the stress table's generator (``sim/dipolophoresis/two_sphere/table_generator.py``). The
default table (486 nodes, r = 2.0005..10) took 4.6 minutes on one core of the development machine;
the four exact near-contact check points below the table (gaps 1e-4..3e-4, L up to 1014; skip with
``--no-contact-check``) another 1.6 minutes.

Usage:
    python scripts/generate_near_field_table.py                 # (resume and) write the table
    python scripts/generate_near_field_table.py --chunk 50      # at most 50 new nodes, then stop
    python scripts/generate_near_field_table.py --convergence   # print the convergence study only
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

# One BLAS thread unless the caller asks otherwise: the dense solves are small (<= 6000 unknowns) and
# OpenBLAS threads on a shared 2-core machine made them ~10x slower. Must precede the numpy import.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sim.dipolophoresis.two_sphere import table_generator as driver  # noqa: E402
from sim.dipolophoresis.two_sphere.solution import PairFunctionValues, solve_pair_functions  # noqa: E402
from sim.dipolophoresis.two_sphere.tabulation import (  # noqa: E402
    COLUMNS,
    FUNCTION_NAMES,
    LOG_FORM,
    NEAR_CONTACT_FORMS,
    fit_near_contact,
    near_contact_points,
    near_contact_value,
)

DEFAULT_OUTPUT = REPO / "sim" / "dipolophoresis" / "tables" / "near_field.txt"
DEFAULT_WORK = REPO / "runs" / "near_field_table" / "work.jsonl"  # runs/ is git-ignored
REPORT_SEPARATIONS = (2.0005, 2.001, 2.005, 2.01, 2.05, 2.1, 2.5, 3.0, 4.0, 5.0, 10.0)


def format_table(
    records: list[driver.Record], contact: list[driver.Record], settings: driver.Record, command: str
) -> str:
    """Table text: provenance header, column line, one row per node."""
    r, values, err_icep, err_dep, orders = driver.record_columns(
        records, "r", "values", "error_icep", "error_dep", "order"
    )
    values = values.T
    c_value, c_check = settings["order_constant"], settings["check_constant"]
    lines = [
        "# Exact two-sphere dipolophoresis functions of equal ideally polarisable spheres (thin, fully",
        "# polarised double layers) in a uniform field: induced-charge electrophoresis (ICEP) and",
        "# dielectrophoresis (DEP). Velocity of sphere alpha, xh from beta to alpha, th = angle(e, xh):",
        "#   U_alpha = U0 [(F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t],  U0 = eps a E0^2/eta",
        "# (docs/model.md; Saintillan 2008, Phys. Fluids 20, 067104). Isolated pair: no images,",
        "# no blending.",
        "#",
        "# Method (sim/dipolophoresis/two_sphere): electric problem of two insulating spheres by twin",
        "# multipole expansion with the axial addition theorem (m = 0, 1), zeta = phi_0 - phi_s with zero",
        "# net charge; ICEP: force- and torque-free Stokes problems with slip u_s = +zeta grad_s(phi),",
        "# Lamb's solution about each centre with Galerkin projection on both surfaces (Gauss-Legendre,",
        "# 2L+40 points per sphere); DEP: Maxwell force -(1/2) int |grad_s phi|^2 n dS times the exact",
        "# two-sphere mobility from the same Stokes code (its rigid resistance scalars match the exact",
        "# table of tests/reference_data to 1e-7 relative for s >= 2.2, and to that table's own",
        "# accuracy, ~1e-5, below).",
        f"# Truncation: degree L = ceil(14 + c/sqrt(r - 2)), c = {c_value:g} for the values (L = "
        f"{int(orders.min())}..{int(orders.max())});",
        f"# error_icep/error_dep = max |F(c = {c_value:g}) - F(c = {c_check:g})| over the three functions of",
        "# the mechanism: a conservative bound (the error falls ~20x from c = 8 to c = 10).",
        "# Estimated error (units U0) at selected r (nearest node):",
    ]
    for target in REPORT_SEPARATIONS:
        k = int(np.argmin(np.abs(r - target)))
        lines.append(
            driver.error_report_line(r[k], orders[k], {"error_icep": err_icep[k], "error_dep": err_dep[k]})
        )
    lines += [
        driver.nodes_line(r),
        "# Interpolation (sim/dipolophoresis/near_field.py): cubic not-a-knot spline in s = ln(r - 2).",
        "# Beyond the last node: far-field forms (docs/model.md#dipolophoresis). Below the first node",
        "# (gap xi < xi_0): forms fitted exactly through the nodes at xi_0, ~2 xi_0, ~4 xi_0",
        "# (the loader refits them; values here):",
        "# 'power' F = A xi^p (1 + B xi); 'log' F = C + a/L + b/L^2 with L = ln(1/xi).",
    ]
    fit_nodes = near_contact_points(r)
    fits = [
        fit_near_contact(r[fit_nodes] - 2.0, values[k, fit_nodes], NEAR_CONTACT_FORMS[k]) for k in range(6)
    ]
    for name, form, (first, second, third) in zip(FUNCTION_NAMES, NEAR_CONTACT_FORMS, fits, strict=True):
        if form == LOG_FORM:
            lines.append(f"#   {name:12s} log   C = {first: .6e}  a = {second: .6e}  b = {third: .6e}")
        else:
            lines.append(f"#   {name:12s} power A = {first: .6e}  B = {second: .6e}  p = {third: .5f}")
    lines += driver.contact_check_lines(
        contact,
        lambda gap: [
            near_contact_value(gap, form, fit) for form, fit in zip(NEAR_CONTACT_FORMS, fits, strict=True)
        ],
        digits=6,
    )
    lines += driver.table_body(command, COLUMNS, r, values, orders, [(err_icep, ".2e"), (err_dep, ".2e")])
    return "\n".join(lines) + "\n"


GENERATOR = driver.TableGenerator[PairFunctionValues](
    script="scripts/generate_near_field_table.py",
    description=__doc__ or "",
    default_output=DEFAULT_OUTPUT,
    default_work=DEFAULT_WORK,
    solve=solve_pair_functions,
    error_groups={"error_icep": slice(0, 3), "error_dep": slice(3, 6)},
    format_table=format_table,
    report_separations=REPORT_SEPARATIONS,
    convergence_label="the 6 functions",
)


def main() -> None:
    GENERATOR.main()


if __name__ == "__main__":
    main()
