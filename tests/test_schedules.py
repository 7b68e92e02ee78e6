"""``dipenv.schedules``: random hold/ramp shear-rate schedules and the shipped fixed ones."""

from __future__ import annotations

import math

import numpy as np
import pytest

import sim
from dipenv.schedules import (
    FIXED_SPLITS,
    draw_schedule,
    fixed_schedules,
    mean_rate,
    schedule_from_dict,
    schedule_to_dict,
    split_seeds,
    spread_order,
)


def _segments(schedule: sim.PiecewiseLinear) -> list[tuple[str, float, float, float]]:
    """(kind, duration, start rate, end rate) of each stretch between consecutive knots."""
    knots = list(zip(schedule.times, schedule.values, strict=True))
    return [
        ("hold" if v0 == v1 else "ramp", t1 - t0, v0, v1)
        for (t0, v0), (t1, v1) in zip(knots, knots[1:], strict=False)
    ]


def test_draws_alternate_holds_and_ramps_within_their_ranges() -> None:
    rng = np.random.default_rng(5)
    rates = []
    for _ in range(300):
        schedule = draw_schedule(rng, 12.0)
        segments = _segments(schedule)
        assert schedule.times[0] == 0.0 and schedule.times[-1] >= 12.0
        kinds = [s[0] for s in segments]
        assert kinds[::2] == ["hold"] * len(kinds[::2]) and all(k == "ramp" for k in kinds[1::2])
        for kind, length, _, _ in segments:
            low, high = (1.0, 4.0) if kind == "hold" else (0.5, 2.0)
            assert low <= length <= high
        rates.extend(schedule.values)
    logs = np.log(np.unique(rates))
    assert np.all((logs >= math.log(0.2)) & (logs <= math.log(5.0)))
    # log-uniform: mean of log(rate) is 0 (the range is symmetric in log) within 4 standard errors
    assert abs(logs.mean()) < 4 * (2 * math.log(5) / math.sqrt(12)) / math.sqrt(logs.size)


def test_same_generator_same_schedule() -> None:
    a = draw_schedule(np.random.default_rng(7), 12.0)
    b = draw_schedule(np.random.default_rng(7), 12.0)
    assert a == b


def test_shipped_schedules_are_the_generator_s_from_their_seeds() -> None:
    for split, (count, seed) in FIXED_SPLITS.items():
        shipped = fixed_schedules(split)
        assert len(shipped) == count
        seeds = split_seeds(split)
        if split == "test":
            assert seeds == [seed + k for k in range(count)]
        for k, schedule in enumerate(shipped):
            assert schedule == draw_schedule(np.random.default_rng(seeds[k]), 12.0)
            assert schedule_from_dict(schedule_to_dict(schedule)) == schedule


def test_validation_schedules_are_stratified_by_mean_rate() -> None:
    """The 8 validation schedules sit at the midpoints of 8 equal-count bins of a 64-draw pool's mean
    rates: one per bin, and their mean rate is within 10% of the pool's (the first 8 plain draws were at
    0.86 against the pool's 1.48). Any prefix spreads: the first 4 come from bins 0, 4, 2, 6."""
    count, seed = FIXED_SPLITS["validation"]
    pool = sorted(
        (mean_rate(draw_schedule(np.random.default_rng(s), 12.0), 12.0), s) for s in range(seed, seed + 64)
    )
    rank = {s: r for r, (_, s) in enumerate(pool)}
    bins = [rank[s] // 8 for s in split_seeds("validation")]
    assert bins == spread_order(count) == [0, 4, 2, 6, 1, 5, 3, 7]
    chosen = np.mean([mean_rate(x, 12.0) for x in fixed_schedules("validation")])
    pool_mean = np.mean([m for m, _ in pool])
    assert abs(chosen / pool_mean - 1.0) < 0.1
    assert sorted(spread_order(5)) == list(range(5)) and spread_order(1) == [0]


@pytest.mark.parametrize(
    "data, message",
    [
        ({"times": [0, 1], "rates": [1, 0]}, "needs shear"),
        ("fast", "schedule must be"),
        ({"times": [0, 2, 1], "rates": [1, 1, 1]}, "times must increase"),
    ],
)
def test_bad_schedules_are_refused(data, message) -> None:
    with pytest.raises(ValueError, match=message):
        schedule_from_dict(data)
    with pytest.raises(ValueError, match="split must be one of"):
        fixed_schedules("train")
    with pytest.raises(ValueError, match="rate_range"):
        draw_schedule(np.random.default_rng(0), 1.0, rate_range=(0.0, 1.0))
