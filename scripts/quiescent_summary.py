"""Table and figure of the quiescent sweep (``results/quiescent/spec.yml``): particle pressure, contact
structure along the field and diffusivities against the volume fraction, per mechanism.

    python scripts/quiescent_summary.py runs/quiescent [--out results/quiescent/short]

Writes ``table.md`` and ``quiescent.png`` into ``--out`` (default: the sweep folder, beside its points: files
derived from that sweep, rewritten every time). Another ``--out`` follows the run-folder protocol
(:mod:`agents.folders`): claimed for this script with the sweep's path as identity (a report of another
sweep is refused, exit 2, unless ``--overwrite``); a pre-manifest folder holding the reports is adopted.
Units: time a/U0, stresses eps E0^2, diffusivities U0 a (U0 = eps E0^2 a / eta); the field is along y.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from agents.folders import add_folder_options, report_folder, save_figure, write_text_atomic  # noqa: E402
from sim.runs.io import read_json  # noqa: E402

SCRIPT = "quiescent_summary.py"
FILES = ("table.md", "quiescent.png")
"""The reports this script writes (a pre-manifest report folder holds them)."""


def load(sweep: Path) -> list[dict[str, Any]]:
    """Every finished point's ``result.json``, sorted by mechanism and volume fraction."""
    results = []
    for path in sorted(sweep.glob("*/result.json")):
        result = read_json(path)
        if result.get("shear_rate", 1) == 0:
            results.append(result)
    return sorted(results, key=lambda r: (r["mechanism"], r["volume_fraction"]))


def _fmt(value: float, error: float | None = None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    text = f"{value:.{digits}g}"
    if error is not None and math.isfinite(error):
        text += f" ± {error:.2g}"
    return text


def table(results: list[dict[str, Any]]) -> str:
    lines = [
        "| mechanism | phi | Pi | Pi: repulsion / DEP virial | contacts per particle | A_yy (field) "
        "| D_xx | D_yy (field) | D_zz |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        parts = r["contributions"]
        fabric = r.get("fabric_tensor") or [[math.nan] * 3] * 3
        lines.append(
            f"| {r['mechanism']} | {r['volume_fraction']:.2f} "
            f"| {_fmt(r['particle_pressure'], r['particle_pressure_stderr'])} "
            f"| {_fmt(parts['repulsion']['particle_pressure'])} "
            f"/ {_fmt(parts['dep_virial']['particle_pressure'])} "
            f"| {_fmt(r.get('contact_number', math.nan))} | {_fmt(fabric[1][1])} "
            f"| {_fmt(r.get('diffusivity_xx', math.nan))} | {_fmt(r.get('diffusivity_yy', math.nan))} "
            f"| {_fmt(r.get('diffusivity_zz', math.nan))} |"
        )
    return "\n".join(lines) + "\n"


def figure(results: list[dict[str, Any]], path: Path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for mechanism, marker in (("dip", "o"), ("dep", "s")):
        rows = [r for r in results if r["mechanism"] == mechanism]
        if not rows:
            continue
        phi = [r["volume_fraction"] for r in rows]
        axes[0].errorbar(
            phi,
            [r["particle_pressure"] for r in rows],
            yerr=[r["particle_pressure_stderr"] for r in rows],
            marker=marker,
            label=mechanism,
        )
        axes[1].plot(phi, [r["fabric_tensor"][1][1] for r in rows], marker=marker, label=f"{mechanism}: A_yy")
        axes[1].plot(
            phi, [r["contact_number"] for r in rows], marker=marker, ls="--", label=f"{mechanism}: Z"
        )
        axes[2].plot(phi, [r["diffusivity_yy"] for r in rows], marker=marker, label=f"{mechanism}: D_yy")
        axes[2].plot(
            phi, [r["diffusivity_xx"] for r in rows], marker=marker, ls="--", label=f"{mechanism}: D_xx"
        )
    axes[0].axhline(0.0, color="k", lw=0.8)
    axes[0].set(xlabel="phi", ylabel="Pi / (eps E0^2)", title="particle pressure")
    axes[1].axhline(1 / 3, color="k", lw=0.8, ls=":")
    axes[1].set(xlabel="phi", title="contacts: A_yy (1/3 isotropic, 1 chains) and Z")
    axes[2].set(xlabel="phi", ylabel="D / (U0 a)", title="diffusivity", yscale="log")
    for ax in axes:
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


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
    results = load(args.sweep)
    if not results:
        parser.error(f"no finished quiescent points in {args.sweep}")
    out = report_folder(
        parser, args.sweep, args.out, SCRIPT, FILES, argv=argv, resume=args.resume, overwrite=args.overwrite
    )
    text = table(results)
    write_text_atomic(out / "table.md", text)
    figure(results, out / "quiescent.png")
    print(text, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
