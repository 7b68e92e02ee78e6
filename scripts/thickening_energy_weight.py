"""Rescore thickening-control episodes for other energy weights w_E (issue 21: choosing v1's w_E).

    python scripts/thickening_energy_weight.py POINTS_DIR [POINTS_DIR ...] [--weights 1,0.5,0.3,0.2,0.1]

Each POINTS_DIR is a folder of ``agents.open_loop`` or ``agents.controllers`` point files (``points/`` or
``tuning/``) of a ``dipenv/ThickeningControl*`` environment. Every point keeps each interval's ``eta_r``,
field energy ``<1/Mn_ref>`` and shear rate in its episodes' traces, so the return of another reward weight
needs no rerun: per episode ``R(w_E) = -sum_k [max(0, eta_r,k - eta_cap) + w_E <1/Mn_ref>_k]`` over its
intervals (``dipenv.rewards.ThickeningPenaltyReward``, applied by ``agents.open_loop.rescore``, which
keeps a failed episode's stored failure penalty), with the cap the episode was run with. Prints two
Markdown tables: per point, the mean eta_r, time above the cap, excess and energy, and
eta_r by the interval's shear rate (thickening at a fixed field); then per w_E the mean return of every
point over its episodes and the best point.
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path
from typing import Any

import numpy as np

from agents.open_loop import rescore
from dipenv.rewards import ThickeningPenaltyReward

RATE_BINS = ((0.0, 0.5), (0.5, 1.5), (1.5, 3.0), (3.0, np.inf))
"""Shear-rate bins (units gammadot_ref) of the thickening table."""


def load_points(folders: list[Path]) -> dict[str, dict[str, Any]]:
    """Label -> the point's ``record`` and its intervals' ``eta``, ``energy``, ``rate`` (all episodes
    concatenated) and ``cap``; ``ValueError`` naming a folder without point files."""
    points: dict[str, dict[str, Any]] = {}
    for folder in folders:
        files = sorted(folder.glob("*.json"))
        if not files:
            raise ValueError(f"{folder} holds no point files (*.json)")
        for path in files:
            record = json.loads(path.read_text())
            traces = [episode["trace"] for episode in record["episodes"]]
            points[f"{folder.parent.name}/{record.get('label', path.stem)}"] = {
                "record": record,
                "eta": np.concatenate([t["eta_r"] for t in traces]),
                "energy": np.concatenate([t["field_energy"] for t in traces]),
                "rate": np.concatenate([t["shear_rate"] for t in traces]),
                "cap": float(traces[0]["eta_cap"]),
            }
    return points


def mean_return(point: dict[str, Any], weight: float) -> float:
    """Mean episode return of ``point`` under energy weight ``weight`` and its own cap
    (:func:`agents.open_loop.rescore` with :class:`dipenv.rewards.ThickeningPenaltyReward`)."""
    record = rescore(copy.deepcopy(point["record"]), ThickeningPenaltyReward(point["cap"], weight))
    return float(np.mean([episode["return"] for episode in record["episodes"]]))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("folders", nargs="+", type=Path, help="folders of point files")
    parser.add_argument("--weights", default="1,0.5,0.3,0.2,0.1", help="energy weights w_E, comma-separated")
    args = parser.parse_args()
    try:
        weights = [float(w) for w in args.weights.split(",")]
    except ValueError:
        parser.error(f"--weights takes numbers separated by commas, got {args.weights!r}")
    if any(not np.isfinite(w) or w < 0.0 for w in weights):
        parser.error(f"--weights must be finite and >= 0, got {args.weights!r}")
    try:
        points = load_points(args.folders)
    except ValueError as error:
        parser.error(f"folders: {error}")
    bins = " | ".join(f"eta_r at rate {lo:g}-{hi:g}" for lo, hi in RATE_BINS)
    print(f"| point | episodes | eta_r | time above cap | excess | energy | {bins} |")
    print("|---|---|---|---|---|---|" + "---|" * len(RATE_BINS))
    for label, p in points.items():
        excess = np.maximum(0.0, p["eta"] - p["cap"])
        by_rate = []
        for lo, hi in RATE_BINS:
            mask = (p["rate"] >= lo) & (p["rate"] < hi)
            by_rate.append(f"{p['eta'][mask].mean():.2f}" if mask.any() else "-")
        episodes = len(p["record"]["episodes"])
        print(
            f"| {label} | {episodes} | {p['eta'].mean():.2f} | {(excess > 0).mean():.0%} | "
            f"{excess.mean():.2f} | {p['energy'].mean():.2f} | " + " | ".join(by_rate) + " |"
        )
    print()
    print("| w_E | " + " | ".join(points) + " | best |")
    print("|---|" + "---|" * (len(points) + 1))
    for weight in weights:
        means = {label: mean_return(p, weight) for label, p in points.items()}
        best = max(means, key=lambda k: means[k])
        print(f"| {weight:g} | " + " | ".join(f"{v:.1f}" for v in means.values()) + f" | {best} |")


if __name__ == "__main__":
    main()
