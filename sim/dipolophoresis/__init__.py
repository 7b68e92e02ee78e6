"""Dipolophoresis (induced-charge electrophoresis + dielectrophoresis) of ideally conductive spheres.

Public contracts (units of ``U0 = eps a E0^2 / eta``, lengths in ``a``; ``docs/model.md#dipolophoresis``):

* :func:`periodic_pair_velocity` — velocity of a sphere due to one sphere at the origin and all its
  periodic images on the (sheared) Lees–Edwards lattice, far-field kernels, Ewald-summed.
* :func:`pair_functions` — the exact isolated two-sphere functions ``(F_par, F_perp, F_x)``.

Modules: :mod:`~sim.dipolophoresis.far_field` (free-space kernels, pair stresslet, DEP force),
:mod:`~sim.dipolophoresis.ewald` and :mod:`~sim.dipolophoresis.spme` (periodic sums),
:mod:`~sim.dipolophoresis.near_field` (table of the exact two-sphere functions),
:mod:`~sim.dipolophoresis.near_field_blend` (the blend into the time step),
:mod:`~sim.dipolophoresis.two_sphere` (the offline solver that made the table).
"""

from sim.dipolophoresis.near_field import pair_functions
from sim.dipolophoresis.periodic import periodic_pair_velocity

__all__ = ["pair_functions", "periodic_pair_velocity"]
