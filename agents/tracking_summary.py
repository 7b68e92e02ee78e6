"""The summary of ``python -m agents.tracking``: per row, its metrics over the episodes, and its gaps to the
best constant field and the map feed-forward, paired per episode (issue 44).

A row is a tuned controller (one record: deterministic given the episode) or a trained policy (one record
per training seed). An episode is a ``(start state index, realisation)`` pair of :mod:`agents.repeats`;
its metrics are those of :func:`agents.tracking_controllers.play_episode`: ``mean_abs_error`` (the mean
over intervals of ``|eta_r - target|``, the headline metric), ``return`` and ``mean_energy``
(``<eps E0^2>``).

* **A row's metric** (``table.md``'s first table): each state's realisations averaged first
  (:func:`agents.repeats.per_state`), then the mean with its 95% stratified-bootstrap interval
  (:func:`agents.statistics.interval_estimates`) over the start states (a controller, or a policy of one
  seed) or over training seeds and states (a policy of several seeds), as ``agents.evaluate`` does.
* **The paired gap** of a row to a reference row (the best constant, the map feed-forward): per episode
  ``(index, realisation)`` held by both (a policy's seeds averaged), the row's metric minus the
  reference's; the gaps averaged per state, then their mean over the states with its 95% bootstrap
  interval over them (realisations of one state share its schedule and target: they are not independent
  samples). The mean equals the mean over the paired episodes when every state has the same realisations.
* **The error reduction** ``1 - sum_s e_s / sum_s e_ref,s`` (the relative reduction of the mean
  ``|eta_r - target|``, per-state errors ``e`` on the paired episodes) with a 95% paired percentile
  bootstrap interval over the states (the ratio bootstrap of :func:`agents.comparison.energy_target`),
  against the issue's acceptance: at least :data:`ERROR_TARGETS` below the reference (30% below the best
  constant, 15% below the feed-forward). "met" if the interval lies at or above the target, "not met" if
  it lies below, "not resolved" if it spans it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.comparison import energy_target
from agents.evaluate import format_interval
from agents.folders import save_figure, write_text_atomic
from agents.open_loop import read_json, write_json
from agents.repeats import episode_key, missing, per_state, select
from agents.statistics import interval_estimates

METRICS = (
    ("mean_abs_error", "mean abs(eta_r - target)", ".3f"),
    ("return", "return", ".2f"),
    ("mean_energy", "field energy <eps E0^2>", ".3f"),
)
"""The per-episode metrics of a row: key, table heading, format."""

REFERENCES = (("constant", "best constant"), ("map_feedforward", "map feed-forward"))
"""The rows every other row is paired with: controller kind, and its name in the tables."""

ERROR_TARGETS = {"constant": 0.30, "map_feedforward": 0.15}
"""Issue 44's acceptance: a policy's mean ``|eta_r - target|`` at least 30% below the best constant's and
15% below the map feed-forward's."""


def episode_values(records: Sequence[dict[str, Any]], metric: str) -> dict[tuple[int, int], float]:
    """Per episode ``(index, realisation)`` held by every record, ``metric`` averaged over the records
    (a policy's training seeds; a controller has one)."""
    by_record = [{episode_key(e): float(e[metric]) for e in r["episodes"]} for r in records]
    keys = set.intersection(*(set(values) for values in by_record)) if by_record else set()
    return {k: float(np.mean([values[k] for values in by_record])) for k in sorted(keys)}


def state_means(values: dict[tuple[int, int], float]) -> np.ndarray:
    """Per start state (sorted), the mean of ``values`` over its realisations
    (:func:`agents.repeats.per_state`)."""
    episodes = [{"index": i, "realisation": k, "value": v} for (i, k), v in values.items()]
    return per_state(episodes, "value")[1]


def metric_interval(records: Sequence[dict[str, Any]], metric: str) -> dict[str, float]:
    """Mean of ``metric`` with its 95% bootstrap interval (module docstring): over the states for one
    record, over seeds and states for several (per-seed averages where an episode failed)."""
    if len(records) == 1:
        return interval_estimates(per_state(records[0]["episodes"], metric)[1].tolist())
    matrix = np.array([per_state(r["episodes"], metric)[1] for r in records])
    if matrix.size and np.all(np.isfinite(matrix)):
        return interval_estimates(matrix)
    return interval_estimates(
        [float(np.nanmean(row)) if np.isfinite(row).any() else math.nan for row in matrix]
    )


def paired_gap(
    records: Sequence[dict[str, Any]], reference: Sequence[dict[str, Any]], target: float
) -> dict[str, Any]:
    """A row's gaps to a reference row, paired per episode, and its error reduction against ``target``
    (module docstring). NaN and "not paired" where they share no finite episode."""
    out: dict[str, Any] = {}
    for metric in ("mean_abs_error", "return"):
        mine, theirs = episode_values(records, metric), episode_values(reference, metric)
        keys = [k for k in mine if k in theirs and math.isfinite(mine[k]) and math.isfinite(theirs[k])]
        gaps = state_means({k: mine[k] - theirs[k] for k in keys})
        stats = interval_estimates(gaps.tolist())
        better = int(np.sum(gaps < 0)) if metric == "mean_abs_error" else int(np.sum(gaps > 0))
        out[metric] = {
            "gap": stats["mean"],
            "ci_low": stats["ci_low"],
            "ci_high": stats["ci_high"],
            "episodes": len(keys),
            "states": int(gaps.size),
            "states_better": better,
        }
        if metric == "mean_abs_error":
            errors = state_means({k: mine[k] for k in keys})
            reference_errors = state_means({k: theirs[k] for k in keys})
    zeros = [0.0] * errors.size
    ratio = energy_target(list(errors), zeros, list(reference_errors), zeros, target=target)
    reduction, low, high = ratio["energy_saved"], ratio["energy_saved_low"], ratio["energy_saved_high"]
    percent = f"{100 * target:.0f}%"
    if ratio["target_states"] == 0:
        verdict = "not paired"
    elif math.isnan(low):
        verdict = f"{100 * reduction:.0f}% lower; one state, no interval"
    elif low >= target:
        verdict = f"met (at least {percent} lower)"
    elif high < target:
        verdict = f"not met (less than {percent} lower)"
    else:
        verdict = f"not resolved (the interval spans {percent})"
    out["error_reduction"] = {"reduction": reduction, "ci_low": low, "ci_high": high, "target": target}
    out["verdict"] = verdict
    return out


def summarise_rows(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per row (``name``, ``label``, ``kind``: the controller kind or ``"policy"``, ``records``): its
    samples, failures, metric intervals and its paired gaps to the reference rows present."""
    references = {kind: next((r for r in rows if r["kind"] == kind), None) for kind, _ in REFERENCES}
    out = []
    for row in rows:
        records = row["records"]
        states = len({e["index"] for e in records[0]["episodes"]})
        episodes = len(records[0]["episodes"])
        samples = f"{states} start states"
        if episodes > states:
            samples += f" x {episodes // states} realisations"
        if row["kind"] == "policy":
            samples = f"{len(records)} training seed{'s' if len(records) > 1 else ''} x {samples}"
        summary = {
            "name": row["name"],
            "label": row["label"],
            "samples": samples,
            "failures": sum(bool(e["failed"]) for r in records for e in r["episodes"]),
            **{metric: metric_interval(records, metric) for metric, _, _ in METRICS},
            "paired": {},
        }
        for kind, _ in REFERENCES:
            reference = references[kind]
            if reference is not None and reference is not row:
                summary["paired"][kind] = paired_gap(records, reference["records"], ERROR_TARGETS[kind])
        out.append(summary)
    return out


def format_tables(summaries: Sequence[dict[str, Any]]) -> str:
    """``table.md``'s tables: the rows' metrics, then each row against each reference present."""
    heads = " | ".join(f"{title} [95% CI]" for _, title, _ in METRICS)
    lines = [f"| row | samples | {heads} | failed episodes |", "|---|---|---|---|---|---|"]
    for s in summaries:
        cells = " | ".join(
            format_interval(s[m]["mean"], s[m]["ci_low"], s[m]["ci_high"], spec) for m, _, spec in METRICS
        )
        lines.append(f"| {s['name']} | {s['samples']} | {cells} | {s['failures']} |")
    for kind, title in REFERENCES:
        paired = [s for s in summaries if kind in s["paired"]]
        if not paired:
            continue
        percent = f"{100 * ERROR_TARGETS[kind]:.0f}%"
        lines += [
            "",
            f"Against the {title}, paired per episode (start state, realisation), the gaps averaged per "
            "state; 95% bootstrap intervals over the states:",
            "",
            f"| row | mean abs error - {title} [95% CI] | states with less error | error reduction [95% CI] "
            f"| at least {percent} lower? | return - {title} [95% CI] | states with a higher return | "
            "paired episodes |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for s in paired:
            p = s["paired"][kind]
            error, ret, cut = p["mean_abs_error"], p["return"], p["error_reduction"]
            gap = format_interval(error["gap"], error["ci_low"], error["ci_high"], "+.3f")
            reduction = format_interval(
                100 * cut["reduction"], 100 * cut["ci_low"], 100 * cut["ci_high"], ".0f"
            )
            ret_gap = format_interval(ret["gap"], ret["ci_low"], ret["ci_high"], "+.2f")
            lines.append(
                f"| {s['name']} | {gap} | {error['states_better']}/{error['states']} | {reduction} % | "
                f"{p['verdict']} | {ret_gap} | {ret['states_better']}/{ret['states']} | {error['episodes']} |"
            )
    return "\n".join(lines)


def plot_traces(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """``traces.png``: eta_r of each row (its first record: a policy's first seed) and the target against
    time, on the first episode (lowest start state, realisation 0) that every row holds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    common = set.intersection(*({episode_key(e) for e in r["records"][0]["episodes"]} for r in rows))
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    if common:
        first = min(common)
        target_drawn = False
        for row in rows:
            episode = next(e for e in row["records"][0]["episodes"] if episode_key(e) == first)
            edges = [0.0, *episode["time"]]  # each value is an interval's average
            if not target_drawn:
                ax.stairs(episode["target_eta_r"], edges, baseline=None, color="k", lw=2.2, label="target")
                target_drawn = True
            ax.stairs(episode["eta_r"], edges, baseline=None, lw=1.2, label=row["name"])
        ax.set_title(f"start state {first[0]}, realisation {first[1]} (interval averages)", fontsize=9)
    ax.set_xlabel("time since the episode start (1/gammadot_ref)")
    ax.set_ylabel("eta_r")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    save_figure(fig, path, dpi=120, bbox_inches="tight")
    plt.close(fig)


ROW_ORDER = ("controller_constant", "controller_map_feedforward", "controller_angle_pi")
"""The tuned controllers' rows first, in this order; then the trained runs' by label."""


def folder_rows(
    out: Path, identity: dict[str, Any], realisations: int
) -> tuple[list[dict[str, Any]], list[str]]:
    """The rows of an ``agents.tracking`` folder (its manifest's ``identity``: ``controller_<kind>`` with
    ``points/<kind>.json``, ``run_<label>`` with a ``points/<seed label>.json`` per seed) on the first
    ``identity["episodes"]`` states, ``realisations`` each; and the row keys left out because a file lacks
    some of those episodes (a row of an earlier command with fewer realisations, or interrupted)."""
    indices = range(identity["episodes"])
    keys = [k for k in ROW_ORDER if k in identity] + sorted(k for k in identity if k.startswith("run_"))
    rows, skipped = [], []
    for row_key in keys:
        kind = row_key.removeprefix("controller_") if row_key.startswith("controller_") else "policy"
        labels = [kind] if kind != "policy" else list(identity[row_key]["runs"])
        files = [out / "points" / f"{label}.json" for label in labels]
        records = [read_json(f) for f in files if f.exists()]
        if len(records) < len(files) or any(missing(r["episodes"], indices, realisations) for r in records):
            skipped.append(row_key)
            continue
        records = [{**r, "episodes": select(r["episodes"], indices, realisations)} for r in records]
        if kind == "policy":
            label = row_key.removeprefix("run_")
            algo, played = identity[row_key]["algo"], identity[row_key]["env_id"]
            name = f"{algo} ({label.removeprefix(algo + '_')})"
            if played != identity["env_id"]:
                name += f" on {played.removeprefix('dipenv/')}"
        else:
            label, name = kind, records[0]["name"]
        rows.append({"label": label, "name": name, "kind": kind, "records": records})
    return rows, skipped


def write_summary(out: Path, identity: dict[str, Any], realisations: int) -> dict[str, Any]:
    """``table.md``, ``results.json`` and ``traces.png`` of an ``agents.tracking`` folder over every row it
    holds with the requested episodes (:func:`folder_rows`); the tables printed, the summaries returned."""
    rows, skipped = folder_rows(out, identity, realisations)
    summaries = summarise_rows(rows)
    n = identity["episodes"]
    episodes = f"the first {n} start states of the {identity['split']} split"
    if "schedules" in identity:
        episodes = (
            f"{n} entries of a schedules file (digest {identity['schedules']}, {out / 'schedules.json'}; "
            f"start states of the {identity['split']} split, each with its start state's target)"
        )
    realised = f" x {realisations} realisations each" if realisations > 1 else ""
    header = (
        f"{identity['env_id']} with env arguments {json.dumps(identity['env_kwargs'])}, "
        f"{episodes}{realised}. "
        f"Controllers tuned on the first {identity['tune_episodes']} states of the {identity['tune_split']} "
        "split (the highest mean return; tuning.csv), policies played with their mean action. mean "
        "abs(eta_r - target): an episode's mean over its intervals of |eta_r - target| (interval averages); "
        "return: the sum of its rewards; field energy: its mean <eps E0^2> = <1/Mn_ref>. Each state's "
        "realisations averaged first; 95% stratified-bootstrap intervals over start states (over training "
        "seeds and states for a policy of several seeds); agents.tracking_summary.\n\n"
    )
    note = ""
    if skipped:
        shown = ", ".join(skipped)
        note = f"\n\nLeft out (their files lack these episodes; rerun with their arguments): {shown}"
    tables = format_tables(summaries)
    write_text_atomic(out / "table.md", header + tables + note + "\n")
    result = {"identity": identity, "realisations": realisations, "rows": summaries, "skipped": skipped}
    write_json(out / "results.json", result)
    if rows:
        plot_traces(rows, out / "traces.png")
    print(tables + note)
    return result


__all__ = [
    "ERROR_TARGETS",
    "METRICS",
    "REFERENCES",
    "episode_values",
    "folder_rows",
    "format_tables",
    "metric_interval",
    "paired_gap",
    "plot_traces",
    "state_means",
    "summarise_rows",
    "write_summary",
]
