"""Bias of a simulator setting against the noise of one episode, from two open-loop points (issue 22).

    python scripts/bound_bias.py REFERENCE_POINT_JSON OTHER_POINT_JSON [--label "0.8% bound"]

Both files are ``agents.open_loop`` points of the same constant field on the same start states and
realisations, played with two simulator settings (e.g. the displacement bound 0.4% and 0.8%:
``--env-kwargs '{"simulation_overrides": {"max_displacement": 0.008}}'``). Each pair of episodes
starts from the same state, so the per-state difference (the realisations of a state averaged first)
drops what the states share. Printed per quantity (second-half means of the interval eta_r, N1 and N2,
the whole-episode excess eta_r over the cap and field energy, and the return): both means, the mean
paired difference with its standard error over the states and a 95% interval (normal approximation, the
standard error times 1.96), and the noise of one episode in the reference (the pooled within-state
standard deviation between realisations). The setting passes issue 22's test for a quantity where
``|difference| < noise / 3`` and the standard error is below ``noise / 3``: its bias is then much
smaller than the statistical error of the episodes it changes.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

QUANTITIES = (
    ("eta_r, 2nd half", lambda e: e["eta_second_half"]),
    ("N1, 2nd half", lambda e: _second_half(e["trace"]["n1"])),
    ("N2, 2nd half", lambda e: _second_half(e["trace"]["n2"])),
    ("excess eta_r over the cap", lambda e: e["excess_viscosity"]),
    ("field energy", lambda e: e["energy_mean"]),
    ("return", lambda e: e["return"]),
)


def _second_half(values: list[float]) -> float:
    x = np.asarray(values, dtype=float)
    return float(x[x.size // 2 :].mean())


def by_state(path: Path) -> dict[tuple[int, int], dict]:
    """The episodes of a point file keyed by (state, realisation)."""
    episodes = json.loads(path.read_text())["episodes"]
    return {(int(e["index"]), int(e.get("realisation", 0))): e for e in episodes}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("reference", type=Path)
    parser.add_argument("other", type=Path)
    parser.add_argument("--label", default="other", help="name of the other setting in the table")
    args = parser.parse_args(argv)
    reference, other = by_state(args.reference), by_state(args.other)
    keys = sorted(set(reference) & set(other))
    if not keys:
        parser.error("the two points share no (state, realisation)")
    states = sorted({s for s, _ in keys})
    realisations = len(keys) // len(states)
    print(
        f"{args.label} against the reference: {len(states)} states x {realisations} realisations, paired "
        "per state (realisations averaged first)\n"
    )
    print(
        "| quantity | reference | other | difference ± se | 95% interval | noise of one episode | "
        "|difference| < noise/3 and se < noise/3 |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, read in QUANTITIES:
        ref = defaultdict(list)
        new = defaultdict(list)
        for s, r in keys:
            ref[s].append(read(reference[(s, r)]))
            new[s].append(read(other[(s, r)]))
        ref_means = np.array([np.mean(ref[s]) for s in states])
        new_means = np.array([np.mean(new[s]) for s in states])
        diff = new_means - ref_means
        se = float(diff.std(ddof=1) / math.sqrt(diff.size)) if diff.size > 1 else math.nan
        pooled = [np.var(ref[s], ddof=1) * (len(ref[s]) - 1) for s in states if len(ref[s]) > 1]
        dof = sum(len(ref[s]) - 1 for s in states if len(ref[s]) > 1)
        noise = math.sqrt(sum(pooled) / dof) if dof else math.nan
        mean = float(diff.mean())
        passes = abs(mean) < noise / 3 and se < noise / 3
        if noise < 1e-9 * max(1.0, abs(float(ref_means.mean()))):
            # a quantity without noise (the energy of a constant field): equal up to the rounding of the
            # interval clock, or not
            passes = abs(mean) <= 1e-9 * max(1.0, abs(float(ref_means.mean())))
        print(
            f"| {name} | {ref_means.mean():.3f} | {new_means.mean():.3f} | {mean:+.3f} ± {se:.3f} | "
            f"[{mean - 1.96 * se:+.3f}, {mean + 1.96 * se:+.3f}] | {noise:.3f} | {'yes' if passes else 'no'} "
            "|"
        )


if __name__ == "__main__":
    main()
