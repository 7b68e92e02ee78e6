"""``Simulation``: the one object that owns state and the step loop.

The step itself is compiled (:func:`sim.stepper.advance`); this facade calls it in chunks of many steps,
keeps the per-step records (stress per contribution, minimum gap, solver iterations), and offers
snapshot/restore for environments that reset from pre-sheared states.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from dataclasses import field as dataclass_field
from typing import Any

import numpy as np

from sim.config import SimulationConfig
from sim.geometry.configurations import random_packing
from sim.observables.stress import (
    N_CONTRIBUTIONS,
    STRESS_CONTRIBUTIONS,
    block_average,
    particle_pressure,
    rheology,
)
from sim.state import SimulationState
from sim.step_parameters import field_parameters, run_ewald_plan, step_parameters
from sim.stepper import STATUS_MESSAGES, STATUS_OK, advance, stop_time


class SimulationError(RuntimeError):
    """A step failed (solver or overlap removal did not converge); the message says where."""


_RECORD_FIELDS = (
    "strain",
    "time_step",
    "stress",
    "min_gap",
    "solver_iterations",
    "overlap_sweeps",
    "u_rms_dip",
    "u_rms_shear",
    "mason_number",
)


@dataclass
class StepRecords:
    """Per-step records; the stress of a step is evaluated at the configuration the step starts from.

    Averages over records are time averages: each sample stands for the step that follows it
    (``time_step``), which varies when the step adapts.

    Attributes:
        strain: (S,) clock at which each sample was evaluated (strain, or time a/U0 when quiescent).
        time_step: (S,) size of the step taken after the sample.
        stress: (S, C, 3, 3) stress contributions (units eta gammadot; eps E0^2 when quiescent),
            C = len(STRESS_CONTRIBUTIONS).
        min_gap: (S,) smallest surface gap among listed pairs (units a).
        solver_iterations: (S,) PCG iterations.
        overlap_sweeps: (S,) overlap-removal sweeps after the step (0 when nothing overlapped).
        u_rms_dip: (S,) RMS over particles of the dipolophoretic velocity ``|U^d|``.
        u_rms_shear: (S,) RMS over particles of the shear-and-repulsion disturbance velocity
            ``|U' |`` (translational, the affine ``u_inf`` excluded).
        mason_number: (S,) Mason number of the field in force during the step (inf: off).
    """

    strain: np.ndarray
    time_step: np.ndarray
    stress: np.ndarray
    min_gap: np.ndarray
    solver_iterations: np.ndarray
    overlap_sweeps: np.ndarray
    u_rms_dip: np.ndarray
    u_rms_shear: np.ndarray
    mason_number: np.ndarray

    @classmethod
    def empty(cls) -> StepRecords:
        return cls(
            np.zeros(0),
            np.zeros(0),
            np.zeros((0, N_CONTRIBUTIONS, 3, 3)),
            np.zeros(0),
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
        )

    @classmethod
    def concatenate(cls, parts: list[StepRecords]) -> StepRecords:
        """Records of consecutive chunks joined in order (empty records for no chunk)."""
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in _RECORD_FIELDS))

    def arrays(self) -> dict[str, Any]:
        return {f"record_{name}": getattr(self, name) for name in _RECORD_FIELDS}

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray] | np.lib.npyio.NpzFile) -> StepRecords:
        return cls(*(np.array(data[f"record_{name}"]) for name in _RECORD_FIELDS))

    def select(self, mask: np.ndarray) -> StepRecords:
        """The records where ``mask`` (S,) is true."""
        return StepRecords(*(getattr(self, name)[mask] for name in _RECORD_FIELDS))

    @property
    def total_stress(self) -> np.ndarray:
        """(S, 3, 3) sum of all contributions."""
        return self.stress.sum(axis=1)


@dataclass(frozen=True)
class RheologyResult:
    """Averaged rheology of a run (after the transient), with block-average standard errors.

    All stresses in units ``eta gammadot`` (``eps E0^2`` when quiescent); ``contributions`` maps each
    stress contribution name to its mean ``(eta_r, N1, N2)`` share; every mean is a time average.
    ``u_rms_dip`` and ``u_rms_shear`` are the RMS (over particles and time) of the dipolophoretic and of
    the shear-and-repulsion disturbance velocities (paper §3.4, Fig. 7). ``particle_pressure`` is
    ``-tr(Sigma^p)/3`` (:func:`sim.observables.stress.particle_pressure`), with its block standard error
    and its share per contribution in ``pressure_contributions``.
    """

    relative_viscosity: float
    relative_viscosity_stderr: float
    n1: float
    n1_stderr: float
    n2: float
    n2_stderr: float
    averaged_from_strain: float
    samples: int
    contributions: dict[str, tuple[float, float, float]]
    u_rms_dip: float = math.nan
    u_rms_shear: float = math.nan
    particle_pressure: float = math.nan
    particle_pressure_stderr: float = math.nan
    pressure_contributions: dict[str, float] = dataclass_field(default_factory=dict)


class Simulation:
    """Stokesian dynamics of N spheres in a Lees–Edwards box under shear and an electric field.

    The field (Mason number and direction) is part of the state: :meth:`set_field` changes it between
    :meth:`advance` calls, and :meth:`snapshot` / :meth:`restore` carry it.

    Args:
        config: the run's parameters (its ``mason_number`` and ``field_direction`` are the initial field).
        state: start from a copy of this state instead of a fresh random packing.
        keep_records: keep every step's records (needed by :meth:`rheology`); environments that only
            read each chunk's records pass False so that memory stays flat.

    Example:
        >>> sim = Simulation(SimulationConfig(n_particles=64, volume_fraction=0.3, strain=1.0))
        >>> sim.advance_to(0.1)
        >>> sim.set_field(1.0, (0.0, 1.0, 0.0))  # Mn = 1, field along y
        >>> sim.advance_to(0.2)
        >>> sim.rheology().relative_viscosity  # doctest: +SKIP
    """

    def __init__(
        self, config: SimulationConfig, state: SimulationState | None = None, keep_records: bool = True
    ) -> None:
        self.config = config
        if state is None:
            positions = random_packing(
                config.n_particles, config.volume_fraction, config.seed, min_gap=config.initial_min_gap
            )
            state = SimulationState.initial(positions, config.mason_number, config.field_direction)
        if state.positions.shape != (config.n_particles, 3):
            raise ValueError(
                f"state has {state.positions.shape[0]} particles but config.n_particles={config.n_particles}"
            )
        self.state = state.copy()  # the caller's state object is never stepped
        self.keep_records = keep_records
        self._chunks: list[StepRecords] = []
        self._params = step_parameters(config)
        self._plan = run_ewald_plan(config)

    @property
    def records(self) -> StepRecords:
        """All step records so far (chunks are joined once, when read, not on every step)."""
        if len(self._chunks) != 1:
            self._chunks = [StepRecords.concatenate(self._chunks)]
        return self._chunks[0]

    @records.setter
    def records(self, value: StepRecords) -> None:
        self._chunks = [value]

    # -- field -----------------------------------------------------------------------------------------
    def set_field(self, mason_number: float, direction: Sequence[float] | np.ndarray | None = None) -> None:
        """Set the electric field for the following steps.

        Args:
            mason_number: ``Mn = eta gammadot / (eps E0^2)`` in (0, inf]; ``inf`` switches the field off
                (not allowed in a quiescent run, where the field sets the units).
            direction: field direction (three finite numbers, not all zero; normalised here); None keeps
                the current direction. Both are validated by :class:`~sim.config.SimulationConfig`
                (which also checks the box against the near-field cut-off when the field is on); nothing
                changes when they are refused.

        Raises:
            ValueError: naming the parameter and its valid range.
        """
        if isinstance(mason_number, np.floating):
            mason_number = float(mason_number)
        current = self.state.field_direction if direction is None else direction
        # the configuration's own checks (range, quiescent runs, direction, box for the near field)
        checked = replace(
            self.config,
            mason_number=mason_number,
            field_direction=tuple(current),  # type: ignore[arg-type]
        )
        self.state.field_direction = np.array(checked.field_direction, dtype=np.float64)
        self.state.mason_number = float(checked.mason_number)

    @property
    def field(self) -> tuple[float, np.ndarray]:
        """The field in force: ``(mason_number, direction)``."""
        return self.state.mason_number, self.state.field_direction.copy()

    # -- state -----------------------------------------------------------------------------------------
    def snapshot(self) -> SimulationState:
        """Copy of the current state, field included (restore it with :meth:`restore`)."""
        return self.state.copy()

    def restore(self, state: SimulationState, keep_records: bool = False) -> None:
        """Continue from ``state`` (field included); the step records are cleared unless ``keep_records``."""
        self.state = state.copy()
        if not keep_records:
            self._chunks = []

    # -- stepping --------------------------------------------------------------------------------------
    def _step(self, max_steps: int, end_time: float) -> StepRecords:
        s = self.state
        field = field_parameters(self.config, s.mason_number, s.field_direction, self._plan)
        (
            clock,
            has_previous,
            stored,
            done,
            status,
            times,
            steps,
            stress,
            gaps,
            iterations,
            sweeps,
            rms_dip,
            rms_shear,
        ) = advance(
            s.positions,
            s.previous_velocity,
            s.warm_start,
            s.previous_warm_start,
            s.stored_solutions,
            s.has_previous,
            s.strain,
            s.step_history,
            s.displacement,
            max_steps,
            end_time,
            self._params,
            field,
        )
        chunk = StepRecords(
            times[:done].copy(),
            steps[:done].copy(),
            stress[:done].copy(),
            gaps[:done].copy(),
            iterations[:done].copy(),
            sweeps[:done].copy(),
            rms_dip[:done].copy(),
            rms_shear[:done].copy(),
            np.full(done, s.mason_number),
        )
        if self.keep_records:
            self._chunks.append(chunk)
        s.strain = clock
        s.has_previous = has_previous
        s.stored_solutions = stored
        s.step += done
        if status != STATUS_OK:
            raise SimulationError(f"step {s.step} (strain {s.strain:.4f}): {STATUS_MESSAGES[status]}")
        return chunk

    def advance(self, n_steps: int) -> StepRecords:
        """Take ``n_steps`` steps in one compiled call; returns (and appends) their records."""
        if isinstance(n_steps, bool) or int(n_steps) != n_steps or n_steps < 0:
            raise ValueError(f"n_steps must be an integer >= 0, got {n_steps!r}")
        return self._step(int(n_steps), math.inf)

    def advance_to(
        self,
        strain: float,
        chunk_steps: int = 200,
        on_chunk: Callable[[Simulation], None] | None = None,
    ) -> StepRecords:
        """Step until the clock reaches ``strain`` (the first step that gets there or beyond ends it).

        Steps adapt, so the clock may pass ``strain`` by less than one step; stopping there and calling
        again continues the same trajectory bit for bit. Returns the records of these steps.
        """
        if not math.isfinite(strain):
            raise ValueError(f"strain must be finite, got {strain!r}")
        if isinstance(chunk_steps, bool) or int(chunk_steps) != chunk_steps or chunk_steps < 1:
            raise ValueError(f"chunk_steps must be an integer >= 1, got {chunk_steps!r}")
        parts = []
        while self.state.strain < stop_time(float(strain), self.config.time_step):
            parts.append(self._step(int(chunk_steps), float(strain)))
            if on_chunk is not None:
                on_chunk(self)
        return StepRecords.concatenate(parts)

    # -- results ---------------------------------------------------------------------------------------
    def rheology(self, from_strain: float | None = None) -> RheologyResult:
        """Time averages of ``eta_r``, ``N1``, ``N2`` over samples at strain >= ``from_strain``.

        ``from_strain`` defaults to the configured transient.
        """
        start = self.config.transient if from_strain is None else from_strain
        return summarise(self.records, start, self.config.n_blocks)


def summarise(records: StepRecords, from_strain: float, n_blocks: int = 10) -> RheologyResult:
    """Time-averaged rheology of ``records`` from ``from_strain`` on, with block standard errors."""
    selected = records.select(records.strain >= from_strain - 1e-12)
    weights = selected.time_step
    stress = selected.stress
    eta, n1, n2 = rheology(stress.sum(axis=1))
    b_eta = block_average(eta, n_blocks, weights)
    b_n1 = block_average(n1, n_blocks, weights)
    b_n2 = block_average(n2, n_blocks, weights)
    b_pressure = block_average(particle_pressure(stress.sum(axis=1)), n_blocks, weights)
    pressures: dict[str, float] = {}
    contributions: dict[str, tuple[float, float, float]] = {}
    total_weight = float(weights.sum())
    for index, name in enumerate(STRESS_CONTRIBUTIONS):
        e, a, b = rheology(stress[:, index])
        if e.size:
            contributions[name] = tuple(  # type: ignore[assignment]
                float(np.sum(weights * x) / total_weight) for x in (e, a, b)
            )
            pressures[name] = float(np.sum(weights * particle_pressure(stress[:, index])) / total_weight)
        else:
            contributions[name] = (math.nan, math.nan, math.nan)
            pressures[name] = math.nan
    if eta.size:
        u_dip = math.sqrt(float(np.sum(weights * selected.u_rms_dip**2) / total_weight))
        u_shear = math.sqrt(float(np.sum(weights * selected.u_rms_shear**2) / total_weight))
    else:
        u_dip = u_shear = math.nan
    return RheologyResult(
        b_eta.mean,
        b_eta.stderr,
        b_n1.mean,
        b_n1.stderr,
        b_n2.mean,
        b_n2.stderr,
        float(from_strain),
        int(eta.size),
        contributions,
        u_dip,
        u_shear,
        b_pressure.mean,
        b_pressure.stderr,
        pressures,
    )
