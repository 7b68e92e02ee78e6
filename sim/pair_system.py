"""The pair system of one configuration: pair list, lubrication, ``R_FU`` blocks and repulsive forces.

Shared by the time step (:mod:`sim.stepper`) and by diagnostics that need extra solves at a given
configuration (:mod:`sim.observables.interparticle_stress`), so that both see exactly the same matrix.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sim.contacts.repulsion import repulsive_forces
from sim.geometry.box import lees_edwards_offset
from sim.geometry.neighbors import build_pair_list
from sim.hydrodynamics.lubrication import assemble_resistance, pair_scalars
from sim.hydrodynamics.stokes_drag import FORCE_DRAG, TORQUE_DRAG


@njit(cache=True)
def pair_system(
    positions: np.ndarray,
    strain: float,
    params,  # StepParameters (sim.step_parameters)
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pair list, lubrication scalars, block-sparse ``R_FU`` and repulsive forces at one configuration.

    Args:
        positions: (N, 3) wrapped positions (units a).
        strain: accumulated strain (sets the Lees–Edwards offset).
        params: :class:`sim.step_parameters.StepParameters` (box, lubrication cut-off and
            regularisation, repulsion scale and range).

    Returns:
        pairs (M, 2), unit vectors (M, 3), lubrication scalars (M, 22), gaps (M,), diagonal (N, 6, 6)
        and pair (M, 6, 6) blocks of ``R_FU``, repulsive forces (N, 3) and their virial sum (3, 3).
    """
    n = positions.shape[0]
    offset = lees_edwards_offset(strain, params.box_length)
    pairs, separations = build_pair_list(
        positions, params.box_length, offset, 2.0 + params.lubrication_cutoff
    )
    scalars, units, gaps = pair_scalars(
        pairs, separations, params.lubrication_cutoff, params.lubrication_regularisation
    )
    diag, off = assemble_resistance(n, pairs, units, scalars, FORCE_DRAG, TORQUE_DRAG)
    forces, virial = repulsive_forces(n, pairs, units, gaps, params.repulsion_scale, params.repulsion_range)
    return pairs, units, scalars, gaps, diag, off, forces, virial
