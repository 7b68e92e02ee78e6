"""Exact stresslets of two equal ideally polarisable spheres in a uniform field (ICEP and DEP).

Problem. Two equal spheres (radius ``a = 1``, thin fully polarised double layers) at centre distance
``r``, field ``E0 e``; ``x = x_alpha - x_beta`` (from beta to alpha), ``xh = x/r``, ``c = e . xh``.
Units: stresslets in ``pi eps a^3 E0^2``, forces in ``pi eps a^2 E0^2`` (``eps = eta = a = E0 = 1``
in the code, then divided by ``pi``). Batchelor's (1970) sign convention: a rigid sphere in a
straining flow ``E . x`` carries ``S = (20/3) pi eta a^3 E``; the stresslet of a particle with surface
velocity ``u`` (rigid motion plus slip) is

    S = int_S [ sym(x (sigma . n)) - (1/3) I x . sigma . n - eta (u n + n u) ] dS,

its contribution to the bulk particle stress ``n <S>`` (Batchelor 1970; Kim & Karrila 1991, chapter 2).
The isolated ICEP sphere carries ``S0 = 9 (ee - I/3)`` (docs/model.md#dipolophoresis; it is the
squirmer stresslet ``4 pi B2 (ee - I/3)`` with ``B2 = 9/4``, Ishikawa et al. 2006).

Two mechanisms:

(a) **ICEP.** Force- and torque-free spheres with the slip ``u_s = zeta grad_s(phi)`` of the exact
    two-sphere electric problem (:mod:`.electric`, :mod:`.icep`). Reported: the pair correction
    ``dS = S_alpha - S0``.
(b) **DEP.** The stresslet each sphere carries because it moves rigidly (no slip) under the exact Maxwell
    forces ``F_alpha = -F_beta`` (:mod:`.dep`) in the two-sphere flow, and the force itself.

How the stresslet is extracted. The disturbance flow is the sum of Lamb's decaying solutions about the
two centres (:mod:`.stokes`); the split into a part regular outside sphere 1 and a part regular outside
sphere 2 is unique (their difference would be an entire decaying Stokes flow), so sphere ``i``'s own
expansion is the multipole expansion of its boundary integral. Its ``r^-2`` velocity comes only from the
degree-2 pressure mode ``p = c r^-3 P_2^m(cos th) cos(m ph)``, whose velocity is ``x p / 2``; the stresslet
flow is ``u_i = -(3/(8 pi eta)) x_i x_j x_k S_jk / r^5`` (Kim & Karrila 1991, chapter 2), so
``S = -(4 pi/3) c P`` with ``P`` the traceless tensor of ``P_2^m cos(m ph) = P_jk xh_j xh_k``:

    m = 0: P = (3/2)(zz - I/3)  ->  S = -2 pi c (zz - I/3)
    m = 1: P = -(3/2)(xz + zx)  ->  S = +2 pi c (xz + zx)          (Condon--Shortley phase)
    m = 2: P = 3 (xx - yy)      ->  S = -4 pi c (xx - yy)

(pair frame: sphere 1 = beta at the origin, sphere 2 = alpha at ``r z``). Checked against the isolated
values above and, for rigid pairs, against the exact ``X^G, Y^G, Y^H, X^M, Y^M, Z^M`` of
``tests/reference_data`` (tests/test_two_sphere_stresslet.py). Finding: near contact that table's ``Z^M``
is less accurate than its other functions (its Lamb rows differ from ours by 2e-4 at s = 2.025 and 8e-5 at
2.05, and are not monotone between its near-field row 2.02 and 2.025); ours, converged in ``L`` to 1e-8,
approaches Townsend's (2023) contact constants ``Z11M = 1.02509700``, ``Z12M = -0.07231066`` to 1e-5.

Azimuthal orders. With ``e = cos(al) z + sin(al) x`` (``al`` = angle between ``e`` and ``xh``) the potential
is ``phi = cos(al) phi_0 + sin(al) Phi_1 cos(ph)`` and ``zeta = cos(al) Z_0 + sin(al) Z_1 cos(ph)``; the slip
is quadratic in the field:

    cos^2(al):  u_th = Z_0 phi_0'                                                           (m = 0)
    sin^2(al):  u_th = (1/2) Z_1 Phi_1'                                                     (m = 0)
              + u_th = (1/2) Z_1 Phi_1' cos(2 ph),  u_ph = -(1/2) Z_1 (Phi_1/sin th) sin(2 ph)   (m = 2)
    sin(2 al):  u_th = (1/2)(Z_0 Phi_1' + Z_1 phi_0') cos(ph),
                u_ph = -(1/2) Z_0 (Phi_1/sin th) sin(ph)                                    (m = 1)

(``sin(al) cos(al) = sin(2 al)/2``; the ``m = 1`` slip is that of :func:`.icep.icep_slips`).

The ``cos(2 ph)`` part moves neither sphere (so the velocity tables need only ``m = 0, 1``) but it has a
stresslet: the ``m = 2`` Stokes problem is solved here (:class:`QuadrupolarStokes`, Lamb's solution of
azimuthal order 2 about both centres, same Galerkin method as :mod:`.stokes`).

Isotropic decomposition. Any symmetric traceless tensor built from ``e`` and ``xh``, even and quadratic in
``e``, is

    S = f1 T1 + f2 T2 + f3 T3 + f4 T4,
    T1 = ee - I/3,  T2 = c (e xh + xh e) - (2/3) c^2 I,  T3 = xh xh - I/3,  T4 = c^2 (xh xh - I/3).

Completeness and independence: a linear map from ``ee`` (six components) to symmetric traceless tensors
(five) that is invariant under rotations about ``xh`` and reflections in planes containing ``xh`` (an
achiral pair) has one free coefficient per azimuthal order of the output, except ``m = 0``, where the
``zz`` part of ``ee`` and its trace (``= 1``) both contribute: 2 + 1 + 1 = 4 coefficients. In the pair
frame, with ``A`` (``cos^2 al`` term, m = 0), ``B`` (``sin^2 al``, m = 0 and 2) and ``X`` (``sin 2al`` term,
m = 1) the components of ``S = cos^2(al) A + sin^2(al) B + sin(2 al) X``,

    f1 = B_xx - B_yy                      (the only m = 2 term: T1 alone has a cos(2 ph) part)
    f2 = 2 X_xz - f1                      (xz component)
    f3 = (3 B_zz + f1)/2                  (zz component, c^0)
    f4 = (3/2)(A_zz - B_zz - f1) - 2 f2    (zz component, c^2)

a unique inverse, so the four tensors are independent and complete.

Far field (docs/model.md#dipolophoresis; confirmed here by the exact solution): the ICEP pair correction is
``r^-3 [9 ee - 36 c (e xh + xh e) + (225/2 c^2 - 45/2) xh xh + (9/2 - 27/2 c^2) I]``, i.e.
``(f1, f2, f3, f4) = (9, -36, -45/2, 225/2) / r^3``; ``r^3 f`` -> these to 1e-3 at r = 160 and the residual
is ``O(r^-5)`` (fitted slope -5.0, no ``r^-4`` term), ``~ -(57/2)(1, -5, -5/2, 35/2)/r^5`` (fitted at
r = 160..320 to 0.2 %, not derived). At r = 4 the O(r^-3) form overestimates ``f4`` by 34 %; below
r ~ 2.1 the signs of ``f2`` and ``f4`` (and of ``f3`` below 2.003) differ from it, and ``f2, f4`` diverge
weakly at contact.

What is exact and what is approximated (issue 11, item 7). Exact (to the stated truncation) for an isolated
pair in the thin-double-layer, no-surface-conduction, linear-zeta model: the electric problem, the slip, the
two-sphere Stokes flows of all three azimuthal orders, hence each sphere's full ICEP stresslet, the Maxwell
force and the rigid-body stresslets under it. Approximated in the suspension stress built from them:
pairwise additivity (three-body corrections neglected, as for the velocities), the blend to the far field
at the cut-off, the near-contact extrapolation below ``r - 2 = 5e-4``; and the DEP contribution to the
bulk stress is modelled, as in docs/model.md and the paper, by the pair virial ``-x F`` plus these induced
stresslets (the first moment of the Maxwell traction beyond the virial, e.g. the isolated-sphere
``(3/5) pi eps a^3 E0^2 (ee - I/3)``, is not included).

DEP. The force on alpha is ``F = (F_par c^2 + F_perp s^2) xh + F_x sin(2 al) t`` (``t`` the unit vector of
``e - c xh``; far field ``(-6, 3, 3)/r^4``, i.e. ``F = -3 W/r^4``); the two spheres carry ``+-F`` and the
rigid-body stresslet each then carries is

    S = s_par (F . xh)(xh xh - I/3) + s_perp [F_t xh + xh F_t],   F_t = F - (F . xh) xh,

with the force-to-stresslet mobilities ``s_par, s_perp`` (units ``a``; far field ``s_par = 5/(2 r^2)``, the
Faxen stresslet of the partner's Stokeslet). In the basis above
``(g1, g2, g3, g4) = (0, 2 s_perp F_x, s_par F_perp, s_par (F_par - F_perp) - 4 s_perp F_x)``; far field
``g3 = 15/(2 r^6)``, ``g4 = -45/(2 r^6)``, ``g2 = O(r^-8)``.

References:
    G. K. Batchelor, J. Fluid Mech. 41, 545 (1970) (bulk stress, stresslet).
    D. Saintillan, Phys. Fluids 20, 067104 (2008) (two-sphere ICEP/DEP by twin multipole expansions).
    S. Kim & S. J. Karrila, Microhydrodynamics (1991), sections 2.3, 4.2 and 11.3.
    D. J. Jeffrey, Phys. Fluids A 4, 16 (1992) (two-sphere resistance functions X^G .. Z^M).
    T. Ishikawa, M. P. Simmonds & T. J. Pedley, J. Fluid Mech. 568, 119 (2006) (squirmer stresslet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from sim.dipolophoresis.two_sphere.dep import maxwell_forces
from sim.dipolophoresis.two_sphere.electric import ElectricSolution, solve_electric
from sim.dipolophoresis.two_sphere.icep import icep_slips
from sim.dipolophoresis.two_sphere.legendre import LegendreTable
from sim.dipolophoresis.two_sphere.stokes import (
    PairQuadrature,
    TwoSphereStokes,
    galerkin_matrix,
    galerkin_test_functions,
    lamb_mode_velocities,
)
from sim.dipolophoresis.two_sphere.tabulation import split_table_text
from sim.dipolophoresis.two_sphere.truncation import truncation_order

FloatArray = NDArray[np.float64]

__all__ = [
    "ICEP_FAR_FIELD_COEFFICIENTS",
    "ISOLATED_STRESSLET",
    "NEAR_CONTACT_RATIO",
    "STRESS_COLUMNS",
    "STRESS_FUNCTION_NAMES",
    "PairFrameStresslets",
    "PairStressletValues",
    "QuadrupolarStokes",
    "StressTable",
    "basis_tensors",
    "decompose_pair_frame",
    "fit_shifted_power",
    "icep_m2_slip",
    "icep_pair_frame_stresslets",
    "lamb_velocities_m2",
    "legendre_table_m2",
    "near_contact_nodes",
    "read_stress_table_text",
    "shifted_power_value",
    "solve_pair_stresslets",
    "stresslet_from_multipole",
    "stresslet_tensor",
]

ISOLATED_STRESSLET = 9.0
"""``S0 = 9 (ee - I/3)`` in units ``pi eps a^3 E0^2`` (docs/model.md#dipolophoresis)."""

ICEP_FAR_FIELD_COEFFICIENTS = (9.0, -36.0, -22.5, 112.5)
"""``r^3 (f1, f2, f3, f4)`` of docs/model.md#icep-pair-stresslet's O(r^-3) ICEP pair correction."""


# ------------------------------------------------------------------------------------------------
# Tensor algebra of the decomposition
# ------------------------------------------------------------------------------------------------
def basis_tensors(e: ArrayLike, xh: ArrayLike) -> FloatArray:
    """The four basis tensors ``T1..T4`` (see module docstring), shape ``(4, 3, 3)``.

    Args:
        e: shape ``(3,)``, unit field direction.
        xh: shape ``(3,)``, unit vector from beta to alpha.
    """
    e_arr = np.asarray(e, dtype=float)
    x_arr = np.asarray(xh, dtype=float)
    c = float(e_arr @ x_arr)
    identity = np.eye(3)
    t3 = np.outer(x_arr, x_arr) - identity / 3.0
    return np.stack(
        [
            np.outer(e_arr, e_arr) - identity / 3.0,
            c * (np.outer(e_arr, x_arr) + np.outer(x_arr, e_arr)) - (2.0 / 3.0) * c * c * identity,
            t3,
            c * c * t3,
        ]
    )


def stresslet_tensor(functions: ArrayLike, e: ArrayLike, xh: ArrayLike) -> FloatArray:
    """``f1 T1 + f2 T2 + f3 T3 + f4 T4``, shape ``(3, 3)`` (units of ``functions``)."""
    return np.einsum("k,kij->ij", np.asarray(functions, dtype=float), basis_tensors(e, xh))


def decompose_pair_frame(a: FloatArray, b: FloatArray, x: FloatArray) -> tuple[float, float, float, float]:
    """Scalar functions ``(f1, f2, f3, f4)`` from the pair-frame tensors of ``c^2 A + s^2 B + sin(2al) X``.

    Args:
        a, b, x: shape ``(3, 3)`` each, pair frame (``xh = z``, ``e = cos(al) z + sin(al) x``).

    Returns:
        ``(f1, f2, f3, f4)`` (module docstring: the unique inverse of the decomposition).
    """
    f1 = b[0, 0] - b[1, 1]
    f2 = 2.0 * x[0, 2] - f1
    f3 = 0.5 * (3.0 * b[2, 2] + f1)
    f4 = 1.5 * (a[2, 2] - b[2, 2] - f1) - 2.0 * f2
    return float(f1), float(f2), float(f3), float(f4)


def stresslet_from_multipole(m: int, coefficient: float) -> FloatArray:
    """Stresslet (units ``pi eta a^3`` x velocity scale) of a degree-2 pressure mode of amplitude ``c``.

    ``S/pi = -2 c (zz - I/3)`` (m = 0), ``+2 c (xz + zx)`` (m = 1), ``-4 c (xx - yy)`` (m = 2); pair frame,
    ``p = c r^-3 P_2^m(cos th) cos(m ph)`` about the sphere's centre (module docstring).
    """
    out = np.zeros((3, 3))
    if m == 0:
        out[:] = -2.0 * coefficient * (np.diag([0.0, 0.0, 1.0]) - np.eye(3) / 3.0)
    elif m == 1:
        out[0, 2] = out[2, 0] = 2.0 * coefficient
    elif m == 2:
        out[0, 0], out[1, 1] = -4.0 * coefficient, 4.0 * coefficient
    else:
        raise ValueError(f"m must be 0, 1 or 2, got {m}")
    return out


# ------------------------------------------------------------------------------------------------
# Azimuthal order 2: Legendre functions and Lamb's solution
# ------------------------------------------------------------------------------------------------
def legendre_table_m2(order: int, cos_theta: FloatArray, sin_theta: FloatArray) -> LegendreTable:
    """``P_n^2(cos th)``, ``dP_n^2/dth`` and ``2 P_n^2/sin th`` for ``n = 0..order`` (rows), no division.

    With ``x = cos th``, ``s = sin th`` and the recurrences of ``P_n, P_n', P_n''`` (``P''_{n+1} = P''_{n-1} +
    (2n+1) P'_n``): ``P_n^2 = s^2 P_n''`` (Condon--Shortley phase ``(-1)^2 = 1``, as
    :func:`scipy.special.lpmv`), ``dP_n^2/dth = s [(n(n+1) - 2) P_n' - 2 x P_n'']`` (from Legendre's
    equation differentiated once) and     ``2 P_n^2/s = 2 s P_n''``.

    Args:
        order: highest degree (>= 2).
        cos_theta, sin_theta: shape ``(n_points,)``.

    Returns:
        :class:`~sim.dipolophoresis.two_sphere.legendre.LegendreTable`, arrays ``(order + 1, n_points)``.
    """
    if order < 2:
        raise ValueError(f"order must be >= 2, got {order}")
    x = np.asarray(cos_theta, dtype=float)
    s = np.asarray(sin_theta, dtype=float)
    p = np.empty((order + 1, x.shape[0]))
    dp = np.empty_like(p)
    d2p = np.empty_like(p)
    p[0], p[1] = 1.0, x
    dp[0], dp[1] = 0.0, 1.0
    d2p[0], d2p[1] = 0.0, 0.0
    for n in range(1, order):
        p[n + 1] = ((2 * n + 1) * x * p[n] - n * p[n - 1]) / (n + 1)
        dp[n + 1] = dp[n - 1] + (2 * n + 1) * p[n]
        d2p[n + 1] = d2p[n - 1] + (2 * n + 1) * dp[n]
    degrees = np.arange(order + 1, dtype=float)[:, None]
    value = s * s * d2p
    d_theta = s * ((degrees * (degrees + 1.0) - 2.0) * dp - 2.0 * x * d2p)
    return LegendreTable(value, d_theta, 2.0 * s * d2p)


def lamb_velocities_m2(order: int, r: FloatArray, cos_theta: FloatArray, sin_theta: FloatArray) -> FloatArray:
    """Velocity amplitudes of Lamb's decaying modes of azimuthal order 2, degrees ``2..order``.

    Same modes and normalisation as :func:`sim.dipolophoresis.two_sphere.stokes.lamb_velocities` (potential
    ``grad Phi``, pressure mode, ``curl(x chi)``; ``Phi, p ~ r^(-n-1) P_n^2 cos 2ph``, ``chi ~ r^(-n-1) P_n^2
    sin 2ph``), amplitudes of ``(cos 2ph, cos 2ph, sin 2ph)`` in the spherical basis of the centre.

    Returns:
        shape ``(3, 3, order - 1, n_points)``: (type, component, degree ``n = 2..order``, point).
    """
    table = legendre_table_m2(order, cos_theta, sin_theta)
    n = np.arange(2, order + 1, dtype=float)[:, None]
    value, d_theta, m_sin = table.value[2:], table.d_dtheta[2:], table.m_over_sin[2:]
    return lamb_mode_velocities(n, value, d_theta, m_sin, r, 3)


class QuadrupolarStokes(PairQuadrature):
    """Azimuthal order 2 of the two-sphere Stokes problem (slip- or boundary-velocity-driven).

    An ``m = 2`` surface velocity exerts no force or torque (rigid motions have ``m <= 1``), so the spheres
    do not move and the problem is a plain Dirichlet problem for the disturbance flow: Lamb's decaying
    modes of degrees ``2..L`` about both centres, Galerkin projection on the vector harmonics of order 2 on
    both surfaces, exactly as :class:`~sim.dipolophoresis.two_sphere.stokes.TwoSphereStokes` does for
    ``m = 0, 1`` (same quadrature nodes for the same ``L`` and ``n_quad``; the quadrature, test functions
    and matrix assembly are those of :mod:`.stokes`: :class:`~.stokes.PairQuadrature`,
    :func:`~.stokes.galerkin_test_functions`, :func:`~.stokes.galerkin_matrix`).

    Args:
        separation: centre distance ``d/a`` (> 2), or ``None`` for an isolated sphere.
        order: truncation degree ``L`` (default :func:`truncation_order`; 4 for one sphere).
        n_quad: Gauss--Legendre points per sphere (default ``2 L + 40``).
    """

    m = 2

    def __init__(self, separation: float | None, order: int | None = None, n_quad: int | None = None):
        super().__init__(separation, order, n_quad)
        self._tests = self._test_functions()
        self._build()

    def _test_functions(self) -> FloatArray:
        table = legendre_table_m2(self.order, self.cos_theta, self.sin_theta)
        value, d_theta, m_sin = table.value[2:], table.d_dtheta[2:], table.m_over_sin[2:]
        return galerkin_test_functions(value, d_theta, m_sin, self.weights, 3)

    def project(self, surface_velocity: FloatArray) -> FloatArray:
        """Galerkin projection of ``(n_spheres, 3, n_quad)`` amplitudes (of ``cos 2ph, cos 2ph, sin 2ph``)."""
        v = np.asarray(surface_velocity, dtype=float)
        return np.einsum("tcnk,sck->stn", self._tests, v).reshape(-1)

    def _build(self) -> None:
        order = self.order
        matrix = galerkin_matrix(
            self.centres,
            self.cos_theta,
            self.sin_theta,
            self._tests,
            lambda r, cos_t, sin_t: lamb_velocities_m2(order, r, cos_t, sin_t),
        )
        self._scale = 1.0 / np.abs(matrix).max(axis=0)
        self._lu = scipy.linalg.lu_factor(matrix * self._scale)

    def solve(self, surface_velocity: FloatArray) -> FloatArray:
        """Lamb coefficients for a prescribed disturbance velocity on both surfaces.

        Args:
            surface_velocity: shape ``(n_spheres, 3, n_quad)``, amplitudes at :attr:`cos_theta`.

        Returns:
            shape ``(n_spheres, 3, L - 1)``: ``[i, t, n - 2]``, types as in
            :meth:`TwoSphereStokes.solve_mobility_multipoles`; ``[i, 1, 0]`` is the degree-2 pressure
            amplitude (stresslet).
        """
        x = scipy.linalg.lu_solve(self._lu, self.project(surface_velocity)) * self._scale
        return x.reshape(self.n_spheres, 3, self.order - 1)


# ------------------------------------------------------------------------------------------------
# The pair problem
# ------------------------------------------------------------------------------------------------
def icep_m2_slip(transverse: ElectricSolution, stokes: QuadrupolarStokes) -> FloatArray:
    """The ``cos 2ph`` part of the ``sin^2(al)`` ICEP slip.

    ``u_th = Z_1 Phi_1'/2`` (amplitude of ``cos 2ph``), ``u_ph = -Z_1 Phi_1/(2 sin th)`` (of ``sin 2ph``).

    Returns:
        shape ``(n_spheres, 3, n_quad)``, units ``U0``.
    """
    slip = np.zeros((stokes.n_spheres, 3, stokes.n_quad))
    for sphere in range(stokes.n_spheres):
        _, d_theta, over_sin = transverse.surface_potential(sphere, stokes.cos_theta, stokes.sin_theta)
        zeta = transverse.zeta(sphere, stokes.cos_theta, stokes.sin_theta)
        slip[sphere, 1] = 0.5 * zeta * d_theta
        slip[sphere, 2] = -0.5 * zeta * over_sin
    return slip


@dataclass(frozen=True)
class PairFrameStresslets:
    """Pair-frame stresslets of both spheres (units ``pi eps a^3 E0^2``), index 0 = beta, 1 = alpha.

    Attributes:
        a: shape ``(n_spheres, 3, 3)``: the ``cos^2(al)`` term (field along the line of centres).
        b: shape ``(n_spheres, 3, 3)``: the ``sin^2(al)`` term (m = 0 and m = 2 parts).
        x: shape ``(n_spheres, 3, 3)``: the ``sin(2 al)`` term (m = 1).
        velocity: shape ``(3,)``: alpha's ICEP ``(F_par, F_perp, F_x)`` from the same solves (units ``U0``).
    """

    a: FloatArray
    b: FloatArray
    x: FloatArray
    velocity: FloatArray

    def tensor(self, angle: float, sphere: int = -1) -> FloatArray:
        """Stresslet of one sphere for ``e = cos(angle) z + sin(angle) x`` (pair frame), shape ``(3, 3)``."""
        c, s = np.cos(angle), np.sin(angle)
        return c * c * self.a[sphere] + s * s * self.b[sphere] + 2.0 * s * c * self.x[sphere]


def icep_pair_frame_stresslets(
    axial: ElectricSolution,
    transverse: ElectricSolution,
    stokes_axisymmetric: TwoSphereStokes,
    stokes_transverse: TwoSphereStokes,
    stokes_quadrupolar: QuadrupolarStokes,
) -> PairFrameStresslets:
    """Full ICEP stresslets (not yet minus ``S0``) of both spheres in the pair frame.

    Args:
        axial, transverse: electric solutions (``m = 0``, ``m = 1``).
        stokes_axisymmetric, stokes_transverse, stokes_quadrupolar: Stokes systems for ``m = 0, 1, 2``.

    Returns:
        :class:`PairFrameStresslets`.
    """
    slip_par, slip_perp, slip_x = icep_slips(axial, transverse, stokes_axisymmetric, stokes_transverse)
    slip_m2 = icep_m2_slip(transverse, stokes_quadrupolar)
    ns = stokes_axisymmetric.n_spheres
    motion_par, mult_par = stokes_axisymmetric.solve_mobility_multipoles(slip=slip_par)
    motion_perp, mult_perp = stokes_axisymmetric.solve_mobility_multipoles(slip=slip_perp)
    motion_x, mult_x = stokes_transverse.solve_mobility_multipoles(slip=slip_x)
    mult_m2 = stokes_quadrupolar.solve(slip_m2)
    a = np.stack([stresslet_from_multipole(0, mult_par[i, 1, 1]) for i in range(ns)])
    b = np.stack(
        [
            stresslet_from_multipole(0, mult_perp[i, 1, 1]) + stresslet_from_multipole(2, mult_m2[i, 1, 0])
            for i in range(ns)
        ]
    )
    x = np.stack([stresslet_from_multipole(1, mult_x[i, 1, 1]) for i in range(ns)])
    velocity = np.array([motion_par.velocity[-1], motion_perp.velocity[-1], motion_x.velocity[-1]])
    return PairFrameStresslets(a, b, x, velocity)


@dataclass(frozen=True)
class PairStressletValues:
    """Exact two-sphere stress functions at one separation.

    Attributes:
        separation: centre distance ``r/a``.
        order: truncation degree ``L`` (electric and Stokes expansions).
        icep: ``(f1, f2, f3, f4)`` of the ICEP pair correction ``dS = S_alpha - S0`` (``pi eps a^3 E0^2``).
        dep: ``(g1, g2, g3, g4)`` of the DEP-induced stresslet of one sphere (``g1 = 0``), same units.
        dep_force: ``(F_par, F_perp, F_x)`` of the Maxwell force on alpha, units ``pi eps a^2 E0^2``.
        force_mobility: ``(s_par, s_perp)``: stresslet per unit force (units ``a``), module docstring.
        symmetry_error: max over mechanisms of ``|S_alpha - S_beta|`` (units ``pi eps a^3 E0^2``); zero
            exactly for equal spheres, so a measure of the truncation/rounding error.
    """

    separation: float
    order: int
    icep: tuple[float, float, float, float]
    dep: tuple[float, float, float, float]
    dep_force: tuple[float, float, float]
    force_mobility: tuple[float, float]
    symmetry_error: float

    def as_array(self) -> FloatArray:
        """Shape ``(10,)``: ICEP ``f1..f4``, DEP ``g2..g4``, DEP force ``F_par, F_perp, F_x``."""
        return np.array(self.icep + self.dep[1:] + self.dep_force)


def solve_pair_stresslets(
    separation: float | None, order: int | None = None, n_quad: int | None = None
) -> PairStressletValues:
    """ICEP pair correction, DEP-induced stresslet and DEP force at one separation (truncation ``L``).

    Args:
        separation: centre distance ``r/a`` (> 2), or ``None`` for an isolated sphere (all zero).
        order: truncation degree ``L`` (default :func:`truncation_order`; 4 for one sphere).
        n_quad: Gauss--Legendre points per sphere (default ``2 L + 40``).

    Returns:
        :class:`PairStressletValues`.
    """
    if order is None:
        order = 4 if separation is None else truncation_order(separation)
    axial = solve_electric(separation, 0, order)
    transverse = solve_electric(separation, 1, order)
    stokes0 = TwoSphereStokes(separation, 0, order, n_quad)
    stokes1 = TwoSphereStokes(separation, 1, order, n_quad)
    stokes2 = QuadrupolarStokes(separation, order, n_quad)
    frame = icep_pair_frame_stresslets(axial, transverse, stokes0, stokes1, stokes2)
    icep = list(decompose_pair_frame(frame.a[-1], frame.b[-1], frame.x[-1]))
    icep[0] -= ISOLATED_STRESSLET
    symmetry = float(
        max(
            np.abs(frame.a[0] - frame.a[-1]).max(),
            np.abs(frame.b[0] - frame.b[-1]).max(),
            np.abs(frame.x[0] - frame.x[-1]).max(),
        )
    )
    if separation is None:
        zero4 = (0.0, 0.0, 0.0, 0.0)
        return PairStressletValues(
            separation=float("inf"),
            order=order,
            icep=(icep[0], icep[1], icep[2], icep[3]),
            dep=zero4,
            dep_force=(0.0, 0.0, 0.0),
            force_mobility=(0.0, 0.0),
            symmetry_error=symmetry,
        )
    # DEP: Maxwell force on alpha (antisymmetric part; units eps E0^2 a^2 -> divide by pi).
    forces = maxwell_forces(axial, transverse, stokes0)
    f_par, f_perp, f_x = (0.5 * (forces[:, 1] - forces[:, 0]) / np.pi).tolist()
    _, mult_along = stokes0.solve_mobility_multipoles(forces=np.array([-1.0, 1.0]))
    _, mult_across = stokes1.solve_mobility_multipoles(forces=np.array([-1.0, 1.0]))
    # Unit force on alpha (and -1 on beta): S = s_par (zz - I/3) and s_perp (xz + zx), physical units.
    s_par = -2.0 * np.pi * mult_along[1, 1, 1]
    s_perp = 2.0 * np.pi * mult_across[1, 1, 1]
    symmetry = max(
        symmetry,
        abs(mult_along[0, 1, 1] - mult_along[1, 1, 1]) * 2.0 * np.pi * abs(f_par),
        abs(mult_across[0, 1, 1] - mult_across[1, 1, 1]) * 2.0 * np.pi * abs(f_x),
    )
    dep = (0.0, 2.0 * s_perp * f_x, s_par * f_perp, s_par * (f_par - f_perp) - 4.0 * s_perp * f_x)
    return PairStressletValues(
        separation=float(separation),
        order=order,
        icep=(icep[0], icep[1], icep[2], icep[3]),
        dep=(float(dep[0]), float(dep[1]), float(dep[2]), float(dep[3])),
        dep_force=(float(f_par), float(f_perp), float(f_x)),
        force_mobility=(float(s_par), float(s_perp)),
        symmetry_error=float(symmetry),
    )


# ------------------------------------------------------------------------------------------------
# Table format (tables/near_field_stress.txt) and the near-contact form, shared by the generator
# (scripts/generate_near_field_stress_table.py) and the loader (sim/dipolophoresis/near_field_stress.py)
# ------------------------------------------------------------------------------------------------
STRESS_FUNCTION_NAMES = (
    "icep_f1", "icep_f2", "icep_f3", "icep_f4",
    "dep_g2", "dep_g3", "dep_g4",
    "dep_F_par", "dep_F_perp", "dep_F_x",
)  # fmt: skip
"""The tabulated functions, order of :meth:`PairStressletValues.as_array` (``dep_g1 = 0`` is omitted)."""

STRESS_COLUMNS = (
    "r",
    *STRESS_FUNCTION_NAMES,
    "order",
    "error_icep",
    "error_dep",
    "error_force",
    "symmetry_error",
)

SHIFTED_POWER_FORM = 2
"""Near-contact form ``F = C + A xi^p`` (parameters ``(C, A, p)``), ``xi = r - 2``."""

NEAR_CONTACT_RATIO = 2.0**0.25
"""Target ratio ``q`` of the gaps of the three nodes used by :func:`fit_shifted_power` (nodes 0, j, 2j)."""


@dataclass(frozen=True)
class StressTable:
    """The tabulated exact stress functions.

    Attributes:
        r: shape ``(n,)``, centre distances (``ln(r - 2)`` uniform: the nodes of ``near_field.txt``).
        values: shape ``(10, n)``, rows in the order of :data:`STRESS_FUNCTION_NAMES` (stresslets in
            ``pi eps a^3 E0^2``, forces in ``pi eps a^2 E0^2``).
        order: shape ``(n,)``, truncation degree.
        error_icep, error_dep, error_force: shape ``(n,)``, max ``|value(c = 10) - value(c = 8)|`` over the
            ICEP ``f``, the DEP ``g`` and the force functions (a conservative truncation-error bound).
        symmetry_error: shape ``(n,)``, ``max |S_alpha - S_beta|`` (zero exactly; rounding check).
        header: the comment lines (provenance).
    """

    r: FloatArray
    values: FloatArray
    order: FloatArray
    error_icep: FloatArray
    error_dep: FloatArray
    error_force: FloatArray
    symmetry_error: FloatArray
    header: tuple[str, ...]


def read_stress_table_text(text: str) -> StressTable:
    """Parse the text of ``near_field_stress.txt``.

    Raises:
        ValueError: if the column line differs from :data:`STRESS_COLUMNS`.
    """
    header, data = split_table_text(text, STRESS_COLUMNS, "stress table")
    n_functions = len(STRESS_FUNCTION_NAMES)
    return StressTable(
        r=data[:, 0].copy(),
        values=np.ascontiguousarray(data[:, 1 : 1 + n_functions].T),
        order=data[:, 1 + n_functions].copy(),
        error_icep=data[:, 2 + n_functions].copy(),
        error_dep=data[:, 3 + n_functions].copy(),
        error_force=data[:, 4 + n_functions].copy(),
        symmetry_error=data[:, 5 + n_functions].copy(),
        header=header,
    )


def near_contact_nodes(r: FloatArray) -> NDArray[np.int64]:
    """Indices ``(0, j, 2j)`` of the first nodes; gap ratio ``~NEAR_CONTACT_RATIO`` (uniform in ``s``)."""
    spacing = float(np.log(r[1] - 2.0) - np.log(r[0] - 2.0))
    j = max(1, round(float(np.log(NEAR_CONTACT_RATIO)) / spacing))
    return np.array([0, j, 2 * j])


def fit_shifted_power(gaps: ArrayLike, values: ArrayLike) -> tuple[float, float, float]:
    """Fit ``F = C + A xi^p`` exactly through three geometrically spaced gaps.

    With ``D1 = F1 - F0``, ``D2 = F2 - F1`` and ``q = xi_1/xi_0 = xi_2/xi_1``: ``q^p = D2/D1``,
    ``A = D1/(xi_0^p (q^p - 1))``, ``C = F0 - A xi_0^p``. ``p > 0``: a finite contact value ``C`` approached
    like ``xi^p``; ``p < 0``: a weak divergence.

    Args:
        gaps: shape ``(3,)``, increasing, geometric.
        values: shape ``(3,)``.

    Returns:
        ``(C, A, p)``.

    Raises:
        ValueError: if the gaps are not geometric or the values are not strictly monotone.
    """
    xi = np.asarray(gaps, dtype=float)
    f = np.asarray(values, dtype=float)
    q = xi[1] / xi[0]
    if not (q > 1.0 and abs(xi[2] / xi[1] - q) < 1e-9 * q):
        raise ValueError(f"gaps must be geometric and increasing, got {xi}")
    d1, d2 = f[1] - f[0], f[2] - f[1]
    if not d2 / d1 > 0.0:
        raise ValueError(f"shifted power form needs strictly monotone values, got {f}")
    p = float(np.log(d2 / d1) / np.log(q))
    amplitude = d1 / (xi[0] ** p * (q**p - 1.0))
    return float(f[0] - amplitude * xi[0] ** p), float(amplitude), p


def shifted_power_value(gap: float, parameters: ArrayLike) -> float:
    """``C + A xi^p`` (reference implementation for tests and the table header)."""
    c, a, p = (float(v) for v in np.asarray(parameters, dtype=float))
    return c + a * gap**p
