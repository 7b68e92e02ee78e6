"""The field-direction map (issue 44): table and figure from the sweeps of ``scripts/direction_map.sh``.

Reads ``ROOT/phi<phi>_<direction>/<point>/result.json`` (one ``sim sweep`` folder per volume fraction and
direction), averages each (phi, direction, Mn) over its seeds (mean and standard error over seeds; with one
seed, the run's own block standard error) and prints a Markdown table per volume fraction: eta_r, N1, N2,
the layer order psi along the box axis nearest the field, and the stress split of eta_r into hydrodynamic
(Stokes drag + lubrication), repulsion and dipolophoretic (ICEP isolated + pair, DEP virial + stresslet)
parts (the solvent's 1 is left out of the split). ``--plot PNG`` draws eta_r against Mn, one line per
direction, one panel per phi, with the no-field value as a band. ``--collect DEST`` copies the small
files of every finished point (``result.json``, ``params.json``, ``layering.csv``) to ``DEST`` in the
same layout, for committing (the sweep reuses a point from its ``result.json`` and ``params.json``).

    python scripts/direction_map_table.py /work/runs/direction_map --plot results/direction_map/map.png \\
        --collect results/direction_map > results/direction_map/table.md
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

DIRECTIONS = {
    "y": "y (gradient)",
    "z": "z (vorticity)",
    "x": "x (flow)",
    "ext": "(x+y)/sqrt2 (extensional)",
    "comp": "(x-y)/sqrt2 (compressional)",
    "yz": "(y+z)/sqrt2",
}
NO_FIELD_ETA = {0.45: (10.0, "N = 500 box-size study, strains 20-100"), 0.30: (math.nan, "")}
HYDRODYNAMIC = ("stokes_drag", "lubrication")
DIPOLOPHORETIC = ("icep_isolated", "icep_pair", "dep_virial", "dep_stresslet")
SMALL_FILES = ("result.json", "params.json", "layering.csv")
FOLDER = re.compile(r"^phi(?P<phi>[0-9.]+)_(?P<direction>[a-z]+)$")


def read_points(root: Path) -> dict[tuple[float, str, float], list[dict[str, Any]]]:
    """Finished points by (phi, direction key, Mn)."""
    points: dict[tuple[float, str, float], list[dict[str, Any]]] = defaultdict(list)
    for folder in sorted(root.iterdir()):
        match = FOLDER.match(folder.name)
        if not match or not folder.is_dir():
            continue
        for result in sorted(folder.glob("*/result.json")):
            data = json.loads(result.read_text())
            key = (round(float(match["phi"]), 3), match["direction"], float(data["mason_number"]))
            points[key].append(data)
    return points


def _mean(values: list[float], errors: list[float]) -> tuple[float, float]:
    if len(values) == 1:
        return values[0], errors[0]
    array = np.asarray(values, dtype=float)
    return float(array.mean()), float(array.std(ddof=1) / math.sqrt(array.size))


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Seed average of one (phi, direction, Mn)."""
    out: dict[str, Any] = {"seeds": sorted(int(r["seed"]) for r in runs)}
    for name in ("relative_viscosity", "n1", "n2", "layer_order"):
        values = [float(r[name]) for r in runs]
        errors = [float(r.get(f"{name}_stderr", math.nan)) for r in runs]
        out[name], out[f"{name}_stderr"] = _mean(values, errors)
    for part, names in (
        ("hydrodynamic", HYDRODYNAMIC),
        ("repulsion", ("repulsion",)),
        ("dip", DIPOLOPHORETIC),
    ):
        values = [sum(float(r["contributions"][n]["relative_viscosity"]) for n in names) for r in runs]
        out[f"eta_{part}"] = float(np.mean(values))
    return out


def _cell(mean: float, error: float, digits: int = 2) -> str:
    if not math.isfinite(mean):
        return ""
    return f"{mean:.{digits}f} ± {error:.{digits}f}" if math.isfinite(error) else f"{mean:.{digits}f}"


def table(points: dict[tuple[float, str, float], list[dict[str, Any]]]) -> str:
    lines = []
    for phi in sorted({key[0] for key in points}, reverse=True):
        masons = sorted({key[2] for key in points if key[0] == phi})
        lines += [f"### phi = {phi:.2f}: eta_r (mean ± s.e. over seeds; seeds in brackets)", ""]
        lines.append("| direction | " + " | ".join(f"Mn {m:g}" for m in masons) + " |")
        lines.append("|---|" + "---|" * len(masons))
        for direction, label in DIRECTIONS.items():
            cells = []
            for mason in masons:
                runs = points.get((phi, direction, mason))
                if not runs:
                    cells.append("")
                    continue
                s = summarise(runs)
                cells.append(
                    f"{_cell(s['relative_viscosity'], s['relative_viscosity_stderr'])} [{len(runs)}]"
                )
            if any(cells):
                lines.append(f"| {label} | " + " | ".join(cells) + " |")
        lines += ["", f"### phi = {phi:.2f}: every quantity", ""]
        lines.append(
            "| direction | Mn | seeds | eta_r | N1 | N2 | psi | eta_r: hydrodynamic | repulsion | DIP |"
        )
        lines.append("|---|---|---|---|---|---|---|---|---|---|")
        for direction, label in DIRECTIONS.items():
            for mason in masons:
                runs = points.get((phi, direction, mason))
                if not runs:
                    continue
                s = summarise(runs)
                lines.append(
                    f"| {label} | {mason:g} | {','.join(map(str, s['seeds']))} | "
                    f"{_cell(s['relative_viscosity'], s['relative_viscosity_stderr'])} | "
                    f"{_cell(s['n1'], s['n1_stderr'], 1)} | {_cell(s['n2'], s['n2_stderr'], 1)} | "
                    f"{_cell(s['layer_order'], s['layer_order_stderr'], 3)} | {s['eta_hydrodynamic']:.2f} | "
                    f"{s['eta_repulsion']:.2f} | {s['eta_dip']:.2f} |"
                )
        lines.append("")
    return "\n".join(lines)


def plot(points: dict[tuple[float, str, float], list[dict[str, Any]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phis = sorted({key[0] for key in points}, reverse=True)
    fig, axes = plt.subplots(1, len(phis), figsize=(5.5 * len(phis), 4.2), squeeze=False)
    for ax, phi in zip(axes[0], phis, strict=True):
        for direction, label in DIRECTIONS.items():
            masons = sorted(key[2] for key in points if key[0] == phi and key[1] == direction)
            if not masons:
                continue
            stats = [summarise(points[(phi, direction, m)]) for m in masons]
            ax.errorbar(
                masons,
                [s["relative_viscosity"] for s in stats],
                yerr=[s["relative_viscosity_stderr"] for s in stats],
                marker="o",
                capsize=3,
                label=label,
            )
        eta, source = NO_FIELD_ETA.get(phi, (math.nan, ""))
        if math.isfinite(eta):
            ax.axhline(eta, color="0.4", ls="--", lw=1, label=f"no field ({source})")
        ax.set_xscale("log")
        ax.set_xlabel("Mason number Mn")
        ax.set_ylabel("relative viscosity eta_r")
        ax.set_title(f"phi = {phi:.2f}, N = 500, strains 10-30")
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def collect(root: Path, dest: Path) -> int:
    count = 0
    for result in root.glob("phi*_*/*/result.json"):
        target = dest / result.parent.relative_to(root)
        target.mkdir(parents=True, exist_ok=True)
        for name in SMALL_FILES:
            if (result.parent / name).exists():
                shutil.copy2(result.parent / name, target / name)
        count += 1
    return count


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], allow_abbrev=False)
    parser.add_argument("root", type=Path, help="folder holding the phi<phi>_<direction> sweeps")
    parser.add_argument("--plot", type=Path, help="write the figure here (PNG)")
    parser.add_argument("--collect", type=Path, help="copy the finished points' small files here")
    args = parser.parse_args(argv)
    if not args.root.is_dir():
        parser.exit(2, f"direction_map_table.py: error: {args.root} is not a folder\n")
    points = read_points(args.root)
    if not points:
        parser.exit(2, f"direction_map_table.py: error: no finished points under {args.root}\n")
    print(table(points))
    if args.plot:
        plot(points, args.plot)
    if args.collect:
        print(f"collected {collect(args.root, args.collect)} points into {args.collect}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
