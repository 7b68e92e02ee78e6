"""Train PPO or SAC on a dipenv environment.

    python -m agents.train --env dipenv/FieldMagnitude-v0 --algo ppo --seed 0 --out runs/ppo/seed0
    python -m agents.train --env dipenv/FieldMagnitude-v0 --algo ppo --seeds 0-4 --out runs/ppo [--workers 1]
        [--scheduler tcp://host:8786] [--timesteps N] [--n-envs N] [--hyperparams key=value ...]
        [--env-kwargs JSON] [--no-progress]

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (RL Zoo layout, one entry per env id),
overridden by ``--hyperparams``. Training runs ``n_envs`` environments in a ``SubprocVecEnv`` (a
``DummyVecEnv`` for one, or inside a daemonic worker) under ``VecNormalize``; an ``EvalCallback``
evaluates the deterministic policy on every validation start state (``start_state="cycle"``) every
``eval_freq`` steps and keeps the best model; checkpoints (model, normalisation statistics and, for SAC,
the replay buffer) every ``checkpoint_freq`` steps; TensorBoard logs; a progress bar.

A run folder holds ``config.yml`` (env id and arguments, algorithm, seed, resolved hyperparameters,
versions), ``command.txt``, ``model.zip``, ``vecnormalize.pkl``, ``result.json``, ``checkpoints/``,
``eval/`` (``evaluations.npz``, ``best_model.zip``), ``monitor/`` and ``tb/``. Rerunning the same command
skips finished runs and resumes interrupted ones from their last checkpoint (not bit-identical to an
uninterrupted run: the environments restart their episodes); the validation log and the best model carry
over, and the Monitor files are appended to (episodes finished after the last checkpoint stay in them).
With ``--seeds`` each seed is a task in ``OUT/seed<k>`` on the local pool (``--workers``) or a Dask
cluster (``--scheduler``).
"""

from __future__ import annotations

import argparse
import functools
import json
import multiprocessing as mp
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.tasks import parse_seeds, run_tasks
from agents.usage import directory, json_object, usage_error

PROG = "python -m agents.train"

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
ALGOS = ("ppo", "sac")
_TRAINING_KEYS = ("n_timesteps", "n_envs", "policy", "normalize", "eval_freq", "checkpoint_freq")


def load_hyperparams(algo: str, env_id: str, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``hyperparams/<algo>.yml`` with ``overrides`` applied.

    Raises:
        ValueError: for an unknown algorithm or an env id without an entry.
    """
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {', '.join(ALGOS)}, got {algo!r}")
    table = yaml.safe_load((HYPERPARAMS_DIR / f"{algo}.yml").read_text())
    if env_id not in table:
        raise ValueError(f"no {algo} hyperparameters for {env_id!r} in {HYPERPARAMS_DIR / (algo + '.yml')}")
    params = dict(table[env_id])
    params.update(overrides or {})
    return params


def can_start_subprocesses() -> bool:
    """False inside a daemonic process (a Dask worker, a multiprocessing.Pool worker)."""
    return not mp.current_process().daemon


def versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import sim
    from dipenv.state_library import simulator_source_digest

    return {
        "sim": sim.__version__,
        "sim_source": simulator_source_digest(),
        "stable_baselines3": str(stable_baselines3.__version__),
        "gymnasium": str(gymnasium.__version__),
        "torch": str(torch.__version__),
        "python": sys.version.split()[0],
    }


def _latest_checkpoint(folder: Path) -> tuple[int, Path] | None:
    found = []
    for path in folder.glob("ckpt_*_steps.zip"):
        match = re.fullmatch(r"ckpt_(\d+)_steps\.zip", path.name)
        if match:
            found.append((int(match.group(1)), path))
    return max(found) if found else None


def missing_normalisation(out: Path, hyperparams: dict[str, Any]) -> str | None:
    """Why ``out`` cannot be resumed, or None: its latest checkpoint lacks the ``VecNormalize`` statistics
    saved with it (a resumed policy would see observations scaled by fresh statistics). A run without
    checkpoints, one trained without normalisation, or one already finished is not resumed from them."""
    if not hyperparams.get("normalize"):
        return None
    latest = _latest_checkpoint(out / "checkpoints")
    if latest is None:
        return None
    try:
        done = json.loads((out / "result.json").read_text())
        if int(done["timesteps"]) >= int(hyperparams["n_timesteps"]):
            return None  # finished: a rerun returns its result
    except (OSError, ValueError, KeyError, TypeError):
        pass
    steps, model = latest
    stats = out / "checkpoints" / f"ckpt_vecnormalize_{steps}_steps.pkl"
    if stats.exists():
        return None
    return (
        f"--out {out}: resuming from {model} needs the observation normalisation saved with it, {stats}, "
        "which is missing (fresh statistics would feed the policy differently scaled observations); "
        "restore it, or delete the run's folder to train afresh, or choose another --out"
    )


def train_run(payload: dict[str, Any]) -> dict[str, Any]:
    """Train one seed into ``payload["out"]`` (a task; see the module docstring). Returns ``result.json``."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from agents.callbacks import PhysicsLoggerCallback
    from agents.rollout import make_env, make_monitored_env

    torch.set_num_threads(1)
    out = Path(payload["out"])
    env_id, algo, seed = payload["env_id"], payload["algo"], int(payload["seed"])
    env_kwargs = dict(payload["env_kwargs"])
    hp = dict(payload["hyperparams"])
    progress = bool(payload.get("progress", True))
    probe = make_env(env_id, {**env_kwargs, "progress": progress})  # settings now, start states below
    identity = {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        # resolved defaults: a changed env default is a different run
        "env_settings": probe.unwrapped.settings(),  # type: ignore[attr-defined]
        "algo": algo,
        "seed": seed,
        "hyperparams": hp,
    }
    comparable = {**identity, "hyperparams": {k: v for k, v in hp.items() if k != "n_timesteps"}}
    config_file = out / "config.yml"
    if config_file.exists():
        old = yaml.safe_load(config_file.read_text())
        old_comparable = {k: old.get(k) for k in identity}
        old_comparable["hyperparams"] = {
            k: v for k, v in (old.get("hyperparams") or {}).items() if k != "n_timesteps"
        }
        if old_comparable != comparable:
            probe.close()
            raise SystemExit(f"{out} holds a different run (config.yml differs); choose another --out")
        if (out / "result.json").exists():
            done = json.loads((out / "result.json").read_text())
            if int(done["timesteps"]) >= int(hp["n_timesteps"]):
                probe.close()
                return dict(done)  # finished (a larger n_timesteps continues it from its last checkpoint)
    problem = missing_normalisation(out, hp)
    if problem is not None:  # main() refuses this before any task starts
        probe.close()
        raise FileNotFoundError(problem)
    out.mkdir(parents=True, exist_ok=True)
    config_file.write_text(yaml.safe_dump({**identity, "versions": versions()}, sort_keys=False))
    (out / "command.txt").write_text(payload["command"] + "\n")

    total = int(hp.pop("n_timesteps"))
    n_envs = int(hp.pop("n_envs"))
    policy = hp.pop("policy")
    normalize = bool(hp.pop("normalize"))
    eval_freq = int(hp.pop("eval_freq"))
    checkpoint_freq = int(hp.pop("checkpoint_freq"))

    library = probe.unwrapped.library()  # type: ignore[attr-defined]
    library.ensure(["train", "validation"], progress=progress)
    n_validation = probe.unwrapped.split_sizes["validation"]  # type: ignore[attr-defined]
    probe.close()

    quiet = {**env_kwargs, "progress": False}
    checkpoints = out / "checkpoints"
    latest = _latest_checkpoint(checkpoints)
    vec_cls = SubprocVecEnv if n_envs > 1 and can_start_subprocesses() else DummyVecEnv
    venv = make_vec_env(
        functools.partial(make_env, env_id, quiet),
        n_envs=n_envs,
        seed=seed,
        vec_env_cls=vec_cls,
        monitor_dir=str(out / "monitor"),
        monitor_kwargs={"override_existing": latest is None},  # a resumed run appends its episodes
    )
    eval_venv = DummyVecEnv(
        [
            functools.partial(
                make_monitored_env, env_id, {**quiet, "split": "validation", "start_state": "cycle"}
            )
        ]
    )
    gamma = float(hp.get("gamma", 0.99))
    algo_cls: Any = PPO if algo == "ppo" else SAC
    if latest is not None:
        steps_done, model_path = latest
        stats = checkpoints / f"ckpt_vecnormalize_{steps_done}_steps.pkl"  # checked above
        env: Any = VecNormalize.load(str(stats), venv) if normalize else venv
        model = algo_cls.load(str(model_path), env=env, device="cpu")
        buffer = checkpoints / f"ckpt_replay_buffer_{steps_done}_steps.pkl"
        if algo == "sac" and buffer.exists():
            model.load_replay_buffer(str(buffer))
    else:
        steps_done = 0
        env = VecNormalize(venv, gamma=gamma) if normalize else venv
        model = algo_cls(
            policy, env, seed=seed, device="cpu", tensorboard_log=str(out / "tb"), verbose=0, **hp
        )
    eval_env: Any = (
        VecNormalize(eval_venv, training=False, norm_reward=False, gamma=gamma) if normalize else eval_venv
    )
    callbacks = CallbackList(
        [
            CheckpointCallback(
                save_freq=max(checkpoint_freq // n_envs, 1),
                save_path=str(checkpoints),
                name_prefix="ckpt",
                save_vecnormalize=normalize,
                save_replay_buffer=algo == "sac",
            ),
            EvalCallback(
                eval_env,
                n_eval_episodes=n_validation,
                eval_freq=max(eval_freq // n_envs, 1),
                best_model_save_path=str(out / "eval"),
                log_path=str(out / "eval"),
                deterministic=True,
                verbose=0,
            ),
            PhysicsLoggerCallback(),
        ]
    )
    if latest is not None:
        _restore_eval_history(callbacks.callbacks[1], out / "eval" / "evaluations.npz", steps_done)
    tic = time.perf_counter()
    remaining = max(total - steps_done, 0)
    if remaining:
        model.learn(
            total_timesteps=remaining,
            callback=callbacks,
            progress_bar=progress,
            reset_num_timesteps=latest is None,
            tb_log_name="run",
        )
    wall = time.perf_counter() - tic
    model.save(str(out / "model.zip"))
    if normalize:
        env.save(str(out / "vecnormalize.pkl"))
    eval_cb = callbacks.callbacks[1]
    result = {
        "env_id": env_id,
        "algo": algo,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "resumed_from": steps_done,
        "wall_seconds": wall,
        "env_steps_per_second": remaining / wall if wall > 0 else float("nan"),
        "best_validation_return": float(getattr(eval_cb, "best_mean_reward", float("nan"))),
        "last_validation_return": float(getattr(eval_cb, "last_mean_reward", float("nan"))),
        "library_key": library.key,
    }
    env.close()
    eval_env.close()
    (out / "result.json").write_text(json.dumps(result, indent=1))
    return result


def _restore_eval_history(callback: Any, log: Path, steps_done: int) -> None:
    """A resumed run keeps its validation history and best return (SB3's EvalCallback starts empty,
    so it would overwrite ``evaluations.npz`` with the new evaluations only and take the first of them
    as the best model). Evaluations after the checkpoint resumed from are dropped: they are redone."""
    if not log.exists():
        return
    with np.load(log) as data:
        keep = data["timesteps"] <= steps_done
        callback.evaluations_timesteps = [int(t) for t in data["timesteps"][keep]]
        callback.evaluations_results = [list(map(float, r)) for r in data["results"][keep]]
        callback.evaluations_length = [list(map(int, n)) for n in data["ep_lengths"][keep]]
    if callback.evaluations_results:
        callback.best_mean_reward = max(float(np.mean(r)) for r in callback.evaluations_results)


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["gamma=0.9", "policy_kwargs={net_arch: [8]}"]`` -> values parsed as YAML."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            usage_error(PROG, f"--hyperparams takes key=value, got {item!r}")
        key, value = item.split("=", 1)
        out[key.strip()] = yaml.safe_load(value)
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--env", required=True, help="environment id, e.g. dipenv/FieldMagnitude-v0")
    parser.add_argument("--algo", default="ppo", choices=ALGOS)
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=int, default=None, help="one training seed; OUT is the run folder")
    seeds.add_argument("--seeds", default=None, help="several seeds (0-4, 0,2,5); runs go to OUT/seed<k>")
    parser.add_argument("--out", required=True, type=directory)
    parser.add_argument("--timesteps", type=int, default=None, help="override n_timesteps")
    parser.add_argument("--n-envs", type=int, default=None, help="override n_envs")
    parser.add_argument("--hyperparams", nargs="*", default=[], help="key=value overrides (YAML values)")
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of extra environment arguments")
    parser.add_argument("--workers", type=int, default=1, help="trainings at once on the local pool")
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address (instead of local workers)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    return parser


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    args = build_parser().parse_args(argv)
    overrides = parse_overrides(args.hyperparams)
    if args.timesteps is not None:
        overrides["n_timesteps"] = args.timesteps
    if args.n_envs is not None:
        overrides["n_envs"] = args.n_envs
    try:
        hp = load_hyperparams(args.algo, args.env, overrides)
    except ValueError as error:
        usage_error(PROG, f"--env/--algo: {error}")
    env_kwargs = json_object(PROG, "--env-kwargs", args.env_kwargs)
    command = " ".join([sys.executable, "-m", "agents.train", *(argv if argv is not None else sys.argv[1:])])
    if args.seeds is not None:
        try:
            seeds = parse_seeds(args.seeds)
        except ValueError as error:
            usage_error(PROG, f"--seeds: {error}")
        outs = [args.out / f"seed{s}" for s in seeds]
    else:
        seeds = [0 if args.seed is None else args.seed]
        outs = [args.out]
    for out in outs:
        problem = missing_normalisation(out, hp)
        if problem is not None:
            usage_error(PROG, problem)
    payloads = [
        {
            "env_id": args.env,
            "env_kwargs": env_kwargs,
            "algo": args.algo,
            "seed": s,
            "hyperparams": hp,
            "out": str(o),
            "command": command,
            "progress": not args.no_progress and len(seeds) == 1,
        }
        for s, o in zip(seeds, outs, strict=True)
    ]
    results = run_tasks(train_run, payloads, workers=args.workers, scheduler=args.scheduler)
    for r in results:
        print(
            f"{r['algo']} seed {r['seed']}: {r['timesteps']} steps, {r['wall_seconds']:.0f} s, "
            f"best validation return {r['best_validation_return']:.2f}"
        )
    return results


if __name__ == "__main__":
    main()
