"""Repulsive force (paper eq. 2.7) and its virial."""

from __future__ import annotations

import math

import numpy as np

from sim.contacts.repulsion import repulsion_scale, repulsive_forces


def test_force_law_matches_equation() -> None:
    """|F| = (F0/sigma) e^{-h/sigma} / (1 - e^{-h/sigma}) evaluated directly (relative 1e-12)."""
    f0 = repulsion_scale(5000.0)
    assert math.isclose(f0, 6 * math.pi / 5000.0)
    sigma = 1e-3
    gaps = np.array([1e-6, 1e-4, 1e-3, 5e-3, 2e-2])
    n = 2 * gaps.size
    pairs = np.array([[2 * k, 2 * k + 1] for k in range(gaps.size)], dtype=np.int64)
    units = np.tile([0.0, 0.0, 1.0], (gaps.size, 1))
    forces, _ = repulsive_forces(n, pairs, units, gaps, f0, sigma)
    expected = f0 / sigma * np.exp(-gaps / sigma) / (1 - np.exp(-gaps / sigma))
    np.testing.assert_allclose(forces[1::2, 2], expected, rtol=1e-12)
    np.testing.assert_allclose(forces[0::2, 2], -expected, rtol=1e-12)  # repulsive: i pushed away from j


def test_newton_third_law_and_virial() -> None:
    """Forces sum to zero; W = sum_pairs |F| r d d equals sum_i x_i F_i (unwrapped), so -W/V = -n<xF>."""
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 10, (6, 3))
    pairs = np.array([[0, 1], [0, 2], [3, 4], [1, 5]], dtype=np.int64)
    for i, j in pairs:  # put each pair at a small gap along a random direction
        d = rng.normal(size=3)
        x[j] = x[i] + (2.0 + rng.uniform(1e-4, 3e-3)) * d / np.linalg.norm(d)
    sep = x[pairs[:, 1]] - x[pairs[:, 0]]
    r = np.linalg.norm(sep, axis=1)
    forces, virial = repulsive_forces(6, pairs, sep / r[:, None], r - 2.0, 0.01, 1e-3)
    assert np.abs(forces.sum(axis=0)).max() < 1e-12 * np.abs(forces).max()
    np.testing.assert_allclose(virial, np.einsum("pi,pj->ij", x, forces), rtol=1e-9, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(virial) >= -1e-12)  # repulsion: positive particle pressure
