"""Smooth particle-mesh Ewald for the far-field DIP sums (sim/dipolophoresis/spme.py and its use in
sim/dipolophoresis/ewald.py).

Independent numbers: B-spline identities (partition of unity, symmetry), charge conservation, a
brute-force Fourier sum over the sheared reciprocal lattice written here in numpy, and the plain Ewald
sums (tests/test_ewald.py checks those against docs/model.md and direct lattice sums).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_ewald import hard_sphere_configuration

from sim.dipolophoresis import spme
from sim.dipolophoresis.ewald import (
    _MECHANISM_COEFFICIENTS,
    METHOD_EWALD,
    METHOD_SPME,
    EwaldPlan,
    _ewald_fourier_sums,
    _fractional_coordinates,
    _spme_fourier_sums,
    dip_far_field,
    ewald_plan,
)

RNG = np.random.default_rng(11)


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(v * v, axis=1))))


@pytest.mark.parametrize("order", [4, 6, 8, 10, 12])
def test_bspline_identities(order: int) -> None:
    """sum_j M_p(w + j) = 1, M_p(u) = M_p(p - u) (1e-14), and |b(m)|^2 positive and finite for even p."""
    s = RNG.random((50, 3))
    base, weights = spme.bspline_weights(s, (16, 24, 16), order)
    np.testing.assert_allclose(weights.sum(axis=2), 1.0, atol=1e-14)
    assert np.all(weights >= 0.0)
    row = np.empty(order)
    mirrored = np.empty(order)
    spme._spline_row(0.3, order, row)
    spme._spline_row(0.7, order, mirrored)  # M_p(0.3 + j) = M_p(p - 0.3 - j) = M_p(0.7 + (p - 1 - j))
    np.testing.assert_allclose(row, mirrored[::-1], atol=1e-14)
    moduli = spme.bspline_moduli(24, order)
    assert np.all(np.isfinite(moduli)) and np.all(moduli > 0.0)
    assert abs(moduli[0] - 1.0) < 1e-14  # sum_j M_p(j + 1) = 1


def test_spreading_and_interpolation() -> None:
    """Spread unit charges sum to N (1e-12); interpolating a constant field returns it (1e-14)."""
    mesh = (20, 30, 20)
    s = RNG.random((37, 3))
    base, weights = spme.bspline_weights(s, mesh, 8)
    grid = spme.spread_unit_charges(base, weights, mesh)
    assert abs(grid.sum() - 37.0) < 1e-12
    ones = np.ones(mesh)
    velocity = np.zeros((37, 3))
    spme.interpolate_add(base, weights, ones, 2.0 * ones, -ones, velocity)
    np.testing.assert_allclose(velocity, np.tile([1.0, 2.0, -1.0], (37, 1)), atol=1e-14)


def _brute_force_fourier_velocity(positions, box, offset, xi, k_cutoff, q, a_s, a_t):
    """(1/V) sum_{0 < |k| <= k_c} K^(k) sum_beta exp(i k.(x_alpha - x_beta)), numpy over all k."""
    m_max = int(1.5 * k_cutoff * box / (2 * math.pi)) + 2
    r = np.arange(-m_max, m_max + 1)
    m = np.stack([a.ravel() for a in np.meshgrid(r, r, r, indexing="ij")], axis=1)
    k = (2 * math.pi / box) * np.stack([m[:, 0], m[:, 1] - m[:, 0] * offset / box, m[:, 2]], axis=1)
    k2 = (k * k).sum(1)
    keep = (k2 > 0) & (k2 <= k_cutoff**2)
    k, k2 = k[keep], k2[keep]
    g = (1 + k2 / (4 * xi * xi)) * np.exp(-k2 / (4 * xi * xi))
    qk = k @ q
    kqk = (k * qk).sum(1)
    w = a_s * (qk - k * (kqk / k2)[:, None]) + a_t * k * kqk[:, None]
    kernel = -8j * math.pi * (g / k2)[:, None] * w
    phase = np.exp(1j * positions @ k.T)
    rho = np.conj(phase).sum(0)
    return np.real((phase * rho)[:, :, None] * kernel[None]).sum(1) / box**3


@pytest.mark.parametrize("offset", [0.0, 2.3, -5.0])
def test_spme_fourier_part_matches_brute_force(offset: float) -> None:
    """SPME Fourier velocities == brute-force k-sum (sheared lattice), 1e-9 relative with a fine mesh.

    Order 10 on a 64^3 mesh for modes up to m ~ 8 leaves an interpolation error ~1e-11 (measured
    2.4e-11 absolute for |U| ~ 0.27); the plain-Ewald loop must agree to rounding (1e-13).
    """
    box = 10.0
    positions = RNG.random((5, 3)) * box
    e = np.array([0.0, 1.0, 0.0])
    q = np.outer(e, e) - np.eye(3) / 3
    xi, k_cutoff = 0.9, 5.0
    a_s, a_t = _MECHANISM_COEFFICIENTS["icep"]
    brute = _brute_force_fourier_velocity(positions, box, offset, xi, k_cutoff, q, a_s, a_t)
    scale = np.abs(brute).max()
    for method in (METHOD_SPME, METHOD_EWALD):
        velocity = np.zeros((5, 3))
        stress, virial = np.zeros((3, 3)), np.zeros((3, 3))
        if method == METHOD_SPME:
            _spme_fourier_sums(
                positions, box, offset, xi, k_cutoff, (64, 64, 64), 10, q, a_s, a_t, velocity, stress, virial
            )
            assert np.abs(velocity - brute).max() <= 1e-9 * scale
        else:
            _ewald_fourier_sums(positions, box, offset, xi, k_cutoff, q, a_s, a_t, velocity, stress, virial)
            assert np.abs(velocity - brute).max() <= 1e-13 * scale


@pytest.mark.parametrize("offset_fraction", [0.0, 0.37, -0.5])
def test_spme_meets_planned_accuracy(offset_fraction: float) -> None:
    """dip_far_field with an SPME plan at accuracy 1e-6 vs a 1e-11 Ewald reference (phi = 0.45, N = 200):
    rms velocity error / rms velocity < 1e-6; stress sums agree to 1e-4 of their largest component (the
    plan controls velocities; measured stress differences ~1e-6)."""
    positions, box = hard_sphere_configuration(200, 0.45, 21)
    offset = offset_fraction * box
    e = np.array([0.0, 0.6, 0.8])
    reference = ewald_plan(box, 200, 1e-11, "ewald", mechanism="all")
    plan = ewald_plan(box, 200, 1e-6, "spme")
    assert plan.method == METHOD_SPME
    v_ref, s_ref, d_ref = dip_far_field(positions, box, offset, e, 1.0, 1.0, reference)
    v, s, d = dip_far_field(positions, box, offset, e, 1.0, 1.0, plan)
    assert _rms(v - v_ref) < 1e-6 * _rms(v_ref)
    assert np.abs(s - s_ref).max() < 1e-4 * np.abs(s_ref).max()
    assert np.abs(d - d_ref).max() < 1e-4 * np.abs(d_ref).max()
    assert abs(np.trace(s)) <= 1e-13 * np.abs(s).max()


def test_mesh_error_estimate() -> None:
    """spme.mesh_error predicts the measured SPME-vs-Ewald velocity difference (same xi, r_c, k_c) within
    a factor 2.5 (the alias model of the module docstring; worst-case shear offset L/2)."""
    positions, box = hard_sphere_configuration(120, 0.3, 22)
    density = 120 / box**3
    xi, r_c, k_c = 0.8, 0.5 * box, 6.0
    e = np.array([0.0, 1.0, 0.0])
    a_s, a_t = _MECHANISM_COEFFICIENTS["dip"]
    exact = EwaldPlan(xi, r_c, k_c, METHOD_EWALD, (0, 0, 0), 0, box)
    ref = dip_far_field(positions, box, -0.5 * box, e, 1.0, 1.0, exact)[0]
    for mesh, order in (((24, 36, 24), 6), ((30, 45, 30), 8)):
        plan = EwaldPlan(xi, r_c, k_c, METHOD_SPME, mesh, order, box)
        err = _rms(dip_far_field(positions, box, -0.5 * box, e, 1.0, 1.0, plan)[0] - ref)
        estimate = spme.mesh_error(xi, k_c, box, mesh, order, density, a_s, a_t)
        assert 1 / 2.5 < err / estimate < 2.5


def test_auto_method_and_mesh_shape() -> None:
    """method="auto" switches at spme.AUTO_SPME_MIN_PARTICLES; SPME meshes hold the sheared k-sphere."""
    n_small = spme.AUTO_SPME_MIN_PARTICLES - 1
    n_large = spme.AUTO_SPME_MIN_PARTICLES
    box_small = (n_small * 4 / 3 * math.pi / 0.45) ** (1 / 3)
    box_large = (n_large * 4 / 3 * math.pi / 0.45) ** (1 / 3)
    assert ewald_plan(box_small, n_small).method == METHOD_EWALD
    plan = ewald_plan(box_large, n_large)
    assert plan.method == METHOD_SPME
    m_c = plan.k_cutoff * plan.box_length / (2 * math.pi)
    k1, k2, k3 = plan.mesh
    assert k1 > 2 * m_c and k3 > 2 * m_c and k2 > 3 * m_c
    assert plan.order % 2 == 0


def test_fractional_coordinates() -> None:
    """x = s1 a1 + s2 a2 + s3 a3 (mod the lattice) with a2 = (delta, L, 0); s in [0, 1)."""
    box, offset = 7.0, 2.1
    positions = RNG.random((20, 3)) * box
    s = _fractional_coordinates(positions, box, offset)
    assert np.all((s >= 0) & (s < 1))
    rebuilt = np.stack([box * s[:, 0] + offset * s[:, 1], box * s[:, 1], box * s[:, 2]], axis=1)
    d = rebuilt - positions
    n2 = np.round(d[:, 1] / box)
    d[:, 0] -= n2 * offset
    d[:, 1] -= n2 * box
    d -= box * np.round(d / box)
    assert np.abs(d).max() < 1e-12
