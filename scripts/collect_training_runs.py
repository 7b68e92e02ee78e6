#!/usr/bin/env python
"""Copy the small files of a training study and its evaluation into a results folder.

    python scripts/collect_training_runs.py runs/ppo_d3 runs/evaluation_d3 \
        [--out results/ppo/FieldMagnitude-v0]

Per seed (``STUDY/seed*/`` with a ``model.zip``): ``config.yml``, ``command.txt``, ``result.json``, the
final model and its normalisation (``model.zip``, ``vecnormalize.pkl``: what ``agents.evaluate`` plays),
the validation log ``eval/evaluations.npz`` (read by ``--model best`` and the learning curve), the Monitor
files, and the TensorBoard logs summarised as ``training_returns.csv`` (``steps,ep_rew_mean``:
``agents.evaluate.write_training_returns``; the learning curve reads it in their place). Of the
evaluation: its command, tables, ``results.json`` and plots. Checkpoints, TensorBoard logs and the
evaluation's per-run traces stay out (megabytes; rerun the commands in docs/agents.md to get them).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from agents.evaluate import TRAINING_RETURNS_CSV, write_training_returns

ROOT = Path(__file__).resolve().parents[1]
RUN_FILES = ("config.yml", "command.txt", "result.json", "model.zip", "vecnormalize.pkl")
EVALUATION_FILES = (
    "command.txt",
    "table.md",
    "verdict.md",
    "results.json",
    "pareto.png",
    "traces.png",
    "learning.png",
)


def finished_runs(study: Path) -> list[Path]:
    """The study's ``seed*`` folders with a final ``model.zip``, by name."""
    return sorted(p for p in study.glob("seed*") if (p / "model.zip").is_file())


def collect(runs: list[Path], evaluation: Path, out: Path) -> None:
    """Copy ``runs`` and ``evaluation`` into ``out`` (see the module docstring)."""
    for run in runs:
        dest = out / run.name
        (dest / "eval").mkdir(parents=True, exist_ok=True)
        for name in RUN_FILES:
            shutil.copy2(run / name, dest / name)
        shutil.copy2(run / "eval" / "evaluations.npz", dest / "eval" / "evaluations.npz")
        for stale in ("tb", "monitor"):
            shutil.rmtree(dest / stale, ignore_errors=True)
        shutil.copytree(run / "monitor", dest / "monitor")
        write_training_returns(run, dest / TRAINING_RETURNS_CSV)
    (out / "evaluation").mkdir(parents=True, exist_ok=True)
    for name in EVALUATION_FILES:
        shutil.copy2(evaluation / name, out / "evaluation" / name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", type=Path, help="folder of training runs (python -m agents.train --seeds)")
    parser.add_argument("evaluation", type=Path, help="folder written by python -m agents.evaluate")
    parser.add_argument(
        "--out",
        type=Path,
        default=ROOT / "results" / "ppo" / "FieldMagnitude-v0",
        help="results folder (default: results/ppo/FieldMagnitude-v0 of this repository)",
    )
    args = parser.parse_args(argv)
    runs = finished_runs(args.study)
    if not runs:
        parser.error(f"no finished run (seed*/model.zip) in {args.study}")
    collect(runs, args.evaluation, args.out)
    print(f"collected {', '.join(r.name for r in runs)} and the evaluation into {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
