"""The complete dynamical state of a run (what a checkpoint holds)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class SimulationState:
    """Everything the next step depends on; restoring it continues a run bit for bit.

    Attributes:
        positions: (N, 3) float64 wrapped positions in [0, L)^3 (units a); :class:`sim.Simulation` wraps a
            state's positions into the box when it takes it (:meth:`sim.Simulation.enter`).
        previous_velocity: (N, 3) float64 total velocity of the last step, for AB2 (units a gammadot).
        warm_start: (N, 6) float64 last disturbance velocity ``[U - u_inf, Omega - omega_inf]``.
        previous_warm_start: (N, 6) float64 the one before; the PCG initial guess extrapolates the two.
        stored_solutions: how many of ``warm_start``, ``previous_warm_start`` are valid (0, 1 or 2).
        has_previous: False before the first step (which is then explicit Euler).
        time: the clock, in units ``1/gammadot_ref`` (``docs/units.md``; equal to the strain while the
            shear rate is the reference rate 1).
        strain: accumulated shear strain ``int gammadot(t) dt`` (it sets the Lees–Edwards offset, the AB2
            history shift across the boundary and the affine part removed from the MSD).
        step: number of steps taken.
        step_history: (2,) float64 sizes of the last two steps (0 before they exist), for variable-step
            AB2 and the extrapolated PCG guess.
        mason_number: the field in force now, as the Mason number at the reference rate
            ``Mn_ref = eta gammadot_ref/(eps E0^2)`` (``inf``: off); the instantaneous Mason number is
            ``shear_rate * mason_number``.
        field_direction: (3,) float64 unit vector of the field in force now.
        displacement: (N, 3) float64 non-affine displacement of each sphere in the unwrapped frame since the
            start of the run (units a): ``X(t) - X(0) - gammadot x_hat int_0^t Y dt'``, accumulated per step
            by :func:`sim.observables.diffusion.accumulate_displacement` (overlap removal included). It
            does not change the dynamics; the mean-square displacement uses its differences between
            samples only, so its origin is arbitrary. Defaults to zeros (an empty array given here is
            replaced by zeros of the positions' shape).
        shear_rate: the shear rate in force now, ``gammadot / gammadot_ref`` (>= 0); NaN (the default)
            means "not set": :class:`sim.Simulation` then takes its configuration's ``shear_rate``.
    """

    positions: np.ndarray
    previous_velocity: np.ndarray
    warm_start: np.ndarray
    previous_warm_start: np.ndarray
    stored_solutions: int
    has_previous: bool
    time: float
    strain: float
    step: int
    step_history: np.ndarray = field(default_factory=lambda: np.zeros(2))
    mason_number: float = math.inf
    field_direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    displacement: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    shear_rate: float = math.nan

    def __post_init__(self) -> None:
        if self.displacement.size == 0 and self.positions.shape[0] > 0:
            self.displacement = np.zeros((self.positions.shape[0], 3))
        if self.displacement.shape != self.positions.shape:
            raise ValueError(
                f"displacement must have the shape of positions {self.positions.shape}, "
                f"got {self.displacement.shape}"
            )

    @classmethod
    def initial(
        cls,
        positions: np.ndarray,
        mason_number: float = math.inf,
        field_direction: tuple[float, float, float] = (0.0, 1.0, 0.0),
        shear_rate: float = math.nan,
    ) -> SimulationState:
        """State at rest before the first step, with the initial field and shear rate (NaN: the
        configuration's rate, set by :class:`sim.Simulation`).

        ``positions`` (N, 3) may lie anywhere (a centred box, images of the primary box): the simulation
        wraps them into ``[0, L)^3`` when it takes the state (:meth:`sim.Simulation.enter`). Non-finite
        positions are refused here (``ValueError``): they cannot be wrapped."""
        positions = np.array(positions, dtype=np.float64)
        if positions.ndim != 2 or positions.shape[1] != 3:
            raise ValueError(f"positions must have shape (N, 3), got {positions.shape}")
        if not np.all(np.isfinite(positions)):
            raise ValueError("positions must be finite (NaN or inf cannot be wrapped into the box)")
        n = positions.shape[0]
        return cls(
            positions=np.ascontiguousarray(positions),
            previous_velocity=np.zeros((n, 3)),
            warm_start=np.zeros((n, 6)),
            previous_warm_start=np.zeros((n, 6)),
            stored_solutions=0,
            has_previous=False,
            time=0.0,
            strain=0.0,
            step=0,
            step_history=np.zeros(2),
            mason_number=float(mason_number),
            field_direction=np.array(field_direction, dtype=np.float64),
            shear_rate=float(shear_rate),
        )

    def copy(self) -> SimulationState:
        """Deep copy (a snapshot)."""
        return SimulationState(
            self.positions.copy(),
            self.previous_velocity.copy(),
            self.warm_start.copy(),
            self.previous_warm_start.copy(),
            self.stored_solutions,
            self.has_previous,
            self.time,
            self.strain,
            self.step,
            self.step_history.copy(),
            self.mason_number,
            self.field_direction.copy(),
            self.displacement.copy(),
            self.shear_rate,
        )

    def arrays(self) -> dict[str, Any]:
        """Arrays for ``np.savez`` (scalars as 0-d arrays, exact)."""
        return {
            "positions": self.positions,
            "previous_velocity": self.previous_velocity,
            "warm_start": self.warm_start,
            "previous_warm_start": self.previous_warm_start,
            "stored_solutions": np.array(self.stored_solutions, dtype=np.int64),
            "has_previous": np.array(self.has_previous),
            "time": np.array(self.time, dtype=np.float64),
            "strain": np.array(self.strain, dtype=np.float64),
            "step": np.array(self.step, dtype=np.int64),
            "step_history": self.step_history,
            "mason_number": np.array(self.mason_number, dtype=np.float64),
            "field_direction": self.field_direction,
            "displacement": self.displacement,
            "shear_rate": np.array(self.shear_rate, dtype=np.float64),
        }

    @classmethod
    def from_arrays(
        cls, data: dict[str, np.ndarray] | np.lib.npyio.NpzFile, shear_rate: float = math.nan
    ) -> SimulationState:
        """Inverse of :meth:`arrays`.

        Checkpoints written before ``displacement`` was part of the state load with zeros (its origin is
        arbitrary: only differences between later samples enter the mean-square displacement). Those
        written before the shear rate could change (no ``time``) held the clock in ``strain`` and ran at
        one rate, 1 or 0: they load with that clock as ``time``, the strain ``shear_rate * time`` and
        ``shear_rate`` (the run's configured rate, passed by the caller; NaN, not known, counts as the
        reference rate 1 for the strain and leaves the rate to the configuration of the simulation).
        """
        displacement = (
            np.array(data["displacement"], dtype=np.float64) if "displacement" in data else np.zeros((0, 3))
        )
        if "time" in data:
            time = float(data["time"])
            strain = float(data["strain"])
            shear_rate = float(data["shear_rate"])
        else:
            time = float(data["strain"])
            strain = (1.0 if math.isnan(shear_rate) else shear_rate) * time
        return cls(
            positions=np.array(data["positions"], dtype=np.float64),
            previous_velocity=np.array(data["previous_velocity"], dtype=np.float64),
            warm_start=np.array(data["warm_start"], dtype=np.float64),
            previous_warm_start=np.array(data["previous_warm_start"], dtype=np.float64),
            stored_solutions=int(data["stored_solutions"]),
            has_previous=bool(data["has_previous"]),
            time=time,
            strain=strain,
            step=int(data["step"]),
            step_history=np.array(data["step_history"], dtype=np.float64),
            mason_number=float(data["mason_number"]),
            field_direction=np.array(data["field_direction"], dtype=np.float64),
            displacement=displacement,
            shear_rate=float(shear_rate),
        )

    def save(self, path: str | Path) -> None:
        """Write the state to an ``.npz`` file."""
        np.savez(path, **self.arrays())

    @classmethod
    def load(cls, path: str | Path) -> SimulationState:
        """Read a state written by :meth:`save`."""
        with np.load(path) as data:
            return cls.from_arrays(data)
