"""The repulsion's total effect on the bulk stress: direct virial plus the stresslet it induces.

The ``repulsion`` contribution of :mod:`sim.observables.stress` is the direct virial ``-n <x F^p>``
alone; the hydrodynamic stresslet of the motion the repulsive forces drive,
``-n <R_SU . R_FU^-1 . F^p>``, sits inside ``lubrication`` because the step solves for the shear- and
repulsion-driven velocity together (paper eq. 2.9, ``docs/model.md#bulk-stress``). Sierou & Brady (2002)
report
the sum of the two as the interparticle-force stress, ``-n <(x I + R_SU . R_FU^-1) . F^p>``. By
linearity of Stokes flow the split needs one extra solve, ``R_FU . V^p = F^p``; this module does that
at a given configuration (a diagnostic, outside the time step).

Limit (tested): for two spheres alone, pushed apart by ``+-F`` along their line of centres, the
induced stresslet cancels the virial as the gap closes (lubrication makes the pair rigid in that
direction, and internal forces in a rigid body carry no particle stress; Batchelor 1970), so the total
interparticle stress vanishes at contact.

References:
    Batchelor, G. K. (1970) J. Fluid Mech. 41, 545-570.
    Sierou, A. & Brady, J. F. (2002) J. Rheol. 46, 1031-1056.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.config import SimulationConfig
from sim.hydrodynamics.lubrication import pair_stresslet_sum
from sim.hydrodynamics.resistance_solver import solve_resistance
from sim.pair_system import pair_system
from sim.step_parameters import step_parameters


@dataclass(frozen=True)
class InterparticleStress:
    """Stress tensors (3, 3) in units ``eta gammadot`` at one configuration.

    Attributes:
        virial: ``-n <x F^p>`` (the ``repulsion`` contribution of the step).
        induced: ``-n <R_SU . R_FU^-1 . F^p>`` (part of the step's ``lubrication`` contribution).
    """

    virial: np.ndarray
    induced: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """Sierou & Brady's interparticle-force stress, ``virial + induced``."""
        return self.virial + self.induced


def interparticle_stress(
    positions: np.ndarray, strain: float, config: SimulationConfig
) -> InterparticleStress:
    """Split the repulsion's stress at one configuration (same pair list, lubrication and solver
    settings as the time step).

    Args:
        positions: (N, 3) wrapped positions (units a).
        strain: accumulated strain (sets the Lees–Edwards offset).
        config: the run's configuration (box, lubrication, repulsion and solver parameters).

    Raises:
        RuntimeError: if the resistance solve does not converge.
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    n = positions.shape[0]
    if positions.shape != (config.n_particles, 3):
        raise ValueError(f"positions must have shape ({config.n_particles}, 3), got {positions.shape}")
    length = config.box_length
    pairs, units, scalars, _, diag, off, forces, virial = pair_system(
        positions, strain, step_parameters(config)
    )
    rhs = np.zeros((n, 6))
    rhs[:, :3] = forces
    velocities, iterations, residual = solve_resistance(
        diag, off, pairs, rhs, np.zeros((n, 6)), config.solver_tolerance, config.solver_max_iterations
    )
    if iterations < 0:
        raise RuntimeError(f"interparticle_stress: the resistance solve failed (residual {residual:.2e})")
    volume = length**3
    induced = pair_stresslet_sum(pairs, units, scalars, velocities, np.zeros((3, 3))) / volume
    return InterparticleStress(virial=-virial / volume, induced=induced)
