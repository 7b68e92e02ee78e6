"""Elimination order of the DILU preconditioner: spanning forest, leaves-first order, relabelling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from sim.hydrodynamics.elimination_order import (
    block_weights,
    elimination_order,
    leaves_first_order,
    maximum_spanning_forest,
    relabel_system,
)


def _random_graph(seed: int, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    edges: set[tuple[int, int]] = set()
    while len(edges) < m:
        i, j = rng.choice(n, 2, replace=False)
        edges.add((int(min(i, j)), int(max(i, j))))
    pairs = np.array(sorted(edges), dtype=np.int64)
    return pairs, rng.uniform(1.0, 100.0, size=m)  # distinct weights (almost surely): unique forest


@pytest.mark.parametrize("seed, n, m", [(0, 30, 45), (1, 60, 50), (2, 100, 300)])
def test_forest_is_the_maximum_one_scipy_finds(seed: int, n: int, m: int) -> None:
    """Independent reference: scipy's minimum spanning tree of 1/weight (same forest when weights are
    distinct). The forest has N - (number of components) edges; with m = 50 < n = 60 it is a forest."""
    pairs, w = _random_graph(seed, n, m)
    mask = maximum_spanning_forest(pairs, w, n)
    graph = coo_matrix((1.0 / w, (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    reference = minimum_spanning_tree(graph).tocoo()
    expected = {(int(min(a, b)), int(max(a, b))) for a, b in zip(reference.row, reference.col, strict=True)}
    assert {tuple(p) for p in pairs[mask].tolist()} == expected
    n_components, _ = connected_components(graph, directed=False)
    assert mask.sum() == n - n_components


@pytest.mark.parametrize("seed", [3, 4])
def test_order_puts_every_particle_after_its_descendants(seed: int) -> None:
    """No-fill property: when a particle is eliminated at most one of its forest neighbours (its
    parent) is still waiting, so Gaussian elimination of the forest part creates no fill."""
    n = 80
    pairs, w = _random_graph(seed, n, 120)
    mask = maximum_spanning_forest(pairs, w, n)
    order = leaves_first_order(pairs, mask, n)
    assert sorted(order.tolist()) == list(range(n))
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    later = np.zeros(n, dtype=np.int64)
    for i, j in pairs[mask]:
        later[i if rank[i] < rank[j] else j] += 1
    assert later.max() <= 1


def test_relabelled_matrix_is_the_permuted_dense_matrix() -> None:
    """P R P^T by dense indexing equals the relabelled block-sparse matrix (exact: only copies)."""
    rng = np.random.default_rng(5)
    n = 12
    pairs, _ = _random_graph(5, n, 20)
    diag = rng.normal(size=(n, 6, 6))
    off = rng.normal(size=(len(pairs), 6, 6))
    order = elimination_order(off, pairs, n)

    def dense(d: np.ndarray, o: np.ndarray, p: np.ndarray) -> np.ndarray:
        a = np.zeros((6 * n, 6 * n))
        for q in range(n):
            a[6 * q : 6 * q + 6, 6 * q : 6 * q + 6] = d[q]
        for k, (i, j) in enumerate(p):
            a[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = o[k]
            a[6 * j : 6 * j + 6, 6 * i : 6 * i + 6] = o[k].T
        return a

    new_diag, new_off, new_pairs = relabel_system(diag, off, pairs, order)
    assert np.all(new_pairs[:, 0] < new_pairs[:, 1])
    assert np.all(np.diff(new_pairs[:, 0]) >= 0)
    dof = (6 * order[:, None] + np.arange(6)[None, :]).ravel()
    permuted = dense(diag, off, pairs)[np.ix_(dof, dof)]
    np.testing.assert_array_equal(dense(new_diag, new_off, new_pairs), permuted)


def test_block_weights_are_frobenius_norms() -> None:
    off = np.random.default_rng(6).normal(size=(7, 6, 6))
    np.testing.assert_allclose(block_weights(off), np.linalg.norm(off, axis=(1, 2)), rtol=1e-14)
