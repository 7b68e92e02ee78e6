"""``Simulation``: the one object that owns state and the step loop.

The step itself is compiled (:func:`sim.stepper.advance`); this facade calls it in chunks of many steps,
keeps the per-step records (stress per contribution, minimum gap, solver iterations), and offers
snapshot/restore for environments that reset from pre-sheared states.

Two parameters may change between ``advance`` calls: the field (:meth:`Simulation.set_field`) and the shear
rate (:meth:`Simulation.set_shear_rate`). The clock (``state.time``, units ``1/gammadot_ref``) and the
accumulated strain (``state.strain = int gammadot dt``) are kept apart; they are equal while the rate is the
reference rate 1 (``docs/units.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from dataclasses import field as dataclass_field
from typing import Any

import numpy as np

from sim.config import SimulationConfig, check_shear_rate
from sim.geometry.box import lees_edwards_offset, wrap_positions
from sim.geometry.configurations import random_packing
from sim.integrators import shift_crossed_velocities
from sim.observables.stress import (
    N_CONTRIBUTIONS,
    STRESS_CONTRIBUTIONS,
    block_average,
    particle_pressure,
    rheology,
)
from sim.state import SimulationState
from sim.step_parameters import field_parameters, run_ewald_plan, step_parameters, with_shear_rate
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
    "time",
    "shear_rate",
)


@dataclass
class StepRecords:
    """Per-step records; the stress of a step is evaluated at the configuration the step starts from.

    Averages over records are time averages: each sample stands for the step that follows it
    (``time_step``), which varies when the step adapts.

    Attributes:
        strain: (S,) accumulated strain at which each sample was evaluated.
        time_step: (S,) size (time, units ``1/gammadot_ref``) of the step taken after the sample.
        stress: (S, C, 3, 3) stress contributions (units ``eta gammadot_ref``; a quiescent run at
            ``Mn_ref = 1`` has ``eps E0^2 = eta gammadot_ref``), C = len(STRESS_CONTRIBUTIONS).
        min_gap: (S,) smallest surface gap among listed pairs (units a).
        solver_iterations: (S,) PCG iterations.
        overlap_sweeps: (S,) overlap-removal sweeps after the step (0 when nothing overlapped).
        u_rms_dip: (S,) RMS over particles of the dipolophoretic velocity ``|U^d|``.
        u_rms_shear: (S,) RMS over particles of the shear-and-repulsion disturbance velocity
            ``|U' |`` (translational, the affine ``u_inf`` excluded).
        mason_number: (S,) Mason number at the reference rate ``Mn_ref`` of the field in force during
            the step (inf: off); :attr:`instantaneous_mason_number` is ``shear_rate * mason_number``.
        time: (S,) clock at which each sample was evaluated (units ``1/gammadot_ref``); defaults to
            ``strain`` (records made at the reference rate).
        shear_rate: (S,) shear rate ``gammadot / gammadot_ref`` in force during the step; defaults to 1.
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
    time: np.ndarray = None  # type: ignore[assignment]
    shear_rate: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.time is None:
            self.time = np.array(self.strain, dtype=np.float64)
        if self.shear_rate is None:
            self.shear_rate = np.ones_like(self.strain, dtype=np.float64)

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
    def from_arrays(
        cls, data: dict[str, np.ndarray] | np.lib.npyio.NpzFile, shear_rate: float = 1.0
    ) -> StepRecords:
        """Inverse of :meth:`arrays`. Records saved before the shear rate could change (no
        ``record_time``) held the clock in ``record_strain`` at one rate: they load with that clock as
        ``time``, ``shear_rate`` (the run's rate, given by the caller) and strain ``shear_rate * time``."""
        if "record_time" in data:
            return cls(*(np.array(data[f"record_{name}"]) for name in _RECORD_FIELDS))
        clock = np.array(data["record_strain"], dtype=np.float64)
        old = {name: np.array(data[f"record_{name}"]) for name in _RECORD_FIELDS[:-2]}
        old["strain"] = shear_rate * clock
        return cls(**old, time=clock, shear_rate=np.full(clock.shape, float(shear_rate)))

    def select(self, mask: np.ndarray) -> StepRecords:
        """The records where ``mask`` (S,) is true."""
        return StepRecords(*(getattr(self, name)[mask] for name in _RECORD_FIELDS))

    @property
    def total_stress(self) -> np.ndarray:
        """(S, 3, 3) sum of all contributions."""
        return self.stress.sum(axis=1)

    @property
    def instantaneous_mason_number(self) -> np.ndarray:
        """(S,) ``Mn = (gammadot / gammadot_ref) Mn_ref`` in force during each step (inf: field off)."""
        with np.errstate(invalid="ignore"):
            return np.where(np.isinf(self.mason_number), np.inf, self.shear_rate * self.mason_number)

    def rheology(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per step ``eta_r = Sigma_xy / gammadot``, ``N1``, ``N2`` of the total stress
        (:func:`sim.observables.stress.rheology`)."""
        return rheology(self.total_stress, self.shear_rate)


@dataclass(frozen=True)
class RheologyResult:
    """Averaged rheology of a run (after the transient), with block-average standard errors.

    All stresses in units ``eta gammadot_ref``; ``eta_r`` is ``Sigma_xy / gammadot`` per step
    (:func:`sim.observables.stress.rheology`); ``contributions`` maps each stress contribution name to its
    mean ``(eta_r, N1, N2)`` share; every mean is a time average.
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
    averaged_from_time: float
    samples: int
    contributions: dict[str, tuple[float, float, float]]
    u_rms_dip: float = math.nan
    u_rms_shear: float = math.nan
    particle_pressure: float = math.nan
    particle_pressure_stderr: float = math.nan
    pressure_contributions: dict[str, float] = dataclass_field(default_factory=dict)


class Simulation:
    """Stokesian dynamics of N spheres in a Lees–Edwards box under shear and an electric field.

    The field (Mason number at the reference rate and direction) and the shear rate are part of the
    state: :meth:`set_field` and :meth:`set_shear_rate` change them between :meth:`advance` calls, and
    :meth:`snapshot` / :meth:`restore` carry them.

    Args:
        config: the run's parameters (its ``mason_number`` and ``field_direction`` are the initial field).
        state: start from a copy of this state instead of a fresh random packing. Its positions may lie
            anywhere (a centred box, images of the primary box): they are wrapped into the primary box
            ``[0, L)^3`` as the simulator's own states are (:meth:`enter`); non-finite ones are refused.
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
            state = SimulationState.initial(
                positions, config.mason_number, config.field_direction, config.shear_rate
            )
        self.state = self.enter(state)  # a wrapped copy: the caller's state object is never stepped
        self.keep_records = keep_records
        self._chunks: list[StepRecords] = []
        self._params = with_shear_rate(step_parameters(config), self.state.shear_rate)
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
            mason_number: ``Mn_ref = eta gammadot_ref / (eps E0^2)`` in (0, inf]; ``inf`` switches the
                field off (not allowed while the shear rate is 0: nothing would drive the suspension).
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
            shear_rate=self.state.shear_rate,
            strain=0.0,
            transient_strain=None,
        )
        self.state.field_direction = np.array(checked.field_direction, dtype=np.float64)
        self.state.mason_number = float(checked.mason_number)

    @property
    def field(self) -> tuple[float, np.ndarray]:
        """The field in force: ``(mason_number, direction)`` (``mason_number`` at the reference rate)."""
        return self.state.mason_number, self.state.field_direction.copy()

    # -- shear rate ------------------------------------------------------------------------------------
    def set_shear_rate(self, shear_rate: float) -> None:
        """Set the shear rate ``gammadot / gammadot_ref`` for the following steps.

        The field keeps its ``Mn_ref`` (so ``U0`` and ``F0`` stay as they are, and the instantaneous Mason
        number becomes ``shear_rate * Mn_ref``); the strain goes on accumulating from where it is, so the
        Lees–Edwards images move on continuously.

        Args:
            shear_rate: finite and >= 0 (units ``gammadot_ref``); 0 stops the flow, which needs a field
                (a finite Mason number). Nothing changes when it is refused.

        Raises:
            ValueError: naming ``shear_rate`` and its valid range.
        """
        if isinstance(shear_rate, np.floating | np.integer):
            shear_rate = float(shear_rate)
        check_shear_rate(shear_rate)
        if shear_rate == 0.0 and math.isinf(self.state.mason_number):
            raise ValueError(
                "shear_rate = 0 needs a field: with the field off (mason_number = inf) nothing would drive "
                "the suspension; set a finite Mason number first"
            )
        self.state.shear_rate = float(shear_rate)
        self._params = with_shear_rate(self._params, self.state.shear_rate)

    @property
    def shear_rate(self) -> float:
        """The shear rate in force (units ``gammadot_ref``)."""
        return self.state.shear_rate

    # -- state -----------------------------------------------------------------------------------------
    def snapshot(self) -> SimulationState:
        """Copy of the current state, field included (restore it with :meth:`restore`)."""
        return self.state.copy()

    def enter(self, state: SimulationState) -> SimulationState:
        """A copy of ``state`` as this simulation steps it: positions wrapped into the primary box
        ``[0, L)^3`` and the shear rate set (the configuration's where the state leaves it NaN).

        The box is periodic with the Lees–Edwards rule (:func:`sim.geometry.box.wrap_positions`): a
        position ``n`` periods above the box in ``y`` is the image ``(x - n delta, y - n L, z)`` with the
        offset ``delta`` of the state's strain, so a configuration shifted by any lattice vector (or
        centred on the origin, as GSD files store it) is the same configuration and runs the same, to
        round-off. The image moves ``n L gammadot`` slower in ``x``, so a wrapped particle's last-step
        velocity (the AB2 history) is shifted by that. Positions already in the box are left bit for
        bit (a snapshot restores exactly).

        Raises:
            ValueError: positions of another shape than ``(config.n_particles, 3)``, or not finite.
        """
        positions = np.asarray(state.positions)
        if positions.shape != (self.config.n_particles, 3):
            raise ValueError(
                f"state has positions of shape {positions.shape}: config.n_particles="
                f"{self.config.n_particles} needs ({self.config.n_particles}, 3)"
            )
        if not np.all(np.isfinite(positions)):
            bad = int(np.count_nonzero(~np.all(np.isfinite(positions), axis=1)))
            raise ValueError(f"state positions must be finite: {bad} particles have NaN or inf coordinates")
        if not math.isfinite(state.strain):
            raise ValueError(f"state strain must be finite, got {state.strain!r}")
        entered = state.copy()
        if math.isnan(entered.shear_rate):  # a state that does not say: the configuration's rate
            entered.shear_rate = self.config.shear_rate
        entered.positions = np.ascontiguousarray(entered.positions, dtype=np.float64)
        box_length = self.config.box_length
        crossings = wrap_positions(
            entered.positions, box_length, lees_edwards_offset(entered.strain, box_length)
        )
        if entered.has_previous and np.any(crossings):
            entered.previous_velocity = np.ascontiguousarray(entered.previous_velocity, dtype=np.float64)
            shift_crossed_velocities(entered.previous_velocity, crossings, box_length, entered.shear_rate)
        return entered

    def restore(self, state: SimulationState, keep_records: bool = False) -> None:
        """Continue from ``state`` (field and shear rate included; its positions wrapped into the box as
        in :meth:`enter`); the step records are cleared unless ``keep_records``."""
        self.state = self.enter(state)
        self._params = with_shear_rate(self._params, self.state.shear_rate)
        if not keep_records:
            self._chunks = []

    # -- stepping --------------------------------------------------------------------------------------
    def _step(self, max_steps: int, end_time: float) -> StepRecords:
        s = self.state
        field = field_parameters(self.config, s.mason_number, s.field_direction, self._plan)
        (
            clock,
            strain,
            has_previous,
            stored,
            done,
            status,
            times,
            strains,
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
            s.time,
            s.strain,
            s.step_history,
            s.displacement,
            max_steps,
            end_time,
            self._params,
            field,
        )
        chunk = StepRecords(
            strains[:done].copy(),
            steps[:done].copy(),
            stress[:done].copy(),
            gaps[:done].copy(),
            iterations[:done].copy(),
            sweeps[:done].copy(),
            rms_dip[:done].copy(),
            rms_shear[:done].copy(),
            np.full(done, s.mason_number),
            times[:done].copy(),
            np.full(done, s.shear_rate),
        )
        if self.keep_records:
            self._chunks.append(chunk)
        s.time = clock
        s.strain = strain
        s.has_previous = has_previous
        s.stored_solutions = stored
        s.step += done
        if status != STATUS_OK:
            raise SimulationError(
                f"step {s.step} (time {s.time:.4f}, strain {s.strain:.4f}): {STATUS_MESSAGES[status]}"
            )
        return chunk

    def advance(self, n_steps: int) -> StepRecords:
        """Take ``n_steps`` steps in one compiled call; returns (and appends) their records."""
        if isinstance(n_steps, bool) or int(n_steps) != n_steps or n_steps < 0:
            raise ValueError(f"n_steps must be an integer >= 0, got {n_steps!r}")
        return self._step(int(n_steps), math.inf)

    def advance_to(
        self,
        time: float,
        chunk_steps: int = 200,
        on_chunk: Callable[[Simulation], None] | None = None,
    ) -> StepRecords:
        """Step until the clock reaches ``time`` (the first step that gets there or beyond ends it).

        ``time`` is the clock (units ``1/gammadot_ref``; it equals the strain at the reference rate).
        Steps adapt, so the clock may pass ``time`` by less than one step; stopping there and calling
        again continues the same trajectory bit for bit. Returns the records of these steps.
        """
        if not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        if isinstance(chunk_steps, bool) or int(chunk_steps) != chunk_steps or chunk_steps < 1:
            raise ValueError(f"chunk_steps must be an integer >= 1, got {chunk_steps!r}")
        parts = []
        while self.state.time < stop_time(float(time), self.config.time_step):
            parts.append(self._step(int(chunk_steps), float(time)))
            if on_chunk is not None:
                on_chunk(self)
        return StepRecords.concatenate(parts)

    # -- results ---------------------------------------------------------------------------------------
    def rheology(self, from_time: float | None = None) -> RheologyResult:
        """Time averages of ``eta_r``, ``N1``, ``N2`` over samples at clock >= ``from_time``.

        ``from_time`` defaults to the configured transient (:attr:`SimulationConfig.transient_time`).
        """
        start = self.config.transient_time if from_time is None else from_time
        return summarise(self.records, start, self.config.n_blocks)


def summarise(records: StepRecords, from_time: float, n_blocks: int = 10) -> RheologyResult:
    """Time-averaged rheology of ``records`` from the clock ``from_time`` on, with block standard errors."""
    selected = records.select(records.time >= from_time - 1e-12)
    weights = selected.time_step
    stress = selected.stress
    eta, n1, n2 = rheology(stress.sum(axis=1), selected.shear_rate)
    b_eta = block_average(eta, n_blocks, weights)
    b_n1 = block_average(n1, n_blocks, weights)
    b_n2 = block_average(n2, n_blocks, weights)
    b_pressure = block_average(particle_pressure(stress.sum(axis=1)), n_blocks, weights)
    pressures: dict[str, float] = {}
    contributions: dict[str, tuple[float, float, float]] = {}
    total_weight = float(weights.sum())
    for index, name in enumerate(STRESS_CONTRIBUTIONS):
        e, a, b = rheology(stress[:, index], selected.shear_rate)
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
        float(from_time),
        int(eta.size),
        contributions,
        u_dip,
        u_shear,
        b_pressure.mean,
        b_pressure.stderr,
        pressures,
    )
