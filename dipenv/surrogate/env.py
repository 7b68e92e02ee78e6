"""``ThickeningControlSurrogate``: the thickening-control task with a fitted model in place of the simulator.

Spaces, schedules (the generator, the fixed splits), action map and reward object are those of
:class:`dipenv.envs.thickening_control.ThickeningControlEnv`, reused from ``dipenv``; only the dynamics
differ: the next frame's dynamic part (``slog eta_r``, ``slog N1``, ``slog N2``, the microstructure) is
sampled from a fitted model (:mod:`dipenv.surrogate.models`, ``docs/surrogate.md``), in numpy, so that an
env step costs tens of microseconds instead of about a second.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import sim
from dipenv.actions import (
    DEFAULT_MASON_MAX,
    DEFAULT_MASON_MIN,
    DEFAULT_OFF_BAND,
    FieldStrengthMapping,
    field_energy,
    validate_action,
)
from dipenv.checks import check_episode_arguments
from dipenv.envs.thickening_control import DEFAULT_MAX_PIECE, thickening_frame_features
from dipenv.observations import ObservationFeature, observation_bounds
from dipenv.realisations import REALISATION_SEED
from dipenv.rewards import (
    DEFAULT_ENERGY_WEIGHT,
    DEFAULT_FAILURE_PENALTY,
    ThickeningPenaltyReward,
    ViscosityTargetReward,
    default_viscosity_cap,
)
from dipenv.schedules import (
    FIXED_SPLITS,
    HOLD_RANGE,
    RAMP_RANGE,
    RATE_RANGE,
    STRATIFIED_POOLS,
    draw_schedule,
    fixed_schedules,
    schedule_from_dict,
    schedule_to_dict,
    split_seeds,
)
from dipenv.state_library import DEFAULT_SPLIT_SIZES, SPLITS, check_split_sizes, pick_start_index
from dipenv.surrogate.features import N_DYNAMIC, IntervalTable, interval_table, inverse_signed_log
from dipenv.surrogate.models import SurrogateModel, default_model_path, load_model

SIMULATOR_ONLY_KWARGS = frozenset(
    {
        "actuator_substeps",
        "ewald_accuracy",
        "library_root",
        "near_field",
        "near_field_cutoff",
        "max_displacement",
        "preshear_strain",
        "progress",
        "simulation_overrides",
        "solver_tolerance",
        "time_step",
    }
)
"""Arguments of the simulator env that shape only the simulation: accepted and ignored (recorded in
``settings()["ignored"]``), so that a command written for ``ThickeningControl-v2`` runs unchanged."""


class ThickeningControlSurrogateEnv(gym.Env[np.ndarray, np.ndarray]):
    """## Description

    :class:`dipenv.envs.thickening_control.ThickeningControlEnv` with the simulator replaced by a fitted
    model of its trajectories (``docs/surrogate.md``): each interval the model samples the next frame's
    ``eta_r``, ``N1``, ``N2`` and microstructure from the current frame (ensemble) or its structure
    variables (lambda model), the field and the interval's rates. Stochastic: one episode is one sample.

    ## Spaces, reward, schedules

    As ``ThickeningControl``: ``Box(-1, 1, (1,))`` through :class:`dipenv.actions.FieldStrengthMapping`;
    the observation frame of ``ThickeningControl`` (15 entries; ``history_length`` stacks frames); the
    reward :class:`dipenv.rewards.ThickeningPenaltyReward` on the model's interval ``eta_r`` and the
    field energy ``1/Mn_ref``; training schedules drawn by :func:`dipenv.schedules.draw_schedule` with
    ``self.np_random`` after the start-state index, as the simulator env draws them (the same seed gives the
    same index and schedule), the validation and test splits' fixed schedules, ``options["schedule"]``.

    ## Starting State

    The dynamic part of a data episode's first frame (a pre-sheared train start state, field off), stored
    in the model: the train state ``index`` when the data hold it, else one drawn with the episode's
    generator (below; every start state is a field-free pre-sheared state; they differ by noise). The rate
    entry is the schedule's first rate.

    ## Arguments

    ``model``: path of a model ``.npz`` (default: the shipped ``dipenv/data/surrogate_v0.npz``); the
    others as ``ThickeningControlEnv`` (``n_particles`` and ``volume_fraction`` must be the model's data's,
    ``control_interval`` its interval). Simulator-only arguments (:data:`SIMULATOR_ONLY_KWARGS`) are
    ignored. ``reset`` options: ``split``, ``index``, ``schedule``, ``realisation`` (below),
    ``volume_fraction`` (must be the model's).

    ## Realisations

    A surrogate episode's noise (the start frame where the data do not hold the train ``index``, the
    ensemble member and every sampled interval) is drawn from a generator: for realisation 0 (the default)
    ``self.np_random`` itself, so that ``reset(seed=s)`` gives the episode it gave before the option was
    honoured, bit for bit; for realisation ``k >= 1``, once the index, schedule and target are set (those of
    realisation 0), a generator of its own, ``numpy.random.default_rng((REALISATION_SEED, split number,
    index, k, d))`` with :data:`dipenv.realisations.REALISATION_SEED`, the split numbers of
    :data:`dipenv.state_library.SPLITS` (train 0, validation 1, test 2, fresh 3) and ``d`` one draw of
    ``self.np_random`` (so the seed still decides the sample). So realisations ``0 .. R-1`` of one episode
    at one seed are ``R`` independent samples of the model, as the simulator's are ``R`` chaotic repeats,
    and every controller that plays realisation ``k`` meets the same start frame, member and draws.

    ## Version History

    * v0 (2026-12-07): issue 43's second fidelity.
    """

    metadata = {"render_modes": [], "render_fps": 4}  # noqa: RUF012
    rate_observed: ClassVar[bool] = True
    reset_options: ClassVar[tuple[str, ...]] = (
        "split",
        "index",
        "volume_fraction",
        "realisation",
        "schedule",
    )
    """The ``reset`` options this env takes (a subclass adds its own)."""

    def __init__(
        self,
        model: str | Path | SurrogateModel | None = None,
        n_particles: int = 64,
        volume_fraction: float = 0.45,
        control_interval: float = 0.25,
        episode_steps: int = 48,
        mason_min: float = DEFAULT_MASON_MIN,
        mason_max: float = DEFAULT_MASON_MAX,
        off_band: float = DEFAULT_OFF_BAND,
        eta_cap: float | None = None,
        energy_weight: float = DEFAULT_ENERGY_WEIGHT,
        failure_penalty: float = DEFAULT_FAILURE_PENALTY,
        history_length: int = 0,
        split: str = "train",
        start_state: str = "random",
        split_sizes: dict[str, int] | None = None,
        rate_range: tuple[float, float] = RATE_RANGE,
        hold_range: tuple[float, float] = HOLD_RANGE,
        ramp_range: tuple[float, float] = RAMP_RANGE,
        max_piece: float = DEFAULT_MAX_PIECE,
        actuator_time_constant: float = 0.0,
        render_mode: str | None = None,
        **simulator_kwargs: Any,
    ) -> None:
        super().__init__()
        unknown = set(simulator_kwargs) - SIMULATOR_ONLY_KWARGS
        if unknown:
            raise TypeError(f"unexpected arguments {sorted(unknown)} for {type(self).__name__}")
        if actuator_time_constant != 0.0:
            raise ValueError(
                f"actuator_time_constant must be 0 (no actuator lag), got {actuator_time_constant!r}"
            )
        if render_mode is not None:
            raise ValueError(
                f"the surrogate env renders nothing: render_mode must be None, got {render_mode!r}"
            )
        check_episode_arguments(episode_steps, history_length, split, start_state, SPLITS)
        if not (math.isfinite(max_piece) and max_piece > 0.0):
            raise ValueError(f"max_piece must be finite and > 0, got {max_piece!r}")
        # every split's size, fresh's default added where not given (as the simulator env resolves them)
        sizes = check_split_sizes(DEFAULT_SPLIT_SIZES if split_sizes is None else split_sizes)
        self.model_path = None if isinstance(model, SurrogateModel) else Path(model or default_model_path())
        self.model = model if isinstance(model, SurrogateModel) else load_model(self.model_path)
        data = self.model.settings
        for name, value in (("n_particles", n_particles), ("volume_fraction", volume_fraction)):
            if name in data and not math.isclose(float(data[name]), float(value), rel_tol=1e-9):
                raise ValueError(f"{name}={value!r}, but the model was fitted at {name}={data[name]!r}")
        if "control_interval" in data and not math.isclose(
            data["control_interval"], control_interval, rel_tol=1e-9
        ):
            raise ValueError(
                f"control_interval={control_interval!r}, but the model was fitted on intervals of "
                f"{data['control_interval']!r}"
            )
        self.n_particles = int(n_particles)
        self.volume_fraction = float(volume_fraction)
        self.control_interval = float(control_interval)
        self.episode_steps = episode_steps
        self.mapping = FieldStrengthMapping(mason_min, mason_max, off_band)
        self.energy_weight = float(energy_weight)
        self.failure_penalty = float(failure_penalty)
        self.history_length = history_length
        self.split = split
        self.start_state = start_state
        self.split_sizes = sizes
        self.rate_range = tuple(float(x) for x in rate_range)
        self.hold_range = tuple(float(x) for x in hold_range)
        self.ramp_range = tuple(float(x) for x in ramp_range)
        self.max_piece = float(max_piece)
        self.ignored = dict(simulator_kwargs)
        self.render_mode = render_mode
        self.reward_function: ViscosityTargetReward = self._make_reward(eta_cap)
        draw_schedule(np.random.default_rng(0), self.episode_duration, rate_range, hold_range, ramp_range)

        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        features = self.frame_features()
        self._obs_low, self._obs_high = observation_bounds(features, history_length)
        self.observation_space = spaces.Box(self._obs_low, self._obs_high, dtype=np.float32)
        self.observation_labels = [
            f"{f.name}[t-{lag}]" if lag else f.name for lag in range(history_length + 1) for f in features
        ]
        self._frame_size = len(features)
        self._obs = np.zeros(self._frame_size * (history_length + 1))
        self._schedule = sim.constant(1.0)
        self._table: IntervalTable | None = None
        self._steps = 0
        self._mason = math.inf
        self._direction: np.ndarray = np.array((0.0, 1.0, 0.0))  # y; a direction-aware model turns it
        self._cycle = 0
        self._noise = np.random.default_rng(0)  # the episode's generator: reset sets it (Realisations)
        self._needs_reset = True
        self._last_eta = math.nan

    # -- configuration ---------------------------------------------------------------------------------------
    @property
    def episode_duration(self) -> float:
        """Time an episode lasts: ``episode_steps * control_interval``."""
        return self.episode_steps * self.control_interval

    def frame_features(self) -> list[ObservationFeature]:
        """The frame of ``ThickeningControl`` (or of the stress-only id)."""
        return thickening_frame_features(self.rate_observed)

    def _make_reward(self, eta_cap: float | None) -> ViscosityTargetReward:
        """The reward object: ``ThickeningPenaltyReward`` at ``eta_cap`` (default: the tabulated cap)."""
        cap = (
            default_viscosity_cap(self.volume_fraction, self.n_particles)
            if eta_cap is None
            else float(eta_cap)
        )
        return ThickeningPenaltyReward(cap, self.energy_weight, self.failure_penalty)

    def settings(self) -> dict[str, Any]:
        """Every setting that shapes an episode (JSON-ready), the model's identity included."""
        digest = ""
        if self.model_path is not None:
            digest = hashlib.sha256(self.model_path.read_bytes()).hexdigest()[:16]
        return {
            "surrogate": {
                "model": str(self.model_path) if self.model_path is not None else "<in memory>",
                "kind": self.model.kind,
                "digest": digest,
            },
            "n_particles": self.n_particles,
            "volume_fraction": self.volume_fraction,
            "control_interval": self.control_interval,
            "episode_steps": self.episode_steps,
            "mason_min": self.mapping.mason_min,
            "mason_max": self.mapping.mason_max,
            "off_band": self.mapping.off_band,
            "reward": {
                "eta_cap": self.reward_function.target_viscosity,
                "energy_weight": self.energy_weight,
                "failure_penalty": self.failure_penalty,
            },
            "history_length": self.history_length,
            "schedule": {
                "rate_range": list(self.rate_range),
                "hold_range": list(self.hold_range),
                "ramp_range": list(self.ramp_range),
                "max_piece": self.max_piece,
            },
            "observation": [f.name for f in self.frame_features()],
            "ignored": sorted(self.ignored),
        }

    def fixed_schedule(self, split: str, index: int) -> sim.PiecewiseLinear:
        """Schedule ``index`` of a fixed split, as :meth:`ThickeningControlEnv.fixed_schedule` gives it."""
        count, seed = FIXED_SPLITS[split]
        defaults = (self.rate_range, self.hold_range, self.ramp_range, self.episode_duration) == (
            RATE_RANGE,
            HOLD_RANGE,
            RAMP_RANGE,
            12.0,
        )
        if defaults and index < count:
            return fixed_schedules(split)[index]
        parameters = (self.rate_range, self.hold_range, self.ramp_range)
        if index < count:
            index_seed = split_seeds(split, self.episode_duration, *parameters)[index]
        else:
            index_seed = seed + STRATIFIED_POOLS.get(split, 0) + index
        return draw_schedule(np.random.default_rng(index_seed), self.episode_duration, *parameters)

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode (options: ``split``, ``index``, ``schedule``, ``realisation``,
        ``volume_fraction``; see the class docstring)."""
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - set(self.reset_options)
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(unknown)}; allowed: {', '.join(self.reset_options)}"
            )
        realisation = options.get("realisation", 0)
        if isinstance(realisation, bool) or not isinstance(realisation, int | np.integer) or realisation < 0:
            raise ValueError(f"options['realisation'] must be an integer >= 0, got {realisation!r}")
        phi = float(options.get("volume_fraction", self.volume_fraction))
        if not math.isclose(phi, self.volume_fraction, rel_tol=1e-9):
            raise ValueError(f"the surrogate holds volume_fraction={self.volume_fraction} only, got {phi!r}")
        split = options.get("split", self.split)
        if split not in SPLITS:
            raise ValueError(f"options['split'] must be one of {', '.join(SPLITS)}, got {split!r}")
        size = self.split_sizes[split]
        index, self._cycle = pick_start_index(options, size, self.start_state, self._cycle, self.np_random)
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < size:
            raise ValueError(f"options['index'] must be an integer in [0, {size}), got {index!r}")
        own = options.get("schedule")
        if own is not None:
            schedule = schedule_from_dict(own)
        elif split == "train":
            schedule = draw_schedule(
                self.np_random, self.episode_duration, self.rate_range, self.hold_range, self.ramp_range
            )
        else:
            schedule = self.fixed_schedule(split, int(index))
        self._schedule = schedule
        self._table = interval_table(schedule, self.episode_steps, self.control_interval, self.max_piece)
        self._after_schedule(split, int(index), options)

        self._noise = self.np_random
        if realisation:  # its own sample of the model (class docstring, Realisations)
            drawn = int(self.np_random.integers(2**63))
            entropy = (REALISATION_SEED, SPLITS.index(split), int(index), int(realisation), drawn)
            self._noise = np.random.default_rng(entropy)
        model = self.model
        matches = np.flatnonzero(model.start_indices == int(index)) if split == "train" else np.empty(0, int)
        row = int(matches[0]) if matches.size else int(self._noise.integers(len(model.start_frames)))
        start = model.start_frames[row]
        model.begin(start, self._noise)
        self._steps = 0
        self._mason = math.inf
        self._needs_reset = False
        eta = float(inverse_signed_log(start[0]))
        n1, n2 = (float(v) for v in inverse_signed_log(start[1:3]))
        frame = self._frame(start, self._table.rate_initial, eta)
        self._obs[:] = np.tile(frame, self.history_length + 1)
        self._last_eta = eta
        info = {
            "split": split,
            "index": int(index),
            "realisation": int(realisation),
            "start_frame": row,
            "volume_fraction": phi,
            "library_key": f"surrogate:{model.kind}",
            "eta_r": eta,
            "n1": n1,
            "n2": n2,
            "target_viscosity": self.reward_function.target_viscosity,
            "strain": 0.0,
            "schedule": schedule_to_dict(schedule),
            "shear_rate": float(schedule(0.0)),
            "eta_cap": self.reward_function.target_viscosity,
            "time": 0.0,
        }
        return self._observation(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Sample one interval of the model under the field of ``action``."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (and after an episode has ended)")
        clipped, was_clipped = validate_action(action, (1,))
        return self._advance(self.mapping.mason_number(float(clipped[0])), was_clipped)

    def render(self) -> None:  # type: ignore[override]
        return None

    # -- internals ------------------------------------------------------------------------------------------
    def _advance(
        self, mason: float, was_clipped: bool, direction: np.ndarray | None = None
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One interval under the field ``mason`` (and ``direction``, for a direction-aware model): sample
        the model, score, update the observation; the step's return value. Subclasses add to it through
        :meth:`_interval_started` and :meth:`_interval_info`."""
        table = self._table
        assert table is not None
        k = self._steps
        self._interval_started(k)
        if direction is None:
            dynamic = self.model.step(self._mason, mason, table, k, self._noise)
        else:
            previous = self._direction
            dynamic = self.model.step(self._mason, mason, table, k, self._noise, previous, direction)
            self._direction = direction
        self._mason = mason
        self._steps += 1
        eta = float(inverse_signed_log(dynamic[0]))
        n1, n2 = (float(v) for v in inverse_signed_log(dynamic[1:3]))
        rate = float(table.rate_mean[k])
        energy = field_energy(mason)
        reward, terms = self.reward_function(eta, energy)
        frame = self._frame(dynamic, float(table.rate_end[k]), eta * rate)
        size = self._frame_size
        if self.history_length:
            self._obs[size:] = self._obs[:-size].copy()
        self._obs[:size] = frame
        truncated = self._steps >= self.episode_steps
        self._needs_reset = truncated
        self._last_eta = eta
        time = self._steps * self.control_interval
        info: dict[str, Any] = {
            "mason_number_command": mason,
            "mason_number": mason,
            "action_clipped": was_clipped,
            "strain": time,
            "simulation_failed": False,
            "failure_message": "",
            "target_viscosity": self.reward_function.target_viscosity,
            "eta_r": eta,
            "n1": n1,
            "n2": n2,
            "field_energy": energy,
            "reward": reward,
            **terms,
            "shear_stress": eta * rate,
            "shear_rate": rate,
            "shear_rate_end": float(table.rate_end[k]),
            "instantaneous_mason_number": math.inf if math.isinf(mason) else rate * mason,
            "eta_cap": self.reward_function.target_viscosity,
            "time": time,
        }
        self._interval_info(k, eta, info)
        return self._observation(), reward, False, truncated, info

    def _interval_started(self, k: int) -> None:
        """Called by :meth:`_advance` before interval ``k`` is sampled (the tracking surrogate sets the
        reward's target to the interval's mean target here)."""

    def _interval_info(self, k: int, eta: float, info: dict[str, Any]) -> None:
        """Called by :meth:`_advance` with interval ``k``'s ``eta_r`` and ``info``, to edit ``info`` in
        place (the tracking surrogate adds its target and error)."""

    def _after_schedule(self, split: str, index: int, options: dict[str, Any]) -> None:
        """Called by ``reset`` once the schedule is set, before the start frame is chosen (the tracking
        surrogate draws its target here, as the simulator env draws it after the schedule)."""

    def _frame(self, dynamic: np.ndarray, rate_end: float, shear_stress: float) -> np.ndarray:
        mason = self._mason
        energy_fraction = 0.0 if math.isinf(mason) else min(1.0, self.mapping.mason_min / mason)
        frame = np.empty(self._frame_size)
        frame[:N_DYNAMIC] = dynamic
        frame[N_DYNAMIC] = energy_fraction
        frame[N_DYNAMIC + 1] = self.mapping.coordinate(mason)
        if self.rate_observed:
            frame[N_DYNAMIC + 2] = math.log10(rate_end)
        else:
            frame[0] = math.copysign(math.log10(1.0 + abs(shear_stress)), shear_stress)
        return frame

    def _observation(self) -> np.ndarray:
        return np.clip(self._obs, self._obs_low, self._obs_high).astype(np.float32)


class ThickeningControlSurrogateStressOnlyEnv(ThickeningControlSurrogateEnv):
    """As :class:`ThickeningControlSurrogateEnv`, with the observation of
    :class:`dipenv.envs.thickening_control.ThickeningControlStressOnlyEnv`: index 0 is ``slog`` of the
    interval's shear stress ``Sigma_xy`` (the model's ``eta_r`` times the interval's mean rate; at reset
    the start frame's ``eta_r``, pre-sheared at rate 1), and neither ``eta_r`` nor the rate is observed."""

    rate_observed = False


def surrogate_kwargs(env_id: str, **overrides: Any) -> dict[str, Any]:
    """Keyword arguments that give a surrogate env the settings of the simulator id ``env_id`` (its
    registered kwargs, less those the surrogate ignores), updated with ``overrides``."""
    spec = gym.spec(env_id)
    kwargs = {k: v for k, v in dict(spec.kwargs).items() if k not in SIMULATOR_ONLY_KWARGS}
    kwargs.update(overrides)
    return kwargs
