"""Electric potential around two insulating (fully polarised double layer) spheres in a uniform field.

Problem (thin, fully charged Debye layers, no surface conduction; Squires & Bazant 2004, 2006;
Saintillan 2008, Phys. Fluids 20, 067104, section II): outside two equal spheres of radius ``a``
the potential ``phi`` obeys Laplace's equation, the completely polarised double layer makes every
sphere an insulator,

    d phi / d n = 0 on both surfaces,        phi -> -E0 e . x far away,

and the induced zeta potential is ``zeta = phi_0 - phi_surface`` with the (constant) metal potential
``phi_0`` fixed by zero net charge (``zeta`` has zero mean over each sphere).

Method: twin multipole expansion (Jeffrey 1973; Jeffrey & Onishi 1984 use the same device for
Stokes flow). Sphere 1 is centred at the origin, sphere 2 at ``d z_hat``; the field is either along
the line of centres (``m = 0``, ``e = z_hat``) or across it (``m = 1``, ``e = x_hat``). Then

    phi = -E0 e . x + sum_{l>=1} [a1_l (a/r1)^(l+1) + a2_l (a/r2)^(l+1)] P_l^m(cos theta_i) cos(m phi),

with ``P_l^m`` the associated Legendre functions of :func:`scipy.special.lpmv` (Condon--Shortley
phase). Near sphere ``i`` the applied field and the other sphere's multipoles form a regular
expansion ``sum_n b_i,n r_i^n P_n^m``, obtained with the axial addition theorem (Hobson 1931)

    r2^(-l-1) P_l^m(cos th2) = sum_{n>=m} (-1)^(l+m) (n+l)!/((n+m)!(l-m)!) r1^n P_n^m(cos th1)/d^(n+l+1)

(source at ``+d z`` seen from sphere 1; the sign is ``(-1)^(n+m)`` for the source at ``-d z`` seen
from sphere 2). The insulating condition holds degree by degree: ``n b_n - (n+1) a_n = 0``, i.e.
``a_n = n/(n+1) b_n``. Truncating both sums at degree ``L`` leaves a ``2L x 2L`` linear system.
On the surface of sphere ``i`` (local polar angle measured from ``+z`` at its own centre)

    phi_s = sum_{n>=0} (2n+1)/(n+1) b_i,n P_n^m,   zeta = -sum_{n>=1} (2n+1)/(n+1) b_i,n P_n^m.

An isolated sphere gives ``phi_s = -(3/2) E0 a cos(theta)`` and ``zeta = (3/2) E0 a cos(theta)``.
The truncation error falls roughly like ``exp(-c L sqrt(d/a - 2))``: ``L`` must grow like
``(d/a - 2)^(-1/2)`` near contact (:mod:`.truncation`). Convergence is slowest for ``m = 1``: the field
across the line of centres is singular in the thin gap between nearly touching insulating spheres
(thin-film potential ``~ rho^(sqrt 2 - 1)`` at distances ``sqrt(d - 2) << rho << 1`` from the axis), so
the local surface field needs ``L`` ~ 200 for 1e-5 at ``d = 2.005`` while the integrated pair functions
converge faster.

Units: lengths ``a = 1``, potentials ``E0 a`` (``E0 = 1``). For ``m = 1`` every amplitude returned
here multiplies ``cos(phi)`` (and the azimuthal derivative multiplies ``-sin(phi)``).

References:
    D. Saintillan, Phys. Fluids 20, 067104 (2008), section II and appendix.
    T. M. Squires & M. Z. Bazant, J. Fluid Mech. 509, 217 (2004); 560, 65 (2006).
    D. J. Jeffrey, Proc. R. Soc. Lond. A 335, 355 (1973) (twin multipole expansions).
    E. W. Hobson, The theory of spherical and ellipsoidal harmonics (1931), addition theorems.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaln

from sim.dipolophoresis.two_sphere.legendre import legendre_table
from sim.dipolophoresis.two_sphere.truncation import truncation_order

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ElectricSolution:
    """Twin-multipole solution of the two-sphere insulating problem for one azimuthal order.

    Attributes:
        separation: centre distance ``d`` in units of ``a``; ``None`` for an isolated sphere.
        m: 0 (field along the line of centres, ``e = z_hat``) or 1 (field across, ``e = x_hat``).
        order: truncation degree ``L``.
        incident: shape ``(n_spheres, L + 1)``, regular coefficients ``b_i,n`` (``n = 0..L``) about each
            centre (applied field plus the other sphere's re-expanded multipoles), units ``E0 a``.
        multipoles: shape ``(n_spheres, L + 1)``, irregular coefficients ``a_i,n = n/(n+1) b_i,n``.
    """

    separation: float | None
    m: int
    order: int
    incident: FloatArray
    multipoles: FloatArray

    @property
    def n_spheres(self) -> int:
        """1 for an isolated sphere, 2 for a pair."""
        return int(self.incident.shape[0])

    def surface_potential(
        self, sphere: int, cos_theta: FloatArray, sin_theta: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Surface potential of one sphere and its angular derivatives.

        Args:
            sphere: 0 (sphere 1, at the origin) or 1 (sphere 2, at ``d z_hat``).
            cos_theta, sin_theta: shape ``(n_points,)``, local polar angle measured from ``+z``.

        Returns:
            ``(phi_s, dphi_s/dtheta, m phi_s/sin(theta))``, each shape ``(n_points,)``, units ``E0 a``;
            for ``m = 1`` they are the amplitudes of ``cos(phi)``. ``phi_s`` includes the constant
            ``b_0`` (the local mean potential, which ``zeta`` removes).
        """
        table = legendre_table(self.order, self.m, cos_theta, sin_theta)
        degrees = np.arange(self.order + 1, dtype=float)
        coefficients = (2.0 * degrees + 1.0) / (degrees + 1.0) * self.incident[sphere]
        return coefficients @ table.value, coefficients @ table.d_dtheta, coefficients @ table.m_over_sin

    def zeta(self, sphere: int, cos_theta: FloatArray, sin_theta: FloatArray) -> FloatArray:
        """Induced zeta potential ``zeta = phi_0 - phi_s`` (zero mean) on one sphere, units ``E0 a``.

        Returns the amplitude (of ``cos(phi)`` for ``m = 1``), shape ``(n_points,)``.
        """
        table = legendre_table(self.order, self.m, cos_theta, sin_theta)
        degrees = np.arange(self.order + 1, dtype=float)
        coefficients = -(2.0 * degrees + 1.0) / (degrees + 1.0) * self.incident[sphere]
        coefficients[0] = 0.0
        return coefficients @ table.value

    def potential(self, points: FloatArray) -> FloatArray:
        """Potential at arbitrary points outside the spheres (for checks), units ``E0 a``.

        Args:
            points: shape ``(n, 3)`` Cartesian positions (sphere 1 at the origin, sphere 2 at ``d z``).

        Returns:
            shape ``(n,)``, the full potential including the applied ``-E0 e . x``.
        """
        points = np.atleast_2d(np.asarray(points, dtype=float))
        e_dot_x = points[:, 2] if self.m == 0 else points[:, 0]
        total = -e_dot_x
        rho = np.hypot(points[:, 0], points[:, 1])
        safe_rho = np.where(rho > 0, rho, 1.0)
        azimuthal = np.ones_like(rho) if self.m == 0 else np.where(rho > 0, points[:, 0] / safe_rho, 1.0)
        centres = [0.0] if self.n_spheres == 1 else [0.0, float(self.separation)]  # type: ignore[arg-type]
        degrees = np.arange(self.order + 1, dtype=float)
        for sphere, zc in enumerate(centres):
            z = points[:, 2] - zc
            r = np.hypot(rho, z)
            table = legendre_table(self.order, self.m, z / r, rho / r)
            radial = r[None, :] ** (-degrees[:, None] - 1.0)
            field = (self.multipoles[sphere][:, None] * radial * table.value).sum(axis=0)
            total = total + field * azimuthal
        return total


def addition_matrices(separation: float, m: int, order: int) -> tuple[FloatArray, FloatArray]:
    """Re-expansion matrices of the axial addition theorem for degrees ``0..order``.

    Returns:
        ``(K12, K21)``, each shape ``(L + 1, L + 1)``: ``K12[n, l]`` maps sphere 2's irregular
        coefficient of degree ``l`` to sphere 1's regular coefficient of degree ``n``; ``K21`` the
        reverse. Entries with ``n < m`` or ``l < max(m, 1)`` are zero.
    """
    d = float(separation)
    n = np.arange(order + 1, dtype=float)[:, None]
    l = np.arange(order + 1, dtype=float)[None, :]
    valid = (n >= m) & (l >= max(m, 1))
    with np.errstate(invalid="ignore"):
        log_ratio = gammaln(n + l + 1) - gammaln(n + m + 1) - gammaln(np.maximum(l - m, 0) + 1)
        magnitude = np.exp(log_ratio - (n + l + 1) * math.log(d))
    magnitude = np.where(valid, magnitude, 0.0)
    sign_12 = np.where(((l + m) % 2) == 0, 1.0, -1.0)
    sign_21 = np.where(((n + m) % 2) == 0, 1.0, -1.0)
    return sign_12 * magnitude, sign_21 * magnitude


def solve_electric(separation: float | None, m: int, order: int | None = None) -> ElectricSolution:
    """Solve the insulating two-sphere problem in a unit uniform field (twin multipole expansion).

    Args:
        separation: centre distance ``d/a`` (> 2), or ``None`` for an isolated sphere.
        m: 0 for the field along the line of centres (``e = z_hat``, from sphere 1 towards sphere 2),
            1 for the field across it (``e = x_hat``).
        order: truncation degree ``L``; default :func:`.truncation.truncation_order` (4 for one sphere).

    Returns:
        :class:`ElectricSolution` (units ``E0 = a = 1``).

    Raises:
        ValueError: if ``separation <= 2`` or ``m`` is not 0 or 1.
    """
    if m not in (0, 1):
        raise ValueError(f"m must be 0 or 1, got {m}")
    if separation is not None and not separation > 2.0:
        raise ValueError(f"separation must exceed 2 (touching spheres), got {separation}")
    if order is None:
        order = 4 if separation is None else truncation_order(separation)
    size = order + 1
    degrees = np.arange(size, dtype=float)
    insulating = degrees / (degrees + 1.0)  # a_n = n/(n+1) b_n
    applied = np.zeros((2, size))
    # -E0 z = -r P_1(cos th); about sphere 2 also the constant -d.  -E0 x = +r P_1^1(cos th) cos(phi).
    applied[:, 1] = -1.0 if m == 0 else 1.0
    if separation is None:
        incident = applied[:1].copy()
        return ElectricSolution(None, m, order, incident, insulating * incident)
    if m == 0:
        applied[1, 0] = -float(separation)
    k12, k21 = addition_matrices(separation, m, order)
    # Unknowns a_1 (degrees 0..L), a_2 (0..L): a_i - D K a_j = D applied_i.
    identity = np.eye(size)
    system = np.block([[identity, -insulating[:, None] * k12], [-insulating[:, None] * k21, identity]])
    rhs = np.concatenate([insulating * applied[0], insulating * applied[1]])
    solution = np.linalg.solve(system, rhs)
    multipoles = np.stack([solution[:size], solution[size:]])
    incident = applied + np.stack([k12 @ multipoles[1], k21 @ multipoles[0]])
    return ElectricSolution(float(separation), m, order, incident, multipoles)
