"""``ViscosityTrackingSurrogate``: the viscosity-tracking task with a fitted model in place of the simulator.

Spaces, schedules, targets, action map, direction convention and reward are those of
:class:`dipenv.envs.viscosity_tracking.ViscosityTrackingEnv`, reused from ``dipenv``; only the dynamics
differ: the next frame's dynamic part is sampled from a fitted ensemble that sees the field's direction
(:mod:`dipenv.surrogate.models`, the direction block of :mod:`dipenv.surrogate.features`;
``docs/surrogate.md#the-tracking-surrogate``). It mirrors how
:class:`dipenv.surrogate.env.ThickeningControlSurrogateEnv` wraps ``ThickeningControl``, and is built on it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

import sim
from dipenv.actions import canonical_direction, validate_action
from dipenv.envs.viscosity_tracking import (
    TRACKING_ENERGY_WEIGHT,
    field_orientation,
    tracking_direction,
    tracking_frame_features,
)
from dipenv.observations import ObservationFeature, signed_log
from dipenv.rewards import ViscosityTargetReward
from dipenv.surrogate.env import ThickeningControlSurrogateEnv
from dipenv.surrogate.features import N_DYNAMIC, Y_AXIS
from dipenv.surrogate.models import SurrogateModel, load_model
from dipenv.tracking import (
    TARGET_HOLD_RANGE,
    TARGET_PREVIEW,
    TARGET_RAMP_RANGE,
    TARGET_RANGE,
    check_tracking_arguments,
    draw_target,
    fixed_target,
    target_to_dict,
    validate_target,
)

DEFAULT_TRACKING_MODEL = "tracking_surrogate_v0.npz"
"""The tracking model shipped in ``dipenv/data/`` (fitted on 2026-12-07 on 100 ``ViscosityTracking-v0``
episodes; ``docs/surrogate.md#the-tracking-fit``)."""


def default_tracking_model_path() -> Path:
    """``dipenv/data/`` :data:`DEFAULT_TRACKING_MODEL`."""
    return Path(__file__).resolve().parent.parent / "data" / DEFAULT_TRACKING_MODEL


class ViscosityTrackingSurrogateEnv(ThickeningControlSurrogateEnv):
    """## Description

    :class:`dipenv.envs.viscosity_tracking.ViscosityTrackingEnv` with the simulator replaced by a fitted
    model of its trajectories (``docs/surrogate.md#the-tracking-surrogate``): each interval a
    direction-aware ensemble samples the next frame's ``eta_r``, ``N1``, ``N2`` and microstructure from the
    current frame, the field (strength and direction) of this and the previous interval and the interval's
    rates. Stochastic: one episode is one sample.

    ## Spaces, reward, schedules, targets

    As ``ViscosityTracking``: ``Box(-1, 1, (3,))`` ``[u, polar, azimuth]`` (strength through
    :class:`dipenv.actions.FieldStrengthMapping`, direction by
    :func:`dipenv.envs.viscosity_tracking.tracking_direction`); the observation frame of
    ``ViscosityTracking`` (21 entries: the dynamic part, the field's energy fraction, coordinate and
    direction, the rate, the target now, over the coming interval and ``target_preview`` ahead;
    ``history_length`` stacks frames); the reward ``-(|eta_r - target| + w_E / Mn_ref)`` per interval
    (:class:`dipenv.rewards.ViscosityTargetReward` at the interval's mean target, on the model's interval
    ``eta_r``). A training reset draws the start index, the rate schedule and then the target with
    ``self.np_random``, as the simulator env does (the same seed gives the same index, schedule and
    target); the validation, test and fresh splits use the simulator env's fixed schedules and targets;
    ``options`` ``schedule`` and ``target`` run your own.

    ## Starting State

    As :class:`dipenv.surrogate.env.ThickeningControlSurrogateEnv` (a data episode's first frame, field off
    along ``y``).

    ## Arguments

    ``model``: a model ``.npz`` fitted on tracking data (``direction_inputs``; default
    ``dipenv/data/`` :data:`DEFAULT_TRACKING_MODEL`, the shipped model); the others as
    ``ViscosityTrackingEnv`` (``eta_cap`` refused; ``n_particles``, ``volume_fraction`` and
    ``control_interval`` must be the model's data's); simulator-only arguments are ignored.

    ## Version History

    * v0: issue 44's second fidelity of ``ViscosityTracking-v0``.
    """

    reset_options: ClassVar[tuple[str, ...]] = (*ThickeningControlSurrogateEnv.reset_options, "target")

    def __init__(
        self,
        model: str | Path | SurrogateModel | None = None,
        *,
        target_range: tuple[float, float] = TARGET_RANGE,
        target_hold_range: tuple[float, float] = TARGET_HOLD_RANGE,
        target_ramp_range: tuple[float, float] = TARGET_RAMP_RANGE,
        target_preview: float = TARGET_PREVIEW,
        energy_weight: float = TRACKING_ENERGY_WEIGHT,
        **kwargs: Any,
    ) -> None:
        (
            self.target_range,
            self.target_hold_range,
            self.target_ramp_range,
            self.target_preview,
        ) = check_tracking_arguments(
            kwargs, target_range, target_hold_range, target_ramp_range, target_preview
        )
        if model is None:
            model = default_tracking_model_path()
            if not model.is_file():
                raise FileNotFoundError(
                    f"the shipped tracking surrogate is missing ({model}; reinstall the package): or pass "
                    "model=PATH, a model fitted on ViscosityTracking episodes "
                    "(docs/surrogate.md#the-tracking-surrogate)"
                )
        loaded = model if isinstance(model, SurrogateModel) else load_model(model)
        if not loaded.direction:
            name = "the model given" if isinstance(model, SurrogateModel) else str(model)
            raise ValueError(
                "the tracking surrogate needs a model that sees the field's direction (direction_inputs): "
                f"{name} (kind {loaded.kind}) knows fields along y only"
            )
        self._target = sim.constant(math.sqrt(self.target_range[0] * self.target_range[1]))
        self._direction = np.array(Y_AXIS)
        super().__init__(
            model if isinstance(model, SurrogateModel) else Path(model),
            energy_weight=energy_weight,
            **kwargs,
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        draw_target(np.random.default_rng(0), self.episode_duration, *self._target_ranges())

    # -- configuration ---------------------------------------------------------------------------------------
    def frame_features(self) -> list[ObservationFeature]:
        """The frame of ``ViscosityTracking``."""
        return tracking_frame_features(self.rate_observed)

    def _make_reward(self, eta_cap: float | None) -> ViscosityTargetReward:
        # -|eta_r - target| - w_E <eps E0^2>; the target is set to each interval's mean before it runs
        return ViscosityTargetReward(float(self._target(0.0)), self.energy_weight, self.failure_penalty)

    def _target_ranges(self) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
        return self.target_range, self.target_hold_range, self.target_ramp_range

    def settings(self) -> dict[str, Any]:
        settings = super().settings()
        settings["reward"] = {
            "kind": "tracking",
            "energy_weight": self.energy_weight,
            "failure_penalty": self.failure_penalty,
        }
        settings["target"] = {
            "target_range": list(self.target_range),
            "hold_range": list(self.target_hold_range),
            "ramp_range": list(self.target_ramp_range),
            "preview": self.target_preview,
        }
        return settings

    def fixed_target(self, split: str, index: int) -> sim.PiecewiseLinear:
        """Target ``index`` of a fixed split, as :meth:`ViscosityTrackingEnv.fixed_target` gives it."""
        self.fixed_schedule(split, index)  # the same checks of split and index
        return fixed_target(split, int(index), self.episode_duration, *self._target_ranges())

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode (options: those of the thickening surrogate and ``target``)."""
        options = dict(options or {})
        if "target" in options:  # checked before anything changes
            options["target"] = validate_target(options["target"], "options['target']")
        _, info = super().reset(seed=seed, options=options)
        target = self._target
        info.pop("eta_cap", None)
        info.update(target=target_to_dict(target), target_eta_r=float(target(0.0)))
        info["target_viscosity"] = info["target_eta_r"]
        return self._observation(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Sample one interval of the model under the field (strength and direction) of ``action``."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (and after an episode has ended)")
        try:
            clipped, was_clipped = validate_action(action, (3,))
        except ValueError as error:
            raise ValueError(
                "action must be [u (strength), polar, azimuth], three finite floats in [-1, 1] (beyond "
                f"[-1, 1] clipped): {error}"
            ) from None
        mason = self.mapping.mason_number(float(clipped[0]))
        # as the simulator env: canonical (e_y >= 0), then one representative of +-e on the equator
        direction = field_orientation(
            canonical_direction(tracking_direction(float(clipped[1]), float(clipped[2])))
        )
        return self._advance(mason, was_clipped, direction)

    # -- internals ------------------------------------------------------------------------------------------
    def _interval_started(self, k: int) -> None:
        start = k * self.control_interval
        target_mean = float(self._target.mean(start, start + self.control_interval))
        self.reward_function = replace(self.reward_function, target_viscosity=target_mean)

    def _interval_info(self, k: int, eta: float, info: dict[str, Any]) -> None:
        """As the simulator env's ``info``: the direction in force, the interval's target and error, and
        no ``eta_cap`` (the tracking task has none)."""
        target_mean = self.reward_function.target_viscosity
        del info["eta_cap"]
        info["field_direction"] = self._direction.copy()
        info["target_eta_r"] = target_mean
        info["target_eta_r_end"] = float(self._target((k + 1) * self.control_interval))
        info["tracking_error"] = eta - target_mean

    def _after_schedule(self, split: str, index: int, options: dict[str, Any]) -> None:
        own = options.get("target")
        if own is not None:
            target = own  # validated by reset
        elif split == "train":  # drawn after the rate schedule, from the same generator
            target = draw_target(self.np_random, self.episode_duration, *self._target_ranges())
        else:
            target = self.fixed_target(split, index)
        self._target = target
        self._direction = np.array(Y_AXIS)  # the simulator env resets the field to y, off
        self.reward_function = replace(self.reward_function, target_viscosity=float(target(0.0)))

    def _frame(self, dynamic: np.ndarray, rate_end: float, shear_stress: float) -> np.ndarray:
        """The ``ViscosityTracking`` frame: the dynamic part, the field in force (energy fraction,
        coordinate, direction), the rate at the interval's end and the target features."""
        mason = self._mason
        amplitude = self.mapping.amplitude(mason)
        frame = np.empty(self._frame_size)
        frame[:N_DYNAMIC] = dynamic
        frame[N_DYNAMIC] = min(1.0, amplitude**2)
        frame[N_DYNAMIC + 1] = self.mapping.coordinate(mason)
        frame[N_DYNAMIC + 2 : N_DYNAMIC + 5] = self._direction
        frame[N_DYNAMIC + 5] = math.log10(rate_end)
        frame[N_DYNAMIC + 6 :] = self._target_features()
        return frame

    def _target_features(self) -> np.ndarray:
        """slog of the target now, over the coming interval, and ``target_preview`` ahead (episode time)."""
        now = self._steps * self.control_interval
        target = self._target
        values = (
            target(now),
            target.mean(now, now + self.control_interval),
            target(now + self.target_preview),
        )
        return np.array([signed_log(v) for v in values])
