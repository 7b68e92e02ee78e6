"""Periodic far-field dipolophoresis on the sheared Lees–Edwards lattice by Ewald summation.

What is summed (lengths in ``a``, ``docs/model.md#dipolophoresis``, kernels in
:mod:`sim.dipolophoresis.far_field`):

* velocities, units ``U0 = eps a E0^2/eta``:
  ``U_alpha = sum'_{beta, n} [a_S S + a_T T](x_alpha - x_beta + n) : Q``,
  ``a_S = -(9/8) w_icep``, ``a_T = -(11/24) w_icep + (1/12) w_dep``;
* the O(r^-3) pair correction to the ICEP stresslet, ``sum_alpha dS_alpha / V`` (units ``eps E0^2``);
* the DEP force virial ``-(1/V) sum_pairs sym(x F_alpha)`` (units ``eps E0^2``);

over all particles and lattice images ``n = n1 a1 + n2 a2 + n3 a3`` with ``a1 = (L, 0, 0)``,
``a2 = (delta, L, 0)``, ``a3 = (0, 0, L)`` (``delta`` the Lees–Edwards offset), the prime excluding
``beta = alpha, n = 0``. All three lattice sums are conditionally convergent (the Stokes dipole ``S``
decays as ``r^-2``, the stress kernels as ``r^-3``); here they are defined, as in the simulation, by
dropping the ``k = 0`` Fourier term (zero mean disturbance flow and zero mean disturbance field: the
imposed flow and the mean field ``E0 e`` are the bulk values). ``Q = ee - I/3`` replaces ``ee`` everywhere:
the ``I/3`` part contributes nothing physical, but the real- and Fourier-space parts of ``T`` are not
separately traceless. No minimum-image or truncated sum of a slowly decaying kernel is used anywhere.

Derivative form. With ``Phi = 1/r`` (harmonic) and ``rho = r`` (biharmonic), the Oseen tensor is
``G_ij = 2 d_ij Phi - d_i d_j rho`` and

    S:Q = -2 Q.grad Phi + Q_jk d_i d_j d_k rho,      T:Q = 2 Q_jk d_i d_j d_k Phi,
    dS/pi = 3 (QH + HQ) - 3 H + 3 (Q:H) I + tr(H) I - (15/2) Q_kl d_i d_j d_k d_l rho,   H = grad grad Phi,
    F/pi = Q_jk d_i d_j d_k Phi   (DEP force on alpha),

where the ``dS`` form is the physical construction (electric part ``9 ST(e d + d e)`` from the lattice
sum of the dipole fields, hydrodynamic part ``(20/3)`` times the rate of strain of the lattice ICEP
stresslet flow); in free space it equals the formula of ``docs/model.md#dipolophoresis`` (``tr H = 0`` there).
In the
periodic sum ``tr H`` is the constant ``4 pi/V`` per image set (Lorentz local field of the mean-field
convention), and keeping it makes every Ewald part of ``dS`` exactly traceless.

Splitting (Hasimoto 1959; Beenakker 1986). One Fourier screening factor serves all kernels,
``g(k) = (1 + k^2/(4 xi^2)) exp(-k^2/(4 xi^2))``, applied to ``Phi^ = 4 pi/k^2`` and
``rho^ = -8 pi/k^4``. In real space

    Phi_R = erfc(xi r)/r - (xi/sqrt(pi)) exp(-xi^2 r^2),
    rho_R = r erfc(xi r) - exp(-xi^2 r^2)/(xi sqrt(pi)),

both Gaussian-short-ranged, with ``lap rho_R = 2 Phi_R`` (so the real and Fourier parts of ``G`` are
each divergence-free). The Fourier part is ``(1/V) sum_{k != 0} f^(k) g(k) exp(i k.x)`` over the
reciprocal lattice ``k = (2 pi/L) (m1, m2 - m1 delta/L, m3)`` with one shared structure factor
``rho(k) = sum_beta exp(-i k.x_beta)`` (all spheres carry the same ``Q``). The velocity multiplier is
``-8 pi i (g/k^2) [a_S (Q.k - k (k.Q.k)/k^2) + a_T k (k.Q.k)]``. The self terms (Fourier part at
``x = 0``) vanish for all three quantities (odd kernels; and for ``dS`` and the virial by direct
evaluation). The real-space sum takes every image within ``r_c``: with ``r_c <= L/2`` that is one
minimum image per pair; in small boxes the plan may take ``r_c`` up to ``1.5 L`` (several images per pair,
the Lees–Edwards images shifted by ``delta``; and for ``r_c > L`` a sphere's own images, which add stress
but no velocity), so that a smaller ``xi`` needs far fewer wave vectors (issue 22: N = 64 at phi = 0.45,
``L = 8.4``: ``xi`` 1.16 -> 0.61, ~6300 -> ~800 wave vectors).

Error estimate (rms per particle, random positions; Kolafa & Perram 1992 style). With density
``n = N/V`` and orientation-averaged squared kernels,

    dU_R^2 = n int_{r_c}^inf <|K_R(x)|^2> 4 pi r^2 dr,
    dU_F^2 = n/(2 pi)^3 int_{k_c}^inf <|K^_F(k)|^2> 4 pi k^2 dk,

``<|K_R|^2> = r^2 [(2/9) A^2 + (8/45) r^2 A B + (4/45) r^4 B^2]`` (``K_R = A Q.x + B (x.Q.x) x``) and
``<|K^_F|^2> = 64 pi^2 g^2 [(2/15) a_S^2/k^2 + (4/45) a_T^2 k^2]`` (both independent of the shear: the
Fourier sum always covers the whole ball ``|k| <= k_c``). These match measured truncation errors of
hard-sphere suspensions within 10-20% (tests/test_ewald.py). The velocity scale is
``U_ref = f U_ideal`` with ``U_ideal^2 = n int_2^inf <|U_pair|^2> 4 pi r^2 dr = 4 pi n (0.4 a_S^2 -
0.4 a_S a_T + 0.3 a_T^2)``, the rms free-space velocity of an ideal gas of spheres outside contact,
and ``f = 0.15`` (ICEP, DIP) or ``0.5`` (DEP): the measured rms velocity of random hard-sphere
packings (phi = 0.02..0.55, N = 30 and 200) was 0.19..5.8 ``U_ideal`` for ICEP and DIP (dense
suspensions screen the O(r^-2) sums; one near-contact pair raises the rms) and 1.2..19 ``U_ideal`` for
DEP. :func:`ewald_plan` requires ``sqrt(dU_R^2 + dU_F^2 [+ dU_mesh^2]) <= accuracy * U_ref`` (equal
shares) for the mechanism(s) it is made for and, among the admissible splitting parameters, takes
the one of least modelled cost; the achieved error is then ~0.05..0.8 ``accuracy`` relative to the rms
velocity (tests/test_ewald.py, test_spme.py, ``benchmarks/dip_far_field.py``). The stress sums are not
separately controlled: with the velocity plan their relative errors were 1e-7..3e-5 (benchmark).

Cost. Real space: a cell list in the sheared fractional coordinates, branch-free candidate and
compaction loops, and a vectorised pair block (``erfc`` from a Chebyshev series of ``erfcx`` so that
the only scalar transcendental is one ``exp`` per pair); about 4 ns per candidate and 17 ns per pair
within ``r_c``. Fourier space: explicit structure factors from per-axis phase tables (built by
recurrence), about 1.3 ns per (particle, wave vector) plus ~30 ns per wave vector for its
position-independent factors, computed row by row in a vectorised loop (one exponential per row); or SPME
(:mod:`sim.dipolophoresis.spme`) for large ``N``. Timings and the
crossover are in the :mod:`sim.dipolophoresis.spme` docstring.

References:
    Hasimoto, H. (1959) J. Fluid Mech. 5, 317. Beenakker, C. W. J. (1986) J. Chem. Phys. 85, 1581.
    Kolafa, J. & Perram, J. W. (1992) Mol. Sim. 9, 351 (cut-off errors of Ewald sums).
    Essmann, U. et al. (1995) J. Chem. Phys. 103, 8577 (smooth particle-mesh Ewald; :mod:`spme`).
    Saintillan, D. (2008) Phys. Fluids 20, 067104; Park, J. S. & Saintillan, D. (2010) J. Fluid Mech.
    662, 66 (kernels and their Ewald sums). Mirfendereski & Park (2024) J. Fluid Mech. §2.1.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy import optimize, special

from sim.dipolophoresis import spme
from sim.dipolophoresis.far_field import DEP_T_COEFFICIENT, ICEP_S_COEFFICIENT, ICEP_T_COEFFICIENT
from sim.numba_cache import REPRODUCIBLE_FASTMATH

__all__ = [
    "METHOD_EWALD",
    "METHOD_SPME",
    "EwaldPlan",
    "dip_far_field",
    "dip_far_field_with_pairs",
    "collects_near_pairs",
    "ewald_plan",
    "estimated_errors",
]

METHOD_EWALD = 0
"""``EwaldPlan.method`` code: plain Ewald sums (structure factor per wave vector)."""
METHOD_SPME = 1
"""``EwaldPlan.method`` code: smooth particle-mesh Ewald for the Fourier part."""

_SQRT_PI = math.sqrt(math.pi)
_TWO_PI = 2.0 * math.pi


class EwaldPlan(NamedTuple):
    """Parameters of the periodic sums; made once per run by :func:`ewald_plan`, valid at every strain.

    Attributes:
        splitting: Ewald splitting parameter ``xi`` (units ``1/a``).
        real_cutoff: Real-space cut-off ``r_c`` (units ``a``), ``<= 1.5 L`` (every image within it is summed).
        k_cutoff: Fourier cut-off ``k_c`` (units ``1/a``): wave vectors with ``|k| <= k_c`` are summed.
        method: :data:`METHOD_EWALD` or :data:`METHOD_SPME`.
        mesh: SPME mesh ``(K1, K2, K3)`` along the sheared-lattice axes (unused by plain Ewald).
        order: B-spline order ``p`` of SPME (even; unused by plain Ewald).
        box_length: Box side ``L`` the plan was made for (units ``a``).
    """

    splitting: float
    real_cutoff: float
    k_cutoff: float
    method: int
    mesh: tuple[int, int, int]
    order: int
    box_length: float


# --------------------------------------------------------------------------------------------------
# Real-space kernels
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _radial_functions(r: float, xi: float) -> tuple[float, float, float, float, float, float]:
    """Radial derivative functions of the real-space parts ``Phi_R`` and ``rho_R``.

    ``f_1 = f'/r``, ``f_{n+1} = f_n'/r``, so that ``d_i f = x_i f_1``, ``d_i d_j f = d_ij f_1 + x_i x_j f_2``,
    ``d_i d_j d_k f = (d_ij x_k + d_ik x_j + d_jk x_i) f_2 + x_i x_j x_k f_3`` and the fourth derivative
    has ``(dd + dd + dd) f_2 + (six d x x terms) f_3 + xxxx f_4``. With ``E = exp(-xi^2 r^2)/sqrt(pi)``:

        Phi_1 = -erfc/r^3 + E (2 xi^3 - 2 xi/r^2)
        Phi_2 = 3 erfc/r^5 + E (-4 xi^5 + 4 xi^3/r^2 + 6 xi/r^4)
        Phi_3 = -15 erfc/r^7 + E (8 xi^7 - 8 xi^5/r^2 - 20 xi^3/r^4 - 30 xi/r^6)
        rho_2 = -erfc/r^3 - 2 xi E/r^2
        rho_3 = 3 erfc/r^5 + E (4 xi^3/r^2 + 6 xi/r^4)
        rho_4 = -15 erfc/r^7 - E (8 xi^5/r^2 + 20 xi^3/r^4 + 30 xi/r^6)

    (``erfc = erfc(xi r)``; derived symbolically and checked against finite differences in the tests).

    Returns:
        ``(Phi_1, Phi_2, Phi_3, rho_2, rho_3, rho_4)`` at distance ``r`` (units ``a``).
    """
    xr = xi * r
    ec = math.erfc(xr)
    ex = math.exp(-xr * xr) / _SQRT_PI
    ir2 = 1.0 / (r * r)
    ir = math.sqrt(ir2)
    ir3 = ir2 * ir
    ir4 = ir2 * ir2
    ir5 = ir4 * ir
    ir6 = ir4 * ir2
    ir7 = ir6 * ir
    xi2 = xi * xi
    xi3 = xi2 * xi
    xi5 = xi3 * xi2
    xi7 = xi5 * xi2
    phi1 = -ec * ir3 + ex * (2.0 * xi3 - 2.0 * xi * ir2)
    phi2 = 3.0 * ec * ir5 + ex * (-4.0 * xi5 + 4.0 * xi3 * ir2 + 6.0 * xi * ir4)
    phi3 = -15.0 * ec * ir7 + ex * (8.0 * xi7 - 8.0 * xi5 * ir2 - 20.0 * xi3 * ir4 - 30.0 * xi * ir6)
    rho2 = -ec * ir3 - 2.0 * xi * ex * ir2
    rho3 = 3.0 * ec * ir5 + ex * (4.0 * xi3 * ir2 + 6.0 * xi * ir4)
    rho4 = -15.0 * ec * ir7 - ex * (8.0 * xi5 * ir2 + 20.0 * xi3 * ir4 + 30.0 * xi * ir6)
    return phi1, phi2, phi3, rho2, rho3, rho4


def _erfcx_chebyshev(degree: int) -> np.ndarray:
    """Chebyshev coefficients of ``erfcx(x) = exp(x^2) erfc(x)`` in ``u`` on ``0 <= x <= _ERFCX_X_MAX``.

    ``t = 2/(2 + x)`` maps ``[0, x_max]`` to ``[t_lo, 1]`` and ``u = (2t - 1 - t_lo)/(1 - t_lo)`` to
    ``[-1, 1]``; ``erfcx`` is analytic in ``t`` there (singular only at ``t = 0``), so the series
    converges geometrically: degree 21 gives a relative error below ``2e-14`` (checked in the tests).
    """
    t_lo = 2.0 / (2.0 + _ERFCX_X_MAX)

    def f(u: np.ndarray) -> np.ndarray:
        t = 0.5 * (u * (1.0 - t_lo) + 1.0 + t_lo)
        return np.asarray(special.erfcx(2.0 / t - 2.0))

    return np.ascontiguousarray(np.polynomial.chebyshev.chebinterpolate(f, degree))  # type: ignore[type-var]


_ERFCX_X_MAX = 10.0
_ERFCX_T_LOW = 2.0 / (2.0 + _ERFCX_X_MAX)
_ERFCX_DEGREE = 21
_ERFCX_COEFFICIENTS = _erfcx_chebyshev(_ERFCX_DEGREE)


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy")
def _real_space_block(
    count: int,
    bx: np.ndarray,
    by: np.ndarray,
    bz: np.ndarray,
    br2: np.ndarray,
    bgauss: np.ndarray,
    xi: float,
    q: tuple[float, float, float, float, float, float],
    a_s: float,
    a_t: float,
    ux: np.ndarray,
    uy: np.ndarray,
    uz: np.ndarray,
    erfc_buf: np.ndarray,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float]:
    """Real-space terms of ``count`` pairs (separations ``x = x_alpha - x_beta`` within the cut-off).

    Branch-free (``error_model="numpy"`` drops numba's division and ``sqrt`` checks; the fast-math
    flags are only the reproducible ones of :data:`sim.numba_cache.REPRODUCIBLE_FASTMATH`);
    ``erfc(xi r) = exp(-xi^2 r^2) erfcx(xi r)`` with ``erfcx`` from its Chebyshev series
    (:func:`_erfcx_chebyshev`) and ``bgauss = exp(-xi^2 r^2)`` computed by the caller. The series is
    evaluated in a loop of its own into ``erfc_buf``: LLVM vectorises that loop (one output array),
    but not the pair loop with its three velocity outputs and twelve sums (it cannot rule out overlap
    of that many arrays; measured: no vector instructions). The split halves the real-space time at
    N = 64 and saves ~20% at N = 500, bit for bit the same numbers. Per pair (module docstring for units):
    the velocity of alpha ``A Q.x + B (x.Q.x) x`` into ``ux, uy, uz`` (beta gets its negative);
    the sums of ``2 D_R`` (the stresslet corrections of both spheres) and of ``K_R`` (the pair virial)
    are returned as ``xx, xy, xz, yy, yz, zz`` of each, with

        A = -4 a_S xi^3 exp(-xi^2 r^2)/sqrt(pi) + 4 a_T Phi_2,     B = a_S rho_3 + 2 a_T Phi_3,
        D_R = Q (6 Phi_1 - 15 rho_2) + (Qx x + x Qx)(3 Phi_2 - 15 rho_3) - x x (3 Phi_2 + 7.5 q rho_4)
              + I (3 q Phi_2 + r^2 Phi_2 - 7.5 q rho_3),
        K_R = (x Qx + Qx x) Phi_2 + x x q Phi_3,

    ``q = x.Q.x``, the radial functions as in :func:`_radial_functions`, and the tuple ``q`` holding
    ``Q_xx, Q_xy, Q_xz, Q_yy, Q_yz, Q_zz``.
    """
    q00, q01, q02, q11, q12, q22 = q
    xi2 = xi * xi
    xi3 = xi2 * xi
    xi5 = xi3 * xi2
    xi7 = xi5 * xi2
    inv_sqrt_pi = 1.0 / _SQRT_PI
    t_scale = 2.0 / (1.0 - _ERFCX_T_LOW)
    t_shift = (1.0 + _ERFCX_T_LOW) / (1.0 - _ERFCX_T_LOW)
    for i in range(count):  # erfc(xi r): one output, so that LLVM vectorises it
        r2 = br2[i]
        ir2 = 1.0 / r2
        ir = math.sqrt(ir2)
        x = xi * r2 * ir
        u = max(t_scale * 2.0 / (2.0 + x) - t_shift, -1.0)
        b1 = 0.0
        b2 = 0.0
        for k in range(_ERFCX_DEGREE, 0, -1):
            b1, b2 = 2.0 * u * b1 - b2 + _ERFCX_COEFFICIENTS[k], b1
        erfc_buf[i] = bgauss[i] * (u * b1 - b2 + _ERFCX_COEFFICIENTS[0])
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    v0 = v1 = v2 = v3 = v4 = v5 = 0.0
    for i in range(count):
        dx = bx[i]
        dy = by[i]
        dz = bz[i]
        r2 = br2[i]
        ir2 = 1.0 / r2
        ir = math.sqrt(ir2)
        gauss = bgauss[i]
        ec = erfc_buf[i]
        ex = gauss * inv_sqrt_pi
        ir3 = ir2 * ir
        ir4 = ir2 * ir2
        ir5 = ir4 * ir
        ir6 = ir4 * ir2
        ir7 = ir6 * ir
        phi1 = -ec * ir3 + ex * (2.0 * xi3 - 2.0 * xi * ir2)
        phi2 = 3.0 * ec * ir5 + ex * (-4.0 * xi5 + 4.0 * xi3 * ir2 + 6.0 * xi * ir4)
        phi3 = -15.0 * ec * ir7 + ex * (8.0 * xi7 - 8.0 * xi5 * ir2 - 20.0 * xi3 * ir4 - 30.0 * xi * ir6)
        rho2 = -ec * ir3 - 2.0 * xi * ex * ir2
        rho3 = 3.0 * ec * ir5 + ex * (4.0 * xi3 * ir2 + 6.0 * xi * ir4)
        rho4 = -15.0 * ec * ir7 - ex * (8.0 * xi5 * ir2 + 20.0 * xi3 * ir4 + 30.0 * xi * ir6)
        qx0 = q00 * dx + q01 * dy + q02 * dz
        qx1 = q01 * dx + q11 * dy + q12 * dz
        qx2 = q02 * dx + q12 * dy + q22 * dz
        qq = dx * qx0 + dy * qx1 + dz * qx2
        a_coef = a_s * 2.0 * (rho2 - phi1) + 4.0 * a_t * phi2
        b_coef = (a_s * rho3 + 2.0 * a_t * phi3) * qq
        ux[i] = a_coef * qx0 + b_coef * dx
        uy[i] = a_coef * qx1 + b_coef * dy
        uz[i] = a_coef * qx2 + b_coef * dz
        c_q = 2.0 * (6.0 * phi1 - 15.0 * rho2)
        c_sym = 2.0 * (3.0 * phi2 - 15.0 * rho3)
        c_xx = -2.0 * (3.0 * phi2 + 7.5 * qq * rho4)
        c_i = 2.0 * (3.0 * qq * phi2 + r2 * phi2 - 7.5 * qq * rho3)
        v_xx = qq * phi3
        s_xx = 2.0 * qx0 * dx
        s_xy = qx0 * dy + dx * qx1
        s_xz = qx0 * dz + dx * qx2
        s_yy = 2.0 * qx1 * dy
        s_yz = qx1 * dz + dy * qx2
        s_zz = 2.0 * qx2 * dz
        xx = dx * dx
        xy = dx * dy
        xz = dx * dz
        yy = dy * dy
        yz = dy * dz
        zz = dz * dz
        s0 += c_q * q00 + c_sym * s_xx + c_xx * xx + c_i
        s1 += c_q * q01 + c_sym * s_xy + c_xx * xy
        s2 += c_q * q02 + c_sym * s_xz + c_xx * xz
        s3 += c_q * q11 + c_sym * s_yy + c_xx * yy + c_i
        s4 += c_q * q12 + c_sym * s_yz + c_xx * yz
        s5 += c_q * q22 + c_sym * s_zz + c_xx * zz + c_i
        v0 += s_xx * phi2 + xx * v_xx
        v1 += s_xy * phi2 + xy * v_xx
        v2 += s_xz * phi2 + xz * v_xx
        v3 += s_yy * phi2 + yy * v_xx
        v4 += s_yz * phi2 + yz * v_xx
        v5 += s_zz * phi2 + zz * v_xx
    return s0, s1, s2, s3, s4, s5, v0, v1, v2, v3, v4, v5


_MAX_CELLS_PER_AXIS = 8
"""Largest number of cells per axis tried by :func:`_image_cells` (``r_c > L/2``)."""
_COST_CELL_SLICE = 12e-9
"""Modelled cost (s) of one contiguous slice of neighbouring cells scanned for one particle."""


@njit(cache=True)
def _image_cells(
    box_length: float,
    offset: float,
    cutoff: float,
    n_particles: int,
    cost_candidate: float,
    cost_slice: float,
) -> tuple[int, int, int, int, int, int]:
    """Cells ``(n1, n2, n3)`` and neighbour spans ``(s1, s2, s3)`` of the real-space cell list.

    ``r_c <= L/2`` (one image per pair): ``n_d = floor(h_d/r_c)`` cells with span 1 where that is at
    least 3, else one cell and span 0 (the image is then chosen by rounding). ``r_c > L/2`` (several
    images per pair): ``n_d`` cells of width ``h_d/n_d`` and the span ``s_d = floor(r_c n_d/h_d) + 1``
    (every partner image within ``r_c`` lies within ``s_d`` cells: its fractional coordinate differs by
    at most ``r_c/h_d``), with ``n_d <= 8`` chosen per axis to minimise the modelled cost: candidates
    ``(N/2) prod (2 s_d + 1)/n_d`` and contiguous slices
    ``(2 s_1 + 1)(2 s_2 + 1) (ceil((2 s_3 + 1)/n_3) + 1)``
    per particle. ``h_1 = L/sqrt(1 + (delta/L)^2)``, ``h_2 = h_3 = L`` are the lattice-plane spacings.
    """
    shear = offset / box_length
    spacing1 = box_length / math.sqrt(1.0 + shear * shear)
    if cutoff <= 0.5 * box_length:
        out = np.empty(6, dtype=np.int64)
        for d in range(3):
            h = spacing1 if d == 0 else box_length
            cells = int(math.floor(h / cutoff))
            if cells >= 3:
                out[d] = cells
                out[3 + d] = 1
            else:
                out[d] = 1
                out[3 + d] = 0
        return out[0], out[1], out[2], out[3], out[4], out[5]
    best = math.inf
    b = (1, 1, 1, 1, 1, 1)
    for n1 in range(1, _MAX_CELLS_PER_AXIS + 1):
        s1 = int(math.floor(cutoff * n1 / spacing1)) + 1
        f1 = (2.0 * s1 + 1.0) / n1
        for n2 in range(1, _MAX_CELLS_PER_AXIS + 1):
            s2 = int(math.floor(cutoff * n2 / box_length)) + 1
            f2 = (2.0 * s2 + 1.0) / n2
            for n3 in range(1, _MAX_CELLS_PER_AXIS + 1):
                s3 = int(math.floor(cutoff * n3 / box_length)) + 1
                f3 = (2.0 * s3 + 1.0) / n3
                slices = (2.0 * s1 + 1.0) * (2.0 * s2 + 1.0) * (math.ceil((2.0 * s3 + 1.0) / n3) + 1.0)
                cost = cost_candidate * 0.5 * n_particles * f1 * f2 * f3 + cost_slice * slices
                if cost < best:
                    best = cost
                    b = (n1, n2, n3, s1, s2, s3)
    return b


@njit(cache=True, error_model="numpy")
def _self_image_sums(
    box_length: float,
    offset: float,
    xi: float,
    cutoff: float,
    q: np.ndarray,
    a_s: float,
    a_t: float,
    n_particles: int,
    sums: np.ndarray,
) -> None:
    """Stress sums of every sphere with its own images ``n != 0`` within ``cutoff`` (none if ``r_c <= L``).

    The lattice vectors ``(n1 L + n2 delta, n2 L, n3 L)`` with ``|n| < r_c`` are taken once per pair
    ``+-n`` (``n`` in a half space), as the pair sums take each pair once; their velocities cancel
    (odd kernel). All spheres see the same images: ``N`` times one sum into ``sums`` (2, 6).
    """
    rc2 = cutoff * cutoff
    k2 = int(math.floor(cutoff / box_length))
    capacity = (2 * k2 + 1) * (2 * k2 + 1) * (2 * k2 + 3)
    bx = np.empty(capacity)
    by = np.empty(capacity)
    bz = np.empty(capacity)
    br2 = np.empty(capacity)
    bgauss = np.empty(capacity)
    count = 0
    for n2 in range(0, k2 + 1):
        for n3 in range(-k2, k2 + 1):
            if n2 == 0 and n3 < 0:
                continue
            x_lo = -cutoff - n2 * offset
            x_hi = cutoff - n2 * offset
            for n1 in range(int(math.ceil(x_lo / box_length)), int(math.floor(x_hi / box_length)) + 1):
                if n2 == 0 and n3 == 0 and n1 <= 0:
                    continue
                dx = n1 * box_length + n2 * offset
                dy = n2 * box_length
                dz = n3 * box_length
                r2 = dx * dx + dy * dy + dz * dz
                if r2 >= rc2:
                    continue
                bx[count] = dx
                by[count] = dy
                bz[count] = dz
                br2[count] = r2
                bgauss[count] = math.exp(-xi * xi * r2)
                count += 1
    if count == 0:
        return
    qt = (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2])
    t = _real_space_block(
        count,
        bx,
        by,
        bz,
        br2,
        bgauss,
        xi,
        qt,
        a_s,
        a_t,
        np.empty(count),
        np.empty(count),
        np.empty(count),
        np.empty(count),
    )
    for j in range(6):
        sums[0, j] += n_particles * t[j]
        sums[1, j] += n_particles * t[6 + j]


@njit(cache=True, error_model="numpy")
def _real_space_sums(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    xi: float,
    cutoff: float,
    q: np.ndarray,
    a_s: float,
    a_t: float,
    velocity: np.ndarray,
    sums: np.ndarray,
    near_cutoff: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Real-space sums over all pair images within ``cutoff`` (any ``r_c``; several images if ``> L/2``).

    Cell list in the sheared fractional coordinates ``s`` (:func:`_fractional_coordinates`; the lattice
    is the integer lattice there, so cells wrap independently per axis and the image shift of a
    neighbouring cell is a known integer: a cell ``c + d`` outside ``0..n-1`` is cell ``(c + d) mod n``
    shifted by ``floor((c + d)/n)`` lattice periods, so with spans larger than the cell count each
    partner is visited once per image in reach, which is how the Lees–Edwards offset enters: an image
    one period up in ``y`` is shifted by ``delta`` in ``x``). Cartesian separation from ``ds``:
    ``(L ds1 + delta ds2, L ds2, L ds3)``. Cells and spans from :func:`_image_cells`; with ``r_c <= L/2``
    an axis of fewer than 3 cells has a single cell and the image is chosen by rounding
    (Cartesian, ``y`` before ``x``, as in :func:`sim.geometry.box.minimum_image`, exact for
    ``|r| < L/2``). Particles are sorted by cell, so each neighbouring cell (and each run of
    neighbours along axis 3 with the same image shift) is a contiguous slice; each
    pair image is taken once (sorted index of beta above that of alpha, every image; a sphere's own
    images, present only for ``r_c > L``, by :func:`_self_image_sums`). Candidate distances and the
    compaction of the pairs within ``r_c`` are branch-free loops, the pair terms are evaluated by
    :func:`_real_space_block`. Accumulates into ``velocity`` (N, 3) and ``sums`` (2, 6).

    With ``0 < near_cutoff <= min(cutoff, L/2)`` the pairs closer than ``near_cutoff`` are also returned,
    as the near-field blend needs them (:func:`sim.dipolophoresis.near_field_blend.add_near_field_corrections`
    takes them instead of building a pair list of its own: at N = 300 both were an all-pairs scan of
    the same box, issue 22): ``pairs`` (K, 2) int64 particle indices and ``separations`` (K, 3) the
    separation ``x_j - x_i`` of ``pairs[k] = (i, j)`` (the one image closer than ``L/2``), in the order
    the sums visit them (cell order, not sorted). Otherwise two empty arrays.
    """
    n = positions.shape[0]
    rc2 = cutoff * cutoff
    xi2 = xi * xi
    s = _fractional_coordinates(positions, box_length, offset)
    n1, n2, n3, span1, span2, span3 = _image_cells(
        box_length, offset, cutoff, n, _COST_CANDIDATE, _COST_CELL_SLICE
    )
    round1 = 1.0 if span1 == 0 else 0.0
    round2 = 1.0 if span2 == 0 else 0.0
    round3 = 1.0 if span3 == 0 else 0.0
    # Each partner appears at most this many times among the neighbouring cells of one particle.
    repeats = (
        ((2 * span1 + 1 + n1 - 1) // n1) * ((2 * span2 + 1 + n2 - 1) // n2) * ((2 * span3 + 1 + n3 - 1) // n3)
    )
    capacity = n * repeats
    n_cells = n1 * n2 * n3
    cell = np.empty(n, dtype=np.int64)
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    for p in range(n):
        c1 = min(int(s[p, 0] * n1), n1 - 1)
        c2 = min(int(s[p, 1] * n2), n2 - 1)
        c3 = min(int(s[p, 2] * n3), n3 - 1)
        cell[p] = (c1 * n2 + c2) * n3 + c3
        cell_start[cell[p] + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        order[fill[cell[p]]] = p
        fill[cell[p]] += 1
    t1 = np.empty(n)
    t2 = np.empty(n)
    t3 = np.empty(n)
    for i in range(n):
        t1[i] = s[order[i], 0]
        t2[i] = s[order[i], 1]
        t3[i] = s[order[i], 2]
    qt = (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2])
    cx = np.empty(n)
    cy = np.empty(n)
    cz = np.empty(n)
    cr2 = np.empty(n)
    bx = np.empty(capacity)
    by = np.empty(capacity)
    bz = np.empty(capacity)
    br2 = np.empty(capacity)
    bgauss = np.empty(capacity)
    erfc_buf = np.empty(capacity)
    partner = np.empty(capacity, dtype=np.int64)
    picked = np.empty(capacity, dtype=np.int64)
    ux = np.empty(capacity)
    uy = np.empty(capacity)
    uz = np.empty(capacity)
    vsorted = np.zeros((n, 3))
    want_near = near_cutoff > 0.0
    near2 = near_cutoff * near_cutoff
    near_count = 0
    near_pairs = np.empty((16 * n if want_near else 0, 2), dtype=np.int64)
    near_separations = np.empty((near_pairs.shape[0], 3))
    for i in range(n):
        c = cell[order[i]]
        c3 = c % n3
        c2 = (c // n3) % n2
        c1 = c // (n2 * n3)
        sa1 = t1[i]
        sa2 = t2[i]
        sa3 = t3[i]
        count = 0
        start = 0
        for d1 in range(-span1, span1 + 1):
            e1 = c1 + d1
            k1 = e1 // n1  # image shift (lattice periods) of the neighbouring cell
            e1 -= k1 * n1
            w1 = float(k1)
            for d2 in range(-span2, span2 + 1):
                e2 = c2 + d2
                k2 = e2 // n2
                e2 -= k2 * n2
                w2 = float(k2)
                row = (e1 * n2 + e2) * n3
                # Along axis 3 the neighbouring cells c3 - span3 .. c3 + span3 are one contiguous slice
                # per image shift k3.
                for k3 in range((c3 - span3) // n3, (c3 + span3) // n3 + 1):
                    w3 = float(k3)
                    first = max(c3 - span3 - k3 * n3, 0)
                    last = min(c3 + span3 - k3 * n3, n3 - 1)
                    lo = max(cell_start[row + first], i + 1)
                    hi = cell_start[row + last + 1]
                    m = hi - lo
                    if m <= 0:
                        continue
                    # Separations to the neighbouring cell's image (s_beta + w) of each beta.
                    for j in range(m):
                        ds2 = sa2 - (t2[lo + j] + w2)
                        ds2 -= round2 * math.floor(ds2 + 0.5)
                        ds3 = sa3 - (t3[lo + j] + w3)
                        ds3 -= round3 * math.floor(ds3 + 0.5)
                        dx = box_length * (sa1 - (t1[lo + j] + w1)) + offset * ds2
                        dx -= round1 * box_length * math.floor(dx / box_length + 0.5)
                        dy = box_length * ds2
                        dz = box_length * ds3
                        cx[j] = dx
                        cy[j] = dy
                        cz[j] = dz
                        cr2[j] = dx * dx + dy * dy + dz * dz
                    # Branch-free compaction of the pairs within the cut-off.
                    for j in range(m):
                        picked[count] = j
                        count += 1 if cr2[j] < rc2 else 0
                    for j in range(start, count):
                        k = picked[j]
                        bx[j] = cx[k]
                        by[j] = cy[k]
                        bz[j] = cz[k]
                        br2[j] = cr2[k]
                        bgauss[j] = math.exp(-xi2 * cr2[k])
                        partner[j] = lo + k
                    start = count
        if count == 0:
            continue
        if want_near:
            found = 0
            for j in range(count):  # branch-free selection (``picked`` is free once the pairs are in)
                picked[found] = j
                found += 1 if br2[j] < near2 else 0
            if near_count + found > near_pairs.shape[0]:  # grow (rare: the start holds ~3x the typical)
                capacity = 2 * (near_count + found)
                grown_pairs = np.empty((capacity, 2), dtype=np.int64)
                grown_separations = np.empty((capacity, 3))
                grown_pairs[:near_count] = near_pairs[:near_count]
                grown_separations[:near_count] = near_separations[:near_count]
                near_pairs = grown_pairs
                near_separations = grown_separations
            alpha = order[i]
            for selected in range(found):  # x_j - x_i = -(x_alpha - x_beta)
                j = picked[selected]
                near_pairs[near_count, 0] = alpha
                near_pairs[near_count, 1] = order[partner[j]]
                near_separations[near_count, 0] = -bx[j]
                near_separations[near_count, 1] = -by[j]
                near_separations[near_count, 2] = -bz[j]
                near_count += 1
        t = _real_space_block(count, bx, by, bz, br2, bgauss, xi, qt, a_s, a_t, ux, uy, uz, erfc_buf)
        for j in range(6):
            sums[0, j] += t[j]
            sums[1, j] += t[6 + j]
        ua0 = 0.0
        ua1 = 0.0
        ua2 = 0.0
        for j in range(count):
            b = partner[j]
            ua0 += ux[j]
            ua1 += uy[j]
            ua2 += uz[j]
            vsorted[b, 0] -= ux[j]
            vsorted[b, 1] -= uy[j]
            vsorted[b, 2] -= uz[j]
        vsorted[i, 0] += ua0
        vsorted[i, 1] += ua1
        vsorted[i, 2] += ua2
    for i in range(n):
        p = order[i]
        velocity[p, 0] += vsorted[i, 0]
        velocity[p, 1] += vsorted[i, 1]
        velocity[p, 2] += vsorted[i, 2]
    if cutoff > box_length:
        _self_image_sums(box_length, offset, xi, cutoff, q, a_s, a_t, n, sums)
    return near_pairs[:near_count], near_separations[:near_count]


# --------------------------------------------------------------------------------------------------
# Fourier-space kernels
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _fourier_mode(
    kx: float,
    ky: float,
    kz: float,
    xi: float,
    q: np.ndarray,
    a_s: float,
    a_t: float,
    weight: float,
    s2: float,
    stresslet: np.ndarray,
    virial: np.ndarray,
) -> tuple[float, float, float]:
    """One wave vector: add ``weight * s2 * D^`` to ``stresslet``, ``weight * s2 * K^`` to ``virial``.

    ``s2 = |rho(k)|^2``. Returns the real velocity vector ``16 pi (g/k^2) w(k)`` that multiplies
    ``Im[exp(i k.x_alpha) rho(k)]`` for the pair ``(k, -k)`` (module docstring), with
    ``w = a_S (Q.k - k (k.Q.k)/k^2) + a_T k (k.Q.k)``, and (upper triangles)

        D^ = -4 pi G [3 (Qk k + k Qk) - 3 k k + 3 (kQk) I + k^2 I] + 60 pi g (kQk) k k / k^4,
        K^ = 4 pi [(kQk) G I + (Qk k + k Qk) G + k k (kQk) G'],

    ``G = g/k^2``, ``G' = (1/k) dG/dk = -exp(-k^2/4xi^2) [2/k^4 + 1/(2 xi^2 k^2) + 1/(8 xi^4)]``.
    """
    k2 = kx * kx + ky * ky + kz * kz
    inv4xi2 = 0.25 / (xi * xi)
    gauss = math.exp(-k2 * inv4xi2)
    g = (1.0 + k2 * inv4xi2) * gauss
    big_g = g / k2
    qk0 = q[0, 0] * kx + q[0, 1] * ky + q[0, 2] * kz
    qk1 = q[1, 0] * kx + q[1, 1] * ky + q[1, 2] * kz
    qk2 = q[2, 0] * kx + q[2, 1] * ky + q[2, 2] * kz
    kqk = kx * qk0 + ky * qk1 + kz * qk2
    lon = a_t * kqk - a_s * kqk / k2
    pref = 16.0 * math.pi * big_g
    wx = pref * (a_s * qk0 + lon * kx)
    wy = pref * (a_s * qk1 + lon * ky)
    wz = pref * (a_s * qk2 + lon * kz)
    if s2 != 0.0:
        k = (kx, ky, kz)
        qk = (qk0, qk1, qk2)
        g_prime = -gauss * (2.0 / (k2 * k2) + 2.0 * inv4xi2 / k2 + 2.0 * inv4xi2 * inv4xi2)
        fs = weight * s2
        c_d = -4.0 * math.pi * big_g
        c_kk = 60.0 * math.pi * g * kqk / (k2 * k2)
        for i in range(3):
            for j in range(i, 3):
                sym = qk[i] * k[j] + k[i] * qk[j]
                kk = k[i] * k[j]
                d = c_d * (3.0 * sym - 3.0 * kk) + c_kk * kk
                v = 4.0 * math.pi * (sym * big_g + kk * kqk * g_prime)
                if i == j:
                    d += c_d * (3.0 * kqk + k2)
                    v += 4.0 * math.pi * kqk * big_g
                stresslet[i, j] += fs * d
                virial[i, j] += fs * v
    return wx, wy, wz


@njit(cache=True)
def _fractional_coordinates(positions: np.ndarray, box_length: float, offset: float) -> np.ndarray:
    """Sheared-lattice fractional coordinates ``s`` in ``[0, 1)^3``, shape ``(N, 3)``.

    ``x = s1 a1 + s2 a2 + s3 a3``: ``s2 = y/L``, ``s1 = (x - s2 delta)/L``, ``s3 = z/L``; then
    ``k.x = 2 pi (m1 s1 + m2 s2 + m3 s3)`` for ``k = m1 b1 + m2 b2 + m3 b3``.
    """
    n = positions.shape[0]
    s = np.empty((n, 3))
    for p in range(n):
        s2 = positions[p, 1] / box_length
        s1 = (positions[p, 0] - s2 * offset) / box_length
        s3 = positions[p, 2] / box_length
        s[p, 0] = s1 - math.floor(s1)
        s[p, 1] = s2 - math.floor(s2)
        s[p, 2] = s3 - math.floor(s3)
    return s


@njit(cache=True)
def _phase_table(s: np.ndarray, m_low: int, m_high: int) -> tuple[np.ndarray, np.ndarray]:
    """``cos`` and ``sin`` of ``2 pi m s`` for ``m = m_low..m_high``, shape ``(m_high - m_low + 1, N)``."""
    n = s.shape[0]
    count = m_high - m_low + 1
    cos_t = np.empty((count, n))
    sin_t = np.empty((count, n))
    for p in range(n):
        c1 = math.cos(_TWO_PI * s[p])
        s1 = math.sin(_TWO_PI * s[p])
        c0 = math.cos(_TWO_PI * m_low * s[p])
        s0 = math.sin(_TWO_PI * m_low * s[p])
        for j in range(count):
            if j % 16 == 0:  # re-anchor the recurrence to bound rounding growth
                m = m_low + j
                c0 = math.cos(_TWO_PI * m * s[p])
                s0 = math.sin(_TWO_PI * m * s[p])
            cos_t[j, p] = c0
            sin_t[j, p] = s0
            c0, s0 = c0 * c1 - s0 * s1, s0 * c1 + c0 * s1
    return cos_t, sin_t


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy")
def _wave_row(
    kx: float,
    ky: float,
    m3_lo: int,
    m3_hi: int,
    unit: float,
    xi: float,
    q: tuple[float, float, float, float, float, float],
    a_s: float,
    a_t: float,
    row_gauss: float,
    gauss3: np.ndarray,
    m_c: int,
    coef: np.ndarray,
) -> None:
    """Per-wave factors of the modes ``k = (kx, ky, unit*m3)``, ``m3 = m3_lo..m3_hi`` (weight 2).

    Branch-free (vectorised) form of :func:`_fourier_mode`, none of it depending on the positions:
    ``coef[0:3, t]`` the velocity vector ``16 pi (g/k^2) w(k)``, ``coef[3:9, t]`` ``2 D^`` and
    ``coef[9:15, t]`` ``2 K^`` (components ``xx, xy, xz, yy, yz, zz``) for ``t = m3 - m3_lo``, to be
    multiplied by ``|rho(k)|^2``. ``exp(-k^2/4xi^2) = row_gauss * gauss3[m3 + m_c]``.
    """
    q00, q01, q02, q11, q12, q22 = q
    inv4xi2 = 0.25 / (xi * xi)
    kxy2 = kx * kx + ky * ky
    four_pi = 4.0 * math.pi
    for m3 in range(m3_lo, m3_hi + 1):
        t = m3 - m3_lo
        kz = unit * m3
        k2 = kxy2 + kz * kz
        gauss = row_gauss * gauss3[m3 + m_c]
        g = (1.0 + k2 * inv4xi2) * gauss
        big_g = g / k2
        qk0 = q00 * kx + q01 * ky + q02 * kz
        qk1 = q01 * kx + q11 * ky + q12 * kz
        qk2 = q02 * kx + q12 * ky + q22 * kz
        kqk = kx * qk0 + ky * qk1 + kz * qk2
        lon = a_t * kqk - a_s * kqk / k2
        pref = 16.0 * math.pi * big_g
        coef[0, t] = pref * (a_s * qk0 + lon * kx)
        coef[1, t] = pref * (a_s * qk1 + lon * ky)
        coef[2, t] = pref * (a_s * qk2 + lon * kz)
        g_prime = -gauss * (2.0 / (k2 * k2) + 2.0 * inv4xi2 / k2 + 2.0 * inv4xi2 * inv4xi2)
        c_d = -four_pi * big_g
        c_kk = 60.0 * math.pi * g * kqk / (k2 * k2)
        c_diag = c_d * (3.0 * kqk + k2)
        v_diag = four_pi * kqk * big_g
        sxx = 2.0 * qk0 * kx
        sxy = qk0 * ky + kx * qk1
        sxz = qk0 * kz + kx * qk2
        syy = 2.0 * qk1 * ky
        syz = qk1 * kz + ky * qk2
        szz = 2.0 * qk2 * kz
        kxx = kx * kx
        kxy = kx * ky
        kxz = kx * kz
        kyy = ky * ky
        kyz = ky * kz
        kzz = kz * kz
        cv = four_pi * kqk * g_prime
        coef[3, t] = 2.0 * (c_d * (3.0 * sxx - 3.0 * kxx) + c_kk * kxx + c_diag)
        coef[4, t] = 2.0 * (c_d * (3.0 * sxy - 3.0 * kxy) + c_kk * kxy)
        coef[5, t] = 2.0 * (c_d * (3.0 * sxz - 3.0 * kxz) + c_kk * kxz)
        coef[6, t] = 2.0 * (c_d * (3.0 * syy - 3.0 * kyy) + c_kk * kyy + c_diag)
        coef[7, t] = 2.0 * (c_d * (3.0 * syz - 3.0 * kyz) + c_kk * kyz)
        coef[8, t] = 2.0 * (c_d * (3.0 * szz - 3.0 * kzz) + c_kk * kzz + c_diag)
        coef[9, t] = 2.0 * (four_pi * sxx * big_g + kxx * cv + v_diag)
        coef[10, t] = 2.0 * (four_pi * sxy * big_g + kxy * cv)
        coef[11, t] = 2.0 * (four_pi * sxz * big_g + kxz * cv)
        coef[12, t] = 2.0 * (four_pi * syy * big_g + kyy * cv + v_diag)
        coef[13, t] = 2.0 * (four_pi * syz * big_g + kyz * cv)
        coef[14, t] = 2.0 * (four_pi * szz * big_g + kzz * cv + v_diag)


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy", inline="always")
def _lane_sum(values: np.ndarray, count: int) -> float:
    """``sum(values[:count])`` in eight interleaved partial sums, added up in a fixed order at the end.

    One running sum is a chain of dependent additions (4 cycles each): the structure factor of each wave
    vector spent most of its time waiting on it, since the reproducible fast-math flags
    (:data:`sim.numba_cache.REPRODUCIBLE_FASTMATH`) forbid LLVM to reassociate the sum itself. Written
    out here, the association is part of the source, so compiled and cache-loaded code agree bit for
    bit, and the eight lanes fill one AVX-512 register (or two AVX2 ones).
    """
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    full = count - count % 8
    for p in range(0, full, 8):
        a0 += values[p]
        a1 += values[p + 1]
        a2 += values[p + 2]
        a3 += values[p + 3]
        a4 += values[p + 4]
        a5 += values[p + 5]
        a6 += values[p + 6]
        a7 += values[p + 7]
    for p in range(full, count):
        a0 += values[p]
    return ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7))


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy")
def _ewald_fourier_sums(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    xi: float,
    k_cutoff: float,
    q: np.ndarray,
    a_s: float,
    a_t: float,
    velocity: np.ndarray,
    stresslet: np.ndarray,
    virial: np.ndarray,
) -> None:
    """Fourier-space sums by explicit structure factors over the half space of ``|k| <= k_c``.

    ``stresslet`` and ``virial`` receive ``sum_{all k != 0} D^ |rho|^2`` and ``K^ |rho|^2`` (not yet
    divided by ``V``); ``velocity`` receives the full Fourier part already divided by ``V``.

    Per row ``(m1, m2)`` of wave vectors: the particle phases ``exp(i 2 pi (m1 s1 + m2 s2))`` from the
    per-axis tables (built by recurrence), the position-independent factors of all the row's modes at
    once (:func:`_wave_row`, one exponential per row, vectorised), then per mode the structure factor
    (a running sum over the particles) and the velocity update (a vectorised loop over the particles).
    """
    n = positions.shape[0]
    volume = box_length**3
    s = _fractional_coordinates(positions, box_length, offset)
    unit = _TWO_PI / box_length
    shear = offset / box_length
    m_real = k_cutoff / unit  # |m1|, |m3|, |m2 - m1 delta/L| <= m_real
    m_c = int(math.floor(m_real))
    m2_max = int(math.ceil(1.5 * m_real)) + 1
    kc2 = k_cutoff * k_cutoff
    inv4xi2 = 0.25 / (xi * xi)
    c1, s1 = _phase_table(s[:, 0], 0, m_c)
    c2, s2 = _phase_table(s[:, 1], -m2_max, m2_max)
    c3, s3 = _phase_table(s[:, 2], -m_c, m_c)
    gauss3 = np.empty(2 * m_c + 1)
    for j3 in range(2 * m_c + 1):
        kz = unit * (j3 - m_c)
        gauss3[j3] = math.exp(-kz * kz * inv4xi2)
    qt = (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2])
    coef = np.empty((15, 2 * m_c + 1))
    p_re = np.empty(n)
    p_im = np.empty(n)
    e_re = np.empty(n)
    e_im = np.empty(n)
    ux = np.zeros(n)
    uy = np.zeros(n)
    uz = np.zeros(n)
    d_sum = np.zeros(6)
    k_sum = np.zeros(6)
    for m1 in range(0, m_c + 1):
        kx = unit * m1
        centre = m1 * shear
        lo = max(int(math.ceil(centre - m_real)), -m2_max)
        hi = min(int(math.floor(centre + m_real)), m2_max)
        for m2 in range(lo, hi + 1):
            if m1 == 0 and m2 < 0:
                continue
            ky = unit * (m2 - centre)
            rest = kc2 - kx * kx - ky * ky
            if rest < 0.0:
                continue
            m3_hi = min(int(math.floor(math.sqrt(rest) / unit)), m_c)
            m3_lo = -m3_hi
            if m1 == 0 and m2 == 0:
                m3_lo = 1
            if m3_lo > m3_hi:
                continue
            j2 = m2 + m2_max
            for p in range(n):
                a_r = c1[m1, p]
                a_i = s1[m1, p]
                b_r = c2[j2, p]
                b_i = s2[j2, p]
                p_re[p] = a_r * b_r - a_i * b_i
                p_im[p] = a_r * b_i + a_i * b_r
            row_gauss = math.exp(-(kx * kx + ky * ky) * inv4xi2)
            _wave_row(kx, ky, m3_lo, m3_hi, unit, xi, qt, a_s, a_t, row_gauss, gauss3, m_c, coef)
            for m3 in range(m3_lo, m3_hi + 1):
                t = m3 - m3_lo
                j3 = m3 + m_c
                # rho(k) = sum exp(-i k.x) = sum_re - i sum_im; |rho|^2 = sum_re^2 + sum_im^2.
                for p in range(n):
                    b_r = c3[j3, p]
                    b_i = s3[j3, p]
                    e_re[p] = p_re[p] * b_r - p_im[p] * b_i
                    e_im[p] = p_re[p] * b_i + p_im[p] * b_r
                sum_re = _lane_sum(e_re, n)
                sum_im = _lane_sum(e_im, n)
                rho2 = sum_re * sum_re + sum_im * sum_im
                for c in range(6):
                    d_sum[c] += rho2 * coef[3 + c, t]
                    k_sum[c] += rho2 * coef[9 + c, t]
                wx = coef[0, t]
                wy = coef[1, t]
                wz = coef[2, t]
                for p in range(n):
                    f = e_im[p] * sum_re - e_re[p] * sum_im
                    ux[p] += wx * f
                    uy[p] += wy * f
                    uz[p] += wz * f
    column = 0
    for i in range(3):
        for j in range(i, 3):
            stresslet[i, j] += d_sum[column]
            virial[i, j] += k_sum[column]
            column += 1
    for p in range(n):
        velocity[p, 0] += ux[p] / volume
        velocity[p, 1] += uy[p] / volume
        velocity[p, 2] += uz[p] / volume


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy")
def _mesh_row(
    kx: float,
    ky: float,
    j3_lo: int,
    j3_hi: int,
    unit: float,
    xi: float,
    q: tuple[float, float, float, float, float, float],
    a_s: float,
    a_t: float,
    row_gauss: float,
    gauss3: np.ndarray,
    b3: np.ndarray,
    bb12: float,
    scale: float,
    spectrum_row: np.ndarray,
    field_x: np.ndarray,
    field_y: np.ndarray,
    field_z: np.ndarray,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float]:
    """SPME kernel along one mesh row ``j3 = j3_lo..j3_hi`` (weight 2: the ``-k`` half is implied).

    Branch-free (vectorised) form of :func:`_fourier_mode` for the modes
    ``k = (kx, ky, unit*j3)``: writes the velocity fields ``-8 pi i (g/k^2) w |b|^2 scale F`` and
    returns the sums ``2 |b|^2 |F|^2 D^`` and ``2 |b|^2 |F|^2 K^`` (components ``xx, xy, xz, yy, yz,
    zz``). ``exp(-k^2/4xi^2) = row_gauss * gauss3[j3]`` avoids an exponential per mode.
    """
    q00, q01, q02, q11, q12, q22 = q
    inv4xi2 = 0.25 / (xi * xi)
    kxy2 = kx * kx + ky * ky
    four_pi = 4.0 * math.pi
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    v0 = v1 = v2 = v3 = v4 = v5 = 0.0
    for j3 in range(j3_lo, j3_hi + 1):
        kz = unit * j3
        k2 = kxy2 + kz * kz
        gauss = row_gauss * gauss3[j3]
        g = (1.0 + k2 * inv4xi2) * gauss
        big_g = g / k2
        qk0 = q00 * kx + q01 * ky + q02 * kz
        qk1 = q01 * kx + q11 * ky + q12 * kz
        qk2 = q02 * kx + q12 * ky + q22 * kz
        kqk = kx * qk0 + ky * qk1 + kz * qk2
        lon = a_t * kqk - a_s * kqk / k2
        pref = 16.0 * math.pi * big_g
        wx = pref * (a_s * qk0 + lon * kx)
        wy = pref * (a_s * qk1 + lon * ky)
        wz = pref * (a_s * qk2 + lon * kz)
        bb = bb12 * b3[j3]
        f = spectrum_row[j3]
        fs = 2.0 * bb * (f.real * f.real + f.imag * f.imag)
        c_re = 0.5 * scale * bb * f.imag
        c_im = -0.5 * scale * bb * f.real
        field_x[j3] = complex(wx * c_re, wx * c_im)
        field_y[j3] = complex(wy * c_re, wy * c_im)
        field_z[j3] = complex(wz * c_re, wz * c_im)
        g_prime = -gauss * (2.0 / (k2 * k2) + 2.0 * inv4xi2 / k2 + 2.0 * inv4xi2 * inv4xi2)
        c_d = -four_pi * big_g
        c_kk = 60.0 * math.pi * g * kqk / (k2 * k2)
        c_diag = c_d * (3.0 * kqk + k2)
        v_diag = four_pi * kqk * big_g
        sxx = 2.0 * qk0 * kx
        sxy = qk0 * ky + kx * qk1
        sxz = qk0 * kz + kx * qk2
        syy = 2.0 * qk1 * ky
        syz = qk1 * kz + ky * qk2
        szz = 2.0 * qk2 * kz
        kxx = kx * kx
        kxy = kx * ky
        kxz = kx * kz
        kyy = ky * ky
        kyz = ky * kz
        kzz = kz * kz
        cv = four_pi * kqk * g_prime
        s0 += fs * (c_d * (3.0 * sxx - 3.0 * kxx) + c_kk * kxx + c_diag)
        s1 += fs * (c_d * (3.0 * sxy - 3.0 * kxy) + c_kk * kxy)
        s2 += fs * (c_d * (3.0 * sxz - 3.0 * kxz) + c_kk * kxz)
        s3 += fs * (c_d * (3.0 * syy - 3.0 * kyy) + c_kk * kyy + c_diag)
        s4 += fs * (c_d * (3.0 * syz - 3.0 * kyz) + c_kk * kyz)
        s5 += fs * (c_d * (3.0 * szz - 3.0 * kzz) + c_kk * kzz + c_diag)
        v0 += fs * (four_pi * sxx * big_g + kxx * cv + v_diag)
        v1 += fs * (four_pi * sxy * big_g + kxy * cv)
        v2 += fs * (four_pi * sxz * big_g + kxz * cv)
        v3 += fs * (four_pi * syy * big_g + kyy * cv + v_diag)
        v4 += fs * (four_pi * syz * big_g + kyz * cv)
        v5 += fs * (four_pi * szz * big_g + kzz * cv + v_diag)
    return s0, s1, s2, s3, s4, s5, v0, v1, v2, v3, v4, v5


@njit(cache=True)
def _spme_fourier_sums(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    xi: float,
    k_cutoff: float,
    mesh: tuple[int, int, int],
    order: int,
    q: np.ndarray,
    a_s: float,
    a_t: float,
    velocity: np.ndarray,
    stresslet: np.ndarray,
    virial: np.ndarray,
) -> None:
    """Fourier-space sums by smooth particle-mesh Ewald (same output convention as the Ewald version).

    Unit charges are spread on the ``K1 x K2 x K3`` mesh of the sheared fractional coordinates with
    cardinal B-splines of order ``p`` (:mod:`sim.dipolophoresis.spme`); after a real FFT,
    ``rho(k) ~ conj(b(m)) F[Q](m)`` with the Euler-spline factors ``b``. The three velocity components
    are ``phi_c = (K1 K2 K3/V) IFFT[K^_c |b|^2 F[Q]]`` on the mesh, interpolated back with the same
    B-splines; the stress sums use ``|rho|^2 ~ |b|^2 |F[Q]|^2``. Modes with ``|k| > k_c`` and the
    Nyquist planes are dropped.
    """
    k1, k2, k3 = mesh
    s = _fractional_coordinates(positions, box_length, offset)
    base, weights = spme.bspline_weights(s, mesh, order)
    charges = spme.spread_unit_charges(base, weights, mesh)
    spectrum = spme.real_fft(charges)
    b1 = spme.bspline_moduli(k1, order)
    b2 = spme.bspline_moduli(k2, order)
    b3 = spme.bspline_moduli(k3, order)
    unit = _TWO_PI / box_length
    shear = offset / box_length
    volume = box_length**3
    scale = (k1 * k2 * k3) / volume
    kc2 = k_cutoff * k_cutoff
    h3 = spectrum.shape[2]
    j3_top = min(h3 - 1, (k3 - 1) // 2)  # the Nyquist plane (even K3) is dropped
    gauss3 = np.empty(h3)
    for j3 in range(h3):
        gauss3[j3] = math.exp(-((unit * j3) ** 2) * 0.25 / (xi * xi))
    qt = (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2])
    field_x = np.zeros(spectrum.shape, dtype=np.complex128)
    field_y = np.zeros(spectrum.shape, dtype=np.complex128)
    field_z = np.zeros(spectrum.shape, dtype=np.complex128)
    for j1 in range(k1):
        if 2 * j1 == k1:
            continue
        m1 = j1 if 2 * j1 < k1 else j1 - k1
        kx = unit * m1
        for j2 in range(k2):
            if 2 * j2 == k2:
                continue
            m2 = j2 if 2 * j2 < k2 else j2 - k2
            ky = unit * (m2 - m1 * shear)
            rest = kc2 - kx * kx - ky * ky
            if rest < 0.0:
                continue
            j3_hi = min(int(math.floor(math.sqrt(rest) / unit)), j3_top)
            bb12 = b1[j1] * b2[j2]
            if m1 != 0 or m2 != 0:
                # j3 = 0 plane: its -k partner is another (j1, j2) of the same plane, weight 1.
                f = spectrum[j1, j2, 0]
                bb = bb12 * b3[0]
                s2 = bb * (f.real * f.real + f.imag * f.imag)
                wx, wy, wz = _fourier_mode(kx, ky, 0.0, xi, q, a_s, a_t, 1.0, s2, stresslet, virial)
                # Full-space multiplier -8 pi i (g/k^2) w = -(i/2) * (16 pi (g/k^2) w).
                c = -0.5j * scale * bb * f
                field_x[j1, j2, 0] = wx * c
                field_y[j1, j2, 0] = wy * c
                field_z[j1, j2, 0] = wz * c
            if j3_hi >= 1:
                row_gauss = math.exp(-(kx * kx + ky * ky) * 0.25 / (xi * xi))
                t = _mesh_row(
                    kx,
                    ky,
                    1,
                    j3_hi,
                    unit,
                    xi,
                    qt,
                    a_s,
                    a_t,
                    row_gauss,
                    gauss3,
                    b3,
                    bb12,
                    scale,
                    spectrum[j1, j2],
                    field_x[j1, j2],
                    field_y[j1, j2],
                    field_z[j1, j2],
                )
                column = 0
                for i in range(3):
                    for j in range(i, 3):
                        stresslet[i, j] += t[column]
                        virial[i, j] += t[6 + column]
                        column += 1
    phi_x = spme.inverse_real_fft(field_x, mesh)
    phi_y = spme.inverse_real_fft(field_y, mesh)
    phi_z = spme.inverse_real_fft(field_z, mesh)
    spme.interpolate_add(base, weights, phi_x, phi_y, phi_z, velocity)


# --------------------------------------------------------------------------------------------------
# Public compiled entry point
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def collects_near_pairs(plan: EwaldPlan, box_length: float, near_cutoff: float) -> bool:
    """Whether :func:`dip_far_field_with_pairs` returns the pairs closer than ``near_cutoff``: the
    real-space sum reaches them (``near_cutoff <= r_c``) and each has a single image (``< L/2``)."""
    return 0.0 < near_cutoff <= plan.real_cutoff and near_cutoff < 0.5 * box_length


@njit(cache=True)
def dip_far_field(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    direction: np.ndarray,
    icep_weight: float,
    dep_weight: float,
    plan: EwaldPlan,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Periodic far-field DIP velocities, ICEP pair-stresslet stress and DEP virial stress.

    Args:
        positions: Sphere centres, shape ``(N, 3)``, float64 (units ``a``), wrapped in ``[0, L)^3``
            (any lattice image of a position gives the same result).
        box_length: Box side ``L`` (units ``a``); must equal ``plan.box_length``.
        offset: Lees–Edwards offset ``delta`` in ``[-L/2, L/2]`` (units ``a``), e.g. from
            :func:`sim.geometry.box.lees_edwards_offset`.
        direction: Unit field direction ``e``, shape ``(3,)``, float64.
        icep_weight: Weight of ICEP (0 or 1).
        dep_weight: Weight of DEP (0 or 1).
        plan: :class:`EwaldPlan` from :func:`ewald_plan` for this box.

    Returns:
        ``(velocity, icep_pair_stress, dep_virial_stress)``:
        velocity ``(N, 3)`` in units ``U0 = eps a E0^2/eta``;
        ``icep_pair_stress`` ``(3, 3)``: ``icep_weight * (1/V) sum_alpha dS_alpha`` (O(r^-3) pair
        corrections to the ICEP stresslet, all images), units ``eps E0^2``, symmetric, traceless;
        ``dep_virial_stress`` ``(3, 3)``: ``-dep_weight * (1/V) sum_pairs sym(x F^DEP)`` (all images),
        units ``eps E0^2``, symmetric. The isolated-sphere stresslet ``n S0`` is not included.

    Raises:
        ValueError: inconsistent plan or box, offset outside ``[-L/2, L/2]``, ``direction`` not a unit
            vector, bad ``positions`` shape.

    References:
        Hasimoto (1959); Beenakker (1986); Essmann et al. (1995); Park & Saintillan (2010);
        Mirfendereski & Park (2024) eqs 2.3-2.5; ``docs/model.md#dipolophoresis``.
    """
    velocity, icep_stress, dep_stress, _, _ = dip_far_field_with_pairs(
        positions, box_length, offset, direction, icep_weight, dep_weight, plan, 0.0
    )
    return velocity, icep_stress, dep_stress


@njit(cache=True)
def dip_far_field_with_pairs(
    positions: np.ndarray,
    box_length: float,
    offset: float,
    direction: np.ndarray,
    icep_weight: float,
    dep_weight: float,
    plan: EwaldPlan,
    near_cutoff: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`dip_far_field` and the pairs closer than ``near_cutoff`` from its real-space sum.

    The near-field blend needs every pair closer than its cut-off (4 a); the real-space sum visits them
    anyway, so it hands them over (:func:`_real_space_sums`) when :func:`collects_near_pairs` (``0 <
    near_cutoff <= r_c`` and ``near_cutoff < L/2``); otherwise the pair arrays are empty and the caller
    builds its own list.

    Returns:
        ``(velocity, icep_pair_stress, dep_virial_stress, pairs, separations)`` as :func:`dip_far_field`,
        then ``pairs`` (K, 2) int64 and ``separations`` (K, 3) ``x_j - x_i`` (units ``a``) of the pairs
        closer than ``near_cutoff``, unsorted; K = 0 and shape ``(0, 2)`` when not collected.
    """
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError("positions must have shape (N, 3)")
    if not (box_length > 0.0) or abs(box_length - plan.box_length) > 1e-9 * plan.box_length:
        raise ValueError("box_length must equal plan.box_length (make the plan for this box)")
    if not (abs(offset) <= 0.5 * box_length):
        raise ValueError("offset must lie in [-L/2, L/2]")
    norm = math.sqrt(direction[0] ** 2 + direction[1] ** 2 + direction[2] ** 2)
    if not (abs(norm - 1.0) <= 1e-9):
        raise ValueError("direction must be a unit vector (|e| = 1 within 1e-9)")
    n = positions.shape[0]
    q = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            q[i, j] = direction[i] * direction[j] - (1.0 / 3.0 if i == j else 0.0)
    a_s = ICEP_S_COEFFICIENT * icep_weight
    a_t = ICEP_T_COEFFICIENT * icep_weight + DEP_T_COEFFICIENT * dep_weight
    velocity = np.zeros((n, 3))
    real_sums = np.zeros((2, 6))
    four_d = np.zeros((3, 3))
    four_k = np.zeros((3, 3))
    collect = collects_near_pairs(plan, box_length, near_cutoff)
    near_pairs = np.empty((0, 2), dtype=np.int64)
    near_separations = np.empty((0, 3))
    if n > 1 or plan.real_cutoff > box_length:  # pairs, or a single sphere's own images
        near_pairs, near_separations = _real_space_sums(
            positions,
            box_length,
            offset,
            plan.splitting,
            plan.real_cutoff,
            q,
            a_s,
            a_t,
            velocity,
            real_sums,
            near_cutoff if collect else 0.0,
        )
    if plan.method == METHOD_SPME:
        _spme_fourier_sums(
            positions,
            box_length,
            offset,
            plan.splitting,
            plan.k_cutoff,
            plan.mesh,
            plan.order,
            q,
            a_s,
            a_t,
            velocity,
            four_d,
            four_k,
        )
    else:
        _ewald_fourier_sums(
            positions,
            box_length,
            offset,
            plan.splitting,
            plan.k_cutoff,
            q,
            a_s,
            a_t,
            velocity,
            four_d,
            four_k,
        )
    volume = box_length**3
    icep_stress = np.empty((3, 3))
    dep_stress = np.empty((3, 3))
    column = 0
    for i in range(3):
        for j in range(i, 3):
            d = math.pi / volume * (real_sums[0, column] + four_d[i, j] / volume)
            v = -math.pi / volume * (real_sums[1, column] + 0.5 * four_k[i, j] / volume)
            column += 1
            icep_stress[i, j] = icep_weight * d
            icep_stress[j, i] = icep_weight * d
            dep_stress[i, j] = dep_weight * v
            dep_stress[j, i] = dep_weight * v
    return velocity, icep_stress, dep_stress, near_pairs, near_separations


# --------------------------------------------------------------------------------------------------
# Plan: error estimates and parameter choice (plain Python, run once per simulation)
# --------------------------------------------------------------------------------------------------

_MECHANISM_COEFFICIENTS = {
    "icep": (ICEP_S_COEFFICIENT, ICEP_T_COEFFICIENT),
    "dep": (0.0, DEP_T_COEFFICIENT),
    "dip": (ICEP_S_COEFFICIENT, ICEP_T_COEFFICIENT + DEP_T_COEFFICIENT),
}
"""Velocity-kernel coefficients ``(a_S, a_T)`` of each mechanism."""

_PLAN_MECHANISMS = {"dip": ("dip",), "icep": ("icep",), "dep": ("dep",), "all": ("icep", "dep", "dip")}
"""Mechanisms whose accuracy a plan made for ``mechanism`` guarantees."""

# Safety factor between the estimated rms error and the stated accuracy.
_SAFETY = 1.0

# Ratio of the actual rms velocity to the ideal-gas estimate U_ideal (:func:`_reference_velocity`)
# below which the plan's accuracy is still guaranteed. Observed on random packings (tests'
# random_packing, phi = 0.02..0.55, N = 30 and 200): 0.19..5.8 for ICEP and DIP (dense packings
# screen the O(r^-2) sums; a near-contact pair raises the rms), 1.2..19 for DEP.
_REFERENCE_FRACTION = {"icep": 0.15, "dep": 0.5, "dip": 0.15}

# Cost model (seconds; one core of the development machine, AMD EPYC znver4, measured with process
# time while the machine was shared, so +-30%): real space per particle (cell scan), per candidate
# pair in the neighbouring cells and per pair within the cut-off; explicit Ewald per (particle, wave
# vector of the half space) and per wave vector; SPME per (particle, spline point) for spreading plus
# interpolation, per mesh point for the four real FFTs and per wave vector of the mesh kernel.
_COST_PARTICLE = 600e-9
_COST_CANDIDATE = 4e-9
_COST_PAIR = 17e-9
_COST_PARTICLE_WAVE = 1.0e-9
_COST_WAVE = 100e-9
_COST_SPLINE_POINT = 2.0e-9
_COST_MESH_POINT = 45e-9
_COST_MESH_WAVE = 30e-9

_MAX_REAL_CUTOFF = 1.5
"""Largest real-space cut-off a plan may take, in units of ``L`` (sums over several images above ``L/2``)."""


def _real_space_cost(box_length: float, n_particles: int, cutoff: float) -> float:
    """Modelled cost (s) of :func:`_real_space_sums` (cell list as there, at zero shear)."""
    density = n_particles / box_length**3
    pairs = 0.5 * n_particles * density * (4.0 * math.pi / 3.0) * cutoff**3
    if cutoff <= 0.5 * box_length:
        cells = int(math.floor(box_length / cutoff))
        fraction = 1.0 if cells < 3 else 27.0 / cells**3
        candidates = 0.5 * n_particles * n_particles * fraction
        return _COST_PARTICLE * n_particles + _COST_CANDIDATE * candidates + _COST_PAIR * pairs
    n1, n2, n3, s1, s2, s3 = _image_cells(
        box_length, 0.0, cutoff, n_particles, _COST_CANDIDATE, _COST_CELL_SLICE
    )
    fraction = (2.0 * s1 + 1.0) * (2.0 * s2 + 1.0) * (2.0 * s3 + 1.0) / (n1 * n2 * n3)
    slices = (2.0 * s1 + 1.0) * (2.0 * s2 + 1.0) * (math.ceil((2.0 * s3 + 1.0) / n3) + 1.0)
    candidates = 0.5 * n_particles * n_particles * fraction
    return (
        _COST_PARTICLE * n_particles
        + _COST_CANDIDATE * candidates
        + _COST_CELL_SLICE * slices * n_particles
        + _COST_PAIR * pairs
    )


_PANELS = (0.0, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)


def _tail_nodes() -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss–Legendre nodes and weights on ``[0, 8]`` (panels refined near 0)."""
    nodes = []
    weights = []
    for lo, hi in zip(_PANELS[:-1], _PANELS[1:], strict=True):
        nodes.append(lo + 0.5 * (hi - lo) * (_GL_X + 1.0))
        weights.append(0.5 * (hi - lo) * _GL_W)
    return np.concatenate(nodes), np.concatenate(weights)


_TAIL_T, _TAIL_W = _tail_nodes()


def _kernel_real_rms2(r: np.ndarray, xi: float, a_s: float, a_t: float) -> np.ndarray:
    """Orientation average ``<|K_R|^2>`` of the real-space velocity kernel at distances ``r`` (array)."""
    ec = special.erfc(xi * r)
    ex = np.exp(-((xi * r) ** 2)) / _SQRT_PI
    phi2 = 3.0 * ec / r**5 + ex * (-4.0 * xi**5 + 4.0 * xi**3 / r**2 + 6.0 * xi / r**4)
    phi3 = -15.0 * ec / r**7 + ex * (
        8.0 * xi**7 - 8.0 * xi**5 / r**2 - 20.0 * xi**3 / r**4 - 30.0 * xi / r**6
    )
    rho3 = 3.0 * ec / r**5 + ex * (4.0 * xi**3 / r**2 + 6.0 * xi / r**4)
    a = a_s * (-4.0 * xi**3 * ex) + 4.0 * a_t * phi2
    b = a_s * rho3 + 2.0 * a_t * phi3
    return r * r * ((2.0 / 9.0) * a * a + (8.0 / 45.0) * r * r * a * b + (4.0 / 45.0) * r**4 * b * b)


def _reference_velocity(density: float, a_s: float, a_t: float) -> float:
    """rms free-space velocity of an ideal gas of spheres outside contact (``r >= 2``), units ``U0``.

    ``<|U_pair|^2> = 0.8 a_S^2/r^4 - 9.6 a_S a_T/r^6 + 48 a_T^2/r^8`` (orientation average), so
    ``U_ref^2 = 4 pi n (0.4 a_S^2 - 0.4 a_S a_T + 0.3 a_T^2)``.
    """
    return math.sqrt(4.0 * math.pi * density * (0.4 * a_s * a_s - 0.4 * a_s * a_t + 0.3 * a_t * a_t))


def _real_error(xi: float, cutoff: float, density: float, a_s: float, a_t: float) -> float:
    """Estimated rms real-space truncation error of the velocities (module docstring), units ``U0``."""
    r = cutoff + _TAIL_T / xi
    val = float(np.sum(_TAIL_W / xi * 4.0 * math.pi * r * r * _kernel_real_rms2(r, xi, a_s, a_t)))
    return math.sqrt(max(density * val, 0.0))


def _fourier_error(xi: float, k_cutoff: float, density: float, a_s: float, a_t: float) -> float:
    """Estimated rms Fourier-space truncation error of the velocities (module docstring), units ``U0``."""
    k = k_cutoff + 2.0 * xi * _TAIL_T
    u = k * k / (4.0 * xi * xi)
    g = (1.0 + u) * np.exp(-u)
    kernel2 = (
        64.0 * math.pi**2 * g * g * ((2.0 / 15.0) * a_s * a_s / (k * k) + (4.0 / 45.0) * a_t * a_t * k * k)
    )
    val = float(np.sum(2.0 * xi * _TAIL_W * 4.0 * math.pi * k * k * kernel2))
    return math.sqrt(max(density * val / (2.0 * math.pi) ** 3, 0.0))


def estimated_errors(plan: EwaldPlan, n_particles: int) -> dict[str, float]:
    """Estimated rms velocity errors of ``plan`` relative to the reference velocity, per mechanism.

    Returns:
        ``{"icep": ..., "dep": ..., "dip": ...}``: ``sqrt(dU_R^2 + dU_F^2 + dU_mesh^2)/U_ref`` with
        ``U_ref = f U_ideal`` (module docstring; ``dU_mesh`` from
        :func:`sim.dipolophoresis.spme.mesh_error` for SPME plans). A plan made for a mechanism keeps
        its entry below ``accuracy``.
    """
    density = n_particles / plan.box_length**3
    out = {}
    for name, (a_s, a_t) in _MECHANISM_COEFFICIENTS.items():
        ref = _REFERENCE_FRACTION[name] * _reference_velocity(density, a_s, a_t)
        err2 = _real_error(plan.splitting, plan.real_cutoff, density, a_s, a_t) ** 2
        err2 += _fourier_error(plan.splitting, plan.k_cutoff, density, a_s, a_t) ** 2
        if plan.method == METHOD_SPME:
            err2 += (
                spme.mesh_error(
                    plan.splitting, plan.k_cutoff, plan.box_length, plan.mesh, plan.order, density, a_s, a_t
                )
                ** 2
            )
        out[name] = math.sqrt(err2) / ref
    return out


def _solve_cutoff(error_of, target: float, lower: float, upper: float) -> float | None:
    """Smallest cut-off in ``[lower, upper]`` with ``error_of(cutoff) <= target`` (error decreasing)."""
    if error_of(upper) > target:
        return None
    if error_of(lower) <= target:
        return lower
    return float(
        optimize.brentq(lambda c: math.log(max(error_of(c), 1e-300) / target), lower, upper, xtol=1e-6)
    )


def _cutoffs_for(
    xi: float,
    box_length: float,
    density: float,
    coefficients: list[tuple[float, float]],
    targets: list[float],
    share: float,
) -> tuple[float, float] | None:
    """Real and Fourier cut-offs meeting ``share * target`` for every mechanism ``(a_S, a_T)``, or None."""
    r_c = 0.0
    k_c = 0.0
    for (a_s, a_t), target in zip(coefficients, targets, strict=True):
        t = share * target

        def real_error(c: float, a_s: float = a_s, a_t: float = a_t) -> float:
            return _real_error(xi, c, density, a_s, a_t)

        # Nearest-image range first (as before sums over several images: the same root there).
        rc = _solve_cutoff(real_error, t, 1e-3, 0.5 * box_length)
        if rc is None:
            rc = _solve_cutoff(real_error, t, 0.5 * box_length, _MAX_REAL_CUTOFF * box_length)
        if rc is None:
            return None
        kc = _solve_cutoff(
            lambda c, a_s=a_s, a_t=a_t: _fourier_error(xi, c, density, a_s, a_t), t, 1e-3, 200.0 * xi
        )
        if kc is None:
            return None
        r_c = max(r_c, rc)
        k_c = max(k_c, kc)
    return r_c, k_c


def _half_space_waves(k_cutoff: float, box_length: float) -> float:
    """Approximate number of wave vectors in the half space ``|k| <= k_c``."""
    m = k_cutoff * box_length / _TWO_PI
    return (2.0 * math.pi / 3.0) * m**3


def _validate_plan_inputs(
    box_length: float, n_particles: int, accuracy: float, method: str, mechanism: str
) -> None:
    if mechanism not in _PLAN_MECHANISMS:
        raise ValueError(f"mechanism must be one of 'dip', 'icep', 'dep', 'all', got {mechanism!r}")
    if isinstance(box_length, bool) or not isinstance(box_length, (int, float, np.floating, np.integer)):
        raise ValueError(f"box_length must be a finite number > 4 (units a), got {box_length!r}")
    if not (math.isfinite(float(box_length)) and float(box_length) > 4.0):
        raise ValueError(f"box_length must be a finite number > 4 (units a), got {box_length!r}")
    if isinstance(n_particles, bool) or int(n_particles) != n_particles or n_particles < 1:
        raise ValueError(f"n_particles must be an integer >= 1, got {n_particles!r}")
    if not (isinstance(accuracy, (int, float, np.floating)) and 1e-15 <= float(accuracy) <= 1e-2):
        raise ValueError(f"accuracy must lie in [1e-15, 1e-2], got {accuracy!r}")
    if method not in ("auto", "ewald", "spme"):
        raise ValueError(f"method must be one of 'auto', 'ewald', 'spme', got {method!r}")


def ewald_plan(
    box_length: float,
    n_particles: int,
    accuracy: float = 1e-6,
    method: str = "auto",
    *,
    mechanism: str = "dip",
    splitting: float | None = None,
) -> EwaldPlan:
    """Choose the splitting parameter, cut-offs (and SPME mesh) for a stated velocity accuracy.

    By the error estimate of the module docstring the rms velocity error stays below ``accuracy``
    times the rms velocity of the mechanism the plan is made for (``accuracy * U_ref``, ``U_ref`` a
    calibrated lower bound of the rms velocity of hard-sphere suspensions), at every Lees–Edwards
    offset (the Fourier sum covers the whole ball ``|k| <= k_c`` whatever the shear, and the
    real-space estimate does not depend on it). The real-space cut-off is at most ``1.5 L`` (above ``L/2``
    the real-space sums take several images per pair: the plan of small boxes). Among the
    admissible splitting parameters the one of least modelled cost is taken. Made once per run.

    Args:
        box_length: Box side ``L`` (units ``a``), finite, ``> 4``.
        n_particles: Number of spheres ``N >= 1`` (sets the density in the error estimate).
        accuracy: Target relative rms velocity error, in ``[1e-15, 1e-2]``.
        method: ``"ewald"``, ``"spme"`` or ``"auto"`` (SPME for ``N >= spme.AUTO_SPME_MIN_PARTICLES``).
        mechanism: The mechanism whose velocities must meet ``accuracy`` relative to its own rms velocity:
            ``"dip"`` (default), ``"icep"``, ``"dep"``, or ``"all"`` (each of the three). A DIP plan used
            for DEP alone is about ``U_ref(dip)/U_ref(dep) ~ 4`` times less accurate relative to the
            (much smaller) DEP velocities: make DEP-only runs with ``mechanism="dep"``.
        splitting: Force the splitting parameter ``xi`` (units ``1/a``, ``> 0``) instead of optimising it
            (cut-offs are still chosen for ``accuracy``); for tests of splitting independence.

    Returns:
        An :class:`EwaldPlan`.

    Raises:
        ValueError: An argument is out of range, or no splitting parameter meets ``accuracy`` with
            ``r_c <= 1.5 L`` (the message names the parameter).

    References:
        Kolafa & Perram (1992); Essmann et al. (1995); Deserno & Holm (1998) J. Chem. Phys. 109, 7678.
    """
    _validate_plan_inputs(box_length, n_particles, accuracy, method, mechanism)
    box_length = float(box_length)
    n_particles = int(n_particles)
    accuracy = float(accuracy)
    if splitting is not None and not (math.isfinite(float(splitting)) and float(splitting) > 0.0):
        raise ValueError(f"splitting must be a finite number > 0 (units 1/a), got {splitting!r}")
    if method == "auto":
        method = "spme" if n_particles >= spme.AUTO_SPME_MIN_PARTICLES else "ewald"
    volume = box_length**3
    density = n_particles / volume
    names = _PLAN_MECHANISMS[mechanism]
    coefficients = [_MECHANISM_COEFFICIENTS[name] for name in names]
    targets = [
        accuracy
        * _REFERENCE_FRACTION[name]
        * _reference_velocity(density, *_MECHANISM_COEFFICIENTS[name])
        / _SAFETY
        for name in names
    ]
    share = 1.0 / math.sqrt(3.0) if method == "spme" else 1.0 / math.sqrt(2.0)
    if splitting is not None:
        candidates = [float(splitting)]
    else:
        # xi r_c ~ 2.5..7 for the accuracies allowed; scan from the smallest admissible xi upwards:
        # the grid of the nearest-image sums (r_c <= L/2, from xi = 4/L up), extended downwards in the
        # same geometric steps to xi = 2/r_c,max for sums over several images (small boxes).
        xi_min = 2.0 / (0.5 * box_length)
        ratio = 12.0 ** (1.0 / 39.0)
        extra = math.ceil(math.log(_MAX_REAL_CUTOFF / 0.5) / math.log(ratio))
        candidates = [xi_min * ratio ** (-j) for j in range(extra, 0, -1)]
        candidates += list(xi_min * np.geomspace(1.0, 12.0, 40))
    best: EwaldPlan | None = None
    best_cost = math.inf
    for xi in candidates:
        xi = float(xi)
        cut = _cutoffs_for(xi, box_length, density, coefficients, targets, share)
        if cut is None:
            continue
        r_c, k_c = cut
        real_cost = _real_space_cost(box_length, n_particles, r_c)
        waves = _half_space_waves(k_c, box_length)
        if method == "ewald":
            cost = real_cost + (_COST_PARTICLE_WAVE * n_particles + _COST_WAVE) * waves
            plan = EwaldPlan(xi, r_c, k_c, METHOD_EWALD, (0, 0, 0), 0, box_length)
        else:
            plan = None
            shares = [share * t for t in targets]
            for mesh, order in spme.mesh_candidates(xi, k_c, box_length, density, coefficients, shares):
                mesh_points = float(mesh[0] * mesh[1] * mesh[2])
                c = (
                    real_cost
                    + _COST_SPLINE_POINT * n_particles * order**3
                    + _COST_MESH_POINT * mesh_points
                    + _COST_MESH_WAVE * waves
                )
                if plan is None or c < cost:
                    cost = c
                    plan = EwaldPlan(xi, r_c, k_c, METHOD_SPME, mesh, order, box_length)
            if plan is None:
                continue
        if cost < best_cost:
            best, best_cost = plan, cost
    if best is None:
        raise ValueError(
            f"accuracy={accuracy!r} cannot be met with real_cutoff <= {_MAX_REAL_CUTOFF:g} L for "
            f"box_length={box_length!r}" + (f" and splitting={splitting!r}" if splitting is not None else "")
        )
    return best
