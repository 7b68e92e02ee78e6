"""Gymnasium environments: set the electric field on a sheared dense suspension to hold its viscosity down.

Two classes share one implementation (:class:`FieldControlEnv`): :class:`FieldMagnitudeEnv` (field
strength only, direction fixed along the velocity gradient ``y``, the paper's setting) and
:class:`FieldVectorEnv` (strength and direction). Units as in ``sim``: ``a = eta = gammadot = 1``,
time is strain, stress is in ``eta gammadot``; ``Mn = eta gammadot / (eps E0^2)``.
"""

from __future__ import annotations

import math
import os
from dataclasses import fields, replace
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
    ActuatorFilter,
    FieldStrengthMapping,
    canonical_direction,
    direction_from_action,
    field_energy,
    validate_action,
)
from dipenv.checks import check_episode_arguments, is_real_number, real_number
from dipenv.observations import (
    MICROSTRUCTURE_DOC_ROWS,
    ObservationFeature,
    microstructure_features,
    observation_bounds,
    observation_features,
    observation_frame,
)
from dipenv.realisations import perturbed_state
from dipenv.rewards import (
    DEFAULT_ENERGY_WEIGHT,
    DEFAULT_FAILURE_PENALTY,
    ViscosityTargetReward,
    default_target_viscosity,
)
from dipenv.state_library import (
    DEFAULT_SPLIT_SIZES,
    SPLITS,
    StartState,
    StateLibrary,
    check_split_sizes,
    pick_start_index,
)

DEFAULT_N_PARTICLES = 64
DEFAULT_VOLUME_FRACTION = 0.45
DEFAULT_CONTROL_INTERVAL = 0.25
DEFAULT_EPISODE_STEPS = 48
DEFAULT_SOLVER_TOLERANCE = 1e-6
DEFAULT_EWALD_ACCURACY = 1e-4
"""Requested relative accuracy of the Ewald-summed dipolophoretic velocities in the environments (the
simulator's default is 1e-6). Measured at N = 64, phi = 0.45 on four sheared states against 1e-10: RMS
velocity error 0.8-1.1e-5 and stress error below 5e-7 of the largest DIP stress, far below the
near-field tables' interpolation error and the 2-5% statistical error of an interval-averaged eta_r;
it saves 15-30% of the DIP term's cost per step at N = 64."""
DEFAULT_PRESHEAR_STRAIN = 5.0

_Y = np.array([0.0, 1.0, 0.0])


_ENV_SET_FIELDS = frozenset(
    {"n_particles", "volume_fraction", "mason_number", "field_direction", "shear_rate"}
)
"""Simulation fields an env sets itself (the box and phi from its arguments and start states, the field
from the actions, the rate from the start state or schedule): not accepted as ``simulation_overrides``."""


def _check_overrides(overrides: object) -> dict[str, Any]:
    """``simulation_overrides`` as a dict of :class:`sim.SimulationConfig` fields with valid values, or
    ``ValueError`` naming what is wrong (an unknown field used to fail only at the first reset)."""
    if overrides is None:
        return {}
    if not isinstance(overrides, dict):
        raise ValueError(
            f"simulation_overrides must be a dict of sim.SimulationConfig fields, got {overrides!r}"
        )
    names = {f.name for f in fields(sim.SimulationConfig)}
    for key in overrides:
        if key not in names:
            raise ValueError(f"simulation_overrides: {key!r} is not a sim.SimulationConfig field")
        if key in _ENV_SET_FIELDS:
            raise ValueError(
                f"simulation_overrides: {key!r} is set by the environment itself (its own arguments, start "
                "states, actions or schedule)"
            )
    try:
        sim.SimulationConfig(n_particles=64, volume_fraction=0.45, **overrides)
    except (TypeError, ValueError) as error:
        raise ValueError(f"simulation_overrides {overrides!r} are refused: {error}") from None
    return dict(overrides)


class FieldControlEnv(gym.Env[np.ndarray, np.ndarray]):
    """Shared implementation of :class:`FieldMagnitudeEnv` and :class:`FieldVectorEnv` (see their docstrings).

    Args:
        n_particles: spheres N in the Lees–Edwards box (>= 64 at phi = 0.45 with the exact near field's
            default cut-off 4 a).
        volume_fraction: phi (start-state library and episodes; ``reset(options={"volume_fraction": p})``
            changes it for one episode).
        control_interval: strain over which one action holds (many simulator steps), > 0.
        episode_steps: actions per episode; the episode is then ``truncated``.
        mason_min, mason_max, off_band: the strength mapping (:class:`dipenv.actions.FieldStrengthMapping`).
        actuator_time_constant: first-order lag of the field amplitude (strain); 0 = ideal actuator.
        actuator_substeps: piecewise-constant sub-intervals per interval when the lag is on.
        target_viscosity: eta_target of the reward; None = the tabulated open-loop default for phi.
        energy_weight: w_E of the reward.
        failure_penalty: reward per failed or lost step on a simulator failure.
        history_length: previous observation frames appended to the current one (0 = none).
        split: start-state split for resets without ``options["split"]`` (train, validation, test or
            fresh: the held-out split of the final evaluation, docs/thickening_control.md#the-fresh-split).
        start_state: ``"random"`` (drawn with ``self.np_random``) or ``"cycle"`` (0, 1, 2, ... in turn:
            every state of the split once per cycle, for evaluation).
        split_sizes: states per split of the library (default train 64, validation 8, test 16; fresh
            optional, default 128, :data:`dipenv.state_library.DEFAULT_FRESH_SIZE`). A state is generated
            when a reset first asks for it (or by ``library().ensure``), so a size costs nothing by itself.
        preshear_strain: strain of pure shear that prepares each start state.
        solver_tolerance, ewald_accuracy, near_field, near_field_cutoff, time_step, max_displacement:
            passed to :class:`sim.SimulationConfig` (``ewald_accuracy`` defaults to
            :data:`DEFAULT_EWALD_ACCURACY`, looser than the simulator's 1e-6; see there for its cost).
        simulation_overrides: further :class:`sim.SimulationConfig` fields for the episodes only (not for
            the start-state library), e.g. to trigger the failure path in tests.
        library_root: cache root of the start states (default ``$DIPENV_CACHE_DIR`` or
            ``~/.cache/dipenv``).
        progress: show a progress bar while generating start states.
        render_mode: None or ``"rgb_array"``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012
    vector_field: ClassVar[bool] = False
    target_name: ClassVar[str] = "target_viscosity"
    """The argument that sets the reward's target (the thickening-control envs: ``eta_cap``)."""
    reset_options: ClassVar[tuple[str, ...]] = ("split", "index", "volume_fraction", "realisation")
    """The keys ``reset(options=...)`` accepts (a subclass adds its own)."""

    def __init__(
        self,
        n_particles: int = DEFAULT_N_PARTICLES,
        volume_fraction: float = DEFAULT_VOLUME_FRACTION,
        control_interval: float = DEFAULT_CONTROL_INTERVAL,
        episode_steps: int = DEFAULT_EPISODE_STEPS,
        mason_min: float = DEFAULT_MASON_MIN,
        mason_max: float = DEFAULT_MASON_MAX,
        off_band: float = DEFAULT_OFF_BAND,
        actuator_time_constant: float = 0.0,
        actuator_substeps: int = 4,
        target_viscosity: float | None = None,
        energy_weight: float = DEFAULT_ENERGY_WEIGHT,
        failure_penalty: float = DEFAULT_FAILURE_PENALTY,
        history_length: int = 0,
        split: str = "train",
        start_state: str = "random",
        split_sizes: dict[str, int] | None = None,
        preshear_strain: float = DEFAULT_PRESHEAR_STRAIN,
        solver_tolerance: float = DEFAULT_SOLVER_TOLERANCE,
        ewald_accuracy: float = DEFAULT_EWALD_ACCURACY,
        near_field: str = "exact",
        near_field_cutoff: float = 4.0,
        time_step: float = 2e-3,
        max_displacement: float = 4e-3,
        simulation_overrides: dict[str, Any] | None = None,
        library_root: str | Path | None = None,
        progress: bool = True,
        render_mode: str | None = None,
    ) -> None:
        super().__init__()
        control_interval = real_number("control_interval", control_interval, 0.0, low_open=True)
        check_episode_arguments(episode_steps, history_length, split, start_state, SPLITS)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        resolved_sizes = check_split_sizes(DEFAULT_SPLIT_SIZES if split_sizes is None else split_sizes)
        # Numbers are checked here, by name: a string or a bool used to reach float() or a comparison
        # (Python's message), and a zero pre-shear or a negative target were accepted.
        mason_min = real_number("mason_min", mason_min, 0.0, low_open=True)
        mason_max = real_number("mason_max", mason_max, 0.0, low_open=True)
        off_band = real_number("off_band", off_band, 0.0)
        actuator_time_constant = real_number("actuator_time_constant", actuator_time_constant, 0.0)
        energy_weight = real_number("energy_weight", energy_weight, 0.0)
        failure_penalty = real_number("failure_penalty", failure_penalty, 0.0)
        preshear_strain = real_number("preshear_strain", preshear_strain, 0.0, low_open=True)
        if target_viscosity is not None:
            target_viscosity = real_number(self.target_name, target_viscosity, 0.0, low_open=True)
        if not isinstance(progress, bool):
            raise ValueError(f"progress must be True or False, got {progress!r}")
        if library_root is not None and (
            not isinstance(library_root, str | os.PathLike) or library_root == ""
        ):
            raise ValueError(
                f"library_root must be a folder path (or None for the default cache), got {library_root!r}"
            )
        overrides = _check_overrides(simulation_overrides)
        self.control_interval = control_interval
        self.episode_steps = episode_steps
        self.mapping = FieldStrengthMapping(mason_min, mason_max, off_band)
        self.actuator = ActuatorFilter(actuator_time_constant, actuator_substeps)
        self.energy_weight = energy_weight
        self.failure_penalty = failure_penalty
        self.explicit_target = target_viscosity
        self.history_length = history_length
        self.split = split
        self.start_state = start_state
        self.split_sizes = resolved_sizes
        self.preshear_strain = preshear_strain
        self.progress = progress
        self.render_mode = render_mode
        self.library_root = None if library_root is None else Path(library_root)
        self.base_config = sim.SimulationConfig(
            n_particles=n_particles,
            volume_fraction=volume_fraction,
            strain=self.preshear_strain,
            solver_tolerance=solver_tolerance,
            ewald_accuracy=ewald_accuracy,
            near_field=near_field,
            near_field_cutoff=near_field_cutoff,
            time_step=time_step,
            max_displacement=max_displacement,
        )
        self.simulation_overrides = overrides
        # Checks now that the field can be switched on at all (exact near field needs a wide enough box),
        # in the library's box and in the episodes' (the overrides may change the cut-off).
        self.base_config.check_near_field_box()
        try:
            replace(self.base_config, **overrides).check_near_field_box()
        except ValueError as error:
            raise ValueError(f"simulation_overrides {overrides!r} are refused: {error}") from None
        self.reward_function = self._reward_for(volume_fraction)

        n_actions = 3 if self.vector_field else 1
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n_actions,), dtype=np.float32)
        features = self.frame_features()
        self._obs_low, self._obs_high = observation_bounds(features, history_length)
        self.observation_space = spaces.Box(self._obs_low, self._obs_high, dtype=np.float32)
        self.observation_labels = [
            f"{f.name}[t-{lag}]" if lag else f.name for lag in range(history_length + 1) for f in features
        ]

        self._libraries: dict[float, StateLibrary] = {}
        self._start_cache: dict[tuple[float, str, int], StartState] = {}
        self._simulation: sim.Simulation | None = None
        self._simulation_phi: float | None = None
        self._cycle = 0
        self._steps = 0
        self._episode_start = 0.0
        self._amplitude = 0.0
        self._mason = math.inf
        self._direction = _Y.copy()
        self._frames: list[np.ndarray] = []
        self._needs_reset = True
        self._last_info: dict[str, Any] = {}

    # -- configuration ---------------------------------------------------------------------------------------
    def frame_features(self) -> list[ObservationFeature]:
        """The labelled layout of one observation frame (:func:`dipenv.observations.observation_features`)."""
        return observation_features(self.vector_field)

    def _reward_for(self, volume_fraction: float) -> ViscosityTargetReward:
        target = self.explicit_target
        if target is None:
            target = default_target_viscosity(volume_fraction, self.base_config.n_particles)
        return ViscosityTargetReward(float(target), self.energy_weight, self.failure_penalty)

    def settings(self) -> dict[str, Any]:
        """Every resolved setting that shapes an episode (JSON-ready), defaults included.

        Stored next to results made with this env (open-loop points, training runs) so that a result is
        reused only for the same settings, even when a default changes between versions. The reward's
        parameters sit under ``"reward"``: they do not change the physics, so results that keep their
        per-step ``eta_r`` and field energy (open-loop points) can be rescored instead of rerun.
        """
        config = self.base_config.to_dict()
        for name in ("seed", "strain", "transient_strain", "checkpoint_every", "n_blocks"):
            config.pop(name, None)
        return {
            "simulation": config,
            "simulation_overrides": dict(self.simulation_overrides),
            "control_interval": self.control_interval,
            "episode_steps": self.episode_steps,
            "mason_min": self.mapping.mason_min,
            "mason_max": self.mapping.mason_max,
            "off_band": self.mapping.off_band,
            "actuator_time_constant": self.actuator.time_constant,
            "actuator_substeps": self.actuator.substeps,
            "reward": {
                "target_viscosity": self.reward_function.target_viscosity,
                "energy_weight": self.energy_weight,
                "failure_penalty": self.failure_penalty,
            },
            "history_length": self.history_length,
            "preshear_strain": self.preshear_strain,
        }

    def library(self, volume_fraction: float | None = None) -> StateLibrary:
        """The start-state library of ``volume_fraction`` (default: the env's)."""
        phi = self.base_config.volume_fraction if volume_fraction is None else float(volume_fraction)
        if phi not in self._libraries:
            config = replace(self.base_config, volume_fraction=phi)
            self._libraries[phi] = StateLibrary(
                config,
                self.preshear_strain,
                min(1.0, 0.5 * self.preshear_strain),
                self.split_sizes,
                self.library_root,
            )
        return self._libraries[phi]

    def _episode_simulation(self, volume_fraction: float, start: StartState) -> sim.Simulation:
        if self._simulation is None or self._simulation_phi != volume_fraction:
            config = replace(self.base_config, volume_fraction=volume_fraction, **self.simulation_overrides)
            config.check_near_field_box()
            self._simulation = sim.Simulation(config, state=start.state, keep_records=False)
            self._simulation_phi = volume_fraction
        return self._simulation

    def _start_state(self, volume_fraction: float, split: str, index: int) -> StartState:
        key = (volume_fraction, split, index)
        if key not in self._start_cache:
            self._start_cache[key] = self.library(volume_fraction).load(split, index, progress=self.progress)
        return self._start_cache[key]

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode from a pre-sheared state (field off).

        ``options`` (:attr:`reset_options`; checked first, so that a refused reset changes nothing):
        ``split`` (train/validation/test/fresh), ``index`` (state within the split; default drawn
        with ``self.np_random``, or the next in turn with ``start_state="cycle"``), ``volume_fraction``,
        ``realisation`` (integer >= 0, default 0: the state moved by 1e-9 a with a displacement fixed by
        ``(split, index, realisation)``, for independent repeats of one episode; 0 is the stored state
        itself; :mod:`dipenv.realisations`).
        """
        return self._reset_checked(seed, self._check_reset_options(options))

    def _check_reset_options(self, options: object) -> dict[str, Any]:
        """``options`` checked before anything changes (a refused reset leaves the env as it was): a dict
        of :attr:`reset_options` with valid values, or ``ValueError`` naming the option and what is wrong.
        Returns a copy."""
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise ValueError(
                f"reset options must be a dict (or None) of {', '.join(self.reset_options)}, got "
                f"{options!r}"
            )
        unknown = [key for key in options if key not in self.reset_options]
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(map(str, unknown))}; {type(self).__name__} accepts: "
                f"{', '.join(self.reset_options)}"
            )
        options = dict(options)
        realisation = options.get("realisation", 0)
        if isinstance(realisation, bool) or not isinstance(realisation, int | np.integer) or realisation < 0:
            raise ValueError(f"options['realisation'] must be an integer >= 0, got {realisation!r}")
        split = options.get("split", self.split)
        if not isinstance(split, str) or split not in SPLITS:
            raise ValueError(f"options['split'] must be one of {', '.join(SPLITS)}, got {split!r}")
        if "index" in options:
            index, size = options["index"], self.split_sizes[split]
            if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < size:
                raise ValueError(
                    f"options['index'] must be an integer in [0, {size}) for split {split!r}, got {index!r}"
                )
        if "volume_fraction" in options:
            phi = options["volume_fraction"]
            if not is_real_number(phi):
                raise ValueError(f"options['volume_fraction'] must be a real number, got {phi!r}")
            try:
                config = replace(self.base_config, volume_fraction=float(phi))
                config.check_near_field_box()
                self._reward_for(float(phi))  # a tabulated default target or cap, or an explicit one
            except ValueError as error:
                raise ValueError(f"options['volume_fraction'] = {phi!r} is refused: {error}") from None
        return options

    def _reset_checked(self, seed: int | None, options: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        """:meth:`reset` once :meth:`_check_reset_options` has accepted ``options``."""
        super().reset(seed=seed)
        self._needs_reset = True  # until this reset has finished
        realisation = options.get("realisation", 0)
        split = options.get("split", self.split)
        phi = float(options.get("volume_fraction", self.base_config.volume_fraction))
        size = self.split_sizes[split]
        index, self._cycle = pick_start_index(options, size, self.start_state, self._cycle, self.np_random)
        self.reward_function = self._reward_for(phi)
        start = self._start_state(phi, split, int(index))
        simulation = self._episode_simulation(phi, start)
        if realisation:
            box = simulation.config.box_length
            simulation.restore(perturbed_state(start.state, box, split, int(index), int(realisation)))
        else:
            simulation.restore(start.state)
        simulation.set_field(math.inf, _Y)
        self._steps = 0
        self._episode_start = simulation.state.time
        self._amplitude = 0.0
        self._mason = math.inf
        self._direction = _Y.copy()
        eta, n1, n2 = (float(x) for x in start.tail_average(self.control_interval))
        frame = self._frame(eta, n1, n2, eta)  # pre-sheared at the reference rate: Sigma_xy = eta_r
        self._frames = [frame] * (self.history_length + 1)
        self._needs_reset = False
        info = {
            "split": split,
            "index": int(index),
            "realisation": int(realisation),
            "packing_seed": start.seed,
            "volume_fraction": phi,
            "library_key": self.library(phi).key,
            "eta_r": eta,
            "n1": n1,
            "n2": n2,
            "target_viscosity": self.reward_function.target_viscosity,
            "strain": 0.0,
        }
        self._last_info = info
        return self._observation(), dict(info)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Hold the field given by ``action`` for one control interval (see the class docstring)."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (and after an episode has ended)")
        clipped, was_clipped = validate_action(action, (3,) if self.vector_field else (1,))
        command_mn = self.mapping.mason_number(float(clipped[0]))
        direction = self._action_direction(clipped) if self.vector_field else _Y
        simulation = self._simulation
        assert simulation is not None
        amplitudes, end_amplitude = self.actuator.schedule(
            self._amplitude, self.mapping.amplitude(command_mn), self.control_interval
        )
        # Without lag the commanded Mn is used as is (the amplitude round trip would change its last bit).
        masons = (
            [command_mn]
            if self.actuator.time_constant == 0.0
            else [self.mapping.mason_for_amplitude(a) for a in amplitudes]
        )
        start = self._episode_start + self._steps * self.control_interval
        parts: list[sim.StepRecords] = []
        failure = ""
        try:
            for k, mason in enumerate(masons):
                simulation.set_field(mason, direction)
                end = start + (k + 1) * self.control_interval / len(masons)
                parts.append(self._advance(simulation, end))
        except sim.SimulationError as error:
            failure = str(error)
        self._steps += 1
        self._amplitude = end_amplitude
        lagging = self.actuator.time_constant > 0.0
        self._mason = self.mapping.mason_for_amplitude(end_amplitude) if lagging else command_mn
        self._direction = canonical_direction(direction)
        mn_end = self._mason
        info: dict[str, Any] = {
            "mason_number_command": command_mn,
            "mason_number": mn_end,
            "field_direction": self._direction.copy(),
            "action_clipped": was_clipped,
            "strain": simulation.state.time - self._episode_start,  # time since the start; strain at rate 1
            "simulation_failed": False,
            "failure_message": "",
            "target_viscosity": self.reward_function.target_viscosity,
        }
        means = None if failure else self._interval_means(parts)
        if means is None or not np.all(np.isfinite(simulation.state.positions)):
            failure = failure or "non-finite stress or positions"
            reward, terms = self.reward_function.failure(self.episode_steps - self._steps)
            info.update(terms)
            info.update(simulation_failed=True, failure_message=failure, reward=reward)
            info.update({k: v for k, v in self._last_info.items() if k in ("eta_r", "n1", "n2")})
            self._needs_reset = True
            self._last_info = info
            return self._observation(), reward, True, False, info
        eta, n1, n2, energy, extra = means
        reward, terms = self.reward_function(eta, energy)
        info.update(eta_r=eta, n1=n1, n2=n2, field_energy=energy, reward=reward, **terms, **extra)
        frame = self._frame(eta, n1, n2, extra["shear_stress"])
        self._frames = [frame, *self._frames[:-1]]
        truncated = self._steps >= self.episode_steps
        self._needs_reset = truncated
        self._last_info = info
        return self._observation(), reward, False, truncated, info

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        """``rgb_array``: x–y projection of the particles (shade: z) with the field arrow; None otherwise."""
        if self.render_mode != "rgb_array" or self._simulation is None:
            return None
        from dipenv.rendering import render_projection

        config = self._simulation.config
        return render_projection(
            self._simulation.state.positions,
            config.box_length,
            self._direction,
            self._amplitude,
            title=(
                f"time {self._simulation.state.time - self._episode_start:.2f}  "
                f"eta_r {self._last_info.get('eta_r', float('nan')):.2f}  "
                f"Mn {self._mason:.3g}"
            ),
        )

    def close(self) -> None:
        self._simulation = None
        self._start_cache.clear()

    # -- internals ------------------------------------------------------------------------------------------
    def _action_direction(self, clipped: np.ndarray) -> np.ndarray:
        """The field direction of a vector env's clipped action ``[u, polar, azimuth]``
        (:func:`dipenv.actions.direction_from_action`; a subclass may refine it)."""
        return direction_from_action(float(clipped[1]), float(clipped[2]))

    def _advance(self, simulation: sim.Simulation, end_time: float) -> sim.StepRecords:
        """Advance the episode's simulation to the clock ``end_time`` (the shear rate held as it is)."""
        return simulation.advance_to(end_time)

    def _interval_means(
        self, parts: list[sim.StepRecords]
    ) -> tuple[float, float, float, float, dict[str, Any]] | None:
        """Time averages over the interval's steps (weights: step sizes); None if anything is not finite."""
        time_steps = np.concatenate([p.time_step for p in parts])
        if time_steps.size == 0:
            return None
        stress = np.concatenate([p.stress.sum(axis=1) for p in parts])
        rates = np.concatenate([p.shear_rate for p in parts])
        eta, n1, n2 = sim.rheology(stress, rates)
        mason = np.concatenate([p.mason_number for p in parts])
        energy = np.array([field_energy(float(m)) for m in mason])
        w = time_steps / time_steps.sum()
        values = [float(np.dot(w, x)) for x in (eta, n1, n2, energy)]
        if not all(math.isfinite(v) for v in values):
            return None
        u_dip = np.concatenate([p.u_rms_dip for p in parts])
        u_shear = np.concatenate([p.u_rms_shear for p in parts])
        extra = {
            "shear_stress": float(np.dot(w, stress[:, 0, 1])),
            "shear_rate": float(np.dot(w, rates)),
            "sim_steps": int(time_steps.size),
            "solver_iterations": float(np.mean(np.concatenate([p.solver_iterations for p in parts]))),
            "overlap_sweeps": float(np.mean(np.concatenate([p.overlap_sweeps for p in parts]))),
            "min_gap": float(np.min(np.concatenate([p.min_gap for p in parts]))),
            "u_rms_dip": float(np.sqrt(np.dot(w, u_dip**2))),
            "u_rms_shear": float(np.sqrt(np.dot(w, u_shear**2))),
            # eta_r split by stress contribution (they sum to eta_r up to rounding)
            "eta_r_contributions": {
                name: float(np.dot(w, contribution))
                for name, contribution in zip(
                    sim.STRESS_CONTRIBUTIONS,
                    np.concatenate([p.stress[:, :, 0, 1] for p in parts]).T / rates,
                    strict=True,
                )
            },
        }
        return values[0], values[1], values[2], values[3], extra

    def _frame(self, eta: float, n1: float, n2: float, shear_stress: float) -> np.ndarray:
        """One observation frame from the interval means (``shear_stress``: ``Sigma_xy`` in
        ``eta gammadot_ref``, unused here) and the end state."""
        simulation = self._simulation
        assert simulation is not None
        state = simulation.state
        micro = microstructure_features(
            state.positions, simulation.config.box_length, state.strain, self._direction
        )
        mn = self._mason
        energy_fraction = min(1.0, self._amplitude**2)
        return observation_frame(
            eta,
            n1,
            n2,
            micro,
            energy_fraction,
            self.mapping.coordinate(mn),
            self._direction if self.vector_field else None,
        )

    def _observation(self) -> np.ndarray:
        obs = np.concatenate(self._frames)
        return np.clip(obs, self._obs_low, self._obs_high).astype(np.float32)


_DOC_COMMON = """
    ## Observation Space

    ``Box`` of float32 with finite bounds; one frame per row below, repeated for ``history_length``
    previous intervals (frame ``t-1`` after frame ``t``; at reset the history repeats the first frame).
    Values are clipped into the bounds. Stresses are time averages over the last control interval (the
    first observation: over the last ``control_interval`` strains of the pre-shear); the microstructure
    is that of the configuration at the end of the interval. ``slog(x) = sign(x) log10(1 + |x|)``.

    | index | name | quantity | units | range |
    |---|---|---|---|---|
    | 0 | slog_eta_r | interval-averaged relative viscosity eta_r | slog(eta gammadot) | [-6, 6] |
    | 1 | slog_n1 | interval-averaged N1 = S_xx - S_yy | slog(eta gammadot) | [-6, 6] |
    | 2 | slog_n2 | interval-averaged N2 = S_yy - S_zz | slog(eta gammadot) | [-6, 6] |
    {microstructure_rows}
    | 12 | field_energy_fraction | (E0 / E0_max)^2 = Mn_min / Mn of the field in force (0: off) | 1 | [0, 1] |
    | 13 | field_coordinate | strength-action coordinate of that Mn (-1: off) | 1 | [-1, 1] |
    {direction_rows}

    theta is the angle from the field; the g bins ``abs(cos theta)`` in [0, 1/3) (equator), [1/3, 2/3),
    [2/3, 1] (pole) have equal solid angles; g is normalised by the ideal-gas count (1 for a gas).

    ## Rewards

    ``r = -|eta_r - eta_target| - w_E <eps E0^2>`` (units eta gammadot): ``eta_r`` is averaged over the
    interval (time-weighted over the simulator steps), ``<eps E0^2> = <1/Mn>`` is the time-averaged field
    energy density, i.e. the field energy per unit volume per unit strain. Default ``eta_target``: the
    open-loop ``eta_r`` of a strong constant field at this phi
    (:data:`dipenv.rewards.DEFAULT_TARGET_VISCOSITY`); ``w_E = 1``. ``info`` holds ``reward_viscosity``,
    ``reward_energy``, ``reward_failure`` and the raw physics: ``eta_r``, ``n1``, ``n2``,
    ``field_energy``, ``mason_number`` (in force at the end), ``mason_number_command``,
    ``field_direction``, ``u_rms_dip``, ``u_rms_shear``, ``sim_steps``,
    ``solver_iterations``, ``overlap_sweeps``, ``min_gap``, ``strain`` (since the episode start), and
    ``eta_r_contributions``: ``eta_r`` split by stress contribution (a dict over
    :data:`sim.STRESS_CONTRIBUTIONS`: solvent, Stokes drag, lubrication, repulsion, the ICEP and DEP
    parts; each the interval's time average of ``Sigma_xy^c / (eta gammadot)``, summing to ``eta_r``).

    ## Starting State

    A pre-sheared state from :class:`dipenv.state_library.StateLibrary`: a random packing sheared
    without field for ``preshear_strain`` (5) strains; generated on first use (progress bar) and cached
    under ``~/.cache/dipenv``. The state is drawn with ``self.np_random`` from the ``split`` (train by
    default; ``start_state="cycle"`` takes them in turn); ``reset(options=...)`` may pin ``split``,
    ``index`` and ``volume_fraction``. The field starts off. The simulator is deterministic, so the same
    seed and actions give identical trajectories.

    ## Episode End

    Truncation after ``episode_steps`` actions (48 = 12 strains at the defaults). Termination when the
    simulator fails (overlap removal or the solver does not converge, or a non-finite stress): reward
    ``-failure_penalty * (1 + steps left)``, ``info["simulation_failed"] = True`` and
    ``info["failure_message"]``; no exception escapes ``step``. ``step`` before ``reset`` (or after the
    end) raises ``RuntimeError``.

    ## Arguments

    See :class:`FieldControlEnv`. Defaults: N = 64, phi = 0.45, ``control_interval`` = 0.25 strain,
    ``episode_steps`` = 48, Mn in [0.05, 20] plus off, ``solver_tolerance`` = 1e-6, ``ewald_accuracy`` =
    1e-4, exact near field (cut-off 4 a), no actuator lag, no history.

    ## Version History

    * v0: initial version. Revised before any release (2026-12-02): the simulator's lubrication
      regularisation became 1e-3 (was 1e-4) and the default target 6.1 (was 7.5); ``settings()``
      records both, so stored open-loop points and training runs of the earlier revision are not
      reused.
    * v1 (2026-12-03): N = 300 instead of 64, the box-size study's smallest box whose episode-averaged
      eta_r matches the bulk's (docs/environments.md#box-size); the default target is N = 300's
      plateau (:data:`dipenv.rewards.DEFAULT_TARGET_VISCOSITY`). Everything else is as v0.
    """


class FieldMagnitudeEnv(FieldControlEnv):
    """## Description

    A dense suspension (N ideally conductive spheres at volume fraction phi in a Lees–Edwards box) is
    sheared at a constant rate; an electric field along the velocity gradient ``y`` drives
    dipolophoresis, which at low Mason number breaks up the shear-thickened contact network and lowers
    the viscosity (Mirfendereski & Park 2024, §3.1). The agent sets the field strength once per control
    interval (0.25 strain = 125 simulator steps at Mn >= 1) to hold the viscosity at a low target while
    spending as little field energy as possible.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the strength action ``u``. ``u < -0.9`` (the off band) switches the
    field off; ``u`` in ``[-0.9, 1]`` maps log-linearly to ``Mn`` from 20 (weakest) to 0.05 (strongest)
    (:class:`dipenv.actions.FieldStrengthMapping`). Actions outside ``[-1, 1]`` are clipped (flagged in
    ``info["action_clipped"]``); NaN/inf or a wrong shape raise ``ValueError``. With
    ``actuator_time_constant > 0`` the amplitude ``E0`` follows the command with a first-order lag.
    """

    __doc__ = (__doc__ or "") + _DOC_COMMON.format(
        microstructure_rows=MICROSTRUCTURE_DOC_ROWS, direction_rows=""
    )
    vector_field = False


class FieldVectorEnv(FieldControlEnv):
    """## Description

    As :class:`FieldMagnitudeEnv`, but the agent also turns the field: strength and direction are set
    once per control interval. The direction is the wider lever: in bulk (N = 500, phi = 0.45) eta_r is
    about 8.5 with the field along y and 26-32 along z (vorticity) at Mn 0.2-1, against 10 without a
    field; the map over direction, Mn and phi is in ``docs/direction.md``.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: ``[u, polar, azimuth]``. ``u`` maps to ``Mn`` as in
    :class:`FieldMagnitudeEnv`; the direction is ``e = (sin t cos p, cos t, sin t sin p)`` with
    ``t = (polar + 1) pi/4`` in ``[0, pi/2]`` from ``y`` and ``p = azimuth pi`` in the x–z plane
    (``e`` and ``-e`` are the same field, so the hemisphere covers every direction;
    :func:`dipenv.actions.direction_from_action`). The direction switches at once (no lag). Clipping and
    errors as in :class:`FieldMagnitudeEnv`.
    """

    __doc__ = (__doc__ or "") + _DOC_COMMON.format(
        microstructure_rows=MICROSTRUCTURE_DOC_ROWS,
        direction_rows=(
            "| 14-16 | field_ex, field_ey, field_ez | field direction, flipped to e_y >= 0 | 1 |"
            " [-1, 1], [0, 1], [-1, 1] |"
        ),
    )
    vector_field = True
