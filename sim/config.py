"""Validated simulation parameters.

Units (``sim.units``): sphere radius ``a = 1``, viscosity ``eta = 1``, shear rate ``gammadot = 1``, so
time is strain and stress is in ``eta gammadot``. The Mason number ``Mn = eta gammadot / (eps E0^2)``;
``Mn = inf`` is pure shear.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from sim.geometry.configurations import MAX_VOLUME_FRACTION, box_length_for
from sim.hydrodynamics.resistance_functions import (
    DEFAULT_LUBRICATION_CUTOFF,
    DEFAULT_LUBRICATION_REGULARISATION,
)

DEFAULT_TIME_STEP = 2.0e-3
"""Default step in strain units: particles move about 0.1% of the mean spacing per step at phi = 0.45
(paper: below 0.4%); the convergence study in the README supports it."""


def _check_range(name: str, value: float, low: float, high: float, low_open: bool, high_open: bool) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``value`` is finite and in the stated interval."""
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = (value > low if low_open else value >= low) and (value < high if high_open else value <= high)
    if not ok:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        raise ValueError(f"{name} must be in {left}{low}, {high}{right}, got {value!r}")


@dataclass(frozen=True)
class SimulationConfig:
    """Parameters of one run; a run is a pure function of this object (it includes the seed).

    Attributes:
        n_particles: number of spheres N (>= 2; the box must also be at least twice the pair-list cut-off).
        volume_fraction: phi = N (4/3) pi a^3 / L^3, in (0, 0.6].
        mason_number: Mn = eta gammadot / (eps E0^2), > 0; ``inf`` is pure shear (the only value the
            current simulator supports; dipolophoresis is not implemented yet).
        field_direction: unit vector of the electric field (normalised on construction); default y.
        strain: total strain to run (>= 0).
        seed: seed of the initial random packing.
        time_step: AB2 step in strain units, in (0, 0.05].
        transient_strain: strain discarded before averaging; ``None`` means 10, or half the run if the
            run is shorter than 20.
        n_blocks: number of blocks for block-average standard errors (>= 2).
        lubrication_cutoff: gap below which pair lubrication acts (units a), in (0, 0.9] (the log terms
            must stay positive: cut-off + regularisation < 1).
        lubrication_regularisation: delta in xi -> xi + delta (units a), in [0, 0.1].
        repulsion_range: sigma of the repulsive force (units a), in (0, 0.1].
        repulsion_shear_rate_ratio: gammadot* = 6 pi eta a^2 gammadot / F0, > 0 (Sierou & Brady 2002: 5000).
        overlap_min_gap: gap enforced by overlap removal after every step (units a), in (0, 0.01].
        initial_min_gap: smallest gap of the initial packing (units a), in [overlap_min_gap, 0.1].
        solver_tolerance: relative residual of the resistance solve, in (0, 1e-4].
        solver_max_iterations: PCG iteration cap (>= 10).
        checkpoint_every: strain between checkpoints (> 0).
    """

    n_particles: int
    volume_fraction: float
    mason_number: float = math.inf
    field_direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    strain: float = 30.0
    seed: int = 0
    time_step: float = DEFAULT_TIME_STEP
    transient_strain: float | None = None
    n_blocks: int = 10
    lubrication_cutoff: float = DEFAULT_LUBRICATION_CUTOFF
    lubrication_regularisation: float = DEFAULT_LUBRICATION_REGULARISATION
    repulsion_range: float = 1.0e-3
    repulsion_shear_rate_ratio: float = 5000.0
    overlap_min_gap: float = 1.0e-5
    initial_min_gap: float = 1.0e-2
    solver_tolerance: float = 1.0e-8
    solver_max_iterations: int = 20000
    checkpoint_every: float = 5.0

    def __post_init__(self) -> None:
        if (
            isinstance(self.n_particles, bool)
            or not isinstance(self.n_particles, int)
            or self.n_particles < 2
        ):
            raise ValueError(f"n_particles must be an integer >= 2, got {self.n_particles!r}")
        _check_range("volume_fraction", self.volume_fraction, 0.0, MAX_VOLUME_FRACTION, True, False)
        if not (isinstance(self.mason_number, int | float) and self.mason_number > 0):
            raise ValueError(f"mason_number must be in (0, inf], got {self.mason_number!r}")
        direction = tuple(float(c) for c in self.field_direction)
        norm = math.sqrt(sum(c * c for c in direction))
        if len(direction) != 3 or not all(math.isfinite(c) for c in direction) or norm == 0.0:
            raise ValueError(
                f"field_direction must be three finite numbers, not all zero, got {self.field_direction!r}"
            )
        object.__setattr__(self, "field_direction", tuple(c / norm for c in direction))
        _check_range("strain", self.strain, 0.0, math.inf, False, True)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        _check_range("time_step", self.time_step, 0.0, 0.05, True, False)
        if self.transient_strain is not None:
            _check_range("transient_strain", self.transient_strain, 0.0, max(self.strain, 0.0), False, True)
        if isinstance(self.n_blocks, bool) or not isinstance(self.n_blocks, int) or self.n_blocks < 2:
            raise ValueError(f"n_blocks must be an integer >= 2, got {self.n_blocks!r}")
        _check_range("lubrication_cutoff", self.lubrication_cutoff, 0.0, 0.9, True, False)
        _check_range("lubrication_regularisation", self.lubrication_regularisation, 0.0, 0.1, False, False)
        _check_range("repulsion_range", self.repulsion_range, 0.0, 0.1, True, False)
        _check_range("repulsion_shear_rate_ratio", self.repulsion_shear_rate_ratio, 0.0, math.inf, True, True)
        _check_range("overlap_min_gap", self.overlap_min_gap, 0.0, 0.01, True, False)
        _check_range("initial_min_gap", self.initial_min_gap, self.overlap_min_gap, 0.1, False, False)
        _check_range("solver_tolerance", self.solver_tolerance, 0.0, 1.0e-4, True, False)
        if (
            isinstance(self.solver_max_iterations, bool)
            or not isinstance(self.solver_max_iterations, int)
            or self.solver_max_iterations < 10
        ):
            raise ValueError(
                f"solver_max_iterations must be an integer >= 10, got {self.solver_max_iterations!r}"
            )
        _check_range("checkpoint_every", self.checkpoint_every, 0.0, math.inf, True, True)
        length = self.box_length
        needed = 2.0 * (2.0 + self.lubrication_cutoff)
        if length < needed:
            n_min = math.ceil(self.volume_fraction * needed**3 / (4.0 / 3.0 * math.pi))
            raise ValueError(
                f"n_particles={self.n_particles} is too small for volume_fraction={self.volume_fraction}: "
                f"the box side {length:.3f} a must be at least {needed:.3f} a (twice the pair-list cut-off "
                f"2 + lubrication_cutoff); use n_particles >= {n_min}"
            )

    @property
    def box_length(self) -> float:
        """Side L of the cubic box (units a)."""
        return box_length_for(self.n_particles, self.volume_fraction)

    @property
    def n_steps(self) -> int:
        """Number of steps to reach ``strain`` (rounded up)."""
        return int(math.ceil(self.strain / self.time_step - 1e-9))

    @property
    def transient(self) -> float:
        """Strain discarded before averaging."""
        if self.transient_strain is not None:
            return self.transient_strain
        return 10.0 if self.strain >= 20.0 else 0.5 * self.strain

    @property
    def pure_shear(self) -> bool:
        """True when ``Mn = inf`` (no electric field)."""
        return math.isinf(self.mason_number)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters (``inf`` written as the string ``"inf"``)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["field_direction"] = list(self.field_direction)
        if math.isinf(out["mason_number"]):
            out["mason_number"] = "inf"
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SimulationConfig:
        """Inverse of :meth:`to_dict`."""
        data = dict(data)
        if data.get("mason_number") == "inf":
            data["mason_number"] = math.inf
        if "field_direction" in data:
            data["field_direction"] = tuple(data["field_direction"])
        return cls(**data)
