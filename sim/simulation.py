"""``Simulation``: the one object that owns state and the step loop.

The step itself is compiled (:func:`sim.stepper.advance`); this facade calls it in chunks of many steps,
keeps the per-step records (stress per contribution, minimum gap, solver iterations), and offers
snapshot/restore for environments that reset from pre-sheared states.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.config import SimulationConfig
from sim.contacts.repulsion import repulsion_scale
from sim.geometry.configurations import random_packing
from sim.observables.stress import N_CONTRIBUTIONS, STRESS_CONTRIBUTIONS, block_average, rheology
from sim.state import SimulationState
from sim.stepper import STATUS_MESSAGES, STATUS_OK, advance

OVERLAP_MAX_SWEEPS = 10_000
"""Sweeps after which overlap removal gives up and the step fails (in practice 1-3 are needed)."""


class SimulationError(RuntimeError):
    """A step failed (solver or overlap removal did not converge); the message says where."""


@dataclass
class StepRecords:
    """Per-step records; the stress of a step is evaluated at the configuration the step starts from.

    Attributes:
        strain: (S,) strain at which each stress sample was evaluated.
        stress: (S, C, 3, 3) stress contributions (units eta gammadot), C = len(STRESS_CONTRIBUTIONS).
        min_gap: (S,) smallest surface gap among listed pairs (units a).
        solver_iterations: (S,) PCG iterations.
        overlap_sweeps: (S,) overlap-removal sweeps after the step (0 when nothing overlapped).
    """

    strain: np.ndarray
    stress: np.ndarray
    min_gap: np.ndarray
    solver_iterations: np.ndarray
    overlap_sweeps: np.ndarray

    @classmethod
    def empty(cls) -> StepRecords:
        return cls(
            np.zeros(0),
            np.zeros((0, N_CONTRIBUTIONS, 3, 3)),
            np.zeros(0),
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
        )

    @classmethod
    def concatenate(cls, parts: list[StepRecords]) -> StepRecords:
        """Records of consecutive chunks joined in order (empty records for no chunk)."""
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([p.strain for p in parts]),
            np.concatenate([p.stress for p in parts]),
            np.concatenate([p.min_gap for p in parts]),
            np.concatenate([p.solver_iterations for p in parts]),
            np.concatenate([p.overlap_sweeps for p in parts]),
        )

    def arrays(self) -> dict[str, Any]:
        return {
            "record_strain": self.strain,
            "record_stress": self.stress,
            "record_min_gap": self.min_gap,
            "record_solver_iterations": self.solver_iterations,
            "record_overlap_sweeps": self.overlap_sweeps,
        }

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray] | np.lib.npyio.NpzFile) -> StepRecords:
        return cls(
            np.array(data["record_strain"]),
            np.array(data["record_stress"]),
            np.array(data["record_min_gap"]),
            np.array(data["record_solver_iterations"]),
            np.array(data["record_overlap_sweeps"]),
        )

    @property
    def total_stress(self) -> np.ndarray:
        """(S, 3, 3) sum of all contributions."""
        return self.stress.sum(axis=1)


@dataclass(frozen=True)
class RheologyResult:
    """Averaged rheology of a run (after the transient), with block-average standard errors.

    All stresses in units ``eta gammadot``; ``contributions`` maps each stress contribution name to its
    mean ``(eta_r, N1, N2)`` share.
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


class Simulation:
    """Pure-shear Stokesian dynamics of N spheres in a Lees–Edwards box.

    Example:
        >>> sim = Simulation(SimulationConfig(n_particles=64, volume_fraction=0.3, strain=1.0))
        >>> sim.advance_to(0.1)
        >>> sim.rheology().relative_viscosity  # doctest: +SKIP
    """

    def __init__(self, config: SimulationConfig, state: SimulationState | None = None) -> None:
        if not config.pure_shear:
            raise NotImplementedError(
                f"mason_number={config.mason_number}: dipolophoresis (finite Mason number) is not "
                "implemented yet; only mason_number=inf (pure shear) is supported"
            )
        self.config = config
        if state is None:
            positions = random_packing(
                config.n_particles, config.volume_fraction, config.seed, min_gap=config.initial_min_gap
            )
            state = SimulationState.initial(positions)
        if state.positions.shape != (config.n_particles, 3):
            raise ValueError(
                f"state has {state.positions.shape[0]} particles but config.n_particles={config.n_particles}"
            )
        self.state = state
        self._chunks: list[StepRecords] = []
        self._force_scale = repulsion_scale(config.repulsion_shear_rate_ratio)

    @property
    def records(self) -> StepRecords:
        """All step records so far (chunks are joined once, when read, not on every step)."""
        if len(self._chunks) != 1:
            self._chunks = [StepRecords.concatenate(self._chunks)]
        return self._chunks[0]

    @records.setter
    def records(self, value: StepRecords) -> None:
        self._chunks = [value]

    # -- state -----------------------------------------------------------------------------------------
    def snapshot(self) -> SimulationState:
        """Copy of the current state (restore it with :meth:`restore`)."""
        return self.state.copy()

    def restore(self, state: SimulationState, keep_records: bool = False) -> None:
        """Continue from ``state``; the step records are cleared unless ``keep_records``."""
        self.state = state.copy()
        if not keep_records:
            self._chunks = []

    # -- stepping --------------------------------------------------------------------------------------
    def advance(self, n_steps: int) -> StepRecords:
        """Take ``n_steps`` steps in one compiled call; returns (and appends) their records."""
        if n_steps < 0:
            raise ValueError(f"n_steps must be >= 0, got {n_steps}")
        c = self.config
        s = self.state
        strain, has_previous, stored, done, status, strains, stress, gaps, iterations, sweeps = advance(
            s.positions,
            s.previous_velocity,
            s.warm_start,
            s.previous_warm_start,
            s.stored_solutions,
            s.has_previous,
            s.strain,
            n_steps,
            c.time_step,
            c.box_length,
            c.lubrication_cutoff,
            c.lubrication_regularisation,
            self._force_scale,
            c.repulsion_range,
            c.solver_tolerance,
            c.solver_max_iterations,
            c.overlap_min_gap,
            OVERLAP_MAX_SWEEPS,
        )
        chunk = StepRecords(strains[:done], stress[:done], gaps[:done], iterations[:done], sweeps[:done])
        self._chunks.append(chunk)
        s.strain = strain
        s.has_previous = has_previous
        s.stored_solutions = stored
        s.step += done
        if status != STATUS_OK:
            raise SimulationError(f"step {s.step} (strain {s.strain:.4f}): {STATUS_MESSAGES[status]}")
        return chunk

    def advance_to(
        self,
        strain: float,
        chunk_steps: int = 200,
        on_chunk: Callable[[Simulation], None] | None = None,
    ) -> None:
        """Step until the accumulated strain reaches ``strain`` (within half a step)."""
        total = int(math.ceil((strain - self.state.strain) / self.config.time_step - 1e-9))
        while total > 0:
            n = min(chunk_steps, total)
            self.advance(n)
            total -= n
            if on_chunk is not None:
                on_chunk(self)

    # -- results ---------------------------------------------------------------------------------------
    def rheology(self, from_strain: float | None = None) -> RheologyResult:
        """Averages of ``eta_r``, ``N1``, ``N2`` over samples at strain >= ``from_strain``.

        ``from_strain`` defaults to the configured transient.
        """
        start = self.config.transient if from_strain is None else from_strain
        mask = self.records.strain >= start - 1e-12
        stress = self.records.stress[mask]
        total = stress.sum(axis=1)
        eta, n1, n2 = rheology(total)
        b_eta = block_average(eta, self.config.n_blocks)
        b_n1 = block_average(n1, self.config.n_blocks)
        b_n2 = block_average(n2, self.config.n_blocks)
        contributions: dict[str, tuple[float, float, float]] = {}
        for index, name in enumerate(STRESS_CONTRIBUTIONS):
            e, a, b = rheology(stress[:, index])
            if e.size:
                contributions[name] = (float(e.mean()), float(a.mean()), float(b.mean()))
            else:
                contributions[name] = (math.nan, math.nan, math.nan)
        return RheologyResult(
            b_eta.mean,
            b_eta.stderr,
            b_n1.mean,
            b_n1.stderr,
            b_n2.mean,
            b_n2.stderr,
            float(start),
            int(eta.size),
            contributions,
        )
