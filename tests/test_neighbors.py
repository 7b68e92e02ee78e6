"""Tests of the Lees–Edwards pair lists (sim/geometry/neighbors.py).

Independent reference: the O(N^2) twin ``build_pair_list_brute_force`` and, for it, a direct
search over the 125 images of the sheared lattice. The cell list must return identical pair sets
in identical order; separations are compared with an absolute tolerance of 1e-12 (units of ``a``).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sim.geometry.box import LeesEdwardsBox, lees_edwards_offset, minimum_image
from sim.geometry.configurations import box_length_for
from sim.geometry.neighbors import build_pair_list, build_pair_list_brute_force, pair_list

TOL = 1e-12


def _assert_same_lists(positions: np.ndarray, box_length: float, offset: float, cutoff: float) -> int:
    pairs, seps = build_pair_list(positions, box_length, offset, cutoff)
    ref_pairs, ref_seps = build_pair_list_brute_force(positions, box_length, offset, cutoff)
    assert pairs.dtype == np.int64 and seps.dtype == np.float64
    assert pairs.shape == (len(pairs), 2) and seps.shape == (len(pairs), 3)
    np.testing.assert_array_equal(pairs, ref_pairs)
    np.testing.assert_allclose(seps, ref_seps, rtol=0.0, atol=TOL)
    return len(pairs)


@pytest.mark.parametrize("n_particles", [4, 12, 40, 150, 1000])
@pytest.mark.parametrize("volume_fraction", [0.05, 0.3, 0.55])
def test_cell_list_equals_brute_force(n_particles: int, volume_fraction: float) -> None:
    """Random (overlapping) configurations, random strains incl. |s| > 1, cutoffs 2.05 .. L/2."""
    rng = np.random.default_rng(1000 * n_particles + int(100 * volume_fraction))
    box_length = box_length_for(n_particles, volume_fraction)
    positions = rng.uniform(0.0, box_length, size=(n_particles, 3))
    half = 0.5 * box_length
    cutoffs = {min(2.05, half), min(2.5, half), box_length / 3.0, half, float(rng.uniform(0.3, half))}
    for cutoff in sorted(cutoffs):
        for strain in (0.0, float(rng.uniform(-0.5, 0.5)), float(rng.uniform(1.0, 4.0)), -2.63):
            offset = lees_edwards_offset(strain, box_length)
            _assert_same_lists(positions, box_length, offset, cutoff)


def test_cell_list_on_cell_boundaries_and_exact_cutoff_distances() -> None:
    """Lattice sites on cell faces with many distances equal to the cutoff (strict < on both)."""
    spacing = 2.5
    sites = np.array(list(itertools.product(range(8), repeat=3)), dtype=np.float64) * spacing
    box_length = 8 * spacing
    for strain in (0.0, 0.125, 0.5, 0.3):
        offset = lees_edwards_offset(strain, box_length)
        for cutoff in (2.5, 2.5 * (1 + 1e-12), 5.0):
            _assert_same_lists(sites, box_length, offset, cutoff)


def test_fallback_for_fewer_than_three_cells() -> None:
    """cutoff > L/3 triggers the O(N^2) fallback; still equal to the twin."""
    rng = np.random.default_rng(7)
    box_length = 9.0
    positions = rng.uniform(0.0, box_length, size=(80, 3))
    assert _assert_same_lists(positions, box_length, lees_edwards_offset(1.7, box_length), 4.4) > 0


def test_brute_force_matches_search_over_images() -> None:
    """The brute-force twin against an explicit 125-image search (pair set exact, r to 1e-12)."""
    rng = np.random.default_rng(8)
    box_length = 10.0
    offset = lees_edwards_offset(-1.23, box_length)
    lattice = np.array([[box_length, 0, 0], [offset, box_length, 0], [0, 0, box_length]])
    n, cutoff = 60, 4.0
    positions = rng.uniform(0.0, box_length, size=(n, 3))
    i, j = np.triu_indices(n, k=1)
    integers = np.array(list(itertools.product(range(-2, 3), repeat=3)), dtype=np.float64)
    images = (positions[j] - positions[i])[:, None, :] + (integers @ lattice)[None, :, :]
    shortest = images[np.arange(len(i)), np.argmin(np.sum(images**2, axis=2), axis=1)]
    close = np.linalg.norm(shortest, axis=1) < cutoff
    pairs, seps = build_pair_list_brute_force(positions, box_length, offset, cutoff)
    np.testing.assert_array_equal(pairs, np.column_stack([i[close], j[close]]))
    np.testing.assert_allclose(seps, shortest[close], rtol=0.0, atol=TOL)


def test_pair_list_invariants() -> None:
    """i < j, lexicographic order, |sep| < cutoff and sep = minimum_image(x_j - x_i)."""
    rng = np.random.default_rng(9)
    box = LeesEdwardsBox(box_length_for(2000, 0.45), strain=2.31)
    positions = rng.uniform(0.0, box.length, size=(2000, 3))
    pairs, seps = pair_list(positions, box, 2.5)
    assert len(pairs) > 1000
    assert np.all(pairs[:, 0] < pairs[:, 1])
    keys = pairs[:, 0] * len(positions) + pairs[:, 1]
    assert np.all(np.diff(keys) > 0)
    assert np.all(np.linalg.norm(seps, axis=1) < 2.5)
    raw = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    np.testing.assert_allclose(seps, box.minimum_image(raw), rtol=0.0, atol=TOL)


def test_pair_across_sheared_boundary_found() -> None:
    """A pair that is close only through the image shifted by the offset (hand-built, 1e-12)."""
    box = LeesEdwardsBox(20.0, strain=0.37)  # offset 7.4
    p0 = np.array([3.0, 0.4, 10.0])
    # Particle 1 at y near L; its image at y - L is shifted by -offset in x, landing near p0.
    p1 = np.array([(3.0 + 1.0 + box.offset) % box.length, box.length - 0.6, 10.5])
    positions = np.array([p0, p1, [15.0, 10.0, 3.0]])
    pairs, seps = pair_list(positions, box, 2.5)
    np.testing.assert_array_equal(pairs, [[0, 1]])
    np.testing.assert_allclose(seps[0], [1.0, -1.0, 0.5], rtol=0.0, atol=TOL)
    # Without the shear offset the two are far apart.
    pairs_no_shear, _ = pair_list(positions, box.with_strain(0.0), 2.5)
    assert len(pairs_no_shear) == 0


def test_empty_and_single_particle() -> None:
    for n in (0, 1):
        pairs, seps = build_pair_list(np.zeros((n, 3)), 10.0, 0.0, 2.5)
        assert pairs.shape == (0, 2) and seps.shape == (0, 3)


def test_pair_list_validates_input() -> None:
    box = LeesEdwardsBox(10.0)
    positions = np.full((5, 3), 1.0)
    for bad in (0.0, -1.0, 5.0 + 1e-9, np.nan):
        with pytest.raises(ValueError, match="cutoff"):
            pair_list(positions, box, bad)
    with pytest.raises(ValueError, match="positions"):
        pair_list(np.full((5, 3), 10.0), box, 2.5)
    with pytest.raises(ValueError, match="positions"):
        pair_list(np.zeros((5, 2)), box, 2.5)


def test_scalar_kernel_used_for_separations() -> None:
    """Separations are bit-identical to minimum_image (the definition the consumers rely on)."""
    rng = np.random.default_rng(10)
    box_length = 15.0
    offset = lees_edwards_offset(0.77, box_length)
    positions = rng.uniform(0.0, box_length, size=(300, 3))
    pairs, seps = build_pair_list(positions, box_length, offset, 3.0)
    for (i, j), sep in zip(pairs, seps, strict=True):
        d = positions[j] - positions[i]
        assert tuple(sep) == minimum_image(d[0], d[1], d[2], box_length, offset)
