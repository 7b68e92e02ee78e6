"""Where the viscosity goes when the field turns (issue 44): the stress split over the start of a switch.

From the end state of a steady run of the direction map (as ``scripts/direction_switch.py`` takes it), two
short runs over ``--strain`` (default 0.5) from the same state: one that keeps the field (the control) and one
that turns it to ``--direction`` at the same Mason number. For each, the shear stress ``Sigma_xy / gammadot``
of every stress contribution (``sim.simulation.STRESS_CONTRIBUTIONS``: solvent, Stokes drag, lubrication,
repulsion, the induced-charge and dielectrophoretic terms; units ``eta``, so the parts add up to eta_r),
step-weighted over bins whose edges (``--edges``, default 0 0.002 0.01 0.05 0.1 0.25 0.5, in strain since the
switch) resolve the first hundredths of a strain. A part that jumps in the first bin is the field acting on
the same structure; a part that moves over later bins is the structure changing.

Writes ``OUT/split.csv`` (run, bin start, bin end, one column per contribution, total) and
``OUT/manifest.json``; a pure function of its inputs; a rerun with ``split.csv`` present does nothing. Usage::

    python scripts/direction_switch_split.py \\
        --from "/work/runs/direction_map/phi0.45_z/phi0.450_N500_Mn1_e0,0,1_seed1" \\
        --direction 0,1,0 --out results/direction_switch/split_z_to_y_Mn1_seed1
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from direction_switch import _direction, _positive, load_steady, turned  # noqa: E402

import sim  # noqa: E402
from sim.runs import RunFolderError, claim  # noqa: E402
from sim.runs.io import write_text_atomically  # noqa: E402
from sim.simulation import STRESS_CONTRIBUTIONS  # noqa: E402

EDGES = (0.0, 0.002, 0.01, 0.05, 0.1, 0.25, 0.5)
"""Default bin edges in strain since the switch."""


def split_bins(
    strain: np.ndarray, strain_steps: np.ndarray, parts: np.ndarray, edges: np.ndarray
) -> np.ndarray:
    """Step-weighted means of ``parts`` (steps x C) over the bins ``[edges[i], edges[i+1])`` of ``strain``
    (each step's start, with its strain ``strain_steps``); NaN for a bin no step starts in."""
    out = np.full((len(edges) - 1, parts.shape[1]), np.nan)
    for i, (low, high) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        inside = (strain >= low) & (strain < high)
        if inside.any():
            weights = strain_steps[inside]
            out[i] = weights @ parts[inside] / weights.sum()
    return out


def shear_parts(config: sim.SimulationConfig, state: sim.SimulationState, direction, strain: float):
    """One run from ``state`` with the field along ``direction`` for ``strain``
    (:func:`direction_switch.turned`): (each step's strain since the start, each step's strain, steps x C
    of ``Sigma_xy / gammadot`` per contribution)."""
    records, since = turned(config, state, direction, strain)
    parts = records.stress[:, :, 0, 1] / records.shear_rate[:, None]
    return since, records.time_step * records.shear_rate, parts


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("--from", dest="source", required=True, type=Path, help="steady run folder")
    parser.add_argument("--direction", required=True, type=_direction, help="new field direction x,y,z")
    parser.add_argument("--strain", type=_positive, default=0.5, help="strain of both runs (default 0.5)")
    parser.add_argument(
        "--edges", type=float, nargs="+", default=None, help="bin edges in strain (default: 0 0.002 ... 0.5)"
    )
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="delete the folder's previous run first")
    return parser


def main(argv: list[str] | None = None) -> Path:
    parser = build_parser()
    args = parser.parse_args(argv)
    edges = np.asarray(EDGES if args.edges is None else args.edges, dtype=float)
    if edges.size < 2 or edges[0] != 0.0 or np.any(np.diff(edges) <= 0) or edges[-1] > args.strain:
        parser.error(f"--edges must rise from 0 to at most --strain {args.strain}, got {edges.tolist()}")
    try:
        config, state, _ = load_steady(args.source)
    except ValueError as exc:
        parser.exit(2, f"direction_switch_split.py: error: --from {args.source}: {exc}\n")
    identity = {
        "source": str(args.source.resolve()),
        "source_config": config.to_dict(),
        "direction": list(args.direction),
        "strain": args.strain,
        "edges": edges.tolist(),
    }
    try:
        claim(
            args.out, "scripts/direction_switch_split.py", identity, overwrite=args.overwrite, argv=sys.argv
        )
    except RunFolderError as exc:
        parser.exit(2, f"direction_switch_split.py: error: {exc}\n")
    csv = args.out / "split.csv"
    if csv.exists():
        return csv
    lines = ["run,strain_from,strain_to," + ",".join(STRESS_CONTRIBUTIONS) + ",total"]
    for run, direction in (("keep", config.field_direction), ("switch", args.direction)):
        means = split_bins(*shear_parts(config, state, direction, args.strain), edges)
        for low, high, row in zip(edges[:-1], edges[1:], means, strict=True):
            cells = ",".join(f"{v:.6g}" for v in (*row, row.sum()))
            lines.append(f"{run},{low:g},{high:g},{cells}")
    write_text_atomically(csv, "\n".join(lines) + "\n")
    print("\n".join(lines))
    return csv


if __name__ == "__main__":
    main()
