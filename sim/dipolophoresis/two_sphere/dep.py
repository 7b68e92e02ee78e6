"""Dielectrophoresis (DEP) of two ideally polarisable spheres: Maxwell force times exact mobility.

Force. Outside the thin, fully polarised double layer each sphere is an insulator
(``d phi/d n = 0``), so the Maxwell stress ``eps (E E - E^2 I / 2)`` reduces on the surface to the
normal traction ``-(eps/2) |grad_s phi|^2 n`` and the force on sphere ``i`` is (Saintillan 2008,
eq. 2.13; Squires & Bazant 2006)

    F_i = -(eps/2) surface-integral of |grad_s phi|^2 n dS,

with no torque. For the field ``e = cos(alpha) z_hat + sin(alpha) x_hat`` (sphere 1 at the origin,
sphere 2 at ``d z_hat``) the ``cos^2(alpha)`` and ``sin^2(alpha)`` parts give forces along the line of
centres and the cross term ``sin(2 alpha) grad phi_0 . grad phi_1`` the force along ``x_hat``:

    F_z^par  = -pi  int (dphi_0/dtheta)^2 cos(theta) d(cos theta),
    F_z^perp = -(pi/2) int [(dPhi_1/dtheta)^2 + (Phi_1/sin theta)^2] cos(theta) d(cos theta),
    F_x      = -(pi/2) int (dphi_0/dtheta)(dPhi_1/dtheta) sin(theta) d(cos theta)   (alpha = pi/4),

in units ``eps E0^2 a^2`` (Gauss--Legendre quadrature, exact for the truncated expansions).
Symmetry gives ``F_1 = -F_2``.

Velocity. Sphere 2 carries ``F``, sphere 1 ``-F``, both torque-free; the exact two-sphere mobility
problem is solved with the same Lamb/Galerkin code as ICEP (:mod:`.stokes`), so that
``U_2 = F/(6 pi eta a) [G z z + H (I - z z)]`` with the relative mobility functions ``G`` (along)
and ``H`` (across, torque-free) of Batchelor (1976) computed at the same separation. Units of the
result: ``U0 = eps a E0^2 / eta``. Far away ``F_par -> -1/r^4``, ``F_perp, F_x -> 1/(2 r^4)``.

References:
    D. Saintillan, Phys. Fluids 20, 067104 (2008), section II.C.
    G. K. Batchelor, J. Fluid Mech. 74, 1 (1976) (relative mobility functions G, H).
    D. J. Jeffrey & Y. Onishi, J. Fluid Mech. 139, 261 (1984); S. Kim & S. J. Karrila (1991), ch. 11.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim.dipolophoresis.two_sphere.electric import ElectricSolution
from sim.dipolophoresis.two_sphere.stokes import TwoSphereStokes

FloatArray = NDArray[np.float64]


def maxwell_forces(
    axial: ElectricSolution, transverse: ElectricSolution, stokes: TwoSphereStokes
) -> FloatArray:
    """Maxwell forces on each sphere for the three field orientations, units ``eps E0^2 a^2``.

    Args:
        axial, transverse: electric solutions for ``m = 0`` and ``m = 1``.
        stokes: any Stokes system of the same geometry; its Gauss--Legendre nodes are used.

    Returns:
        shape ``(3, n_spheres)``: rows ``F_z`` (field along, ``alpha = 0``), ``F_z`` (field across,
        ``alpha = pi/2``) and ``F_x`` (``alpha = pi/4``).
    """
    x, s, w = stokes.cos_theta, stokes.sin_theta, stokes.weights
    forces = np.zeros((3, stokes.n_spheres))
    for sphere in range(stokes.n_spheres):
        _, dphi0, _ = axial.surface_potential(sphere, x, s)
        _, dphi1, phi1_over_sin = transverse.surface_potential(sphere, x, s)
        forces[0, sphere] = -np.pi * np.sum(w * dphi0**2 * x)
        forces[1, sphere] = -0.5 * np.pi * np.sum(w * (dphi1**2 + phi1_over_sin**2) * x)
        forces[2, sphere] = -0.5 * np.pi * np.sum(w * dphi0 * dphi1 * s)
    return forces


def relative_mobilities(
    stokes_axisymmetric: TwoSphereStokes, stokes_transverse: TwoSphereStokes
) -> tuple[float, float]:
    """Batchelor's relative mobility functions ``(G, H)`` of two equal torque-free spheres.

    Sphere 2 carries the force ``F`` and sphere 1 ``-F``; then ``U_2 - U_1 = 2 F/(6 pi) [G zz + H(I - zz)]``
    (Batchelor 1976, with ``a = eta = 1``). ``G = 1/(X11A - X12A)`` exactly;
    ``H`` includes the rotation of the torque-free spheres.
    """
    force = np.array([-6.0 * np.pi, 6.0 * np.pi])
    g = stokes_axisymmetric.solve_mobility(forces=force).velocity
    h = stokes_transverse.solve_mobility(forces=force).velocity
    return float(0.5 * (g[1] - g[0])), float(0.5 * (h[1] - h[0]))


def dep_functions(
    axial: ElectricSolution,
    transverse: ElectricSolution,
    stokes_axisymmetric: TwoSphereStokes,
    stokes_transverse: TwoSphereStokes,
) -> tuple[float, float, float]:
    """Exact DEP pair functions ``(F_par, F_perp, F_x)`` of sphere 2 (``xh = +z``), units ``U0``.

    Args:
        axial, transverse: electric solutions for ``m = 0`` and ``m = 1``.
        stokes_axisymmetric, stokes_transverse: Stokes systems for ``m = 0`` and ``m = 1``.

    Returns:
        ``(F_par, F_perp, F_x)`` as defined in ``docs/model.md#dipolophoresis``.
    """
    if stokes_axisymmetric.n_spheres == 1:
        return 0.0, 0.0, 0.0
    forces = maxwell_forces(axial, transverse, stokes_axisymmetric)
    # Use the antisymmetric part (F_1 = -F_2 exactly by symmetry; the difference is a truncation check).
    antisymmetric = 0.5 * (forces[:, 1] - forces[:, 0])
    f_par = stokes_axisymmetric.solve_mobility(forces=np.array([-1.0, 1.0]) * antisymmetric[0]).velocity[1]
    f_perp = stokes_axisymmetric.solve_mobility(forces=np.array([-1.0, 1.0]) * antisymmetric[1]).velocity[1]
    f_x = stokes_transverse.solve_mobility(forces=np.array([-1.0, 1.0]) * antisymmetric[2]).velocity[1]
    return float(f_par), float(f_perp), float(f_x)
