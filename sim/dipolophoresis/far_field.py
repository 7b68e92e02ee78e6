"""Free-space far-field dipolophoresis (DIP = ICEP + DEP) of a pair of ideally conductive spheres.

Notation (``docs/model.md#pair-notation``): lengths in units of the radius ``a``; for a pair,
``x = x_alpha - x_beta``
(from beta to alpha), ``r = |x|``, ``xh = x/r``, ``c = e.xh`` with ``e`` the unit field direction.
Velocities are in units of ``U0 = eps a E0^2 / eta``.

Kernels (method of reflections to O(r^-4); Saintillan 2008, Park & Saintillan 2010, paper eqs 2.3-2.5):

* Stokes dipole ``S_ijk = (d_ij x_k - d_ik x_j - d_jk x_i)/r^3 + 3 x_i x_j x_k / r^5 = -d_k G_ij`` with the
  Oseen tensor ``G_ij = d_ij/r + x_i x_j/r^3 = 2 d_ij/r - d_i d_j r``; ``S:ee = (3c^2 - 1) xh / r^2``.
* Potential quadrupole ``T = lap S``, ``T_ijk = 2 d_i d_j d_k (1/r)``; ``T:ee = -6 W / r^4`` with
  ``W = (5c^2 - 1) xh - 2 c e``.
* Velocity of alpha due to beta: ``U = icep_weight * U_ICEP + dep_weight * U_DEP`` with
  ``U_ICEP = -(9/8) S:ee - (11/24) T:ee`` and ``U_DEP = (1/12) T:ee``.
* The same in the isotropic form used by the near-field tables,
  ``U = (F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t`` with ``th`` the angle between ``e`` and
  ``xh`` and ``t`` the unit vector along the part of ``e`` perpendicular to ``xh``:
  ICEP ``F_par = -9/(4r^2) + 11/(2r^4)``, ``F_perp = 9/(8r^2) - 11/(4r^4)``, ``F_x = -11/(4r^4)``;
  DEP ``F_par = -1/r^4``, ``F_perp = 1/(2r^4)``, ``F_x = 1/(2r^4)``.

Stress kernels (Batchelor sign convention; ``docs/model.md#dipolophoresis`` "DIP stresslet"):

* Pair correction to the ICEP stresslet of alpha, to O(r^-3), in units ``eps a^3 E0^2``::

      dS_alpha = pi r^-3 [ 9 ee - 36 c (e xh + xh e) + (225/2 c^2 - 45/2) xh xh + (9/2 - 27/2 c^2) I ].

  Derivation (re-done here and confirmed; tests/test_far_field.py checks it numerically): the stresslet
  of a force- and torque-free sphere with surface velocity ``u_s`` is ``S = -5 eta ST[int u_s n dS]``
  (reciprocal theorem with the rigid sphere in a straining flow, whose surface traction is
  ``5 eta E.n``; ``ST`` = symmetric traceless part), which for the ICEP slip in a uniform field ``E``
  gives ``S = 9 pi eps a^3 (EE - E^2 I/3)``. (i) Electric part: alpha sees the local field
  ``E0 (e + d)`` with beta's induced-dipole field ``d = (e - 3 c xh)/(2 r^3)`` (``d_i = -(1/2) e_j
  d_i d_j (1/r)``), so ``dS_el = 9 pi eps a^3 E0^2 [e d + d e - (2/3)(e.d) I]``. (ii) Hydrodynamic part:
  alpha, rigid and force-free, in beta's stresslet flow ``u = -(9/8) U0 S:ee`` gains
  ``(20/3) pi eta a^3 E(x_alpha)`` with ``E`` the rate of strain (Faxén; the ``a^2 lap E`` correction is
  O(r^-5)). The sum is the formula above: traceless, symmetric in alpha <-> beta, zero on angular
  average. The field gradient at alpha gives no O(r^-4) term (a dipole-quadrupole product has no
  ``l = 2`` part), so the residual is O(r^-5).
* DEP force on alpha ``F_alpha = -3 pi eps a^2 E0^2 W / r^4`` (so that ``F/(6 pi eta a)`` is the DEP
  velocity ``-U0 W/(2 r^4)``), and its pair virial contribution to the bulk stress,
  ``-x F_alpha / V`` symmetrised: ``+3 pi eps a^3 E0^2 r^-3 sym(xh W) / V``.

References:
    Saintillan, D. (2008) "Nonlinear interactions in electrophoresis of ideally polarizable particles",
    Phys. Fluids 20, 067104. Park, J. S. & Saintillan, D. (2010) "Dipolophoresis in large-scale
    suspensions of ideally polarizable spheres", J. Fluid Mech. 662, 66-90. Mirfendereski, S. &
    Park, J. S. (2024) J. Fluid Mech., eqs 2.3-2.5. Kim, S. & Karrila, S. J. (1991) Microhydrodynamics,
    §2-4 (Faxén laws, stresslet). Batchelor, G. K. (1970) J. Fluid Mech. 41, 545 (bulk stress).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "MECHANISM_WEIGHTS",
    "MECHANISM_DEP",
    "MECHANISM_DIP",
    "MECHANISM_ICEP",
    "dep_pair_force",
    "dep_pair_virial",
    "far_field_functions",
    "icep_pair_stresslet",
    "mechanism_code",
    "mechanism_weights",
    "pair_velocity",
]

MECHANISM_DIP = 0
"""Mechanism code for dipolophoresis, ICEP + DEP (``far_field_functions``)."""
MECHANISM_ICEP = 1
"""Mechanism code for induced-charge electrophoresis alone."""
MECHANISM_DEP = 2
"""Mechanism code for dielectrophoresis alone."""

MECHANISM_WEIGHTS = {"dip": (1.0, 1.0), "icep": (1.0, 0.0), "dep": (0.0, 1.0)}
"""``mechanism name -> (icep_weight, dep_weight)``."""

_CODES = {"dip": MECHANISM_DIP, "icep": MECHANISM_ICEP, "dep": MECHANISM_DEP}

# Coefficients of the velocity kernels: U = A_S S:ee + A_T T:ee (units U0, lengths a).
ICEP_S_COEFFICIENT = -9.0 / 8.0
ICEP_T_COEFFICIENT = -11.0 / 24.0
DEP_T_COEFFICIENT = 1.0 / 12.0


def mechanism_weights(mechanism: str) -> tuple[float, float]:
    """``(icep_weight, dep_weight)`` for ``mechanism`` in ``{"dip", "icep", "dep"}``.

    Raises:
        ValueError: ``mechanism`` is not one of the three names.
    """
    if not isinstance(mechanism, str) or mechanism not in MECHANISM_WEIGHTS:
        raise ValueError(f"mechanism must be one of 'dip', 'icep', 'dep', got {mechanism!r}")
    return MECHANISM_WEIGHTS[mechanism]


def mechanism_code(mechanism: str) -> int:
    """Integer code (:data:`MECHANISM_DIP`, :data:`MECHANISM_ICEP`, :data:`MECHANISM_DEP`) of a name.

    Raises:
        ValueError: ``mechanism`` is not one of ``"dip"``, ``"icep"``, ``"dep"``.
    """
    mechanism_weights(mechanism)
    return _CODES[mechanism]


@njit(cache=True)
def pair_velocity(x: np.ndarray, e: np.ndarray, icep_weight: float, dep_weight: float) -> np.ndarray:
    """Far-field velocity of sphere alpha due to sphere beta in free space (units ``U0``).

    ``U = icep_weight [-(9/8) S:ee - (11/24) T:ee] + dep_weight (1/12) T:ee``
    ``  = icep_weight [-(9/8)(3c^2 - 1) xh/r^2 + (11/4) W/r^4] - dep_weight W/(2 r^4)``.

    Args:
        x: Separation ``x_alpha - x_beta``, shape ``(3,)``, float64 (units ``a``), non-zero.
        e: Unit field direction, shape ``(3,)``, float64.
        icep_weight: Weight of ICEP (0 or 1 for the mechanism switch).
        dep_weight: Weight of DEP (0 or 1).

    Returns:
        Velocity of alpha, shape ``(3,)``, float64 (units ``U0``). Beta's velocity is its negative.

    References:
        Saintillan (2008) Phys. Fluids 20, 067104; Mirfendereski & Park (2024) eqs 2.3-2.5.
    """
    r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2]
    r = math.sqrt(r2)
    c = (e[0] * x[0] + e[1] * x[1] + e[2] * x[2]) / r
    inv_r2 = 1.0 / r2
    inv_r4 = inv_r2 * inv_r2
    s_coef = icep_weight * ICEP_S_COEFFICIENT * (3.0 * c * c - 1.0) * inv_r2
    # T:ee = -6 W / r^4
    w_coef = -6.0 * (icep_weight * ICEP_T_COEFFICIENT + dep_weight * DEP_T_COEFFICIENT) * inv_r4
    out = np.empty(3)
    for i in range(3):
        xh = x[i] / r
        w = (5.0 * c * c - 1.0) * xh - 2.0 * c * e[i]
        out[i] = s_coef * xh + w_coef * w
    return out


@njit(cache=True)
def far_field_functions(r: float, mechanism_code: int) -> tuple[float, float, float]:
    """Scalar far-field functions ``(F_par, F_perp, F_x)`` of the isotropic velocity form (units ``U0``).

    ``U = (F_par cos^2 th + F_perp sin^2 th) xh + F_x sin(2 th) t`` (``docs/model.md#dipolophoresis``), with
    ICEP ``F_par = -9/(4r^2) + 11/(2r^4)``, ``F_perp = 9/(8r^2) - 11/(4r^4)``, ``F_x = -11/(4r^4)``;
    DEP ``F_par = -1/r^4``, ``F_perp = 1/(2r^4)``, ``F_x = 1/(2r^4)``; DIP is their sum.

    Args:
        r: Centre-to-centre distance (units ``a``), ``> 0``.
        mechanism_code: :data:`MECHANISM_DIP` (0), :data:`MECHANISM_ICEP` (1) or :data:`MECHANISM_DEP`
            (2); any other value raises ``ValueError``.

    Returns:
        ``(F_par, F_perp, F_x)`` (units ``U0``).

    References:
        Saintillan (2008); Park & Saintillan (2010) J. Fluid Mech. 662, 66.
    """
    if mechanism_code == MECHANISM_DIP:
        icep, dep = 1.0, 1.0
    elif mechanism_code == MECHANISM_ICEP:
        icep, dep = 1.0, 0.0
    elif mechanism_code == MECHANISM_DEP:
        icep, dep = 0.0, 1.0
    else:
        raise ValueError("mechanism_code must be 0 (dip), 1 (icep) or 2 (dep)")
    inv_r2 = 1.0 / (r * r)
    inv_r4 = inv_r2 * inv_r2
    f_par = icep * (-2.25 * inv_r2 + 5.5 * inv_r4) + dep * (-inv_r4)
    f_perp = icep * (1.125 * inv_r2 - 2.75 * inv_r4) + dep * (0.5 * inv_r4)
    f_x = icep * (-2.75 * inv_r4) + dep * (0.5 * inv_r4)
    return f_par, f_perp, f_x


@njit(cache=True)
def icep_pair_stresslet(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """O(r^-3) pair correction ``dS_alpha`` to the ICEP stresslet of alpha due to beta (free space).

    ``dS = pi r^-3 [9 ee - 36 c (e xh + xh e) + (225/2 c^2 - 45/2) xh xh + (9/2 - 27/2 c^2) I]``
    in units ``eps a^3 E0^2`` (module docstring for the derivation). Even in ``x``: beta gets the same.

    Args:
        x: Separation ``x_alpha - x_beta``, shape ``(3,)``, float64 (units ``a``), non-zero.
        e: Unit field direction, shape ``(3,)``, float64.

    Returns:
        ``dS_alpha``, shape ``(3, 3)``, float64 (units ``eps a^3 E0^2``), symmetric and traceless.

    References:
        ``docs/model.md#dipolophoresis``; Kim & Karrila (1991) §2 (Faxén stresslet); Batchelor (1970).
    """
    r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    xh = x / r
    c = e[0] * xh[0] + e[1] * xh[1] + e[2] * xh[2]
    pref = math.pi / (r * r * r)
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(i, 3):
            v = (
                9.0 * e[i] * e[j]
                - 36.0 * c * (e[i] * xh[j] + xh[i] * e[j])
                + (112.5 * c * c - 22.5) * xh[i] * xh[j]
            )
            if i == j:
                v += 4.5 - 13.5 * c * c
            out[i, j] = pref * v
            out[j, i] = pref * v
    return out


@njit(cache=True)
def dep_pair_force(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Far-field DEP force on alpha due to beta, ``F_alpha = -3 pi W / r^4`` (units ``eps a^2 E0^2``).

    Args:
        x: Separation ``x_alpha - x_beta``, shape ``(3,)``, float64 (units ``a``), non-zero.
        e: Unit field direction, shape ``(3,)``, float64.

    Returns:
        Force on alpha, shape ``(3,)``, float64 (units ``eps a^2 E0^2``); beta feels its negative.

    References:
        Saintillan (2008); ``docs/model.md#dipolophoresis`` "DEP force virial".
    """
    r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    c = (e[0] * x[0] + e[1] * x[1] + e[2] * x[2]) / r
    pref = -3.0 * math.pi / (r * r * r * r)
    out = np.empty(3)
    for i in range(3):
        out[i] = pref * ((5.0 * c * c - 1.0) * x[i] / r - 2.0 * c * e[i])
    return out


@njit(cache=True)
def dep_pair_virial(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Symmetrised pair virial ``-sym(x F_alpha)`` of the far-field DEP force (units ``eps a^3 E0^2``).

    ``-sym(x F_alpha) = 3 pi r^-3 sym(xh W)``; divide by the volume ``V`` for the bulk stress of the pair
    (each pair counted once).

    Args:
        x: Separation ``x_alpha - x_beta``, shape ``(3,)``, float64 (units ``a``), non-zero.
        e: Unit field direction, shape ``(3,)``, float64.

    Returns:
        Shape ``(3, 3)``, float64, symmetric (units ``eps a^3 E0^2``).

    References:
        Batchelor (1970) J. Fluid Mech. 41, 545; ``docs/model.md#dipolophoresis``.
    """
    f = dep_pair_force(x, e)
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(i, 3):
            out[i, j] = -0.5 * (x[i] * f[j] + x[j] * f[i])
            out[j, i] = out[i, j]
    return out
