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
``--chunk N`` to do N nodes per call. Nodes are computed from large to small ``r`` (cheap first). The
default table (486 nodes, r = 2.0005..10) took 4.6 minutes on one core of the development machine;
the four exact near-contact check points below the table (gaps 1e-4..3e-4, L up to 1014; skip with
``--no-contact-check``) another 1.6 minutes.

Usage:
    python scripts/generate_near_field_table.py                 # (resume and) write the table
    python scripts/generate_near_field_table.py --chunk 50      # at most 50 new nodes, then stop
    python scripts/generate_near_field_table.py --convergence   # print the convergence study only
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

# One BLAS thread unless the caller asks otherwise: the dense solves are small (<= 6000 unknowns) and
# OpenBLAS threads on a shared 2-core machine made them ~10x slower. Must precede the numpy import.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sim.dipolophoresis.two_sphere.solution import solve_pair_functions, truncation_order  # noqa: E402
from sim.dipolophoresis.two_sphere.tabulation import (  # noqa: E402
    COLUMNS,
    FUNCTION_NAMES,
    LOG_FORM,
    NEAR_CONTACT_FORMS,
    fit_near_contact,
    near_contact_points,
    near_contact_value,
    node_separations,
)

DEFAULT_OUTPUT = REPO / "sim" / "dipolophoresis" / "tables" / "near_field.txt"
DEFAULT_WORK = REPO / "runs" / "near_field_table" / "work.jsonl"  # runs/ is git-ignored
CONTACT_CHECK_GAPS = (1e-4, 1.5e-4, 2e-4, 3e-4)
REPORT_SEPARATIONS = (2.0005, 2.001, 2.005, 2.01, 2.05, 2.1, 2.5, 3.0, 4.0, 5.0, 10.0)


def solve_node(r: float, constant: float, check_constant: float) -> dict:
    """Both truncation orders at one separation; returns a JSON-serialisable record."""
    start = time.perf_counter()
    high = solve_pair_functions(r, truncation_order(r, constant))
    low = solve_pair_functions(r, truncation_order(r, check_constant))
    difference = np.abs(high.as_array() - low.as_array())
    return {
        "r": r,
        "order": high.order,
        "check_order": low.order,
        "values": high.as_array().tolist(),
        "error_icep": float(difference[:3].max()),
        "error_dep": float(difference[3:].max()),
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


def format_table(records: list[dict], contact: list[dict], settings: dict, command: str) -> str:
    """Table text: provenance header, column line, one row per node."""
    r = np.array([rec["r"] for rec in records])
    values = np.array([rec["values"] for rec in records]).T
    err_icep = np.array([rec["error_icep"] for rec in records])
    err_dep = np.array([rec["error_dep"] for rec in records])
    orders = np.array([rec["order"] for rec in records])
    c_value, c_check = settings["order_constant"], settings["check_constant"]
    lines = [
        "# Exact two-sphere dipolophoresis functions of equal ideally polarisable spheres (thin, fully",
        "# polarised double layers) in a uniform field: induced-charge electrophoresis (ICEP) and",
        "# dielectrophoresis (DEP). Velocity of sphere alpha, xh from beta to alpha, th = angle(e, xh):",
        "#   U_alpha = U0 [(F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t],  U0 = eps a E0^2/eta",
        "# (physics.md section 4; Saintillan 2008, Phys. Fluids 20, 067104). Isolated pair: no images,",
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
            f"#   r = {r[k]:.6f}  L = {orders[k]:4d}  error_icep = {err_icep[k]:.1e}"
            f"  error_dep = {err_dep[k]:.1e}"
        )
    lines += [
        f"# Nodes: r = 2 + exp(s), s uniform, {r.shape[0]} nodes from r = {r[0]:.6f} to {r[-1]:.6f}"
        f" (ds = {math.log(r[1] - 2) - math.log(r[0] - 2):.6f}).",
        "# Interpolation (sim/dipolophoresis/near_field.py): cubic not-a-knot spline in s = ln(r - 2).",
        "# Beyond the last node: far-field forms (physics.md section 4). Below the first node",
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
    if contact:
        lines.append("# Check of these forms against exact solutions below the table (same c), form - exact:")
        for rec in contact:
            gap = rec["r"] - 2.0
            predicted = [
                near_contact_value(gap, form, fit) for form, fit in zip(NEAR_CONTACT_FORMS, fits, strict=True)
            ]
            deviation = " ".join(f"{x - y: .1e}" for x, y in zip(predicted, rec["values"], strict=True))
            exact = " ".join(f"{v: .6e}" for v in rec["values"])
            lines.append(f"#   xi = {gap:.1e} (L = {rec['order']}): exact {exact}")
            lines.append(f"#       form - exact: {deviation}")
    lines += [
        f"# Generated {datetime.date.today().isoformat()} by: {command}",
        " ".join(COLUMNS),
    ]
    for k in range(r.shape[0]):
        row = " ".join(f"{v: .12e}" for v in values[:, k])
        # repr(r): the exact float at which the node was solved (round-trips), so ln(r - 2) is exact.
        lines.append(f"{float(r[k])!r} {row} {orders[k]:d} {err_icep[k]:.2e} {err_dep[k]:.2e}")
    return "\n".join(lines) + "\n"


def convergence_study() -> None:
    """Print |F(L) - F(L_ref)| for several truncation constants at the report separations."""
    constants = (4.0, 6.0, 8.0, 10.0)
    print(
        "r        "
        + "  ".join(f"c={c:g}(L)" for c in constants)
        + "   [max error over the 6 functions, ref c=12]"
    )
    for r in REPORT_SEPARATIONS:
        reference = solve_pair_functions(r, truncation_order(r, 12.0)).as_array()
        cells = []
        for c in constants:
            order = truncation_order(r, c)
            error = np.abs(solve_pair_functions(r, order).as_array() - reference).max()
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
        "--work", type=Path, default=DEFAULT_WORK, help=f"resumable work file (default {DEFAULT_WORK})"
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
    work = args.work
    work.parent.mkdir(parents=True, exist_ok=True)
    records = read_work(work, settings)
    nodes = node_separations(args.gap_min, args.r_max, args.spacing)
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
            f" ({record['seconds']:.1f} s, total {time.perf_counter() - started:.0f} s)",
            flush=True,
        )
    table_records = [records[repr(float(r))] for r in nodes]
    contact = [records[repr(r)] for r in sorted(contact_nodes)]
    command = "python scripts/generate_near_field_table.py " + " ".join(sys.argv[1:])
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(format_table(table_records, contact, settings, command.strip()))
    print(f"wrote {args.output} ({len(table_records)} nodes)", flush=True)


if __name__ == "__main__":
    main()
