#!/usr/bin/env python
"""Generate ``sim/dipolophoresis/tables/near_field_stress.txt``: exact two-sphere stresslets and DEP force.

The table is data; this script is its source. At every node of ``near_field.txt`` (``r = 2 + exp(s)``, ``s``
uniform, ``r = 2.0005 .. 10``) it solves, with ``sim.dipolophoresis.two_sphere.stresslet``:

1. the electric problem of two insulating spheres (twin multipoles, ``m = 0, 1``);
2. the force- and torque-free Stokes problems with the ICEP slip ``u_s = zeta grad_s(phi)`` for the
   azimuthal orders ``m = 0, 1`` and ``2`` (the ``cos 2 phi`` part of the slip moves no sphere but has a
   stresslet), reading each sphere's stresslet from its own degree-2 Lamb pressure mode;
3. the Maxwell force on each sphere and the rigid-body stresslets the pair carries when it moves under
   ``+-F`` (same Stokes code);

and stores the ICEP pair correction ``dS = S_alpha - 9 (ee - I/3)`` as ``f1..f4``, the DEP-induced stresslet
as ``g2..g4`` (``g1 = 0``) and the DEP force on alpha as ``(F_par, F_perp, F_x)`` (module docstring of
``stresslet.py`` for the decomposition; units ``pi eps a^3 E0^2`` and ``pi eps a^2 E0^2``), at truncation
``L = 14 + c/sqrt(r - 2)`` with ``c = 10`` and again with ``c = 8`` (error estimate: the largest difference
of each group of functions; conservative: against ``c = 14`` the ``c = 10`` values are ~30x closer).

Resumable: every finished node is appended (one JSON line) to a work file (default
``runs/near_field_stress_table/work.jsonl``, git-ignored); rerun the same command to continue, or use
``--chunk N`` for N nodes per call. Nodes run from large to small ``r`` (cheap first). One BLAS thread.
Driver shared with ``generate_near_field_table.py``: ``sim/dipolophoresis/two_sphere/table_generator.py``.
The default table (486 nodes, both orders) took 5.8 minutes on one core of the development machine (2
shared cores), the four exact check points below the table (gaps 1e-4..3e-4, L up to 1014; skip with
``--no-contact-check``) 2.4 more.

Usage:
    python scripts/generate_near_field_stress_table.py                 # (resume and) write the table
    python scripts/generate_near_field_stress_table.py --chunk 50      # at most 50 new nodes, then stop
    python scripts/generate_near_field_stress_table.py --convergence   # print the convergence study only
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sim.dipolophoresis.two_sphere import table_generator as driver  # noqa: E402
from sim.dipolophoresis.two_sphere.stresslet import (  # noqa: E402
    ICEP_FAR_FIELD_COEFFICIENTS,
    STRESS_COLUMNS,
    STRESS_FUNCTION_NAMES,
    PairStressletValues,
    fit_shifted_power,
    near_contact_nodes,
    shifted_power_value,
    solve_pair_stresslets,
)
from sim.dipolophoresis.two_sphere.tabulation import read_table_text  # noqa: E402

DEFAULT_OUTPUT = REPO / "sim" / "dipolophoresis" / "tables" / "near_field_stress.txt"
VELOCITY_TABLE = REPO / "sim" / "dipolophoresis" / "tables" / "near_field.txt"
DEFAULT_WORK = REPO / "runs" / "near_field_stress_table" / "work.jsonl"  # runs/ is git-ignored
REPORT_SEPARATIONS = (2.0005, 2.001, 2.005, 2.01, 2.05, 2.1, 2.5, 3.0, 4.0, 6.0, 10.0)
ERROR_KEYS = ("error_icep", "error_dep", "error_force")


def extra_fields(solution: PairStressletValues) -> driver.Record:
    """Work-file fields beyond the values and error estimates."""
    return {"force_mobility": list(solution.force_mobility), "symmetry_error": solution.symmetry_error}


def check_default_nodes(nodes: np.ndarray, settings: driver.Record) -> None:
    """The default nodes must be those of ``near_field.txt`` (bit for bit)."""
    default = settings["gap_min"] == 5e-4 and settings["r_max"] == 10.0 and settings["spacing"] == 0.02
    if VELOCITY_TABLE.exists() and default:
        velocity_nodes = read_table_text(VELOCITY_TABLE.read_text()).r
        if not np.array_equal(nodes, velocity_nodes):
            raise SystemExit("the default nodes differ from those of near_field.txt")


def far_field_values(r: float) -> np.ndarray:
    """Far-field forms of the ten functions (docs/model.md#dipolophoresis and the module docstring)."""
    icep = np.array(ICEP_FAR_FIELD_COEFFICIENTS) / r**3
    dep = np.array([8.0 / r**8, 7.5 / r**6, -22.5 / r**6])
    force = np.array([-6.0, 3.0, 3.0]) / r**4
    return np.concatenate([icep, dep, force])


def format_table(
    records: list[driver.Record], contact: list[driver.Record], settings: driver.Record, command: str
) -> str:
    """Table text: provenance header, column line, one row per node."""
    r, values, symmetry, orders, *error_columns = driver.record_columns(
        records, "r", "values", "symmetry_error", "order", *ERROR_KEYS
    )
    values = values.T
    errors = dict(zip(ERROR_KEYS, error_columns, strict=True))
    c_value, c_check = settings["order_constant"], settings["check_constant"]
    lines = [
        "# Exact two-sphere stresslets of equal ideally polarisable spheres (thin, fully polarised double",
        "# layers) in a uniform field E0 e, and the exact DEP force. x = x_alpha - x_beta (beta -> alpha),",
        "# xh = x/r, c = e.xh. Batchelor (1970) sign convention (a rigid sphere in strain E carries",
        "# +(20/3) pi eta a^3 E). Decomposition (sim/dipolophoresis/two_sphere/stresslet.py):",
        "#   S = f1 T1 + f2 T2 + f3 T3 + f4 T4,  T1 = ee - I/3,  T2 = c (e xh + xh e) - (2/3) c^2 I,",
        "#   T3 = xh xh - I/3,  T4 = c^2 (xh xh - I/3).",
        "# icep_f1..f4: ICEP pair correction of ONE sphere, dS = S_alpha - 9 (ee - I/3), force- and",
        "#   torque-free spheres with slip u_s = +zeta grad_s(phi), units pi eps a^3 E0^2",
        "#   (S_alpha = S_beta exactly).",
        "#   Far field (docs/model.md; confirmed): (9, -36, -45/2, 225/2)/r^3; the exact residual is",
        "#   -(57/2)(1, -5, -5/2, 35/2)/r^5 (fitted, r = 10..160).",
        "# dep_g2..g4: stresslet of ONE sphere moving rigidly under the exact Maxwell forces +-F (g1 = 0),",
        "#   units pi eps a^3 E0^2; far field g2 = 8/r^8, g3 = 15/(2 r^6), g4 = -45/(2 r^6).",
        "# dep_F_par, dep_F_perp, dep_F_x: Maxwell force on alpha,",
        "#   F_alpha = (F_par c^2 + F_perp (1 - c^2)) xh + F_x sin(2 th) t,  t = (e - c xh)/|e - c xh|,",
        "#   units pi eps a^2 E0^2 (beta feels -F_alpha); far field (-6, 3, 3)/r^4, i.e. F = -3 W/r^4.",
        "#",
        "# Method: twin multipole electric problem (m = 0, 1; zeta = phi_0 - phi_s, zero net charge); Lamb's",
        "# solution about each centre with Galerkin projection on both surfaces (Gauss-Legendre 2L+40",
        "# points) for m = 0, 1 and 2; each sphere's stresslet from its own degree-2 pressure mode,",
        "# S = -(4 pi/3) c P_2^m-tensor. Checks (tests/test_two_sphere_stresslet.py): isolated S0, rigid",
        "# sphere in strain, the exact resistance table (X^G, Y^G, Y^H, X^M, Y^M, Z^M and the reciprocal",
        "# R_FE = R_SU^T), uniform zeta -> S = 0, S_alpha = S_beta, far field with fitted residual slope -5.",
        f"# Truncation: L = ceil(14 + c/sqrt(r - 2)), c = {c_value:g}"
        f" (L = {int(orders.min())}..{int(orders.max())});",
        f"# error_* = max |F(c = {c_value:g}) - F(c = {c_check:g})| over the f, the g and the force"
        " functions;",
        "# Conservative: against c = 14 the c = 10 values differ by 1.7e-6 (ICEP, r = 2.0005), 3.3e-7",
        "# (2.005), 2.2e-8 (2.02); DEP stresslet <= 1.7e-8, force <= 3e-10 (~30x below error_*).",
        "# symmetry_error = max |S_alpha - S_beta| (exactly zero for equal spheres).",
        "# Estimated error at selected r (nearest node), and the values next to the far-field forms:",
    ]
    for target in REPORT_SEPARATIONS:
        k = int(np.argmin(np.abs(r - target)))
        lines.append(driver.error_report_line(r[k], orders[k], {key: errors[key][k] for key in ERROR_KEYS}))
        lines.append("#       exact " + " ".join(f"{v: .4e}" for v in values[:, k]))
        lines.append("#       far   " + " ".join(f"{v: .4e}" for v in far_field_values(float(r[k]))))
    lines += [
        driver.nodes_line(r, prefix="those of near_field.txt: "),
        "# Interpolation (sim/dipolophoresis/near_field_stress.py): cubic not-a-knot spline in",
        "# s = ln(r - 2).",
        "# Beyond the last node: the far-field forms above. Below the first node (gap xi < xi_0):",
        "# F = C + A xi^p fitted exactly through the nodes at xi_0, ~2^(1/4) xi_0, ~2^(1/2) xi_0",
        "# (the loader refits; values here;",
        "# p < 0: weak divergence, from the singular transverse field in the gap, like ICEP F_x):",
    ]
    fit_nodes = near_contact_nodes(r)
    fits = [fit_shifted_power(r[fit_nodes] - 2.0, values[k, fit_nodes]) for k in range(values.shape[0])]
    for name, (c_fit, a_fit, p_fit) in zip(STRESS_FUNCTION_NAMES, fits, strict=True):
        lines.append(f"#   {name:11s} C = {c_fit: .6e}  A = {a_fit: .6e}  p = {p_fit: .5f}")
    lines += driver.contact_check_lines(
        contact, lambda gap: [shifted_power_value(gap, fit) for fit in fits], digits=5
    )
    estimates = [(errors[key], ".2e") for key in ERROR_KEYS] + [(symmetry, ".1e")]
    lines += driver.table_body(command, STRESS_COLUMNS, r, values, orders, estimates)
    return "\n".join(lines) + "\n"


GENERATOR = driver.TableGenerator[PairStressletValues](
    script="scripts/generate_near_field_stress_table.py",
    description=__doc__ or "",
    default_output=DEFAULT_OUTPUT,
    default_work=DEFAULT_WORK,
    solve=solve_pair_stresslets,
    error_groups={"error_icep": slice(0, 4), "error_dep": slice(4, 7), "error_force": slice(7, None)},
    format_table=format_table,
    report_separations=REPORT_SEPARATIONS,
    convergence_label="10 functions",
    extra_fields=extra_fields,
    check_nodes=check_default_nodes,
)


def main() -> None:
    GENERATOR.main()


if __name__ == "__main__":
    main()
