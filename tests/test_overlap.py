"""Tests of the Melrose–Ball overlap removal (sim/geometry/overlap.py).

Independent checks: gaps from the O(N^2) pair search, hand-built pairs (including one across the
sheared boundary) whose result follows from geometry, and momentum-like conservation of the pair
centre of mass. Tolerances in units of ``a``.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.geometry.box import LeesEdwardsBox
from sim.geometry.configurations import box_length_for, random_packing
from sim.geometry.neighbors import build_pair_list_brute_force
from sim.geometry.overlap import OVERSHOOT, remove_overlaps, remove_overlaps_checked


def _min_gap(positions: np.ndarray, box: LeesEdwardsBox) -> float:
    _, seps = build_pair_list_brute_force(positions, box.length, box.offset, 3.0)
    return float(np.linalg.norm(seps, axis=1).min() - 2.0)


@pytest.mark.parametrize("strain", [0.0, 0.37, -1.81])
def test_random_overlapping_configuration_is_cleaned(strain: float) -> None:
    """Random placement at phi = 0.4 (hundreds of overlaps) ends with min gap >= min_gap (1 - 1e-9)."""
    rng = np.random.default_rng(3)
    n, min_gap = 400, 1e-3
    box = LeesEdwardsBox(box_length_for(n, 0.4), strain=strain)
    positions = rng.uniform(0.0, box.length, size=(n, 3))
    before = positions.copy()
    assert _min_gap(positions, box) < -1.0
    sweeps, crossings = remove_overlaps_checked(positions, box, min_gap)
    assert sweeps > 1
    assert _min_gap(positions, box) >= min_gap * (1.0 - 1e-9)
    assert np.all(positions >= 0.0) and np.all(positions < box.length)
    # Reported crossings are the y periods between the old and the new (wrapped) positions; the
    # displacements themselves are well below L/2 here.
    np.testing.assert_array_equal(crossings, np.round((before[:, 1] - positions[:, 1]) / box.length))


def test_overlap_free_configuration_is_bit_identical() -> None:
    """No gap below min_gap: zero sweeps, zero crossings, positions untouched bit for bit."""
    box_length = box_length_for(300, 0.45)
    packing = random_packing(300, 0.45, seed=2, min_gap=0.01)  # overlap-free at zero strain
    sheared = LeesEdwardsBox(box_length, strain=0.6)
    cleaned = packing.copy()
    remove_overlaps_checked(cleaned, sheared, 1e-3)  # overlap-free at strain 0.6
    for positions, box in ((packing, LeesEdwardsBox(box_length)), (cleaned, sheared)):
        copy = positions.copy()
        sweeps, crossings = remove_overlaps(positions, box.length, box.offset, 1e-3, 100)
        assert sweeps == 0
        assert not crossings.any()
        np.testing.assert_array_equal(positions, copy)


def test_isolated_pair_centre_of_mass_and_final_distance() -> None:
    """Both spheres move equally: centre of mass unchanged (1e-12); r = (2 + h_min)(1 + 1e-9) (1e-12)."""
    box = LeesEdwardsBox(20.0, strain=0.2)
    positions = np.array([[9.0, 9.5, 10.0], [10.2, 10.1, 9.6], [2.0, 2.0, 2.0]])
    min_gap = 0.01
    centre = positions[:2].mean(axis=0)
    direction = (positions[1] - positions[0]) / np.linalg.norm(positions[1] - positions[0])
    sweeps, crossings = remove_overlaps_checked(positions, box, min_gap)
    assert sweeps == 1 and not crossings.any()
    np.testing.assert_allclose(positions[:2].mean(axis=0), centre, rtol=0.0, atol=1e-12)
    sep = positions[1] - positions[0]
    assert np.linalg.norm(sep) == pytest.approx((2.0 + min_gap) * (1.0 + OVERSHOOT), abs=1e-12)
    np.testing.assert_allclose(sep / np.linalg.norm(sep), direction, rtol=0.0, atol=1e-12)
    np.testing.assert_array_equal(positions[2], [2.0, 2.0, 2.0])


def test_pair_across_sheared_boundary_is_separated_along_line_of_centres() -> None:
    """Overlap through the image at y - L, shifted by -offset: pushed apart along the image line."""
    box = LeesEdwardsBox(16.0, strain=0.41)
    p0 = np.array([5.0, 0.3, 8.0])
    image_sep = np.array([0.6, -0.8, 0.3])  # from p0 to the image of p1 below y = 0
    p1_image = p0 + image_sep
    p1 = np.array([(p1_image[0] + box.offset) % box.length, p1_image[1] + box.length, p1_image[2]])
    positions = np.array([p0, p1])
    centre = p0 + 0.5 * image_sep
    min_gap = 0.002
    sweeps, crossings = remove_overlaps_checked(positions, box, min_gap)
    assert sweeps == 1 and not crossings.any()
    sep = box.minimum_image(positions[1] - positions[0])
    assert np.linalg.norm(sep) == pytest.approx((2.0 + min_gap) * (1.0 + OVERSHOOT), abs=1e-12)
    np.testing.assert_allclose(
        sep / np.linalg.norm(sep), image_sep / np.linalg.norm(image_sep), rtol=0.0, atol=1e-12
    )
    np.testing.assert_allclose(positions[0] + 0.5 * sep, centre, rtol=0.0, atol=1e-12)


def test_push_across_y_boundary_reports_crossing_and_shifts_x() -> None:
    """A sphere pushed through y = L re-enters at y - L with x shifted by -offset; crossings = +1."""
    box = LeesEdwardsBox(16.0, strain=0.41)
    upper = np.array([5.0, box.length - 0.05, 8.0])
    lower = upper - np.array([0.0, 1.0, 0.0])
    positions = np.array([upper, lower])
    sweeps, crossings = remove_overlaps_checked(positions, box, 0.0)
    push = 0.5 * (2.0 * (1.0 + OVERSHOOT) - 1.0)
    np.testing.assert_array_equal(crossings, [1, 0])
    expected_upper = [(5.0 - box.offset) % box.length, box.length - 0.05 + push - box.length, 8.0]
    np.testing.assert_allclose(positions[0], expected_upper, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(positions[1], lower - [0.0, push, 0.0], rtol=0.0, atol=1e-12)


def test_coincident_spheres_are_separated_along_x() -> None:
    box = LeesEdwardsBox(12.0)
    positions = np.array([[6.0, 6.0, 6.0], [6.0, 6.0, 6.0]])
    remove_overlaps_checked(positions, box, 0.01)
    np.testing.assert_allclose(positions[1] - positions[0], [2.01 * (1 + OVERSHOOT), 0, 0], atol=1e-12)


def test_deterministic() -> None:
    rng = np.random.default_rng(4)
    box = LeesEdwardsBox(box_length_for(200, 0.35), strain=1.3)
    start = rng.uniform(0.0, box.length, size=(200, 3))
    first, second = start.copy(), start.copy()
    remove_overlaps_checked(first, box, 1e-3)
    remove_overlaps_checked(second, box, 1e-3)
    np.testing.assert_array_equal(first, second)


def test_sweep_limit_reported_and_raised() -> None:
    rng = np.random.default_rng(5)
    box = LeesEdwardsBox(box_length_for(200, 0.4))
    positions = rng.uniform(0.0, box.length, size=(200, 3))
    sweeps, _ = remove_overlaps(positions.copy(), box.length, box.offset, 1e-3, 1)
    assert sweeps == -1
    with pytest.raises(RuntimeError, match="max_sweeps"):
        remove_overlaps_checked(positions, box, 1e-3, max_sweeps=1)


def test_checked_wrapper_validates_input() -> None:
    box = LeesEdwardsBox(10.0)
    good = np.full((3, 3), 1.0) + np.arange(3)[:, None] * 3.0
    with pytest.raises(ValueError, match="min_gap"):
        remove_overlaps_checked(good.copy(), box, -0.1)
    with pytest.raises(ValueError, match="min_gap"):
        remove_overlaps_checked(good.copy(), box, 3.5)
    with pytest.raises(ValueError, match="max_sweeps"):
        remove_overlaps_checked(good.copy(), box, 0.01, max_sweeps=0)
    with pytest.raises(ValueError, match="positions"):
        remove_overlaps_checked(good.astype(np.float32), box, 0.01)
    with pytest.raises(ValueError, match="positions"):
        remove_overlaps_checked(good + 20.0, box, 0.01)
