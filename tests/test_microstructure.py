"""Microstructure statistics (sim.observables.microstructure) against analytic cases and a numpy twin.

Independent numbers: a simple cubic lattice (fabric I/3, Z = 6, pole/equator counts known exactly), the
same lattice seen through a Lees–Edwards offset of exactly one lattice spacing, a chain of pairs along y
(fabric diag(0, 1, 0)), an ideal gas (fabric I/3, g = 1, Z from the density, within Poisson errors), and a
brute-force numpy evaluation with the box's own minimum image.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.geometry.box import LeesEdwardsBox
from sim.observables.microstructure import angular_pair_distribution, contact_number, fabric_tensor

SPACING = 2.05
CELLS = 4
LENGTH = SPACING * CELLS


def simple_cubic() -> np.ndarray:
    grid = (np.arange(CELLS) + 0.5) * SPACING
    x, y, z = np.meshgrid(grid, grid, grid, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


@pytest.mark.parametrize("strain", [0.0, 0.25, 1.5])  # offsets 0, one spacing, L/2 -> two spacings
def test_simple_cubic_lattice(strain: float) -> None:
    """Nearest neighbours only (r = 2.05 < 2.2 < sqrt(2) * 2.05): A = I/3, Z = 6, 64 y-bonds at the poles."""
    positions = simple_cubic()
    n = positions.shape[0]
    np.testing.assert_allclose(fabric_tensor(positions, LENGTH, strain, 2.2), np.eye(3) / 3, atol=1e-12)
    assert contact_number(positions, LENGTH, strain, 0.06) == pytest.approx(6.0, abs=1e-12)
    assert contact_number(positions, LENGTH, strain, 0.04) == 0.0
    g = angular_pair_distribution(positions, LENGTH, strain, np.array([0.0, 2.0, 0.0]), 2.0, 2.2, 3)
    expected = 0.5 * n * (n - 1) * (4 / 3) * math.pi * (2.2**3 - 8.0) / LENGTH**3 / 3
    np.testing.assert_allclose(g * expected, [2 * n, 0.0, n], atol=1e-9)  # x, z bonds; none; y bonds
    diagonal = angular_pair_distribution(positions, LENGTH, strain, np.array([1.0, 1.0, 0.0]), 2.0, 2.2, 3)
    np.testing.assert_allclose(diagonal * expected, [n, 0.0, 2 * n], atol=1e-9)  # mu = 0 (z), 1/sqrt 2


def test_pairs_along_y_and_empty_shell() -> None:
    """Isolated pairs stacked along y: A = diag(0, 1, 0), all at the pole; no pair: A = 0, g = 0."""
    positions = np.array([[2.0, 2.0, 2.0], [2.0, 4.05, 2.0], [7.0, 7.0, 7.0], [7.0, 9.05, 7.0]])
    length = 14.0
    np.testing.assert_allclose(
        fabric_tensor(positions, length, 0.3, 2.2), np.diag([0.0, 1.0, 0.0]), atol=1e-14
    )
    g = angular_pair_distribution(positions, length, 0.3, np.array([0.0, 1.0, 0.0]), 2.0, 2.2, 4)
    assert g[:3].tolist() == [0.0, 0.0, 0.0] and g[3] > 0
    far = positions[[0, 2]]
    assert np.all(fabric_tensor(far, length, 0.0, 2.2) == 0.0)
    assert contact_number(far, length, 0.0, 0.01) == 0.0


def test_ideal_gas() -> None:
    """Uniform random points: A = I/3 and g = 1 to a few Poisson standard errors; Z from the density."""
    rng = np.random.default_rng(7)
    n, length = 3000, 30.0
    positions = rng.uniform(0.0, length, size=(n, 3))
    fabric = fabric_tensor(positions, length, 0.37, 2.2)
    pairs_expected = 0.5 * n * (n - 1) * (4 / 3) * math.pi * 2.2**3 / length**3  # about 7400
    tolerance = 4.0 * math.sqrt(4.0 / 45.0 / pairs_expected)  # std of the mean of n_x^2 is sqrt(4/45/M)
    np.testing.assert_allclose(fabric, np.eye(3) / 3, atol=tolerance)
    z = contact_number(positions, length, 0.37, 0.2)
    z_expected = 2 * pairs_expected / n
    assert z == pytest.approx(z_expected, abs=4.0 * z_expected / math.sqrt(pairs_expected))
    g = angular_pair_distribution(positions, length, 0.37, np.array([0.3, 1.0, -0.2]), 1.0, 2.2, 3)
    shell_pairs = pairs_expected * (1 - (1 / 2.2) ** 3) / 3
    np.testing.assert_allclose(g, 1.0, atol=4.0 / math.sqrt(shell_pairs))


def test_matches_numpy_brute_force() -> None:
    """Random dense configuration, non-trivial offset: the kernels equal an O(N^2) numpy evaluation."""
    rng = np.random.default_rng(3)
    n, length, strain = 200, 11.0, 0.731
    positions = rng.uniform(0.0, length, size=(n, 3))
    box = LeesEdwardsBox(length, strain)
    i, j = np.triu_indices(n, 1)
    sep = box.minimum_image(positions[j] - positions[i])
    r = np.linalg.norm(sep, axis=1)
    near = sep[r < 2.2] / r[r < 2.2, None]
    np.testing.assert_allclose(
        fabric_tensor(positions, length, strain, 2.2), near.T @ near / len(near), atol=1e-12
    )
    assert contact_number(positions, length, strain, 0.3) == pytest.approx(2 * np.sum(r < 2.3) / n)
    e = np.array([0.0, 0.0, 1.0])
    shell = sep[(r >= 1.5) & (r < 2.5)]
    mu = np.abs(shell @ e) / np.linalg.norm(shell, axis=1)
    counts = np.bincount(np.minimum((mu * 4).astype(int), 3), minlength=4)
    expected = 0.5 * n * (n - 1) * (4 / 3) * math.pi * (2.5**3 - 1.5**3) / length**3 / 4
    np.testing.assert_allclose(
        angular_pair_distribution(positions, length, strain, e, 1.5, 2.5, 4), counts / expected
    )


@pytest.mark.parametrize("cutoff", [0.0, -1.0, 6.0])
def test_cutoff_beyond_half_box_is_rejected(cutoff: float) -> None:
    with pytest.raises(ValueError, match="L/2"):
        fabric_tensor(simple_cubic(), LENGTH, 0.0, cutoff)
    with pytest.raises(ValueError):
        angular_pair_distribution(simple_cubic(), LENGTH, 0.0, np.array([0.0, 0.0, 0.0]), 2.0, 2.2, 3)
