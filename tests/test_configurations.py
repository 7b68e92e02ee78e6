"""Tests of the random packings (sim/geometry/configurations.py).

Independent checks: gaps from the O(N^2) pair search, the volume fraction from its definition
``N (4/3) pi / L^3``, and the Carnahan–Starling contact value of the hard-sphere ``g(r)``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.geometry.configurations import box_length_for, random_packing
from sim.geometry.neighbors import build_pair_list_brute_force


def _gaps(positions: np.ndarray, box_length: float, cutoff: float = 2.5) -> np.ndarray:
    _, seps = build_pair_list_brute_force(positions, box_length, 0.0, cutoff)
    return np.linalg.norm(seps, axis=1) - 2.0


@pytest.mark.parametrize(
    ("n_particles", "volume_fraction", "min_gap"),
    [
        (2, 0.001, 0.01),
        (20, 0.2, 0.01),
        (100, 0.45, 0.01),
        (500, 0.55, 0.01),
        (300, 0.5, 0.0),
        (200, 0.4, 0.05),
    ],
)
def test_packing_has_no_gap_below_min_gap(n_particles: int, volume_fraction: float, min_gap: float) -> None:
    """Every minimum-image gap r - 2 >= min_gap (exact inequality); positions wrapped in [0, L)."""
    positions = random_packing(n_particles, volume_fraction, seed=5, min_gap=min_gap)
    box_length = box_length_for(n_particles, volume_fraction)
    assert positions.shape == (n_particles, 3) and positions.dtype == np.float64
    assert np.all(positions >= 0.0) and np.all(positions < box_length)
    gaps = _gaps(positions, box_length, cutoff=min(2.5, 0.5 * box_length))
    assert gaps.size == 0 or gaps.min() >= min_gap


def test_volume_fraction_is_exact() -> None:
    """N (4/3) pi / L^3 equals the requested phi (relative 1e-12)."""
    for n, phi in [(100, 0.45), (500, 0.55), (2000, 0.3), (7, 0.01)]:
        box_length = box_length_for(n, phi)
        assert n * (4.0 / 3.0) * math.pi / box_length**3 == pytest.approx(phi, rel=1e-12)


def test_same_seed_same_array_different_seed_different() -> None:
    first = random_packing(200, 0.45, seed=42)
    second = random_packing(200, 0.45, seed=42)
    np.testing.assert_array_equal(first, second)
    other = random_packing(200, 0.45, seed=43)
    assert not np.array_equal(first, other)


def test_reaches_phi_055_for_500_particles() -> None:
    """phi = 0.55 and the accepted maximum 0.6 with N = 500: valid packings (gaps >= 0.01)."""
    for phi in (0.55, 0.6):
        positions = random_packing(500, phi, seed=0)
        assert _gaps(positions, box_length_for(500, phi)).min() >= 0.01


def test_pair_structure_is_liquid_like() -> None:
    """phi = 0.45, N = 1000: near contacts exist (not a lattice) and g(r) near contact is close to
    Carnahan–Starling.

    The mean of g over 2 <= r < 2.1 is compared with the Carnahan–Starling contact value
    g(2a) = (1 - phi/2)/(1 - phi)^3 = 4.66 within 50%. The packings are quenched, not equilibrated
    hard-sphere states, so only loose agreement is expected (measured: ~5.5, +20%).
    """
    n, phi = 1000, 0.45
    positions = random_packing(n, phi, seed=1)
    box_length = box_length_for(n, phi)
    gaps = _gaps(positions, box_length)
    n_close = int(np.sum(gaps < 0.1))
    assert n_close > 0
    density = n / box_length**3
    shell = 4.0 / 3.0 * math.pi * (2.1**3 - 2.0**3)
    g_contact = n_close / (0.5 * n * density * shell)
    carnahan_starling = (1 - phi / 2) / (1 - phi) ** 3
    assert abs(g_contact / carnahan_starling - 1.0) < 0.5
    # Isotropy: the mean of each squared component of the contact directions is ~1/3.
    _, seps = build_pair_list_brute_force(positions, box_length, 0.0, 2.1)
    directions = seps / np.linalg.norm(seps, axis=1)[:, None]
    np.testing.assert_allclose(np.mean(directions**2, axis=0), 1.0 / 3.0, atol=0.05)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_particles": 1, "volume_fraction": 0.3}, "n_particles"),
        ({"n_particles": 2.5, "volume_fraction": 0.3}, "n_particles"),
        ({"n_particles": 100, "volume_fraction": 0.0}, "volume_fraction"),
        ({"n_particles": 100, "volume_fraction": 0.61}, "volume_fraction"),
        ({"n_particles": 100, "volume_fraction": float("nan")}, "volume_fraction"),
        ({"n_particles": 5, "volume_fraction": 0.55}, "n_particles"),
        ({"n_particles": 100, "volume_fraction": 0.3, "min_gap": -0.1}, "min_gap"),
    ],
)
def test_random_packing_validates_input(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        random_packing(seed=0, **kwargs)


def test_box_length_for_validates_input() -> None:
    with pytest.raises(ValueError, match="n_particles"):
        box_length_for(0, 0.3)
    with pytest.raises(ValueError, match="volume_fraction"):
        box_length_for(10, 1.0)
