"""The thickening-control study's summary table, from ``agents.evaluate`` folders.

    python scripts/thickening_summary.py EVAL_DIR [EVAL_DIR ...] > table.md

Reads each folder's ``results.json`` and prints one Markdown row per controller or policy (a row met in
an earlier folder, e.g. the baselines of a second evaluation, is printed once): the time above the cap,
the excess eta_r over the cap and the field energy (whole-episode means over the test states), the return
as its interquartile mean with the 95% stratified-bootstrap interval (rliable, as ``agents.evaluate``
computes it), and against the best constant field, paired per state: the return gap [95%], the states
where the row is higher, the probability of improvement [95%], the field energy saved [95%] and the
verdict on the study's energy target (at least 30% less energy at equal or lower excess). The numbers
are ``agents.evaluate``'s; this only selects and formats them, so the README's table has a command.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from agents.evaluate import format_interval
from agents.open_loop import read_json

COLUMNS = (
    "row",
    "time above cap",
    "excess eta_r",
    "energy",
    "return, IQM [95% CI]",
    "return - best constant, paired [95% CI]",
    "states above",
    "P(improvement) [95% CI]",
    "energy saved [95% CI]",
    "energy target",
)


def _interval(value: float, low: float, high: float, spec: str) -> str:
    """:func:`agents.evaluate.format_interval` (the value alone where there is no interval), and nothing
    where the value itself is missing."""
    return "" if math.isnan(value) else format_interval(value, low, high, spec)


def _percent(value: float, low: float, high: float) -> str:
    """A fraction and its interval in per cent (``12 [-5, 28]%``); nothing where the fraction is missing
    (a verdict that could not be paired)."""
    cell = _interval(100 * value, 100 * low, 100 * high, ".0f")
    return cell + "%" if cell else ""


def summary_row(row: dict[str, Any], verdict: dict[str, Any] | None) -> list[str]:
    """The table's cells for one ``results.json`` row and its verdict (None: a baseline row)."""
    ret = row["return"]
    cells = [
        row["name"],
        f"{row['time_above_cap']['mean']:.0%}",
        f"{row['excess_viscosity']['mean']:.2f}",
        f"{row['energy_mean']['mean']:.2f}",
        _interval(ret["iqm"], ret["iqm_ci_low"], ret["iqm_ci_high"], ".1f"),
    ]
    if verdict is None:
        return cells + [""] * (len(COLUMNS) - len(cells))
    return cells + [
        _interval(verdict["state_gap"], verdict["state_gap_low"], verdict["state_gap_high"], "+.1f"),
        f"{verdict['states_above']}/{verdict['states']}",
        _interval(verdict["improvement"], verdict["improvement_low"], verdict["improvement_high"], ".2f"),
        _percent(*(verdict[f"energy_saved{end}"] for end in ("", "_low", "_high"))),
        str(verdict["target_verdict"]),
    ]


def summary_table(results: list[dict[str, Any]]) -> str:
    """The Markdown table of several ``results.json`` contents, each row name once."""
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    seen: set[str] = set()
    for result in results:
        verdicts = {v["name"]: v for v in result.get("verdicts", [])}
        for row in result["rows"]:
            if row["name"] in seen:
                continue
            seen.add(row["name"])
            lines.append("| " + " | ".join(summary_row(row, verdicts.get(row["name"]))) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument(
        "folders", nargs="+", type=Path, metavar="EVAL_DIR", help="agents.evaluate --out folders"
    )
    args = parser.parse_args(argv)
    results = []
    for folder in args.folders:
        path = folder / "results.json"
        if not path.is_file():
            parser.error(f"EVAL_DIR: {folder} holds no results.json (an agents.evaluate --out folder)")
        results.append(read_json(path))  # "nan", "inf" back to floats
    splits = {(r["split"], tuple(r["indices"])) for r in results}
    if len(splits) > 1:
        parser.error(f"EVAL_DIR: the folders were played on different states: {sorted(splits)}")
    sys.stdout.write(summary_table(results))


if __name__ == "__main__":
    main()
