"""How a played controller or policy uses the field by shear rate: the share of intervals at the strongest
field, and how often consecutive intervals switch between the strongest field and a weak one or none.

    python scripts/field_pulsing.py RUN_JSON [RUN_JSON ...] [--strongest 0.1] [--weak 5] [--high-rate 2]
        [--low-rate 1]

``RUN_JSON`` is a per-run file of an ``agents.evaluate`` folder (``DIR/runs/<policy>_seed<k>.json``): its
episodes' interval traces (``mason_number`` = ``Mn_ref`` per interval, ``"inf"`` for no field, and the
interval-mean ``shear_rate``). An interval is *strongest* if ``Mn_ref <= strongest * (1 + 1e-6)`` (the
action ``u = 1`` of ``ThickeningControl-v2`` is ``Mn_ref = 0.1``) and *weak* if ``Mn_ref >= weak`` or the
field is off. Printed per file (Markdown on stdout), each a mean over its episodes of the per-episode
fractions: strongest among the intervals above ``--high-rate`` and below ``--low-rate``, and the fraction
of consecutive pairs whose second interval is above ``--high-rate`` that switch between strongest and weak
(either way). A constant field gives 0 switches; a field that alternates every interval gives 1.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np


def episode_fractions(
    trace: dict, strongest: float, weak: float, high_rate: float, low_rate: float
) -> tuple[float, float, float]:
    """(strongest share above ``high_rate``, strongest share below ``low_rate``, switch share above
    ``high_rate``) of one episode's trace; NaN where no interval qualifies."""
    mason = np.array([math.inf if m == "inf" else float(m) for m in trace["mason_number"]])
    rate = np.asarray(trace["shear_rate"], dtype=float)
    is_strong = mason <= strongest * (1.0 + 1e-6)
    is_weak = mason >= weak
    high, low = rate > high_rate, rate < low_rate
    switch = (is_strong[:-1] & is_weak[1:]) | (is_weak[:-1] & is_strong[1:])

    def share(flags: np.ndarray, where: np.ndarray) -> float:
        return float(flags[where].mean()) if where.any() else math.nan

    return share(is_strong, high), share(is_strong, low), share(switch, high[1:])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--strongest", type=float, default=0.1, help="Mn_ref of the strongest field")
    parser.add_argument("--weak", type=float, default=5.0, help="Mn_ref at or above which a field is weak")
    parser.add_argument("--high-rate", type=float, default=2.0)
    parser.add_argument("--low-rate", type=float, default=1.0)
    args = parser.parse_args(argv)
    for name in ("strongest", "weak", "high_rate", "low_rate"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be a finite number > 0, got {value}")
    print(
        f"| run | episodes | strongest field, rate > {args.high_rate:g} | strongest field, rate < "
        f"{args.low_rate:g} | strongest <-> weak switches per interval, rate > {args.high_rate:g} |"
    )
    print("|---|---|---|---|---|")
    for path in args.runs:
        episodes = json.loads(path.read_text())["episodes"]
        rows = np.array(
            [
                episode_fractions(e["trace"], args.strongest, args.weak, args.high_rate, args.low_rate)
                for e in episodes
            ]
        )
        means = [float(np.nanmean(column)) if np.isfinite(column).any() else math.nan for column in rows.T]
        print(f"| {path.name} | {len(episodes)} | {means[0]:.2f} | {means[1]:.2f} | {means[2]:.2f} |")


if __name__ == "__main__":
    main()
