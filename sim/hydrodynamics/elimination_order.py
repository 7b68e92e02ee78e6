"""Elimination order for the block DILU preconditioner: leaves first along the strongest couplings.

An incomplete factorisation depends on the order in which the unknowns are eliminated. In a dense
suspension the lubrication blocks of near-contact pairs are O(1/xi) and dominate ``R_FU``; the
preconditioner has to capture that network of strong links. We take a maximum-weight spanning forest
of the pair graph (Kruskal 1956; weight of a pair = Frobenius norm of its 6x6 block) and eliminate
every tree from its leaves towards its root (reversed depth-first preorder: each particle comes after
all of its descendants). Eliminating a particle whose other tree neighbours are already eliminated
creates no fill along tree edges, so block DILU is the exact LDL^T factorisation of the forest part
of the matrix; only the weaker, loop-closing pairs are approximated. Spanning-tree preconditioners go
back to Vaidya (1991); here the tree only fixes the order, and DILU still uses every pair.

At phi = 0.45 in steady shear (benchmarks/run.py, warm-started PCG to 1e-8) DILU in the particles' own
(arbitrary) labels needs 68-85 iterations per step for N = 250-2000; in this order it needs 31-46.

References:
    Kruskal, J. B. (1956) Proc. Amer. Math. Soc. 7, 48-50.
    Vaidya, P. M. (1991) Solving linear equations with symmetric diagonally dominant matrices by
        constructing good preconditioners, unpublished manuscript (talk at the IMA, Minneapolis).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sim.geometry.neighbors import group_by_particle


@njit(cache=True)
def block_weights(off: np.ndarray) -> np.ndarray:
    """Frobenius norm of every (6, 6) pair block: the coupling strength of the pair."""
    weights = np.empty(off.shape[0])
    for k in range(off.shape[0]):
        s = 0.0
        for r in range(6):
            for c in range(6):
                s += off[k, r, c] * off[k, r, c]
        weights[k] = np.sqrt(s)
    return weights


@njit(cache=True)
def _find(parent: np.ndarray, p: int) -> int:
    """Root of ``p`` in the union-find forest, halving the path on the way."""
    while parent[p] != p:
        parent[p] = parent[parent[p]]
        p = parent[p]
    return p


@njit(cache=True)
def maximum_spanning_forest(pairs: np.ndarray, weights: np.ndarray, n_particles: int) -> np.ndarray:
    """Kruskal's algorithm on the pair graph, heaviest pairs first.

    Args:
        pairs: (M, 2) int64 particle indices in ``[0, N)``.
        weights: (M,) coupling strengths (ties are broken by pair index, so the result is deterministic).
        n_particles: N.

    Returns:
        (M,) bool mask of the pairs in a maximum-weight spanning forest (one tree per connected component).
    """
    order = np.argsort(-weights, kind="mergesort")
    parent = np.arange(n_particles)
    in_forest = np.zeros(pairs.shape[0], dtype=np.bool_)
    joined = 0
    for t in range(order.shape[0]):
        k = order[t]
        a = _find(parent, pairs[k, 0])
        b = _find(parent, pairs[k, 1])
        if a != b:
            parent[a] = b
            in_forest[k] = True
            joined += 1
            if joined == n_particles - 1:
                break
    return in_forest


@njit(cache=True)
def leaves_first_order(pairs: np.ndarray, in_forest: np.ndarray, n_particles: int) -> np.ndarray:
    """Particles ordered so that every particle follows all of its descendants in the forest.

    Each tree is rooted at its lowest-index particle and walked depth first; the preorder is reversed.

    Returns:
        (N,) int64 permutation: ``order[t]`` is the particle eliminated ``t``-th.
    """
    tree = np.flatnonzero(in_forest)
    n_edges = tree.shape[0]
    ends = np.empty(2 * n_edges, dtype=np.int64)  # both directions of every tree edge
    other = np.empty(2 * n_edges, dtype=np.int64)
    for t in range(n_edges):
        k = tree[t]
        ends[2 * t] = pairs[k, 0]
        other[2 * t] = pairs[k, 1]
        ends[2 * t + 1] = pairs[k, 1]
        other[2 * t + 1] = pairs[k, 0]
    start, grouped = group_by_particle(ends, np.arange(2 * n_edges), n_particles)
    visited = np.zeros(n_particles, dtype=np.bool_)
    stack = np.empty(n_particles, dtype=np.int64)
    order = np.empty(n_particles, dtype=np.int64)
    filled = n_particles  # the preorder is written from the back, i.e. reversed on the fly
    for root in range(n_particles):
        if visited[root]:
            continue
        visited[root] = True
        top = 0
        stack[0] = root
        while top >= 0:
            p = stack[top]
            top -= 1
            filled -= 1
            order[filled] = p
            for q in range(start[p], start[p + 1]):
                child = other[grouped[q]]
                if not visited[child]:
                    visited[child] = True
                    top += 1
                    stack[top] = child
    return order


@njit(cache=True)
def relabel_system(
    diag: np.ndarray, off: np.ndarray, pairs: np.ndarray, order: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same block-sparse matrix with particle ``order[t]`` renamed ``t``.

    Returns:
        diagonal blocks, pair blocks and pairs of ``P R P^T``, with every pair ``(i, j)`` written with
        ``i < j`` (the block transposed where the ends swap) and the pairs grouped by increasing ``i``
        (the layout :func:`sim.hydrodynamics.resistance_solver.dilu_factor` needs).
    """
    n = diag.shape[0]
    m = pairs.shape[0]
    rank = np.empty(n, dtype=np.int64)
    for t in range(n):
        rank[order[t]] = t
    new_diag = np.empty_like(diag)
    for t in range(n):
        new_diag[t] = diag[order[t]]
    renamed = np.empty((m, 2), dtype=np.int64)
    swapped = np.zeros(m, dtype=np.bool_)
    for k in range(m):
        i = rank[pairs[k, 0]]
        j = rank[pairs[k, 1]]
        if i < j:
            renamed[k, 0] = i
            renamed[k, 1] = j
        else:
            renamed[k, 0] = j
            renamed[k, 1] = i
            swapped[k] = True
    start, grouped = group_by_particle(renamed[:, 0], np.arange(m), n)
    new_pairs = np.empty((m, 2), dtype=np.int64)
    new_off = np.empty_like(off)
    for t in range(m):
        k = grouped[t]
        new_pairs[t, 0] = renamed[k, 0]
        new_pairs[t, 1] = renamed[k, 1]
        if swapped[k]:
            for r in range(6):
                for c in range(6):
                    new_off[t, r, c] = off[k, c, r]
        else:
            new_off[t] = off[k]
    return new_diag, new_off, new_pairs


@njit(cache=True)
def elimination_order(off: np.ndarray, pairs: np.ndarray, n_particles: int) -> np.ndarray:
    """Leaves-first order on the maximum spanning forest of the pair couplings (module docstring)."""
    in_forest = maximum_spanning_forest(pairs, block_weights(off), n_particles)
    return leaves_first_order(pairs, in_forest, n_particles)
