"""Two-sphere resistance scalars for equal spheres and the model's pairwise lubrication functions.

Units: sphere radius ``a = 1``, viscosity ``eta = 1``. For a pair at centre distance ``r`` the
dimensionless distance is ``s = r/a`` and the surface gap is ``xi = s - 2``.

Every function returns the 22 scalars of Kim & Karrila (1991, section 11.3) for equal spheres in
the order of :data:`SCALAR_NAMES` (``"11"`` = self term, ``"12"`` = pair term). The dimensional
resistance is the scalar times ``6 pi`` (A), ``4 pi`` (B, G), ``8 pi`` (C, H) or ``(20/3) pi`` (M);
for equal spheres this scaling coincides with that of Jeffrey & Onishi (1984) and Jeffrey (1992).
The tensor forms, sign conventions and equal-sphere label rules are those of
``resistance_functions.md`` section 1; ``tests/dense_reference.py`` assembles them.

Three sets of scalars are provided:

* :func:`near_field_scalars` -- the full near-contact asymptotics (singular terms, O(1) constants
  and ``xi log(1/xi)`` terms) of Jeffrey & Onishi (1984) and Jeffrey (1992) as corrected by
  Townsend (2023). They reproduce the exact values to about 1e-7 for ``xi <= 0.02``; at
  ``xi = 0.025`` they are within 0.01 absolute (0.1 % for X^A, X^G, X^M) and they degrade quickly
  beyond ``xi ~ 0.1``.
* :func:`far_field_scalars` -- the far-field reflection series in ``1/s`` (Jeffrey & Onishi 1984;
  Jeffrey 1992; Townsend 2023), accurate to 1e-4 at ``s = 4`` and 1.3 % at ``s = 3``.
* :func:`lubrication_scalars` -- **the functions the simulation uses**, described next.

The lubrication model
---------------------
The grand resistance tensor is ``R = R_drag + R_lub`` (Mari, Seto, Morris & Denn 2014): the
isolated-sphere Stokes drag (``6 pi``, ``8 pi`` and ``(20/3) pi`` times the identity) on the
diagonal, plus a sum over close pairs of two-sphere lubrication matrices. Following Mari et al.
(and their code LF_DEM) only the divergent parts of the near-contact asymptotics are kept: the
coefficient of ``1/xi`` and of ``log(1/xi)`` of every function. The O(1) constants and the
``xi log(1/xi)`` terms are dropped, for a reason of positivity:

* With the constants, the pair matrix ``R2B - R_drag`` (near-contact forms, isolated values
  subtracted from the self functions) is *not* positive semi-definite. In the collective
  translation mode along the line of centres it has the eigenvalue
  ``6 pi (X11A - 1 + X12A) = 6 pi (0.99541917 - 1 - 0.35015349) ~= -0.355 * 6 pi eta a``
  per pair (the transverse analogue is ``-0.275 * 6 pi``). A particle in a dense cluster with
  about three or more such pairs therefore loses more than its own Stokes drag in that mode and
  ``R_FU`` becomes indefinite: the velocity solve breaks down.
* The singular parts alone form a positive semi-definite pair matrix for every gap (its squeeze
  part is ``(1/4)(1/xi) (U1 - U2).n n`` and the log parts are a quadratic form in the relative
  motion); ``tests/test_resistance_functions.py`` verifies this numerically. Sums of positive
  semi-definite pair matrices plus the positive-definite drag are positive definite.

Each retained singular function is evaluated with a regularised gap ``xi + delta`` (``delta > 0``
keeps the resistance finite at contact, where the short-range repulsion takes over; Mari et al.
2014 use the same device) and switched off smoothly between ``xi_cut/2`` and the cut-off ``xi_cut``::

    f(xi) = w(xi) [c1 / (xi + delta) + cL log(1/(xi + delta))],
    w = 1 for xi <= xi_cut/2;  w = 0 for xi >= xi_cut;
    w = 1 - 3t^2 + 2t^3 with t = (xi - xi_cut/2)/(xi_cut/2) in between.

Below ``xi_cut/2`` the singular terms are unshifted, so the near-contact resistance differs from the
exact two-sphere value only by the dropped O(1) constants. (An earlier version shifted every function by
its value at the cut-off instead; that removed about ``0.66 * 6 pi`` from every squeeze resistance and
lowered eta_r at phi = 0.45 by 12 %.) Because ``w`` is C1 and vanishes at ``xi_cut`` the lubrication
force and stresslet have no jump when a pair enters or leaves the neighbour list. With
``xi_cut + delta < 1`` both ``1/(xi + delta)`` and ``log(1/(xi + delta))`` are positive, so each pair
matrix is ``w`` times a non-negative combination of positive semi-definite matrices and stays positive
semi-definite.

References:
    Jeffrey, D. J. & Onishi, Y. (1984) J. Fluid Mech. 139, 261-290 (X^A, Y^A, Y^B, X^C, Y^C).
    Jeffrey, D. J. (1992) Phys. Fluids A 4, 16-29 (X^G, Y^G, Y^H, X^M, Y^M, Z^M).
    Kim, S. & Karrila, S. J. (1991) Microhydrodynamics, section 11.3 (tensor forms and scaling).
    Townsend, A. K. (2023) Phys. Fluids 35, 127126 (corrected near-contact expressions and
    exact tabulated values, repository Pecnut/stokesian-dynamics).
    Mari, R., Seto, R., Morris, J. F. & Denn, M. M. (2014) J. Rheol. 58, 1693-1724
    (Stokes drag + pairwise lubrication model, singular terms only, regularised gap).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

SCALAR_NAMES: tuple[str, ...] = (
    "XA11", "XA12", "YA11", "YA12", "YB11", "YB12", "XC11", "XC12", "YC11", "YC12", "XG11",
    "XG12", "YG11", "YG12", "YH11", "YH12", "XM11", "XM12", "YM11", "YM12", "ZM11", "ZM12",
)  # fmt: skip
"""Order of the 22 equal-sphere scalars in every array this module returns."""

NUMBER_OF_SCALARS = 22

I_XA11 = 0
I_XA12 = 1
I_YA11 = 2
I_YA12 = 3
I_YB11 = 4
I_YB12 = 5
I_XC11 = 6
I_XC12 = 7
I_YC11 = 8
I_YC12 = 9
I_XG11 = 10
I_XG12 = 11
I_YG11 = 12
I_YG12 = 13
I_YH11 = 14
I_YH12 = 15
I_XM11 = 16
I_XM12 = 17
I_YM11 = 18
I_YM12 = 19
I_ZM11 = 20
I_ZM12 = 21

# Lubrication acts for surface gaps xi = r/a - 2 below this cut-off (0.5 a, as in Mari et al. 2014;
# beyond xi ~ 0.5 the singular terms no longer describe the exact functions, resistance_functions.md
# section 4).
DEFAULT_LUBRICATION_CUTOFF = 0.5

# Gap regularisation delta (units a): xi -> xi + delta bounds the squeeze resistance by 1/(4 delta)
# (in units of 6 pi eta a). 1e-3 as in Mari et al. (2014) (and the default "roughness length" of their
# LF_DEM code). The paper does not state its value, and the sheared-dipolophoresis results depend on it:
# with 1e-4 a weak field (Mn >= 5) raised eta_r by 35-55% above pure shear at phi = 0.45 and turned N1
# positive, because a touching pair is separated by shear only at ~ delta gammadot while the
# (unlubricated) dipolophoretic velocity closes it at a finite speed; with 1e-3 the paper's collapse
# onto pure shear and negative N1 come back (results/delta_dependence/). Pure shear at phi = 0.45
# (N = 100, strain 20): eta_r = 10.28 (1e-3) against 10.88 (1e-4) and 11.99 (1e-5, strain 3-8);
# Maron-Pierce gives 12.25. Below xi ~ delta the short-range repulsion (sigma = 1e-3) keeps surfaces
# apart.
DEFAULT_LUBRICATION_REGULARISATION = 1.0e-3

# Singular coefficients of the near-contact forms (resistance_functions.md section 2):
# column 0 multiplies 1/xi, column 1 multiplies log(1/xi). Rows in SCALAR_NAMES order.
_SINGULAR_COEFFICIENTS = np.array(
    [
        [1.0 / 4.0, 9.0 / 40.0],  # XA11
        [-1.0 / 4.0, -9.0 / 40.0],  # XA12
        [0.0, 1.0 / 6.0],  # YA11
        [0.0, -1.0 / 6.0],  # YA12
        [0.0, -1.0 / 4.0],  # YB11
        [0.0, 1.0 / 4.0],  # YB12
        [0.0, 0.0],  # XC11
        [0.0, 0.0],  # XC12
        [0.0, 1.0 / 5.0],  # YC11
        [0.0, 1.0 / 20.0],  # YC12
        [3.0 / 8.0, 27.0 / 80.0],  # XG11
        [-3.0 / 8.0, -27.0 / 80.0],  # XG12
        [0.0, 1.0 / 8.0],  # YG11
        [0.0, -1.0 / 8.0],  # YG12
        [0.0, 1.0 / 40.0],  # YH11
        [0.0, 1.0 / 10.0],  # YH12
        [3.0 / 20.0, 27.0 / 200.0],  # XM11
        [3.0 / 20.0, 27.0 / 200.0],  # XM12
        [0.0, 3.0 / 25.0],  # YM11
        [0.0, 3.0 / 100.0],  # YM12
        [0.0, 0.0],  # ZM11
        [0.0, 0.0],  # ZM12
    ],
    dtype=np.float64,
)


@njit(cache=True)
def near_field_scalars(xi: float) -> np.ndarray:
    """Full near-contact resistance scalars of two equal spheres (K&K scaling).

    With ``L = log(1/xi)`` (for example, the others follow resistance_functions.md section 2)::

        XA11 =  1/(4 xi) + 9/40 L + 0.99541917 + 3/112 xi L
        XA12 = -1/(4 xi) - 9/40 L - 0.35015349 - 3/112 xi L
        YA11 =  1/6 L + 0.99831711
        YB11 = -1/4 L + 0.23891957 - 1/8 xi L
        XC11 =  1.05179979 - 1/8 xi L                  (7/8 zeta(3) - ...)
        XG11 =  3/(8 xi) + 27/80 L - 0.46921067 + 117/560 xi L
        XM11 =  3/(20 xi) + 27/200 L + 0.71680011 + 353/2800 xi L
        ZM11 =  1.02509700 - 3/40 xi L

    The self functions XA11, YA11, XC11, YC11, XM11, YM11, ZM11 include the isolated-sphere
    value (they tend to 1 far apart); these forms are not the model's lubrication functions
    (see :func:`lubrication_scalars`).

    Args:
        xi: Dimensionless surface gap ``r/a - 2``; must be > 0. Accurate to about 1e-7
            relative for ``xi <= 0.02``; at ``xi = 0.025`` within 0.01 absolute (0.1 % for
            X^A, X^G, X^M; the small YH11, ZM12 and XC12 are off by 4 %, 2 % and 0.6 %).

    Returns:
        float64 array of shape (22,), the scalars in :data:`SCALAR_NAMES` order.

    References:
        Jeffrey & Onishi (1984) J. Fluid Mech. 139, 261 (near-contact forms of X^A, Y^A, Y^B,
        X^C, Y^C); Jeffrey (1992) Phys. Fluids A 4, 16 (X^G, Y^G, Y^H, X^M, Y^M, Z^M); both as
        corrected by Townsend (2023) Phys. Fluids 35, 127126; rationals and constants for
        lambda = 1 as listed in resistance_functions.md section 2.
    """
    lg = math.log(1.0 / xi)
    xl = xi * lg
    out = np.empty(22, dtype=np.float64)
    out[0] = 1.0 / (4.0 * xi) + 9.0 / 40.0 * lg + 0.99541917 + 3.0 / 112.0 * xl  # XA11
    out[1] = -1.0 / (4.0 * xi) - 9.0 / 40.0 * lg - 0.35015349 - 3.0 / 112.0 * xl  # XA12
    out[2] = 1.0 / 6.0 * lg + 0.99831711  # YA11
    out[3] = -1.0 / 6.0 * lg - 0.27365201  # YA12
    out[4] = -1.0 / 4.0 * lg + 0.23891957 - 1.0 / 8.0 * xl  # YB11
    out[5] = 1.0 / 4.0 * lg - 0.00162268 + 1.0 / 8.0 * xl  # YB12
    out[6] = 1.05179979 - 1.0 / 8.0 * xl  # XC11
    out[7] = -0.15025711 + 1.0 / 8.0 * xl  # XC12
    out[8] = 1.0 / 5.0 * lg + 0.70283422 + 47.0 / 250.0 * xl  # YC11
    out[9] = 1.0 / 20.0 * lg - 0.02746397 + 31.0 / 500.0 * xl  # YC12
    out[10] = 3.0 / (8.0 * xi) + 27.0 / 80.0 * lg - 0.46921067 + 117.0 / 560.0 * xl  # XG11
    out[11] = -3.0 / (8.0 * xi) - 27.0 / 80.0 * lg + 0.19550806 - 117.0 / 560.0 * xl  # XG12
    out[12] = 1.0 / 8.0 * lg - 0.14115738 + 1.0 / 16.0 * xl  # YG11
    out[13] = -1.0 / 8.0 * lg + 0.10250060 - 1.0 / 16.0 * xl  # YG12
    out[14] = 1.0 / 40.0 * lg - 0.07401157 + 137.0 / 2000.0 * xl  # YH11
    out[15] = 1.0 / 10.0 * lg - 0.02929029 + 113.0 / 2000.0 * xl  # YH12
    out[16] = 3.0 / (20.0 * xi) + 27.0 / 200.0 * lg + 0.71680011 + 353.0 / 2800.0 * xl  # XM11
    out[17] = 3.0 / (20.0 * xi) + 27.0 / 200.0 * lg - 0.14542416 + 493.0 / 2800.0 * xl  # XM12
    out[18] = 3.0 / 25.0 * lg + 0.88467122 + 57.0 / 2500.0 * xl  # YM11
    out[19] = 3.0 / 100.0 * lg - 0.20758133 + 333.0 / 2500.0 * xl  # YM12
    out[20] = 1.02509700 - 3.0 / 40.0 * xl  # ZM11
    out[21] = -0.07231066 + 3.0 / 40.0 * xl  # ZM12
    return out


@njit(cache=True)
def far_field_scalars(s: float) -> np.ndarray:
    """Far-field series of the two-sphere resistance scalars of equal spheres (K&K scaling).

    Series in ``t = 1/s`` truncated at ``t^12`` as in resistance_functions.md section 3, e.g.::

        XA11 = 1 + 9/4 t^2 + 93/16 t^4 + 1197/64 t^6 + 19821/256 t^8 + ... + 4918189/4096 t^12
        XA12 = -(3/2 t + 19/8 t^3 + 387/32 t^5 + ... + 1178451/2048 t^11)
        XG12 = -(15/4 t^2 + 39/16 t^4 + ...),    ZM12 = -2 t^5

    For X^C only the leading terms are used, ``XC11 = 1 + t^6`` and ``XC12 = -t^3`` (rotlet
    coupling and its first reflection; the higher terms are not included).

    Args:
        s: Centre distance over radius ``r/a``; accurate to 1e-4 absolute for ``s >= 4`` and
            to 1.3 % at ``s = 3`` (worst XG11 and YG11; the others <= 0.8 %).

    Returns:
        float64 array of shape (22,), the scalars in :data:`SCALAR_NAMES` order.

    References:
        Jeffrey & Onishi (1984) J. Fluid Mech. 139, 261 and Jeffrey (1992) Phys. Fluids A 4, 16
        (far-field reflection series and their recurrence relations); lambda = 1 coefficients as
        evaluated with Townsend (2023) Phys. Fluids 35, 127126 (resistance_functions.md section 3).
    """
    t = 1.0 / s
    t2 = t * t
    t3 = t2 * t
    t4 = t2 * t2
    t5 = t4 * t
    t6 = t3 * t3
    t7 = t6 * t
    t8 = t4 * t4
    t9 = t8 * t
    t10 = t5 * t5
    t11 = t10 * t
    t12 = t6 * t6
    out = np.empty(22, dtype=np.float64)
    out[0] = (
        1.0 + 9.0 / 4.0 * t2 + 93.0 / 16.0 * t4 + 1197.0 / 64.0 * t6 + 19821.0 / 256.0 * t8
        + 320173.0 / 1024.0 * t10 + 4918189.0 / 4096.0 * t12
    )  # fmt: skip  # XA11
    out[1] = -(
        3.0 / 2.0 * t + 19.0 / 8.0 * t3 + 387.0 / 32.0 * t5 + 5331.0 / 128.0 * t7
        + 76115.0 / 512.0 * t9 + 1178451.0 / 2048.0 * t11
    )  # fmt: skip  # XA12
    out[2] = (
        1.0 + 9.0 / 16.0 * t2 + 465.0 / 256.0 * t4 + 14745.0 / 4096.0 * t6
        + 570017.0 / 65536.0 * t8 + 33678825.0 / 1048576.0 * t10
    )  # fmt: skip  # YA11
    out[3] = -(
        3.0 / 4.0 * t + 59.0 / 64.0 * t3 + 2259.0 / 1024.0 * t5 + 89643.0 / 16384.0 * t7
        + 4451395.0 / 262144.0 * t9 + 266862875.0 / 4194304.0 * t11
    )  # fmt: skip  # YA12
    out[4] = -(
        9.0 / 8.0 * t3 + 273.0 / 128.0 * t5 + 17625.0 / 2048.0 * t7 + 1017825.0 / 32768.0 * t9
        + 47478057.0 / 524288.0 * t11
    )  # fmt: skip  # YB11
    out[5] = (
        3.0 / 2.0 * t2 + 27.0 / 32.0 * t4 + 1683.0 / 512.0 * t6 + 129003.0 / 8192.0 * t8
        + 7087107.0 / 131072.0 * t10 + 336619227.0 / 2097152.0 * t12
    )  # fmt: skip  # YB12
    out[6] = 1.0 + t6  # XC11 (leading terms only)
    out[7] = -t3  # XC12 (leading term only)
    out[8] = (
        1.0 + 3.0 / 4.0 * t4 + 283.0 / 64.0 * t6 + 11955.0 / 1024.0 * t8 + 511755.0 / 16384.0 * t10
        + 28793891.0 / 262144.0 * t12
    )  # fmt: skip  # YC11
    out[9] = (
        1.0 / 2.0 * t3 + 9.0 / 16.0 * t5 + 369.0 / 256.0 * t7 + 5945.0 / 4096.0 * t9
        + 448833.0 / 65536.0 * t11
    )  # fmt: skip  # YC12
    out[10] = (
        45.0 / 8.0 * t3 + 597.0 / 32.0 * t5 + 6021.0 / 128.0 * t7 + 101205.0 / 512.0 * t9
        + 1886037.0 / 2048.0 * t11
    )  # fmt: skip  # XG11
    out[11] = -(
        15.0 / 4.0 * t2 + 39.0 / 16.0 * t4 + 2331.0 / 64.0 * t6 + 34347.0 / 256.0 * t8
        + 458859.0 / 1024.0 * t10 + 6614187.0 / 4096.0 * t12
    )  # fmt: skip  # XG12
    out[12] = 27.0 / 8.0 * t5 + 531.0 / 128.0 * t7 + 2475.0 / 2048.0 * t9 + 936387.0 / 32768.0 * t11  # YG11
    out[13] = -(
        2.0 * t4 + 81.0 / 32.0 * t6 + 1305.0 / 512.0 * t8 + 81697.0 / 8192.0 * t10
        + 10661481.0 / 131072.0 * t12
    )  # fmt: skip  # YG12
    out[14] = -3.0 / 2.0 * t6 + 81.0 / 64.0 * t8 + 14969.0 / 1024.0 * t10 + 467073.0 / 16384.0 * t12  # YH11
    out[15] = 5.0 / 4.0 * t3 + 27.0 / 16.0 * t7 + 3539.0 / 256.0 * t9 + 196299.0 / 4096.0 * t11  # YH12
    out[16] = (
        1.0 + 15.0 / 4.0 * t4 + 343.0 / 16.0 * t6 + 12207.0 / 320.0 * t8 + 117183.0 / 1280.0 * t10
        + 3045631.0 / 5120.0 * t12
    )  # fmt: skip  # XM11
    out[17] = (
        5.0 * t3 - 51.0 / 8.0 * t5 + 909.0 / 32.0 * t7 + 82001.0 / 640.0 * t9 + 1092033.0 / 2560.0 * t11
    )  # fmt: skip  # XM12
    out[18] = 1.0 + 10.0 * t6 + 41.0 / 5.0 * t8 - 2631.0 / 80.0 * t10 - 4435.0 / 256.0 * t12  # YM11
    out[19] = -5.0 / 2.0 * t3 + 8.0 * t5 - 241.0 / 10.0 * t9 - 20021.0 / 320.0 * t11  # YM12
    out[20] = 1.0 + 25.0 / 8.0 * t8 + 3.0 * t10 - 21.0 / 4.0 * t12  # ZM11
    out[21] = -2.0 * t5  # ZM12
    return out


@njit(cache=True)
def lubrication_scalars(xi: float, xi_cut: float, delta: float) -> np.ndarray:
    """Pairwise lubrication scalars of the model: singular terms, regularised, tapered to 0 at cut-off.

    For each of the 22 scalars, with ``(c1, cL)`` the coefficients of ``1/xi`` and ``log(1/xi)``
    in its near-contact form (:func:`near_field_scalars`) and ``w`` the taper of
    :func:`lubrication_taper`::

        f(xi) = w(xi) [c1 / (xi + delta) + cL log(1/(xi + delta))]   for xi < xi_cut,
        f(xi) = 0                                                    for xi >= xi_cut.

    ``(c1, cL)``: XA11 (1/4, 9/40), XA12 (-1/4, -9/40), YA11 (0, 1/6), YA12 (0, -1/6),
    YB11 (0, -1/4), YB12 (0, 1/4), YC11 (0, 1/5), YC12 (0, 1/20), XG11 (3/8, 27/80),
    XG12 (-3/8, -27/80), YG11 (0, 1/8), YG12 (0, -1/8), YH11 (0, 1/40), YH12 (0, 1/10),
    XM11 (3/20, 27/200), XM12 (3/20, 27/200), YM11 (0, 3/25), YM12 (0, 3/100);
    XC11, XC12, ZM11, ZM12 have no singular part and are identically 0.

    The values contain no isolated-sphere part: the self functions are added to the Stokes drag
    on the diagonal of the grand resistance tensor, not in place of it. The constants of the
    near-contact forms are dropped on purpose (see the module docstring: with them the pair
    matrix has a negative eigenvalue of about -0.355 * 6 pi per pair).

    Args:
        xi: Surface gap ``r/a - 2``. The caller guarantees ``xi + delta > 0`` (overlapping
            pairs are clamped before the call); this is not checked here.
        xi_cut: Cut-off gap; the functions vanish (C1-continuously) for ``xi >= xi_cut``. Requires
            ``xi_cut + delta < 1`` so that the log terms stay positive (the configuration checks it).
        delta: Gap regularisation (>= 0); ``delta = 0`` gives the unregularised singular terms.

    Returns:
        float64 array of shape (22,), the scalars in :data:`SCALAR_NAMES` order.

    References:
        Mari, Seto, Morris & Denn (2014) J. Rheol. 58, 1693 (singular lubrication terms,
        regularised gap, Stokes drag + lubrication model); coefficients from Jeffrey & Onishi (1984)
        and Jeffrey (1992) as corrected by Townsend (2023) Phys. Fluids 35, 127126.
    """
    out = np.zeros(22, dtype=np.float64)
    if xi >= xi_cut:
        return out
    taper = lubrication_taper(xi, xi_cut)
    inverse_term = taper / (xi + delta)
    log_term = taper * math.log(1.0 / (xi + delta))
    for k in range(22):
        out[k] = _SINGULAR_COEFFICIENTS[k, 0] * inverse_term + _SINGULAR_COEFFICIENTS[k, 1] * log_term
    return out


@njit(cache=True)
def lubrication_taper(xi: float, xi_cut: float) -> float:
    """Smooth switch-off of the lubrication functions: 1 for ``xi <= xi_cut/2``, 0 for ``xi >= xi_cut``.

    ``w = 1 - 3 t^2 + 2 t^3`` with ``t = (xi - xi_cut/2) / (xi_cut/2)`` (C1-continuous smoothstep). A
    positive multiple of a positive semi-definite pair matrix stays positive semi-definite.
    """
    half = 0.5 * xi_cut
    if xi <= half:
        return 1.0
    if xi >= xi_cut:
        return 0.0
    t = (xi - half) / half
    return 1.0 - t * t * (3.0 - 2.0 * t)


def scalars_as_dict(values: np.ndarray) -> dict[str, float]:
    """Label an array of 22 resistance scalars with their names.

    Args:
        values: float64 array of shape (22,) in :data:`SCALAR_NAMES` order.

    Returns:
        Mapping from each name in :data:`SCALAR_NAMES` to its value as a Python float.

    Raises:
        ValueError: If ``values`` does not hold exactly 22 entries.
    """
    flat = np.asarray(values, dtype=np.float64).reshape(-1)
    if flat.shape[0] != NUMBER_OF_SCALARS:
        raise ValueError(f"values must hold {NUMBER_OF_SCALARS} scalars, got {flat.shape[0]}")
    return {name: float(value) for name, value in zip(SCALAR_NAMES, flat, strict=True)}
