"""Validated simulation parameters.

Units (``docs/units.md``): sphere radius ``a = 1``, viscosity ``eta = 1`` and a reference shear rate
``gammadot_ref = 1``: time is in ``1/gammadot_ref`` (it equals the strain while the rate is 1) and stress
in ``eta gammadot_ref``. The field is given by the Mason number at the reference rate
``Mn_ref = eta gammadot_ref / (eps E0^2)`` (``inf`` is no field); at a shear rate ``gammadot`` the
instantaneous Mason number is ``(gammadot / gammadot_ref) Mn_ref``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from sim.geometry.configurations import MAX_VOLUME_FRACTION, MIN_VOLUME_FRACTION, box_length_for
from sim.hydrodynamics.resistance_functions import (
    DEFAULT_LUBRICATION_CUTOFF,
    DEFAULT_LUBRICATION_REGULARISATION,
)

DEFAULT_TIME_STEP = 2.0e-3
"""Default (largest) step in time units: particles move about 0.1% of the mean spacing per step at
phi = 0.45 under pure shear (paper: below 0.4%); the convergence study in docs/validation.md supports it."""

DEFAULT_MAX_DISPLACEMENT = 4.0e-3
"""Default bound on a step's non-affine displacement, as a fraction of the mean spacing ``n^(-1/3)``
(paper §2.3: particles move less than 0.4% of the mean interparticle distance per step)."""

MAX_PARTICLES = 50_000
"""Largest N a run accepts (memory of the block-sparse system and the Ewald sums stays below ~10 GiB)."""

MAX_STEPS = 100_000_000
"""Most steps a run may be planned to take at the largest step (``strain / time_step``); a larger
plan is almost certainly a typo in ``--dt`` and would run for days."""

NEAR_FIELD_MODELS = ("exact", "none")
"""``exact``: two-sphere functions blended in below ``near_field_cutoff``; ``none``: far field only."""

MECHANISMS = ("dip", "icep", "dep")
"""Dipolophoresis mechanisms: both (``dip``), induced-charge electrophoresis alone, dielectrophoresis
alone (an electrorheological fluid)."""


def _check_range(name: str, value: float, low: float, high: float, low_open: bool, high_open: bool) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``value`` is finite and in the stated interval."""
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = (value > low if low_open else value >= low) and (value < high if high_open else value <= high)
    if not ok:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        raise ValueError(f"{name} must be in {left}{low}, {high}{right}, got {value!r}")


MIN_SHEAR_RATE = 1e-3
"""Smallest non-zero shear rate a run accepts (units ``gammadot_ref``). ``eta_r = Sigma_xy/(eta gammadot)``
divides the stress by the rate: below it the field's and the repulsion's rate-independent stresses
(order ``eps E0^2`` and ``F0/a^2``) make eta_r meaningless (a rate of 1e-9 gave eta_r = -2.7e7), and a
strain would take more than 10^3 time units of dipolophoretic steps. A rate of exactly 0 is a quiescent
run (field only), whose stress is reported in ``eps E0^2``."""

MAX_SHEAR_RATE = 1e3
"""Largest shear rate a run accepts (units ``gammadot_ref``): the step resolves the flow with a
displacement bound, so the steps per unit time grow with the rate; at 10^3 a unit of time already takes
~10^5 steps of the default size, and faster rates are typos of a rate schedule."""


def check_shear_rate(shear_rate: float, name: str = "shear_rate") -> None:
    """Raise ``ValueError`` naming ``name`` unless ``shear_rate`` is 0 (quiescent) or a finite number in
    [:data:`MIN_SHEAR_RATE`, :data:`MAX_SHEAR_RATE`] (units ``gammadot_ref``)."""
    number = isinstance(shear_rate, int | float) and not isinstance(shear_rate, bool)
    ok = number and math.isfinite(shear_rate)
    if ok and (shear_rate == 0.0 or MIN_SHEAR_RATE <= shear_rate <= MAX_SHEAR_RATE):
        return
    raise ValueError(
        f"{name} must be 0 (quiescent) or in [{MIN_SHEAR_RATE:g}, {MAX_SHEAR_RATE:g}] (units gammadot_ref), "
        f"got {shear_rate!r}"
    )


def _unit_direction(value: Any) -> tuple[float, float, float]:
    """``value`` divided by its length; ``ValueError`` naming ``field_direction`` unless it is three finite
    numbers, not all zero.

    Ordinary vectors are divided by ``sqrt(sum e_i^2)``. When that sum would overflow or underflow (length
    outside ``(1e-150, 1e150)``), the components are first divided by the largest of them, so that a huge
    vector does not become ``(0, 0, 0)`` (``inf`` length) and a tiny one is neither refused as zero nor left
    off unit length by subnormal squares.
    """
    message = f"field_direction must be three finite numbers, not all zero, got {value!r}"
    if isinstance(value, str | bytes):
        raise ValueError(message)
    try:
        direction = tuple(float(c) for c in value)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    if len(direction) != 3 or not all(math.isfinite(c) for c in direction) or not any(direction):
        raise ValueError(message)
    norm = math.sqrt(sum(c * c for c in direction))
    if not 1e-150 < norm < 1e150:
        largest = max(abs(c) for c in direction)
        direction = tuple(c / largest for c in direction)
        norm = math.sqrt(sum(c * c for c in direction))
    return (direction[0] / norm, direction[1] / norm, direction[2] / norm)


@dataclass(frozen=True)
class SimulationConfig:
    """Parameters of one run; a run is a pure function of this object (it includes the seed).

    Attributes:
        n_particles: number of spheres N, in [2, 50000] (the box must also be at least twice the pair-list
            cut-off).
        volume_fraction: phi = N (4/3) pi a^3 / L^3, in [1e-3, 0.6].
        mason_number: ``Mn_ref = eta gammadot_ref / (eps E0^2)`` of the initial field, in (0, inf]; ``inf``
            is no field (pure shear). The dipolophoretic velocity scale is ``U0 = a gammadot_ref / Mn_ref``
            at every shear rate; the instantaneous Mason number is ``shear_rate * mason_number``. A
            quiescent run at ``mason_number = 1`` has ``U0 = 1``: its time is in ``a/U0`` and its stress
            in ``eps E0^2``.
        field_direction: unit vector of the electric field (normalised on construction); default y.
        mechanism: ``dip`` (ICEP + DEP, the paper's model), ``icep`` or ``dep`` (DEP alone: an
            electrorheological fluid).
        shear_rate: initial shear rate ``gammadot / gammadot_ref``, finite and >= 0 (default 1); 0 is a
            quiescent suspension (field only; Park & Saintillan 2010, Mirfendereski & Park 2019).
            :meth:`sim.Simulation.set_shear_rate` changes it during a run.
        strain: run length as accumulated strain at ``shear_rate`` (the run lasts ``strain / shear_rate``
            in time, :attr:`duration`); for a quiescent run, its length in time. >= 0 (a run through
            :func:`sim.runs.run.run_simulation` needs > 0).
        seed: seed of the initial random packing.
        time_step: largest AB2 step in time units (``1/gammadot_ref``), in (0, 0.05]; the step adapts
            below it.
        max_displacement: bound on the non-affine displacement in one step, as a fraction of the mean
            spacing ``n^(-1/3)``, in (0, 0.05]; the step is ``min(time_step, bound / max |U - u_inf|)``.
        near_field: ``exact`` (default: exact two-sphere dipolophoresis functions for pairs closer than
            ``near_field_cutoff``, blended into the far field) or ``none`` (far-field kernels only).
        near_field_cutoff: ``r_c`` of the blend (centre distance, units a), in (2.5, 10] and below L/2.
        near_field_taper: width over which the near-field correction is tapered to 0 at ``r_c``
            (units a), in (0, r_c - 2).
        ewald_accuracy: relative accuracy of the periodic far-field sums, in [1e-12, 1e-2].
        transient_strain: strain (time when quiescent) discarded before averaging; ``None`` means 10, or
            half the run if the run is shorter than 20.
        n_blocks: number of blocks for block-average standard errors (>= 2).
        lubrication_cutoff: gap below which pair lubrication acts (units a), in (0, 0.9] (the log terms
            must stay positive: cut-off + regularisation < 1).
        lubrication_regularisation: delta in xi -> xi + delta (units a), in [0, 0.1].
        repulsion_range: sigma of the repulsive force (units a), in (0, 0.1].
        repulsion_shear_rate_ratio: ``gammadot* = 6 pi eta a^2 gammadot_ref / F0`` at the reference rate,
            > 0 (Sierou & Brady 2002: 5000), so that ``F0`` is a material constant.
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
    mechanism: str = "dip"
    shear_rate: float = 1.0
    strain: float = 30.0
    seed: int = 0
    time_step: float = DEFAULT_TIME_STEP
    max_displacement: float = DEFAULT_MAX_DISPLACEMENT
    ewald_accuracy: float = 1.0e-6
    near_field: str = "exact"
    near_field_cutoff: float = 4.0
    near_field_taper: float = 0.5
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
            or not 2 <= self.n_particles <= MAX_PARTICLES
        ):
            raise ValueError(
                f"n_particles must be an integer in [2, {MAX_PARTICLES}], got {self.n_particles!r}"
            )
        _check_range(
            "volume_fraction", self.volume_fraction, MIN_VOLUME_FRACTION, MAX_VOLUME_FRACTION, False, False
        )
        if not (
            isinstance(self.mason_number, int | float)
            and not isinstance(self.mason_number, bool)
            and self.mason_number > 0
        ):
            raise ValueError(f"mason_number must be in (0, inf], got {self.mason_number!r}")
        if self.mechanism not in MECHANISMS:
            raise ValueError(f"mechanism must be one of {', '.join(MECHANISMS)}, got {self.mechanism!r}")
        check_shear_rate(self.shear_rate)
        object.__setattr__(self, "shear_rate", float(self.shear_rate))
        if self.shear_rate == 0.0 and math.isinf(self.mason_number):
            raise ValueError(
                "mason_number must be finite when shear_rate = 0: a quiescent run needs the field "
                "(mason_number = inf means no field)"
            )
        object.__setattr__(self, "field_direction", _unit_direction(self.field_direction))
        _check_range("strain", self.strain, 0.0, math.inf, False, True)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        _check_range("time_step", self.time_step, 0.0, 0.05, True, False)
        if self.duration / self.time_step > MAX_STEPS:
            raise ValueError(
                f"time_step={self.time_step!r} is too small for strain={self.strain!r} at "
                f"shear_rate={self.shear_rate!r}: the run would take {self.duration / self.time_step:.3g} "
                f"steps (more than {MAX_STEPS:.0e}); time_step must be >= {self.duration / MAX_STEPS:.3g}"
            )
        _check_range("max_displacement", self.max_displacement, 0.0, 0.05, True, False)
        _check_range("ewald_accuracy", self.ewald_accuracy, 1.0e-12, 1.0e-2, False, False)
        if self.near_field not in NEAR_FIELD_MODELS:
            raise ValueError(
                f"near_field must be one of {', '.join(NEAR_FIELD_MODELS)}, got {self.near_field!r}"
            )
        _check_range("near_field_cutoff", self.near_field_cutoff, 2.5, 10.0, True, False)
        _check_range("near_field_taper", self.near_field_taper, 0.0, self.near_field_cutoff - 2.0, True, True)
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

        if not math.isinf(self.mason_number):
            self.check_near_field_box()

    def check_near_field_box(self) -> None:
        """Raise ``ValueError`` if the exact near field is on and the box is not wider than ``2 r_c``.

        Called on construction when the initial field is on, and by :meth:`sim.Simulation.set_field`
        when a field is switched on later (a pure-shear run may use a small box).
        """
        length = self.box_length
        if self.near_field == "exact" and length <= 2.0 * self.near_field_cutoff:
            volume = (4.0 / 3.0) * math.pi
            n_min = math.floor(self.volume_fraction * (2.0 * self.near_field_cutoff) ** 3 / volume) + 1
            raise ValueError(
                f"near_field_cutoff={self.near_field_cutoff} needs a box side above "
                f"{2 * self.near_field_cutoff} a, but n_particles={self.n_particles} at "
                f"volume_fraction={self.volume_fraction} gives {length:.3f} a; use n_particles >= {n_min}, "
                "a smaller near_field_cutoff, or near_field='none'"
            )

    @property
    def box_length(self) -> float:
        """Side L of the cubic box (units a)."""
        return box_length_for(self.n_particles, self.volume_fraction)

    @property
    def duration(self) -> float:
        """Length of the run in time (units ``1/gammadot_ref``): ``strain / shear_rate``, or ``strain`` when
        quiescent; the clock at which a run through :func:`sim.runs.run.run_simulation` ends."""
        return self.strain / self.shear_rate if self.shear_rate > 0.0 else self.strain

    def time_of(self, strain: float) -> float:
        """Time at which a run at ``shear_rate`` reaches ``strain`` from 0 (``strain`` if quiescent)."""
        return strain / self.shear_rate if self.shear_rate > 0.0 else strain

    @property
    def n_steps(self) -> int:
        """Number of steps of the largest size to reach :attr:`duration` (rounded up)."""
        return int(math.ceil(self.duration / self.time_step - 1e-9))

    @property
    def transient(self) -> float:
        """Strain (time when quiescent) discarded before averaging."""
        if self.transient_strain is not None:
            return self.transient_strain
        return 10.0 if self.strain >= 20.0 else 0.5 * self.strain

    @property
    def transient_time(self) -> float:
        """The clock at which averaging starts: :attr:`transient` as a time."""
        return self.time_of(self.transient)

    @property
    def pure_shear(self) -> bool:
        """True when ``Mn = inf`` (no electric field) for the whole run's initial field."""
        return math.isinf(self.mason_number)

    @property
    def quiescent(self) -> bool:
        """True when the run starts without shear flow (``shear_rate = 0``)."""
        return self.shear_rate == 0.0

    @property
    def mean_spacing(self) -> float:
        """Mean interparticle spacing ``n^(-1/3) = L / N^(1/3)`` (units a)."""
        return self.box_length / self.n_particles ** (1.0 / 3.0)

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
