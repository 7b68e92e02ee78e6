"""Train PPO or SAC on a dipenv environment.

    python -m agents.train --env dipenv/FieldMagnitude-v0 --algo ppo --seed 0 --out runs/ppo/seed0
    python -m agents.train --env dipenv/FieldMagnitude-v0 --algo ppo --seeds 0-4 --out runs/ppo [--workers 1]
        [--scheduler tcp://host:8786] [--timesteps N] [--n-envs N] [--hyperparams key=value ...]
        [--env-kwargs JSON] [--init-from RUN_OR_MODEL] [--no-progress] [--resume | --overwrite]

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (RL Zoo layout, one entry per env id),
overridden by ``--hyperparams``. Training runs ``n_envs`` environments in a ``SubprocVecEnv`` (a
``DummyVecEnv`` for one, or inside a daemonic worker) under ``VecNormalize``; an ``EvalCallback``
evaluates the deterministic policy on every validation start state (``start_state="cycle"``) every
``eval_freq`` steps and keeps the best model (its log and the model each renamed into place once whole,
:class:`agents.callbacks.AtomicEvalCallback`); checkpoints (model, normalisation statistics and, for SAC,
the replay buffer) every ``checkpoint_freq`` steps, each written atomically as a set (every file renamed
into place once whole, the model last), so that a process killed while writing one (SIGKILL, a lost node)
resumes from the one before; TensorBoard logs; a progress bar.

A run folder holds ``manifest.json`` (written first: the command and the run's identity, see below),
``config.yml`` (env id and arguments, algorithm, seed, resolved hyperparameters, versions),
``command.txt``, ``model.zip``, ``vecnormalize.pkl``, ``result.json``, ``checkpoints/``,
``eval/`` (``evaluations.npz``, ``best_model.zip``), ``monitor/`` and ``tb/``. Rerunning the same command
skips finished runs and resumes interrupted ones from their last checkpoint (not bit-identical to an
uninterrupted run: the environments restart their episodes); the validation log and the best model carry
over, and the Monitor files are appended to (episodes finished after the last checkpoint stay in them).
SIGTERM (``pkill -TERM -f agents.train``) stops a run at its next environment step with a checkpoint at
that step and exits 143 without a result, so the rerun loses nothing but the episodes under way.
With ``--seeds`` each seed is a task in ``OUT/seed<k>`` on the local pool (``--workers``) or a Dask
cluster (``--scheduler``).

``--init-from RUN_OR_MODEL`` starts each run from a trained policy (a model file, a run folder, or a
``--seeds`` study folder whose ``seed<k>`` starts seed ``k``) and its ``VecNormalize`` statistics, which
keep updating, with the target env's hyperparameters; the spaces must match; the source joins the run's
identity (:mod:`agents.init_from`).

Output folders follow the run-folder protocol (:mod:`agents.folders`): ``OUT`` (and with ``--seeds`` each
``OUT/seed<k>``) is claimed before anything is trained, with the identity env id, env arguments, algorithm,
the resolved hyperparameters, (a run folder) the seed and (with ``--init-from``) the source; ``--seeds``
folders leave the seeds out, so that more seeds join a study. A rerun of the same identity continues; a
larger ``n_timesteps`` (``--timesteps``) continues a run from its last checkpoint, a smaller one is
refused (the folder holds a longer run); a folder of another command or of other parameters is refused
(exit 2) unless ``--overwrite`` deletes the whole previous run (with ``--seeds``: every seed in
``OUT``). A run folder made before manifests (it holds ``config.yml`` or ``model.zip``; a ``--seeds``
folder: ``seed*/config.yml``) is adopted after its ``config.yml`` is checked. Every hyperparameter is
checked, and the model built once, before the folder is claimed.
"""

from __future__ import annotations

import argparse
import copy
import functools
import json
import math
import multiprocessing as mp
import os
import pickle
import re
import signal
import sys
import threading
import time
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.folders import (
    add_folder_options,
    claim_out,
    command_line,
    legacy_markers,
    normalise,
    read_evaluation_log,
    save_atomic,
    write_text_atomic,
)
from agents.init_from import (
    layout,
    load_policy,
    resolve_sources,
    resolved,
    source_problem,
)
from agents.tasks import run_tasks
from agents.usage import (
    checked_env,
    compile_notice,
    directory,
    integer_at_least,
    json_object,
    output_directory,
    scheduler_address,
    seed_list,
    usage_error,
)

PROG = "python -m agents.train"

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
ALGOS = ("ppo", "sac")
_TRAINING_KEYS = ("n_timesteps", "n_envs", "policy", "normalize", "eval_freq", "checkpoint_freq")


_CONSTRUCTOR_SET = (
    "self",
    "policy",
    "env",
    "seed",
    "device",
    "tensorboard_log",
    "verbose",
    "_init_setup_model",
)
"""Arguments of the algorithm's constructor that ``train_run`` sets itself (not hyperparameters)."""

_RANGES: dict[str, tuple[float, float, bool]] = {
    "learning_rate": (0.0, math.inf, False),
    "ent_coef": (0.0, math.inf, True),
    "n_steps": (1, math.inf, True),
    "batch_size": (2, math.inf, True),
    "n_epochs": (1, math.inf, True),
    "gamma": (0.0, 1.0, True),
    "gae_lambda": (0.0, 1.0, True),
    "clip_range": (0.0, math.inf, False),
    "vf_coef": (0.0, math.inf, True),
    "max_grad_norm": (0.0, math.inf, False),
    "buffer_size": (1, math.inf, True),
    "learning_starts": (0, math.inf, True),
    "tau": (0.0, 1.0, False),
    "train_freq": (1, math.inf, True),
    "target_update_interval": (1, math.inf, True),
    "n_timesteps": (1, math.inf, True),
    "n_envs": (1, math.inf, True),
    "eval_freq": (1, math.inf, True),
    "checkpoint_freq": (1, math.inf, True),
}
"""Valid ranges of the numeric hyperparameters: (low, high, low included); ``high`` is always included.
``tau`` > 0; ``batch_size`` >= 2 (PPO normalises advantages over a batch); ``ent_coef`` >= 0 (a negative
entropy bonus rewards a collapsed policy; SAC's ``"auto"`` or ``"auto_X"`` with ``X > 0`` learns it)."""


class HyperparameterError(ValueError):
    """A hyperparameter refused; the message names where it came from (the packaged file or
    ``--hyperparams``)."""


EVAL_SEED_OFFSET = 10_000
"""The validation envs of a run of seed ``s`` are seeded ``s + EVAL_SEED_OFFSET`` at every validation pass
(:class:`agents.callbacks.AtomicEvalCallback`), apart from its training envs' ``s .. s + n_envs - 1``."""


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_hyperparameters(algo: str, params: dict[str, Any], source: str) -> None:
    """Raise :class:`HyperparameterError` naming ``source`` unless every key of ``params`` is an argument
    of the algorithm's constructor (or one of the training keys) and every value has the type of that
    argument's default and lies in its range (:data:`_RANGES`). Cheap: nothing is built."""
    import inspect

    from stable_baselines3 import PPO, SAC

    algo_cls: Any = PPO if algo == "ppo" else SAC
    defaults = {
        name: parameter.default
        for name, parameter in inspect.signature(algo_cls.__init__).parameters.items()
        if name not in _CONSTRUCTOR_SET
    }
    allowed = sorted([*_TRAINING_KEYS, *defaults])
    for key, value in params.items():
        if key not in allowed:
            raise HyperparameterError(
                f"{source}: unknown hyperparameter {key!r} for {algo} (the keys: {', '.join(allowed)})"
            )
        default = defaults.get(key)
        if key in ("n_timesteps", "n_envs", "eval_freq", "checkpoint_freq"):
            default = 1
        elif key == "normalize":
            default = True
        elif key == "policy":
            default = "MlpPolicy"
        problem = None
        if isinstance(default, bool):
            problem = None if isinstance(value, bool) else "true or false"
        elif isinstance(default, int) and not (key == "train_freq" and isinstance(value, list)):
            problem = None if isinstance(value, int) and not isinstance(value, bool) else "an integer"
        elif isinstance(default, float):
            problem = None if _number(value) else "a number"
        elif isinstance(default, str):
            problem = None if isinstance(value, str) or (key == "ent_coef" and _number(value)) else "a string"
        elif key.endswith("_kwargs"):
            problem = None if value is None or isinstance(value, dict) else "a mapping"
        if problem is None and key == "ent_coef" and isinstance(value, str):
            problem = _auto_ent_coef_problem(algo, value)
        if problem is None and key in _RANGES and _number(value):
            low, high, closed = _RANGES[key]
            if not ((value >= low if closed else value > low) and value <= high and math.isfinite(value)):
                kind = "a number" if isinstance(default, float) else "an integer"
                problem = f"{kind} in {'[' if closed else '('}{low}, {high}]"
        if problem is not None:
            raise HyperparameterError(f"{source}: {key} must be {problem}, got {value!r}")
    if algo == "ppo" and int(params.get("n_steps", 2)) * int(params.get("n_envs", 1)) < 2:
        raise HyperparameterError(f"{source}: n_steps * n_envs must be >= 2 (one rollout), got 1")


def _auto_ent_coef_problem(algo: str, value: str) -> str | None:
    """Why the string ``ent_coef`` ``value`` is refused, or None (SAC: ``auto`` or ``auto_X``, ``X > 0``)."""
    allowed = "a number >= 0" + (", 'auto' or 'auto_X' with X > 0" if algo == "sac" else "")
    if algo != "sac" or not value.startswith("auto"):
        return allowed
    if value == "auto":
        return None
    try:
        initial = float(value.removeprefix("auto_")) if value.startswith("auto_") else math.nan
    except ValueError:
        initial = math.nan
    return None if math.isfinite(initial) and initial > 0 else allowed


def model_problem(algo: str, env: Any, params: dict[str, Any]) -> str | None:
    """Why the algorithm cannot be built with the hyperparameters ``params`` on ``env``'s spaces, or None:
    the model is built once (cheap: nothing is trained, SAC's replay buffer made small), so that a policy
    argument SB3 or torch refuse (``policy_kwargs: {net_arch: [-4]}``, an unknown keyword) is named before
    the run's folder is written, not as a traceback after it."""
    import warnings

    from stable_baselines3 import PPO, SAC

    algo_cls: Any = PPO if algo == "ppo" else SAC
    kwargs = {k: v for k, v in copy.deepcopy(params).items() if k not in _TRAINING_KEYS}
    if algo == "sac":
        kwargs["buffer_size"] = min(int(kwargs.get("buffer_size", 1_000_000)), 64)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = algo_cls(params["policy"], env, seed=0, device="cpu", verbose=0, **kwargs)
    except Exception as error:  # SB3, torch and gymnasium refuse arguments with many exception types
        return f"{type(error).__name__}: {error}"
    del model
    return None


def hyperparameter_file(algo: str) -> Path:
    """``hyperparams/<algo>.yml``."""
    return HYPERPARAMS_DIR / f"{algo}.yml"


def load_hyperparams(algo: str, env_id: str, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``hyperparams/<algo>.yml`` with ``overrides`` applied, checked
    (:func:`check_hyperparameters`: the file's entry, then the overrides).

    Raises:
        ValueError: for an unknown algorithm or an env id without an entry;
        HyperparameterError: for a file that is not a YAML mapping of env ids to mappings, or a refused
        key or value (naming the file and entry, or ``--hyperparams``).
    """
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {', '.join(ALGOS)}, got {algo!r}")
    path = hyperparameter_file(algo)
    try:
        table = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        raise HyperparameterError(f"hyperparameter file {path}: cannot be read as YAML ({error})") from None
    if not isinstance(table, dict):
        raise HyperparameterError(f"hyperparameter file {path}: must map env ids to hyperparameters")
    if env_id not in table:
        raise ValueError(f"no {algo} hyperparameters for {env_id!r} in {path}")
    if not isinstance(table[env_id], dict):
        raise HyperparameterError(
            f"hyperparameter file {path}: the entry {env_id} must be a mapping of hyperparameters, got "
            f"{table[env_id]!r}"
        )
    params = dict(table[env_id])
    missing = [key for key in _TRAINING_KEYS if key not in params]
    if missing:
        raise HyperparameterError(
            f"hyperparameter file {path}: the entry {env_id} lacks {', '.join(missing)}"
        )
    check_hyperparameters(algo, params, f"hyperparameter file {path}, entry {env_id}")
    if overrides:
        params.update(overrides)
        check_hyperparameters(algo, params, "--hyperparams")
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
    """The newest whole checkpoint in ``folder``, ``(steps, folder / "ckpt_<steps>_steps.zip")``, or None.

    A checkpoint is a set written model last, each file renamed into place once whole
    (:class:`agents.callbacks.NewestBufferCheckpointCallback`), so a model file marks a whole set. A step
    counts when its model is a whole SB3 archive (:func:`_whole_zip`), its replay buffer (where there is
    one: only the newest is kept) a whole pickle and, in a folder that holds normalisation statistics, its
    statistics a whole pickle too: what a process killed mid-checkpoint left before checkpoints were
    atomic (a truncated file, a model without its statistics) is passed over for the checkpoint before
    it. Temporary files (``.ckpt_*.tmp.*``) never count. A folder without any statistics yields its newest
    model, and :func:`missing_normalisation` refuses to resume a normalised run from it."""
    found = []
    for path in folder.glob("ckpt_*_steps.zip"):
        match = re.fullmatch(r"ckpt_(\d+)_steps\.zip", path.name)
        if match:
            found.append((int(match.group(1)), path))
    normalised = any(folder.glob("ckpt_vecnormalize_*_steps.pkl"))
    for steps, path in sorted(found, reverse=True):
        stats = folder / f"ckpt_vecnormalize_{steps}_steps.pkl"
        buffer = folder / f"ckpt_replay_buffer_{steps}_steps.pkl"
        if (
            _whole_zip(path)
            and (not normalised or _whole_pickle(stats))
            and (not buffer.exists() or _whole_pickle(buffer))
        ):
            return steps, path
    return None


def _whole_zip(path: Path) -> bool:
    """True when ``path`` is a whole SB3 model archive: it ends with a zip's end-of-central-directory record
    (SB3 writes no comment) and its directory lists SB3's ``data``. Opening is not enough: SB3 stores its
    ``.pth`` files uncompressed and they are zip archives themselves, so a model cut short where one of them
    ends, or after it, opens as that inner archive (``zipfile`` looks back for the last such record)."""
    try:
        with path.open("rb") as stream:
            stream.seek(-22, os.SEEK_END)
            end = stream.read(22)
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except (OSError, zipfile.BadZipFile):  # missing, shorter than the record, or no archive
        return False
    return end[:4] == b"PK\x05\x06" and end[20:] == b"\x00\x00" and "data" in names


def _whole_pickle(path: Path) -> bool:
    """True when ``path`` starts like a pickle of protocol 2 or later (SB3 and ``VecNormalize`` write those)
    and ends with its STOP opcode: a cheap check, without unpickling a replay buffer of megabytes, that
    passes over an empty or truncated file."""
    try:
        with path.open("rb") as stream:
            head = stream.read(2)
            stream.seek(-1, os.SEEK_END)
            return head[:1] == pickle.PROTO and head[1:] >= b"\x02" and stream.read(1) == pickle.STOP
    except OSError:  # missing, or shorter than the seek
        return False


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
        "restore it, or give --overwrite to delete the run and train afresh, or choose another --out"
    )


def evaluation_log_problem(out: Path) -> str | None:
    """Why ``out``'s validation log ``eval/evaluations.npz`` cannot carry over to a resumed run, or None
    (no log, or a readable one; :func:`agents.folders.read_evaluation_log`)."""
    log = out / "eval" / "evaluations.npz"
    if not log.exists() or _latest_checkpoint(out / "checkpoints") is None:
        return None  # nothing to resume from
    try:
        read_evaluation_log(log)
    except ValueError as error:
        return (
            f"--out {out}: {error}; a resumed run continues its validation history from it: restore it, "
            "delete it (the history before the checkpoint is lost), or give --overwrite to train afresh"
        )
    return None


def has_progress(out: Path) -> bool:
    """True when ``out`` holds more than a failed attempt's ``config.yml``: a checkpoint, a model or a
    result (an attempt that failed before its first checkpoint left nothing to continue)."""
    return (
        (out / "result.json").exists()
        or (out / "model.zip").exists()
        or _latest_checkpoint(out / "checkpoints") is not None
    )


def run_identity(
    env_id: str,
    env_kwargs: dict[str, Any],
    settings: dict[str, Any],
    algo: str,
    seed: int,
    hp: dict[str, Any],
    init_from: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """What ``config.yml`` records of a run and a rerun must match (``settings``: the env's resolved
    defaults, so a changed env default is a different run; ``init_from``: the source of a fine-tuned run,
    :meth:`agents.init_from.InitSource.identity`, None for a run from scratch)."""
    return {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "env_settings": settings,
        "algo": algo,
        "seed": seed,
        "hyperparams": hp,
        "init_from": init_from,
    }


def run_conflict(out: Path, identity: dict[str, Any]) -> str | None:
    """Why ``out`` cannot take the run ``identity``, or None: its ``config.yml`` records another run
    that made progress (:func:`has_progress`). A ``config.yml`` left by an attempt that failed before
    its first checkpoint is replaced; an unreadable one with progress is refused, naming it."""
    config_file = out / "config.yml"
    if not config_file.exists() or not has_progress(out):
        return None
    try:
        old = yaml.safe_load(config_file.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        return f"--out {out}: its config.yml cannot be read ({error}); choose another --out"
    if not isinstance(old, dict):
        return f"--out {out}: its config.yml is not a run's configuration; choose another --out"

    def comparable(record: dict[str, Any]) -> dict[str, Any]:
        kept = {k: record.get(k) for k in identity}
        kept["init_from"] = resolved(record.get("init_from"))  # a path spelled otherwise is the same source
        hyperparams = {k: v for k, v in (record.get("hyperparams") or {}).items() if k != "n_timesteps"}
        policy_kwargs = hyperparams.get("policy_kwargs")
        if isinstance(policy_kwargs, dict) and policy_kwargs.get("use_sde") is False:
            # Recorded by runs made before train_run deep-copied its hyperparameters: SAC wrote its
            # default ``use_sde=False`` into the shared ``policy_kwargs``. False is the default, so the
            # run is the same.
            hyperparams["policy_kwargs"] = {k: v for k, v in policy_kwargs.items() if k != "use_sde"}
        kept["hyperparams"] = hyperparams
        return kept

    if comparable(old) != comparable(identity):
        mine, theirs = comparable(old), comparable(identity)
        differing = [k for k in identity if mine[k] != theirs[k]]
        if "hyperparams" in differing:
            a, b = mine["hyperparams"], theirs["hyperparams"]
            names = sorted(k for k in set(a) | set(b) if a.get(k, ...) != b.get(k, ...))
            differing[differing.index("hyperparams")] = f"hyperparams ({', '.join(names)})"
        return (
            f"--out {out} holds a different run (config.yml differs in {', '.join(differing)}); choose "
            "another --out, or give --overwrite to delete that run"
        )
    try:
        longer = int((old.get("hyperparams") or {}).get("n_timesteps", 0))
    except (TypeError, ValueError):
        longer = 0
    wanted = identity.get("hyperparams", {}).get("n_timesteps")
    if wanted is not None and longer > int(wanted):
        return (
            f"--out {out} holds a run of {longer} steps, longer than the {wanted} requested (a rerun "
            "continues a run, or makes it longer); choose another --out, or give --overwrite"
        )
    return None


RUN_LEGACY = ("config.yml", "model.zip")
"""Files of a run folder that ``agents.train`` wrote before manifests (``result.json`` is no marker:
``sim run`` writes one too)."""


def manifest_identity(
    env_id: str,
    env_kwargs: dict[str, Any],
    algo: str,
    hp: dict[str, Any],
    seed: int | None,
    init_from: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The identity in a training folder's manifest: a run folder's (``seed`` an integer) or a ``--seeds``
    folder's (``seed`` None: the seeds are not part of it, so that a study takes more of them); the
    hyperparameters by name; ``init_from`` (only where given): a fine-tuned run's source (a run folder:
    :meth:`agents.init_from.InitSource.identity`; a ``--seeds`` folder: the source's path and layout)."""
    identity: dict[str, Any] = {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "algo": algo,
        "layout": "one run" if seed is not None else "a run per seed, OUT/seed<k>",
    }
    if seed is not None:
        identity["seed"] = seed
    if init_from is not None:
        identity["init_from"] = init_from
    clash = sorted(set(identity) & set(hp))
    if clash:  # not a hyperparameter name (check_hyperparameters refuses unknown keys)
        raise ValueError(f"hyperparameters named like identity keys: {clash}")
    return {**identity, **hp}


def compare_identities(saved: Mapping[str, Any], requested: Mapping[str, Any]) -> list[str]:
    """The identity keys that forbid continuing a training folder: every difference, except a larger
    ``n_timesteps`` (a longer run continues from its last checkpoint)."""
    a, b = normalise(saved), normalise(requested)
    for side in (a, b):
        if "init_from" in side:
            side["init_from"] = resolved(side["init_from"])
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    try:
        longer = "n_timesteps" in keys and int(b["n_timesteps"]) > int(a["n_timesteps"])
    except (KeyError, TypeError, ValueError):
        longer = False
    return [k for k in keys if not (k == "n_timesteps" and longer)]


def _json_number(value: float) -> float | None:
    """``value``, or None (JSON null) when it is not finite (``-inf``: no validation yet)."""
    return value if math.isfinite(value) else None


def train_run(payload: dict[str, Any]) -> dict[str, Any]:
    """Train one seed into ``payload["out"]`` (a task; see the module docstring). Returns ``result.json``."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from agents.callbacks import (
        AtomicEvalCallback,
        NewestBufferCheckpointCallback,
        PhysicsLoggerCallback,
        ProgressLineCallback,
        StopOnSignalCallback,
    )
    from agents.rollout import make_env, make_monitored_env

    torch.set_num_threads(1)
    out = Path(payload["out"])
    env_id, algo, seed = payload["env_id"], payload["algo"], int(payload["seed"])
    env_kwargs = dict(payload["env_kwargs"])
    # A deep copy: SB3's off-policy algorithms write ``use_sde`` into the ``policy_kwargs`` they are
    # given, and the seeds of one command share the payload's nested dicts, so without it every seed
    # after the first recorded an extra key (see ``run_conflict``).
    hp = copy.deepcopy(payload["hyperparams"])
    progress = bool(payload.get("progress", True))
    probe = make_env(env_id, {**env_kwargs, "progress": progress})  # settings now, start states below
    settings = probe.unwrapped.settings()  # type: ignore[attr-defined]
    init = payload.get("init_from")  # a fine-tuned run's source (agents.init_from), or None
    identity = run_identity(env_id, env_kwargs, settings, algo, seed, hp, init and init["identity"])
    config_file = out / "config.yml"
    conflict = run_conflict(out, identity)
    if conflict is not None:  # main() refuses this before any task starts
        probe.close()
        raise FileExistsError(conflict)
    if config_file.exists() and has_progress(out):
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
    write_text_atomic(config_file, yaml.safe_dump({**identity, "versions": versions()}, sort_keys=False))
    write_text_atomic(out / "command.txt", payload["command"] + "\n")

    total = int(hp.pop("n_timesteps"))
    n_envs = int(hp.pop("n_envs"))
    policy = hp.pop("policy")
    normalize = bool(hp.pop("normalize"))
    eval_freq = int(hp.pop("eval_freq"))
    checkpoint_freq = int(hp.pop("checkpoint_freq"))

    # the envs step in n_envs processes unless this process may not start any (a daemonic worker); the
    # missing start states are pre-sheared in as many (a surrogate env has no start-state library)
    subprocess_envs = n_envs > 1 and can_start_subprocesses()
    library_of = getattr(probe.unwrapped, "library", None)
    library_key = None
    if callable(library_of):
        library = library_of()
        library.ensure(["train", "validation"], progress=progress, workers=n_envs if subprocess_envs else 1)
        library_key = library.key
    n_validation = probe.unwrapped.split_sizes["validation"]  # type: ignore[attr-defined]
    probe.close()

    quiet = {**env_kwargs, "progress": False}
    checkpoints = out / "checkpoints"
    latest = _latest_checkpoint(checkpoints)
    vec_cls = SubprocVecEnv if subprocess_envs else DummyVecEnv
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
        if init is not None and normalize:
            # the source's statistics, updated from here on (agents.init_from: "What is carried over")
            env = VecNormalize.load(init["vecnormalize"], venv)
            env.training, env.gamma = True, gamma
        else:
            env = VecNormalize(venv, gamma=gamma) if normalize else venv
        model = algo_cls(
            policy, env, seed=seed, device="cpu", tensorboard_log=str(out / "tb"), verbose=0, **hp
        )
        if init is not None:  # the source's policy in a model of the target's hyperparameters
            load_policy(model, init["model"])
    eval_env: Any = (
        VecNormalize(eval_venv, training=False, norm_reward=False, gamma=gamma) if normalize else eval_venv
    )
    checkpointer = NewestBufferCheckpointCallback(
        save_freq=max(checkpoint_freq // n_envs, 1),
        save_path=str(checkpoints),
        name_prefix="ckpt",
        save_vecnormalize=normalize,
        save_replay_buffer=algo == "sac",
    )
    stopper = StopOnSignalCallback(checkpointer)
    callbacks = CallbackList(
        [
            checkpointer,
            AtomicEvalCallback(
                eval_env,
                out / "eval",
                seed=seed + EVAL_SEED_OFFSET,
                n_eval_episodes=n_validation,
                eval_freq=max(eval_freq // n_envs, 1),
                deterministic=True,
                verbose=0,
            ),
            PhysicsLoggerCallback(),
            stopper,
            # without a progress bar, a line per checkpoint on stderr (a study's log shows where it is)
            *([] if progress else [ProgressLineCallback(f"{algo} seed {seed}", total, checkpoint_freq)]),
        ]
    )
    if latest is not None:
        _restore_eval_history(callbacks.callbacks[1], out / "eval" / "evaluations.npz", steps_done)
        # SB3's callbacks count their calls from 0 at every learn(), and validate and checkpoint when the
        # count is a multiple of their period: without this, a run resumed at step S (a SIGTERM
        # checkpoint, or one every 1000 steps against validation every 5000) validates at S + 5000,
        # S + 10000, ... instead of at 5000, 10000, and may miss its last validation.
        for callback in (callbacks, *callbacks.callbacks):
            callback.n_calls = steps_done // n_envs
    tic = time.perf_counter()
    remaining = max(total - steps_done, 0)
    # SIGTERM (e.g. `pkill -TERM -f agents.train`) stops at the next step with a checkpoint there.
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, stopper.request)
    try:
        if remaining:
            model.learn(
                total_timesteps=remaining,
                callback=callbacks,
                progress_bar=progress,
                reset_num_timesteps=latest is None,
                tb_log_name="run",
            )
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if stopper.stopped_at is not None:
        env.close()
        eval_env.close()
        print(
            f"{PROG}: {out} stopped by SIGTERM at step {stopper.stopped_at} of {total}; its checkpoint is "
            "saved: rerun the same command to resume",
            file=sys.stderr,
        )
        raise SystemExit(128 + signal.SIGTERM)
    wall = time.perf_counter() - tic
    if normalize:  # the statistics first: a model.zip beside a missing vecnormalize.pkl is never seen
        save_atomic(env.save, out / "vecnormalize.pkl")
    save_atomic(model.save, out / "model.zip")
    eval_cb = callbacks.callbacks[1]
    result = {
        "env_id": env_id,
        "algo": algo,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "resumed_from": steps_done,
        "wall_seconds": wall,
        "env_steps_per_second": _json_number(remaining / wall if wall > 0 else math.nan),
        # null until a validation has run (SB3 starts them at -inf): result.json stays valid JSON
        "best_validation_return": _json_number(float(getattr(eval_cb, "best_mean_reward", math.nan))),
        "last_validation_return": _json_number(float(getattr(eval_cb, "last_mean_reward", math.nan))),
        "library_key": library_key,  # None for a surrogate env (no start-state library)
        "init_from": init and init["identity"],
    }
    env.close()
    eval_env.close()
    write_text_atomic(out / "result.json", json.dumps(result, indent=1, allow_nan=False))
    return result


def _restore_eval_history(callback: Any, log: Path, steps_done: int) -> None:
    """A resumed run keeps its validation history and best return (SB3's EvalCallback starts empty,
    so it would overwrite ``evaluations.npz`` with the new evaluations only and take the first of them
    as the best model). Evaluations after the checkpoint resumed from are dropped: they are redone."""
    if not log.exists():
        return
    data = read_evaluation_log(log)  # main() refuses a bad log first (evaluation_log_problem)
    keep = data["timesteps"] <= steps_done
    callback.evaluations_timesteps = [int(t) for t in data["timesteps"][keep]]
    callback.evaluations_results = [list(map(float, r)) for r in data["results"][keep]]
    callback.evaluations_length = [list(map(int, n)) for n in data["ep_lengths"][keep]]
    if callback.evaluations_results:
        callback.best_mean_reward = max(float(np.mean(r)) for r in callback.evaluations_results)


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["gamma=0.9", "policy_kwargs={net_arch: [8]}"]`` -> values parsed as YAML (a later ``key=value``
    overrides an earlier one: ``--hyperparams $SHORT eval_freq=1000``); exit 2 naming an item that is not
    ``key=value`` or whose value is not YAML."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            usage_error(PROG, f"--hyperparams takes key=value, got {item!r}")
        key, value = item.split("=", 1)
        key = key.strip()
        if not key:
            usage_error(PROG, f"--hyperparams takes key=value, got {item!r} (no key)")
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError as error:
            problem = " ".join(str(getattr(error, "problem", None) or error).split())
            usage_error(PROG, f"--hyperparams {item!r}: the value is not YAML ({problem})")
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--env", required=True, help="environment id, e.g. dipenv/FieldMagnitude-v0")
    parser.add_argument("--algo", default="ppo", choices=ALGOS)
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument(
        "--seed", type=integer_at_least(0), default=None, help="one training seed >= 0; OUT is the run folder"
    )
    seeds.add_argument(
        "--seeds", type=seed_list, default=None, help="several seeds (0-4, 0,2,5); runs go to OUT/seed<k>"
    )
    parser.add_argument("--out", required=True, type=directory)
    parser.add_argument(
        "--timesteps", type=integer_at_least(1), default=None, help="override n_timesteps, >= 1"
    )
    parser.add_argument("--n-envs", type=integer_at_least(1), default=None, help="override n_envs, >= 1")
    parser.add_argument(
        "--hyperparams",
        nargs="*",
        action="extend",
        default=[],
        help="key=value overrides (YAML values; a later key=value overrides an earlier one, and every "
        "--hyperparams option counts)",
    )
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of extra environment arguments")
    parser.add_argument(
        "--workers", type=integer_at_least(1), default=1, help="trainings at once on the local pool, >= 1"
    )
    parser.add_argument(
        "--scheduler",
        type=scheduler_address,
        default=None,
        help="Dask scheduler address, tcp://HOST:PORT (instead of local workers)",
    )
    parser.add_argument(
        "--init-from",
        type=Path,
        default=None,
        metavar="RUN_OR_MODEL",
        help="start from a trained policy (and its VecNormalize statistics, which keep updating): a model "
        ".zip, a run folder, or a --seeds study folder (seed k from RUN_OR_MODEL/seed<k>); the target's "
        "hyperparameters apply (agents.init_from)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_folder_options(parser)
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
    except HyperparameterError as error:
        usage_error(PROG, str(error))
    except ValueError as error:
        usage_error(PROG, f"--env/--algo: {error}")
    env_kwargs = json_object(PROG, "--env-kwargs", args.env_kwargs)
    output_directory(PROG, args.out)
    probe = checked_env(PROG, args.env, env_kwargs, progress=False)  # bad values now, not after set-up
    settings = probe.unwrapped.settings()
    problem = model_problem(args.algo, probe, hp)
    if problem is not None:
        probe.close()
        source = "--hyperparams" if overrides else f"hyperparameter file {hyperparameter_file(args.algo)}"
        usage_error(PROG, f"{source}: {args.algo} cannot be built with these hyperparameters ({problem})")
    words = command_line("agents.train", argv)
    command = " ".join(words)
    if args.seeds is not None:
        seeds = args.seeds
        outs = [args.out / f"seed{s}" for s in seeds]
    else:
        seeds = [0 if args.seed is None else args.seed]
        outs = [args.out]
    inits: list[dict[str, Any] | None] = [None] * len(seeds)
    if args.init_from is not None:  # the source of each seed, checked against the env and hyperparameters
        try:
            sources = resolve_sources(args.init_from, seeds)
        except ValueError as error:
            probe.close()
            usage_error(PROG, str(error))
        for given in {given.model: given for given in sources}.values():
            problem = source_problem(given, args.algo, probe, args.env, settings, hp)
            if problem is not None:
                probe.close()
                usage_error(PROG, problem)
        inits = [source.payload() for source in sources]
    probe.close()
    if not args.overwrite:  # the run folders' own files (an adopted pre-manifest run, or a resumed one)
        for seed, out in zip(seeds, outs, strict=True):
            init = inits[seeds.index(seed)]
            problem = (
                missing_normalisation(out, hp)
                or run_conflict(
                    out,
                    run_identity(
                        args.env, env_kwargs, settings, args.algo, seed, hp, init and init["identity"]
                    ),
                )
                or evaluation_log_problem(out)
            )
            if problem is not None:
                usage_error(PROG, problem)
    claim = functools.partial(claim_out, PROG, argv=words, compare=compare_identities)
    if args.seeds is not None:
        group = [str(p.relative_to(args.out)) for p in sorted(args.out.glob("seed*/config.yml"))]
        study_init = None
        if args.init_from is not None:
            study_init = {"source": os.path.normpath(str(args.init_from)), "layout": layout(args.init_from)}
        claim(
            args.out,
            "agents.train",
            manifest_identity(args.env, env_kwargs, args.algo, hp, None, study_init),
            resume=args.resume,
            overwrite=args.overwrite,
            legacy=group,
        )
        for seed, out, init in zip(seeds, outs, inits, strict=True):
            identity = manifest_identity(args.env, env_kwargs, args.algo, hp, seed, init and init["identity"])
            claim(out, "agents.train", identity, legacy=legacy_markers(out, RUN_LEGACY))
    else:
        init = inits[0]
        identity = manifest_identity(args.env, env_kwargs, args.algo, hp, seeds[0], init and init["identity"])
        legacy = legacy_markers(args.out, RUN_LEGACY)
        claim(args.out, "agents.train", identity, resume=args.resume, overwrite=args.overwrite, legacy=legacy)
    compile_notice(args.scheduler)
    payloads = [
        {
            "env_id": args.env,
            "env_kwargs": env_kwargs,
            "algo": args.algo,
            "seed": s,
            "hyperparams": hp,
            "init_from": init,
            "out": str(o),
            "command": command,
            "progress": not args.no_progress and len(seeds) == 1,
        }
        for s, o, init in zip(seeds, outs, inits, strict=True)
    ]
    results = run_tasks(train_run, payloads, workers=args.workers, scheduler=args.scheduler)
    for r in results:
        print(
            f"{r['algo']} seed {r['seed']}: {r['timesteps']} steps, {r['wall_seconds']:.0f} s, "
            + (
                f"best validation return {best:.2f}"
                if (best := r["best_validation_return"]) is not None
                else "no validation yet (eval_freq is beyond the run)"
            )
        )
    return results


if __name__ == "__main__":
    main()
