"""g(r) and its x–y projection (sim.observables.pair_distribution) against analytic cases and a twin.

Independent numbers: an ideal gas (g = 1 in every bin within its binomial counting error: for independent
uniform points the pair counts of a bin have exactly binomial variance, since given one point the other's
minimum-image separation is uniform on the cell), a simple cubic lattice (peaks at sqrt(k) d with the
coordination numbers 6, 12, 8, 6, 24, 24, 12; in-plane lattice vectors, one per bin), a pair placed across the
y face at strain 0.3 (its separation worked out by hand from the offset 0.3 L), and the all-pairs twin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.geometry.box import lees_edwards_offset
from sim.observables.pair_distribution import (
    PairDistributionAccumulator,
    pair_histograms,
    pair_histograms_brute_force,
)


def test_ideal_gas_gives_one() -> None:
    """300 uniform points in L = 10, 200 configurations at random strains. Each bin's count C is binomial
    with mean E = S x (ideal count); every bin with E >= 50 is within 5 sqrt(E) of E (g within
    5 / sqrt(E) of 1: 0.5%–14%), the bins with smaller E together likewise, and sum((C - E)^2 / E) over the
    306 bins is within 5 sqrt(2 dof) of its mean dof (chi-square)."""
    rng = np.random.default_rng(5)
    n, length, samples = 300, 10.0, 200
    acc = PairDistributionAccumulator.create(n, length, 5.0, 50, 4.0, 16, 1.0)
    for _ in range(samples):
        acc.add(rng.uniform(0.0, length, (n, 3)), rng.uniform(-2.0, 2.0))
    assert acc.samples == samples
    for counts, expected in (
        (acc.radial_counts, samples * acc.radial_ideal_counts),
        (acc.planar_counts.ravel(), np.full(256, samples * acc.planar_ideal_count)),
    ):
        large = expected >= 50
        assert np.all(np.abs(counts[large] - expected[large]) < 5 * np.sqrt(expected[large]))
        small = expected[~large].sum()
        assert abs(counts[~large].sum() - small) < 5 * math.sqrt(small) + 1e-9
    chi2 = np.sum(
        (acc.radial_counts - samples * acc.radial_ideal_counts) ** 2 / (samples * acc.radial_ideal_counts)
    )
    chi2 += np.sum(
        (acc.planar_counts - samples * acc.planar_ideal_count) ** 2 / (samples * acc.planar_ideal_count)
    )
    assert abs(chi2 - 306) < 5 * math.sqrt(2 * 306)
    assert np.all(np.abs(acc.g_xy - 1) < 0.06)  # E = 9000 per x–y bin: 5 sigma = 5.3%
    np.testing.assert_array_equal(acc.planar_counts, acc.planar_counts[::-1, ::-1])  # +r and -r


SPACING = 2.0 + 1.0 / math.pi  # no lattice distance near a bin edge of width 0.02
CELLS = 6
SHELLS = {1: 6, 2: 12, 3: 8, 4: 6, 5: 24, 6: 24, 8: 12}  # |r|^2 / d^2 -> coordination number


def simple_cubic() -> np.ndarray:
    grid = (np.arange(CELLS) + 0.5) * SPACING
    x, y, z = np.meshgrid(grid, grid, grid, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


@pytest.mark.parametrize("strain", [0.0, 1.0 / 6.0, -1.0 / 3.0, 1.5])  # offsets 0, d, -2d, -3d: a lattice
def test_simple_cubic_lattice_peaks_and_coordination(strain: float) -> None:
    """216 spheres, d = 2.318, L = 6 d: g(r) has counts only at r = sqrt(k) d (k <= 8, below L/2 = 3 d),
    exactly N z_k / 2 pairs each. The x–y grid with bins of side d centred on the in-plane lattice vectors
    (i d, j d), |i|, |j| <= 2, slab h = 1 < d, counts N ordered pairs in every bin but the centre."""
    positions = simple_cubic()
    n, length = positions.shape[0], CELLS * SPACING
    radial, planar = pair_histograms(positions, length, strain, 6.8, 340, 2.5 * SPACING, 5, 1.0)
    expected = np.zeros(340, dtype=np.int64)
    for k, z in SHELLS.items():
        expected[int(math.sqrt(k) * SPACING / 0.02)] = n * z // 2
    np.testing.assert_array_equal(radial, expected)
    lattice = np.full((5, 5), n, dtype=np.int64)
    lattice[2, 2] = 0
    np.testing.assert_array_equal(planar, lattice)
    acc = PairDistributionAccumulator.create(n, length, 6.8, 340, 2.5 * SPACING, 5, 1.0)
    acc.add(positions, strain)
    peak = int(SPACING / 0.02)
    ideal = 0.5 * n * (n - 1) * 4 / 3 * math.pi * ((peak + 1) ** 3 - peak**3) * 0.02**3 / length**3
    assert acc.g_r[peak] == pytest.approx(n * 3 / ideal, rel=1e-12)


@pytest.mark.parametrize("length", [30.0, 12.0])  # cell list with 6 cells per side; its all-pairs fallback
@pytest.mark.parametrize("twin", [pair_histograms, pair_histograms_brute_force])
def test_pair_across_the_y_face_at_strain_0_3(length: float, twin) -> None:
    """Sphere i at (5, 0.2, 6), j at (5 + 1.23 + 0.3 L, L - 0.35, 6.1). Seen through the image below (y - L,
    shifted by -0.3 L in x), j is at r_j - r_i = (1.23, -0.55, 0.1): one pair in the shell of
    r = 1.3513, and the x–y bins of (1.23, -0.55) and (-1.23, 0.55). At strain 0 the same positions are
    (1.23 + 0.3 L, -0.55, 0.1) apart: nothing within range."""
    offset = lees_edwards_offset(0.3, length)
    assert offset == pytest.approx(0.3 * length)
    positions = np.array([[5.0, 0.2, 6.0], [5.0 + 1.23 + offset, length - 0.35, 6.1]])
    radial, planar = twin(positions, length, 0.3, 3.0, 60, 3.0, 60, 1.0)
    expected_radial = np.zeros(60, dtype=np.int64)
    expected_radial[int(math.sqrt(1.23**2 + 0.55**2 + 0.1**2) / 0.05)] = 1
    np.testing.assert_array_equal(radial, expected_radial)
    edges = np.linspace(-3.0, 3.0, 61)
    expected_planar = np.zeros((60, 60), dtype=np.int64)
    for dx, dy in ((1.23, -0.55), (-1.23, 0.55)):
        expected_planar[np.searchsorted(edges, dx) - 1, np.searchsorted(edges, dy) - 1] += 1
    np.testing.assert_array_equal(planar, expected_planar)
    radial0, planar0 = twin(positions, length, 0.0, 3.0, 60, 3.0, 60, 1.0)
    assert radial0.sum() == 0 and planar0.sum() == 0


def test_cell_list_equals_all_pairs_twin() -> None:
    """400 uniform points in L = 20 at strain 0.37 (reach 6 <= L/2: cell list, 3 cells per side): identical
    counts to the all-pairs loop."""
    rng = np.random.default_rng(6)
    positions = rng.uniform(0.0, 20.0, (400, 3))
    args = (20.0, 0.37, 6.0, 120, 4.0, 40, 1.0)
    fast, brute = pair_histograms(positions, *args), pair_histograms_brute_force(positions, *args)
    assert fast[0].sum() > 1000 and fast[1].sum() > 1000
    np.testing.assert_array_equal(fast[0], brute[0])
    np.testing.assert_array_equal(fast[1], brute[1])


def test_run_binning_checkpoint_and_bad_input() -> None:
    """for_box keeps the bin widths and fits the ranges in L/2; arrays() round trip is exact; the
    result arrays carry the npz contract; bad input names the argument."""
    big = PairDistributionAccumulator.for_box(2000, 26.5)
    assert (big.r_max, big.xy_half_width) == pytest.approx((6.0, 5.0))
    assert big.radial_counts.shape == (300,) and big.planar_counts.shape == (100, 100)
    small = PairDistributionAccumulator.for_box(40, 7.48)
    assert small.r_max <= 3.74 and small.xy_half_width <= 3.74
    np.testing.assert_allclose(np.diff(small.r_edges), 0.02, rtol=1e-9)
    np.testing.assert_allclose(np.diff(small.x_edges), 0.1, rtol=1e-9)
    assert np.isnan(small.g_r).all()
    rng = np.random.default_rng(7)
    small.add(rng.uniform(0.0, 7.48, (40, 3)), 0.2)
    copy = PairDistributionAccumulator.from_arrays(small.arrays())
    np.testing.assert_array_equal(copy.g_xy, small.g_xy)
    assert set(small.result_arrays()) >= {"r_edges", "g_r", "x_edges", "y_edges", "g_xy", "samples"}
    with pytest.raises(ValueError, match=r"r_max must be in \(0, 3.74\]"):
        PairDistributionAccumulator.create(40, 7.48, 4.0, 10, 2.0, 10)
    with pytest.raises(ValueError, match="n_xy_bins must be an integer >= 1"):
        PairDistributionAccumulator.create(40, 7.48, 3.0, 10, 2.0, 0)
    with pytest.raises(ValueError, match=r"positions must have shape \(40, 3\)"):
        small.add(np.zeros((3, 3)), 0.0)
    with pytest.raises(ValueError, match="wrapped into"):
        small.add(np.full((40, 3), 8.0), 0.0)
    with pytest.raises(ValueError, match="slab_half_thickness must be in"):
        pair_histograms(np.zeros((2, 3)), 7.48, 0.0, 3.0, 10, 2.0, 10, 0.0)
