"""Bulk stress, its contributions, and rheological functions with block-average errors.

The bulk stress of a suspension (Batchelor 1970; paper eqs 2.8–2.9), in units ``eta gammadot_ref``
(``docs/units.md``)::

    <Sigma> = -p_f I + 2 eta E_inf + <Sigma^p>,
    <Sigma^p> = -n <R_SU . (U - u_inf; Omega - omega_inf)> + n <R_SE : E_inf> + n <S^d> - n <x F^p>

where the velocity in the first term is the shear-and-repulsion disturbance velocity solved from
``R_FU`` (the dipolophoretic velocity ``U^d`` is not in it: its stress is ``S^d``). It is reported per
contribution (the isotropic ``-p_f I`` is not computed; it cancels in ``N1`` and ``N2``):

================== ================================================================================
``solvent``        ``2 eta E_inf``
``stokes_drag``    isolated-sphere stresslets ``n (20/3) pi eta a^3 E_inf`` (gives 2.5 phi)
``lubrication``    pair stresslets ``-R_SU^lub . V' + R_SE^lub : E_inf`` summed over particles / V
``repulsion``      virial of the repulsive forces ``-(1/V) sum_pairs |F| r d d``
``icep_isolated``  ICEP stresslet of isolated spheres ``n S0``, ``S0 = 9 pi eps a^3 E0^2 (ee - I/3)``
``icep_pair``      O(r^-3) pair corrections to the ICEP stresslets (Ewald lattice sum)
``dep_virial``     virial of the dielectrophoretic forces ``-n <x F^DEP>`` (Ewald lattice sum)
``dep_stresslet``  stresslets induced by the DEP forces through the two-sphere mobility (near field only)
================== ================================================================================

The four dipolophoresis terms scale as ``eps E0^2 = eta gammadot_ref / Mn_ref``.

Rheology (paper §2.4): ``eta_r = Sigma_xy / (eta gammadot)`` at the shear rate in force, ``N1 = Sigma_xx
- Sigma_yy``, ``N2 = Sigma_yy - Sigma_zz``. Particle pressure (Jeffrey, Morris & Brady 1993; the
quiescent dipolophoresis results of Mirfendereski & Park 2021): ``Pi = -tr(Sigma^p) / 3``. In this model
only the virials carry a trace (``repulsion`` and ``dep_virial``: repulsive forces give ``Pi > 0``,
attractive ones ``Pi < 0``); the stresslets are traceless (the resistance-function stresslets and ``S0``
are deviatoric by construction, the pair ICEP sum includes its Lorentz term), so ``Pi`` is the
interparticle-force pressure, without the hydrodynamic part that the traces of ``R_SU``, ``R_SE`` would
add in full Stokesian dynamics.

References:
    Batchelor, G. K. (1970) J. Fluid Mech. 41, 545-570.
    Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §2.4.
    Flyvbjerg, H. & Petersen, H. G. (1989) J. Chem. Phys. 91, 461-466 (block averaging).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STRESS_CONTRIBUTIONS: tuple[str, ...] = (
    "solvent",
    "stokes_drag",
    "lubrication",
    "repulsion",
    "icep_isolated",
    "icep_pair",
    "dep_virial",
    "dep_stresslet",
)
"""Names of the stress contributions, in the order of the contribution axis of stress arrays."""

SOLVENT = 0
STOKES_DRAG = 1
LUBRICATION = 2
REPULSION = 3
ICEP_ISOLATED = 4
ICEP_PAIR = 5
DEP_VIRIAL = 6
DEP_STRESSLET = 7
SHEAR_CONTRIBUTIONS = (SOLVENT, STOKES_DRAG, LUBRICATION, REPULSION)
"""Indices of the shear-flow and repulsion contributions."""
DIPOLOPHORESIS_CONTRIBUTIONS = (ICEP_ISOLATED, ICEP_PAIR, DEP_VIRIAL, DEP_STRESSLET)
"""Indices of the dipolophoresis contributions (all zero when the field is off)."""
N_CONTRIBUTIONS = len(STRESS_CONTRIBUTIONS)


def rheology(
    stress: np.ndarray, shear_rate: np.ndarray | float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative viscosity and normal-stress differences of stress tensors.

    Args:
        stress: (..., 3, 3) total stress in units ``eta gammadot_ref`` (axes x flow, y gradient, z
            vorticity).
        shear_rate: the shear rate ``gammadot / gammadot_ref`` of each tensor (broadcast against
            ``stress.shape[:-2]``); None means the reference rate 1.

    Returns:
        ``eta_r = S_xy / gammadot`` (``S_xy`` itself where the rate is 0: no shear, no viscosity; quiescent
        results report the shear stress there), ``N1 = S_xx - S_yy``, ``N2 = S_yy - S_zz`` (in
        ``eta gammadot_ref``), each of shape ``stress.shape[:-2]``.
    """
    stress = np.asarray(stress, dtype=float)
    shear_stress = stress[..., 0, 1]
    if shear_rate is not None:
        rate = np.broadcast_to(np.asarray(shear_rate, dtype=float), shear_stress.shape)
        shear_stress = np.where(rate > 0.0, shear_stress / np.where(rate > 0.0, rate, 1.0), shear_stress)
    return shear_stress, stress[..., 0, 0] - stress[..., 1, 1], stress[..., 1, 1] - stress[..., 2, 2]


def particle_pressure(stress: np.ndarray) -> np.ndarray:
    """Particle pressure ``Pi = -tr(stress) / 3`` of (..., 3, 3) stress tensors (same units)."""
    stress = np.asarray(stress, dtype=float)
    return -np.trace(stress, axis1=-2, axis2=-1) / 3.0


@dataclass(frozen=True)
class BlockAverage:
    """Mean of a time series with the standard error from block averages."""

    mean: float
    stderr: float
    n_blocks: int


def block_average(series: np.ndarray, n_blocks: int = 10, weights: np.ndarray | None = None) -> BlockAverage:
    """Mean and standard error of a correlated time series from ``n_blocks`` contiguous blocks.

    The series is cut into ``n_blocks`` blocks of equal sample count (a remainder at the start is
    dropped); the error is ``std(block means, ddof=1) / sqrt(n_blocks)``, valid when blocks are longer
    than the correlation time (Flyvbjerg & Petersen 1989). With ``weights`` (the time step each sample
    stands for, when the step adapts) every mean is a time average ``sum w x / sum w``; equal weights
    give the unweighted result. With fewer samples than blocks the error is NaN, never zero.
    """
    x = np.asarray(series, dtype=float)
    w = np.ones_like(x) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != x.shape:
        raise ValueError(f"weights must have the shape of series {x.shape}, got {w.shape}")
    if n_blocks < 2:
        raise ValueError(f"n_blocks must be >= 2, got {n_blocks}")
    if x.size == 0:
        return BlockAverage(float("nan"), float("nan"), 0)
    if x.size < n_blocks:
        return BlockAverage(float(np.sum(w * x) / np.sum(w)), float("nan"), 0)
    size = x.size // n_blocks
    start = x.size - size * n_blocks
    xb = x[start:].reshape(n_blocks, size)
    wb = w[start:].reshape(n_blocks, size)
    block_weight = wb.sum(axis=1)
    blocks = (xb * wb).sum(axis=1) / block_weight
    mean = float(np.sum(blocks * block_weight) / np.sum(block_weight))
    return BlockAverage(mean, float(blocks.std(ddof=1) / np.sqrt(n_blocks)), n_blocks)
