"""Aggregate statistics of evaluation scores with ``rliable`` (Agarwal et al. 2021, NeurIPS, "Deep
reinforcement learning at the edge of the statistical precipice").

Scores are arranged as rliable expects, a matrix ``(runs, tasks)``: for a trained policy the runs are its
training seeds and the tasks the start states (with their schedules) it is played on; for a constant field
or a controller, which is deterministic given the state, the start states are the runs of a single task,
so that its interval reflects the spread over states. Point estimates are the mean (rliable's
``aggregate_mean``: the mean over tasks of the mean over runs) and the interquartile mean (``aggregate_iqm``:
the mean of the middle 50% of all scores). Intervals are 95% percentile intervals of the stratified
bootstrap (runs resampled within each task; :data:`BOOTSTRAP_REPS` replicates, seeded by
:data:`BOOTSTRAP_SEED`, so the same scores always give the same interval). The probability of improvement
``P(X > Y)`` of one method over another is rliable's: per task, the Mann–Whitney statistic of their runs
(ties count one half), averaged over tasks.

With one sample there is no interval (NaN bounds), as with a t-interval.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

import numpy as np

BOOTSTRAP_REPS = 2000
"""Bootstrap replicates per interval: the 2.5% and 97.5% percentiles then move by well under a tenth of
the interval's width between seeds of the bootstrap (checked in tests/test_statistics.py)."""

BOOTSTRAP_SEED = 0
"""Seed of the bootstrap: intervals are a pure function of the scores."""


@contextmanager
def _seeded_bootstrap() -> Iterator[None]:
    """rliable 1.2's stratified bootstrap draws its indices from NumPy's global generator
    (``np.random.choice``) and ignores the ``random_state`` it is given; seed the global generator for the
    call and put the caller's state back afterwards."""
    state = np.random.get_state()  # noqa: NPY002 (rliable uses the legacy global generator)
    np.random.seed(BOOTSTRAP_SEED)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def _clean(matrix: np.ndarray | Sequence[float] | Sequence[Sequence[float]]) -> np.ndarray:
    scores = np.asarray(matrix, dtype=float)
    if scores.ndim == 1:
        scores = scores[np.isfinite(scores)].reshape(-1, 1)  # samples = runs of one task
    if scores.ndim != 2:
        raise ValueError(f"scores must be a vector or a (runs, tasks) matrix, got shape {scores.shape}")
    if not np.all(np.isfinite(scores)):
        raise ValueError("a (runs, tasks) score matrix must be finite (drop failed runs first)")
    return scores


def interval_estimates(
    scores: np.ndarray | Sequence[float] | Sequence[Sequence[float]],
) -> dict[str, float]:
    """Mean and IQM of ``scores`` with their 95% stratified-bootstrap intervals.

    Args:
        scores: a ``(runs, tasks)`` matrix, or a vector of samples (the runs of one task; non-finite
            entries are dropped).

    Returns:
        ``mean``, ``ci_low``, ``ci_high``, ``iqm``, ``iqm_ci_low``, ``iqm_ci_high`` (NaN where there are no
        scores; NaN bounds with a single run).
    """
    from rliable import library, metrics

    x = _clean(scores)
    nan = {k: math.nan for k in ("mean", "ci_low", "ci_high", "iqm", "iqm_ci_low", "iqm_ci_high")}
    if x.size == 0:
        return nan
    mean, iqm = float(metrics.aggregate_mean(x)), float(metrics.aggregate_iqm(x))
    if x.shape[0] < 2:
        return {**nan, "mean": mean, "iqm": iqm}

    def aggregate(s: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_mean(s), metrics.aggregate_iqm(s)])

    with _seeded_bootstrap():
        _, intervals = library.get_interval_estimates({"x": x}, aggregate, reps=BOOTSTRAP_REPS)
    ci = intervals["x"]
    return {
        "mean": mean,
        "ci_low": float(ci[0, 0]),
        "ci_high": float(ci[1, 0]),
        "iqm": iqm,
        "iqm_ci_low": float(ci[0, 1]),
        "iqm_ci_high": float(ci[1, 1]),
    }


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> dict[str, float]:
    """``P(X > Y)`` of method X over method Y on the same tasks, with its 95% stratified-bootstrap interval.

    Args:
        x, y: ``(runs, tasks)`` score matrices with the same tasks (columns); the run counts may differ (a
            deterministic baseline has one run per task).

    Returns:
        ``probability``, ``ci_low``, ``ci_high`` (NaN bounds when neither has more than one run).
    """
    from rliable import library, metrics

    x, y = _clean(x), _clean(y)
    if x.shape[1] != y.shape[1]:
        raise ValueError(f"x and y must have the same tasks (columns), got {x.shape} and {y.shape}")
    point = float(metrics.probability_of_improvement(x, y))
    if max(x.shape[0], y.shape[0]) < 2:
        return {"probability": point, "ci_low": math.nan, "ci_high": math.nan}

    def improvement(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.array([metrics.probability_of_improvement(a, b)])

    with _seeded_bootstrap():
        _, intervals = library.get_interval_estimates({"x,y": [x, y]}, improvement, reps=BOOTSTRAP_REPS)
    ci = intervals["x,y"]
    return {"probability": point, "ci_low": float(ci[0, 0]), "ci_high": float(ci[1, 0])}
