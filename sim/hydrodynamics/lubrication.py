"""Pairwise lubrication: two-sphere resistance blocks, strain forcing and pair stresslets.

For a pair (i, j) with unit vector ``d = (x_j - x_i)/|x_j - x_i|`` (from i, label 1, to j, label 2) the
two-sphere resistance tensors of equal spheres are (Jeffrey & Onishi 1984; Jeffrey 1992; Kim & Karrila
1991 §11.3; conventions in ``shared/resistance_functions.md`` §1)::

    A_kl  = XA d_k d_l + YA (delta_kl - d_k d_l)                       (scale 6 pi)
    B_kl  = YB eps_klm d_m                                             (scale 4 pi)
    C_kl  = XC d_k d_l + YC (delta_kl - d_k d_l)                       (scale 8 pi)
    G_klm = XG (d_k d_l - delta_kl/3) d_m
            + YG (d_k delta_lm + d_l delta_km - 2 d_k d_l d_m)         (scale 4 pi)
    H_klm = YH (eps_kmn d_n d_l + eps_lmn d_n d_k)                     (scale 8 pi)
    M     = XM, YM, ZM forms of resistance_functions.md                (scale (20/3) pi)

with the equal-sphere label rules A22 = A11, A21 = A12 (C, M, H likewise), B22 = -B11, B21 = -B12,
G22 = -G11, G21 = -G12 (same ``d``). The hydrodynamic force, torque and stresslet on each particle are::

    F_a = -sum_b [6pi A^ab U'_b + 4pi Bt^ab Omega'_b] + sum_b 4pi Gt^ab : E
    T_a = -sum_b [4pi B^ab U'_b + 8pi C^ab Omega'_b] + sum_b 8pi Ht^ab : E
    S_a = -sum_b [4pi G^ab U'_b + 8pi H^ab Omega'_b] + sum_b (20/3)pi M^ab : E

(``U' = U - u_inf(x)``, ``Omega' = Omega - omega_inf``, ``Bt^ab_kl = B^ba_lk``, ``Gt^ab_klm = G^ba_lmk``).
The scalars come from :func:`sim.hydrodynamics.resistance_functions.lubrication_scalars` (the model's
regularised singular parts, without the isolated-sphere part, which :mod:`stokes_drag` supplies).

Contractions used below (``E`` symmetric and traceless, ``e = E.d``, ``q = d.E.d``)::

    G_lmk E_lm = XG q d_k + 2 YG (e_k - q d_k)            (force from strain, per G block)
    H_lmk E_lm = 2 YH (d x e)_k                            (torque from strain, per H block)
    G_klm U_m  = XG (d_k d_l - delta_kl/3)(d.U) + YG (d_k U_l + d_l U_k - 2 d_k d_l (d.U))
    H_klm W_m  = YH ((W x d)_k d_l + (W x d)_l d_k)
    M_klmn E_mn = (3/2) XM (d_k d_l - delta_kl/3) q + YM (d_k e_l + d_l e_k - 2 d_k d_l q)
                + (1/2) ZM (2 E_kl + delta_kl q + d_k d_l q - 2 d_k e_l - 2 d_l e_k)

(with XM = YM = ZM = 1 the last line is the identity on E, the isolated-sphere limit.)

Units: a = eta = 1; forces in eta a^2 gammadot-units of velocity, stresslets in eta a^3 per unit rate.

References:
    Jeffrey, D. J. & Onishi, Y. (1984) J. Fluid Mech. 139, 261-290.
    Jeffrey, D. J. (1992) Phys. Fluids A 4, 16-29.
    Townsend, A. K. (2023) Phys. Fluids 35, 127126 (corrected coefficients).
    Mari, R., Seto, R., Morris, J. F. & Denn, M. M. (2014) J. Rheol. 58, 1693-1724.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.hydrodynamics.resistance_functions import (
    I_XA11,
    I_XA12,
    I_XC11,
    I_XC12,
    I_XG11,
    I_XG12,
    I_XM11,
    I_XM12,
    I_YA11,
    I_YA12,
    I_YB11,
    I_YB12,
    I_YC11,
    I_YC12,
    I_YG11,
    I_YG12,
    I_YH11,
    I_YH12,
    I_YM11,
    I_YM12,
    I_ZM11,
    I_ZM12,
    lubrication_scalars,
)

_PI = math.pi
N_SCALARS = 22


@njit(cache=True)
def pair_scalars(
    pairs: np.ndarray, separations: np.ndarray, xi_cut: float, delta: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lubrication scalars, unit vectors and gaps of every listed pair.

    Args:
        pairs: (M, 2) int64 particle indices (i, j).
        separations: (M, 3) float64 minimum-image ``x_j - x_i`` (units a).
        xi_cut: lubrication cut-off gap (units a); scalars vanish for ``xi >= xi_cut``.
        delta: gap regularisation (units a), ``xi -> xi + delta``.

    Returns:
        scalars (M, 22) in ``SCALAR_NAMES`` order, unit vectors d (M, 3), gaps xi (M,).
    """
    m = pairs.shape[0]
    scalars = np.zeros((m, N_SCALARS))
    units = np.empty((m, 3))
    gaps = np.empty(m)
    for k in range(m):
        r = math.sqrt(separations[k, 0] ** 2 + separations[k, 1] ** 2 + separations[k, 2] ** 2)
        for c in range(3):
            units[k, c] = separations[k, c] / r
        xi = r - 2.0
        gaps[k] = xi
        if xi < xi_cut:
            scalars[k, :] = lubrication_scalars(xi, xi_cut, delta)
    return scalars, units, gaps


@njit(cache=True)
def _fill_fu_blocks(d: np.ndarray, sc: np.ndarray, diag_i: np.ndarray, diag_j: np.ndarray, off: np.ndarray):
    """Accumulate the 6x6 R_FU blocks of one pair (rows/cols ordered U, Omega).

    ``diag_i += [[A11, -B11], [B11, C11]]``, ``diag_j += [[A11, B11], [-B11, C11]]`` and
    ``off = [[A12, B12], [B12, C12]]`` (the (i, j) block; the (j, i) block is its transpose), each with
    its 6pi / 4pi / 8pi scale. ``B`` is antisymmetric, so ``Bt^11 = -B^11`` and ``Bt^12 = B^21^T = B^12``.
    """
    xa11 = 6.0 * _PI * sc[I_XA11]
    ya11 = 6.0 * _PI * sc[I_YA11]
    xa12 = 6.0 * _PI * sc[I_XA12]
    ya12 = 6.0 * _PI * sc[I_YA12]
    xc11 = 8.0 * _PI * sc[I_XC11]
    yc11 = 8.0 * _PI * sc[I_YC11]
    xc12 = 8.0 * _PI * sc[I_XC12]
    yc12 = 8.0 * _PI * sc[I_YC12]
    yb11 = 4.0 * _PI * sc[I_YB11]
    yb12 = 4.0 * _PI * sc[I_YB12]
    # eps_klm d_m
    ed = np.empty((3, 3))
    ed[0, 0] = 0.0
    ed[0, 1] = d[2]
    ed[0, 2] = -d[1]
    ed[1, 0] = -d[2]
    ed[1, 1] = 0.0
    ed[1, 2] = d[0]
    ed[2, 0] = d[1]
    ed[2, 1] = -d[0]
    ed[2, 2] = 0.0
    for k in range(3):
        for m in range(3):
            dd = d[k] * d[m]
            iso = 1.0 if k == m else 0.0
            a11 = xa11 * dd + ya11 * (iso - dd)
            a12 = xa12 * dd + ya12 * (iso - dd)
            c11 = xc11 * dd + yc11 * (iso - dd)
            c12 = xc12 * dd + yc12 * (iso - dd)
            b11 = yb11 * ed[k, m]
            b12 = yb12 * ed[k, m]
            diag_i[k, m] += a11
            diag_i[k, 3 + m] -= b11
            diag_i[3 + k, m] += b11
            diag_i[3 + k, 3 + m] += c11
            diag_j[k, m] += a11
            diag_j[k, 3 + m] += b11
            diag_j[3 + k, m] -= b11
            diag_j[3 + k, 3 + m] += c11
            off[k, m] = a12
            off[k, 3 + m] = b12
            off[3 + k, m] = b12
            off[3 + k, 3 + m] = c12


@njit(cache=True)
def assemble_resistance(
    n_particles: int,
    pairs: np.ndarray,
    units: np.ndarray,
    scalars: np.ndarray,
    force_drag: float,
    torque_drag: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Block-sparse R_FU = Stokes drag + pairwise lubrication.

    Args:
        n_particles: N.
        pairs: (M, 2) int64 pair indices.
        units: (M, 3) unit vectors ``d`` from i to j.
        scalars: (M, 22) lubrication scalars.
        force_drag, torque_drag: isolated-sphere resistances (6 pi, 8 pi in simulation units).

    Returns:
        diag (N, 6, 6) diagonal blocks and off (M, 6, 6) blocks R_FU[i, j] (R_FU[j, i] = off^T).
    """
    m = pairs.shape[0]
    diag = np.zeros((n_particles, 6, 6))
    off = np.empty((m, 6, 6))
    for p in range(n_particles):
        for c in range(3):
            diag[p, c, c] = force_drag
            diag[p, 3 + c, 3 + c] = torque_drag
    for k in range(m):
        i = pairs[k, 0]
        j = pairs[k, 1]
        _fill_fu_blocks(units[k], scalars[k], diag[i], diag[j], off[k])
    return diag, off


@njit(cache=True)
def _strain_vectors(d: np.ndarray, strain_rate: np.ndarray) -> tuple[np.ndarray, float]:
    """``e = E.d`` and ``q = d.E.d``."""
    e = np.zeros(3)
    for k in range(3):
        for m in range(3):
            e[k] += strain_rate[k, m] * d[m]
    q = d[0] * e[0] + d[1] * e[1] + d[2] * e[2]
    return e, q


@njit(cache=True)
def strain_forcing(
    n_particles: int, pairs: np.ndarray, units: np.ndarray, scalars: np.ndarray, strain_rate: np.ndarray
) -> np.ndarray:
    """Lubrication force and torque from the imposed strain, ``R_FE : E_inf`` (pair part).

    Per pair, ``F_i = 4pi [g(XG11, YG11) - g(XG12, YG12)] = -F_j`` with
    ``g(X, Y) = X q d + 2 Y (e - q d)``, and ``T_i = T_j = 16 pi (YH11 + YH12) d x e``
    (``e = E.d``, ``q = d.E.d``). The isolated-sphere part of R_FE is zero.

    Args:
        strain_rate: (3, 3) symmetric traceless ``E_inf`` (units gammadot).

    Returns:
        (N, 6) array of [F, T] per particle (units eta a^2 gammadot, eta a^3 gammadot).
    """
    out = np.zeros((n_particles, 6))
    for k in range(pairs.shape[0]):
        sc = scalars[k]
        d = units[k]
        e, q = _strain_vectors(d, strain_rate)
        xg = sc[I_XG11] - sc[I_XG12]
        yg = sc[I_YG11] - sc[I_YG12]
        th = 16.0 * _PI * (sc[I_YH11] + sc[I_YH12])
        dxe0 = d[1] * e[2] - d[2] * e[1]
        dxe1 = d[2] * e[0] - d[0] * e[2]
        dxe2 = d[0] * e[1] - d[1] * e[0]
        i = pairs[k, 0]
        j = pairs[k, 1]
        for c in range(3):
            f = 4.0 * _PI * (xg * q * d[c] + 2.0 * yg * (e[c] - q * d[c]))
            out[i, c] += f
            out[j, c] -= f
        out[i, 3] += th * dxe0
        out[i, 4] += th * dxe1
        out[i, 5] += th * dxe2
        out[j, 3] += th * dxe0
        out[j, 4] += th * dxe1
        out[j, 5] += th * dxe2
    return out


@njit(cache=True)
def _add_g_dot_u(out: np.ndarray, factor: float, x: float, y: float, d: np.ndarray, u: np.ndarray):
    """``out += factor * G(x, y) . u``."""
    du = d[0] * u[0] + d[1] * u[1] + d[2] * u[2]
    for k in range(3):
        for m in range(3):
            iso = 1.0 if k == m else 0.0
            val = x * (d[k] * d[m] - iso / 3.0) * du + y * (
                d[k] * u[m] + d[m] * u[k] - 2.0 * d[k] * d[m] * du
            )
            out[k, m] += factor * val


@njit(cache=True)
def _add_h_dot_w(out: np.ndarray, factor: float, y: float, d: np.ndarray, w: np.ndarray):
    """``out += factor * H(y) . w``."""
    wxd0 = w[1] * d[2] - w[2] * d[1]
    wxd1 = w[2] * d[0] - w[0] * d[2]
    wxd2 = w[0] * d[1] - w[1] * d[0]
    wxd = (wxd0, wxd1, wxd2)
    for k in range(3):
        for m in range(3):
            out[k, m] += factor * y * (wxd[k] * d[m] + wxd[m] * d[k])


@njit(cache=True)
def _add_m_colon_e(
    out: np.ndarray, factor: float, xm: float, ym: float, zm: float, d: np.ndarray, strain_rate: np.ndarray
):
    """``out += factor * M(xm, ym, zm) : E``."""
    e, q = _strain_vectors(d, strain_rate)
    for k in range(3):
        for m in range(3):
            iso = 1.0 if k == m else 0.0
            dd = d[k] * d[m]
            val = 1.5 * xm * (dd - iso / 3.0) * q
            val += ym * (d[k] * e[m] + d[m] * e[k] - 2.0 * dd * q)
            val += (
                0.5
                * zm
                * (2.0 * strain_rate[k, m] + iso * q + dd * q - 2.0 * d[k] * e[m] - 2.0 * d[m] * e[k])
            )
            out[k, m] += factor * val


@njit(cache=True)
def pair_stresslets(
    n_particles: int,
    pairs: np.ndarray,
    units: np.ndarray,
    scalars: np.ndarray,
    velocities: np.ndarray,
    strain_rate: np.ndarray,
) -> np.ndarray:
    """Lubrication stresslet of every particle, ``-R_SU^lub . V' + R_SE^lub : E_inf``.

    Per pair (labels 1 = i, 2 = j, ``G21 = -G12``, ``G22 = -G11``, ``H21 = H12``, ``H22 = H11``)::

        S_i = -4pi [G11 U'_i + G12 U'_j] - 8pi [H11 W'_i + H12 W'_j] + (20/3)pi (M11 + M12) : E
        S_j = +4pi [G12 U'_i + G11 U'_j] - 8pi [H12 W'_i + H11 W'_j] + (20/3)pi (M11 + M12) : E

    Args:
        velocities: (N, 6) disturbance velocities ``[U - u_inf, Omega - omega_inf]``.
        strain_rate: (3, 3) ``E_inf``.

    Returns:
        (N, 3, 3) stresslets (units eta a^3 gammadot). The isolated-sphere part is not included.
    """
    out = np.zeros((n_particles, 3, 3))
    g4 = 4.0 * _PI
    h8 = 8.0 * _PI
    m20 = 20.0 * _PI / 3.0
    for k in range(pairs.shape[0]):
        sc = scalars[k]
        d = units[k]
        i = pairs[k, 0]
        j = pairs[k, 1]
        ui = velocities[i, 0:3]
        uj = velocities[j, 0:3]
        wi = velocities[i, 3:6]
        wj = velocities[j, 3:6]
        si = out[i]
        sj = out[j]
        _add_g_dot_u(si, -g4, sc[I_XG11], sc[I_YG11], d, ui)
        _add_g_dot_u(si, -g4, sc[I_XG12], sc[I_YG12], d, uj)
        _add_g_dot_u(sj, g4, sc[I_XG12], sc[I_YG12], d, ui)
        _add_g_dot_u(sj, g4, sc[I_XG11], sc[I_YG11], d, uj)
        _add_h_dot_w(si, -h8, sc[I_YH11], d, wi)
        _add_h_dot_w(si, -h8, sc[I_YH12], d, wj)
        _add_h_dot_w(sj, -h8, sc[I_YH12], d, wi)
        _add_h_dot_w(sj, -h8, sc[I_YH11], d, wj)
        xm = sc[I_XM11] + sc[I_XM12]
        ym = sc[I_YM11] + sc[I_YM12]
        zm = sc[I_ZM11] + sc[I_ZM12]
        _add_m_colon_e(si, m20, xm, ym, zm, d, strain_rate)
        _add_m_colon_e(sj, m20, xm, ym, zm, d, strain_rate)
    return out


@njit(cache=True)
def pair_stresslet_sum(
    pairs: np.ndarray,
    units: np.ndarray,
    scalars: np.ndarray,
    velocities: np.ndarray,
    strain_rate: np.ndarray,
) -> np.ndarray:
    """Sum over particles of :func:`pair_stresslets`, ``sum_p S_p`` (3, 3), without the per-particle array.

    The bulk stress needs only the sum, and each pair's two stresslets add up to one operator of each kind
    (the operators are linear in their scalars; ``G21 = -G12``, ``G22 = -G11``, ``H21 = H12``,
    ``H22 = H11``)::

        S_i + S_j = -4pi G(XG11 - XG12, YG11 - YG12) . (U'_i - U'_j) - 8pi H(YH11 + YH12) . (W'_i + W'_j)
                    + 2 (20/3)pi (M11 + M12) : E,

    a third of the work of :func:`pair_stresslets` and no allocation per pair (equal to its sum to rounding,
    tested to 1e-12). Same arguments and units as :func:`pair_stresslets`.

    Returns:
        (3, 3) sum of the lubrication stresslets of all particles (units eta a^3 gammadot).
    """
    out = np.zeros((3, 3))
    du = np.empty(3)
    w = np.empty(3)
    g4 = 4.0 * _PI
    h8 = 8.0 * _PI
    m40 = 40.0 * _PI / 3.0
    for k in range(pairs.shape[0]):
        sc = scalars[k]
        d = units[k]
        i = pairs[k, 0]
        j = pairs[k, 1]
        for c in range(3):
            du[c] = velocities[i, c] - velocities[j, c]
            w[c] = velocities[i, 3 + c] + velocities[j, 3 + c]
        _add_g_dot_u(out, -g4, sc[I_XG11] - sc[I_XG12], sc[I_YG11] - sc[I_YG12], d, du)
        _add_h_dot_w(out, -h8, sc[I_YH11] + sc[I_YH12], d, w)
        e0 = strain_rate[0, 0] * d[0] + strain_rate[0, 1] * d[1] + strain_rate[0, 2] * d[2]
        e1 = strain_rate[1, 0] * d[0] + strain_rate[1, 1] * d[1] + strain_rate[1, 2] * d[2]
        e2 = strain_rate[2, 0] * d[0] + strain_rate[2, 1] * d[1] + strain_rate[2, 2] * d[2]
        ev = (e0, e1, e2)
        q = d[0] * e0 + d[1] * e1 + d[2] * e2
        xm = sc[I_XM11] + sc[I_XM12]
        ym = sc[I_YM11] + sc[I_YM12]
        zm = sc[I_ZM11] + sc[I_ZM12]
        for a in range(3):  # M(xm, ym, zm) : E, as in _add_m_colon_e
            for b in range(3):
                iso = 1.0 if a == b else 0.0
                dd = d[a] * d[b]
                val = 1.5 * xm * (dd - iso / 3.0) * q
                val += ym * (d[a] * ev[b] + d[b] * ev[a] - 2.0 * dd * q)
                val += (
                    0.5
                    * zm
                    * (2.0 * strain_rate[a, b] + iso * q + dd * q - 2.0 * d[a] * ev[b] - 2.0 * d[b] * ev[a])
                )
                out[a, b] += m40 * val
    return out
