"""Electric problem of two insulating spheres (twin multipole expansion), sim/dipolophoresis/two_sphere.

Independent numbers: the isolated insulating sphere (``phi = -E0 r cos(theta) (1 + a^3/(2 r^3))``,
``zeta = (3/2) E0 a cos(theta)``; Squires & Bazant 2004), scipy's ``lpmv``, direct evaluation of the
potential (addition theorem, insulating boundary condition), and the dipole reflection
``b_1 = -(1 - 1/d^3)`` (field along) / ``1 + 1/(2 d^3)`` (across) of the method of reflections.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import lpmv

from sim.dipolophoresis.two_sphere.electric import addition_matrices, solve_electric
from sim.dipolophoresis.two_sphere.legendre import legendre_table


@pytest.mark.parametrize("m", [0, 1])
def test_legendre_table_matches_scipy(m: int) -> None:
    """Values against scipy.special.lpmv; derivative against a centred difference (h = 1e-6 -> ~1e-8)."""
    theta = np.linspace(1e-3, np.pi - 1e-3, 37)
    table = legendre_table(40, m, np.cos(theta), np.sin(theta))
    h = 1e-6
    for n in (0, 1, 2, 7, 23, 40):
        expected = lpmv(m, n, np.cos(theta))
        np.testing.assert_allclose(table.value[n], expected, atol=1e-11 * max(1, n**m))
        derivative = (lpmv(m, n, np.cos(theta + h)) - lpmv(m, n, np.cos(theta - h))) / (2 * h)
        np.testing.assert_allclose(table.d_dtheta[n], derivative, atol=1e-6 * (n + 1) ** 2)
        np.testing.assert_allclose(
            table.m_over_sin[n], m * expected / np.sin(theta), atol=1e-9 * (n + 1) ** 2
        )


@pytest.mark.parametrize("m", [0, 1])
def test_isolated_sphere_zeta_is_three_halves_cos_theta(m: int) -> None:
    """zeta = (3/2) E0 a e.n exactly (to rounding, 1e-14)."""
    theta = np.linspace(0.0, np.pi, 25)
    solution = solve_electric(None, m)
    zeta = solution.zeta(0, np.cos(theta), np.sin(theta))
    expected = 1.5 * (np.cos(theta) if m == 0 else np.sin(theta))  # amplitude of cos(phi) for m = 1
    np.testing.assert_allclose(zeta, expected, atol=1e-14)
    phi_s, _, _ = solution.surface_potential(0, np.cos(theta), np.sin(theta))
    np.testing.assert_allclose(phi_s, -expected, atol=1e-14)


@pytest.mark.parametrize("m", [0, 1])
def test_addition_theorem_against_direct_evaluation(m: int) -> None:
    """Re-expanded irregular harmonics equal the direct ones at points inside the other sphere's reach."""
    d = 2.3
    k12, k21 = addition_matrices(d, m, 120)
    for l in (1, 2, 5):
        # Point near sphere 1 (r1 = 0.8 < d - 1): harmonic of sphere 2 re-expanded about sphere 1.
        x1 = np.array([0.3, 0.0, 0.74])
        r1, r2 = np.linalg.norm(x1), np.linalg.norm(x1 - [0, 0, d])
        direct = r2 ** (-l - 1) * lpmv(m, l, (x1[2] - d) / r2)
        series = sum(k12[n, l] * r1**n * lpmv(m, n, x1[2] / r1) for n in range(m, 121))
        assert series == pytest.approx(direct, rel=1e-12, abs=1e-15)
        # Point near sphere 2: harmonic of sphere 1 re-expanded about sphere 2.
        y2 = np.array([0.3, 0.0, -0.74])
        r2, r1 = np.linalg.norm(y2), np.linalg.norm(y2 + [0, 0, d])
        direct = r1 ** (-l - 1) * lpmv(m, l, (y2[2] + d) / r1)
        series = sum(k21[n, l] * r2**n * lpmv(m, n, y2[2] / r2) for n in range(m, 121))
        assert series == pytest.approx(direct, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize(("m", "d"), [(0, 2.05), (1, 2.05), (0, 3.0), (1, 3.0)])
def test_insulating_boundary_condition(m: int, d: float) -> None:
    """d phi/d n = 0 on both spheres (centred difference of the full potential, h = 1e-5: error ~1e-9),
    at an order where the truncation error of the surface field is < 1e-9 (L = 150, see the next test)."""
    solution = solve_electric(d, m, 150)
    theta = np.linspace(0.05, np.pi - 0.05, 11)
    azimuth = 0.4
    normals = np.stack(
        [np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth), np.cos(theta)], axis=1
    )
    h = 1e-5
    for centre in (0.0, d):
        surface = normals + np.array([0.0, 0.0, centre])
        normal_derivative = (
            solution.potential(surface + h * normals) - solution.potential(surface - h * normals)
        ) / (2 * h)
        assert np.abs(normal_derivative).max() < 1e-8
        # The surface series agrees with the full potential (same coefficients, independent path).
        sphere = 0 if centre == 0.0 else 1
        phi_s, _, _ = solution.surface_potential(sphere, np.cos(theta), np.sin(theta))
        azimuthal = 1.0 if m == 0 else np.cos(azimuth)
        np.testing.assert_allclose(phi_s * azimuthal, solution.potential(surface), atol=1e-12)


def test_far_field_dipole_reflection() -> None:
    """Sphere 1 sees the applied field plus sphere 2's dipole (-1/2 E0 a^3): b_1 = -(1 - d^-3) along,
    1 + d^-3/2 across; the residual is O(d^-6) (second reflection), checked by its scaling."""
    residuals: dict[int, list[float]] = {0: [], 1: []}
    distances = (8.0, 16.0)
    for d in distances:
        for m, expected in ((0, -(1.0 - d**-3)), (1, 1.0 + 0.5 * d**-3)):
            b = solve_electric(d, m, 20).incident[0, 1]
            residuals[m].append(float(abs(b - expected)))
    for m in (0, 1):
        slope = np.log(residuals[m][1] / residuals[m][0]) / np.log(distances[1] / distances[0])
        assert slope < -5.5, (m, residuals[m])
        assert residuals[m][0] < 2.0 * distances[0] ** -6


@pytest.mark.parametrize("m", [0, 1])
def test_electric_convergence_in_truncation_order(m: int) -> None:
    """Surface field at r = 2.05 converges geometrically: errors drop by > 5x for every +10 in L
    (measured: 8.5x for m = 1, >= 3x-50x for m = 0), reaching < 1e-5 at L = 60."""
    d = 2.05
    theta = np.linspace(0.0, np.pi, 41)
    reference = solve_electric(d, m, 120).surface_potential(1, np.cos(theta), np.sin(theta))[1]
    errors = [
        np.abs(
            solve_electric(d, m, order).surface_potential(1, np.cos(theta), np.sin(theta))[1] - reference
        ).max()
        for order in (20, 40, 60)
    ]
    assert errors[1] < errors[0] / 25 and errors[2] < errors[1] / 25
    assert errors[2] < 1e-5
