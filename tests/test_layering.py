"""Layer order (``sim.observables.layering``) against numbers known without the code: perfect layers give
``psi = 1`` and spacing ``L/m``; an ideal gas gives ``<S(k)> = 1`` (Hansen & McDonald §4.1); ``S(k)`` does
not depend on which Lees–Edwards image represents a particle; the onset rule on hand-made series."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sim.geometry.box import lees_edwards_offset, wrap_positions
from sim.observables.layering import (
    LayerOrderSeries,
    layer_axis,
    layer_harmonics,
    layer_onset_index,
    layer_order,
    layer_wavevectors,
    nearest_layer_axis,
    structure_factor,
    summarise_layering,
)

BOX = 12.0
"""Box side of the tests: harmonics m = 3..6 (spacings 4, 3, 2.4, 2)."""


def _layered(rng: np.random.Generator, axis: int, m: int, per_plane: int, strain: float = 0.0) -> np.ndarray:
    """``m * per_plane`` particles on the planes ``k_m . r = 2 pi j`` (``j = 0..m-1``) of the wavevector
    of :func:`layer_wavevectors`, random in the other directions, wrapped by the Lees–Edwards rule."""
    n = m * per_plane
    positions = rng.uniform(0.0, BOX, (n, 3))
    plane = np.repeat(np.arange(m), per_plane) * BOX / m + 0.37  # a common shift: phases all equal
    positions[:, axis] = plane
    if axis == 0:  # planes normal to the tilted k: m x + t y = L j  ->  x = (L j - t y) / m
        k = layer_wavevectors(BOX, 0, strain, np.array([m]))[0]
        tilt = k[1] * BOX / (2.0 * math.pi)
        positions[:, 0] = plane - tilt * positions[:, 1] / m
    wrap_positions(positions, BOX, lees_edwards_offset(strain, BOX))
    return positions


def test_harmonics_cover_spacings_1_8_to_4() -> None:
    np.testing.assert_array_equal(layer_harmonics(BOX), [3, 4, 5, 6])
    np.testing.assert_array_equal(layer_harmonics(8.41), [3, 4])  # N = 64 at phi = 0.45
    np.testing.assert_array_equal(layer_harmonics(7.2), [2, 3, 4])  # both ends included (7.2/4, 7.2/1.8)
    np.testing.assert_array_equal(layer_harmonics(3.0), [1])  # no m with 1.8 <= 3/m <= 4: nearest 3/2.45


@pytest.mark.parametrize(("axis", "strain"), [(0, 0.0), (0, 0.3), (1, 0.0), (1, 0.3), (2, 0.3)])
def test_perfect_layers_give_psi_one_and_spacing_l_over_m(axis: int, strain: float) -> None:
    """Every phase ``k . r_j`` a multiple of 2 pi: ``|sum| = N``, so ``psi = 1`` (to 1e-12: N = 200 unit
    phasors summed in double precision); the other harmonics see equally filled planes whose phasors
    cancel (``S = 0`` to 1e-12 N; untilted k only). Spacing ``2 pi / k = L/m`` to rounding for k along y, z
    and for the x wavevector at zero offset; at strain 0.3 the offset 3.6 = 1.5 L/5 gives the tilt t = 1/2."""
    rng = np.random.default_rng(7)
    positions = _layered(rng, axis, 5, 40, strain)
    order = layer_order(positions, BOX, axis, strain)
    assert order.psi == pytest.approx(1.0, abs=1e-12)
    assert order.harmonic == 5
    if axis != 0 or strain == 0.0:
        s = structure_factor(positions, layer_wavevectors(BOX, axis, strain, np.array([3, 4, 6])))
        np.testing.assert_allclose(s, 0.0, atol=1e-12 * positions.shape[0])
        assert order.spacing == pytest.approx(BOX / 5, rel=1e-15)
    else:  # tilted planes (here t = 1/2) are closer than L/m by the factor sqrt(1 + t^2 / m^2)
        assert order.spacing == pytest.approx(BOX / 5 / math.sqrt(1 + 0.25 / 25), rel=1e-14)
    direction = np.zeros(3)
    direction[axis] = -2.0  # any length, either sign
    assert layer_order(positions, BOX, direction, strain) == order


@pytest.mark.parametrize(("axis", "strain"), [(1, 0.0), (2, 0.0), (0, 0.3)])
def test_ideal_gas_mean_structure_factor_is_one(axis: int, strain: float) -> None:
    """Uniform independent positions: ``<S(k)> = 1`` at every allowed ``k != 0`` (Hansen & McDonald
    §4.1; ``<exp(-i k . r)> = 0`` over the cell because ``k_axis L / 2 pi`` is a non-zero integer). The
    mean over 400 draws of N = 64 lies within 4 standard errors (sample std / 20) of 1 for each harmonic:
    a fixed seed, and a 6e-5 chance per harmonic of failing for a correct code."""
    rng = np.random.default_rng(11)
    k = layer_wavevectors(BOX, axis, strain, layer_harmonics(BOX))
    samples = np.array([structure_factor(rng.uniform(0.0, BOX, (64, 3)), k) for _ in range(400)])
    mean = samples.mean(axis=0)
    stderr = samples.std(axis=0, ddof=1) / math.sqrt(samples.shape[0])
    assert np.all(np.abs(mean - 1.0) < 4.0 * stderr), (mean, stderr)
    assert np.all((0.75 < stderr * 20) & (stderr * 20 < 1.25))  # var S = 1 - 1/N; std of std ~ 0.07


def test_lees_edwards_images_leave_s_unchanged() -> None:
    """Replacing particles by periodic images ``r + n1 a1 + n2 a2 + n3 a3`` of the sheared lattice
    (``a2 = (delta, L, 0)``), or rewrapping them, leaves ``S`` unchanged for k along y and z (no x
    component: delta does not enter) and for the tilted x wavevector (``k . a2`` a multiple of 2 pi),
    to 1e-9 (phases up to ~100 rad in double precision); for k along y it does not depend on the strain
    at all. The plain x wavevector ``2 pi m / L e_x`` changes: why the tilt is needed."""
    rng = np.random.default_rng(3)
    strain = 0.37
    delta = lees_edwards_offset(strain, BOX)
    positions = rng.uniform(0.0, BOX, (64, 3))
    lattice = np.array([[BOX, 0.0, 0.0], [delta, BOX, 0.0], [0.0, 0.0, BOX]])
    images = positions + rng.integers(-2, 3, (64, 3)) @ lattice
    rewrapped = images.copy()
    wrap_positions(rewrapped, BOX, delta)
    np.testing.assert_allclose(rewrapped, positions, atol=1e-12)  # the same particles
    for axis in (0, 1, 2):
        k = layer_wavevectors(BOX, axis, strain, layer_harmonics(BOX))
        np.testing.assert_allclose(structure_factor(images, k), structure_factor(positions, k), atol=1e-9)
    for other in (0.0, 0.11, 5.6):
        assert layer_order(positions, BOX, 1, other) == layer_order(positions, BOX, 1, strain)
    plain = layer_wavevectors(BOX, 0, 0.0, layer_harmonics(BOX))
    assert np.max(np.abs(structure_factor(images, plain) - structure_factor(positions, plain))) > 1e-3


def test_directions() -> None:
    assert layer_axis((0.0, 0.0, -3.0)) == 2 and layer_axis([1, 0, 0]) == 0
    for bad in ((1.0, 1.0, 0.0), (0.0, 1.0, 1e-6)):
        with pytest.raises(ValueError, match="field_direction must be along x, y or z"):
            layer_order(np.zeros((4, 3)), BOX, bad)
    with pytest.raises(ValueError, match="field_direction must be three finite numbers"):
        layer_axis((0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="field_direction as an axis index must be 0, 1 or 2"):
        layer_order(np.zeros((4, 3)), BOX, 3)
    assert nearest_layer_axis((0.2, -0.9, 0.3)) == 1 and nearest_layer_axis((0.0, 1.0, 0.0)) == 1


def test_onset_needs_a_plateau_above_ten_a_gain_of_three_and_five_samples_above_half_of_it() -> None:
    """Hand-made series: a single excursion above half the plateau (index 5) does not count, five in a
    row (from 20) do; a plateau with ``S_peak`` below 10 is not layered."""
    psi = np.full(60, 0.02)
    psi[5] = 0.4
    psi[20:] = 0.5
    assert layer_onset_index(psi, 0.5, 64) == 20
    psi[22] = 0.2  # the stretch from 20 broken: the next full stretch of 5 starts at 23
    assert layer_onset_index(psi, 0.5, 64) == 23
    assert layer_onset_index(psi, 0.5, 19) is None  # 0.5 * 19 < 10
    assert layer_onset_index(psi[:3], 0.5, 64) is None
    assert layer_onset_index(psi, math.nan, 64) is None
    start = psi.copy()
    start[:5] = 0.2  # ordered from the start: the plateau 0.5 is 2.5 times the first samples' 0.2
    assert layer_onset_index(start, 0.5, 64) is None
    start[:5] = 0.16  # 0.5 >= 3 * 0.16: grown during the run; samples 0-4 are below half the plateau
    assert layer_onset_index(start, 0.5, 64) == 23


def test_onset_of_the_n500_run_whose_peak_was_there_from_the_start() -> None:
    """The box-size study's N = 500 run (phi 0.45, Mn 1, seed 1; results/box_size): psi 0.024 at strain 0
    (S_peak 12 at the liquid-peak harmonic m = 9, spacing 1.86 a) and a plateau of 0.043 (S 21). It
    passes the S >= 10 test but gained a factor of under 2: not layered, so no onset (was strain 0)."""
    path = Path(__file__).parents[1] / "results/box_size/phi0.45_large/phi0.450_N500_Mn1_seed1/layering.csv"
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    plateau = float(table[table[:, 1] >= 20.0, 2].mean())
    assert plateau * 500 >= 10.0 and plateau == pytest.approx(0.0429, abs=5e-4)
    assert layer_onset_index(table[:, 2], plateau, 500) is None


def test_series_summary_and_checkpoint_arrays() -> None:
    """Plateau and block error over the samples after ``from_time``; spacing of the modal harmonic; onset
    time and strain read off the row; arrays round-trip exactly."""
    rng = np.random.default_rng(5)
    series = LayerOrderSeries(box_length=BOX, axis=1, n_particles=200, rows=[])
    gas = rng.uniform(0.0, BOX, (200, 3))
    for i in range(10):
        series.add(gas, 0.05 * i, 0.1 * i)
    layered = _layered(rng, 1, 5, 40)
    for i in range(10, 30):
        series.add(layered, 0.05 * i, 0.1 * i)
    summary = summarise_layering(series, from_time=0.5, n_blocks=4)
    assert summary.samples == 20 and summary.order == pytest.approx(1.0, abs=1e-12)
    assert summary.order_stderr == pytest.approx(0.0, abs=1e-12)
    assert summary.spacing == pytest.approx(BOX / 5, rel=1e-15)
    assert summary.onset_time == 0.05 * 10 and summary.onset_strain == 0.1 * 10
    copy = LayerOrderSeries.from_arrays(series.arrays())
    assert copy == series
    empty = summarise_layering(LayerOrderSeries(BOX, 1, 200, []), 0.0)
    assert empty.samples == 0 and math.isnan(empty.order) and math.isnan(empty.onset_time)
