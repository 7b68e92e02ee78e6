"""Stokes flow around two equal spheres: Lamb's solution about each centre, Galerkin on both surfaces.

Used offline for (i) the force- and torque-free motion of two spheres driven by a prescribed slip
velocity (induced-charge electrophoresis, :mod:`.icep`), (ii) the exact two-sphere mobility under
prescribed forces (dielectrophoresis, :mod:`.dep`) and (iii) the rigid-body resistance functions
(checked against the exact table of ``tests/reference_data``).

Geometry and notation: spheres of radius ``a = 1``, sphere 1 centred at the origin, sphere 2 at
``d z_hat``; viscosity ``eta = 1``. Each problem has one azimuthal order ``m``: ``m = 0``
(axisymmetric, no swirl: motion along the line of centres) or ``m = 1`` (translation along
``x_hat`` and rotation about ``y_hat``). Velocity fields are written in a sphere's local spherical
components as ``u_r cos(m phi) e_r + u_theta cos(m phi) e_theta + u_phi sin(m phi) e_phi``; the
arrays here hold the three amplitudes ``(u_r, u_theta, u_phi)``.

Representation (Lamb 1932; Happel & Brenner 1965 section 3.2; Kim & Karrila 1991 section 4.2): the
disturbance flow is the sum over both spheres of Lamb's decaying solutions of degree ``n = 1..L``
about each centre,

    u = sum_n [ grad(Phi_-n-1) + curl(x chi_-n-1)
                - (n-2)/(2n(2n-1)) r^2 grad(p_-n-1) + (n+1)/(n(2n-1)) x p_-n-1 ],

with ``Phi, p ~ r^(-n-1) P_n^m(cos theta) cos(m phi)`` and ``chi ~ r^(-n-1) P_n^m sin(m phi)``
(``chi`` only for ``m = 1``). The ``n = 1`` pressure mode is the Stokeslet and the ``n = 1`` ``chi``
mode the rotlet: the force that sphere i exerts on the fluid is ``4 pi c_p1 z_hat`` (``m = 0``) or
``-4 pi c_p1 x_hat`` (``m = 1``), its torque on the fluid ``-8 pi c_chi1 y_hat``; a force- and
torque-free sphere has ``c_p1 = c_chi1 = 0`` and unknown ``U, Omega`` instead.

Boundary conditions ``u = U_i + Omega_i x (x - x_i) + u_slip`` on each surface are imposed in the
Galerkin sense: the residual is projected on the vector spherical harmonics ``P_n^m e_r``,
``grad_s(P_n^m cos m phi)`` and ``x_hat x grad_s(P_n^m sin m phi)`` of the same surface,
``n = 1..L``, by Gauss--Legendre quadrature in ``cos(theta)`` (azimuth exact). This is the twin
multipole method of Jeffrey & Onishi (1984) with the re-expansion of the other sphere's multipoles done
by quadrature instead of by addition theorems; with enough quadrature points (``n_quad >= 2 L``) the
two coincide. The square system (``2L`` or ``3L`` equations per sphere) is solved by LU; the
truncation error falls like ``exp(-c L sqrt(d - 2))``, so ``L`` grows like ``(d - 2)^(-1/2)``.

Why this method: one code serves the slip-driven (ICEP), force-driven (DEP) and rigid (resistance)
problems for both azimuthal orders, so the rigid-body results can be checked against the exact
resistance table and the slip problems inherit the same accuracy; the transverse ICEP function
``F_x`` needs the non-axisymmetric ``m = 1`` problem, which a stream function cannot describe.

References:
    H. Lamb, Hydrodynamics, 6th ed. (1932), section 335.
    J. Happel & H. Brenner, Low Reynolds number hydrodynamics (1965), section 3.2.
    S. Kim & S. J. Karrila, Microhydrodynamics (1991), sections 4.2 and 11.3.
    D. J. Jeffrey & Y. Onishi, J. Fluid Mech. 139, 261 (1984).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from sim.dipolophoresis.two_sphere.legendre import legendre_table
from sim.dipolophoresis.two_sphere.truncation import truncation_order

FloatArray = NDArray[np.float64]


def rigid_translation(m: int, cos_theta: FloatArray, sin_theta: FloatArray) -> FloatArray:
    """Surface amplitudes of a unit translation (``z_hat`` for ``m = 0``, ``x_hat`` for ``m = 1``).

    Returns shape ``(3, n_points)``: ``(u_r, u_theta, u_phi)`` amplitudes on a unit sphere.
    """
    if m == 0:
        return np.stack([cos_theta, -sin_theta, np.zeros_like(cos_theta)])
    return np.stack([sin_theta, cos_theta, -np.ones_like(cos_theta)])


def rigid_rotation(cos_theta: FloatArray, sin_theta: FloatArray) -> FloatArray:
    """Surface amplitudes of a unit rotation about ``y_hat`` (``m = 1``), shape ``(3, n_points)``."""
    return np.stack([np.zeros_like(cos_theta), np.ones_like(cos_theta), -cos_theta])


def lamb_velocities(
    m: int, order: int, r: FloatArray, cos_theta: FloatArray, sin_theta: FloatArray
) -> FloatArray:
    """Velocity amplitudes of Lamb's decaying solutions of degrees ``1..order`` about one centre.

    Args:
        m: azimuthal order (0 or 1).
        order: highest degree ``L``.
        r, cos_theta, sin_theta: shape ``(n_points,)``, spherical coordinates about the centre (``r > 0``).

    Returns:
        shape ``(n_types, 3, L, n_points)``: type 0 = potential ``grad Phi``, type 1 = pressure mode,
        type 2 (``m = 1`` only) = ``curl(x chi)``; component axis ``(u_r, u_theta, u_phi)`` in the
        spherical basis of this centre; unit coefficients.
    """
    table = legendre_table(order, m, cos_theta, sin_theta)
    n = np.arange(1, order + 1, dtype=float)[:, None]
    value = table.value[1:]
    d_theta = table.d_dtheta[1:]
    m_sin = table.m_over_sin[1:]
    return lamb_mode_velocities(n, value, d_theta, m_sin, r, 2 if m == 0 else 3)


def lamb_mode_velocities(
    n: FloatArray, value: FloatArray, d_theta: FloatArray, m_sin: FloatArray, r: FloatArray, n_types: int
) -> FloatArray:
    """Lamb's decaying modes of degrees ``n`` from the associated Legendre functions of one azimuthal order.

    Shared by :func:`lamb_velocities` (``m = 0, 1``) and
    :func:`~sim.dipolophoresis.two_sphere.stresslet.lamb_velocities_m2` (``m = 2``).

    Args:
        n: shape ``(n_degrees, 1)``, the degrees (floats).
        value, d_theta, m_sin: shape ``(n_degrees, n_points)``, ``P_n^m``, ``dP_n^m/dtheta`` and
            ``m P_n^m/sin(theta)`` at the points.
        r: shape ``(n_points,)``, distance from the centre (``r > 0``).
        n_types: 2 (potential and pressure modes: ``m = 0``) or 3 (also ``curl(x chi)``).

    Returns:
        shape ``(n_types, 3, n_degrees, n_points)``, as :func:`lamb_velocities`.
    """
    log_r = np.log(r)[None, :]
    r_n2 = np.exp((-n - 2.0) * log_r)  # r^(-n-2)
    r_n1 = np.exp((-n - 1.0) * log_r)
    r_n0 = np.exp(-n * log_r)
    alpha = -(n - 2.0) / (2.0 * n * (2.0 * n - 1.0))
    beta = (n + 1.0) / (n * (2.0 * n - 1.0))
    out = np.zeros((n_types, 3, n.shape[0], r.shape[0]))
    out[0, 0] = -(n + 1.0) * r_n2 * value
    out[0, 1] = r_n2 * d_theta
    out[0, 2] = -r_n2 * m_sin
    out[1, 0] = (beta - (n + 1.0) * alpha) * r_n0 * value
    out[1, 1] = alpha * r_n0 * d_theta
    out[1, 2] = -alpha * r_n0 * m_sin
    if n_types == 3:
        out[2, 1] = r_n1 * m_sin
        out[2, 2] = -r_n1 * d_theta
    return out


def galerkin_test_functions(
    value: FloatArray, d_theta: FloatArray, m_sin: FloatArray, weights: FloatArray, n_types: int
) -> FloatArray:
    """Weighted, normalised test functions of one azimuthal order (radial, ``grad_s``, toroidal).

    Args:
        value, d_theta, m_sin: shape ``(n_degrees, n_quad)``, ``P_n^m``, ``dP_n^m/dtheta``,
            ``m P_n^m/sin(theta)`` at the quadrature nodes.
        weights: shape ``(n_quad,)``, the Gauss--Legendre weights.
        n_types: 2 (``m = 0``: no toroidal functions) or 3.

    Returns:
        shape ``(n_types, 3, n_degrees, n_quad)``: each test function scaled to unit norm (Galerkin rows of
        unit scale), times the weights.
    """
    tests = np.zeros((n_types, 3, value.shape[0], value.shape[1]))
    tests[0, 0] = value
    tests[1, 1] = d_theta
    tests[1, 2] = -m_sin
    if n_types == 3:
        tests[2, 1] = -m_sin
        tests[2, 2] = d_theta
    norms = np.sqrt(np.einsum("tcnk,k->tn", tests**2, weights))
    norms[norms == 0.0] = 1.0
    return tests / norms[:, None, :, None] * weights


def galerkin_matrix(
    centres: list[float],
    cos_theta: FloatArray,
    sin_theta: FloatArray,
    tests: FloatArray,
    modes: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
) -> FloatArray:
    """Galerkin matrix of Lamb's modes about every centre, tested on every sphere's surface.

    The modes of the other sphere are evaluated at this sphere's quadrature nodes (re-expansion by
    quadrature) and turned from that sphere's spherical basis into this one's (both bases share the
    azimuth about the line of centres, so only ``(u_r, u_theta)`` rotate).

    Args:
        centres: ``z`` of the sphere centres (one or two).
        cos_theta, sin_theta: shape ``(n_quad,)``, the quadrature nodes on each sphere.
        tests: shape ``(n_types, 3, n_degrees, n_quad)``, weighted test functions
            (:func:`galerkin_test_functions`).
        modes: ``modes(r, cos_theta, sin_theta)``: the velocity amplitudes of the modes about one centre,
            shape ``(n_types, 3, n_degrees, n_points)`` (:func:`lamb_velocities`).

    Returns:
        shape ``(n_spheres * size, n_spheres * size)``, ``size = n_types * n_degrees``: rows (target sphere,
        test type, degree), columns (source sphere, mode type, degree).
    """
    n_types, _, n_degrees, n_quad = tests.shape
    size = n_types * n_degrees
    n_spheres = len(centres)
    matrix = np.zeros((n_spheres * size, n_spheres * size))
    test_matrix = tests.transpose(0, 2, 1, 3).reshape(size, 3 * n_quad)
    for s in range(n_spheres):  # target sphere (equations)
        rho = sin_theta
        for t in range(n_spheres):  # source sphere (multipoles)
            z_rel = centres[s] - centres[t] + cos_theta
            r = np.hypot(rho, z_rel)
            cos_t, sin_t = z_rel / r, rho / r
            vel = modes(r, cos_t, sin_t)  # (nt, 3, L, nq) in t's spherical basis
            if s != t:
                u_rho = vel[:, 0] * sin_t + vel[:, 1] * cos_t
                u_z = vel[:, 0] * cos_t - vel[:, 1] * sin_t
                vel = np.stack(
                    [
                        u_rho * sin_theta + u_z * cos_theta,
                        u_rho * cos_theta - u_z * sin_theta,
                        vel[:, 2],
                    ],
                    axis=1,
                )
            block = test_matrix @ vel.transpose(0, 2, 1, 3).reshape(size, 3 * n_quad).T
            matrix[s * size : (s + 1) * size, t * size : (t + 1) * size] = block
    return matrix


@dataclass(frozen=True)
class RigidMotion:
    """Result of a two-sphere Stokes solve, per sphere (shape ``(n_spheres,)`` each).

    Attributes:
        velocity: translational velocity along ``z_hat`` (``m = 0``) or ``x_hat`` (``m = 1``).
        rotation: angular velocity about ``y_hat`` (zero for ``m = 0``).
        force: force exerted by the sphere on the fluid (= minus the hydrodynamic force on it), same axis.
        torque: torque exerted by the sphere on the fluid about ``y_hat`` (zero for ``m = 0``).
    """

    velocity: FloatArray
    rotation: FloatArray
    force: FloatArray
    torque: FloatArray


class PairQuadrature:
    """Geometry and surface quadrature of a Galerkin system about two equal spheres (or one).

    Sphere 1 at the origin, sphere 2 at ``separation z_hat``; on each sphere ``n_quad`` Gauss--Legendre
    nodes in ``cos(theta)``, ``theta`` increasing from the ``+z`` pole.

    Args:
        separation: centre distance ``d/a`` (> 2), or ``None`` for an isolated sphere.
        order: truncation degree ``L``; default :func:`.truncation.truncation_order` (4 for one sphere).
        n_quad: Gauss--Legendre points per sphere; default ``2 L + 40``.
    """

    def __init__(self, separation: float | None, order: int | None = None, n_quad: int | None = None):
        if separation is not None and not separation > 2.0:
            raise ValueError(f"separation must exceed 2 (touching spheres), got {separation}")
        self.separation = separation
        if order is None:
            order = 4 if separation is None else truncation_order(separation)
        self.order = int(order)
        self.n_quad = 2 * self.order + 40 if n_quad is None else int(n_quad)
        self.n_spheres = 1 if separation is None else 2
        nodes, weights = np.polynomial.legendre.leggauss(self.n_quad)
        self.cos_theta: FloatArray = nodes[::-1].copy()  # theta increasing from the +z pole
        self.sin_theta: FloatArray = np.sqrt((1.0 - self.cos_theta) * (1.0 + self.cos_theta))
        self.weights: FloatArray = weights[::-1].copy()
        self.centres = [0.0] if separation is None else [0.0, float(separation)]


class TwoSphereStokes(PairQuadrature):
    """Galerkin system for Lamb's solution about two equal spheres (or one, ``separation=None``).

    Args:
        separation: centre distance ``d/a`` (> 2), or ``None`` for an isolated sphere.
        m: azimuthal order, 0 or 1.
        order: truncation degree ``L``; default :func:`.truncation.truncation_order` (4 for one sphere).
        n_quad: Gauss--Legendre points per sphere; default ``2 L + 40``.
    """

    def __init__(self, separation: float | None, m: int, order: int | None = None, n_quad: int | None = None):
        if m not in (0, 1):
            raise ValueError(f"m must be 0 or 1, got {m}")
        super().__init__(separation, order, n_quad)
        self.m = m
        self.n_types = 2 if m == 0 else 3
        self._tests = self._test_functions()
        self._build()

    # ----------------------------------------------------------------------------------------------
    def _test_functions(self) -> FloatArray:
        """Weighted test functions, shape ``(n_types, 3, L, n_quad)`` (radial, grad_s, toroidal)."""
        table = legendre_table(self.order, self.m, self.cos_theta, self.sin_theta)
        value, d_theta, m_sin = table.value[1:], table.d_dtheta[1:], table.m_over_sin[1:]
        return galerkin_test_functions(value, d_theta, m_sin, self.weights, self.n_types)

    def project(self, surface_velocity: FloatArray) -> FloatArray:
        """Galerkin projection of surface velocity amplitudes given at the quadrature nodes.

        Args:
            surface_velocity: shape ``(n_spheres, 3, n_quad)`` (or with a leading batch axis),
                ``(u_r, u_theta, u_phi)`` amplitudes on each sphere at :attr:`cos_theta`.

        Returns:
            shape ``(n_equations,)`` (or ``(batch, n_equations)``).
        """
        v = np.asarray(surface_velocity, dtype=float)
        batched = v.ndim == 4
        if not batched:
            v = v[None]
        rows = np.einsum("tcnk,bsck->bstn", self._tests, v).reshape(v.shape[0], -1)
        return rows if batched else rows[0]

    def _build(self) -> None:
        L, m, nt, ns = self.order, self.m, self.n_types, self.n_spheres
        n_eq = ns * nt * L
        matrix = galerkin_matrix(
            self.centres,
            self.cos_theta,
            self.sin_theta,
            self._tests,
            lambda r, cos_t, sin_t: lamb_velocities(m, L, r, cos_t, sin_t),
        )
        rigid = [rigid_translation(m, self.cos_theta, self.sin_theta)]
        if m == 1:
            rigid.append(rigid_rotation(self.cos_theta, self.sin_theta))
        rigid_columns = np.zeros((n_eq, ns * len(rigid)))
        for s in range(ns):
            for k, mode in enumerate(rigid):
                rows = np.einsum("tcnk,ck->tn", self._tests, mode).reshape(-1)
                rigid_columns[s * nt * L : (s + 1) * nt * L, s * len(rigid) + k] = rows
        self._matrix = matrix
        self._rigid_columns = rigid_columns
        self._n_rigid = len(rigid)
        # Columns of the Stokeslet (type 1, n = 1) and rotlet (type 2, n = 1) of each sphere.
        self._stokeslet_cols = [s * nt * L + 1 * L for s in range(ns)]
        self._rotlet_cols = [s * nt * L + 2 * L for s in range(ns)] if m == 1 else []
        # LU factors (column-equilibrated) of the mobility and resistance systems, built on first use.
        self._mobility_lu: tuple[FloatArray, NDArray[np.int32]] | None = None
        self._column_scale: FloatArray = np.ones(0)
        self._resistance_lu: tuple[FloatArray, NDArray[np.int32]] | None = None
        self._resistance_scale: FloatArray = np.ones(0)

    # ----------------------------------------------------------------------------------------------
    def _singular_columns(self) -> list[int]:
        return self._stokeslet_cols + self._rotlet_cols

    def _mobility_system(self) -> tuple[FloatArray, NDArray[np.int32], FloatArray, list[int]]:
        fixed = self._singular_columns()
        free = [j for j in range(self._matrix.shape[1]) if j not in fixed]
        if self._mobility_lu is None:
            a = np.hstack([self._matrix[:, free], -self._rigid_columns])
            self._column_scale = 1.0 / np.abs(a).max(axis=0)
            self._mobility_lu = scipy.linalg.lu_factor(a * self._column_scale)
        lu, piv = self._mobility_lu
        return lu, piv, self._column_scale, free

    def solve_mobility(
        self,
        slip: FloatArray | None = None,
        forces: FloatArray | None = None,
        torques: FloatArray | None = None,
    ) -> RigidMotion:
        """Motion of the spheres under prescribed surface slip, forces and torques (mobility problem).

        Args:
            slip: shape ``(n_spheres, 3, n_quad)``, slip-velocity amplitudes at the quadrature nodes
                (fluid velocity at the surface relative to the rigid motion); default none.
            forces: shape ``(n_spheres,)``, force each sphere exerts on the fluid (the external force
                on it), along ``z_hat`` (``m = 0``) or ``x_hat`` (``m = 1``); default zero.
            torques: shape ``(n_spheres,)``, torque on the fluid about ``y_hat`` (``m = 1``); default 0.

        Returns:
            :class:`RigidMotion`.
        """
        return self.solve_mobility_multipoles(slip, forces, torques)[0]

    def solve_resistance(self, velocities: FloatArray, rotations: FloatArray | None = None) -> RigidMotion:
        """Forces and torques needed to move the spheres rigidly (resistance problem, no slip).

        Args:
            velocities: shape ``(n_spheres,)``, velocities along ``z_hat`` (``m = 0``) or ``x_hat``.
            rotations: shape ``(n_spheres,)``, angular velocities about ``y_hat`` (``m = 1``).

        Returns:
            :class:`RigidMotion` with the forces/torques the spheres exert on the fluid.
        """
        return self.solve_resistance_multipoles(velocities, rotations)[0]

    # ----------------------------------------------------------------------------------------------
    # The same solves, returning the full multipole coefficients as well (the stresslet,
    # sim/dipolophoresis/two_sphere/stresslet.py, reads them); the methods above return their motion.
    def _unpack_multipoles(self, coefficients: FloatArray) -> FloatArray:
        """Coefficient vector (column order of the Galerkin matrix) -> shape ``(n_spheres, n_types, L)``."""
        return coefficients.reshape(self.n_spheres, self.n_types, self.order).copy()

    def solve_mobility_multipoles(
        self,
        slip: FloatArray | None = None,
        forces: FloatArray | None = None,
        torques: FloatArray | None = None,
    ) -> tuple[RigidMotion, FloatArray]:
        """:meth:`solve_mobility`, also returning the Lamb coefficients of both spheres.

        Args:
            slip, forces, torques: as for :meth:`solve_mobility`.

        Returns:
            ``(motion, multipoles)``: the :class:`RigidMotion` of :meth:`solve_mobility` and the
            coefficients, shape ``(n_spheres, n_types, L)``: ``[i, t, n - 1]`` multiplies the mode of
            type ``t`` (0 potential, 1 pressure, 2 ``chi``) and degree ``n`` about the centre of sphere
            ``i`` (unit modes of :func:`lamb_velocities`). The type-1 degree-2 entry is the sphere's
            stresslet (pressure ``p = c r^-3 P_2^m(cos theta) cos(m phi)``).
        """
        ns = self.n_spheres
        lu, piv, scale, free = self._mobility_system()
        rhs = np.zeros(self._matrix.shape[0]) if slip is None else self.project(slip)
        forces_arr = np.zeros(ns) if forces is None else np.asarray(forces, dtype=float)
        torques_arr = np.zeros(ns) if torques is None else np.asarray(torques, dtype=float)
        stokeslet = forces_arr / (4.0 * np.pi) * (1.0 if self.m == 0 else -1.0)
        rotlet = -torques_arr / (8.0 * np.pi)
        known = np.concatenate([stokeslet, rotlet if self.m == 1 else np.zeros(0)])
        singular = self._singular_columns()
        rhs = rhs - self._matrix[:, singular] @ known
        x = scipy.linalg.lu_solve((lu, piv), rhs) * scale
        rigid = x[len(free) :].reshape(ns, self._n_rigid)
        coefficients = np.zeros(self._matrix.shape[1])
        coefficients[free] = x[: len(free)]
        coefficients[singular] = known
        rotation = rigid[:, 1] if self.m == 1 else np.zeros(ns)
        motion = RigidMotion(
            rigid[:, 0].copy(), rotation.copy(), forces_arr, torques_arr if self.m == 1 else np.zeros(ns)
        )
        return motion, self._unpack_multipoles(coefficients)

    def solve_resistance_multipoles(
        self,
        velocities: FloatArray,
        rotations: FloatArray | None = None,
        surface_velocity: FloatArray | None = None,
    ) -> tuple[RigidMotion, FloatArray]:
        """:meth:`solve_resistance` with an optional extra prescribed surface velocity; Lamb coefficients too.

        The disturbance velocity on sphere ``i`` is ``U_i + Omega_i x (x - x_i) + surface_velocity_i``
        (e.g. ``surface_velocity = -E . (x - x_i)`` for a sphere that moves with a straining flow ``E . x``).

        Args:
            velocities, rotations: as for :meth:`solve_resistance`.
            surface_velocity: shape ``(n_spheres, 3, n_quad)`` amplitudes at the quadrature nodes, or None.

        Returns:
            ``(motion, multipoles)`` as for :meth:`solve_mobility_multipoles`; ``motion.force`` and
            ``motion.torque`` are those the spheres exert on the fluid.
        """
        ns = self.n_spheres
        u = np.asarray(velocities, dtype=float)
        w = np.zeros(ns) if rotations is None else np.asarray(rotations, dtype=float)
        if self._resistance_lu is None:
            self._resistance_scale = 1.0 / np.abs(self._matrix).max(axis=0)
            self._resistance_lu = scipy.linalg.lu_factor(self._matrix * self._resistance_scale)
        known = np.stack([u, w], axis=1)[:, : self._n_rigid].reshape(-1)
        rhs = self._rigid_columns @ known
        if surface_velocity is not None:
            rhs = rhs + self.project(surface_velocity)
        x = scipy.linalg.lu_solve(self._resistance_lu, rhs) * self._resistance_scale
        force = x[self._stokeslet_cols] * 4.0 * np.pi * (1.0 if self.m == 0 else -1.0)
        torque = -8.0 * np.pi * x[self._rotlet_cols] if self.m == 1 else np.zeros(ns)
        motion = RigidMotion(u, w if self.m == 1 else np.zeros(ns), force, torque)
        return motion, self._unpack_multipoles(x)
