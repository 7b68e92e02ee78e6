"""Gymnasium environments: suppress shear thickening while the shear rate changes.

:class:`ThickeningControlEnv` (the rate is observed) and :class:`ThickeningControlStressOnlyEnv` (only the
measured stresses and the microstructure: the agent must infer the operating point) share the machinery
of :class:`dipenv.envs.field_control.FieldControlEnv`; what they add is a shear-rate schedule per episode
(:mod:`dipenv.schedules`), followed by the simulator through :func:`sim.follow`, and the thickening
reward (:class:`dipenv.rewards.ThickeningPenaltyReward`). Units: ``docs/units.md`` (time in
``1/gammadot_ref``, stress in ``eta gammadot_ref``, the field as ``Mn_ref``).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

import sim
from dipenv.checks import is_real_number, real_number, real_pair
from dipenv.envs.field_control import FieldControlEnv
from dipenv.observations import MICROSTRUCTURE_DOC_ROWS, ObservationFeature, observation_features, signed_log
from dipenv.rewards import ThickeningPenaltyReward, ViscosityTargetReward, default_viscosity_cap
from dipenv.schedules import (
    FIXED_SPLITS,
    HOLD_RANGE,
    RAMP_RANGE,
    RATE_RANGE,
    STRATIFIED_POOLS,
    draw_schedule,
    fixed_schedules,
    schedule_to_dict,
    schedule_window,
    split_seeds,
    validate_schedule,
)

DEFAULT_MAX_PIECE = 0.05
"""Longest stretch of a ramp held at one rate (time units): a 0.25 interval inside a ramp is followed in
five rates, each the schedule's mean over its stretch (:func:`sim.follow`)."""

RATE_FEATURE = ObservationFeature(
    "log10_shear_rate", "log10(gammadot_ref)", -2.0, 2.0, "shear rate in force at the end of the interval"
)
SHEAR_STRESS_FEATURE = ObservationFeature(
    "slog_shear_stress", "slog(eta gammadot_ref)", -6.0, 6.0, "interval-averaged shear stress Sigma_xy"
)


def thickening_frame_features(rate_observed: bool) -> list[ObservationFeature]:
    """One observation frame of the thickening-control ids: the field-control frame plus the rate, or,
    for the stress-only ids, with the shear stress in place of eta_r and no rate."""
    features = observation_features(False)
    if rate_observed:
        return [*features, RATE_FEATURE]
    return [SHEAR_STRESS_FEATURE, *features[1:]]


class ThickeningControlEnv(FieldControlEnv):
    """## Description

    The suspension of :class:`dipenv.envs.field_control.FieldMagnitudeEnv` (N spheres at phi in a
    Lees–Edwards box, field along the velocity gradient ``y``) is sheared at a rate that changes as a
    process's does: each episode follows a schedule of holds and ramps, log-uniform over
    ``rate_range`` (default ``[0.2, 5] gammadot_ref``; holds of 1–4, ramps of 0.5–2 time units;
    :mod:`dipenv.schedules`). At a fixed field the instantaneous Mason number ``Mn = rate x Mn_ref`` rises
    with the rate, and the suspension shear-thickens (Mirfendereski & Park 2024, Fig. 3b). The agent sets
    the field strength once per control interval (0.25 time units) to keep ``eta_r`` below a cap with as
    little field energy as possible: a constant field sized for the highest rate wastes energy at low
    rates.

    ## Action Space

    As ``FieldMagnitude-v0``: ``Box(-1, 1, (1,), float32)``; ``u < -0.9`` is off, ``u`` in ``[-0.9, 1]``
    maps log-linearly to ``Mn_ref`` from 20 to ``mason_min`` (:class:`dipenv.actions.FieldStrengthMapping`):
    0.05 in ``-v0`` and ``-v1``, 0.1 in ``-v2``.

    ## Observation Space

    The frame of ``FieldMagnitude-v0`` (stresses in ``eta gammadot_ref``; the microstructure of the end
    state; the field in force, as ``Mn_ref``) plus the shear rate; ``observation_labels`` names every
    index; ``history_length`` stacks previous frames. ``slog(x) = sign(x) log10(1 + |x|)``.

    | index | name | quantity | units | range |
    |---|---|---|---|---|
    | 0 | slog_eta_r | interval-averaged relative viscosity eta_r | slog(eta gammadot_ref) | [-6, 6] |
    | 1 | slog_n1 | interval-averaged N1 = S_xx - S_yy | slog(eta gammadot_ref) | [-6, 6] |
    | 2 | slog_n2 | interval-averaged N2 = S_yy - S_zz | slog(eta gammadot_ref) | [-6, 6] |
    {microstructure_rows}
    | 12 | field_energy_fraction | (E0 / E0_max)^2 = Mn_min / Mn_ref in force (0: off) | 1 | [0, 1] |
    | 13 | field_coordinate | strength-action coordinate of that Mn_ref (-1: off) | 1 | [-1, 1] |
    | 14 | log10_shear_rate | shear rate in force at the end of the interval | log10(gammadot_ref) | [-2, 2] |

    ## Rewards

    ``r = -(max(0, eta_r - eta_cap) + w_E <eps E0^2>)`` per interval: ``eta_r = Sigma_xy/(eta gammadot)``
    time-averaged over the interval at the rates in force, ``<eps E0^2> = <1/Mn_ref>`` the field energy
    density (``eta gammadot_ref``). Default ``eta_cap``: :data:`dipenv.rewards.DEFAULT_VISCOSITY_CAP`
    (the constant fields' low-viscosity plateau at phi = 0.45: 6.5 at N = 64, 7.7 at N = 300). ``w_E``:
    1 by default and in ``-v0``, :data:`dipenv.THICKENING_ENERGY_WEIGHT_V1` (0.3) in ``-v1``, where the
    bigger box's smaller field effect needs a lighter weight for any field to pay. ``info`` holds every term
    and ``eta_r``, ``n1``, ``n2``, ``shear_stress``, ``shear_rate`` (interval mean), ``shear_rate_end``,
    ``instantaneous_mason_number`` (interval mean of rate x Mn_ref), ``mason_number`` (``Mn_ref``),
    ``field_energy``, ``eta_cap``, ``time`` (since the episode start) and the simulator's step statistics.

    ## Starting State

    A pre-sheared state of the start-state library, as ``FieldMagnitude-v0``, field off, the rate set
    to the schedule's first value. Training episodes draw their schedule with ``self.np_random``; the
    validation, test and fresh splits pair start state ``k`` with fixed schedule ``k``
    (:func:`dipenv.schedules.fixed_schedules`), so every controller meets the same episodes. The fresh
    split is held out: played only in the final evaluation, never tuned, selected or designed on
    (``docs/thickening_control.md#the-fresh-split``).
    ``reset(options={"schedule": {"times": [...], "rates": [...]}})`` runs a schedule of your own,
    checked by :func:`dipenv.schedules.validate_schedule` before anything changes: times from 0 (the
    episode start), increasing (two equal times make a jump); rates in
    ``[sim.MIN_SHEAR_RATE, sim.MAX_SHEAR_RATE]``; at most :data:`dipenv.schedules.MAX_SCHEDULE_KNOTS`
    knots, which cost no more per interval than a few.

    ## Episode End

    Truncation after ``episode_steps`` (48 = 12 time units); termination on a simulator failure, as
    ``FieldMagnitude-v0``.

    ## Arguments

    Those of :class:`dipenv.envs.field_control.FieldControlEnv` (no actuator lag here), plus ``eta_cap``,
    ``rate_range``, ``hold_range``, ``ramp_range`` and ``max_piece`` (longest stretch of a ramp held at
    one rate, 0.05 time units: a ramp is followed as a staircase at the ramp's mean over each stretch).

    ## Version History

    * v0: initial version (2026-12-02).
    * v1 (2026-12-03): N = 300 instead of 64 (docs/environments.md#box-size), and the default cap is
      N = 300's plateau (:data:`dipenv.rewards.DEFAULT_VISCOSITY_CAP`); ``w_E = 0.3`` instead of 1
      (revised 2026-12-03, before any policy was trained on v1: at 1 no constant field beats no field
      in the N = 300 box). Everything else is as v0.
    * 2026-12-03, both versions, before any controller or policy was tuned on the new split: the 8
      validation schedules are stratified by mean rate (:func:`dipenv.schedules.split_seeds`; the first 8
      draws had a mean rate of 0.86, the generator's is 1.49). The test schedules are unchanged.
    * v2 (2026-12-03): the strongest field is ``Mn_ref = 0.1`` instead of 0.05 (:data:`dipenv.
      THICKENING_V2_KWARGS`): fields below 0.1 cost more energy per interval than the largest excess
      eta_r they could remove, and were the slowest to simulate. Physics, schedules and start states are
      v1's.
    * 2026-12-07, every version: the ``fresh`` split (128 schedules and start states, held out for the
      final evaluation; issue 43); schedules and reset options are checked before anything changes, and
      a schedule rate must lie in the simulator's range (rate 0 and 1e-9 are refused; issue 45). The
      episodes of every accepted input are unchanged.
    """

    __doc__ = (__doc__ or "").replace("{microstructure_rows}", MICROSTRUCTURE_DOC_ROWS)
    rate_observed: ClassVar[bool] = True
    reset_options: ClassVar[tuple[str, ...]] = (*FieldControlEnv.reset_options, "schedule")
    target_name: ClassVar[str] = "eta_cap"

    def __init__(
        self,
        *args: Any,
        eta_cap: float | None = None,
        rate_range: tuple[float, float] = RATE_RANGE,
        hold_range: tuple[float, float] = HOLD_RANGE,
        ramp_range: tuple[float, float] = RAMP_RANGE,
        max_piece: float = DEFAULT_MAX_PIECE,
        **kwargs: Any,
    ) -> None:
        lag = kwargs.get("actuator_time_constant", 0.0)
        if not (is_real_number(lag) and lag == 0.0):
            raise ValueError(
                "actuator_time_constant must be 0 in the thickening-control environments (no actuator lag), "
                f"got {lag!r}"
            )
        if "target_viscosity" in kwargs:
            raise ValueError("the thickening-control environments take eta_cap, not target_viscosity")
        if eta_cap is not None:
            eta_cap = real_number("eta_cap", eta_cap, 0.0, low_open=True)
        self.explicit_cap = eta_cap
        self.rate_range = real_pair("rate_range", rate_range)
        low, high = sim.MIN_SHEAR_RATE, sim.MAX_SHEAR_RATE
        if not low <= self.rate_range[0] <= self.rate_range[1] <= high:
            raise ValueError(
                f"rate_range must be [low, high] with sim.MIN_SHEAR_RATE = {low:g} <= low <= high <= "
                f"sim.MAX_SHEAR_RATE = {high:g} (the simulator's rates, gammadot_ref), got {rate_range!r}"
            )
        self.hold_range = real_pair("hold_range", hold_range)
        self.ramp_range = real_pair("ramp_range", ramp_range)
        self.max_piece = real_number("max_piece", max_piece, 0.0, low_open=True)
        super().__init__(*args, **kwargs)
        # draw once now, so that bad ranges are refused at make, not at the first reset
        draw_schedule(
            np.random.default_rng(0), self.episode_duration, self.rate_range, self.hold_range, self.ramp_range
        )
        self._schedule = sim.constant(1.0)

    @property
    def episode_duration(self) -> float:
        """Time an episode lasts: ``episode_steps * control_interval``."""
        return self.episode_steps * self.control_interval

    # -- configuration ---------------------------------------------------------------------------------------
    def frame_features(self) -> list[ObservationFeature]:
        return thickening_frame_features(self.rate_observed)

    def _reward_for(self, volume_fraction: float) -> ViscosityTargetReward:
        cap = self.explicit_cap
        if cap is None:
            cap = default_viscosity_cap(volume_fraction, self.base_config.n_particles)
        return ThickeningPenaltyReward(float(cap), self.energy_weight, self.failure_penalty)

    def settings(self) -> dict[str, Any]:
        settings = super().settings()
        settings["schedule"] = {
            "rate_range": list(self.rate_range),
            "hold_range": list(self.hold_range),
            "ramp_range": list(self.ramp_range),
            "max_piece": self.max_piece,
        }
        settings["reward"]["eta_cap"] = settings["reward"].pop("target_viscosity")
        settings["observation"] = [f.name for f in self.frame_features()]
        return settings

    def fixed_schedule(self, split: str, index: int) -> sim.PiecewiseLinear:
        """Schedule ``index`` of a validation, test or fresh split: the shipped one when this env has the
        default schedule parameters and episode duration, else drawn from the same seed with this env's.
        ``ValueError`` for the train split (its episodes draw their schedules) or an index outside the
        split's states (``split_sizes``)."""
        if split not in FIXED_SPLITS:
            raise ValueError(
                f"split must be one of {', '.join(FIXED_SPLITS)} for fixed schedules (train episodes draw "
                f"theirs with the env's np_random), got {split!r}"
            )
        size = self.split_sizes[split]
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < size:
            raise ValueError(f"index must be an integer in [0, {size}) for split {split!r}, got {index!r}")
        count, seed = FIXED_SPLITS[split]
        defaults = (self.rate_range, self.hold_range, self.ramp_range, self.episode_duration) == (
            RATE_RANGE, HOLD_RANGE, RAMP_RANGE, 12.0
        )
        if defaults and index < count:
            return fixed_schedules(split)[index]
        parameters = (self.rate_range, self.hold_range, self.ramp_range)
        if index < count:
            index_seed = split_seeds(split, self.episode_duration, *parameters)[index]
        else:
            index_seed = seed + STRATIFIED_POOLS.get(split, 0) + index  # past the split's own draws
        rng = np.random.default_rng(index_seed)
        return draw_schedule(rng, self.episode_duration, *parameters)

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """As :meth:`FieldControlEnv.reset`, with the option ``schedule`` (see the class docstring), checked
        by :func:`dipenv.schedules.validate_schedule` before anything changes."""
        return self._reset_checked(seed, self._check_reset_options(options))

    def _check_reset_options(self, options: object) -> dict[str, Any]:
        checked = super()._check_reset_options(options)
        if "schedule" in checked:
            checked["schedule"] = validate_schedule(checked["schedule"], "options['schedule']")
        return checked

    def _reset_checked(self, seed: int | None, options: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        options = dict(options)
        schedule = options.pop("schedule", None)
        _, info = super()._reset_checked(seed, options)
        if schedule is None:
            if info["split"] == "train":
                schedule = draw_schedule(
                    self.np_random, self.episode_duration, self.rate_range, self.hold_range, self.ramp_range
                )
            else:
                schedule = self.fixed_schedule(info["split"], info["index"])
        self._schedule = schedule
        simulation = self._simulation
        assert simulation is not None
        simulation.set_shear_rate(schedule(0.0))
        eta = info["eta_r"]
        self._frames = [self._frame(eta, info["n1"], info["n2"], eta)] * (self.history_length + 1)
        info.update(
            schedule=schedule_to_dict(schedule),
            shear_rate=schedule(0.0),
            eta_cap=self.reward_function.target_viscosity,
            time=0.0,
        )
        self._last_info = info
        return self._observation(), dict(info)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Hold the field for one interval while the rate follows the episode's schedule."""
        observation, reward, terminated, truncated, info = super().step(action)
        simulation = self._simulation
        assert simulation is not None
        rate = info.get("shear_rate", math.nan)
        mason = info["mason_number"]
        info.update(
            shear_rate_end=simulation.shear_rate,
            instantaneous_mason_number=math.inf if math.isinf(mason) else rate * mason,
            eta_cap=self.reward_function.target_viscosity,
            time=simulation.state.time - self._episode_start,
        )
        return observation, reward, terminated, truncated, info

    # -- internals ------------------------------------------------------------------------------------------
    def _advance(self, simulation: sim.Simulation, end_time: float) -> sim.StepRecords:
        # The window is the schedule bit for bit on the way to end_time (sim.follow reads nothing else),
        # and its length does not grow with the schedule's (dipenv.schedules.schedule_window).
        origin = self._episode_start
        window = schedule_window(self._schedule, simulation.state.time - origin, end_time - origin)
        return sim.follow(simulation, end_time, window, self.max_piece, origin=origin)

    def _frame(self, eta: float, n1: float, n2: float, shear_stress: float) -> np.ndarray:
        frame = super()._frame(eta, n1, n2, shear_stress)
        if self.rate_observed:
            simulation = self._simulation
            assert simulation is not None
            return np.append(frame, math.log10(simulation.shear_rate))
        frame[0] = signed_log(shear_stress)
        return frame


class ThickeningControlStressOnlyEnv(ThickeningControlEnv):
    """## Description

    As :class:`ThickeningControlEnv`, but the observation holds only what a device without a flow meter
    measures: the interval-averaged shear stress ``Sigma_xy`` (index 0, ``slog`` of ``eta gammadot_ref``),
    ``N1``, ``N2``, the microstructure and the field in force; neither the rate nor ``eta_r``. The agent
    must infer the operating point (``history_length`` stacks previous frames for that). Action, reward,
    start states and episode end as :class:`ThickeningControlEnv`.

    ## Observation Space

    | index | name | quantity | units | range |
    |---|---|---|---|---|
    | 0 | slog_shear_stress | interval-averaged shear stress Sigma_xy | slog(eta gammadot_ref) | [-6, 6] |
    | 1 | slog_n1 | interval-averaged N1 = S_xx - S_yy | slog(eta gammadot_ref) | [-6, 6] |
    | 2 | slog_n2 | interval-averaged N2 = S_yy - S_zz | slog(eta gammadot_ref) | [-6, 6] |
    | 3-7 | fabric_xx, fabric_yy, fabric_xy, fabric_xz, fabric_yz | A - I/3 (end state) | 1 | [-1, 1] |
    | 8 | contact_number | as :class:`ThickeningControlEnv` | 1 | [0, 13] |
    | 9-11 | g_equator, g_middle, g_pole | angular g, as :class:`ThickeningControlEnv` | 1 | [0, 100] |
    | 12 | field_energy_fraction | as :class:`ThickeningControlEnv` | 1 | [0, 1] |
    | 13 | field_coordinate | as :class:`ThickeningControlEnv` | 1 | [-1, 1] |
    """

    rate_observed = False
