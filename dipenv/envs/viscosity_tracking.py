"""Gymnasium environments: make the viscosity follow a target by turning and scaling the field (issue 44).

:class:`ViscosityTrackingEnv` (the rate is observed) and :class:`ViscosityTrackingStressOnlyEnv` (only the
measured stresses, the microstructure, the field and the target) are the thickening-control machinery of
:class:`dipenv.envs.thickening_control.ThickeningControlEnv` (start states, shear-rate schedules and their
splits, realisations, the simulator followed by :func:`sim.follow`) with a three-component action (field
strength and direction, as :class:`dipenv.envs.field_control.FieldVectorEnv`), a target ``eta_r(t)`` per
episode (:mod:`dipenv.tracking`) and a tracking reward. Units: ``docs/units.md`` (time in
``1/gammadot_ref``, stress in ``eta gammadot_ref``, the field as ``Mn_ref``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

import sim
from dipenv.actions import direction_from_action, validate_action
from dipenv.envs.thickening_control import RATE_FEATURE, SHEAR_STRESS_FEATURE, ThickeningControlEnv
from dipenv.observations import MICROSTRUCTURE_DOC_ROWS, ObservationFeature, observation_features, signed_log
from dipenv.rewards import ViscosityTargetReward
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

TRACKING_ENERGY_WEIGHT = 0.1
"""Default ``w_E`` of the tracking reward. The strongest field of the action range (``Mn_ref = 0.1``,
``eps E0^2 = 10``) then costs 1 per interval, about one interval's noise of eta_r at N = 300 (sd 0.8-1.4),
and a field at ``Mn_ref = 1`` costs 0.1: small against the tracking error, so energy decides only between
fields that track about equally well (a target of 10: no field, or a weak field along y), and never pays
for leaving the target by more than a fraction of a unit."""

DIRECTION_ROUND_OFF = 1e-12
"""Components of the action's direction below this are set to 0: the round-off of ``cos(pi/2)`` and
``sin(pi)`` (6e-17, 1.2e-16), so that the axes are exact (the map's ``x``, ``z``; ``e`` and ``-e`` on the
equator are exact negatives). The smallest component a float32 action can ask for is about 1e-8."""

TARGET_FEATURES = [
    ObservationFeature(
        "slog_target_eta_r", "slog(1)", 0.0, 6.0, "target eta_r now (at the start of the coming interval)"
    ),
    ObservationFeature(
        "slog_target_eta_r_next", "slog(1)", 0.0, 6.0, "target eta_r averaged over the coming interval"
    ),
    ObservationFeature(
        "slog_target_eta_r_ahead", "slog(1)", 0.0, 6.0, "target eta_r target_preview time units ahead"
    ),
]


def tracking_direction(polar: float, azimuth: float) -> np.ndarray:
    """The field direction of the action's ``(polar, azimuth)``: :func:`dipenv.actions.direction_from_action`
    with components below :data:`DIRECTION_ROUND_OFF` set to 0."""
    e = direction_from_action(polar, azimuth)
    e[np.abs(e) < DIRECTION_ROUND_OFF] = 0.0
    return e


def field_orientation(direction: np.ndarray) -> np.ndarray:
    """One representative of ``{e, -e}`` (one field: dipolophoresis is quadratic in it): the first nonzero
    of ``e_y``, ``e_x``, ``e_z`` positive. Off the equator this is ``e_y > 0`` (as
    :func:`dipenv.actions.canonical_direction`); on it, ``e_x > 0`` (or ``e_z > 0`` along ``z``), so that
    ``e`` and ``-e`` give one observation."""
    e = np.asarray(direction, dtype=np.float64)
    for k in (1, 0, 2):
        if e[k] != 0.0:
            return (-e if e[k] < 0.0 else e) + 0.0  # + 0.0: no negative zeros
    return e + 0.0


def tracking_frame_features(rate_observed: bool) -> list[ObservationFeature]:
    """One observation frame of the tracking ids: the vector field-control frame (with the direction), the
    rate (or, for the stress-only id, the shear stress in place of eta_r and no rate), and the target."""
    features = observation_features(True)
    features = [*features, RATE_FEATURE] if rate_observed else [SHEAR_STRESS_FEATURE, *features[1:]]
    return [*features, *TARGET_FEATURES]


_DIRECTION_ROWS = (
    "| 14-16 | field_ex, field_ey, field_ez | field direction, one of +-e: e_y > 0 (on the equator e_x > 0) "
    "| 1 | [-1, 1], [0, 1], [-1, 1] |"
)
_TARGET_ROWS = (
    "| 17-19 | slog_target_eta_r, slog_target_eta_r_next, slog_target_eta_r_ahead | as "
    ":class:`ViscosityTrackingEnv` | slog(1) | [0, 6] |"
)
"""Rows of the observation tables in the docstrings below, too long for one source line."""


class ViscosityTrackingEnv(ThickeningControlEnv):
    """## Description

    The sheared suspension of :class:`dipenv.envs.thickening_control.ThickeningControlEnv` (N spheres at
    phi in a Lees–Edwards box; the shear rate follows a schedule of holds and ramps in
    ``[0.2, 5] gammadot_ref``) must show a relative viscosity ``eta_r`` that follows a target ``eta_r(t)``:
    holds and ramps drawn log-uniformly in ``target_range`` (default 9-25; :mod:`dipenv.tracking` says why).
    The agent sets the field's strength **and direction** once per control interval (0.25 time units). The
    direction is the wide lever: at phi = 0.45 in bulk the field along the velocity gradient ``y`` lowers
    eta_r to 7.8-12, along the flow ``x`` it gives 11.5-14.4 and along the vorticity ``z`` 14.6-32 (no
    field: 10; ``docs/direction.md``), so the target range needs both.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: ``[u, polar, azimuth]``, the convention of ``FieldVector``.

    * ``u``: the strength, as ``ThickeningControl``: ``u < -0.9`` is off (zero strength: no field, whatever
      the direction), ``u`` in ``[-0.9, 1]`` maps log-linearly to ``Mn_ref`` from 20 to ``mason_min``
      (0.1; :class:`dipenv.actions.FieldStrengthMapping`). The instantaneous Mason number is
      ``rate x Mn_ref``.
    * direction ``e = (sin t cos p, cos t, sin t sin p)`` with ``t = (polar + 1) pi/4`` in ``[0, pi/2]``
      from ``y`` and ``p = azimuth pi`` in the flow–vorticity plane (:func:`tracking_direction`). Since
      ``E -> -E`` is an exact symmetry, the hemisphere ``e_y >= 0`` is every field. The map's directions:
      ``y`` at ``polar = -1`` (any azimuth), ``x`` at ``(1, 0)``, ``z`` at ``(1, 0.5)``, ``(x+y)/sqrt2`` at
      ``(0, 0)``, ``(x-y)/sqrt2`` (as ``(-x+y)/sqrt2``) at ``(0, 1)``, ``(y+z)/sqrt2`` at ``(0, 0.5)``
      (:func:`dipenv.actions.action_from_direction` inverts it). Components below 1e-12 are round-off and
      set to 0, so the axes are exact and equator actions ``p`` and ``p +- 1`` are exactly ``e`` and
      ``-e``.

    Why this parameterisation: the ``FieldVector`` ids, their observation (``field_ex/ey/ez``) and their
    tools already use it, so policies and controllers carry over; it covers the hemisphere with two
    bounded coordinates, no constraint for a Gaussian policy to respect; and the y->z path, which spans the
    whole target range at one strength (8.7 to 27 at Mn 1), is one coordinate (``polar`` at
    ``azimuth = 0.5``). Its costs: the azimuth is irrelevant at ``polar = -1`` and wraps at +-1.
    Out-of-range actions are clipped (``info["action_clipped"]``); NaN/inf or a wrong shape raise
    ``ValueError`` naming the three components and their range.

    ## Observation Space

    The frame of ``ThickeningControl`` with the field's direction (as ``FieldVector``) and three target
    features; ``observation_labels`` names every index, ``history_length`` stacks previous frames.
    ``slog(x) = sign(x) log10(1 + |x|)``; the target is in the units of eta_r, so
    ``slog_eta_r - slog_target_eta_r_next`` is the error to close.

    | index | name | quantity | units | range |
    |---|---|---|---|---|
    | 0 | slog_eta_r | interval-averaged relative viscosity eta_r | slog(eta gammadot_ref) | [-6, 6] |
    | 1 | slog_n1 | interval-averaged N1 = S_xx - S_yy | slog(eta gammadot_ref) | [-6, 6] |
    | 2 | slog_n2 | interval-averaged N2 = S_yy - S_zz | slog(eta gammadot_ref) | [-6, 6] |
    {microstructure_rows}
    | 12 | field_energy_fraction | (E0 / E0_max)^2 = Mn_min / Mn_ref in force (0: off) | 1 | [0, 1] |
    | 13 | field_coordinate | strength-action coordinate of that Mn_ref (-1: off) | 1 | [-1, 1] |
    {direction_rows}
    | 17 | log10_shear_rate | shear rate in force at the end of the interval | log10(gammadot_ref) | [-2, 2] |
    | 18 | slog_target_eta_r | target eta_r now (start of the coming interval) | slog(1) | [0, 6] |
    | 19 | slog_target_eta_r_next | target eta_r averaged over the coming interval | slog(1) | [0, 6] |
    | 20 | slog_target_eta_r_ahead | target eta_r ``target_preview`` (1) time units ahead | slog(1) | [0, 6] |

    The g bins are relative to the field's direction (also when it is off: the direction last asked for).

    ## Rewards

    ``r = -(|eta_r - eta_target| + w_E <eps E0^2>)`` per interval, a penalty per unit time: ``eta_r`` and
    the target ``eta_target`` are time averages over the interval (the clock, not the strain: the
    simulator's steps weighted by their duration; the target's exact mean over its linear pieces), and
    ``<eps E0^2> = <1/Mn_ref>`` the field energy density in ``eta gammadot_ref``. The intervals are equal in
    time, so the return is the time integral of the penalty rate divided by the interval. ``w_E``:
    ``energy_weight``, default :data:`TRACKING_ENERGY_WEIGHT` (0.1). ``info`` holds the terms
    (``reward_viscosity``, ``reward_energy``, ``reward_failure``), ``target_eta_r`` (the interval's target,
    also as ``target_viscosity``), ``target_eta_r_end``, ``tracking_error`` (``eta_r - target_eta_r``),
    ``eta_r``, ``n1``, ``n2``, ``shear_stress``, ``shear_rate`` (interval mean), ``shear_rate_end``,
    ``mason_number`` (``Mn_ref``), ``instantaneous_mason_number``, ``field_direction``, ``field_energy``,
    ``time`` (since the episode start) and the simulator's step statistics; ``reset`` adds the episode's
    ``schedule`` and ``target`` knots.

    ## Starting State

    As ``ThickeningControl``: a pre-sheared state of the start-state library (the ``-v2`` box's), field off,
    the rate at its schedule's first value. Training episodes draw their rate schedule and then their
    target with ``self.np_random``; the validation, test and fresh splits pair start state ``k``, rate
    schedule ``k`` and target ``k`` (:meth:`fixed_target`; :mod:`dipenv.tracking`), so every controller
    meets the same episodes. The fresh split is held out for a final evaluation
    (``docs/thickening_control.md#the-fresh-split``). ``reset(options=...)`` takes ``schedule`` (the rate,
    as ``ThickeningControl``) and ``target`` (``{"times": [...], "values": [...]}``, times from 0,
    values in [1, 1000]; :func:`dipenv.tracking.validate_target`), both checked before anything changes.

    ## Episode End

    Truncation after ``episode_steps`` (48 = 12 time units); termination on a simulator failure (reward
    ``-failure_penalty`` per lost step, ``info["simulation_failed"]``), as ``ThickeningControl``.

    ## Arguments

    Those of :class:`dipenv.envs.thickening_control.ThickeningControlEnv` but ``eta_cap`` (and
    ``target_viscosity``), which the tracking reward has no use for and refuses, plus ``target_range``
    (default (9, 25)), ``target_hold_range`` ((2, 4)), ``target_ramp_range`` ((0.5, 2)), ``target_preview``
    (1 time unit, >= 0) and ``energy_weight`` (``w_E``, default 0.1).

    ## Version History

    * v0 (2026-12-07): initial version, in the box of ``ThickeningControl-v2`` (N = 300, phi = 0.45,
      ``Mn_ref`` 0.1-20 + off).
    """

    __doc__ = (
        (__doc__ or "")
        .replace("{microstructure_rows}", MICROSTRUCTURE_DOC_ROWS)
        .replace("{direction_rows}", _DIRECTION_ROWS)
    )
    vector_field: ClassVar[bool] = True
    rate_observed: ClassVar[bool] = True
    reset_options: ClassVar[tuple[str, ...]] = (*ThickeningControlEnv.reset_options, "target")
    target_name: ClassVar[str] = "target_range"

    def __init__(
        self,
        *args: Any,
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
        self._target = sim.constant(math.sqrt(self.target_range[0] * self.target_range[1]))
        super().__init__(*args, energy_weight=energy_weight, **kwargs)

    # -- configuration ---------------------------------------------------------------------------------------
    def frame_features(self) -> list[ObservationFeature]:
        return tracking_frame_features(self.rate_observed)

    def _reward_for(self, volume_fraction: float) -> ViscosityTargetReward:
        # -|eta_r - target| - w_E <eps E0^2>; the target is set to each interval's mean before it runs
        return ViscosityTargetReward(float(self._target(0.0)), self.energy_weight, self.failure_penalty)

    def settings(self) -> dict[str, Any]:
        settings = super().settings()
        settings["reward"].pop("eta_cap", None)
        settings["reward"]["kind"] = "tracking"
        settings["target"] = {
            "target_range": list(self.target_range),
            "hold_range": list(self.target_hold_range),
            "ramp_range": list(self.target_ramp_range),
            "preview": self.target_preview,
        }
        return settings

    def fixed_target(self, split: str, index: int) -> sim.PiecewiseLinear:
        """Target ``index`` of a validation, test or fresh split: the shipped one when this env has the
        default target parameters and a 12-time-unit episode, else drawn from the same seed with this
        env's (:func:`dipenv.tracking.fixed_target`). ``ValueError`` for the train split or an index
        outside the split's states."""
        self.fixed_schedule(split, index)  # the same checks of split and index
        return fixed_target(
            split,
            int(index),
            self.episode_duration,
            self.target_range,
            self.target_hold_range,
            self.target_ramp_range,
        )

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def _check_reset_options(self, options: object) -> dict[str, Any]:
        checked = super()._check_reset_options(options)
        if "target" in checked:
            checked["target"] = validate_target(checked["target"], "options['target']")
        return checked

    def _reset_checked(self, seed: int | None, options: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        options = dict(options)
        target = options.pop("target", None)
        _, info = super()._reset_checked(seed, options)
        if target is None:
            if info["split"] == "train":  # drawn after the rate schedule, from the same generator
                target = draw_target(
                    self.np_random,
                    self.episode_duration,
                    self.target_range,
                    self.target_hold_range,
                    self.target_ramp_range,
                )
            else:
                target = self.fixed_target(info["split"], info["index"])
        self._target = target
        self.reward_function = replace(self.reward_function, target_viscosity=float(target(0.0)))
        frame = self._frames[0].copy()  # the frame was built before the target was known
        frame[-len(TARGET_FEATURES) :] = self._target_features()
        self._frames = [frame] * (self.history_length + 1)
        info.pop("eta_cap", None)
        info.update(target=target_to_dict(target), target_eta_r=float(target(0.0)))
        info["target_viscosity"] = info["target_eta_r"]
        self._last_info = info
        return self._observation(), dict(info)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Hold the field of ``action`` for one interval while the rate follows its schedule; the reward
        charges the distance of the interval's eta_r from the interval's target."""
        if self._needs_reset:
            return super().step(action)  # RuntimeError: reset first
        try:
            validate_action(action, (3,))
        except ValueError as error:
            raise ValueError(
                "action must be [u (strength), polar, azimuth], three finite floats in [-1, 1] (beyond "
                f"[-1, 1] clipped): {error}"
            ) from None
        start = self._steps * self.control_interval
        end = start + self.control_interval
        target_mean = self._target.mean(start, end)
        self.reward_function = replace(self.reward_function, target_viscosity=float(target_mean))
        observation, reward, terminated, truncated, info = super().step(action)
        self._direction = field_orientation(self._direction)  # as the observation shows it (_frame)
        info.pop("eta_cap", None)
        info.update(
            field_direction=self._direction.copy(),
            target_eta_r=float(target_mean),
            target_eta_r_end=float(self._target(end)),
            tracking_error=math.nan if info["simulation_failed"] else info["eta_r"] - float(target_mean),
        )
        return observation, reward, terminated, truncated, info

    # -- internals ------------------------------------------------------------------------------------------
    def _action_direction(self, clipped: np.ndarray) -> np.ndarray:
        return tracking_direction(float(clipped[1]), float(clipped[2]))

    def _frame(self, eta: float, n1: float, n2: float, shear_stress: float) -> np.ndarray:
        # the equator's e and -e are one field: one observation (and the step's info) for both
        self._direction = field_orientation(self._direction)
        frame = super()._frame(eta, n1, n2, shear_stress)
        return np.append(frame, self._target_features())

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


class ViscosityTrackingStressOnlyEnv(ViscosityTrackingEnv):
    """## Description

    As :class:`ViscosityTrackingEnv`, but the observation holds what a device without a flow meter measures,
    as in ``ThickeningControlStressOnly``: the interval-averaged shear stress ``Sigma_xy`` in place of
    ``eta_r``, and no shear rate. The target (an ``eta_r``) is still observed: the agent must infer the rate
    to compare them (``history_length`` stacks previous frames).

    ## Action Space

    As :class:`ViscosityTrackingEnv`: ``Box(-1, 1, (3,), float32)``, strength, polar angle from ``y``,
    azimuth.

    ## Observation Space

    | index | name | quantity | units | range |
    |---|---|---|---|---|
    | 0 | slog_shear_stress | interval-averaged shear stress Sigma_xy | slog(eta gammadot_ref) | [-6, 6] |
    | 1 | slog_n1 | interval-averaged N1 = S_xx - S_yy | slog(eta gammadot_ref) | [-6, 6] |
    | 2 | slog_n2 | interval-averaged N2 = S_yy - S_zz | slog(eta gammadot_ref) | [-6, 6] |
    | 3-7 | fabric_xx, fabric_yy, fabric_xy, fabric_xz, fabric_yz | A - I/3 (end state) | 1 | [-1, 1] |
    | 8 | contact_number | as :class:`ViscosityTrackingEnv` | 1 | [0, 13] |
    | 9-11 | g_equator, g_middle, g_pole | angular g, as :class:`ViscosityTrackingEnv` | 1 | [0, 100] |
    | 12 | field_energy_fraction | as :class:`ViscosityTrackingEnv` | 1 | [0, 1] |
    | 13 | field_coordinate | as :class:`ViscosityTrackingEnv` | 1 | [-1, 1] |
    | 14-16 | field_ex, field_ey, field_ez | as :class:`ViscosityTrackingEnv` | 1 | [-1, 1] |
    {target_rows}

    ## Rewards

    As :class:`ViscosityTrackingEnv` (the reward charges eta_r, which the env measures but does not show).

    ## Starting State

    As :class:`ViscosityTrackingEnv`.

    ## Episode End

    As :class:`ViscosityTrackingEnv`.
    """

    __doc__ = (__doc__ or "").replace("{target_rows}", _TARGET_ROWS)
    rate_observed = False


TRACKING_KWARGS: dict[str, Any] = {"n_particles": 300, "mason_min": 0.1}
"""The ``-v0`` tracking ids' box and field range: those of ``ThickeningControl-v2`` (N = 300, the box-size
study's smallest box that matches N = 500, docs/environments.md#box-size; ``Mn_ref`` >= 0.1), so they share
its start-state library. The energy weight is the class default (:data:`TRACKING_ENERGY_WEIGHT`)."""
