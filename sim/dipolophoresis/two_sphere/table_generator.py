"""Driver shared by the offline table generators of the exact two-sphere functions.

``scripts/generate_near_field_table.py`` (velocities, ``tables/near_field.txt``) and
``scripts/generate_near_field_stress_table.py`` (stresslets and DEP force, ``tables/near_field_stress.txt``)
tabulate functions of the centre distance at the nodes ``r = 2 + exp(s)``, ``s`` uniform between
``ln(gap_min)`` and ``ln(r_max - 2)`` (:func:`.tabulation.node_separations`). Every node is solved at the
truncation degree ``L = 14 + c/sqrt(r - 2)`` (:func:`.truncation.truncation_order`) for the order constant
``c`` and again for the check constant; the largest difference over a group of functions is stored as that
group's error estimate.

What the two generators share lives here: the command line, the resumable work file (first line the
settings, which must match; then one JSON record per finished node, appended and flushed at once), the loop
over the nodes (large ``r`` first: cheap first) and over the exact check points below the table
(:data:`CONTACT_CHECK_GAPS`), the convergence study, and the common pieces of the table text (error report
lines, the contact check of the near-contact forms, the provenance line and the rows). What each table
stores, its header and its near-contact forms are the script's (:class:`TableGenerator`).

Plain numpy; the scripts set one BLAS thread before importing numpy (the dense solves are small).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from sim.dipolophoresis.two_sphere.tabulation import node_separations
from sim.dipolophoresis.two_sphere.truncation import truncation_order

FloatArray = NDArray[np.float64]
Record = dict[str, Any]
"""One finished node of the work file (JSON object): ``r``, ``order``, ``check_order``, ``values``, the
error estimates, the script's extra fields and ``seconds``."""

CONTACT_CHECK_GAPS: Final = (1e-4, 1.5e-4, 2e-4, 3e-4)
"""Gaps ``r - 2`` of the exact solutions below the table that check its near-contact forms."""

CONVERGENCE_CONSTANTS: Final = (4.0, 6.0, 8.0, 10.0)
"""Order constants ``c`` compared in the convergence study (reference ``c = 12``)."""


class PairSolution(Protocol):
    """What a generator needs of an exact solve at one separation."""

    @property
    def order(self) -> int: ...

    def as_array(self) -> FloatArray: ...


SolutionT = TypeVar("SolutionT", bound=PairSolution)


def _no_extra_fields(solution: PairSolution) -> Record:
    return {}


@dataclass(frozen=True)
class TableGenerator(Generic[SolutionT]):
    """One table generator: what it solves, what it stores and how its table reads.

    Attributes:
        script: path of the script from the repository root (stated in the table's provenance line).
        description: the script's docstring (``--help``).
        default_output, default_work: default table and work file.
        solve: ``solve(r, L)``, the exact functions at centre distance ``r`` and truncation degree ``L``.
        error_groups: record key -> the functions (slice of ``solve(...).as_array()``) over which that key
            stores the largest difference between the two truncation orders, e.g.
            ``{"error_icep": slice(0, 3)}``.
        format_table: ``format_table(records, contact, settings, command)``: the table text from the
            records of the table nodes (increasing ``r``), those of the contact check points (increasing
            ``r``; empty with ``--no-contact-check``), the settings and the command line.
        report_separations: where the convergence study is printed.
        convergence_label: what the convergence study's maximum runs over (e.g. ``"the 6 functions"``).
        extra_fields: further JSON fields of a node's record from the solve at the order constant.
        check_nodes: optional ``check_nodes(nodes, settings)`` run before any node is solved (raise
            :class:`SystemExit` to refuse).
    """

    script: str
    description: str
    default_output: Path
    default_work: Path
    solve: Callable[[float, int], SolutionT]
    error_groups: Mapping[str, slice]
    format_table: Callable[[list[Record], list[Record], Record, str], str]
    report_separations: tuple[float, ...]
    convergence_label: str
    extra_fields: Callable[[SolutionT], Record] = field(default=_no_extra_fields)
    check_nodes: Callable[[FloatArray, Record], None] | None = None

    def solve_node(self, r: float, constant: float, check_constant: float) -> Record:
        """Both truncation orders at one separation; returns a JSON-serialisable record."""
        start = time.perf_counter()
        high = self.solve(r, truncation_order(r, constant))
        low = self.solve(r, truncation_order(r, check_constant))
        difference = np.abs(high.as_array() - low.as_array())
        return {
            "r": r,
            "order": high.order,
            "check_order": low.order,
            "values": high.as_array().tolist(),
            **{key: float(difference[rows].max()) for key, rows in self.error_groups.items()},
            **self.extra_fields(high),
            "seconds": time.perf_counter() - start,
        }

    def convergence_study(self) -> None:
        """Print max ``|F(L) - F(L_ref)|`` over all functions for several truncation constants."""
        print(
            "r        "
            + "  ".join(f"c={c:g}(L)" for c in CONVERGENCE_CONSTANTS)
            + f"   [max error over {self.convergence_label}, ref c=12]"
        )
        for r in self.report_separations:
            reference = self.solve(r, truncation_order(r, 12.0)).as_array()
            cells = []
            for c in CONVERGENCE_CONSTANTS:
                order = truncation_order(r, c)
                error = np.abs(self.solve(r, order).as_array() - reference).max()
                cells.append(f"{error:.1e}({order})")
            print(f"{r:<8g} " + "  ".join(cells), flush=True)

    def parser(self) -> argparse.ArgumentParser:
        """The command line shared by the generators."""
        parser = argparse.ArgumentParser(
            description=self.description,
            formatter_class=argparse.RawDescriptionHelpFormatter,
            allow_abbrev=False,  # a prefix of a flag is not that flag
        )
        parser.add_argument("--r-max", type=float, default=10.0, help="last node (default 10)")
        parser.add_argument(
            "--gap-min", type=float, default=5e-4, help="first node's gap r - 2 (default 5e-4)"
        )
        parser.add_argument(
            "--spacing", type=float, default=0.02, help="max step in ln(r - 2) (default 0.02)"
        )
        parser.add_argument("--order-constant", type=float, default=10.0, help="c of L = 14 + c/sqrt(r-2)")
        parser.add_argument("--check-constant", type=float, default=8.0, help="c of the error-estimate solve")
        parser.add_argument("--output", type=Path, default=self.default_output)
        parser.add_argument(
            "--work",
            type=Path,
            default=self.default_work,
            help=f"resumable work file (default {self.default_work})",
        )
        parser.add_argument(
            "--chunk", type=int, default=None, help="compute at most this many new nodes, then stop"
        )
        parser.add_argument(
            "--no-contact-check", action="store_true", help="skip the exact points below the table"
        )
        parser.add_argument("--convergence", action="store_true", help="print the convergence study and exit")
        return parser

    def main(self, argv: Sequence[str] | None = None) -> None:
        """Parse the command line, (resume and) solve the missing nodes, then write the table."""
        arguments = list(sys.argv[1:] if argv is None else argv)
        args = self.parser().parse_args(arguments)
        if args.convergence:
            self.convergence_study()
            return
        settings = {
            "r_max": args.r_max,
            "gap_min": args.gap_min,
            "spacing": args.spacing,
            "order_constant": args.order_constant,
            "check_constant": args.check_constant,
        }
        nodes = node_separations(args.gap_min, args.r_max, args.spacing)
        if self.check_nodes is not None:
            self.check_nodes(nodes, settings)
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
            record = self.solve_node(r, args.order_constant, args.check_constant)
            append_work(work, record)
            records[repr(r)] = record
            errors = " ".join(
                f"err_{key.removeprefix('error_')} = {record[key]:.1e}" for key in self.error_groups
            )
            print(
                f"[{count + 1}/{len(todo) + len(todo_contact)}] r = {r:.6f} L = {record['order']} {errors}"
                f" ({record['seconds']:.1f} s, total {time.perf_counter() - started:.0f} s)",
                flush=True,
            )
        table_records = [records[repr(float(r))] for r in nodes]
        contact = [records[repr(r)] for r in sorted(contact_nodes)]
        command = f"python {self.script} " + " ".join(arguments)
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(self.format_table(table_records, contact, settings, command.strip()))
        print(f"wrote {args.output} ({len(table_records)} nodes)", flush=True)


# ------------------------------------------------------------------------------------------------
# The work file
# ------------------------------------------------------------------------------------------------
def read_work(path: Path, settings: Record) -> dict[str, Record]:
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


def append_work(path: Path, record: Record) -> None:
    """Append one record and flush it to disk (an interrupted run loses at most the node in progress)."""
    with path.open("a") as handle:
        handle.write(json.dumps(record) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


# ------------------------------------------------------------------------------------------------
# Pieces of the table text
# ------------------------------------------------------------------------------------------------
def record_columns(records: Sequence[Record], *keys: str) -> tuple[np.ndarray, ...]:
    """One array per key over the records (``"values"``: shape ``(n_nodes, n_functions)``)."""
    return tuple(np.array([record[key] for record in records]) for key in keys)


def error_report_line(r: float, order: int, errors: Mapping[str, float]) -> str:
    """``#   r = ...  L = ...  error_icep = ...`` for the header's error report at one node."""
    cells = "  ".join(f"{key} = {value:.1e}" for key, value in errors.items())
    return f"#   r = {r:.6f}  L = {order:4d}  {cells}"


def nodes_line(r: FloatArray, prefix: str = "") -> str:
    """The header line that states the nodes (count, range and the step ``ds`` in ``ln(r - 2)``)."""
    return (
        f"# Nodes: {prefix}r = 2 + exp(s), s uniform, {r.shape[0]} nodes from r = {r[0]:.6f} to {r[-1]:.6f}"
        f" (ds = {math.log(r[1] - 2) - math.log(r[0] - 2):.6f})."
    )


def contact_check_lines(
    contact: Sequence[Record], predict: Callable[[float], Sequence[float]], digits: int
) -> list[str]:
    """Header lines comparing the near-contact forms with the exact solutions below the table.

    Args:
        contact: records of the check points (increasing ``r``); none gives no lines.
        predict: the near-contact forms of all functions at a gap ``xi``.
        digits: digits after the point of the printed exact values.
    """
    if not contact:
        return []
    lines = ["# Check of these forms against exact solutions below the table (same c), form - exact:"]
    for record in contact:
        gap = record["r"] - 2.0
        predicted = predict(gap)
        deviation = " ".join(f"{x - y: .1e}" for x, y in zip(predicted, record["values"], strict=True))
        exact = " ".join(f"{v: .{digits}e}" for v in record["values"])
        lines.append(f"#   xi = {gap:.1e} (L = {record['order']}): exact {exact}")
        lines.append(f"#       form - exact: {deviation}")
    return lines


def table_body(
    command: str,
    columns: Sequence[str],
    r: FloatArray,
    values: FloatArray,
    orders: np.ndarray,
    estimates: Sequence[tuple[np.ndarray, str]],
) -> list[str]:
    """The provenance line, the column line and one row per node.

    Args:
        command: the command line that generated the table.
        columns: the column names.
        r: shape ``(n,)``, the nodes; ``values``: shape ``(n_functions, n)``; ``orders``: shape ``(n,)``.
        estimates: the per-node columns after ``order``, each with its format (e.g. ``(error_icep, ".2e")``).
    """
    lines = [f"# Generated {datetime.date.today().isoformat()} by: {command}", " ".join(columns)]
    for k in range(r.shape[0]):
        row = " ".join(f"{v: .12e}" for v in values[:, k])
        tail = " ".join(format(column[k], spec) for column, spec in estimates)
        # repr(r): the exact float at which the node was solved (round-trips), so ln(r - 2) is exact.
        lines.append(f"{float(r[k])!r} {row} {orders[k]:d} {tail}")
    return lines
