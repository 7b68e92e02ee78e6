"""Where a fine-tuned training run starts: ``agents.train --init-from RUN_OR_MODEL`` (issue 43).

A run started with ``--init-from`` begins with the policy of another run (for example one pretrained on
``dipenv/ThickeningControlSurrogate-v0``) and trains it on ``--env`` (for example
``dipenv/ThickeningControl-v2``) with ``--env``'s hyperparameters. What ``RUN_OR_MODEL`` may be, and which
model each seed takes (:func:`resolve_sources`):

* a model file ``*.zip``: every seed starts from it (``RUN/model.zip``, a checkpoint
  ``RUN/checkpoints/ckpt_<N>_steps.zip``, ``RUN/eval/best_model.zip``);
* a run folder (it holds ``model.zip`` or ``config.yml``, as ``agents.train --seed`` writes it): every seed
  starts from its ``model.zip`` (the run must have finished);
* a study folder (``agents.train --seeds`` writes ``OUT/seed<k>``): seed ``k`` starts from
  ``RUN_OR_MODEL/seed<k>/model.zip``, so ``--seeds 0-4 --init-from DIR`` pairs the seeds one to one; a seed
  without its folder is refused, naming it.

**What is carried over.** The policy's parameters (PPO: the actor, the critic and the action noise's
``log_std``; SAC: the actor and both critics with their targets), loaded into a model built afresh with the
target's hyperparameters: ``learning_rate`` (and any schedule), ``n_steps``, ``clip_range``, the entropy
coefficient and the rest are ``--env``'s entry in ``agents/hyperparams/<algo>.yml`` with ``--hyperparams``
over it, never the source's. The optimiser starts afresh (Adam's moments of the source's last updates
belong to its own loss), and so do SAC's replay buffer and entropy coefficient. The step count starts at
0: ``n_timesteps`` counts the fine-tuning steps only. When the source trained under ``VecNormalize`` its
statistics (``vecnormalize.pkl`` beside ``model.zip``, ``ckpt_vecnormalize_<N>_steps.pkl`` beside a
checkpoint) are loaded and **keep updating** during fine-tuning (as RL Zoo's ``--trained-agent`` does): the
policy first sees observations scaled as in pretraining, and the running means then follow the new env's
observations, at the pace their sample count allows (a source of 10^6 steps moves little in 10^4).

**Checks** (exit 2 before the folder is claimed): the model reads as an SB3 model of ``--algo``'s policy;
its observation and action spaces equal ``--env``'s (the message names both), and so do the observation
frames' labels where the source's ``config.yml`` records them (a stress-only frame has the full frame's
shape); its parameters fit the policy the target hyperparameters build (``policy_kwargs``); the source's
normalisation matches the target's ``normalize`` (statistics present where it normalised).

**Identity.** The source's model path, run folder, seed, env id and the SHA-256 of its ``model.zip`` and
statistics join the run's identity (``manifest.json`` and ``config.yml``), so a rerun from another source
(another run, another seed, or the same run trained further) is refused; a ``--seeds`` folder records the
source's path and the layout.
"""

from __future__ import annotations

import copy
import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

LAYOUT_PER_SEED = "seed k from SOURCE/seed<k>"
LAYOUT_ONE = "every seed from one model"


@dataclass(frozen=True)
class InitSource:
    """The model a run starts from, with what its run folder records (None where unknown)."""

    model: Path
    vecnormalize: Path | None
    run: Path | None
    seed: int | None
    env_id: str | None
    algo: str | None
    normalize: bool | None
    observation: list[str] | None

    def identity(self) -> dict[str, Any]:
        """What joins a run's identity (paths as given, normalised; the files by their digests)."""
        return {
            "model": os.path.normpath(str(self.model)),
            "run": None if self.run is None else os.path.normpath(str(self.run)),
            "seed": self.seed,
            "env_id": self.env_id,
            "model_sha256": file_digest(self.model),
            "vecnormalize_sha256": None if self.vecnormalize is None else file_digest(self.vecnormalize),
        }

    def payload(self) -> dict[str, Any]:
        """What a training task needs (JSON-ready)."""
        return {
            "model": str(self.model),
            "vecnormalize": None if self.vecnormalize is None else str(self.vecnormalize),
            "identity": self.identity(),
        }


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, 16 hex digits."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:16]


def _is_run(folder: Path) -> bool:
    return (folder / "model.zip").exists() or (folder / "config.yml").exists()


def _config(run: Path | None) -> dict[str, Any]:
    if run is None:
        return {}
    try:
        record = yaml.safe_load((run / "config.yml").read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return {}
    return record if isinstance(record, dict) else {}


def _source(model: Path, stats: Path | None, run: Path | None) -> InitSource:
    record = _config(run)
    hyperparams = record.get("hyperparams") if isinstance(record.get("hyperparams"), dict) else {}
    settings = record.get("env_settings") if isinstance(record.get("env_settings"), dict) else {}
    seed = record.get("seed")
    normalize = hyperparams.get("normalize") if hyperparams else None
    observation = settings.get("observation") if settings else None
    return InitSource(
        model=model,
        vecnormalize=stats if stats is not None and stats.exists() else None,
        run=run,
        seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
        env_id=record.get("env_id") if isinstance(record.get("env_id"), str) else None,
        algo=record.get("algo") if isinstance(record.get("algo"), str) else None,
        normalize=normalize if isinstance(normalize, bool) else None,
        observation=[str(x) for x in observation] if isinstance(observation, list) else None,
    )


def _from_model_file(path: Path) -> InitSource:
    parent = path.parent
    run = parent if (parent / "config.yml").exists() else None
    if run is None and (parent.parent / "config.yml").exists():  # RUN/checkpoints/, RUN/eval/
        run = parent.parent
    stats = None
    if path.name == "model.zip":
        stats = parent / "vecnormalize.pkl"
    elif match := re.fullmatch(r"ckpt_(\d+)_steps\.zip", path.name):
        stats = parent / f"ckpt_vecnormalize_{match.group(1)}_steps.pkl"
    return _source(path, stats, run)


def _from_run(folder: Path) -> InitSource:
    model = folder / "model.zip"
    if not model.exists():
        raise ValueError(
            f"--init-from {folder}: the run holds no model.zip (has it finished?); give one of its "
            f"checkpoints, {folder / 'checkpoints' / 'ckpt_<N>_steps.zip'}"
        )
    return _source(model, folder / "vecnormalize.pkl", folder)


def layout(path: Path) -> str:
    """:data:`LAYOUT_PER_SEED` for a study folder (``seed<k>/`` inside), else :data:`LAYOUT_ONE`."""
    if path.is_dir() and not _is_run(path) and any(path.glob("seed*/")):
        return LAYOUT_PER_SEED
    return LAYOUT_ONE


def resolve_sources(path: Path, seeds: list[int]) -> list[InitSource]:
    """The source of each seed (see the module docstring); ``ValueError`` naming ``--init-from`` and
    what is missing."""
    if path.is_file():
        if path.suffix != ".zip":
            raise ValueError(f"--init-from {path}: a model file is a .zip (SB3's model.zip), got {path.name}")
        return [_from_model_file(path)] * len(seeds)
    if not path.is_dir():
        raise ValueError(f"--init-from {path}: no such model file or folder")
    if _is_run(path):
        return [_from_run(path)] * len(seeds)
    if layout(path) == LAYOUT_PER_SEED:
        missing = [f"seed{k}" for k in seeds if not _is_run(path / f"seed{k}")]
        if missing:
            held = sorted(p.name for p in path.glob("seed*/") if _is_run(p))
            raise ValueError(
                f"--init-from {path}: a study folder pairs seed k with {path}/seed<k>, and it has no run for "
                f"{', '.join(missing)} (it holds {', '.join(held) or 'none'})"
            )
        return [_from_run(path / f"seed{k}") for k in seeds]
    raise ValueError(
        f"--init-from {path}: neither a model .zip, a run folder (model.zip, config.yml) nor a study folder "
        "(seed<k>/ run folders)"
    )


def source_problem(
    source: InitSource, algo: str, env: Any, env_id: str, settings: dict[str, Any], hp: dict[str, Any]
) -> str | None:
    """Why a run of ``algo`` with hyperparameters ``hp`` on ``env`` (the id ``env_id``, its ``settings``)
    cannot start from ``source``, or None (the checks of the module docstring)."""
    import warnings

    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.save_util import load_from_zip_file

    where = f"--init-from {source.model}"
    try:
        data, params, _ = load_from_zip_file(source.model, device="cpu", print_system_info=False)
    except Exception as error:  # SB3 raises many kinds for a file that is no model
        return f"{where}: cannot be read as a Stable-Baselines3 model ({type(error).__name__}: {error})"
    if not isinstance(data, dict) or not isinstance(params, dict) or "policy" not in params:
        return f"{where}: not a Stable-Baselines3 model (no policy parameters)"
    if source.algo is not None and source.algo != algo:
        return f"{where}: the source was trained with {source.algo}, and --algo is {algo}"
    obs_space, action_space = data.get("observation_space"), data.get("action_space")
    if obs_space != env.observation_space or action_space != env.action_space:
        return (
            f"{where}: its spaces do not match --env {env_id}'s: observation space {obs_space} against "
            f"{env.observation_space}, action space {action_space} against {env.action_space}"
        )
    frame = settings.get("observation")
    if source.observation is not None and isinstance(frame, list) and source.observation != frame:
        return (
            f"{where}: its observation space {obs_space} matches --env {env_id}'s, but the frames differ: "
            f"{source.observation} (source {source.env_id}) against {frame}"
        )
    from agents.train import _TRAINING_KEYS

    algo_cls: Any = PPO if algo == "ppo" else SAC
    kwargs = {k: v for k, v in copy.deepcopy(hp).items() if k not in _TRAINING_KEYS}
    if algo == "sac":
        kwargs["buffer_size"] = min(int(kwargs.get("buffer_size", 1_000_000)), 64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = algo_cls(hp["policy"], env, seed=0, device="cpu", verbose=0, **kwargs)
    policy_class = data.get("policy_class")
    if isinstance(policy_class, type) and not isinstance(model.policy, policy_class):
        return (
            f"{where}: its policy is a {policy_class.__name__}, and {algo} builds a "
            f"{type(model.policy).__name__} (another algorithm?)"
        )
    stored: Any = params["policy"]  # a state dict (SB3 types the parameters' mapping loosely)
    target = {k: tuple(v.shape) for k, v in model.policy.state_dict().items()}
    given = {k: tuple(v.shape) for k, v in stored.items()}
    if target != given:
        differing = sorted(k for k in set(target) | set(given) if target.get(k) != given.get(k))
        shown = "; ".join(f"{k}: {given.get(k)} there, {target.get(k)} here" for k in differing[:3])
        return (
            f"{where}: its parameters do not fit the policy of the target hyperparameters (policy_kwargs "
            f"{hp.get('policy_kwargs')}): {shown}"
        )
    normalize = bool(hp.get("normalize"))
    normalised = source.normalize if source.normalize is not None else source.vecnormalize is not None
    if normalize and not normalised:
        return (
            f"{where}: the source trained without VecNormalize and the target normalises its observations; "
            "give --hyperparams normalize=false, or a source that normalised"
        )
    if normalize and source.vecnormalize is None:
        return (
            f"{where}: the source trained under VecNormalize, and its statistics are not beside the model "
            "(vecnormalize.pkl, or ckpt_vecnormalize_<N>_steps.pkl beside a checkpoint); give its run folder"
        )
    if not normalize and normalised:
        return (
            f"{where}: the source trained under VecNormalize and the target does not normalise "
            "(normalize: false); the policy would see unscaled observations"
        )
    return None


def load_policy(model: Any, path: str) -> None:
    """Copy the policy parameters of the SB3 model file ``path`` into ``model``'s policy (exactly)."""
    from stable_baselines3.common.save_util import load_from_zip_file

    _, params, _ = load_from_zip_file(path, device="cpu", load_data=False, print_system_info=False)
    model.policy.load_state_dict(params["policy"])


def resolved(value: Any) -> Any:
    """An ``init_from`` identity with its paths resolved (a relative and an absolute spelling of the same
    source compare equal)."""
    if not isinstance(value, dict):
        return value
    return {
        k: str(Path(v).resolve()) if k in ("model", "run", "source") and isinstance(v, str) else v
        for k, v in value.items()
    }


__all__ = [
    "LAYOUT_ONE",
    "LAYOUT_PER_SEED",
    "InitSource",
    "file_digest",
    "layout",
    "load_policy",
    "resolve_sources",
    "resolved",
    "source_problem",
]
