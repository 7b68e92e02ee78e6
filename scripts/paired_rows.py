"""Two rows of an evaluation compared on the same start states: return, excess viscosity and field energy of
row A minus row B, paired per state.

    python scripts/paired_rows.py --a RUN_JSON [RUN_JSON ...] --b RUN_JSON [RUN_JSON ...] [--split test]
        [--names A,B]

Each ``RUN_JSON`` is a per-run file of an ``agents.evaluate`` folder (``DIR/runs/<policy>_seed<k>.json``) or
a controller's or constant field's point (``DIR/points/<label>.json``). A row's episodes on one start state
(its seeds' and realisations' episodes, those of ``--split``) are averaged first; the two rows must cover
the same states. Printed (Markdown): per row the mean over states of the whole-episode return, the excess
``eta_r`` over the cap and the field energy ``<eps E0^2>`` (``eta gammadot_ref``); then A - B, paired per
state, with the 95% bootstrap intervals over the states of :func:`agents.statistics.interval_estimates`
(the intervals of ``agents.evaluate``'s gaps paired per state), the energy saving of A against B,
``1 - sum E_A / sum E_B``, from :func:`agents.comparison.energy_target`, and the number of states where A
is higher.

Every value must be finite, and the excess viscosity and the field energy >= 0 (an energy saving of a
negative energy, or a gap to an infinite one, is no number to print): a file that breaks this exits 2 naming
it, the state and the quantity.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from agents.comparison import energy_target
from agents.statistics import interval_estimates

QUANTITIES = ("return", "excess_viscosity", "energy_mean")
NON_NEGATIVE = ("excess_viscosity", "energy_mean")


class BadValue(ValueError):
    """An episode value that no comparison can use (non-finite, or a negative energy or excess)."""


def checked(path: Path, index: int, quantity: str, raw: object) -> float:
    """``raw`` as a float, or :class:`BadValue` naming the file, the state and the quantity."""
    value = float(raw)  # type: ignore[arg-type]
    if not math.isfinite(value) or (quantity in NON_NEGATIVE and value < 0.0):
        need = "finite and >= 0" if quantity in NON_NEGATIVE else "finite"
        raise BadValue(f"{path}: state {index}: {quantity} must be {need}, got {raw!r}")
    return value


def per_state(files: list[Path], split: str) -> dict[int, dict[str, float]]:
    """Mean of each quantity over a row's episodes on each start state (index), failed episodes left out;
    :class:`BadValue` for a value no comparison can use (:func:`checked`)."""
    pooled: dict[int, dict[str, list[float]]] = {}
    for path in files:
        for episode in json.loads(path.read_text())["episodes"]:
            if episode.get("split", split) != split or episode.get("failed"):
                continue
            index = int(episode["index"])
            slot = pooled.setdefault(index, {q: [] for q in QUANTITIES})
            for q in QUANTITIES:
                slot[q].append(checked(path, index, q, episode[q]))
    return {index: {q: float(np.mean(v)) for q, v in values.items()} for index, values in pooled.items()}


def compare(a: dict[int, dict[str, float]], b: dict[int, dict[str, float]]) -> dict[str, dict[str, float]]:
    """A - B per quantity, paired over the states both rows hold (raises if they hold different states)."""
    if set(a) != set(b):
        raise ValueError(f"the rows cover different states: A {sorted(a)}, B {sorted(b)}")
    states = sorted(a)
    out: dict[str, dict[str, float]] = {}
    for q in QUANTITIES:
        gaps = np.array([a[s][q] - b[s][q] for s in states])
        stats = interval_estimates(gaps)
        out[q] = {
            "a": float(np.mean([a[s][q] for s in states])),
            "b": float(np.mean([b[s][q] for s in states])),
            "gap": stats["mean"],
            "low": stats["ci_low"],
            "high": stats["ci_high"],
            "states_higher": int((gaps > 0).sum()),
        }
    target = energy_target(
        [a[s]["energy_mean"] for s in states],
        [a[s]["excess_viscosity"] for s in states],
        [b[s]["energy_mean"] for s in states],
        [b[s]["excess_viscosity"] for s in states],
    )
    out["energy_saved"] = {k: target[k] for k in ("energy_saved", "energy_saved_low", "energy_saved_high")}
    out["states"] = {"count": len(states)}
    return out


def table(result: dict[str, dict[str, float]], names: tuple[str, str]) -> str:
    """The comparison as a Markdown table."""
    a, b = names
    n = result["states"]["count"]
    lines = [
        f"| quantity | {a} | {b} | {a} - {b}, paired per state [95% CI] | states where {a} is higher |",
        "|---|---|---|---|---|",
    ]
    for q in QUANTITIES:
        r = result[q]
        lines.append(
            f"| {q} | {r['a']:.3f} | {r['b']:.3f} | {r['gap']:+.3f} [{r['low']:+.3f}, {r['high']:+.3f}] "
            f"| {r['states_higher']}/{n} |"
        )
    s = result["energy_saved"]
    if math.isfinite(s["energy_saved"]):
        lines.append(
            f"\nField energy saved by {a} against {b}: {100 * s['energy_saved']:.0f}% "
            f"[{100 * s['energy_saved_low']:.0f}, {100 * s['energy_saved_high']:.0f}] ({n} states)."
        )
    else:  # B spends no field energy (a saving against nothing is undefined), or a value is not finite
        lines.append(
            f"\nField energy saved by {a} against {b}: n/a ({b} spends no field energy, or an energy is not "
            f"finite) ({n} states)."
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("--a", type=Path, nargs="+", required=True, help="row A's run or point files")
    parser.add_argument("--b", type=Path, nargs="+", required=True, help="row B's run or point files")
    parser.add_argument("--split", default="test", help="episodes of this split only (default test)")
    parser.add_argument("--names", default="A,B", help="the two rows' names in the table (default A,B)")
    args = parser.parse_args(argv)
    names = tuple(args.names.split(","))
    if len(names) != 2:
        parser.error(f"--names takes two comma-separated names, got {args.names!r}")
    rows = []
    for option, files in (("--a", args.a), ("--b", args.b)):
        try:
            rows.append(per_state(files, args.split))
        except BadValue as error:
            parser.error(f"{option}: {error}")
        except (OSError, ValueError, KeyError, TypeError) as error:  # missing, unreadable or not a run file
            parser.error(f"{option}: cannot read the episodes of {[str(f) for f in files]}: {error!r}")
        if not rows[-1]:
            parser.error(f"{option}: no episodes of split {args.split!r} in {[str(f) for f in files]}")
    try:
        result = compare(rows[0], rows[1])
    except ValueError as error:
        parser.error(str(error))
    print(table(result, (names[0], names[1])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
