"""Smooth particle-mesh Ewald (SPME) machinery for the Fourier part of the far-field DIP sums.

Used by :func:`sim.dipolophoresis.ewald.dip_far_field` when ``plan.method == METHOD_SPME``; this
module holds the mesh operations, the mesh-error estimate and the mesh choice, and
:mod:`sim.dipolophoresis.ewald` the physics (Fourier kernels, real-space sums).

Method (Essmann et al. 1995). All spheres carry the same quadrupole ``Q = ee - I/3``, so the Fourier
part needs one scalar structure factor ``rho(k) = sum_beta exp(-i k.x_beta)``. In the sheared-lattice
fractional coordinates ``s`` (``x = s1 a1 + s2 a2 + s3 a3``, the Lees–Edwards lattice is the integer
lattice there) scaled to the mesh, ``u_d = K_d s_d``, the Euler exponential spline gives

    exp(2 pi i m u/K) ~ b(m) sum_k M_p(u - k) exp(2 pi i m k/K),
    b(m) = exp(2 pi i (p-1) m/K) / sum_{j=0}^{p-2} M_p(j+1) exp(2 pi i m j/K),

with ``M_p`` the cardinal B-spline of order ``p``. Hence ``rho(m) ~ conj(b(m)) FFT[C](m)`` with
``C(k) = sum_beta prod_d M_p(u_beta,d - k_d)`` (unit charges spread on the mesh), and a field
``sum_m X(m) exp(2 pi i m.u_alpha/K)`` at the particles is the B-spline interpolation of
``IFFT[X |b|^2 ...]``. numba cannot call an FFT, so the FFTs run in ``numba.objmode`` blocks that call
``scipy.fft`` (pocketfft); everything else is compiled, and :func:`dip_far_field` stays one compiled
entry point.

Mesh error estimate (used by :func:`mesh_candidates`). A plane wave of fractional frequency ``theta = m/K``
(``|theta| <= 1/2``) interpolated with order-``p`` B-splines acquires aliases at ``theta + j``
(``j != 0``) of relative amplitude ``(theta/(theta + j))^p`` (the ``p``-th power of the spline's
``sinc`` transform, Hockney & Eastwood 1988; Deserno & Holm 1998). Spreading and interpolation each
alias, with random phases in a disordered configuration, so per axis the relative squared error of a
mode is ``2 sum_{j=+-1,+-2} (theta/(theta+j))^(2p)``, summed over the three axes, and the rms velocity
error is ``dU_mesh^2 = n/(2 pi)^3 int_{|k|<=k_c} <|K^_F(k)|^2> eps^2(k) d^3k`` with the worst
Lees–Edwards shear (``delta = L/2``, which stretches the ``m2`` range to ``1.5 m_c``).
tests/test_spme.py checks SPME against plain Ewald at the planned accuracy.

Benchmark (``python benchmarks/dip_far_field.py``: phi = 0.45, accuracy 1e-6, DIP, e = y, strain
0.37; ms per call of ``dip_far_field`` including both stress sums, CPU time of one core of the 2-core
development machine (AMD EPYC znver4) while other jobs shared it, so +-30%; error = rms velocity error
/ rms velocity against a 1e-11 Ewald reference):

    N      Ewald ms   SPME ms   error (Ewald / SPME)    SPME mesh, order
    64       0.56      3.6      4.0e-7 / 3.6e-7         36 x 54 x 36, 12
    250      1.9       4.6      2.6e-7 / 2.2e-7         30 x 45 x 30, 12
    500      4.5       5.7      1.6e-7 / 1.4e-7         30 x 45 x 30, 12
    1000     9.8      10.9      3.8e-7 / 3.5e-7         36 x 54 x 36, 10
    2000    28.9      29.0      5.5e-8 / 4.9e-8         48 x 72 x 48, 10
    4000   117        73        5.6e-8 / 5.7e-8         60 x 90 x 60, 12

Plain Ewald grows as ~N^1.6 (the optimal splitting keeps ``r_c`` near ``L/2``), SPME as ~N^1.3 from
1000 on. Measured again on 2026-12-06 with the machine's other core idle (median of 10 calls, same
command with ``--sizes``): N = 750: Ewald 8.5, SPME 8.3 ms; 1000: 13.2 and 11.1; 1500: 25.9 and 20.3;
2000: 38.9 and 24.7 (errors as above). They now cross at N ~ 750 (the real-space sums of the large
Ewald cut-offs cost more than the loaded-machine table showed), hence :data:`AUTO_SPME_MIN_PARTICLES`
= 1000 (it was 2000). At N = 4000 SPME spends about a third in the real-space sum (``r_c ~ 8``), a third
in the four FFTs and the rest in spreading and interpolation (order 10-12: ``p^3`` mesh points per
particle).

References:
    Essmann, U., Perera, L., Berkowitz, M. L., Darden, T., Lee, H. & Pedersen, L. G. (1995) "A smooth
    particle mesh Ewald method", J. Chem. Phys. 103, 8577. Hockney, R. W. & Eastwood, J. W. (1988)
    Computer Simulation Using Particles, IOP. Deserno, M. & Holm, C. (1998) J. Chem. Phys. 109, 7678.
    Saintillan, D., Darve, E. & Shaqfeh, E. S. G. (2005) Phys. Fluids 17, 033301 (SPME for Stokes
    sums). Mirfendereski & Park (2024) J. Fluid Mech. §2.1.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.fft
from numba import njit, objmode

from sim.numba_cache import REPRODUCIBLE_FASTMATH

__all__ = [
    "AUTO_SPME_MIN_PARTICLES",
    "bspline_moduli",
    "bspline_weights",
    "interpolate_add",
    "mesh_candidates",
    "inverse_real_fft",
    "mesh_error",
    "real_fft",
    "spread_unit_charges",
]

AUTO_SPME_MIN_PARTICLES = 1000
"""``ewald_plan(method="auto")`` uses SPME from this many particles on (benchmark crossover, phi = 0.45)."""

_ORDERS = (4, 6, 8, 10, 12)


@njit(cache=True)
def _spline_row(w: float, order: int, out: np.ndarray) -> None:
    """``out[j] = M_p(w + j)``, ``j = 0..p-1``, for ``w`` in ``[0, 1)`` (Essmann et al. 1995 eq. 4.1).

    Recursion ``M_n(u) = [u M_{n-1}(u) + (n - u) M_{n-1}(u - 1)]/(n - 1)`` from ``M_2(u) = 1 - |u - 1|``.
    """
    out[0] = w
    out[1] = 1.0 - w
    for j in range(2, order):
        out[j] = 0.0
    for n in range(3, order + 1):
        inv = 1.0 / (n - 1)
        for j in range(n - 1, -1, -1):
            u = w + j
            left = out[j] if j < n - 1 else 0.0
            right = out[j - 1] if j >= 1 else 0.0
            out[j] = (u * left + (n - u) * right) * inv


@njit(cache=True)
def bspline_weights(s: np.ndarray, mesh: tuple[int, int, int], order: int) -> tuple[np.ndarray, np.ndarray]:
    """B-spline weights of each particle on the mesh.

    Args:
        s: Fractional coordinates in ``[0, 1)``, shape ``(N, 3)``, float64.
        mesh: ``(K1, K2, K3)``.
        order: Spline order ``p >= 2``.

    Returns:
        ``(base, weights)``: ``base`` (N, 3) int64 ``floor(K_d s_d)``; ``weights`` (N, 3, p) with
        ``weights[a, d, j] = M_p(u - floor(u) + j)``, the weight of mesh point ``base - j`` (mod ``K_d``).
    """
    n = s.shape[0]
    base = np.empty((n, 3), dtype=np.int64)
    weights = np.empty((n, 3, order))
    row = np.empty(order)
    for a in range(n):
        for d in range(3):
            u = s[a, d] * mesh[d]
            fl = math.floor(u)
            base[a, d] = int(fl)
            _spline_row(u - fl, order, row)
            for j in range(order):
                weights[a, d, j] = row[j]
    return base, weights


@njit(cache=True, error_model="numpy")
def spread_unit_charges(base: np.ndarray, weights: np.ndarray, mesh: tuple[int, int, int]) -> np.ndarray:
    """Mesh ``C(k) = sum_a prod_d M_p(u_ad - k_d)`` of unit charges, shape ``mesh``, float64."""
    k1, k2, k3 = mesh
    order = weights.shape[2]
    grid = np.zeros((k1, k2, k3))
    idx3 = np.empty(order, dtype=np.int64)
    for a in range(base.shape[0]):
        top3 = base[a, 2]
        contiguous = top3 - order + 1 >= 0  # the p points along axis 3 do not wrap
        for j in range(order):
            idx3[j] = (top3 - j) % k3
        for j1 in range(order):
            i1 = (base[a, 0] - j1) % k1
            w1 = weights[a, 0, j1]
            for j2 in range(order):
                i2 = (base[a, 1] - j2) % k2
                w12 = w1 * weights[a, 1, j2]
                if contiguous:
                    for j3 in range(order):
                        grid[i1, i2, top3 - j3] += w12 * weights[a, 2, j3]
                else:
                    for j3 in range(order):
                        grid[i1, i2, idx3[j3]] += w12 * weights[a, 2, j3]
    return grid


@njit(cache=True, fastmath=REPRODUCIBLE_FASTMATH, error_model="numpy")
def interpolate_add(
    base: np.ndarray,
    weights: np.ndarray,
    field_x: np.ndarray,
    field_y: np.ndarray,
    field_z: np.ndarray,
    velocity: np.ndarray,
) -> None:
    """Add ``sum_k prod_d M_p(u_ad - k_d) field_c(k)`` to ``velocity[a, c]`` (B-spline interpolation)."""
    k1, k2, k3 = field_x.shape
    order = weights.shape[2]
    idx3 = np.empty(order, dtype=np.int64)
    for a in range(base.shape[0]):
        top3 = base[a, 2]
        contiguous = top3 - order + 1 >= 0  # the p points along axis 3 do not wrap
        for j in range(order):
            idx3[j] = (top3 - j) % k3
        vx = 0.0
        vy = 0.0
        vz = 0.0
        for j1 in range(order):
            i1 = (base[a, 0] - j1) % k1
            w1 = weights[a, 0, j1]
            for j2 in range(order):
                i2 = (base[a, 1] - j2) % k2
                w12 = w1 * weights[a, 1, j2]
                if contiguous:
                    for j3 in range(order):
                        w = w12 * weights[a, 2, j3]
                        vx += w * field_x[i1, i2, top3 - j3]
                        vy += w * field_y[i1, i2, top3 - j3]
                        vz += w * field_z[i1, i2, top3 - j3]
                else:
                    for j3 in range(order):
                        w = w12 * weights[a, 2, j3]
                        i3 = idx3[j3]
                        vx += w * field_x[i1, i2, i3]
                        vy += w * field_y[i1, i2, i3]
                        vz += w * field_z[i1, i2, i3]
        velocity[a, 0] += vx
        velocity[a, 1] += vy
        velocity[a, 2] += vz


@njit(cache=True)
def bspline_moduli(size: int, order: int) -> np.ndarray:
    """``|b(m)|^2`` for ``m = 0..K-1`` (Essmann et al. 1995 eq. 4.4), shape ``(K,)``."""
    row = np.empty(order)
    _spline_row(0.0, order, row)  # row[j] = M_p(j); M_p(j + 1) = row[j + 1]
    out = np.empty(size)
    for m in range(size):
        re = 0.0
        im = 0.0
        for j in range(order - 1):
            arg = 2.0 * math.pi * m * j / size
            re += row[j + 1] * math.cos(arg)
            im += row[j + 1] * math.sin(arg)
        den = re * re + im * im
        out[m] = 1.0 / den if den > 1e-30 else 0.0
    return out


@njit(cache=True)
def real_fft(grid: np.ndarray) -> np.ndarray:
    """``scipy.fft.rfftn`` of a real 3-D mesh (in an ``objmode`` block), shape ``(K1, K2, K3//2 + 1)``."""
    with objmode(out="complex128[:, :, ::1]"):
        out = np.ascontiguousarray(scipy.fft.rfftn(grid))
    return out


@njit(cache=True)
def inverse_real_fft(spectrum: np.ndarray, mesh: tuple[int, int, int]) -> np.ndarray:
    """``scipy.fft.irfftn`` back to a real mesh of shape ``mesh`` (in an ``objmode`` block)."""
    k1, k2, k3 = mesh
    with objmode(out="float64[:, :, ::1]"):
        out = np.ascontiguousarray(scipy.fft.irfftn(spectrum, s=(k1, k2, k3)))
    return out


# --------------------------------------------------------------------------------------------------
# Mesh error estimate and mesh choice (plain Python, once per run)
# --------------------------------------------------------------------------------------------------


def _alias_error2(theta: np.ndarray, order: int) -> np.ndarray:
    """Relative squared alias error per axis: ``2 sum_{j=+-1,+-2} (theta/(theta + j))^(2p)``."""
    total = np.zeros_like(theta)
    for j in (-2, -1, 1, 2):
        ratio2 = (theta / (theta + j)) ** 2
        power = ratio2.copy()
        for _ in range(order - 1):
            power *= ratio2
        total += power
    return 2.0 * total


@functools.lru_cache(maxsize=64)
def _unit_ball_quadrature(
    n_radial: int = 20, n_polar: int = 12, n_azimuth: int = 24
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``(x, y, z, |x|)`` and weights of a product quadrature over the unit ball."""
    xr, wr = np.polynomial.legendre.leggauss(n_radial)
    k = 0.5 * (xr + 1.0)
    wk = 0.5 * wr * k * k
    xc, wc = np.polynomial.legendre.leggauss(n_polar)
    ph = (np.arange(n_azimuth) + 0.5) * 2.0 * math.pi / n_azimuth
    wph = np.full(n_azimuth, 2.0 * math.pi / n_azimuth)
    kk, cc, pp = np.meshgrid(k, xc, ph, indexing="ij")
    ww = wk[:, None, None] * wc[None, :, None] * wph[None, None, :]
    sc = np.sqrt(1.0 - cc * cc)
    return (
        (kk * sc * np.cos(pp)).ravel(),
        (kk * sc * np.sin(pp)).ravel(),
        (kk * cc).ravel(),
        kk.ravel(),
        ww.ravel(),
    )


def _mesh_error_integrals(
    xi: float, k_cutoff: float, box_length: float, mesh: tuple[int, int, int], order: int
) -> tuple[float, float]:
    """``(I_S, I_T)`` with ``dU_mesh^2 = n/(2 pi)^3 64 pi^2 (a_S^2 I_S + a_T^2 I_T)`` (module docstring)."""
    ux, uy, uz, uk, uw = _unit_ball_quadrature()
    kx, ky, kz, k, w = k_cutoff * ux, k_cutoff * uy, k_cutoff * uz, k_cutoff * uk, k_cutoff**3 * uw
    u = k * k / (4.0 * xi * xi)
    g = (1.0 + u) * np.exp(-u)
    scale = box_length / (2.0 * math.pi)
    m1 = kx * scale
    m2 = ky * scale + 0.5 * np.abs(m1)
    m3 = kz * scale
    eps2 = (
        _alias_error2(m1 / mesh[0], order)
        + _alias_error2(m2 / mesh[1], order)
        + _alias_error2(m3 / mesh[2], order)
    )
    weight = w * g * g * eps2
    return float(np.sum(weight * (2.0 / 15.0) / (k * k))), float(np.sum(weight * (4.0 / 45.0) * k * k))


def mesh_error(
    xi: float,
    k_cutoff: float,
    box_length: float,
    mesh: tuple[int, int, int],
    order: int,
    density: float,
    a_s: float,
    a_t: float,
) -> float:
    """Estimated rms velocity error (units ``U0``) of the SPME interpolation (module docstring).

    Args:
        xi: Splitting parameter (units ``1/a``).
        k_cutoff: Fourier cut-off (units ``1/a``).
        box_length: Box side ``L`` (units ``a``).
        mesh: ``(K1, K2, K3)``.
        order: B-spline order ``p``.
        density: Number density ``N/V`` (units ``a^-3``).
        a_s: Coefficient of ``S:Q`` in the velocity kernel.
        a_t: Coefficient of ``T:Q``.

    Returns:
        ``dU_mesh`` (units ``U0``), evaluated at the worst Lees–Edwards shear ``delta = L/2``.
    """
    i_s, i_t = _mesh_error_integrals(xi, k_cutoff, box_length, mesh, order)
    val = 64.0 * math.pi**2 * (a_s * a_s * i_s + a_t * a_t * i_t)
    return math.sqrt(max(density * val / (2.0 * math.pi) ** 3, 0.0))


def mesh_candidates(
    xi: float,
    k_cutoff: float,
    box_length: float,
    density: float,
    coefficients: list[tuple[float, float]],
    targets: list[float],
) -> list[tuple[tuple[int, int, int], int]]:
    """Smallest admissible mesh for each B-spline order (4, 6, 8): ``[(mesh, order), ...]``.

    The mesh must hold every mode with ``|k| <= k_c`` at any shear: ``K1, K3 > 2 m_c`` and
    ``K2 > 3 m_c`` (``m_c = k_c L/(2 pi)``; ``K2 = 1.5 K1`` rounded up), sizes FFT-friendly
    (``scipy.fft.next_fast_len``), and its :func:`mesh_error` must lie below ``targets`` (units ``U0``)
    for each mechanism's velocity coefficients ``(a_S, a_T)`` in ``coefficients``. The caller weighs
    their costs. Orders needing more than 512 points per axis
    are left out.
    """
    m_c = k_cutoff * box_length / (2.0 * math.pi)
    sizes = []
    size = scipy.fft.next_fast_len(int(math.floor(2.0 * m_c)) + 2, real=True)
    while size <= 512:
        sizes.append(size)
        size = scipy.fft.next_fast_len(size + 1, real=True)

    def mesh_of(size: int) -> tuple[int, int, int]:
        return (size, scipy.fft.next_fast_len(int(math.ceil(1.5 * size)), real=True), size)

    out = []
    for order in _ORDERS:

        def admissible(size: int, order: int = order) -> bool:
            i_s, i_t = _mesh_error_integrals(xi, k_cutoff, box_length, mesh_of(size), order)
            factor = density * 64.0 * math.pi**2 / (2.0 * math.pi) ** 3
            return all(
                math.sqrt(max(factor * (a_s * a_s * i_s + a_t * a_t * i_t), 0.0)) <= t
                for (a_s, a_t), t in zip(coefficients, targets, strict=True)
            )

        if not sizes or not admissible(sizes[-1]):
            continue
        lo, hi = 0, len(sizes) - 1  # sizes[hi] is admissible
        while lo < hi:
            mid = (lo + hi) // 2
            if admissible(sizes[mid]):
                hi = mid
            else:
                lo = mid + 1
        out.append((mesh_of(sizes[hi]), order))
    return out
