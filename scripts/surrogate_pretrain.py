"""Issue 43's pretrain -> fine-tune protocol: PPO seeds pretrained on the surrogate, each fine-tuned in the
simulator, with the simulator time each seed used.

    python scripts/surrogate_pretrain.py --out DIR [--seeds 0-4] [--pretrain-steps 1000000]
        [--finetune-steps 10000] [--pretrain-env dipenv/ThickeningControlSurrogate-v0]
        [--env dipenv/ThickeningControl-v2] [--algo ppo] [--env-kwargs JSON] [--workers 2]
        [--pretrain-hyperparams key=value ...] [--finetune-hyperparams key=value ...]
        [--resume | --overwrite]

Two ``agents.train`` studies, one after the other, in one folder:

1. ``DIR/pretrain``: ``agents.train --env PRETRAIN_ENV --seeds SEEDS --timesteps PRETRAIN_STEPS`` (the
   surrogate's hyperparameters from ``agents/hyperparams/<algo>.yml``, ``--pretrain-hyperparams`` over
   them);
2. ``DIR/finetune``: ``agents.train --env ENV --seeds SEEDS --timesteps FINETUNE_STEPS --init-from
   DIR/pretrain``: seed ``k`` starts from ``DIR/pretrain/seed<k>`` (its policy and its normalisation
   statistics, which keep updating) and trains with ``ENV``'s hyperparameters (``--finetune-hyperparams``
   over them; :mod:`agents.init_from`).

Then ``DIR/summary.json`` and ``DIR/summary.md``, a row per seed: the pretraining's surrogate steps, wall
time and validation returns (in the surrogate), and the fine-tuning's **simulator use**: its training
steps (control intervals), the validation episodes' steps (``eval/evaluations.npz``; a validation pass
of ``ThickeningControl-v2`` is 8 x 48 = 384 steps), their sum, the simulated time (steps x the control
interval, in ``1/gammadot_ref``), the wall time of the fine-tuning, and its validation returns (in the
simulator). The PPO rows of the thickening-control study used 10^4 training steps and two validation
passes per seed (10,768 simulator steps): ``--finetune-steps 10000`` compares at equal simulator time.

**Resumable.** ``DIR`` is claimed for the script (``manifest.json``: the env ids, the step counts, the
algorithm, the env arguments and both hyperparameter lists; not the seeds, so that more join, nor
``--workers``); its two studies are ``agents.train`` folders with their own manifests. A rerun skips the
finished seeds of each stage and resumes interrupted ones from their last checkpoint (SIGTERM stops a
stage with a checkpoint, exit 143), and rewrites the summary. Another step count or env is refused (exit
2), unless ``--overwrite`` deletes the whole folder.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from agents import train  # noqa: E402
from agents.folders import (  # noqa: E402
    add_folder_options,
    check_parent,
    claim_for_script,
    read_evaluation_log,
    write_text_atomic,
)
from agents.usage import integer_at_least, seed_list  # noqa: E402

SCRIPT = "surrogate_pretrain.py"
TODAY_SIMULATOR_STEPS = 10_000 + 2 * 8 * 48
"""Simulator steps of one PPO seed of the thickening-control study: 10^4 training steps and validation
passes at 5,000 and 10,000 steps (8 episodes x 48 intervals each)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=f"python scripts/{SCRIPT}",
        description=(__doc__ or "").split("\n")[0],
        allow_abbrev=False,
    )
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--seeds", type=seed_list, default=seed_list("0-4"), help="default 0-4")
    parser.add_argument("--pretrain-steps", type=integer_at_least(1), default=1_000_000)
    parser.add_argument("--finetune-steps", type=integer_at_least(1), default=10_000)
    parser.add_argument("--pretrain-env", default="dipenv/ThickeningControlSurrogate-v0")
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2", help="the simulator id fine-tuned on")
    parser.add_argument("--algo", default="ppo", choices=train.ALGOS)
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of env arguments (both stages)")
    parser.add_argument("--workers", type=integer_at_least(1), default=1, help="seeds at once, >= 1")
    for stage in ("pretrain", "finetune"):
        parser.add_argument(
            f"--{stage}-hyperparams",
            nargs="*",
            action="extend",
            default=[],
            help=f"key=value overrides of the {stage} stage's hyperparameters (agents.train --hyperparams)",
        )
    add_folder_options(parser)
    return parser


def _stage_argv(args: argparse.Namespace, stage: str) -> list[str]:
    seeds = ",".join(str(s) for s in args.seeds)
    common = ["--algo", args.algo, "--seeds", seeds, "--workers", str(args.workers), "--no-progress"]
    common += ["--env-kwargs", args.env_kwargs]
    if stage == "pretrain":
        argv = ["--env", args.pretrain_env, "--out", str(args.out / "pretrain")]
        argv += ["--timesteps", str(args.pretrain_steps), *common]
        extra = args.pretrain_hyperparams
    else:
        argv = ["--env", args.env, "--out", str(args.out / "finetune")]
        argv += ["--init-from", str(args.out / "pretrain"), "--timesteps", str(args.finetune_steps), *common]
        extra = args.finetune_hyperparams
    return [*argv, *(["--hyperparams", *extra] if extra else [])]


def _validation(run: Path) -> dict[str, Any]:
    log = run / "eval" / "evaluations.npz"
    if not log.exists():
        return {"passes": 0, "steps": 0, "best": None, "last": None}
    data = read_evaluation_log(log)
    means = data["results"].mean(axis=1)
    return {
        "passes": int(data["timesteps"].size),
        "steps": int(data["ep_lengths"].sum()),
        "best": float(means.max()) if means.size else None,
        "last": float(means[-1]) if means.size else None,
    }


def summarise(out: Path, seeds: list[int], control_interval: float) -> dict[str, Any]:
    """Per seed: the pretraining's surrogate steps, wall time and validation returns; the fine-tuning's
    simulator steps (training and validation), simulated time and wall time. Written to ``summary.json``
    and ``summary.md``."""
    rows = []
    for seed in seeds:
        pre = json.loads((out / "pretrain" / f"seed{seed}" / "result.json").read_text())
        fine_run = out / "finetune" / f"seed{seed}"
        fine = json.loads((fine_run / "result.json").read_text())
        validation = _validation(fine_run)
        simulator_steps = int(fine["timesteps"]) + validation["steps"]
        rows.append(
            {
                "seed": seed,
                "pretrain_steps": int(pre["timesteps"]),
                "pretrain_wall_seconds": pre["wall_seconds"],
                "pretrain_steps_per_second": pre["env_steps_per_second"],
                "pretrain_best_validation_return": pre["best_validation_return"],
                "finetune_training_steps": int(fine["timesteps"]),
                "finetune_validation_passes": validation["passes"],
                "finetune_validation_steps": validation["steps"],
                "simulator_steps": simulator_steps,
                "simulated_time": simulator_steps * control_interval,
                "finetune_wall_seconds": fine["wall_seconds"],
                "finetune_best_validation_return": validation["best"],
                "finetune_last_validation_return": validation["last"],
                "source_model_sha256": (fine.get("init_from") or {}).get("model_sha256"),
            }
        )
    summary = {
        "seeds": seeds,
        "control_interval": control_interval,
        "today_simulator_steps_per_seed": TODAY_SIMULATOR_STEPS,
        "rows": rows,
    }
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=1, allow_nan=False) + "\n")

    def number(value: Any, spec: str) -> str:
        missing = value is None or (isinstance(value, float) and not math.isfinite(value))
        return "" if missing else f"{value:{spec}}"

    lines = [
        "| seed | surrogate steps | pretrain wall s | surrogate validation return | simulator training steps "
        "| simulator validation steps | simulator steps | simulated time | fine-tune wall s "
        "| best validation return | last validation return |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row['seed']} | {row['pretrain_steps']} | {number(row['pretrain_wall_seconds'], '.0f')} "
            f"| {number(row['pretrain_best_validation_return'], '.1f')} | {row['finetune_training_steps']} "
            f"| {row['finetune_validation_steps']} | {row['simulator_steps']} | {row['simulated_time']:g} "
            f"| {number(row['finetune_wall_seconds'], '.0f')} "
            f"| {number(row['finetune_best_validation_return'], '.1f')} "
            f"| {number(row['finetune_last_validation_return'], '.1f')} |"
        )
    lines.append("")
    lines.append(
        f"A PPO seed of the thickening-control study used {TODAY_SIMULATOR_STEPS} simulator steps (10^4 "
        "training steps, two validation passes)."
    )
    write_text_atomic(out / "summary.md", "\n".join(lines) + "\n")
    return summary


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        env_kwargs = json.loads(args.env_kwargs)
    except json.JSONDecodeError as error:
        parser.error(f"--env-kwargs must be a JSON object ({error})")
    if not isinstance(env_kwargs, dict):
        parser.error("--env-kwargs must be a JSON object")
    for option, items in (
        ("--pretrain-hyperparams", args.pretrain_hyperparams),
        ("--finetune-hyperparams", args.finetune_hyperparams),
    ):
        bad = [item for item in items if "=" not in item]
        if bad:
            parser.error(f"{option} takes key=value, got {bad[0]!r}")
    check_parent(parser, args.out)
    identity = {
        "pretrain_env": args.pretrain_env,
        "env": args.env,
        "algo": args.algo,
        "pretrain_steps": args.pretrain_steps,
        "finetune_steps": args.finetune_steps,
        "env_kwargs": env_kwargs,
        "pretrain_hyperparams": list(args.pretrain_hyperparams),
        "finetune_hyperparams": list(args.finetune_hyperparams),
    }
    claim_for_script(
        parser, args.out, SCRIPT, identity, argv=argv, resume=args.resume, overwrite=args.overwrite
    )
    print(f"pretraining {len(args.seeds)} seeds on {args.pretrain_env} ({args.pretrain_steps} steps each)")
    train.main(_stage_argv(args, "pretrain"))
    print(f"fine-tuning them on {args.env} ({args.finetune_steps} steps each)")
    train.main(_stage_argv(args, "finetune"))
    from agents.rollout import make_env

    probe = make_env(args.env, {**env_kwargs, "progress": False})
    interval = float(probe.unwrapped.control_interval)  # type: ignore[attr-defined]
    probe.close()
    summary = summarise(args.out, args.seeds, interval)
    print((args.out / "summary.md").read_text())
    return summary


if __name__ == "__main__":
    main()
