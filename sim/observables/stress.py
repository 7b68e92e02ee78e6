"""Bulk stress, its contributions, and rheological functions with block-average errors.

The bulk stress of a suspension (Batchelor 1970; paper eqs 2.8–2.9), in units ``eta gammadot``::

    <Sigma> = -p_f I + 2 eta E_inf + <Sigma^p>,
    <Sigma^p> = -n <R_SU . (U - u_inf; Omega - omega_inf)> + n <R_SE : E_inf> - n <x F^p>

where the velocity in the first term is the shear-and-repulsion disturbance velocity solved from
``R_FU``. It is reported per contribution (the isotropic ``-p_f I`` is not computed; it cancels in
``N1`` and ``N2``):

============== ==================================================================================
``solvent``    ``2 eta E_inf``
``stokes_drag`` isolated-sphere stresslets ``n (20/3) pi eta a^3 E_inf`` (gives 2.5 phi)
``lubrication`` pair stresslets ``-R_SU^lub . V' + R_SE^lub : E_inf`` summed over particles / V
``repulsion``   virial of the repulsive forces ``-(1/V) sum_pairs |F| r d d``
============== ==================================================================================

Rheology (paper §2.4): ``eta_r = Sigma_xy / (eta gammadot)``, ``N1 = Sigma_xx - Sigma_yy``,
``N2 = Sigma_yy - Sigma_zz``.

References:
    Batchelor, G. K. (1970) J. Fluid Mech. 41, 545-570.
    Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §2.4.
    Flyvbjerg, H. & Petersen, H. G. (1989) J. Chem. Phys. 91, 461-466 (block averaging).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STRESS_CONTRIBUTIONS: tuple[str, ...] = ("solvent", "stokes_drag", "lubrication", "repulsion")
"""Names of the stress contributions, in the order of the contribution axis of stress arrays."""

SOLVENT = 0
STOKES_DRAG = 1
LUBRICATION = 2
REPULSION = 3
N_CONTRIBUTIONS = len(STRESS_CONTRIBUTIONS)


def rheology(stress: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative viscosity and normal-stress differences of stress tensors.

    Args:
        stress: (..., 3, 3) total stress in units ``eta gammadot`` (axes x flow, y gradient, z vorticity).

    Returns:
        ``eta_r = S_xy``, ``N1 = S_xx - S_yy``, ``N2 = S_yy - S_zz``, each of shape ``stress.shape[:-2]``.
    """
    stress = np.asarray(stress, dtype=float)
    return stress[..., 0, 1], stress[..., 0, 0] - stress[..., 1, 1], stress[..., 1, 1] - stress[..., 2, 2]


@dataclass(frozen=True)
class BlockAverage:
    """Mean of a time series with the standard error from block averages."""

    mean: float
    stderr: float
    n_blocks: int


def block_average(series: np.ndarray, n_blocks: int = 10) -> BlockAverage:
    """Mean and standard error of a correlated time series from ``n_blocks`` contiguous blocks.

    The series is cut into ``n_blocks`` equal blocks (a remainder at the start is dropped); the error is
    ``std(block means, ddof=1) / sqrt(n_blocks)``, valid when blocks are longer than the correlation
    time (Flyvbjerg & Petersen 1989). With fewer samples than blocks the error is NaN, never zero.
    """
    x = np.asarray(series, dtype=float)
    if n_blocks < 2:
        raise ValueError(f"n_blocks must be >= 2, got {n_blocks}")
    if x.size == 0:
        return BlockAverage(float("nan"), float("nan"), 0)
    if x.size < n_blocks:
        return BlockAverage(float(x.mean()), float("nan"), 0)
    size = x.size // n_blocks
    blocks = x[x.size - size * n_blocks :].reshape(n_blocks, size).mean(axis=1)
    return BlockAverage(float(blocks.mean()), float(blocks.std(ddof=1) / np.sqrt(n_blocks)), n_blocks)
