"""Headroom of rate-aware control, estimated from the constant fields alone (a quasi-static oracle).

    python scripts/rate_oracle.py POINTS_DIR [--cap 7.7] [--energy-weight 0.3]
        [--rate-bins 0.2,0.35,0.5,0.75,1,1.5,2,3,4,5] [--reference Mn0.5]

``POINTS_DIR`` holds ``agents.open_loop`` points of a thickening-control env (``DIR/points``), all on the
same test schedules. Every interval of every episode is put in a bin of its mean shear rate. Per bin and
constant field the script averages the interval's excess ``max(0, eta_r - cap)``, its field energy and its
reward ``-(excess + w_E energy)``. A controller that knew the rate and switched at once between the
measured constant fields, finding in each bin the suspension as that constant field left it, would score
the best field's averages in every bin (weighted by the time the schedules spend in it). That is the
*quasi-static oracle*. It is optimistic, because it ignores the 0.5–1 time units the microstructure needs
to follow a new field. It is also limited to the measured fields.

Printed (Markdown):

* per bin, the time share, each field's mean reward per interval and the best field;
* the oracle's return over an episode (48 intervals at the mean reward), excess and energy, against the
  constant fields';
* the oracle's energy front: for weights ``lambda``, the fields that minimise ``excess + lambda energy``
  bin by bin. The front is joined linearly, which is what sharing the time between two oracles gives. The
  script reads the least energy at which it reaches the reference constant's excess, and the energy
  saving that this allows against the reference.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

EPISODE_INTERVALS = 48
LAMBDAS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 2.0, 1e3)


def load(points: Path, bins: np.ndarray, cap: float) -> dict[str, dict[str, np.ndarray]]:
    """Per point label: the bin occupancy and the per-bin mean excess and energy."""
    out = {}
    for path in sorted(points.glob("*.json")):
        episodes = json.loads(path.read_text())["episodes"]
        rate = np.concatenate([e["trace"]["shear_rate"] for e in episodes])
        eta = np.concatenate([e["trace"]["eta_r"] for e in episodes])
        energy = np.concatenate([e["trace"]["field_energy"] for e in episodes])
        which = np.clip(np.digitize(rate, bins) - 1, 0, bins.size - 2)
        counts = np.bincount(which, minlength=bins.size - 1)
        excess = np.maximum(0.0, eta - cap)

        def mean(x: np.ndarray, which: np.ndarray = which, counts: np.ndarray = counts) -> np.ndarray:
            sums = np.bincount(which, weights=x, minlength=bins.size - 1)
            return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

        out[path.stem] = {"share": counts / counts.sum(), "excess": mean(excess), "energy": mean(energy)}
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("points", type=Path, help="an agents.open_loop points folder")
    parser.add_argument(
        "--cap", type=float, default=7.7, help="eta_cap of the env (default 7.7, the -v1/-v2 one)"
    )
    parser.add_argument("--energy-weight", type=float, default=0.3, help="w_E (default 0.3)")
    parser.add_argument("--rate-bins", default="0.2,0.35,0.5,0.75,1,1.5,2,3,4,5")
    parser.add_argument("--reference", default="Mn0.5", help="the constant field to compare with")
    args = parser.parse_args(argv)
    bins = np.array([float(b) for b in args.rate_bins.split(",")])
    if bins.size < 2 or np.any(np.diff(bins) <= 0):
        parser.error(f"--rate-bins must be at least two increasing edges, got {args.rate_bins!r}")
    bins[-1] = np.nextafter(bins[-1], math.inf)  # the top edge is inside the last bin
    fields = load(args.points, bins, args.cap)
    if args.reference not in fields:
        parser.error(f"--reference {args.reference} is not a point of {args.points} ({', '.join(fields)})")
    share = fields[args.reference]["share"]
    labels = list(fields)
    w = args.energy_weight
    reward = {k: -(v["excess"] + w * v["energy"]) for k, v in fields.items()}

    heads = " | ".join(f"{lo:g}-{hi:.3g}" for lo, hi in zip(bins[:-1], bins[1:], strict=True))
    print(f"Mean reward per interval by shear-rate bin (cap {args.cap:g}, w_E {w:g}):\n")
    print(f"| field | {heads} | return |")
    print("|---|" + "---|" * (bins.size - 1) + "---|")
    print("| time share | " + " | ".join(f"{s:.3f}" for s in share) + " | |")
    for k in labels:
        total = EPISODE_INTERVALS * float(np.nansum(share * reward[k]))
        print(f"| {k} | " + " | ".join(f"{r:.2f}" for r in reward[k]) + f" | {total:.1f} |")
    best = [
        max(labels, key=lambda k, b=b: -math.inf if math.isnan(reward[k][b]) else reward[k][b])
        for b in range(share.size)
    ]
    print("| best | " + " | ".join(best) + " | |")

    def score(pick: list[str]) -> tuple[float, float, float]:
        excess = sum(share[b] * fields[k]["excess"][b] for b, k in enumerate(pick))
        energy = sum(share[b] * fields[k]["energy"][b] for b, k in enumerate(pick))
        return float(excess), float(energy), -EPISODE_INTERVALS * float(excess + w * energy)

    ex, en, ret = score(best)
    ref = fields[args.reference]
    ref_ex, ref_en = float(np.nansum(share * ref["excess"])), float(np.nansum(share * ref["energy"]))
    reference = (
        f"return {-EPISODE_INTERVALS * (ref_ex + w * ref_en):.1f}, excess {ref_ex:.3f}, energy {ref_en:.2f}"
    )
    print(
        f"\nOracle (best field per bin): return {ret:.1f}, excess {ex:.3f}, energy {en:.2f}; the reference "
        f"{args.reference}: {reference}.\n"
    )

    front = []
    print("| lambda | excess | energy | fields by bin |")
    print("|---|---|---|---|")
    for lam in LAMBDAS:
        pick = [
            min(
                labels,
                key=lambda k, b=b: (
                    math.inf
                    if math.isnan(fields[k]["excess"][b])
                    else fields[k]["excess"][b] + lam * fields[k]["energy"][b]
                ),
            )
            for b in range(share.size)
        ]
        ex, en, _ = score(pick)
        front.append((ex, en))
        print(f"| {lam:g} | {ex:.3f} | {en:.2f} | {', '.join(pick)} |")
    points = sorted(set(front))
    # least energy at the reference's excess, on the front joined linearly
    reach = [en for ex, en in points if ex <= ref_ex]
    candidates = list(reach)
    for (x0, y0), (x1, y1) in zip(points, points[1:], strict=False):
        if x0 <= ref_ex <= x1 and x1 > x0:
            candidates.append(y0 + (y1 - y0) * (ref_ex - x0) / (x1 - x0))
    if candidates:
        least = min(candidates)
        print(
            f"\nLeast oracle energy at the reference's excess {ref_ex:.3f}: {least:.2f}, a saving of "
            f"{100 * (1 - least / ref_en):.0f}% against {args.reference}'s {ref_en:.2f}."
        )
    else:
        print(f"\nThe oracle front never reaches the reference's excess {ref_ex:.3f}.")


if __name__ == "__main__":
    main()
