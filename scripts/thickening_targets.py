"""Issue 43's target checklist of the thickening-control study, from one ``agents.evaluate`` folder.

    python scripts/thickening_targets.py EVAL_DIR [--pulse NAME_PREFIX] [--share 0.10] [--rows NAME ...]

Reads ``EVAL_DIR/results.json`` and prints, in Markdown, one line naming the split, the number of states and
the best constant field (its mean return), then one table row per trained policy (by default each row with
a verdict and more than one training seed; ``--rows`` names them) with issue 43's five targets, each a cell
with its numbers and a verdict, met / not met / not resolved, and an overall verdict ("all five met" or
"not met: " and the targets that are not met):

1. **Return lead** over the best constant field: the return gap paired per state (the verdict's
   ``state_gap`` [95% interval], :func:`agents.evaluate.state_gap`) as a share of the best constant's
   |mean return|. With the target ``T = share x |R_const|``: met if the gap is at least ``T`` and its
   interval lies above 0 (``gap >= T`` and ``low > 0``); not met if the interval lies below ``T`` or at or
   below 0 (``high < T`` or ``high <= 0``); else not resolved (among them a gap below ``T`` whose interval
   reaches it, and a gap at ``T`` whose interval reaches 0). NaN (not paired): not resolved.
2. **Every seed beats the constant**: per training seed, its mean return over the states minus the best
   constant's mean over the same states (``returns``, paired as :func:`agents.evaluate._paired_returns`
   pairs them); met if every seed is above, else not met; not resolved where the states cannot be paired.
3. **Energy** (issue 21's target, :func:`agents.comparison.energy_target`: at least 30% less field energy
   than the best constant at equal or lower excess eta_r over the cap): the verdict's energy saved
   [95%], excess gap [95%] and ``target_verdict``, copied ("not paired" reads not resolved).
4. **Beats the pulse controller** (the row whose name starts with ``--pulse``, default "pulse on"): the
   return gap to it paired per state, :func:`agents.evaluate.state_gap` with the pulse row in the place of
   the best constant; met if the interval lies above 0, not met if it lies below 0, else not resolved.
   "no pulse row" (not resolved) where the evaluation has none.
5. **Simulator time**: per seed, at most the simulator steps of the original runs (``n_timesteps``
   10^4, ``results/thickening_control/v2/rl/ppo``). The run folders are the ``agents.evaluate``
   RUN_DIRS of ``EVAL_DIR``'s ``manifest.json`` (``params.runs``) or, without one, of its ``command.txt``
   (the words between ``agents.evaluate`` and its first option; relative paths against the current
   folder, then the repository's root); they are grouped and named by :func:`agents.evaluate.find_runs`,
   the function that named the rows (``ppo (ppo)``: the algorithm and the group folder's name; a row's
   ", best validation" and ", sampled" suffixes are dropped to match). Each seed's ``config.yml``
   (:func:`agents.folders.read_run_config`): its ``hyperparams.n_timesteps`` count as simulator steps,
   or as surrogate steps where its ``env_id`` is a surrogate's (:data:`dipenv.SURROGATE_IDS`,
   :data:`dipenv.TRACKING_SURROGATE_IDS`); a fine-tuned run (``init_from``, :mod:`agents.init_from`:
   ``n_timesteps`` counts the fine-tuning steps only) adds its source run's steps, read the same way
   from the source's folder (a checkpoint ``ckpt_<N>_steps.zip`` counts N; where the source folder is
   gone, a surrogate source by its recorded ``env_id`` adds no simulator step and unknown surrogate
   steps). Where ``result.json`` records another number of steps trained (PPO finishes its last
   rollout: the original runs trained 10,186-10,450), it is shown beside; the verdict compares the
   configured ``n_timesteps``, as the original runs' 10^4 is. Met if every seed's simulator steps are at
   most 10^4 (which contains the issue's other way to meet it, ten times the experience for at most 10^4
   simulator steps), not met if one exceeds them; not resolved where a seed's steps are unknown, and "run
   folders not found" where the folders cannot be found.

The numbers are ``agents.evaluate``'s (the verdicts) or computed by its functions; this selects, pairs
and judges them.
"""

from __future__ import annotations

import argparse
import io
import math
import re
import sys
from contextlib import redirect_stderr
from pathlib import Path
from typing import Any

import numpy as np

import dipenv
from agents.evaluate import _paired_returns, find_runs, format_interval, state_gap
from agents.folders import read_run_config
from agents.open_loop import read_json
from sim.runs import RunFolderError, read_manifest

ROOT = Path(__file__).resolve().parents[1]
"""The repository's root: where the committed evaluations' relative run paths lie."""

ORIGINAL_STEPS = 10_000
"""The simulator steps per seed of the original runs (``results/thickening_control/v2/rl``)."""

SURROGATE_IDS = (*dipenv.SURROGATE_IDS, *dipenv.TRACKING_SURROGATE_IDS)

MET, NOT_MET, OPEN = "met", "not met", "not resolved"

TARGETS = ("return lead", "every seed", "energy", "pulse", "simulator time")
"""The five targets' short names, as the overall verdict lists them."""

COLUMNS = (
    "row",
    "1. return - best constant, paired per state [95% CI] = share of its return (target: {share:.0%})",
    "2. every seed beats the constant",
    "3. energy saved [95% CI], excess eta_r - constant [95% CI] (target: >= 30% less at equal excess)",
    "4. return - pulse controller, paired per state [95% CI]",
    "5. simulator time per seed (target: <= 10^4 steps)",
    "overall",
)

ROW_SUFFIXES = (", sampled", ", best validation")
"""What ``agents.evaluate`` appends to a group's name (``--actions``, ``--model best``)."""


class Target:
    """One target's cell: the numbers as text, the verdict (met, not met, not resolved) and the numbers."""

    def __init__(self, text: str, verdict: str, numbers: dict[str, Any] | None = None) -> None:
        self.text, self.verdict, self.numbers = text, verdict, numbers or {}

    def cell(self) -> str:
        return f"{self.text}: {self.verdict}" if self.text else self.verdict


def return_lead(verdict: dict[str, Any], best: dict[str, Any], share: float) -> Target:
    """Target 1 from the verdict's ``state_gap`` and the best constant row's mean return."""
    gap, low, high = (float(verdict[f"state_gap{end}"]) for end in ("", "_low", "_high"))
    scale = abs(float(best["return"]["mean"]))
    target = share * scale
    numbers = {"gap": gap, "low": low, "high": high, "scale": scale, "target": target}
    if math.isnan(gap):
        return Target("not paired", OPEN, numbers)
    numbers["share"] = gap / scale if scale > 0 else math.nan
    if gap >= target and low > 0:
        word = MET
    elif high < target or high <= 0:
        word = NOT_MET
    else:
        word = OPEN
    text = f"{format_interval(gap, low, high, '+.2f')} = {numbers['share']:.0%} of {scale:.2f}"
    return Target(text, word, numbers)


def seed_gaps(row: dict[str, Any], best: dict[str, Any]) -> Target:
    """Target 2: each seed's mean return over the states minus the best constant's on the same states."""
    paired = _paired_returns(row, best)
    if paired is None:
        return Target("not paired", OPEN)
    x, y = paired
    gaps = x.mean(axis=1) - y.mean(axis=0).mean()
    above = int(np.sum(gaps > 0))
    text = f"{above}/{gaps.size} seeds above (min {gaps.min():+.1f})"
    return Target(text, MET if above == gaps.size else NOT_MET, {"gaps": gaps.tolist()})


def energy(verdict: dict[str, Any]) -> Target:
    """Target 3: the verdict's energy saving, excess gap and ``target_verdict``, copied."""
    if "target_verdict" not in verdict:
        return Target("no energy verdict (not a thickening-control row)", OPEN)
    saved, low, high = (100 * float(verdict[f"energy_saved{end}"]) for end in ("", "_low", "_high"))
    excess = [float(verdict[f"excess_gap{end}"]) for end in ("", "_low", "_high")]
    word = str(verdict["target_verdict"])
    if math.isnan(saved):
        return Target("not paired", OPEN)
    kept = format_interval(saved, low, high, ".0f")
    text = f"{kept}% saved, excess {format_interval(excess[0], excess[1], excess[2], '+.3f')}"
    return Target(text, word if word in (MET, NOT_MET) else OPEN, {"verdict": word})


def pulse_gap(row: dict[str, Any], pulse: dict[str, Any] | None) -> Target:
    """Target 4: :func:`agents.evaluate.state_gap` of the row against the pulse controller's row."""
    if pulse is None:
        return Target("no pulse row", OPEN)
    gap = state_gap(row, pulse)
    value, low, high = gap["state_gap"], gap["state_gap_low"], gap["state_gap_high"]
    if math.isnan(value):
        return Target("not paired", OPEN, gap)
    word = MET if low > 0 else NOT_MET if high < 0 else OPEN
    text = f"{format_interval(value, low, high, '+.2f')}, {gap['states_above']}/{gap['states']} states above"
    return Target(text, word, gap)


def _steps_text(steps: int | None) -> str:
    """``10000``, ``3e5`` (a round number from 10^5 on), ``?`` where unknown."""
    if steps is None:
        return "?"
    if steps >= 100_000:
        short = f"{steps:.0e}".replace("e+0", "e").replace("e+", "e")
        if float(short) == steps:
            return short
    return str(steps)


def _find(path: str | Path) -> Path | None:
    """A path as written in a command: absolute, or relative to the current folder, then to the
    repository's root; None where it is not there."""
    path = Path(path)
    for candidate in (path,) if path.is_absolute() else (Path.cwd() / path, ROOT / path):
        if candidate.exists():
            return candidate
    return None


def training_steps(run: Path, depth: int = 0, upto: int | None = None) -> dict[str, Any]:
    """A run's training steps per kind: ``simulator``, ``surrogate`` (None where unknown), ``trained``
    (``result.json``'s ``timesteps`` where it differs from ``n_timesteps``) and ``notes``; a fine-tuned
    run's source counted in (see the module docstring). ``upto``: the steps of the checkpoint that was
    used instead of ``n_timesteps``."""
    try:
        config = read_run_config(run, "RUN_DIRS")
    except ValueError as error:
        return {"simulator": None, "surrogate": None, "notes": [str(error)]}
    hyper = config.get("hyperparams")
    steps = (hyper.get("n_timesteps") if isinstance(hyper, dict) else None) if upto is None else upto
    steps = int(steps) if isinstance(steps, int | float) and not isinstance(steps, bool) else None
    surrogate = config["env_id"] in SURROGATE_IDS
    out: dict[str, Any] = {
        "simulator": 0 if surrogate else steps,
        "surrogate": steps if surrogate else 0,
        "notes": [] if steps is not None else [f"{run / 'config.yml'} has no hyperparams.n_timesteps"],
    }
    result = run / "result.json"
    if steps is not None and upto is None and result.is_file():
        trained = read_json(result).get("timesteps")
        if isinstance(trained, int) and trained != steps:
            out["trained"] = trained
    source = config.get("init_from")
    if isinstance(source, dict) and depth < 5:
        out = _add(out, _source_steps(source, depth))
    return out


def _source_steps(source: dict[str, Any], depth: int) -> dict[str, Any]:
    """The steps of a fine-tuned run's source (its ``init_from`` record)."""
    model = Path(str(source.get("model") or ""))
    folder = _find(source["run"]) if source.get("run") else None
    if folder is not None and (folder / "config.yml").is_file():
        checkpoint = re.fullmatch(r"ckpt_(\d+)_steps\.zip", model.name)
        steps = training_steps(folder, depth + 1, int(checkpoint.group(1)) if checkpoint else None)
        how = f"fine-tuned from {model if checkpoint else source['run']}"
        if model.name == "best_model.zip":
            how += " (its best validation model: at most its n_timesteps)"
        steps["notes"] = [how, *steps["notes"]]
        steps.pop("trained", None)
        return steps
    where = source.get("run") or model
    if source.get("env_id") in SURROGATE_IDS:
        note = f"fine-tuned from {where}: not found; {source['env_id']}: surrogate steps unknown"
        return {"simulator": 0, "surrogate": None, "notes": [note]}
    return {"simulator": None, "surrogate": None, "notes": [f"fine-tuned from {where}: not found"]}


def _add(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    def plus(x: int | None, y: int | None) -> int | None:
        return None if x is None or y is None else x + y

    return {
        **a,
        "simulator": plus(a["simulator"], b["simulator"]),
        "surrogate": plus(a["surrogate"], b["surrogate"]),
        "notes": a["notes"] + b["notes"],
    }


def simulator_time(runs: list[Path] | None) -> Target:
    """Target 5 over a policy's run folders (None: not found)."""
    if not runs:
        return Target("run folders not found", OPEN)
    seeds = [training_steps(run) for run in runs]

    def spread(key: str) -> str:
        values = [s[key] for s in seeds if s[key] is not None]
        if len(values) < len(seeds):
            return "?"
        low, high = min(values), max(values)
        return _steps_text(low) if low == high else f"{_steps_text(low)}-{_steps_text(high)}"

    text = f"{spread('simulator')} simulator steps, {spread('surrogate')} surrogate steps"
    trained = sorted({s["trained"] for s in seeds if "trained" in s})
    if trained:
        text += f" (result.json: {trained[0]}{f'-{trained[-1]}' if len(trained) > 1 else ''} trained)"
    notes = sorted({n for s in seeds for n in s["notes"]})
    if notes:
        text += f" ({'; '.join(notes)})"
    simulator = [s["simulator"] for s in seeds]
    if any(s is None for s in simulator):
        word = OPEN
    else:
        word = MET if max(simulator) <= ORIGINAL_STEPS else NOT_MET
    return Target(text, word, {"seeds": seeds})


def evaluated_runs(folder: Path) -> list[str] | None:
    """The RUN_DIRS of an ``agents.evaluate`` folder: its manifest's ``params.runs``, or the words of its
    ``command.txt`` between ``agents.evaluate`` and the first option; None where neither names them."""
    try:
        manifest = read_manifest(folder)
    except RunFolderError:
        manifest = None
    if manifest is not None and isinstance(manifest.params.get("runs"), list):
        return [str(p) for p in manifest.params["runs"]]
    command = folder / "command.txt"
    if not command.is_file():
        return None
    words = command.read_text().split()
    if "agents.evaluate" not in words:
        return None
    runs = []
    for word in words[words.index("agents.evaluate") + 1 :]:
        if word.startswith("-"):
            break
        runs.append(word)
    return runs


def run_groups(paths: list[str] | None) -> dict[str, list[Path]]:
    """Row name -> run folders, named by :func:`agents.evaluate.find_runs` (a path that is gone, or that
    ``find_runs`` refuses, is left out)."""
    groups: dict[str, list[Path]] = {}
    for path in paths or []:
        found = _find(path)
        if found is None:
            continue
        try:
            with redirect_stderr(io.StringIO()):
                named = find_runs([found])
        except SystemExit:
            continue
        for name, runs in named.items():
            groups.setdefault(name, []).extend(r for r in runs if r not in groups.get(name, []))
    return groups


def group_name(row_name: str) -> str:
    """The name ``find_runs`` gave a row's group (the row name without its suffixes)."""
    for suffix in ROW_SUFFIXES:
        row_name = row_name.removesuffix(suffix)
    return row_name


def row_targets(
    row: dict[str, Any],
    verdict: dict[str, Any],
    best: dict[str, Any],
    pulse: dict[str, Any] | None,
    runs: list[Path] | None,
    share: float,
) -> dict[str, Target]:
    """The five targets of one row, by :data:`TARGETS` name."""
    return dict(
        zip(
            TARGETS,
            (
                return_lead(verdict, best, share),
                seed_gaps(row, best),
                energy(verdict),
                pulse_gap(row, pulse),
                simulator_time(runs),
            ),
            strict=True,
        )
    )


def overall(targets: dict[str, Target]) -> str:
    """ "all five met", or "not met: " and the targets that are not (those unresolved marked so)."""
    missed = [
        name if t.verdict == NOT_MET else f"{name} ({t.verdict})"
        for name, t in targets.items()
        if t.verdict != MET
    ]
    return "all five met" if not missed else "not met: " + ", ".join(missed)


def trained_rows(result: dict[str, Any]) -> list[str]:
    """The rows with a verdict and more than one training seed."""
    judged = {v["name"] for v in result.get("verdicts", [])}
    return [r["name"] for r in result["rows"] if r["name"] in judged and len(r["returns"]) > 1]


def targets_table(
    result: dict[str, Any],
    folder: Path,
    names: list[str],
    pulse_prefix: str = "pulse on",
    share: float = 0.10,
) -> str:
    """The header line and the Markdown table of ``names`` (rows of ``result``, with verdicts)."""
    rows = {r["name"]: r for r in result["rows"]}
    verdicts = {v["name"]: v for v in result.get("verdicts", [])}
    best = next(r for r in result["rows"] if r["name"].startswith("best constant"))
    pulse = next((r for r in result["rows"] if r["name"].startswith(pulse_prefix)), None)
    groups = run_groups(evaluated_runs(folder))
    lines = [
        f"Split {result['split']}, {len(result['indices'])} states; {best['name']}: mean return "
        f"{best['return']['mean']:.2f}; pulse controller: {pulse['name'] if pulse else 'none'}.",
        "",
        "| " + " | ".join(c.format(share=share) for c in COLUMNS) + " |",
        "|" + "---|" * len(COLUMNS),
    ]
    for name in names:
        targets = row_targets(rows[name], verdicts[name], best, pulse, groups.get(group_name(name)), share)
        cells = [name, *(t.cell() for t in targets.values()), overall(targets)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("folder", type=Path, metavar="EVAL_DIR", help="an agents.evaluate --out folder")
    parser.add_argument(
        "--pulse",
        default="pulse on",
        metavar="NAME_PREFIX",
        help='the pulse controller\'s row (default "pulse on")',
    )
    parser.add_argument(
        "--share",
        type=float,
        default=0.10,
        help="the return lead's target, a share of |best constant's return|",
    )
    parser.add_argument(
        "--rows", nargs="+", metavar="NAME", help="the rows to judge (default: the trained ones)"
    )
    args = parser.parse_args(argv)
    path = args.folder / "results.json"
    if not path.is_file():
        parser.error(f"EVAL_DIR: {args.folder} holds no results.json (an agents.evaluate --out folder)")
    if not math.isfinite(args.share) or args.share <= 0:
        parser.error(f"--share must be a positive number, got {args.share}")
    result = read_json(path)  # "nan", "inf" back to floats
    if not any(r["name"].startswith("best constant") for r in result["rows"]):
        parser.error(f"EVAL_DIR: {path} has no best constant row")
    judged = {v["name"] for v in result.get("verdicts", [])}
    names = args.rows if args.rows else trained_rows(result)
    unknown = [n for n in names if n not in judged]
    if unknown:
        parser.error(f"--rows: no verdict for {unknown} in {path} (rows with one: {sorted(judged)})")
    sys.stdout.write(targets_table(result, args.folder, names, args.pulse, args.share))


if __name__ == "__main__":
    main()
