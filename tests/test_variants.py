"""``sim.variants``: piecewise-linear schedules and following them with the shear rate.

Independent numbers: integrals of piecewise-linear functions by hand (trapezoids), a fine midpoint
quadrature, and the plain ``Simulation`` (a constant schedule must be exactly ``advance_to``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulation, SimulationConfig
from sim.variants import PiecewiseLinear, constant, follow, pieces, ramp, schedule_from_segments

SCHEDULE = schedule_from_segments([("hold", 0.03, 1.0), ("ramp", 0.04, 3.0), ("hold", 0.02, 0.5)], 1.0)
"""Hold 1 for 0.03, ramp to 3 over 0.04, jump to 0.5 and hold for 0.02."""


def test_values_and_exact_integrals() -> None:
    assert SCHEDULE.times == pytest.approx((0.0, 0.03, 0.07, 0.07, 0.09), abs=1e-15)
    assert SCHEDULE(0.05) == pytest.approx(2.0) and SCHEDULE(0.07) == 0.5 and SCHEDULE(-1.0) == 1.0
    assert SCHEDULE(1.0) == 0.5
    # by hand: 0.03 * 1 + 0.04 * (1 + 3) / 2 + 0.02 * 0.5 = 0.12
    assert SCHEDULE.integral(0.0, 0.09) == pytest.approx(0.12, abs=1e-15)
    # a midpoint rule on 70000 cells: exact on the linear cells, O(h) = 1e-6 error at the jump's cell
    edges = np.linspace(0.01, 0.08, 70001)
    quadrature = sum((b - a) * SCHEDULE(0.5 * (a + b)) for a, b in zip(edges[:-1], edges[1:], strict=True))
    assert SCHEDULE.integral(0.01, 0.08) == pytest.approx(quadrature, abs=1e-6)
    assert ramp(0.0, 2.0, 1.0, 2.0).mean(1.0, 3.0) == pytest.approx(1.0)
    assert constant(4.0).mean(3.0, 7.0) == 4.0


def test_pieces_cut_ramps_only() -> None:
    cut = pieces(SCHEDULE, 0.0, 0.09, 0.01)
    assert cut[0] == (0.0, 0.03)  # the hold is one piece
    assert len([p for p in cut if 0.03 <= p[0] < 0.07]) == 4  # the ramp in 0.01 pieces
    assert cut[-1] == (0.07, 0.09)


def test_a_constant_schedule_is_a_plain_advance() -> None:
    config = SimulationConfig(n_particles=64, volume_fraction=0.45, mason_number=1.0, seed=2)
    plain, driven = Simulation(config), Simulation(config)
    plain.set_shear_rate(2.0)
    plain.advance_to(0.03)
    follow(driven, 0.03, constant(2.0))
    np.testing.assert_array_equal(driven.state.positions, plain.state.positions)


def test_following_a_schedule_accumulates_its_integral() -> None:
    sim = Simulation(SimulationConfig(n_particles=64, volume_fraction=0.45, mason_number=1.0, seed=2))
    records = follow(sim, 0.09, SCHEDULE, max_piece=0.01)
    # each piece overshoots by less than one step; at most 1 + 4 + 1 pieces, steps <= 2e-3, rate <= 3
    assert abs(sim.state.strain - SCHEDULE.integral(0.0, 0.09)) <= 6 * 3.0 * 2e-3
    assert set(np.round(records.shear_rate[records.time < 0.03], 12)) == {1.0}
    assert set(np.round(records.shear_rate[records.time >= 0.0705], 12)) == {0.5}
    ramp_rates = records.shear_rate[(records.time > 0.031) & (records.time < 0.069)]
    assert np.all(np.diff(ramp_rates) >= 0) and ramp_rates.min() > 1.0 and ramp_rates.max() < 3.0


@pytest.mark.parametrize(
    "times, values, message",
    [
        ((), (), "non-empty"),
        ((0, 1), (1,), "one length"),
        ((0, math.nan), (1, 1), "finite"),
        ((1, 0), (1, 1), "must not decrease"),
    ],
)
def test_bad_variants_are_refused(times, values, message) -> None:
    with pytest.raises(ValueError, match=message):
        PiecewiseLinear(times, values)
    with pytest.raises(ValueError, match="duration"):
        ramp(0, 1, 0, 0)
    with pytest.raises(ValueError, match="segment kind"):
        schedule_from_segments([("jump", 1.0, 1.0)], 1.0)


def test_knots_inside_is_the_plain_scan_and_lookups_match_searchsorted() -> None:
    """The bisection look-ups (O(log n), so a 100,000-knot schedule is followed at once) give the same
    knots and values as the plain scan and ``np.searchsorted`` they replaced, jumps included."""
    import numpy as np

    from sim import PiecewiseLinear

    rng = np.random.default_rng(4)
    times = np.sort(np.concatenate([rng.uniform(0.0, 10.0, 200), [3.0, 3.0]]))
    variant = PiecewiseLinear(tuple(times), tuple(rng.uniform(0.2, 5.0, times.size)))
    for start, end in ((0.0, 10.0), (2.5, 3.0), (3.0, 3.5), (-1.0, 0.5), (9.9, 12.0), (4.0, 4.0)):
        assert variant.knots_inside(start, end) == tuple(t for t in variant.times if start < t < end)
    for time in np.concatenate([rng.uniform(-1.0, 11.0, 300), times]):
        k = int(np.searchsorted(times, time, side="right")) - 1
        if time < times[0]:
            expected = variant.values[0]
        elif k >= times.size - 1:
            expected = variant.values[-1]
        else:
            t0, t1 = times[k], times[k + 1]
            v0, v1 = variant.values[k], variant.values[k + 1]
            expected = v0 + (v1 - v0) * (time - t0) / (t1 - t0)
        assert variant(float(time)) == expected
