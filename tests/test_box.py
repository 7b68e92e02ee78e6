"""Tests of the Lees–Edwards box (sim/geometry/box.py).

Independent references: an explicit search over the images ``n1*a1 + n2*a2 + n3*a3``
(``n in -2..2``) of the sheared lattice, exact integer arithmetic of the offset, and hand-worked
crossings. Tolerances are absolute, in units of ``a`` (box sides 6–30).
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from sim.geometry.box import (
    LeesEdwardsBox,
    lees_edwards_offset,
    minimum_image,
    minimum_image_array,
    wrap_positions,
)

TOL = 1e-12


def _lattice(box_length: float, offset: float) -> np.ndarray:
    return np.array([[box_length, 0.0, 0.0], [offset, box_length, 0.0], [0.0, 0.0, box_length]])


_IMAGE_INTEGERS = np.array(list(itertools.product(range(-2, 3), repeat=3)), dtype=np.float64)


def _brute_force_images(dr: np.ndarray, lattice: np.ndarray) -> np.ndarray:
    """Shortest of the 125 images dr + n1 a1 + n2 a2 + n3 a3 (n in -2..2) of each row of dr (M, 3)."""
    images = dr[:, None, :] + (_IMAGE_INTEGERS @ lattice)[None, :, :]
    best = np.argmin(np.einsum("mkd,mkd->mk", images, images), axis=1)
    return images[np.arange(len(dr)), best]


@pytest.mark.parametrize(
    ("strain", "expected_fraction"),
    [
        (0.0, 0.0),
        (0.25, 0.25),
        (1.25, 0.25),
        (-0.75, 0.25),
        (0.5, -0.5),
        (-0.5, -0.5),
        (0.75, -0.25),
        (3.9, -0.1),
        (-2.1, -0.1),
    ],
)
def test_offset_mapping_hand_values(strain: float, expected_fraction: float) -> None:
    """Offset = strain*L mod L in [-L/2, L/2): hand-computed fractions of L (tolerance 1e-12)."""
    box_length = 8.0
    offset = lees_edwards_offset(strain, box_length)
    assert -box_length / 2 <= offset < box_length / 2
    assert offset == pytest.approx(expected_fraction * box_length, abs=TOL)


def test_offset_range_and_congruence_random() -> None:
    """For random strains in [-50, 50]: offset in [-L/2, L/2) and (strain*L - offset)/L an integer (1e-9)."""
    rng = np.random.default_rng(11)
    for _ in range(2000):
        box_length = float(rng.uniform(3.0, 40.0))
        strain = float(rng.uniform(-50.0, 50.0))
        offset = lees_edwards_offset(strain, box_length)
        assert -box_length / 2 <= offset < box_length / 2
        periods = (strain * box_length - offset) / box_length
        assert abs(periods - round(periods)) < 1e-9


def test_minimum_image_matches_search_over_images() -> None:
    """Minimum image equals the shortest of the 125 images n in -2..2 whenever |r| < L/2 (1e-12)."""
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(200):
        box_length = float(rng.uniform(6.0, 30.0))
        strain = float(rng.uniform(-3.7, 3.7))
        offset = lees_edwards_offset(strain, box_length)
        # Separations of two wrapped positions: components in (-L, L).
        dr = rng.uniform(0.0, box_length, (50, 3)) - rng.uniform(0.0, box_length, (50, 3))
        reference = _brute_force_images(dr, _lattice(box_length, offset))
        unique = np.linalg.norm(reference, axis=1) < 0.5 * box_length * (1.0 - 1e-9)
        result = minimum_image_array(dr, box_length, offset)
        np.testing.assert_allclose(result[unique], reference[unique], rtol=0.0, atol=TOL)
        first = int(np.argmax(unique))
        assert minimum_image(*dr[first], box_length, offset) == tuple(result[first])
        checked += int(unique.sum())
    assert checked > 1000


def test_minimum_image_removes_arbitrary_lattice_vectors() -> None:
    """r + (n1 a1 + n2 a2 + n3 a3) with |n| <= 5 maps back to r for |r| < L/2 (tolerance 1e-12)."""
    rng = np.random.default_rng(2)
    for _ in range(2000):
        box_length = float(rng.uniform(6.0, 30.0))
        strain = float(rng.uniform(-5.0, 5.0))
        offset = lees_edwards_offset(strain, box_length)
        lattice = _lattice(box_length, offset)
        direction = rng.normal(size=3)
        r = direction / np.linalg.norm(direction) * rng.uniform(0.0, 0.499 * box_length)
        n = rng.integers(-5, 6, size=3)
        dr = r + n @ lattice
        result = np.array(minimum_image(dr[0], dr[1], dr[2], box_length, offset))
        np.testing.assert_allclose(result, r, rtol=0.0, atol=TOL)


def test_minimum_image_array_and_box_method_agree_with_scalar_kernel() -> None:
    """Array kernel, box method on (M, 3) and (3,) give the scalar kernel's result exactly."""
    rng = np.random.default_rng(3)
    box = LeesEdwardsBox(13.0, strain=-1.37)
    dr = rng.uniform(-20.0, 20.0, size=(50, 3))
    expected = np.array([minimum_image(*row, box.length, box.offset) for row in dr])
    np.testing.assert_array_equal(minimum_image_array(dr, box.length, box.offset), expected)
    np.testing.assert_array_equal(box.minimum_image(dr), expected)
    np.testing.assert_array_equal(box.minimum_image(dr[7]), expected[7])
    assert box.minimum_image(dr[7]).shape == (3,)
    with pytest.raises(ValueError, match="dr"):
        box.minimum_image(np.zeros((4, 2)))


@pytest.mark.parametrize(("y", "periods"), [(10.3, 1), (20.3, 2), (-0.4, -1), (-9.7, -1), (-10.1, -2)])
def test_wrap_crossing_shifts_x_by_offset(y: float, periods: int) -> None:
    """Crossing y = L n times shifts x by -n*offset and reports n (hand values, tolerance 1e-12)."""
    box = LeesEdwardsBox(10.0, strain=0.23)  # offset 2.3
    positions = np.array([[4.0, y, 5.0]])
    crossings = wrap_positions(positions, box.length, box.offset)
    assert crossings.dtype == np.int64
    assert crossings[0] == periods
    expected_x = (4.0 - periods * 2.3) % 10.0
    np.testing.assert_allclose(positions[0], [expected_x, y - periods * 10.0, 5.0], rtol=0.0, atol=TOL)


def test_wrap_keeps_positions_in_box_and_minimum_images() -> None:
    """Wrapped positions lie in [0, L)^3; all pair minimum images are unchanged (1e-12)."""
    rng = np.random.default_rng(4)
    for strain in (0.0, 0.41, -2.77, 7.5):
        box = LeesEdwardsBox(9.0, strain=strain)
        positions = rng.uniform(-3 * box.length, 4 * box.length, size=(60, 3))
        wrapped, crossings = box.wrap(positions)
        assert np.all(wrapped >= 0.0) and np.all(wrapped < box.length)
        np.testing.assert_array_equal(crossings, np.floor(positions[:, 1] / box.length).astype(np.int64))
        i, j = np.triu_indices(len(positions), k=1)
        before = box.minimum_image(positions[j] - positions[i])
        after = box.minimum_image(wrapped[j] - wrapped[i])
        # Only pairs closer than L/2 have a unique minimum image.
        close = np.linalg.norm(before, axis=1) < 0.5 * box.length - 1e-9
        np.testing.assert_allclose(after[close], before[close], rtol=0.0, atol=TOL)


def test_wrap_is_identity_on_wrapped_positions() -> None:
    """Already wrapped positions are left bit-identical with zero crossings."""
    rng = np.random.default_rng(5)
    box = LeesEdwardsBox(11.0, strain=0.8)
    positions = rng.uniform(0.0, box.length, size=(100, 3))
    copy = positions.copy()
    crossings = wrap_positions(positions, box.length, box.offset)
    np.testing.assert_array_equal(positions, copy)
    assert not crossings.any()


def test_wrap_tiny_negative_coordinate_stays_below_length() -> None:
    """y = -1e-17 wraps into [0, L) (not onto L itself) with crossings = -1."""
    box = LeesEdwardsBox(10.0, strain=0.1)
    wrapped, crossings = box.wrap(np.array([[-1e-17, -1e-17, -1e-17]]))
    assert np.all(wrapped >= 0.0) and np.all(wrapped < box.length)
    assert crossings[0] in (-1, 0)


def test_minimum_image_periodic_in_strain() -> None:
    """Strains s, s + 1 and s - 3 give the same minimum-image separations (1e-12) and lattices."""
    rng = np.random.default_rng(6)
    for _ in range(20):
        box = LeesEdwardsBox(float(rng.uniform(6.0, 20.0)), strain=float(rng.uniform(-2.0, 2.0)))
        dr = rng.uniform(-box.length, box.length, size=(200, 3))
        base = box.minimum_image(dr)
        close = np.linalg.norm(base, axis=1) < 0.5 * box.length - 1e-9
        for shift in (1.0, -3.0):
            other = box.with_strain(box.strain + shift)
            np.testing.assert_allclose(other.minimum_image(dr)[close], base[close], rtol=0.0, atol=TOL)
            np.testing.assert_allclose(other.lattice_vectors, box.lattice_vectors, rtol=0.0, atol=1e-12 * 20)


def test_box_properties() -> None:
    """Volume L^3, lattice rows a1, a2 = (offset, L, 0), a3; with_strain keeps the length."""
    box = LeesEdwardsBox(10, strain=0.3)
    assert isinstance(box.length, float)
    assert box.volume == pytest.approx(1000.0, rel=1e-15)
    np.testing.assert_allclose(
        box.lattice_vectors, [[10.0, 0, 0], [3.0, 10.0, 0], [0, 0, 10.0]], rtol=0.0, atol=TOL
    )
    other = box.with_strain(0.7)
    assert other.length == box.length and other.strain == 0.7
    assert other.offset == pytest.approx(-3.0, abs=TOL)
    with pytest.raises(dataclasses.FrozenInstanceError):
        box.length = 3.0  # type: ignore[misc]


@pytest.mark.parametrize("length", [0.0, -1.0, np.nan, np.inf])
def test_box_rejects_bad_length(length: float) -> None:
    with pytest.raises(ValueError, match="length"):
        LeesEdwardsBox(length)


def test_box_rejects_bad_strain_and_positions() -> None:
    with pytest.raises(ValueError, match="strain"):
        LeesEdwardsBox(5.0, strain=np.nan)
    box = LeesEdwardsBox(5.0)
    with pytest.raises(ValueError, match="positions"):
        box.wrap(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="positions"):
        box.wrap(np.array([[np.nan, 0.0, 0.0]]))
