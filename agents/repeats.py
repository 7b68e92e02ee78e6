"""Several realisations of each held-out episode, and the per-state averages over them.

An evaluation plays each start state (and, in the thickening-control environments, its rate schedule)
``repeats`` times, realisation ``k = 0 .. repeats-1`` of :mod:`dipenv.realisations` (``k = 0`` is the stored
state itself, so one repeat is the plain evaluation). The realisations of one state are not independent
samples of a controller's skill across states: they measure the chaotic noise of one episode. Every
statistic over states therefore first averages a state's realisations (:func:`per_state`), and the
intervals stay intervals over states (or over training seeds and states).

Stored episodes carry ``realisation`` (missing in files written before it existed: 0). The per-state
statistics group by ``index``; an episode without one (a hand-made or pre-index record) counts as a state
of its own, numbered by its position in the list.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np


def realisation_of(episode: dict[str, Any]) -> int:
    """The realisation of a stored episode (0 where the record predates realisations)."""
    return int(episode.get("realisation", 0))


def episode_key(episode: dict[str, Any]) -> tuple[int, int]:
    """``(start-state index, realisation)`` of a stored episode."""
    return int(episode["index"]), realisation_of(episode)


def wanted_keys(indices: Iterable[int], repeats: int) -> list[tuple[int, int]]:
    """Every ``(index, realisation)`` an evaluation of ``indices`` with ``repeats`` realisations needs,
    state by state."""
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    return [(int(i), k) for i in indices for k in range(repeats)]


def select(episodes: Sequence[dict[str, Any]], indices: Iterable[int], repeats: int) -> list[dict[str, Any]]:
    """The episodes of ``indices`` and realisations ``0 .. repeats-1``, sorted by state then realisation
    (a stored record may hold more)."""
    keys = set(wanted_keys(indices, repeats))
    return sorted((e for e in episodes if episode_key(e) in keys), key=episode_key)


def missing(
    episodes: Sequence[dict[str, Any]], indices: Iterable[int], repeats: int
) -> list[tuple[int, int]]:
    """The ``(index, realisation)`` pairs of :func:`wanted_keys` that ``episodes`` lacks."""
    have = {episode_key(e) for e in episodes}
    return [key for key in wanted_keys(indices, repeats) if key not in have]


def _by_state(episodes: Sequence[dict[str, Any]], key: str) -> dict[int, list[float]]:
    """Metric ``key`` of each episode, grouped by start state (``index``; an episode without one is a
    state of its own, numbered by its position in the list)."""
    groups: dict[int, list[float]] = {}
    for position, episode in enumerate(episodes):
        groups.setdefault(int(episode.get("index", position)), []).append(float(episode[key]))
    return groups


def per_state(episodes: Sequence[dict[str, Any]], key: str) -> tuple[list[int], np.ndarray]:
    """The states (sorted) and, per state, the mean of metric ``key`` over its realisations (NaN where
    every realisation of that state is NaN, e.g. failed)."""
    groups = _by_state(episodes, key)
    states = sorted(groups)
    values = [groups[s] for s in states]
    means = np.array([np.nanmean(v) if np.isfinite(v).any() else math.nan for v in values], dtype=float)
    return states, means


def within_state_sd(episodes: Sequence[dict[str, Any]], key: str) -> float:
    """The pooled standard deviation of metric ``key`` between realisations of the same state (the noise
    of one episode, over the finite values); NaN with fewer than two realisations per state."""
    groups = {s: [x for x in v if math.isfinite(x)] for s, v in _by_state(episodes, key).items()}
    squares, dof = 0.0, 0
    for values in groups.values():
        if len(values) > 1:
            squares += float(np.sum((np.asarray(values) - np.mean(values)) ** 2))
            dof += len(values) - 1
    return math.sqrt(squares / dof) if dof else math.nan
