"""Tabulate the box-size study (issue 24) from its sweep folders: per (phi, Mn, N) the box side L, the
number of field-induced layers of spacing 2.45 a that fit (L / 2.45), and over seeds the mean ± standard
error of eta_r, N1, N2 and the layer order psi, the layer spacing and the strain at which ordering sets in
(docs/layering.md); per seed, eta_r and psi.

The onset is recomputed from each run's ``layering.csv`` with today's rule
(:func:`sim.observables.layering.layer_onset_index`: a plateau S >= 10 that is at least 3 times the start's),
so runs made before that rule was tightened read the same as new ones; the ``layered`` column counts the
seeds that pass it, and the onset's mean is over those seeds.

    python scripts/box_size_table.py SWEEP_DIR [SWEEP_DIR ...] > results/box_size/table.md
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from sim.observables.layering import layer_onset_index

LAYER_SPACING = 2.45
"""Spacing of the field-induced layers, in units of a (README; docs/layering.md)."""


def mean_se(values: list[float]) -> str:
    x = np.array([v for v in values if isinstance(v, int | float) and math.isfinite(v)], dtype=float)
    if x.size == 0:
        return "–"
    if x.size == 1:
        return f"{x[0]:.3g}"
    return f"{x.mean():.3g} ± {x.std(ddof=1) / math.sqrt(x.size):.2g}"


def per_seed(values: list[float]) -> str:
    return ", ".join(f"{v:.2f}" for v in values)


def number(value: object) -> float:
    """A result.json number, NaN if missing; ``"inf"`` (no field: JSON has no infinity) is read back."""
    if isinstance(value, str) and value in ("inf", "-inf"):
        return float(value)
    return float(value) if isinstance(value, int | float) else math.nan


def onset_strain(run_dir: Path, r: dict) -> float:
    """Onset strain by today's rule from the run's layering.csv (NaN: not layered, or no file)."""
    path = run_dir / "layering.csv"
    plateau = number(r.get("layer_order"))
    if not path.exists() or not math.isfinite(plateau):
        return math.nan
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    index = layer_onset_index(table[:, 2], plateau, int(r["n_particles"]))
    return math.nan if index is None else float(table[index, 1])


def main(folders: list[str]) -> None:
    groups: dict[tuple[float, float, int], list[dict]] = defaultdict(list)
    for folder in folders:
        for result in sorted(Path(folder).glob("*/result.json")):
            r = json.loads(result.read_text())
            r["onset_now"] = onset_strain(result.parent, r)
            groups[(r["volume_fraction"], number(r["mason_number"]), r["n_particles"])].append(r)
    print(
        "| phi | Mn | N | L/a | L/2.45a | seeds | strain | eta_r | N1 | N2 | layer order psi | spacing/a "
        "| layered | onset strain | eta_r per seed | psi per seed |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (phi, mason, n), runs in sorted(groups.items(), key=lambda kv: (kv[0][0], -kv[0][1], kv[0][2])):
        side = (n * 4.0 / 3.0 * math.pi / phi) ** (1.0 / 3.0)
        runs.sort(key=lambda r: r["seed"])
        print(
            f"| {phi:g} | {'inf' if math.isinf(mason) else f'{mason:g}'} | {n} | {side:.2f} | "
            f"{side / LAYER_SPACING:.2f} | {len(runs)} | {max(r['strain'] for r in runs):.0f} | "
            f"{mean_se([r['relative_viscosity'] for r in runs])} | {mean_se([r['n1'] for r in runs])} | "
            f"{mean_se([r['n2'] for r in runs])} | {mean_se([number(r.get('layer_order')) for r in runs])} | "
            f"{mean_se([number(r.get('layer_spacing')) for r in runs])} | "
            f"{sum(math.isfinite(r['onset_now']) for r in runs)}/{len(runs)} | "
            f"{mean_se([r['onset_now'] for r in runs])} | "
            f"{per_seed([r['relative_viscosity'] for r in runs])} | "
            f"{per_seed([number(r.get('layer_order')) for r in runs])} |"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        description="Tabulate the box-size study (Markdown on stdout).", allow_abbrev=False
    )
    parser.add_argument("sweeps", nargs="+", help="folders written by python -m sim sweep")
    main(parser.parse_args().sweeps)
