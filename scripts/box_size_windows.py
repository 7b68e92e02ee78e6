"""eta_r in strain windows against N: the box-size study's time series (issue 24).

    python scripts/box_size_windows.py RUN_DIR [RUN_DIR ...] [--windows 0-6,6-12,12-20,20-40]

Each RUN_DIR is a ``sim sweep`` output folder (or a folder of run folders) whose points hold
``timeseries.csv`` and ``result.json``. Per N (and phi, Mn): the mean over seeds of each run's
time-averaged eta_r in each strain window, with the standard error over seeds (``± 0`` for one seed), and
the per-seed values. Printed as a Markdown table. Episodes of the environments last 12 strains, so the
windows 0-6 and 6-12 are what an episode's first and second halves see after the field is switched on
(here from a random packing, not from the envs' pre-sheared states).
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np


def parse_windows(text: str) -> list[tuple[float, float]]:
    """``"0-6,6-12"`` -> ``[(0, 6), (6, 12)]``; ``ValueError`` naming the bad window."""
    windows = []
    for part in text.split(","):
        bounds = part.split("-")
        try:
            low, high = (float(v) for v in bounds)
        except ValueError:
            low = high = math.nan
        if not (0.0 <= low < high):
            raise ValueError(f"each window must be LOW-HIGH with 0 <= LOW < HIGH, got {part!r}")
        windows.append((low, high))
    return windows


def window_means(run: Path, windows: list[tuple[float, float]]) -> list[float]:
    data = np.genfromtxt(run / "timeseries.csv", delimiter=",", names=True, usecols=("strain", "eta_r"))
    strain, eta = data["strain"], data["eta_r"]
    out = []
    for low, high in windows:
        inside = (strain >= low) & (strain < high)
        complete = inside.any() and strain[-1] >= high - 0.01 * (high - low)
        out.append(float(eta[inside].mean()) if complete else math.nan)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--windows", default="0-6,6-12,12-20,20-40,40-60,60-80,80-100")
    args = parser.parse_args()
    try:
        windows = parse_windows(args.windows)
    except ValueError as error:
        parser.error(f"--windows: {error}")  # exit 2
    groups: dict[tuple[float, float, int], list[list[float]]] = defaultdict(list)
    for folder in args.runs:
        for result in sorted(folder.rglob("result.json")):
            run = result.parent
            if not (run / "timeseries.csv").exists():
                continue
            r = json.loads(result.read_text())
            # float() reads back the "inf" of a field-free run (JSON has no infinity)
            key = (float(r["volume_fraction"]), float(r["mason_number"]), int(r["n_particles"]))
            groups[key].append(window_means(run, windows))
    head = " | ".join(f"strain {low:g}-{high:g}" for low, high in windows)
    print(f"| phi | Mn | N | seeds | {head} |")
    print("|" + "---|" * (4 + len(windows)))
    for (phi, mason, n), values in sorted(groups.items()):
        table = np.array(values)
        cells = []
        for j in range(len(windows)):
            column = table[:, j][np.isfinite(table[:, j])]
            if column.size == 0:
                cells.append("")
                continue
            se = column.std(ddof=1) / math.sqrt(column.size) if column.size > 1 else 0.0
            per_seed = ", ".join(f"{v:.2f}" for v in column)
            cells.append(f"{column.mean():.2f} ± {se:.2f} ({per_seed})")
        label = "inf" if math.isinf(mason) else f"{mason:g}"
        print(f"| {phi:g} | {label} | {n} | {len(values)} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
