"""The six exact two-sphere dipolophoresis functions (ICEP and DEP) at one separation.

Combines :mod:`.electric` (insulating spheres, ``m = 0`` and ``m = 1``), :mod:`.icep` and :mod:`.dep`
(Lamb's solution about both centres, :mod:`.stokes`) into the pair functions of ``docs/model.md``
section 4: the velocity of sphere ``alpha`` due to sphere ``beta`` at ``x = x_alpha - x_beta``,
``xh = x/r``, field ``E0 e`` at angle ``th`` to ``xh``,

    U_alpha = U0 [ (F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t ],

``t`` the unit vector of ``e`` perpendicular to ``xh``, ``U0 = eps a E0^2/eta``, for ICEP and for DEP.
(Sphere 1 of the solvers is ``beta``, sphere 2 is ``alpha``.)

Truncation: both expansions use degree ``L = 14 + c/sqrt(r/a - 2)`` (:func:`truncation_order`);
``c = 10`` gives about 1e-7 U0 or better at every separation from ``r = 2.0001 a`` up (the error falls
roughly like ``exp(-1.5 (L - 14) sqrt(r - 2))``, i.e. ~4.5x per unit of ``c``). The generator
(``scripts/generate_near_field_table.py``) estimates the error from a second solve at ``c = 8``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim.dipolophoresis.two_sphere.dep import dep_functions
from sim.dipolophoresis.two_sphere.electric import solve_electric
from sim.dipolophoresis.two_sphere.icep import icep_functions
from sim.dipolophoresis.two_sphere.stokes import TwoSphereStokes
from sim.dipolophoresis.two_sphere.truncation import DEFAULT_ORDER_CONSTANT, truncation_order

__all__ = ["DEFAULT_ORDER_CONSTANT", "PairFunctionValues", "solve_pair_functions", "truncation_order"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PairFunctionValues:
    """Exact two-sphere functions at one separation (units ``U0``).

    Attributes:
        separation: centre distance ``r/a``.
        order: truncation degree used for both the electric and the Stokes expansions.
        icep: ``(F_par, F_perp, F_x)`` for induced-charge electrophoresis.
        dep: ``(F_par, F_perp, F_x)`` for dielectrophoresis.
    """

    separation: float
    order: int
    icep: tuple[float, float, float]
    dep: tuple[float, float, float]

    def as_array(self) -> FloatArray:
        """Shape ``(6,)``: ICEP ``F_par, F_perp, F_x`` then DEP ``F_par, F_perp, F_x``."""
        return np.array(self.icep + self.dep)


def solve_pair_functions(
    separation: float, order: int | None = None, n_quad: int | None = None
) -> PairFunctionValues:
    """Compute the ICEP and DEP pair functions at one separation by twin multipole expansions.

    Args:
        separation: centre distance ``r/a`` (> 2).
        order: truncation degree ``L`` (default :func:`truncation_order`).
        n_quad: Gauss--Legendre points per sphere (default ``2 L + 40``).

    Returns:
        :class:`PairFunctionValues`.
    """
    if order is None:
        order = truncation_order(separation)
    axial = solve_electric(separation, 0, order)
    transverse = solve_electric(separation, 1, order)
    stokes_axisymmetric = TwoSphereStokes(separation, 0, order, n_quad)
    stokes_transverse = TwoSphereStokes(separation, 1, order, n_quad)
    icep = icep_functions(axial, transverse, stokes_axisymmetric, stokes_transverse)
    dep = dep_functions(axial, transverse, stokes_axisymmetric, stokes_transverse)
    return PairFunctionValues(float(separation), order, icep, dep)
