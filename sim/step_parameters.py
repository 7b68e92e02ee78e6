"""The one place where configuration names become the compiled step's parameters.

The time step (:mod:`sim.stepper`) takes two small named tuples instead of a long positional list, so a
kernel reads ``params.lubrication_cutoff`` rather than its 11th argument, and swapping two values of the
same type cannot go unnoticed by a reader (an end-to-end test through :class:`sim.Simulation` also checks
the mapping against independent numbers).

* :class:`StepParameters`: the box, lubrication, repulsion, solver, overlap removal and step-size
  control, fixed for a run, and the shear rate, which may change between ``advance`` calls
  (:meth:`sim.Simulation.set_shear_rate`: :func:`with_shear_rate`); built by :func:`step_parameters`
  from a :class:`~sim.config.SimulationConfig`.
* :class:`FieldParameters`: the electric field, which may change between ``advance`` calls
  (:meth:`sim.Simulation.set_field`), built by :func:`field_parameters`.

Units (``docs/units.md``): ``a = eta = 1`` and the reference shear rate ``gammadot_ref = 1``: time is in
``1/gammadot_ref``, stress in ``eta gammadot_ref``; the field is given by its Mason number at the
reference rate ``Mn_ref``, so the dipolophoretic velocity scale is ``U0 = a gammadot_ref / Mn_ref`` at
any shear rate (quiescent runs included), and the instantaneous Mason number is
``(gammadot / gammadot_ref) Mn_ref``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sim.config import SimulationConfig
from sim.contacts.repulsion import repulsion_scale
from sim.dipolophoresis.ewald import EwaldPlan, ewald_plan
from sim.dipolophoresis.near_field import NEAR_FIELD_ASYMPTOTICS, NEAR_FIELD_COEFFICIENTS, NEAR_FIELD_GRID
from sim.dipolophoresis.near_field_stress import STRESS_ASYMPTOTICS, STRESS_COEFFICIENTS, STRESS_GRID

OVERLAP_MAX_SWEEPS = 10_000
"""Sweeps after which overlap removal gives up and the step fails (in practice 1-20 are needed)."""

NEAR_FIELD_TABLES = (
    NEAR_FIELD_GRID,
    NEAR_FIELD_COEFFICIENTS,
    NEAR_FIELD_ASYMPTOTICS,
    STRESS_GRID,
    STRESS_COEFFICIENTS,
    STRESS_ASYMPTOTICS,
)
"""The exact two-sphere tables the compiled step reads (velocities, then stresses)."""
if not np.array_equal(NEAR_FIELD_GRID, STRESS_GRID):  # the blend evaluates both tables on one search
    raise RuntimeError("the near-field velocity and stress tables must share their nodes")

MIN_STEP_FRACTION = 1.0e-4
"""The adaptive step never falls below this fraction of ``time_step``; steps taken at the floor are
visible in the records (``dt``) and mean the displacement bound was not met."""

MAX_STEP_GROWTH = 2.0
"""Largest ratio of consecutive steps ``dt_n / dt_{n-1}`` (variable-step AB2 is zero-stable for
ratios below ``1 + sqrt(2)``; Hairer, Nørsett & Wanner 1993, §III.5)."""


class StepParameters(NamedTuple):
    """Run-constant parameters of the compiled step (see :func:`step_parameters` for the mapping).

    Attributes:
        box_length: cube side ``L`` (units a).
        shear_rate: ``gammadot / gammadot_ref`` in force (>= 0; 0 is quiescent); multiplies ``u_inf``
            and ``E_inf`` and the Lees–Edwards offset rate.
        lubrication_cutoff: gap below which pair lubrication acts (units a).
        lubrication_regularisation: ``delta`` in ``xi -> xi + delta`` (units a).
        repulsion_scale: ``F0 = 6 pi eta a^2 gammadot_ref / gammadot*`` (paper eq. 2.7), a material
            constant: it does not follow the shear rate.
        repulsion_range: ``sigma`` (units a).
        solver_tolerance: relative residual of the resistance solve.
        solver_max_iterations: PCG iteration cap.
        overlap_min_gap: gap restored by overlap removal after each step (units a).
        overlap_max_sweeps: sweeps after which overlap removal reports failure.
        max_time_step: largest step (time units).
        min_time_step: smallest step the adaptive control may take.
        max_step_growth: largest ratio of consecutive steps.
        max_displacement: largest non-affine displacement per step (units a, absolute).
    """

    box_length: float
    shear_rate: float
    lubrication_cutoff: float
    lubrication_regularisation: float
    repulsion_scale: float
    repulsion_range: float
    solver_tolerance: float
    solver_max_iterations: int
    overlap_min_gap: float
    overlap_max_sweeps: int
    max_time_step: float
    min_time_step: float
    max_step_growth: float
    max_displacement: float


class FieldParameters(NamedTuple):
    """The electric field seen by the compiled step.

    Attributes:
        strength: ``U0 = 1/Mn_ref`` in simulation units, which is also ``eps E0^2`` in stress units
            ``eta gammadot_ref``; 0 means the field is off.
        direction: (3,) float64 unit vector ``e``.
        icep_weight: 1 if induced-charge electrophoresis acts, else 0.
        dep_weight: 1 if dielectrophoresis acts, else 0.
        plan: Ewald/SPME splitting and cut-offs of the periodic far-field sums.
        near_field_cutoff: ``r_c`` of the exact near-field blend (units a); 0 means far field only.
        near_field_taper: width of the blend's taper below ``r_c`` (units a).
        near_field_tables: the two-sphere tables ``(grid, coefficients, asymptotics)`` of
            :mod:`sim.dipolophoresis.near_field` followed by those of
            :mod:`sim.dipolophoresis.near_field_stress`.
    """

    strength: float
    direction: np.ndarray
    icep_weight: float
    dep_weight: float
    plan: EwaldPlan
    near_field_cutoff: float
    near_field_taper: float
    near_field_tables: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def step_parameters(config: SimulationConfig) -> StepParameters:
    """Map a configuration onto :class:`StepParameters` (every config name appears here once)."""
    return StepParameters(
        box_length=float(config.box_length),
        shear_rate=float(config.shear_rate),
        lubrication_cutoff=float(config.lubrication_cutoff),
        lubrication_regularisation=float(config.lubrication_regularisation),
        repulsion_scale=float(repulsion_scale(config.repulsion_shear_rate_ratio)),
        repulsion_range=float(config.repulsion_range),
        solver_tolerance=float(config.solver_tolerance),
        solver_max_iterations=int(config.solver_max_iterations),
        overlap_min_gap=float(config.overlap_min_gap),
        overlap_max_sweeps=OVERLAP_MAX_SWEEPS,
        max_time_step=float(config.time_step),
        min_time_step=float(config.time_step * MIN_STEP_FRACTION),
        max_step_growth=MAX_STEP_GROWTH,
        max_displacement=float(config.max_displacement * config.mean_spacing),
    )


def field_strength(mason_number: float) -> float:
    """Dipolophoretic velocity scale ``U0 = a gammadot_ref / Mn_ref`` in simulation units (0 when the field
    is off), the same at every shear rate (``docs/units.md``); a quiescent run at ``Mn_ref = 1`` thus has
    ``U0 = 1``, the unit quiescent results have always been given in."""
    if math.isinf(mason_number):
        return 0.0
    return 1.0 / mason_number


def with_shear_rate(params: StepParameters, shear_rate: float) -> StepParameters:
    """``params`` with another shear rate (``gammadot / gammadot_ref``, >= 0); nothing else changes."""
    return params._replace(shear_rate=float(shear_rate))


def field_parameters(
    config: SimulationConfig, mason_number: float, direction: np.ndarray, plan: EwaldPlan
) -> FieldParameters:
    """The field ``E0 e`` with ``Mn = eta gammadot / (eps E0^2)`` for the compiled step.

    Args:
        config: the run (mechanism and near-field model).
        mason_number: current Mason number at the reference rate ``Mn_ref``, in (0, inf] (``inf``: off).
        direction: (3,) unit field direction.
        plan: the run's Ewald plan (:func:`sim.dipolophoresis.ewald.ewald_plan`).
    """
    return FieldParameters(
        strength=field_strength(mason_number),
        direction=np.ascontiguousarray(direction, dtype=np.float64),
        icep_weight=1.0 if config.mechanism in ("dip", "icep") else 0.0,
        dep_weight=1.0 if config.mechanism in ("dip", "dep") else 0.0,
        plan=plan,
        near_field_cutoff=float(config.near_field_cutoff) if config.near_field == "exact" else 0.0,
        near_field_taper=float(config.near_field_taper),
        near_field_tables=NEAR_FIELD_TABLES,
    )


def run_ewald_plan(config: SimulationConfig) -> EwaldPlan:
    """The Ewald plan of a run (made once; valid at every strain)."""
    return ewald_plan(
        config.box_length, config.n_particles, config.ewald_accuracy, mechanism=config.mechanism
    )
