"""Model-predictive control of the thickening-control envs through the surrogate model (issue 43).

A classical model-based baseline beside the trained policies and the hand-built controllers of
:mod:`agents.controllers`: at every control interval :class:`MPCController` rolls the surrogate's ensemble
(:meth:`dipenv.surrogate.models.EnsembleModel.rollout`, the vectorised rollout) out over the next
``horizon`` intervals under ``candidates`` sequences of actions, scores each by the env's own reward
(``ThickeningPenaltyReward``: ``min(0, eta_cap - eta_r) - w_E / Mn_ref`` per interval, summed over the
horizon, averaged over ``samples`` model samples), and applies the first action of the best sequence. The
sequences are refined by the cross-entropy method (``iterations`` > 1; Rubinstein 1999, as in PETS, Chua
et al. 2018); ``iterations = 1`` is random shooting. Each interval's action is a mixture: off with
probability ``p_off`` (starts at 0.25, so that on/off patterns are tried), else a Gaussian in the action
coordinate ``u`` clipped to the on range ``[-0.9, 1]`` (starts at mean 0, sd 0.6); after each iteration the
``elites`` best sequences refit both, per interval. The previous decision's best sequence, shifted by one
interval, is candidate 0 of the next (a warm start).

**The model and the plant.** Bound to the surrogate env (``dipenv/ThickeningControlSurrogate-v0``), the
controller uses the env's own model (it knows the plant's dynamics, not its noise); bound to the simulator
(``dipenv/ThickeningControl-v2``) it uses the shipped surrogate (or ``model=PATH``) as its internal model
while the simulator is the plant. It needs the frame's dynamic part in the observation (``slog_eta_r``,
``slog_n1``, ``slog_n2`` and the microstructure, the ensemble's inputs): the stress-only ids are refused,
with a message naming what is missing. The model must be an ensemble (the lambda model's structure
variables are not in the frame, so its rollout cannot start mid-episode) fitted for the env's box and
interval.

**The rate schedule.** ``preview=False`` (default) holds the observed rate (``log10_shear_rate``, at the
end of the previous interval) over the horizon: the controller knows what the feed-forward, the pulse
controller and the trained policies know, so the rows compare like with like. ``preview=True`` reads the
episode's shear-rate schedule from the env instead (the thickening envs hold it from ``reset``:
``info["schedule"]``, and the simulator follows it), so the rollouts see the coming rates, including a jump
inside the horizon: the setting of a process whose rate programme is known in advance, an oracle none of
the other rows has.

**Determinism.** :meth:`MPCController.reset` (called after every ``env.reset``, as
:func:`agents.rollout.run_episode` does) reseeds the controller's generator from ``seed``; candidates and
model samples come from it, so the same seed and the same observations give the same actions.

**Cost.** One decision costs ``iterations`` rollouts of ``candidates x samples`` rows over ``horizon``
intervals (numpy, one core): about 10 ms per 2,000 row-intervals, so the default (64 x 4 x 8, 2
iterations) takes about 25 ms against about 1 s for a simulator step (``docs/surrogate.md``,
"MPC on the surrogate", has the measured numbers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


def _whole(name: str, value: float, low: int) -> int:
    """``value`` as an integer >= ``low`` (a grid gives floats: 8.0 is 8), else ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if value != int(value) or int(value) < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def episode_schedule(unwrapped: Any) -> Any:
    """The shear-rate schedule of the episode under way in a thickening-control env (simulator or
    surrogate: both keep it from ``reset``, where ``info["schedule"]`` reports it), or None."""
    schedule = getattr(unwrapped, "_schedule", None)
    return schedule if callable(schedule) else None


@dataclass
class MPCController:
    """Model-predictive control through the surrogate's ensemble (see the module docstring).

    Attributes:
        horizon: intervals looked ahead, >= 1 (cut at the episode's end).
        candidates: action sequences per iteration, >= 2.
        iterations: cross-entropy iterations, >= 1 (1: random shooting).
        samples: model samples per sequence, >= 1 (each draws an ensemble member and its noise).
        elites: sequences kept to refit the sampling distribution, in ``[1, candidates]`` (default:
            an eighth of the candidates, at least 1).
        seed: seed of the controller's generator (reseeded at every ``reset``).
        preview: read the episode's rate schedule from the env (an oracle; default: hold the observed rate).
        model: path of a surrogate model ``.npz``; default: the env's own model (surrogate env), else the
            shipped one.
    """

    horizon: int = 8
    candidates: int = 64
    iterations: int = 2
    samples: int = 4
    elites: int | None = None
    seed: int = 0
    preview: bool = False
    model: str | None = None

    def __post_init__(self) -> None:
        self.horizon = _whole("horizon", self.horizon, 1)
        self.candidates = _whole("candidates", self.candidates, 2)
        self.iterations = _whole("iterations", self.iterations, 1)
        self.samples = _whole("samples", self.samples, 1)
        elites = max(1, self.candidates // 8) if self.elites is None else self.elites
        self.elites = _whole("elites", elites, 1)
        self.seed = _whole("seed", self.seed, 0)
        if self.elites > self.candidates:
            raise ValueError(f"elites must be <= candidates ({self.candidates}), got {self.elites}")
        if not isinstance(self.preview, bool | int | float):
            raise ValueError(f"preview must be true or false, got {self.preview!r}")
        self.preview = bool(self.preview)
        self._unwrapped: Any = None
        self._surrogate: Any = None
        self._dynamic: np.ndarray = np.empty(0, dtype=np.int64)
        self._rate_index = -1
        self._rng = np.random.default_rng(self.seed)
        self._table: Any = None
        self._step = 0
        self._previous = math.inf
        self._plan: np.ndarray | None = None

    # -- set-up ---------------------------------------------------------------------------------------------
    def bind(self, env: Any) -> MPCController:
        """Read the env's observation layout, action map, reward and model; ``ValueError`` naming what is
        missing when the env cannot be controlled this way."""
        from dipenv.rewards import ThickeningPenaltyReward
        from dipenv.surrogate.features import DYNAMIC_LABELS
        from dipenv.surrogate.models import EnsembleModel, SurrogateModel, load_model

        unwrapped = env.unwrapped
        name = type(unwrapped).__name__
        labels = list(getattr(unwrapped, "observation_labels", []))
        missing = [label for label in DYNAMIC_LABELS if label not in labels]
        if missing:
            shown = ", ".join(label for label in labels if "[" not in label) or "no labels"
            raise ValueError(
                f"MPC needs the surrogate model's inputs in the observation, and that of {name} lacks "
                f"{', '.join(missing)} (it holds {shown}); the stress-only ids hide eta_r: use "
                "ThickeningControl-v2 or ThickeningControlSurrogate-v0"
            )
        for attribute in ("mapping", "reward_function", "control_interval", "episode_steps", "max_piece"):
            if not hasattr(unwrapped, attribute):
                raise ValueError(f"MPC needs a thickening-control env; {name} has no {attribute!r}")
        if not isinstance(unwrapped.reward_function, ThickeningPenaltyReward):
            raise ValueError(
                f"MPC scores with ThickeningPenaltyReward; {name}'s reward is "
                f"{type(unwrapped.reward_function).__name__}"
            )
        own = getattr(unwrapped, "model", None)
        if self.model is not None:
            surrogate = load_model(Path(self.model))
        elif isinstance(own, SurrogateModel):
            surrogate = own
        else:
            surrogate = load_model()
        if not isinstance(surrogate, EnsembleModel):
            raise ValueError(
                f"MPC rolls an ensemble out from the observed frame; the model is a {surrogate.kind!r} "
                "model, whose structure variables are not in the frame"
            )
        config = getattr(unwrapped, "base_config", unwrapped)
        physics = {
            "n_particles": getattr(config, "n_particles", None),
            "volume_fraction": getattr(config, "volume_fraction", None),
            "control_interval": unwrapped.control_interval,
        }
        for key, value in physics.items():
            fitted = surrogate.settings.get(key)
            if fitted is not None and value is not None and not math.isclose(float(fitted), float(value)):
                raise ValueError(
                    f"the surrogate model was fitted at {key}={fitted!r}, and {name} has {key}={value!r}: "
                    "its rollouts would not predict this env"
                )
        self._unwrapped = unwrapped
        self._surrogate = surrogate
        self._dynamic = np.array([labels.index(label) for label in DYNAMIC_LABELS])
        self._rate_index = labels.index("log10_shear_rate") if "log10_shear_rate" in labels else -1
        if not self.preview and self._rate_index < 0:
            raise ValueError(f"preview=False holds the observed rate, and {name} does not observe it")
        self.reset()
        return self

    def reset(self) -> None:
        """Start an episode (after ``env.reset``): reseed, and read the episode's schedule."""
        from dipenv.surrogate.features import interval_table

        self._rng = np.random.default_rng(self.seed)
        self._step = 0
        self._previous = math.inf
        self._plan = None
        self._table = None
        unwrapped = self._unwrapped
        if unwrapped is None:
            return
        schedule = episode_schedule(unwrapped) if self.preview else None
        if schedule is not None:
            self._table = interval_table(
                schedule, unwrapped.episode_steps, unwrapped.control_interval, unwrapped.max_piece
            )

    # -- one decision ---------------------------------------------------------------------------------------
    def _horizon_table(self, obs: np.ndarray, length: int) -> Any:
        import sim
        from dipenv.surrogate.features import interval_table

        if self._table is not None:
            return self._table.window(self._step, self._step + length)
        rate = 10.0 ** float(obs[self._rate_index])
        unwrapped = self._unwrapped
        return interval_table(sim.constant(rate), length, unwrapped.control_interval, unwrapped.max_piece)

    def _masons(self, u: np.ndarray) -> np.ndarray:
        mapping = self._unwrapped.mapping
        return np.vectorize(mapping.mason_number, otypes=[np.float64])(u)

    def scores(self, obs: np.ndarray, u: np.ndarray, table: Any) -> np.ndarray:
        """(N,) the mean return over ``samples`` model rollouts of the action sequences ``u`` (N, H) from
        the frame in ``obs`` over the intervals of ``table``."""
        from dipenv.surrogate.features import inverse_signed_log

        frame = np.asarray(obs, dtype=np.float64)[self._dynamic]
        masons = self._masons(u)
        n = u.shape[0]
        rollouts = self._surrogate.rollout(
            np.repeat(frame[None, :], n, axis=0),
            masons,
            [table] * n,
            self._rng,
            self.samples,
            previous=np.full(n, self._previous),
        )
        eta = inverse_signed_log(rollouts[..., 0])  # (N, samples, H)
        reward = self._unwrapped.reward_function
        energy = np.where(np.isfinite(masons), 1.0 / masons, 0.0)  # dipenv.actions.field_energy
        per_step = np.minimum(0.0, reward.target_viscosity - eta) - reward.energy_weight * energy[:, None, :]
        return np.asarray(per_step.sum(axis=2).mean(axis=1))

    def plan(self, obs: np.ndarray) -> np.ndarray:
        """The best action sequence (H,) from the observation ``obs`` (advances nothing)."""
        unwrapped = self._unwrapped
        if unwrapped is None:
            raise RuntimeError("bind(env) the controller before use")
        left = unwrapped.episode_steps - self._step
        if left <= 0:
            raise RuntimeError(
                f"the controller has acted {self._step} times in an episode of {unwrapped.episode_steps}: "
                "reset() it after env.reset()"
            )
        length = min(self.horizon, left)
        table = self._horizon_table(np.asarray(obs).reshape(-1), length)
        rng = self._rng
        threshold = unwrapped.mapping.off_threshold  # u below it: off; -0.9 in the thickening ids
        can_be_off = threshold > -1.0
        mean = np.zeros(length)
        sd = np.full(length, 0.6)
        p_off = np.full(length, 0.25 if can_be_off else 0.0)
        best_score, best = -math.inf, np.zeros(length)
        for _ in range(self.iterations):
            off = rng.random((self.candidates, length)) < p_off
            on = np.clip(mean + sd * rng.standard_normal((self.candidates, length)), threshold, 1.0)
            u = np.where(off, -1.0, on)
            if self._plan is not None:  # warm start: last decision's best, shifted by one interval
                shifted = self._plan[1 : length + 1]
                u[0, : shifted.size] = shifted
            score = self.scores(obs, u, table)
            order = np.argsort(-score, kind="stable")
            if score[order[0]] > best_score:
                best_score, best = float(score[order[0]]), u[order[0]].copy()
            elite = u[order[: self.elites]]
            elite_off = elite < threshold
            if can_be_off:
                p_off = np.clip(elite_off.mean(axis=0), 0.05, 0.95)
            for j in range(length):
                kept = elite[~elite_off[:, j], j]
                if kept.size:
                    mean[j] = kept.mean()
                    sd[j] = max(float(kept.std()), 0.05)
        return best

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        best = self.plan(obs)
        self._plan = best
        u = float(best[0])
        self._previous = self._unwrapped.mapping.mason_number(u)
        self._step += 1
        return np.array([u], dtype=np.float32)


__all__ = ["MPCController", "episode_schedule"]
