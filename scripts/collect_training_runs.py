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
evaluation's per-run traces stay out (megabytes; rerun the commands in docs/agents.md to get them). The
runs' and the evaluation's ``manifest.json`` (their owner and identity) are copied where they exist.

``--out`` follows the run-folder protocol (:mod:`agents.folders`): it is claimed for this script, with the
study's and the evaluation's paths as identity, before anything is copied; a collection of another study is
refused (exit 2) unless ``--overwrite`` deletes it first. A folder collected before manifests (it holds
``evaluation/table.md`` or ``seed*/training_returns.csv``) is adopted. Files are copied atomically.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

from agents.evaluate import TRAINING_RETURNS_CSV, write_training_returns
from agents.folders import add_folder_options, check_parent, claim_for_script, compare_paths, legacy_markers

ROOT = Path(__file__).resolve().parents[1]
RUN_FILES = ("config.yml", "command.txt", "result.json", "model.zip", "vecnormalize.pkl")
OPTIONAL_FILES = ("manifest.json",)
"""Copied where they exist (runs and evaluations made before manifests have none)."""
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


def copy_atomic(source: Path, dest: Path) -> None:
    """``shutil.copy2`` into a temporary file beside ``dest``, then renamed over it."""
    handle, tmp = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.name}.", suffix=".tmp")
    os.close(handle)
    try:
        shutil.copy2(source, tmp)
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def collect(runs: list[Path], evaluation: Path, out: Path) -> None:
    """Copy ``runs`` and ``evaluation`` into ``out`` (see the module docstring)."""
    for run in runs:
        dest = out / run.name
        (dest / "eval").mkdir(parents=True, exist_ok=True)
        for name in RUN_FILES:
            copy_atomic(run / name, dest / name)
        for name in OPTIONAL_FILES:
            if (run / name).exists():
                copy_atomic(run / name, dest / name)
        copy_atomic(run / "eval" / "evaluations.npz", dest / "eval" / "evaluations.npz")
        for stale in ("tb", "monitor"):
            shutil.rmtree(dest / stale, ignore_errors=True)
        shutil.copytree(run / "monitor", dest / "monitor")
        write_training_returns(run, dest / TRAINING_RETURNS_CSV)
    (out / "evaluation").mkdir(parents=True, exist_ok=True)
    for name in (*EVALUATION_FILES, *OPTIONAL_FILES):
        if name in EVALUATION_FILES or (evaluation / name).exists():
            copy_atomic(evaluation / name, out / "evaluation" / name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("study", type=Path, help="folder of training runs (python -m agents.train --seeds)")
    parser.add_argument("evaluation", type=Path, help="folder written by python -m agents.evaluate")
    parser.add_argument(
        "--out",
        type=Path,
        default=ROOT / "results" / "ppo" / "FieldMagnitude-v0",
        help="results folder (default: results/ppo/FieldMagnitude-v0 of this repository)",
    )
    add_folder_options(parser, "--out")
    args = parser.parse_args(argv)
    check_parent(parser, args.out)
    runs = finished_runs(args.study)
    if not runs:
        parser.error(f"no finished run (seed*/model.zip) in {args.study}")
    absent = [str(p) for p in (args.evaluation / name for name in EVALUATION_FILES) if not p.is_file()]
    if absent:
        parser.error(f"{args.evaluation} is no finished agents.evaluate folder: it lacks {', '.join(absent)}")
    legacy = [str(p.relative_to(args.out)) for p in sorted(args.out.glob("seed*/" + TRAINING_RETURNS_CSV))]
    claim_for_script(
        parser,
        args.out,
        "collect_training_runs.py",
        {"study": os.path.normpath(str(args.study)), "evaluation": os.path.normpath(str(args.evaluation))},
        argv=argv,
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, ["evaluation/table.md", *legacy], script="collect_training_runs.py"),
        compare=compare_paths(["study", "evaluation"]),
    )
    collect(runs, args.evaluation, args.out)
    print(f"collected {', '.join(r.name for r in runs)} and the evaluation into {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
