"""The compiled time step: velocity terms, stress, adaptive AB2 move, wrap, overlap removal.

The particle velocity is a sum of terms (paper eq. 2.6, ``docs/model.md#time-stepping``)::

    U = u_inf + R_FU^-1 . (R_FE : E_inf + F^p) + U^d,        Omega^d = 0,

and each term has one compiled entry point that returns its velocity and writes its own slots of the
stress-contribution axis (:data:`sim.observables.stress.STRESS_CONTRIBUTIONS`):

* :func:`hydrodynamic_term`: shear flow and repulsion by the resistance formulation (pair list,
  lubrication, ``R_FU`` solve by PCG with a warm start); slots ``solvent``, ``stokes_drag``,
  ``lubrication``, ``repulsion``.
* :func:`dipolophoresis_term`: the dipolophoretic velocity ``U^d`` of the mobility approach (periodic
  far-field sums) and its stresses; slots ``icep_isolated``, ``icep_pair``, ``dep_virial``.

A new physical term is one more such function called from :func:`evaluate`.

Stepping (:func:`advance`): second-order Adams–Bashforth with a variable step (explicit Euler first),
``x_{n+1} = x_n + dt_n [(1 + w/2) U_n - (w/2) U_{n-1}]`` with ``w = dt_n / dt_{n-1}``, where ``dt_n`` is
the largest step that keeps the non-affine displacement ``dt_n max_p |U_p - u_inf(x_p)|`` below
``params.max_displacement`` (paper §2.3: < 0.4% of the mean spacing), capped by ``max_time_step`` and by
``max_step_growth * dt_{n-1}``, and floored at ``min_time_step``. The Lees–Edwards wrap follows, then
Melrose–Ball overlap removal; last, the step's non-affine displacement in the unwrapped frame is added to
the state's ``displacement`` (:func:`sim.observables.diffusion.accumulate_displacement`, O(N); it does not
feed back on the dynamics). Everything is ``@njit``; :func:`advance` loops over many steps without
returning to Python.

Time and strain: the clock ``t`` is in units ``1/gammadot_ref``; the shear rate ``gammadot`` (in units
``gammadot_ref``, ``params.shear_rate``) is constant within one :func:`advance` call and may change between
calls, so the accumulated strain ``gamma = int gammadot dt``, which sets the Lees–Edwards offset, is carried
beside the clock and advanced by ``gammadot dt`` per step (``docs/units.md``).

References:
    Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §2.1–2.4.
    Hairer, E., Nørsett, S. P. & Wanner, G. (1993) Solving ODEs I, §III.5 (variable-step multistep).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.dipolophoresis.ewald import collects_near_pairs, dip_far_field_with_pairs
from sim.dipolophoresis.near_field_blend import add_near_field_corrections, add_pair_corrections
from sim.geometry.box import lees_edwards_offset, wrap_positions
from sim.geometry.overlap import remove_overlaps
from sim.hydrodynamics.lubrication import pair_stresslet_sum, strain_forcing
from sim.hydrodynamics.resistance_solver import solve_resistance
from sim.hydrodynamics.stokes_drag import STRESSLET_DRAG
from sim.integrators import shift_crossed_velocities, variable_step_adams_bashforth
from sim.observables.diffusion import accumulate_displacement
from sim.observables.stress import (
    DEP_STRESSLET,
    DEP_VIRIAL,
    DIPOLOPHORESIS_CONTRIBUTIONS,
    ICEP_ISOLATED,
    ICEP_PAIR,
    LUBRICATION,
    N_CONTRIBUTIONS,
    REPULSION,
    SOLVENT,
    STOKES_DRAG,
)
from sim.pair_system import pair_system

STATUS_OK = 0
STATUS_SOLVER_FAILED = 1
STATUS_OVERLAP_FAILED = 2
STATUS_NON_FINITE = 3
STATUS_MESSAGES = {
    STATUS_OK: "ok",
    STATUS_SOLVER_FAILED: "the resistance solve did not converge (matrix not SPD or iteration cap reached)",
    STATUS_OVERLAP_FAILED: "overlap removal did not converge within its sweep cap",
    STATUS_NON_FINITE: "a velocity was not finite (NaN or inf)",
}

ISOLATED_ICEP_STRESSLET = 9.0 * math.pi
"""``S0 = 9 pi eps a^3 E0^2 (ee - I/3)`` for an ideally polarisable sphere with a fully polarised thin
double layer (``docs/model.md#dipolophoresis``; the B2 squirming mode of the ICEO slip ``(9/4) U0 sin(th)
cos(th)``)."""


@njit(cache=True)
def shear_strain_rate(shear_rate: float) -> np.ndarray:
    """``E_inf = (gammadot/2)(x y + y x)`` for ``u_inf = gammadot y x_hat``."""
    e = np.zeros((3, 3))
    e[0, 1] = 0.5 * shear_rate
    e[1, 0] = 0.5 * shear_rate
    return e


@njit(cache=True)
def hydrodynamic_term(
    positions: np.ndarray, strain: float, warm_start: np.ndarray, params, stress: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Shear flow and repulsion: ``U = u_inf + V'`` with ``R_FU . V' = R_FE : E_inf + F^p``.

    Args:
        positions: (N, 3) wrapped positions (units a).
        strain: accumulated strain (Lees–Edwards offset).
        warm_start: (N, 6) initial guess for ``V' = [U - u_inf, Omega - omega_inf]``.
        params: :class:`sim.step_parameters.StepParameters`.
        stress: (N_CONTRIBUTIONS, 3, 3); the slots ``solvent``, ``stokes_drag``, ``lubrication``,
            ``repulsion`` are overwritten (units eta gammadot, or eps E0^2 when quiescent).

    Returns:
        velocity (N, 3) ``u_inf + V'`` (translational), disturbance ``V'`` (N, 6), the smallest gap
        among listed pairs (inf if none), PCG iterations (-1 if the solve failed).
    """
    n = positions.shape[0]
    pairs, units, scalars, gaps, diag, off, forces, virial = pair_system(positions, strain, params)
    strain_rate = shear_strain_rate(params.shear_rate)
    rhs = strain_forcing(n, pairs, units, scalars, strain_rate)
    for p in range(n):
        for c in range(3):
            rhs[p, c] += forces[p, c]
    disturbance, iterations, _ = solve_resistance(
        diag, off, pairs, rhs, warm_start, params.solver_tolerance, params.solver_max_iterations
    )
    velocity = np.empty((n, 3))
    for p in range(n):
        for c in range(3):
            velocity[p, c] = disturbance[p, c]
        velocity[p, 0] += params.shear_rate * positions[p, 1]

    volume = params.box_length**3
    stresslet_sum = pair_stresslet_sum(pairs, units, scalars, disturbance, strain_rate)
    for a in range(3):
        for b in range(3):
            stress[SOLVENT, a, b] = 2.0 * strain_rate[a, b]
            stress[STOKES_DRAG, a, b] = n * STRESSLET_DRAG * strain_rate[a, b] / volume
            stress[LUBRICATION, a, b] = stresslet_sum[a, b] / volume
            stress[REPULSION, a, b] = -virial[a, b] / volume
    min_gap = math.inf
    for k in range(gaps.shape[0]):
        if gaps[k] < min_gap:
            min_gap = gaps[k]
    return velocity, disturbance, min_gap, iterations


@njit(cache=True)
def dipolophoresis_term(
    positions: np.ndarray, strain: float, params, field, stress: np.ndarray
) -> np.ndarray:
    """Dipolophoretic velocity ``U^d`` (mobility approach, paper eq. 2.3) and its stresses.

    ``U^d_alpha = U0 sum_beta [M^ICEP + M^DEP](x_alpha - x_beta) : ee`` over all particles and their
    periodic images (Ewald sums of the far-field kernels, ``docs/model.md#dipolophoresis``), with the exact
    two-sphere
    functions blended in for pairs closer than ``field.near_field_cutoff``
    (:mod:`sim.dipolophoresis.near_field_blend`); the isolated-sphere ICEP
    stresslet ``n S0``, the O(r^-3) pair corrections to it and the DEP force virial go to the slots
    ``icep_isolated``, ``icep_pair``, ``dep_virial`` (all zero when the field is off).

    Args:
        positions: (N, 3) wrapped positions (units a).
        strain: accumulated strain (Lees–Edwards offset of the lattice).
        params: :class:`sim.step_parameters.StepParameters`.
        field: :class:`sim.step_parameters.FieldParameters` (``strength`` = ``U0`` = ``eps E0^2``).
        stress: (N_CONTRIBUTIONS, 3, 3); the three dipolophoresis slots are overwritten.

    Returns:
        (N, 3) ``U^d`` in simulation units.
    """
    n = positions.shape[0]
    for k in DIPOLOPHORESIS_CONTRIBUTIONS:
        stress[k, :, :] = 0.0
    if field.strength == 0.0:
        return np.zeros((n, 3))
    offset = lees_edwards_offset(strain, params.box_length)
    e = field.direction
    velocity, icep_pair, dep_virial, near_pairs, near_separations = dip_far_field_with_pairs(
        positions,
        params.box_length,
        offset,
        e,
        field.icep_weight,
        field.dep_weight,
        field.plan,
        field.near_field_cutoff,
    )
    dep_stresslet = np.zeros((3, 3))
    if field.near_field_cutoff > 0.0 and collects_near_pairs(
        field.plan, params.box_length, field.near_field_cutoff
    ):
        add_pair_corrections(  # the pairs the real-space sum found closer than the cut-off
            near_pairs,
            near_separations,
            params.box_length,
            e,
            field.icep_weight,
            field.dep_weight,
            field.near_field_cutoff,
            field.near_field_taper,
            field.near_field_tables,
            velocity,
            icep_pair,
            dep_virial,
            dep_stresslet,
        )
    elif field.near_field_cutoff > 0.0:
        add_near_field_corrections(
            positions,
            params.box_length,
            offset,
            e,
            field.icep_weight,
            field.dep_weight,
            field.near_field_cutoff,
            field.near_field_taper,
            field.near_field_tables,
            velocity,
            icep_pair,
            dep_virial,
            dep_stresslet,
        )
    strength = field.strength
    for p in range(n):
        for c in range(3):
            velocity[p, c] *= strength
    density = n / params.box_length**3
    for a in range(3):
        for b in range(3):
            q = e[a] * e[b] - (1.0 / 3.0 if a == b else 0.0)
            stress[ICEP_ISOLATED, a, b] = field.icep_weight * density * ISOLATED_ICEP_STRESSLET * q * strength
            stress[ICEP_PAIR, a, b] = icep_pair[a, b] * strength
            stress[DEP_VIRIAL, a, b] = dep_virial[a, b] * strength
            stress[DEP_STRESSLET, a, b] = dep_stresslet[a, b] * strength
    return velocity


@njit(cache=True)
def evaluate(
    positions: np.ndarray, strain: float, warm_start: np.ndarray, params, field
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, int]:
    """Velocities and stress contributions at one configuration (the sum of all velocity terms).

    Returns:
        velocity (N, 3) total translational velocity ``u_inf + V' + U^d``, disturbance ``V'`` (N, 6)
        of the resistance solve, ``U^d`` (N, 3), stress (N_CONTRIBUTIONS, 3, 3), the smallest listed
        gap, PCG iterations (-1 on failure).
    """
    stress = np.zeros((N_CONTRIBUTIONS, 3, 3))
    velocity, disturbance, min_gap, iterations = hydrodynamic_term(
        positions, strain, warm_start, params, stress
    )
    dip_velocity = dipolophoresis_term(positions, strain, params, field, stress)
    for p in range(velocity.shape[0]):
        for c in range(3):
            velocity[p, c] += dip_velocity[p, c]
    return velocity, disturbance, dip_velocity, stress, min_gap, iterations


@njit(cache=True)
def stop_time(end_time: float, max_time_step: float) -> float:
    """The clock at or beyond which a run to ``end_time`` is over: ``end_time`` less ``1e-9`` of a step,
    so that rounding in the accumulated clock never adds a step. One rule for the step loop
    (:func:`advance`), :meth:`sim.Simulation.advance_to` and the resume checks of :mod:`sim.runs.run`."""
    return end_time - 1e-9 * max_time_step


@njit(cache=True)
def choose_time_step(non_affine_max: float, previous_dt: float, has_previous: bool, params) -> float:
    """Largest step with ``dt max|U - u_inf| <= max_displacement``, within the caps (module docstring)."""
    dt = params.max_time_step
    if non_affine_max * dt > params.max_displacement:
        dt = params.max_displacement / non_affine_max
    if has_previous and dt > params.max_step_growth * previous_dt:
        dt = params.max_step_growth * previous_dt
    if dt < params.min_time_step:
        dt = params.min_time_step
    return dt


@njit(cache=True)
def _rms_rows(v: np.ndarray, columns: int) -> float:
    s = 0.0
    for p in range(v.shape[0]):
        for c in range(columns):
            s += v[p, c] * v[p, c]
    return math.sqrt(s / max(v.shape[0], 1))


@njit(cache=True)
def advance(
    positions: np.ndarray,
    previous_velocity: np.ndarray,
    warm_start: np.ndarray,
    previous_warm_start: np.ndarray,
    stored_solutions: int,
    has_previous: bool,
    time: float,
    strain: float,
    step_history: np.ndarray,
    displacement: np.ndarray,
    max_steps: int,
    end_time: float,
    params,
    field,
) -> tuple:
    """Take steps in place until the clock reaches ``end_time`` or ``max_steps`` steps are done.

    ``positions``, ``previous_velocity`` (N, 3), ``warm_start``, ``previous_warm_start`` (N, 6, the last
    two disturbance solutions, of which ``stored_solutions`` are valid) and ``step_history`` (2,: the
    last two step sizes) are updated in place; with ``time``, ``strain`` (the accumulated strain, advanced
    by ``params.shear_rate * dt`` per step) and ``has_previous`` they form the complete
    dynamical state: the same state gives the same trajectory bit for bit, however the steps are split
    between calls. ``displacement`` (N, 3) accumulates each step's non-affine displacement in the
    unwrapped frame, overlap removal included (:func:`sim.observables.diffusion.accumulate_displacement`);
    it is an observable, never read by the dynamics. The loop stops at the first step that brings the
    clock to ``end_time`` or beyond (no step is shortened to land on it, so stopping and continuing never
    changes the trajectory). The PCG initial guess extrapolates the last two solutions linearly in time.

    Returns:
        time, strain, has_previous, stored_solutions, steps completed, status (``STATUS_*``), and per step
        (valid up to the number completed): time at the start of the step (n,), accumulated strain at the
        start of the step (n,), step size (n,), stress
        (n, N_CONTRIBUTIONS, 3, 3) at the start of the step, smallest gap (n,), PCG iterations (n,),
        overlap-removal sweeps (n,), RMS of ``U^d`` (n,), RMS of the translational ``V'`` (n,).
    """
    time_series = np.zeros(max_steps)
    strain_series = np.zeros(max_steps)
    dt_series = np.zeros(max_steps)
    stress_series = np.zeros((max_steps, N_CONTRIBUTIONS, 3, 3))
    gap_series = np.zeros(max_steps)
    iteration_series = np.zeros(max_steps, dtype=np.int64)
    sweep_series = np.zeros(max_steps, dtype=np.int64)
    rms_dip_series = np.zeros(max_steps)
    rms_shear_series = np.zeros(max_steps)
    n = positions.shape[0]
    guess = np.empty_like(warm_start)
    step_start = np.empty_like(positions)
    status = STATUS_OK
    done = 0
    stop = stop_time(end_time, params.max_time_step)
    while done < max_steps and time < stop:
        if stored_solutions >= 2 and step_history[1] > 0.0:
            ratio = step_history[0] / step_history[1]
            for p in range(n):
                for c in range(6):
                    guess[p, c] = warm_start[p, c] + ratio * (warm_start[p, c] - previous_warm_start[p, c])
        else:
            guess[:, :] = warm_start
        velocity, disturbance, dip_velocity, stress, min_gap, iterations = evaluate(
            positions, strain, guess, params, field
        )
        if iterations < 0:
            status = STATUS_SOLVER_FAILED
            break
        non_affine_max = 0.0
        for p in range(n):
            s = 0.0
            for c in range(3):
                u = disturbance[p, c] + dip_velocity[p, c]
                s += u * u
            if s > non_affine_max:
                non_affine_max = s
        non_affine_max = math.sqrt(non_affine_max)
        if not math.isfinite(non_affine_max):
            status = STATUS_NON_FINITE
            break
        dt = choose_time_step(non_affine_max, step_history[0], has_previous, params)

        time_series[done] = time
        strain_series[done] = strain
        dt_series[done] = dt
        stress_series[done] = stress
        gap_series[done] = min_gap
        iteration_series[done] = iterations
        rms_dip_series[done] = _rms_rows(dip_velocity, 3)
        rms_shear_series[done] = _rms_rows(disturbance, 3)
        previous_warm_start[:, :] = warm_start
        warm_start[:, :] = disturbance
        stored_solutions = min(stored_solutions + 1, 2)

        step_start[:, :] = positions
        variable_step_adams_bashforth(
            positions, velocity, previous_velocity, has_previous, dt, step_history[0]
        )
        step_history[1] = step_history[0]
        step_history[0] = dt
        time += dt
        strain += params.shear_rate * dt
        offset = lees_edwards_offset(strain, params.box_length)
        crossings = wrap_positions(positions, params.box_length, offset)
        shift_crossed_velocities(velocity, crossings, params.box_length, params.shear_rate)
        sweeps, crossings = remove_overlaps(
            positions, params.box_length, offset, params.overlap_min_gap, params.overlap_max_sweeps
        )
        shift_crossed_velocities(velocity, crossings, params.box_length, params.shear_rate)
        accumulate_displacement(
            displacement, step_start, positions, dt, params.shear_rate, params.box_length, offset
        )
        previous_velocity[:, :] = velocity
        has_previous = True
        sweep_series[done] = sweeps
        done += 1
        if sweeps < 0:
            status = STATUS_OVERLAP_FAILED
            break
    return (
        time,
        strain,
        has_previous,
        stored_solutions,
        done,
        status,
        time_series,
        strain_series,
        dt_series,
        stress_series,
        gap_series,
        iteration_series,
        sweep_series,
        rms_dip_series,
        rms_shear_series,
    )
