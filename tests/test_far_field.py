"""Free-space far-field DIP kernels (sim/dipolophoresis/far_field.py).

Independent numbers: the signs and symmetries of docs/model.md#dipolophoresis, its free-space reference
velocities,
the isotropic (F_par, F_perp, F_x) form, the isolated-sphere stresslet S0 = 9 pi eps a^3 E0^2 (ee - I/3),
and, for the O(r^-3) pair correction to the ICEP stresslet, a numerical re-derivation: the exact
electric problem of an insulating sphere in the applied field plus a distant sphere's dipole field
(spherical-harmonic projection, surface quadrature of the slip) and the Faxén stresslet of the
distant sphere's stresslet flow (finite differences of the Kim & Karrila stresslet flow).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import sph_harm_y

from sim.dipolophoresis.far_field import (
    MECHANISM_DEP,
    MECHANISM_DIP,
    MECHANISM_ICEP,
    dep_pair_force,
    dep_pair_virial,
    far_field_functions,
    icep_pair_stresslet,
    mechanism_code,
    mechanism_weights,
    pair_velocity,
)

MECHANISMS = {"dip": (1.0, 1.0), "icep": (1.0, 0.0), "dep": (0.0, 1.0)}
RNG = np.random.default_rng(20240607)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
@pytest.mark.parametrize("r", [2.1, 3.0, 6.0, 25.0])
def test_along_field_attract_perpendicular_repel(mechanism: str, r: float) -> None:
    """docs/model.md#dipolophoresis: field along the line of centres -> U.xh < 0; perpendicular -> U.xh > 0
    (strict)."""
    icep, dep = MECHANISMS[mechanism]
    for _ in range(5):
        xh = _unit(RNG.normal(size=3))
        perp = _unit(np.cross(xh, RNG.normal(size=3)))
        assert pair_velocity(r * xh, xh, icep, dep) @ xh < 0.0
        assert pair_velocity(r * xh, -xh, icep, dep) @ xh < 0.0
        assert pair_velocity(r * xh, perp, icep, dep) @ xh > 0.0


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
def test_pair_antisymmetry_and_zero_sum(mechanism: str) -> None:
    """U_beta = -U_alpha exactly (odd kernels), so an N-body free-space sum of pair velocities is zero.

    Tolerance: 1e-15 relative for the pair (one sign flip of the same arithmetic); 1e-13 of the
    largest velocity for the 12-body sum (rounding of 132 terms).
    """
    icep, dep = MECHANISMS[mechanism]
    e = _unit(RNG.normal(size=3))
    for _ in range(20):
        x = RNG.normal(size=3) * 4.0
        u = pair_velocity(x, e, icep, dep)
        np.testing.assert_allclose(pair_velocity(-x, e, icep, dep), -u, rtol=1e-15, atol=0.0)
    positions = RNG.uniform(0.0, 15.0, size=(12, 3))
    total = np.zeros(3)
    largest = 0.0
    for a in range(12):
        for b in range(12):
            if a != b:
                u = pair_velocity(positions[a] - positions[b], e, icep, dep)
                total += u
                largest = max(largest, float(np.abs(u).max()))
    assert np.abs(total).max() <= 1e-13 * largest


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
def test_rotation_covariance(mechanism: str) -> None:
    """Rotating the separation and the field together rotates the velocity: U(Rx, Re) = R U(x, e), 1e-14."""
    icep, dep = MECHANISMS[mechanism]
    for _ in range(10):
        rot = _random_rotation(RNG)
        x = RNG.normal(size=3) * 3.0
        e = _unit(RNG.normal(size=3))
        u = pair_velocity(x, e, icep, dep)
        np.testing.assert_allclose(
            pair_velocity(rot @ x, rot @ e, icep, dep), rot @ u, rtol=0, atol=1e-14 * (1 + np.abs(u).max())
        )
        ds = icep_pair_stresslet(x, e)
        np.testing.assert_allclose(
            icep_pair_stresslet(rot @ x, rot @ e), rot @ ds @ rot.T, rtol=0, atol=1e-14 * np.abs(ds).max()
        )


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
def test_vector_form_equals_scalar_functions(mechanism: str) -> None:
    """U = (F_par c^2 + F_perp s^2) xh + F_x sin(2 th) t with the far-field F's: 1e-14 relative.

    ``sin(2 th) t = 2 c (e - c xh)`` (``t`` the unit vector of ``e`` perpendicular to ``xh``).
    """
    icep, dep = MECHANISMS[mechanism]
    code = mechanism_code(mechanism)
    for _ in range(30):
        r = RNG.uniform(2.0, 20.0)
        xh = _unit(RNG.normal(size=3))
        e = _unit(RNG.normal(size=3))
        c = float(e @ xh)
        f_par, f_perp, f_x = far_field_functions(r, code)
        expected = (f_par * c * c + f_perp * (1.0 - c * c)) * xh + f_x * 2.0 * c * (e - c * xh)
        u = pair_velocity(r * xh, e, icep, dep)
        np.testing.assert_allclose(u, expected, rtol=0, atol=1e-14 * np.abs(u).max())


def test_scalar_functions_published_coefficients() -> None:
    """docs/model.md#dipolophoresis far-field coefficients at r = 3 (exact rational arithmetic, 1e-15), DIP =
    ICEP + DEP."""
    r = 3.0
    icep = far_field_functions(r, MECHANISM_ICEP)
    dep = far_field_functions(r, MECHANISM_DEP)
    dip = far_field_functions(r, MECHANISM_DIP)
    np.testing.assert_allclose(
        icep,
        [-9 / (4 * r**2) + 11 / (2 * r**4), 9 / (8 * r**2) - 11 / (4 * r**4), -11 / (4 * r**4)],
        rtol=1e-15,
    )
    np.testing.assert_allclose(dep, [-1 / r**4, 1 / (2 * r**4), 1 / (2 * r**4)], rtol=1e-15)
    np.testing.assert_allclose(dip, np.add(icep, dep), rtol=1e-15)
    with pytest.raises(ValueError, match="mechanism_code"):
        far_field_functions(r, 7)


def test_free_space_reference_values() -> None:
    """docs/model.md#dipolophoresis free-space pair values at x = (1.5, 2.5, -0.7), e = y (8 decimals given:
    atol 6e-9)."""
    x = np.array([1.5, 2.5, -0.7])
    e = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(
        pair_velocity(x, e, 1.0, 0.0), [-0.02581713, -0.09977040, 0.01204800], atol=6e-9
    )
    np.testing.assert_allclose(
        pair_velocity(x, e, 0.0, 1.0), [-0.00766351, -0.00245581, 0.00357630], atol=6e-9
    )


def test_mechanism_names() -> None:
    assert mechanism_weights("dip") == (1.0, 1.0)
    assert mechanism_weights("icep") == (1.0, 0.0)
    assert mechanism_weights("dep") == (0.0, 1.0)
    for bad in ("DIP", "", None, 1):
        with pytest.raises(ValueError, match="mechanism"):
            mechanism_weights(bad)  # type: ignore[arg-type]


def test_dep_force_and_virial() -> None:
    """F^DEP/(6 pi) equals the DEP velocity (Stokes drag, a = eta = 1), 1e-15; the virial is -sym(x F)."""
    for _ in range(10):
        x = RNG.normal(size=3) * 3.0
        e = _unit(RNG.normal(size=3))
        f = dep_pair_force(x, e)
        np.testing.assert_allclose(f / (6.0 * math.pi), pair_velocity(x, e, 0.0, 1.0), rtol=1e-14)
        np.testing.assert_allclose(dep_pair_force(-x, e), -f, rtol=1e-15)
        vir = dep_pair_virial(x, e)
        np.testing.assert_allclose(vir, -0.5 * (np.outer(x, f) + np.outer(f, x)), rtol=1e-15)
        # +3 pi r^-3 sym(xh W) (docs/model.md#dipolophoresis)
        r = np.linalg.norm(x)
        xh = x / r
        c = e @ xh
        w = (5 * c * c - 1) * xh - 2 * c * e
        np.testing.assert_allclose(
            vir, 1.5 * math.pi / r**3 * (np.outer(xh, w) + np.outer(w, xh)), rtol=1e-14
        )


def _sphere_quadrature(n_polar: int = 40, n_azimuth: int = 80) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polar angles, azimuths and weights of a Gauss-Legendre x uniform rule on the unit sphere."""
    x, w = np.polynomial.legendre.leggauss(n_polar)
    phi = (np.arange(n_azimuth) + 0.5) * 2.0 * math.pi / n_azimuth
    theta, ph = np.meshgrid(np.arccos(x), phi, indexing="ij")
    weights = np.repeat(w[:, None], n_azimuth, axis=1) * (2.0 * math.pi / n_azimuth)
    return theta.ravel(), ph.ravel(), weights.ravel()


def test_stresslet_correction_symmetric_traceless_zero_mean() -> None:
    """dS is symmetric, traceless (1e-14) and even in x; its average over directions of x is zero (1e-13)."""
    e = _unit(np.array([0.3, -0.5, 0.8]))
    for _ in range(10):
        x = RNG.normal(size=3) * 4.0
        ds = icep_pair_stresslet(x, e)
        np.testing.assert_allclose(ds, ds.T, rtol=0, atol=0)
        assert abs(np.trace(ds)) <= 1e-14 * np.abs(ds).max()
        np.testing.assert_allclose(icep_pair_stresslet(-x, e), ds, rtol=1e-15)
    theta, ph, w = _sphere_quadrature(24, 48)
    mean = np.zeros((3, 3))
    for t, p, wt in zip(theta, ph, w, strict=True):
        xh = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])
        mean += wt * icep_pair_stresslet(3.0 * xh, e)
    assert np.abs(mean).max() / (4 * math.pi) <= 1e-13 * np.abs(icep_pair_stresslet(3.0 * e, e)).max()


def _icep_stresslet_numerical(x: np.ndarray, e: np.ndarray, lmax: int = 8) -> np.ndarray:
    """ICEP stresslet of sphere alpha (at the origin) with sphere beta at -x, electric part only.

    External potential (E0 = a = 1): the applied field and beta's induced dipole,
    ``phi_ext(y) = -e.y - (1/2) e.(y + x)/|y + x|^3``. Insulating sphere: each regular harmonic
    ``c_lm r^l Y_lm`` of ``phi_ext`` gets the response ``l/(l+1) c_lm r^-(l+1) Y_lm``, so on the surface
    ``phi_s = sum (2l+1)/(l+1) c_lm Y_lm``; ``zeta = mean(phi_s) - phi_s`` (no net charge); slip
    ``u = zeta grad_s phi_s``; stresslet ``S = -5 ST[int u n dS]`` (reciprocal theorem; eta = eps = 1).
    Surface gradients by 5-point differences of the harmonic expansion in (theta, phi).
    """
    theta, ph, w = _sphere_quadrature()
    n = np.stack([np.sin(theta) * np.cos(ph), np.sin(theta) * np.sin(ph), np.cos(theta)], axis=1)
    rel = n + x
    phi_ext = -(n @ e) - 0.5 * (rel @ e) / np.linalg.norm(rel, axis=1) ** 3
    terms = []
    for ell in range(lmax + 1):
        for m in range(-ell, ell + 1):
            coefficient = np.sum(w * phi_ext * np.conj(sph_harm_y(ell, m, theta, ph)))
            terms.append((ell, m, (2 * ell + 1) / (ell + 1) * coefficient))

    def surface(t: np.ndarray, p: np.ndarray) -> np.ndarray:
        return np.real(sum(c * sph_harm_y(ell, m, t, p) for ell, m, c in terms))

    h = 1e-3
    phi_s = surface(theta, ph)

    def d(fun_shift) -> np.ndarray:
        return (-fun_shift(2 * h) + 8 * fun_shift(h) - 8 * fun_shift(-h) + fun_shift(-2 * h)) / (12 * h)

    d_theta = d(lambda s: surface(theta + s, ph))
    d_phi = d(lambda s: surface(theta, ph + s))
    e_theta = np.stack([np.cos(theta) * np.cos(ph), np.cos(theta) * np.sin(ph), -np.sin(theta)], axis=1)
    e_phi = np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], axis=1)
    grad_s = d_theta[:, None] * e_theta + (d_phi / np.sin(theta))[:, None] * e_phi
    zeta = np.sum(w * phi_s) / (4 * math.pi) - phi_s
    slip = zeta[:, None] * grad_s
    moment = np.einsum("k,ki,kj->ij", w, slip, n)
    sym = 0.5 * (moment + moment.T)
    return -5.0 * (sym - np.trace(sym) / 3.0 * np.eye(3))


def _faxen_stresslet_numerical(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """(20/3) pi E(x): rate of strain at alpha of beta's stresslet flow, central differences.

    Stresslet flow of a traceless ``S`` (Kim & Karrila 1991): ``u(y) = -3/(8 pi) (y.S.y) y/|y|^5``, with
    beta's isolated ICEP stresslet ``S0 = 9 pi (ee - I/3)``.
    """
    s0 = 9.0 * math.pi * (np.outer(e, e) - np.eye(3) / 3.0)

    def flow(y: np.ndarray) -> np.ndarray:
        return -3.0 / (8.0 * math.pi) * (y @ s0 @ y) * y / np.linalg.norm(y) ** 5

    h = 1e-3 * np.linalg.norm(x)
    grad = np.empty((3, 3))
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        grad[:, j] = (-flow(x + 2 * step) + 8 * flow(x + step) - 8 * flow(x - step) + flow(x - 2 * step)) / (
            12 * h
        )
    return (20.0 / 3.0) * math.pi * 0.5 * (grad + grad.T)


def test_isolated_stresslet_numerical() -> None:
    """The numerical slip stresslet of an isolated sphere is S0 = 9 pi (ee - I/3)
    (docs/model.md#dipolophoresis), 1e-9."""
    e = _unit(np.array([0.2, 0.9, -0.3]))
    far = 1e7 * _unit(np.array([1.0, 0.3, 0.2]))  # beta's dipole field negligible (1e-21)
    np.testing.assert_allclose(
        _icep_stresslet_numerical(far, e), 9 * math.pi * (np.outer(e, e) - np.eye(3) / 3), atol=1e-9
    )


def test_stresslet_correction_matches_derivation() -> None:
    """docs/model.md#icep-pair-stresslet's O(r^-3) dS equals the numerical electric change plus the Faxén
    stresslet.

    The neglected terms are O(r^-5) (no O(r^-4): a dipole-quadrupole product has no l = 2 part, and the
    Faxén correction is O(r^-5)), so the relative residual must fall like r^-2: measured 7.8e-4 at
    r = 25 and 2.0e-4 at r = 50 (ratio 3.99); required below 4e-4 at r = 50 and a ratio in 3.6..4.4
    (an error in any O(r^-3) coefficient would leave a residual that does not decay).
    """
    e = _unit(np.array([0.3, 0.8, -0.2]))
    direction = _unit(np.array([0.6, -0.1, 0.75]))
    s0 = 9 * math.pi * (np.outer(e, e) - np.eye(3) / 3)
    residual = {}
    for r in (25.0, 50.0):
        x = r * direction
        numerical = _icep_stresslet_numerical(x, e) - s0 + _faxen_stresslet_numerical(x, e)
        formula = icep_pair_stresslet(x, e)
        residual[r] = np.abs(numerical - formula).max() / np.abs(formula).max()
    assert residual[50.0] < 4e-4
    assert 3.6 < residual[25.0] / residual[50.0] < 4.4
