"""Non-affine displacement, MSD and diffusivities (sim.observables.diffusion) against analytic cases.

Independent numbers: ballistic trajectories (MSD = v^2 t^2 exactly), Gaussian random walks (MSD = 2 D t; the
fitted D's spread over seeds measured beforehand), exact unwrapped trajectories with a known non-affine
part (linear in time) wrapped by the box's own Lees–Edwards rule, and a numpy recomputation of the step
loop's accumulation from the positions of a real run.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim import Simulation, SimulationConfig, SimulationState
from sim.geometry.box import LeesEdwardsBox, lees_edwards_offset, wrap_positions
from sim.observables.diffusion import (
    MsdAccumulator,
    accumulate_displacement,
    diffusivity_fit_window,
    fit_diffusivity,
    mean_square_displacement,
)


def test_ballistic_msd_is_v_squared_t_squared() -> None:
    """D_p(t) = v_p t: MSD_a(m) = <v_a^2> (m dt)^2 exactly (round-off: rtol 1e-12), batch and running twin,
    with the ring buffer wrapped (60 samples, 12 lags)."""
    rng = np.random.default_rng(1)
    n, samples, interval, max_lag = 30, 60, 0.05, 12
    velocity = rng.normal(size=(n, 3))
    times = interval * np.arange(samples)
    trajectory = times[:, None, None] * velocity[None]
    expected = np.mean(velocity**2, axis=0)[None, :] * (interval * np.arange(max_lag + 1))[:, None] ** 2
    np.testing.assert_allclose(mean_square_displacement(trajectory, max_lag), expected, rtol=1e-12, atol=0)
    running = MsdAccumulator.create(n, max_lag)
    for k in range(samples):
        running.add(trajectory[k], times[k])
    np.testing.assert_allclose(running.msd, expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(running.lag_times, interval * np.arange(max_lag + 1), rtol=1e-12)
    np.testing.assert_array_equal(running.origins[1:], samples - np.arange(1, max_lag + 1))
    assert running.span == pytest.approx(times[-1])


def test_running_accumulator_equals_batch_twin_and_round_trips() -> None:
    """Arbitrary (random) samples: the ring-buffer accumulator equals the all-origins batch function (rtol
    1e-12: summation order only); lags beyond the samples are NaN; arrays() round trip is exact."""
    rng = np.random.default_rng(2)
    samples = rng.normal(size=(25, 7, 3)).cumsum(axis=0)
    running = MsdAccumulator.create(7, 30)
    for k in range(25):
        running.add(samples[k], 0.1 * k)
    batch = mean_square_displacement(samples, 30)
    np.testing.assert_allclose(running.msd[:25], batch[:25], rtol=1e-12)
    assert np.isnan(running.msd[25:]).all() and np.isnan(batch[25:]).all()
    copy = MsdAccumulator.from_arrays(running.arrays())
    copy.add(samples[-1] + 1.0, 2.5)
    running.add(samples[-1] + 1.0, 2.5)
    np.testing.assert_array_equal(copy.squared_sums, running.squared_sums)
    np.testing.assert_array_equal(copy.lag_time_sums, running.lag_time_sums)
    with pytest.raises(ValueError, match="time must not precede"):
        running.add(samples[0], 0.0)
    with pytest.raises(ValueError, match=r"displacement must have shape \(7, 3\)"):
        running.add(samples[0, :3], 9.0)
    with pytest.raises(ValueError, match="max_lag must be an integer >= 1"):
        MsdAccumulator.create(7, 0)


def test_random_walk_slope_is_two_d() -> None:
    """Gaussian steps of variance 2 D dt per component (D = 0.1, 1000 walkers, 401 samples, dt = 0.05).

    At one lag the MSD is 2 D dt within 5 sigma of its estimator, sigma = sqrt(2 / (N (S - 1))) = 0.22%
    relative (independent squared Gaussians). The fitted D over the window [1, 5] (span 20 / 4) spread by
    2.4% (1 sigma, 40 seeds measured when the test was written): tolerance 12% (5 sigma).
    """
    rng = np.random.default_rng(3)
    n, samples, interval, diffusivity = 1000, 401, 0.05, 0.1
    steps = rng.normal(0.0, math.sqrt(2 * diffusivity * interval), (samples, n, 3))
    steps[0] = 0.0
    trajectory = steps.cumsum(axis=0)
    running = MsdAccumulator.create(n, 200)
    for k in range(samples):
        running.add(trajectory[k], k * interval)
    sigma = math.sqrt(2.0 / (n * (samples - 1)))
    np.testing.assert_allclose(running.msd[1], 2 * diffusivity * interval, rtol=5 * sigma)
    window = diffusivity_fit_window(running.span, 200 * interval)
    assert window == pytest.approx((1.0, 5.0))
    fitted = fit_diffusivity(running.lag_times, running.msd, window)
    np.testing.assert_allclose(fitted, diffusivity, rtol=0.12)


def test_fit_window_rule_and_too_short_runs() -> None:
    """Window [1, min(max lag, span / 4)]; NaN when it spans less than a factor two; a linear MSD with an
    intercept is fitted exactly (1e-12)."""
    assert diffusivity_fit_window(20.0, 10.0) == (1.0, 5.0)
    assert diffusivity_fit_window(100.0, 10.0) == (1.0, 10.0)
    lags = np.linspace(0.0, 10.0, 201)
    msd = np.column_stack([0.3 + 2 * 0.01 * lags, 0.1 + 2 * 0.02 * lags, 2 * 0.03 * lags])
    np.testing.assert_allclose(fit_diffusivity(lags, msd, (1.0, 5.0)), [0.01, 0.02, 0.03], rtol=1e-12)
    assert np.isnan(fit_diffusivity(lags, msd, diffusivity_fit_window(7.9, 10.0))).all()
    with pytest.raises(ValueError, match="span must be finite and >= 0"):
        diffusivity_fit_window(-1.0, 10.0)
    with pytest.raises(ValueError, match="window start must be finite and > 0"):
        fit_diffusivity(lags, msd, (0.0, 5.0))


def _exact_walk(
    shear_rate: float, drift: np.ndarray, n_steps: int, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unwrapped X(t) = X0 + (c t + gammadot (Y0 t + v t^2 / 2), v t, w t) at random step times; returns
    times, the wrapped positions (box's Lees–Edwards wrap) and the y crossings of each step."""
    rng = np.random.default_rng(seed)
    length = 7.3
    start = rng.uniform(0.0, length, (20, 3))
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.005, 0.05, n_steps))])
    wrapped, crossings = [], []
    for t in times:
        x = start.copy()
        x[:, 0] += drift[0] * t + shear_rate * (start[:, 1] * t + 0.5 * drift[1] * t * t)
        x[:, 1] += drift[1] * t
        x[:, 2] += drift[2] * t
        crossings.append(wrap_positions(x, length, lees_edwards_offset(shear_rate * t, length)))
        wrapped.append(x)
    return times, np.array(wrapped), np.array(crossings)


@pytest.mark.parametrize("shear_rate", [1.0, 0.0])
@pytest.mark.parametrize("drift", [(0.0, 0.0, 0.0), (0.4, 6.0, -1.1)])
def test_affine_part_removed_exactly_and_known_displacement_recovered(shear_rate: float, drift) -> None:
    """The compiled per-step accumulation on exact trajectories (100 random steps, strain up to ~2.8): pure
    affine motion (drift 0) gives zero non-affine displacement, and a constant non-affine velocity
    (c, v, w) (crossing the y faces about 45 times) gives exactly (c, v, w) t: the trapezoid rule is exact
    for y linear in time. Tolerance 1e-11 a: round-off of positions ~7 a over 100 steps."""
    drift = np.array(drift)
    times, wrapped, crossings = _exact_walk(shear_rate, drift, 100, seed=4)
    if drift[1] != 0.0:
        assert np.abs(crossings).sum() > 20
    displacement = np.zeros((20, 3))
    for k in range(1, times.size):
        offset = lees_edwards_offset(shear_rate * times[k], 7.3)
        accumulate_displacement(
            displacement, wrapped[k - 1], wrapped[k], times[k] - times[k - 1], shear_rate, 7.3, offset
        )
    np.testing.assert_allclose(displacement, np.tile(drift * times[-1], (20, 1)), rtol=0, atol=1e-11)


@pytest.mark.parametrize("upwards", [True, False])
def test_one_crossing_of_the_y_face_at_strain_0_3(upwards: bool) -> None:
    """One sphere crosses y = L (or y = 0) in a step ending at strain 0.3 (offset 0.3 L): its image jumps by
    -/+ the offset in x, and the accumulated displacement is the known non-affine one, (0.02, +/-0.05,
    0.01) (1e-13 a)."""
    length, dt, t_end = 9.0, 0.01, 0.3
    y_old = length - 0.03 if upwards else 0.03
    dy = 0.05 if upwards else -0.05
    old = np.array([[4.0, y_old, 2.0]])
    non_affine = np.array([0.02, dy, 0.01])
    new = old + non_affine
    new[0, 0] += dt * (y_old + 0.5 * dy)  # the affine part, gammadot = 1
    box = LeesEdwardsBox(length, t_end)
    wrapped, crossings = box.wrap(new)
    assert crossings[0] == (1 if upwards else -1)
    assert abs(wrapped[0, 0] - new[0, 0]) > 1.0  # the x jump of the image
    displacement = np.zeros((1, 3))
    accumulate_displacement(displacement, old, wrapped, dt, 1.0, length, box.offset)
    np.testing.assert_allclose(displacement[0], non_affine, rtol=0, atol=1e-13)


def test_step_loop_accumulates_each_steps_non_affine_displacement() -> None:
    """A real run (N = 40, phi = 0.5, steps up to 0.01, overlap removal active): after every step the
    state's displacement grows by the numpy recomputation from the wrapped positions, minimum image with
    the box at the new strain and the trapezoid affine part (atol 1e-13 a; the same arithmetic in another
    order). Snapshots carry it; old checkpoints load with zeros."""
    config = SimulationConfig(
        n_particles=40, volume_fraction=0.5, strain=1.0, seed=3, time_step=0.01, initial_min_gap=1e-3
    )
    sim = Simulation(config)
    expected = np.zeros((40, 3))
    for _ in range(25):
        old, t_old = sim.state.positions.copy(), sim.state.strain
        sim.advance(1)
        dt = sim.state.strain - t_old
        step = LeesEdwardsBox(config.box_length, sim.state.strain).minimum_image(sim.state.positions - old)
        step[:, 0] -= dt * (old[:, 1] + 0.5 * step[:, 1])
        expected += step
        np.testing.assert_allclose(sim.state.displacement, expected, rtol=0, atol=1e-13)
    assert np.abs(expected).max() > 1e-3
    assert sim.records.overlap_sweeps.sum() > 0
    snapshot = sim.snapshot()
    np.testing.assert_array_equal(snapshot.displacement, sim.state.displacement)
    arrays = sim.state.arrays()
    np.testing.assert_array_equal(SimulationState.from_arrays(arrays).displacement, sim.state.displacement)
    old_checkpoint = {k: v for k, v in arrays.items() if k != "displacement"}
    np.testing.assert_array_equal(SimulationState.from_arrays(old_checkpoint).displacement, 0.0)
    with pytest.raises(ValueError, match="displacement must have the shape of positions"):
        dataclasses.replace(snapshot, displacement=np.zeros((3, 3)))
