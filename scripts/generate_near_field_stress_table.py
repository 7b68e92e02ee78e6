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
The default table (486 nodes, both orders) took 5.8 minutes on one core of the development machine (2
shared cores), the four exact check points below the table (gaps 1e-4..3e-4, L up to 1014; skip with
``--no-contact-check``) 2.4 more.

Usage:
    python scripts/generate_near_field_stress_table.py                 # (resume and) write the table
    python scripts/generate_near_field_stress_table.py --chunk 50      # at most 50 new nodes, then stop
    python scripts/generate_near_field_stress_table.py --convergence   # print the convergence study only
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import sys
import time
from pathlib import Path

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sim.dipolophoresis.two_sphere.stresslet import (  # noqa: E402
    ICEP_FAR_FIELD_COEFFICIENTS,
    STRESS_COLUMNS,
    STRESS_FUNCTION_NAMES,
    fit_shifted_power,
    near_contact_nodes,
    shifted_power_value,
    solve_pair_stresslets,
)
from sim.dipolophoresis.two_sphere.tabulation import node_separations, read_table_text  # noqa: E402
from sim.dipolophoresis.two_sphere.truncation import truncation_order  # noqa: E402

DEFAULT_OUTPUT = REPO / "sim" / "dipolophoresis" / "tables" / "near_field_stress.txt"
VELOCITY_TABLE = REPO / "sim" / "dipolophoresis" / "tables" / "near_field.txt"
DEFAULT_WORK = REPO / "runs" / "near_field_stress_table" / "work.jsonl"  # runs/ is git-ignored
CONTACT_CHECK_GAPS = (1e-4, 1.5e-4, 2e-4, 3e-4)
REPORT_SEPARATIONS = (2.0005, 2.001, 2.005, 2.01, 2.05, 2.1, 2.5, 3.0, 4.0, 6.0, 10.0)


def solve_node(r: float, constant: float, check_constant: float) -> dict:
    """Both truncation orders at one separation; returns a JSON-serialisable record."""
    start = time.perf_counter()
    high = solve_pair_stresslets(r, truncation_order(r, constant))
    low = solve_pair_stresslets(r, truncation_order(r, check_constant))
    difference = np.abs(high.as_array() - low.as_array())
    return {
        "r": r,
        "order": high.order,
        "check_order": low.order,
        "values": high.as_array().tolist(),
        "force_mobility": list(high.force_mobility),
        "error_icep": float(difference[:4].max()),
        "error_dep": float(difference[4:7].max()),
        "error_force": float(difference[7:].max()),
        "symmetry_error": high.symmetry_error,
        "seconds": time.perf_counter() - start,
    }


def read_work(path: Path, settings: dict) -> dict[str, dict]:
    """Finished records keyed by ``repr(r)``; the first line holds the settings, which must match."""
    if not path.exists():
        path.write_text(json.dumps({"settings": settings}) + "\n")
        return {}
    lines = path.read_text().splitlines()
    stored = json.loads(lines[0]).get("settings")
    if stored != settings:
        raise SystemExit(
            f"{path}: settings {stored} differ from {settings}; delete it or use the same options"
        )
    records = {}
    for line in lines[1:]:
        if line.strip():
            record = json.loads(line)
            records[repr(record["r"])] = record
    return records


def append_work(path: Path, record: dict) -> None:
    with path.open("a") as handle:
        handle.write(json.dumps(record) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


def far_field_values(r: float) -> np.ndarray:
    """Far-field forms of the ten functions (physics.md section 4 and the module docstring)."""
    icep = np.array(ICEP_FAR_FIELD_COEFFICIENTS) / r**3
    dep = np.array([8.0 / r**8, 7.5 / r**6, -22.5 / r**6])
    force = np.array([-6.0, 3.0, 3.0]) / r**4
    return np.concatenate([icep, dep, force])


def format_table(records: list[dict], contact: list[dict], settings: dict, command: str) -> str:
    """Table text: provenance header, column line, one row per node."""
    r = np.array([rec["r"] for rec in records])
    values = np.array([rec["values"] for rec in records]).T
    errors = {
        key: np.array([rec[key] for rec in records]) for key in ("error_icep", "error_dep", "error_force")
    }
    symmetry = np.array([rec["symmetry_error"] for rec in records])
    orders = np.array([rec["order"] for rec in records])
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
        "#   Far field (physics.md section 4; confirmed): (9, -36, -45/2, 225/2)/r^3; the exact residual is",
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
        lines.append(
            f"#   r = {r[k]:.6f}  L = {orders[k]:4d}  error_icep = {errors['error_icep'][k]:.1e}"
            f"  error_dep = {errors['error_dep'][k]:.1e}  error_force = {errors['error_force'][k]:.1e}"
        )
        lines.append("#       exact " + " ".join(f"{v: .4e}" for v in values[:, k]))
        lines.append("#       far   " + " ".join(f"{v: .4e}" for v in far_field_values(float(r[k]))))
    lines += [
        f"# Nodes: those of near_field.txt: r = 2 + exp(s), s uniform, {r.shape[0]} nodes from r = {r[0]:.6f}"
        f" to {r[-1]:.6f} (ds = {math.log(r[1] - 2) - math.log(r[0] - 2):.6f}).",
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
    if contact:
        lines.append("# Check of these forms against exact solutions below the table (same c), form - exact:")
        for rec in contact:
            gap = rec["r"] - 2.0
            predicted = [shifted_power_value(gap, fit) for fit in fits]
            deviation = " ".join(f"{x - y: .1e}" for x, y in zip(predicted, rec["values"], strict=True))
            exact = " ".join(f"{v: .5e}" for v in rec["values"])
            lines.append(f"#   xi = {gap:.1e} (L = {rec['order']}): exact {exact}")
            lines.append(f"#       form - exact: {deviation}")
    lines += [f"# Generated {datetime.date.today().isoformat()} by: {command}", " ".join(STRESS_COLUMNS)]
    for k in range(r.shape[0]):
        row = " ".join(f"{v: .12e}" for v in values[:, k])
        lines.append(
            f"{float(r[k])!r} {row} {orders[k]:d} {errors['error_icep'][k]:.2e} {errors['error_dep'][k]:.2e}"
            f" {errors['error_force'][k]:.2e} {symmetry[k]:.1e}"
        )
    return "\n".join(lines) + "\n"


def convergence_study() -> None:
    """Print max |F(L) - F(L_ref)| over the ten functions for several truncation constants."""
    constants = (4.0, 6.0, 8.0, 10.0)
    print(
        "r        "
        + "  ".join(f"c={c:g}(L)" for c in constants)
        + "   [max error over 10 functions, ref c=12]"
    )
    for r in REPORT_SEPARATIONS:
        reference = solve_pair_stresslets(r, truncation_order(r, 12.0)).as_array()
        cells = []
        for c in constants:
            order = truncation_order(r, c)
            error = np.abs(solve_pair_stresslets(r, order).as_array() - reference).max()
            cells.append(f"{error:.1e}({order})")
        print(f"{r:<8g} " + "  ".join(cells), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--r-max", type=float, default=10.0, help="last node (default 10)")
    parser.add_argument("--gap-min", type=float, default=5e-4, help="first node's gap r - 2 (default 5e-4)")
    parser.add_argument("--spacing", type=float, default=0.02, help="max step in ln(r - 2) (default 0.02)")
    parser.add_argument("--order-constant", type=float, default=10.0, help="c of L = 14 + c/sqrt(r-2)")
    parser.add_argument("--check-constant", type=float, default=8.0, help="c of the error-estimate solve")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument(
        "--work", type=Path, default=DEFAULT_WORK, help=f"resumable work file ({DEFAULT_WORK})"
    )
    parser.add_argument(
        "--chunk", type=int, default=None, help="compute at most this many new nodes, then stop"
    )
    parser.add_argument(
        "--no-contact-check", action="store_true", help="skip the exact points below the table"
    )
    parser.add_argument("--convergence", action="store_true", help="print the convergence study and exit")
    args = parser.parse_args()
    if args.convergence:
        convergence_study()
        return
    settings = {
        "r_max": args.r_max,
        "gap_min": args.gap_min,
        "spacing": args.spacing,
        "order_constant": args.order_constant,
        "check_constant": args.check_constant,
    }
    nodes = node_separations(args.gap_min, args.r_max, args.spacing)
    if VELOCITY_TABLE.exists() and args.gap_min == 5e-4 and args.r_max == 10.0 and args.spacing == 0.02:
        velocity_nodes = read_table_text(VELOCITY_TABLE.read_text()).r
        if not np.array_equal(nodes, velocity_nodes):
            raise SystemExit("the default nodes differ from those of near_field.txt")
    work = args.work
    work.parent.mkdir(parents=True, exist_ok=True)
    records = read_work(work, settings)
    todo = [float(r) for r in nodes[::-1] if repr(float(r)) not in records]
    contact_nodes = [] if args.no_contact_check else [2.0 + gap for gap in CONTACT_CHECK_GAPS[::-1]]
    todo_contact = [r for r in contact_nodes if repr(r) not in records]
    print(
        f"{len(nodes)} nodes, {len(nodes) - len(todo)} done; {len(todo_contact)} contact checks to do",
        flush=True,
    )
    budget = args.chunk if args.chunk is not None else len(todo) + len(todo_contact)
    started = time.perf_counter()
    for count, r in enumerate(todo + todo_contact):
        if count >= budget:
            print(f"chunk of {budget} done; rerun to continue", flush=True)
            return
        record = solve_node(r, args.order_constant, args.check_constant)
        append_work(work, record)
        records[repr(r)] = record
        print(
            f"[{count + 1}/{len(todo) + len(todo_contact)}] r = {r:.6f} L = {record['order']}"
            f" err_icep = {record['error_icep']:.1e} err_dep = {record['error_dep']:.1e}"
            f" err_force = {record['error_force']:.1e} ({record['seconds']:.1f} s,"
            f" total {time.perf_counter() - started:.0f} s)",
            flush=True,
        )
    table_records = [records[repr(float(r))] for r in nodes]
    contact = [records[repr(r)] for r in sorted(contact_nodes)]
    command = "python scripts/generate_near_field_stress_table.py " + " ".join(sys.argv[1:])
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(format_table(table_records, contact, settings, command.strip()))
    print(f"wrote {args.output} ({len(table_records)} nodes)", flush=True)


if __name__ == "__main__":
    main()
