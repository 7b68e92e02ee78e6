"""Induced-charge electrophoresis (ICEP) of two ideally polarisable spheres: exact pair functions.

Physics (Squires & Bazant 2004, 2006; Saintillan 2008, Phys. Fluids 20, 067104): each sphere carries
the induced zeta potential ``zeta`` of the insulating electric problem (:mod:`.electric`) and the
fluid slips over its surface with the Helmholtz--Smoluchowski velocity

    u_s = +(eps/eta) zeta grad_s(phi)          (draws fluid in at the poles, out at the equator).

The spheres are force- and torque-free; their translational velocities follow from the Stokes
problem with this slip (:class:`.stokes.TwoSphereStokes`). Units: lengths ``a``, velocities
``U0 = eps a E0^2 / eta`` (so ``eps = eta = a = E0 = 1`` below).

Decomposition by azimuthal order. With sphere 1 at the origin and sphere 2 at ``d z_hat``, the field
``e = cos(alpha) z_hat + sin(alpha) x_hat`` has potential ``phi = cos(alpha) phi_0 + sin(alpha) phi_1``
with ``phi_0`` the axisymmetric (``m = 0``) solution and ``phi_1 = Phi_1(theta) cos(varphi)`` the
transverse one; ``zeta = cos(alpha) Z_0 + sin(alpha) Z_1 cos(varphi)``. The slip is quadratic:

* ``cos^2(alpha)``: ``u_theta = Z_0 dphi_0/dtheta`` (axisymmetric) -> ``F_par``;
* ``sin^2(alpha)``: its ``m = 0`` part ``u_theta = (1/2) Z_1 dPhi_1/dtheta`` -> ``F_perp`` (the
  ``cos 2 varphi`` part moves neither sphere);
* ``sin(2 alpha)/2``: the ``m = 1`` part ``u_theta = Z_0 Phi_1' + Z_1 phi_0'``,
  ``u_varphi = -Z_0 Phi_1/sin(theta)`` (amplitudes of ``cos`` and ``sin varphi``) -> ``F_x``.

Sphere 2's velocity is then ``U = (F_par cos^2 alpha + F_perp sin^2 alpha) z_hat + F_x sin(2 alpha) x_hat``,
i.e. the functions of ``docs/model.md#dipolophoresis`` with ``alpha`` = sphere 2 and ``xh = z_hat``:
``F_par`` is ``U_z`` for ``alpha = 0``, ``F_perp`` is ``U_z`` for ``alpha = pi/2`` and ``F_x`` is ``U_x``
for ``alpha = pi/4``. Sphere 1 moves with ``-U`` (symmetry of equal spheres).

Method and why: the slip-driven mobility problem is solved directly (Lamb's solution about each
centre, Galerkin on both surfaces, :mod:`.stokes`) for ``m = 0`` and ``m = 1``, instead of the
reciprocal theorem, because the reciprocal theorem needs the surface tractions of the two-sphere
rigid-body problems (not only the resistance scalars) and the direct solve gives, with the same code,
the rigid resistance functions that are checked against the exact table.

References:
    D. Saintillan, Phys. Fluids 20, 067104 (2008).
    T. M. Squires & M. Z. Bazant, J. Fluid Mech. 509, 217 (2004); 560, 65 (2006).
    L. D. Reed & F. A. Morrison, J. Colloid Interface Sci. 54, 117 (1976); F. A. Morrison, J. Colloid
    Interface Sci. 34, 210 (1970) (uniform-zeta spheres translate at the Smoluchowski velocity).
    J. Happel & H. Brenner (1965); S. Kim & S. J. Karrila (1991) (Lamb's solution).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim.dipolophoresis.two_sphere.electric import ElectricSolution
from sim.dipolophoresis.two_sphere.stokes import TwoSphereStokes

FloatArray = NDArray[np.float64]


def _surface(electric: ElectricSolution, stokes: TwoSphereStokes, sphere: int) -> tuple[FloatArray, ...]:
    """``(zeta, dphi/dtheta, phi/sin(theta))`` amplitudes at the Stokes quadrature nodes of one sphere."""
    _, d_theta, m_over_sin = electric.surface_potential(sphere, stokes.cos_theta, stokes.sin_theta)
    zeta = electric.zeta(sphere, stokes.cos_theta, stokes.sin_theta)
    return zeta, d_theta, m_over_sin


def icep_slips(
    axial: ElectricSolution,
    transverse: ElectricSolution,
    stokes_axisymmetric: TwoSphereStokes,
    stokes_transverse: TwoSphereStokes,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Slip-velocity amplitudes of the three ICEP problems at the quadrature nodes.

    Args:
        axial: electric solution with the field along the line of centres (``m = 0``).
        transverse: electric solution with the field across it (``m = 1``).
        stokes_axisymmetric, stokes_transverse: the ``m = 0`` and ``m = 1`` Stokes systems (their
            quadrature nodes are used).

    Returns:
        ``(slip_par, slip_perp, slip_x)``: shapes ``(n_spheres, 3, n_quad)`` of the ``m = 0``
        (``slip_par``, ``slip_perp``) and ``m = 1`` (``slip_x``) systems; units ``U0``.
    """
    ns = stokes_axisymmetric.n_spheres
    slip_par = np.zeros((ns, 3, stokes_axisymmetric.n_quad))
    slip_perp = np.zeros_like(slip_par)
    slip_x = np.zeros((ns, 3, stokes_transverse.n_quad))
    for sphere in range(ns):
        z0, dphi0, _ = _surface(axial, stokes_axisymmetric, sphere)
        z1, dphi1, _ = _surface(transverse, stokes_axisymmetric, sphere)
        slip_par[sphere, 1] = z0 * dphi0
        slip_perp[sphere, 1] = 0.5 * z1 * dphi1
        z0, dphi0, _ = _surface(axial, stokes_transverse, sphere)
        z1, dphi1, phi1_over_sin = _surface(transverse, stokes_transverse, sphere)
        slip_x[sphere, 1] = 0.5 * (z0 * dphi1 + z1 * dphi0)
        slip_x[sphere, 2] = -0.5 * z0 * phi1_over_sin
    return slip_par, slip_perp, slip_x


def icep_functions(
    axial: ElectricSolution,
    transverse: ElectricSolution,
    stokes_axisymmetric: TwoSphereStokes,
    stokes_transverse: TwoSphereStokes,
) -> tuple[float, float, float]:
    """Exact ICEP pair functions ``(F_par, F_perp, F_x)`` of sphere 2 (``xh = +z``), units ``U0``.

    Args:
        axial, transverse: electric solutions for ``m = 0`` and ``m = 1`` at the same separation.
        stokes_axisymmetric, stokes_transverse: Stokes systems for ``m = 0`` and ``m = 1``.

    Returns:
        ``(F_par, F_perp, F_x)`` as defined in ``docs/model.md#dipolophoresis``.
    """
    slip_par, slip_perp, slip_x = icep_slips(axial, transverse, stokes_axisymmetric, stokes_transverse)
    ns = stokes_axisymmetric.n_spheres
    f_par = stokes_axisymmetric.solve_mobility(slip=slip_par).velocity[ns - 1]
    f_perp = stokes_axisymmetric.solve_mobility(slip=slip_perp).velocity[ns - 1]
    f_x = stokes_transverse.solve_mobility(slip=slip_x).velocity[ns - 1]
    return float(f_par), float(f_perp), float(f_x)


def uniform_zeta_velocities(
    electric: ElectricSolution, stokes: TwoSphereStokes, zeta: float = 1.0
) -> FloatArray:
    """Velocities of spheres with a fixed uniform zeta (Reed & Morrison 1976 test), units ``eps E0 zeta/eta``.

    The slip is ``u_s = zeta grad_s(phi)`` with the same electric solution; the exact answer is the
    Smoluchowski velocity ``U = zeta E0 e`` for every sphere at every separation (Morrison 1970).

    Args:
        electric: electric solution of order ``m`` (field along ``z`` for 0, ``x`` for 1).
        stokes: Stokes system of the same order ``m``.
        zeta: the uniform zeta potential (units ``E0 a``).

    Returns:
        shape ``(n_spheres,)``: velocities along the field.
    """
    slip = np.zeros((stokes.n_spheres, 3, stokes.n_quad))
    for sphere in range(stokes.n_spheres):
        _, d_theta, m_over_sin = electric.surface_potential(sphere, stokes.cos_theta, stokes.sin_theta)
        slip[sphere, 1] = zeta * d_theta
        slip[sphere, 2] = -zeta * m_over_sin
    return stokes.solve_mobility(slip=slip).velocity
