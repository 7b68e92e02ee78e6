"""What a feedback controller measures: the noise of one interval's eta_r against the thickening signal.

    python scripts/interval_noise.py POINT_JSON [POINT_JSON ...] [--rate-bins 0.2,0.5,1,2,3,5]

Each ``POINT_JSON`` is an ``agents.open_loop`` point (``DIR/points/<label>.json``) of a thickening-control
env played with several realisations per start state (``--repeats K``, K >= 2). Realisations of one state
follow the same rate schedule under the same field, so at each interval their spread is the noise of the
measured interval eta_r alone (the chaos of the suspension at N particles), with the schedule's effect
removed. Printed per point (Markdown):

* the within-state standard deviation of the interval eta_r (pooled over states and intervals, and over
  the second half of the episodes only);
* the autocorrelation of that noise (each realisation minus its state's mean trace) at lags of 1, 2, 4 and
  8 intervals: how many intervals a controller must average to see through it;
* the signal: the mean interval eta_r in bins of the interval's mean shear rate (all episodes), i.e. how
  far the suspension thickens as the rate climbs under this field.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from agents.rollout import record_episodes

LAGS = (1, 2, 4, 8)


def summarise(path: Path, bins: list[float]) -> dict[str, object] | None:
    """Noise, its autocorrelation and eta_r by rate bin for one point file (None with one realisation per
    state: no noise to measure)."""
    episodes = record_episodes(path)
    traces: dict[int, list[np.ndarray]] = defaultdict(list)
    for episode in episodes:
        traces[episode["index"]].append(np.asarray(episode["trace"]["eta_r"], dtype=float))
    groups = [np.array(v) for v in traces.values() if len(v) >= 2]
    if not groups:
        return None
    variance = np.array([g.var(axis=0, ddof=1) for g in groups])  # (states, intervals)
    half = variance.shape[1] // 2
    residuals = np.concatenate([g - g.mean(axis=0) for g in groups])
    correlation = [float(np.mean([np.corrcoef(r[:-lag], r[lag:])[0, 1] for r in residuals])) for lag in LAGS]
    rates = np.concatenate([np.asarray(e["trace"]["shear_rate"], dtype=float) for e in episodes])
    etas = np.concatenate([np.asarray(e["trace"]["eta_r"], dtype=float) for e in episodes])
    by_rate = []
    for low, high in zip(bins[:-1], bins[1:], strict=True):
        inside = (rates >= low) & (rates < high if high != bins[-1] else rates <= high)
        by_rate.append(
            (low, high, float(etas[inside].mean()) if inside.any() else float("nan"), int(inside.sum()))
        )
    return {
        "label": path.stem,
        "states": len(groups),
        "realisations": int(np.median([len(g) for g in groups])),
        "sd": float(np.sqrt(variance.mean())),
        "sd_second_half": float(np.sqrt(variance[:, half:].mean())),
        "correlation": correlation,
        "by_rate": by_rate,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("points", nargs="+", type=Path)
    parser.add_argument("--rate-bins", default="0.2,0.5,1,2,3,5", help="edges of the shear-rate bins")
    args = parser.parse_args(argv)
    try:
        bins = [float(b) for b in args.rate_bins.split(",")]
    except ValueError:
        parser.error(f"--rate-bins must be comma-separated numbers, got {args.rate_bins!r}")
    if len(bins) < 2 or any(b <= a for a, b in zip(bins, bins[1:], strict=False)):
        parser.error(f"--rate-bins must be at least two increasing edges, got {args.rate_bins!r}")
    rows = []
    for path in args.points:
        try:
            row = summarise(path, bins)
        except ValueError as exc:
            parser.error(str(exc))
        if row is None:
            print(
                f"{path}: skipped, one realisation per state (agents.open_loop --repeats 2 or more)",
                file=sys.stderr,
            )
        else:
            rows.append(row)
    lags = " | ".join(f"lag {k}" for k in LAGS)
    print(f"| point | states x realisations | sd of interval eta_r | 2nd half | {lags} |")
    print("|---|---|---|---|" + "---|" * len(LAGS))
    for r in rows:
        corr = " | ".join(f"{c:.2f}" for c in r["correlation"])  # type: ignore[attr-defined]
        size = f"{r['states']} x {r['realisations']}"
        print(f"| {r['label']} | {size} | {r['sd']:.2f} | {r['sd_second_half']:.2f} | {corr} |")
    print()
    heads = " | ".join(f"rate {lo:g}-{hi:g}" for lo, hi in zip(bins[:-1], bins[1:], strict=True))
    print(f"| point | {heads} |")
    print("|---|" + "---|" * (len(bins) - 1))
    for r in rows:
        cells = " | ".join(f"{m:.2f} ({n})" for _, _, m, n in r["by_rate"])  # type: ignore[attr-defined]
        print(f"| {r['label']} | {cells} |")


if __name__ == "__main__":
    main()
