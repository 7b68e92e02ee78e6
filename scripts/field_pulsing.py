"""How a played controller or policy uses the field by shear rate: the share of intervals at the strongest
field, and how often consecutive intervals switch between the strongest field and a weak one or none.

    python scripts/field_pulsing.py RUN_JSON [RUN_JSON ...] [--strongest 0.1] [--weak 5] [--high-rate 2]
        [--low-rate 1] [--rate-bins 0.2,0.5,1,2,3,5] [--plot PNG [--labels A,B,...]]

``RUN_JSON`` is a per-run file of an ``agents.evaluate`` folder (``DIR/runs/<policy>_seed<k>.json``) or a
controller's or constant field's point (``DIR/points/<label>.json``): its episodes' interval traces
(``mason_number`` = ``Mn_ref`` per interval, ``"inf"`` for no field, and the interval-mean ``shear_rate``). An
interval is *strongest* if ``Mn_ref <= strongest * (1 + 1e-6)`` (the action ``u = 1`` of
``ThickeningControl-v2`` is ``Mn_ref = 0.1``) and *weak* if ``Mn_ref >= weak`` or the field is off. Printed
per file (Markdown on stdout), each a mean over its episodes of the per-episode fractions: strongest among the
intervals above ``--high-rate`` and below ``--low-rate``, and the fraction of consecutive pairs whose second
interval is above ``--high-rate`` that switch between strongest and weak (either way). A constant field gives
0 switches; a field that alternates every interval gives 1.

A second table bins every interval of a file's episodes by its mean shear rate (``--rate-bins``, edges in
``gammadot_ref``) and gives, per bin, the mean field energy ``eps E0^2 = 1/Mn_ref`` (``eta gammadot_ref``),
the mean excess ``max(0, eta_r - eta_cap)`` and the mean reward per interval: where a controller spends its
field and where it pays for thickening. Intervals outside the edges are left out. ``--plot PNG`` draws
the field energy and the excess by rate bin, one line per file, or per label: files given the same label in
``--labels`` (one per file, comma-separated) are pooled into one line, e.g. the seeds of one policy.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from agents.rollout import record_episodes


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


def rate_bin_means(traces: list[dict], edges: np.ndarray) -> np.ndarray:
    """(B, 4) per rate bin ``[edges[b], edges[b + 1])``: share of all intervals, mean field energy, mean
    excess ``max(0, eta_r - eta_cap)`` and mean reward; NaN means for a bin with no interval."""
    rate = np.concatenate([np.asarray(t["shear_rate"], dtype=float) for t in traces])
    energy = np.concatenate([np.asarray(t["field_energy"], dtype=float) for t in traces])
    excess = np.concatenate(
        [np.maximum(0.0, np.asarray(t["eta_r"], dtype=float) - np.asarray(t["eta_cap"])) for t in traces]
    )
    reward = np.concatenate([np.asarray(t["reward"], dtype=float) for t in traces])
    out = np.full((len(edges) - 1, 4), math.nan)
    for b in range(len(edges) - 1):
        inside = (rate >= edges[b]) & (rate < edges[b + 1])
        out[b, 0] = inside.mean()
        if inside.any():
            out[b, 1:] = energy[inside].mean(), excess[inside].mean(), reward[inside].mean()
    return out


def plot_rate_bins(tables: dict[str, np.ndarray], edges: np.ndarray, path: Path) -> None:
    """Field energy and excess by rate bin (tables of :func:`rate_bin_means`), one line per entry, at the
    bins' geometric centres (arithmetic where an edge is 0) on a log rate axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lo, hi = edges[:-1], edges[1:]
    centres = np.where(lo > 0, np.sqrt(lo * hi), 0.5 * (lo + hi))
    fig, (energy_ax, excess_ax) = plt.subplots(1, 2, figsize=(9.5, 3.8), sharex=True)
    for name, table in tables.items():
        energy_ax.plot(centres, table[:, 1], "o-", label=name)
        excess_ax.plot(centres, table[:, 2], "o-", label=name)
    energy_ax.set(
        xscale="log",
        xlabel="shear rate (gammadot_ref), interval mean",
        ylabel="field energy eps E0^2 = 1/Mn_ref",
        title="where the field is spent",
    )
    excess_ax.set(
        xlabel="shear rate (gammadot_ref), interval mean",
        ylabel="excess max(0, eta_r - eta_cap)",
        title="where thickening is paid",
    )
    ticks = edges[edges > 0]
    for ax in (energy_ax, excess_ax):
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
        ax.set_xticks([], minor=True)
        ax.grid(alpha=0.3)
    excess_ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--strongest", type=float, default=0.1, help="Mn_ref of the strongest field")
    parser.add_argument("--weak", type=float, default=5.0, help="Mn_ref at or above which a field is weak")
    parser.add_argument("--high-rate", type=float, default=2.0)
    parser.add_argument("--low-rate", type=float, default=1.0)
    parser.add_argument(
        "--rate-bins", default="0.2,0.5,1,2,3,5", help="comma-separated increasing edges of the rate bins"
    )
    parser.add_argument("--plot", type=Path, metavar="PNG", help="draw the rate-bin means to this file")
    parser.add_argument(
        "--labels", help="comma-separated line labels for --plot, one per RUN_JSON (equal labels pool)"
    )
    args = parser.parse_args(argv)
    labels_given = args.labels.split(",") if args.labels is not None else [p.stem for p in args.runs]
    if len(labels_given) != len(args.runs):
        parser.error(f"--labels must name each of the {len(args.runs)} RUN_JSON, got {len(labels_given)}")
    if args.labels is not None and args.plot is None:
        parser.error("--labels names the lines of --plot; give --plot PNG too")
    try:
        edges = np.array([float(x) for x in args.rate_bins.split(",")])
    except ValueError:
        parser.error(f"--rate-bins must be comma-separated numbers, got {args.rate_bins!r}")
    if len(edges) < 2 or not (np.isfinite(edges).all() and (edges >= 0).all() and (np.diff(edges) > 0).all()):
        parser.error(
            f"--rate-bins must be at least two finite, increasing edges >= 0, got {args.rate_bins!r}"
        )
    for name in ("strongest", "weak", "high_rate", "low_rate"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be a finite number > 0, got {value}")
    print(
        f"| run | episodes | strongest field, rate > {args.high_rate:g} | strongest field, rate < "
        f"{args.low_rate:g} | strongest <-> weak switches per interval, rate > {args.high_rate:g} |"
    )
    print("|---|---|---|---|---|")
    traces: list[tuple[str, list[dict]]] = []  # per file, in order (two folders may hold equal names)
    for path in args.runs:
        try:
            episodes = record_episodes(path)
        except ValueError as exc:
            parser.error(str(exc))
        traces.append((path.name, [e["trace"] for e in episodes]))
        rows = np.array(
            [
                episode_fractions(e["trace"], args.strongest, args.weak, args.high_rate, args.low_rate)
                for e in episodes
            ]
        )
        means = [float(np.nanmean(column)) if np.isfinite(column).any() else math.nan for column in rows.T]
        print(f"| {path.name} | {len(episodes)} | {means[0]:.2f} | {means[1]:.2f} | {means[2]:.2f} |")
    labels = [f"{lo:g}-{hi:g}" for lo, hi in zip(edges[:-1], edges[1:], strict=True)]
    print(
        "\nPer shear-rate bin: field energy 1/Mn_ref / excess eta_r over the cap / reward, means per interval"
    )
    print("(the first row: each bin's share of the intervals)\n")
    print("| run | " + " | ".join(labels) + " |")
    print("|---|" + "---|" * len(labels))
    for k, (name, file_traces) in enumerate(traces):
        table = rate_bin_means(file_traces, edges)
        if k == 0:
            print("| share | " + " | ".join(f"{v:.2f}" for v in table[:, 0]) + " |")
        cells = [f"{e:.2f} / {x:.2f} / {r:.2f}" for _, e, x, r in table]
        print(f"| {name} | " + " | ".join(cells) + " |")
    if args.plot is not None:
        pooled: dict[str, list[dict]] = {}
        for label, (_, file_traces) in zip(labels_given, traces, strict=True):
            pooled.setdefault(label, []).extend(file_traces)
        plot_rate_bins({k: rate_bin_means(v, edges) for k, v in pooled.items()}, edges, args.plot)


if __name__ == "__main__":
    main()
