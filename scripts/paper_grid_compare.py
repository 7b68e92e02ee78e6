"""Compare the paper grid (``results/paper_grid/spec.yml``) point by point with the paper's results.

    python scripts/paper_grid_compare.py runs/paper_grid [--out results/paper_grid]

Reads every finished point (``sim.plots.sweep.load_sweep``: means and standard errors over seeds),
writes ``values.md`` (eta_r, N1, N2, particle pressure, ``U_rms^DIP / U_rms^shear``, D_yy per phi and Mn)
and ``comparison.md`` (each statement of docs/validation.md#published-results about sheared dipolophoresis,
the numbers
that test it and whether they agree), and prints both. Points not run yet show as "–"; a statement
whose points are missing reads "not run".

The reports are written beside the sweep's points (the default ``--out``: files derived from that sweep,
rewritten every time; the sweep folder stays ``sim sweep``'s). Another ``--out`` follows the run-folder
protocol (:mod:`agents.folders`): it is claimed for this script with the sweep's path as identity (a report
of another sweep is refused, exit 2, unless ``--overwrite``); a pre-manifest folder holding the reports is
adopted.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from agents.folders import add_folder_options, report_folder, write_text_atomic
from sim.observables.stress import DIPOLOPHORESIS_CONTRIBUTIONS, SHEAR_CONTRIBUTIONS, STRESS_CONTRIBUTIONS
from sim.plots.sweep import Group, Series, load_sweep

SCRIPT = "paper_grid_compare.py"
FILES = ("values.md", "comparison.md")
"""The reports this script writes (a pre-manifest report folder holds them)."""

Value = tuple[float, float]


def _fmt(value: Value | None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value[0]):
        return "–"
    mean, error = value
    text = f"{mean:.{digits}g}"
    return text + (f" ± {error:.2g}" if math.isfinite(error) else "")


def _mason(mn: float) -> str:
    return "inf" if math.isinf(mn) else f"{mn:g}"


class Grid:
    """Seed-averaged quantities of one series, looked up by (phi, Mn)."""

    def __init__(self, series: Series) -> None:
        self.series = series

    def get(self, phi: float, mn: float, name: str) -> Value | None:
        group: Group | None = self.series.groups.get((phi, mn))
        if group is None:
            return None
        return group.stats.get(name)

    def mean(self, phi: float, mn: float, name: str) -> float:
        value = self.get(phi, mn, name)
        return value[0] if value is not None else math.nan


SHEAR_PARTS = tuple(STRESS_CONTRIBUTIONS[k] for k in SHEAR_CONTRIBUTIONS)
DIP_PARTS = tuple(STRESS_CONTRIBUTIONS[k] for k in DIPOLOPHORESIS_CONTRIBUTIONS)


def _parts(group: Group, key: str) -> str:
    """Seed-mean of the shear-and-repulsion and of the dipolophoresis parts of ``key``."""
    shear = [sum(r["contributions"][n][key] for n in SHEAR_PARTS) for r in group.results]
    dip = [sum(r["contributions"][n][key] for n in DIP_PARTS) for r in group.results]
    return f"{sum(shear) / len(shear):.2f} / {sum(dip) / len(dip):.2f}"


def values_table(grid: Grid) -> str:
    lines = [
        "| phi | Mn | seeds | eta_r | N1 | N2 | eta_r shear / DIP | N1 shear / DIP | N2 shear / DIP "
        "| Pi | U_rms ratio | D_yy | steps/strain |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (phi, mn), group in sorted(grid.series.groups.items()):
        stats = group.stats
        steps = sum(r["steps"] / r["strain"] for r in group.results) / len(group.results)
        lines.append(
            f"| {phi:.2f} | {_mason(mn)} | {len(group.results)} | {_fmt(stats['eta_r'])} "
            f"| {_fmt(stats['n1'])} | {_fmt(stats['n2'])} | {_parts(group, 'relative_viscosity')} "
            f"| {_parts(group, 'n1')} | {_parts(group, 'n2')} | {_fmt(stats.get('particle_pressure'))} "
            f"| {_fmt(stats['u_rms_ratio'])} | {_fmt(stats['diffusivity_yy'])} | {steps:.0f} |"
        )
    return "\n".join(lines) + "\n"


def _ratio(grid: Grid, phi: float, a: float, b: float) -> float:
    return grid.mean(phi, a, "eta_r") / grid.mean(phi, b, "eta_r")


def claims(grid: Grid) -> list[tuple[str, str, str]]:
    """(paper says, we get, agrees?) rows; the thresholds are the paper's words made numbers."""
    phis = grid.series.phis
    rows: list[tuple[str, str, str]] = []

    def row(statement: str, parts: list[str], verdicts: list[bool]) -> None:
        if not parts:
            rows.append((statement, "not run", "–"))
            return
        verdict = "yes" if all(verdicts) else ("no" if not any(verdicts) else "partly")
        rows.append((statement, "; ".join(parts), verdict))

    # phi = 0.15 nearly Newtonian: every Mn within 10% of pure shear
    parts, ok = [], []
    if 0.15 in phis:
        ratios = [
            grid.mean(0.15, mn, "eta_r") / grid.mean(0.15, math.inf, "eta_r") for mn in grid.series.masons
        ]
        ratios = [r for r in ratios if math.isfinite(r)]
        if ratios:
            spread = max(abs(r - 1) for r in ratios)
            parts.append(f"phi 0.15: eta_r within {100 * spread:.0f}% of pure shear over Mn")
            ok.append(spread <= 0.10)
    row("phi = 0.15 nearly Newtonian (within 10% of pure shear)", parts, ok)

    # low Mn lowers the viscosity at phi >= 0.3
    parts, ok = [], []
    for phi in (p for p in phis if p >= 0.3):
        for mn in (0.1, 0.5):
            r = _ratio(grid, phi, mn, math.inf)
            if math.isfinite(r):
                parts.append(f"phi {phi:g}, Mn {mn:g}: {r:.2f} x pure shear")
                ok.append(r < 1)
    row("Mn <= 0.5 gives a lower viscosity than no field (phi >= 0.3)", parts, ok)

    # Mn >= 5 collapses onto pure shear: Mn = 10 within 10%
    parts, ok = [], []
    for phi in phis:
        r = _ratio(grid, phi, 10.0, math.inf)
        if math.isfinite(r):
            parts.append(f"phi {phi:g}: Mn 10 at {r:.2f} x pure shear")
            ok.append(abs(r - 1) <= 0.10)
    row("Mn >= 5 collapses onto the pure-shear curve (Mn = 10 within 10%)", parts, ok)

    # strong drop from Mn = 2 to Mn = 1 (phi >= 0.3)
    parts, ok = [], []
    for phi in (p for p in phis if p >= 0.3):
        r = _ratio(grid, phi, 1.0, 2.0)
        if math.isfinite(r):
            parts.append(f"phi {phi:g}: eta_r(Mn 1)/eta_r(Mn 2) = {r:.2f}")
            ok.append(r < 0.8)
    row("strong drop from Mn = 2 to Mn = 1 (ratio < 0.8)", parts, ok)

    # ~5x thickening between the plateaus at phi = 0.45-0.5
    parts, ok = [], []
    for phi in (p for p in phis if p >= 0.45):
        lows = [grid.mean(phi, mn, "eta_r") for mn in (0.1, 0.5)]
        lows = [v for v in lows if math.isfinite(v)]
        high = grid.mean(phi, 10.0, "eta_r")
        if lows and math.isfinite(high):
            low = min(lows)
            parts.append(f"phi {phi:g}: eta_r(Mn 10) / min(Mn 0.1, 0.5) = {high / low:.1f}")
            ok.append(3.0 <= high / low <= 8.0)
    row("~5x thickening between low- and high-Mn plateaus at phi = 0.45-0.5 (3-8x)", parts, ok)

    # normal stress signs at low Mn
    parts, ok = [], []
    for phi in phis:
        n1, n2 = grid.mean(phi, 0.1, "n1"), grid.mean(phi, 0.1, "n2")
        if math.isfinite(n1):
            expected = (n1 > 0 and n2 < 0) if phi < 0.3 else (n1 < 0 and n2 > 0)
            parts.append(f"phi {phi:g}: N1 {n1:+.2g}, N2 {n2:+.2g}")
            ok.append(expected)
    row("Mn = 0.1: N1 > 0, N2 < 0 at phi = 0.15; N1 < 0, N2 > 0 at phi >= 0.3", parts, ok)

    parts, ok = [], []
    for phi in phis:
        n1, n2 = grid.mean(phi, 10.0, "n1"), grid.mean(phi, 10.0, "n2")
        if math.isfinite(n1):
            parts.append(f"phi {phi:g}: N1 {n1:+.2g}, N2 {n2:+.2g}")
            ok.append(n1 < 0 and n2 < 0)
    row("Mn >> 1 (here 10): N1 < 0 and N2 < 0", parts, ok)

    # velocity ratio crossing 1 at Mn = 0.7-1 (accept 0.5-1.5)
    parts, ok = [], []
    for phi, mn_c in grid.series.crossovers().items():
        if math.isfinite(mn_c):
            parts.append(f"phi {phi:g}: Mn_c = {mn_c:.2f}")
            ok.append(0.5 <= mn_c <= 1.5)
    row("U_rms^DIP / U_rms^shear crosses 1 at Mn = 0.7-1 (0.5-1.5 accepted)", parts, ok)

    # D_yy smallest near Mn = 1
    parts, ok = [], []
    for phi in phis:
        finite = [
            (grid.mean(phi, mn, "diffusivity_yy"), mn)
            for mn in grid.series.masons
            if math.isfinite(mn) and math.isfinite(grid.mean(phi, mn, "diffusivity_yy"))
        ]
        if len(finite) >= 3:
            lowest = min(finite)[1]
            parts.append(f"phi {phi:g}: smallest at Mn {lowest:g}")
            ok.append(0.5 <= lowest <= 2.0)
    row("D_yy smallest near Mn = 1 (0.5-2)", parts, ok)
    return rows


def comparison_table(rows: list[tuple[str, str, str]]) -> str:
    lines = ["| paper says | we get | agrees? |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("sweep", type=Path, help="folder written by python -m sim sweep")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default: the sweep folder, beside its points; another folder is claimed)",
    )
    add_folder_options(parser, "--out")
    args = parser.parse_args(argv)
    try:
        loaded = load_sweep(args.sweep)
    except (FileNotFoundError, ValueError) as exc:
        parser.error(str(exc))
    series = [s for s in loaded if s.key and "dip" in str(s.key)] or loaded
    grid = Grid(series[0])
    values = values_table(grid)
    comparison = comparison_table(claims(grid))
    out = report_folder(
        parser, args.sweep, args.out, SCRIPT, FILES, argv=argv, resume=args.resume, overwrite=args.overwrite
    )
    write_text_atomic(out / "values.md", values)
    write_text_atomic(out / "comparison.md", comparison)
    print(values)
    print(comparison, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
