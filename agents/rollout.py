"""One evaluation path for learned and open-loop policies: make the env, run an episode, summarise it.

Episode metrics (all control intervals have the same strain, so plain means over steps are time
averages):

* ``eta_second_half``: time-averaged ``eta_r`` over the second half of the episode (steady state);
* ``energy_second_half``: time-averaged field energy ``<eps E0^2> = <1/Mn>`` over the same half (units
  eta gammadot; the field energy per unit volume per unit strain);
* ``energy_mean``: the same over the whole episode; ``return``: the undiscounted sum of rewards.

Episodes of the thickening-control environments (``info`` holds ``eta_cap``; the rate follows a schedule,
so there is no steady half) add whole-episode metrics:

* ``time_above_cap``: fraction of the intervals whose ``eta_r`` exceeds ``eta_cap``;
* ``excess_viscosity``: time-averaged ``max(0, eta_r - eta_cap)`` (the thickening penalty per unit time);
* ``eta_mean``: time-averaged ``eta_r``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

Policy = Callable[[np.ndarray], np.ndarray]


def make_env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)`` after registering the dipenv ids (picklable with a partial).
    The argument ``residual`` is no env's: it wraps the env so that its actions are corrections to a
    controller's (:mod:`agents.residual`)."""
    import dipenv  # noqa: F401  (registers the ids)
    from agents.residual import RESIDUAL_KEY, residual_env

    kwargs = dict(env_kwargs or {})
    residual = kwargs.pop(RESIDUAL_KEY, None)
    env = gym.make(env_id, **kwargs)
    return env if residual is None else residual_env(env, residual)


def statistics_file(config: dict[str, Any], stats_file: Path) -> Path | None:
    """The ``VecNormalize`` statistics a trained run's policy is played with: ``stats_file`` when the run's
    ``config.yml`` (``config``) normalised its observations (a config without the setting: when the file
    exists), else None."""
    normalize = bool((config.get("hyperparams") or {}).get("normalize", stats_file.exists()))
    return stats_file if normalize else None


def trained_policy(
    algo: str, model_file: str | Path, stats_file: str | Path | None, deterministic: bool = True
) -> Callable[[np.ndarray], np.ndarray]:
    """A trained SB3 policy (``algo`` ppo or sac) as ``obs -> action``: the observation normalised by the
    ``VecNormalize`` statistics in ``stats_file`` (frozen; None: raw), then the model's mean action
    (``deterministic``) or a sample of its policy."""
    from stable_baselines3 import PPO, SAC

    model = (PPO if algo == "ppo" else SAC).load(str(model_file), device="cpu")
    normaliser = None
    if stats_file is not None:
        import pickle

        with open(stats_file, "rb") as handle:
            normaliser = pickle.load(handle)
        normaliser.training = False

    def policy(obs: np.ndarray) -> np.ndarray:
        x = normaliser.normalize_obs(obs) if normaliser is not None else obs
        return np.asarray(model.predict(x, deterministic=deterministic)[0])

    return policy


def record_episodes(path: str | Path) -> list[dict[str, Any]]:
    """The ``episodes`` of a stored point or run record (``agents.open_loop``, ``agents.controllers``,
    ``agents.evaluate``: each with its ``trace``); ``ValueError`` naming the file when it is not JSON or
    holds no such list."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable JSON record ({exc})") from None
    episodes = data.get("episodes") if isinstance(data, dict) else None
    if not isinstance(episodes, list) or not all(
        isinstance(e, dict) and isinstance(e.get("trace"), dict) for e in episodes
    ):
        raise ValueError(f"{path}: holds no list of episodes with traces (a point or run record)")
    return episodes


def library_key(unwrapped: Any) -> str | None:
    """The start-state library key of an unwrapped env, or None for an env without a library (the
    surrogate envs draw their start frames from their model's data)."""
    library = getattr(unwrapped, "library", None)
    return library().key if callable(library) else None


def make_monitored_env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> gym.Env:
    """:func:`make_env` wrapped in SB3's ``Monitor`` (episode returns and lengths for evaluation)."""
    from stable_baselines3.common.monitor import Monitor

    return Monitor(make_env(env_id, env_kwargs))


@dataclass
class EpisodeTrace:
    """Per-step record of one episode (strain since its start, at the end of each interval)."""

    split: str
    index: int
    realisation: int = 0
    strain: list[float] = field(default_factory=list)
    action: list[list[float]] = field(default_factory=list)
    mason_number: list[float] = field(default_factory=list)
    field_energy: list[float] = field(default_factory=list)
    eta_r: list[float] = field(default_factory=list)
    n1: list[float] = field(default_factory=list)
    n2: list[float] = field(default_factory=list)
    reward: list[float] = field(default_factory=list)
    time: list[float] = field(default_factory=list)
    shear_rate: list[float] = field(default_factory=list)
    eta_cap: float = math.nan
    failed: bool = False
    library_key: str = ""

    def summary(self) -> dict[str, Any]:
        """The episode metrics of the module docstring (NaN where the episode failed first)."""
        n = len(self.eta_r)
        half = slice(n // 2, n)
        ok = n > 0 and not self.failed
        out = {
            "split": self.split,
            "index": self.index,
            "realisation": self.realisation,
            "steps": n,
            "failed": self.failed,
            "eta_second_half": float(np.mean(self.eta_r[half])) if ok else math.nan,
            "energy_second_half": float(np.mean(self.field_energy[half])) if ok else math.nan,
            "energy_mean": float(np.mean(self.field_energy)) if ok else math.nan,
            "return": float(np.sum(self.reward)),
        }
        if math.isfinite(self.eta_cap):
            eta = np.asarray(self.eta_r, dtype=float)
            out["time_above_cap"] = float(np.mean(eta > self.eta_cap)) if ok else math.nan
            out["excess_viscosity"] = float(np.mean(np.maximum(eta - self.eta_cap, 0.0))) if ok else math.nan
            out["eta_mean"] = float(np.mean(eta)) if ok else math.nan
        return out

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["mason_number"] = [m if math.isfinite(m) else "inf" for m in self.mason_number]
        return out


def run_episode(
    env: gym.Env,
    policy: Policy,
    split: str,
    index: int,
    seed: int = 0,
    realisation: int = 0,
    schedule: Any = None,
) -> EpisodeTrace:
    """Run ``policy`` from start state ``index`` of ``split`` until the episode ends (a policy with a
    ``reset()`` method, such as a feedback controller of :mod:`agents.controllers`, is reset first).
    ``realisation`` > 0 starts from that state moved by 1e-9 a (:mod:`dipenv.realisations`): an
    independent repeat of the same episode. ``schedule`` (the thickening-control envs only: ``{"times":
    [...], "rates": [...]}``) replaces the split's schedule ``index`` (:mod:`agents.schedules`)."""
    options: dict[str, Any] = {"split": split, "index": index}
    if realisation:
        options["realisation"] = realisation
    if schedule is not None:
        options["schedule"] = schedule
    obs, info = env.reset(seed=seed, options=options)
    trace = EpisodeTrace(
        split=split, index=index, realisation=realisation, library_key=str(info.get("library_key", ""))
    )
    trace.eta_cap = float(info.get("eta_cap", math.nan))
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset()
    done = False
    while not done:
        action = np.asarray(policy(obs), dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        if info.get("simulation_failed"):
            trace.failed = True
            trace.reward.append(float(reward))
            break
        trace.strain.append(float(info["strain"]))
        trace.action.append([float(a) for a in action.reshape(-1)])
        trace.mason_number.append(float(info["mason_number"]))
        trace.field_energy.append(float(info["field_energy"]))
        trace.eta_r.append(float(info["eta_r"]))
        trace.n1.append(float(info["n1"]))
        trace.n2.append(float(info["n2"]))
        trace.reward.append(float(reward))
        if "eta_cap" in info:  # the thickening-control environments
            trace.time.append(float(info["time"]))
            trace.shear_rate.append(float(info["shear_rate"]))
    return trace


def constant_policy(action: Sequence[float]) -> Policy:
    """A policy that always returns ``action``."""
    fixed = np.asarray(action, dtype=np.float32)
    return lambda obs: fixed
