"""agents.statistics: rliable's point estimates and stratified-bootstrap intervals, checked against
numbers computed here by hand, and the bootstrap's reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from agents.statistics import interval_estimates, probability_of_improvement


def test_point_estimates_are_the_mean_and_the_interquartile_mean() -> None:
    """IQM of 8 samples = mean of the middle 4 (25% trimmed from each end, as scipy's trim_mean); the
    mean of a (runs, tasks) matrix is the mean over tasks of the mean over runs."""
    x = np.array([5.0, -1.0, 2.0, 9.0, 3.0, 4.0, 100.0, 0.0])
    out = interval_estimates(x)
    assert out["mean"] == pytest.approx(x.mean(), rel=1e-12)
    assert out["iqm"] == pytest.approx(np.mean([2.0, 3.0, 4.0, 5.0]), rel=1e-12)
    assert out["iqm"] == pytest.approx(stats.trim_mean(x, 0.25), rel=1e-12)
    matrix = np.array([[1.0, 10.0], [3.0, 30.0], [5.0, 20.0]])
    assert interval_estimates(matrix)["mean"] == pytest.approx((3.0 + 20.0) / 2, rel=1e-12)


def test_bootstrap_interval_covers_the_mean_and_shrinks_with_the_sample() -> None:
    """A percentile bootstrap interval of the mean of n normal samples has a half-width close to
    1.96 s / sqrt(n) (within 15% at n = 200: the bootstrap's own noise with 2000 replicates is ~3%, the
    percentile interval's small-sample bias below 1%), and the same scores give the same interval."""
    rng = np.random.default_rng(3)
    x = rng.normal(2.0, 1.5, size=200)
    out = interval_estimates(x)
    half = (out["ci_high"] - out["ci_low"]) / 2
    assert half == pytest.approx(1.96 * x.std(ddof=1) / math.sqrt(x.size), rel=0.15)
    assert out["ci_low"] < out["mean"] < out["ci_high"]
    np.random.seed(123)  # noqa: NPY002  (the caller's global generator: neither used nor moved by the bootstrap)
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    assert interval_estimates(x) == out
    assert np.array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    assert out["iqm_ci_low"] < out["iqm"] < out["iqm_ci_high"]


def test_one_sample_has_no_interval_and_non_finite_samples_are_dropped() -> None:
    out = interval_estimates([4.0, math.nan])
    assert out["mean"] == 4.0 and math.isnan(out["ci_low"]) and math.isnan(out["iqm_ci_high"])
    assert math.isnan(interval_estimates([])["mean"])
    with pytest.raises(ValueError, match="finite"):
        interval_estimates(np.array([[1.0, math.nan], [2.0, 3.0]]))


def test_probability_of_improvement_counts_wins_per_task() -> None:
    """Per task, the fraction of (x run, y run) pairs with x > y (ties one half), averaged over tasks:
    5 seeds against one deterministic run per state."""
    x = np.array([[1.0, 5.0], [2.0, 6.0], [3.0, 7.0], [4.0, 8.0], [5.0, 9.0]])
    y = np.array([[2.5, 5.0]])
    # task 0: 3 of 5 above 2.5 -> 0.6; task 1: 4 above and one tie at 5 -> (4 + 0.5) / 5 = 0.9
    out = probability_of_improvement(x, y)
    assert out["probability"] == pytest.approx((0.6 + 0.9) / 2, rel=1e-12)
    assert out["ci_low"] <= out["probability"] <= out["ci_high"]
    with pytest.raises(ValueError, match="same tasks"):
        probability_of_improvement(x, np.array([[1.0, 2.0, 3.0]]))
