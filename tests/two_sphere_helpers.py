"""Helpers shared by the tests of the two-sphere solvers and of the near-field tables built from them."""

from __future__ import annotations

import numpy as np

from sim.dipolophoresis.two_sphere.electric import ElectricSolution, solve_electric
from sim.dipolophoresis.two_sphere.stokes import TwoSphereStokes


def electric_and_stokes(
    r: float | None, order: int
) -> tuple[ElectricSolution, ElectricSolution, TwoSphereStokes, TwoSphereStokes]:
    """Electric solutions (``m = 0, 1``) and Stokes systems (``m = 0, 1``) at one separation and order
    (``r = None``: an isolated sphere), in the argument order of ``icep_slips`` and ``icep_functions``."""
    return (
        solve_electric(r, 0, order),
        solve_electric(r, 1, order),
        TwoSphereStokes(r, 0, order),
        TwoSphereStokes(r, 1, order),
    )


def radii_in_every_regime(seed: int, count: int, r_first: float, r_last: float) -> np.ndarray:
    """Centre distances that visit every regime of a table loader: contact, below the first node
    (``r_first``), the first and the last node (``r_last``), beyond the table, then ``count`` random gaps
    ``exp(U(-9, 3))`` (seeded)."""
    rng = np.random.default_rng(seed)
    return np.concatenate([[2.0, 2.0001, r_first, r_last, 11.0], 2.0 + np.exp(rng.uniform(-9, 3, count))])
