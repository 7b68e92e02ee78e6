"""PCG solve of the block-sparse resistance system against a dense direct solve."""

from __future__ import annotations

import numpy as np
import pytest

from sim.config import SimulationConfig
from sim.geometry.configurations import random_packing
from sim.geometry.neighbors import group_by_particle
from sim.hydrodynamics.elimination_order import elimination_order, relabel_system
from sim.hydrodynamics.resistance_solver import (
    NEGLIGIBLE_FORCING,
    block_matvec,
    cholesky_blocks,
    dilu_factor,
    pairs_are_sorted,
    scaled_dilu_factor,
    solve_resistance,
    solve_resistance_in_order,
)
from sim.pair_system import pair_system
from sim.step_parameters import step_parameters


def _random_system(seed: int, n: int = 20, m: int = 40):
    """Random block-sparse SPD matrix: drag-like diagonal plus PSD pair blocks (B B^T per pair)."""
    rng = np.random.default_rng(seed)
    pairs = []
    while len(pairs) < m:
        i, j = sorted(rng.choice(n, 2, replace=False))
        if (i, j) not in pairs:
            pairs.append((i, j))
    pairs = np.array(sorted(pairs), dtype=np.int64)
    dense = np.zeros((6 * n, 6 * n))
    diag = np.zeros((n, 6, 6))
    off = np.zeros((m, 6, 6))
    for p in range(n):
        diag[p] = np.eye(6) * 6 * np.pi
    for k, (i, j) in enumerate(pairs):
        b = rng.normal(size=(12, 3)) * rng.uniform(0.1, 30.0)
        blk = b @ b.T  # PSD 12x12 pair matrix, condition up to ~1e3 relative to the drag
        diag[i] += blk[:6, :6]
        diag[j] += blk[6:, 6:]
        off[k] = blk[:6, 6:]
    for p in range(n):
        dense[6 * p : 6 * p + 6, 6 * p : 6 * p + 6] = diag[p]
    for k, (i, j) in enumerate(pairs):
        dense[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = off[k]
        dense[6 * j : 6 * j + 6, 6 * i : 6 * i + 6] = off[k].T
    return diag, off, pairs, dense, rng


def test_matvec_and_solve_match_dense() -> None:
    """Solution to the stated tolerance: ||x - x_dense|| / ||x_dense|| <= cond * tol (here < 1e-7)."""
    diag, off, pairs, dense, rng = _random_system(0)
    n = diag.shape[0]
    x = rng.normal(size=(n, 6))
    assert np.allclose(block_matvec(diag, off, pairs, x).ravel(), dense @ x.ravel(), rtol=1e-13, atol=1e-10)
    b = rng.normal(size=(n, 6))
    sol, iterations, residual = solve_resistance(diag, off, pairs, b, np.zeros((n, 6)), 1e-12, 10000)
    exact = np.linalg.solve(dense, b.ravel())
    assert iterations > 0 and residual <= 1e-12
    assert np.linalg.norm(sol.ravel() - exact) / np.linalg.norm(exact) < 1e-7


def test_warm_start_converges_faster_to_same_answer() -> None:
    diag, off, pairs, dense, rng = _random_system(1)
    n = diag.shape[0]
    b = rng.normal(size=(n, 6))
    cold, it_cold, _ = solve_resistance(diag, off, pairs, b, np.zeros((n, 6)), 1e-10, 10000)
    guess = cold + 1e-6 * rng.normal(size=cold.shape)
    warm, it_warm, _ = solve_resistance(diag, off, pairs, b, guess, 1e-10, 10000)
    assert it_warm < it_cold
    assert np.abs(warm - cold).max() < 1e-8 * np.abs(cold).max()


def test_failure_is_reported_not_hidden() -> None:
    """A non-positive diagonal block or an exhausted iteration cap returns iterations = -1."""
    diag, off, pairs, _, rng = _random_system(2)
    n = diag.shape[0]
    b = rng.normal(size=(n, 6))
    _, it, _ = solve_resistance(diag, off, pairs, b, np.zeros((n, 6)), 1e-14, 2)
    assert it == -1
    bad = diag.copy()
    bad[3] = -np.eye(6)
    _, ok = cholesky_blocks(bad)
    assert not ok
    _, it, _ = solve_resistance(bad, off, pairs, b, np.zeros((n, 6)), 1e-8, 100)
    assert it == -1


def test_zero_rhs_gives_zero() -> None:
    diag, off, pairs, _, _ = _random_system(3)
    n = diag.shape[0]
    sol, it, res = solve_resistance(diag, off, pairs, np.zeros((n, 6)), np.ones((n, 6)), 1e-8, 100)
    assert it == 0 and res == 0.0 and not sol.any()


@pytest.mark.parametrize("eisenstat", [True, False])
def test_warm_start_at_a_faded_forcing_is_dropped(eisenstat: bool) -> None:
    """A quiescent run's repulsion can fall by many orders between steps: a warm start at the old
    scale (here 1e10 x the new solution) leaves a residual that rounding keeps far above tol ||b||.
    The solver must then start from zero and converge to the dense solution (the stated tolerance, as
    in test_matvec_and_solve_match_dense); before the fix it hit the iteration cap."""
    diag, off, pairs, dense, rng = _random_system(4)
    n = diag.shape[0]
    b = 1e-15 * rng.normal(size=(n, 6))
    exact = np.linalg.solve(dense, b.ravel())
    guess = 1e10 * exact.reshape(n, 6) + 1e-6 * rng.normal(size=(n, 6))
    sol, it, res = solve_resistance_in_order(diag, off, pairs, b, guess, 1e-10, 2000, eisenstat)
    assert it > 0 and res <= 1e-10
    assert np.linalg.norm(sol.ravel() - exact) / np.linalg.norm(exact) < 1e-6


def test_negligible_forcing_gives_zero() -> None:
    """Below NEGLIGIBLE_FORCING the CG inner products would underflow: the solution is zero."""
    diag, off, pairs, _, rng = _random_system(5)
    n = diag.shape[0]
    b = 0.5 * NEGLIGIBLE_FORCING * rng.normal(size=(n, 6)) / np.sqrt(6 * n)
    sol, it, res = solve_resistance(diag, off, pairs, b, np.ones((n, 6)), 1e-8, 100)
    assert it == 0 and res == 0.0 and not sol.any()


def _chain_system(seed: int, n: int = 12):
    """A chain 0-1-2-...: its pair graph is a tree, on which DILU is the exact LDL^T factorisation."""
    rng = np.random.default_rng(seed)
    pairs = np.array([[p, p + 1] for p in range(n - 1)], dtype=np.int64)
    diag = np.array([np.eye(6) * 6 * np.pi for _ in range(n)])
    off = np.zeros((n - 1, 6, 6))
    for k in range(n - 1):
        b = rng.normal(size=(12, 4)) * 40.0  # stiff, like near-contact lubrication
        blk = b @ b.T
        diag[k] += blk[:6, :6]
        diag[k + 1] += blk[6:, 6:]
        off[k] = blk[:6, 6:]
    return diag, off, pairs, rng


def test_dilu_is_exact_on_a_tree() -> None:
    """On a chain PCG with DILU converges in one iteration (M = A), to the dense answer (1e-10)."""
    diag, off, pairs, rng = _chain_system(4)
    n = diag.shape[0]
    b = rng.normal(size=(n, 6))
    sol, iterations, residual = solve_resistance(diag, off, pairs, b, np.zeros((n, 6)), 1e-10, 100)
    assert iterations == 1 and residual <= 1e-10
    np.testing.assert_allclose(block_matvec(diag, off, pairs, sol), b, rtol=1e-9, atol=1e-9)


def test_dilu_factor_detects_indefinite_blocks_and_unsorted_pairs_fall_back() -> None:
    """Label-order PCG falls back to block-Jacobi for unsorted pairs (right answer, more iterations)."""
    diag, off, pairs, rng = _chain_system(5)
    bad = diag.copy()
    bad[0] = -np.eye(6)
    _, ok = dilu_factor(bad, off, pairs)
    assert not ok
    assert pairs_are_sorted(pairs)
    assert not pairs_are_sorted(pairs[::-1].copy())
    flipped = pairs[::-1].copy()
    off_flipped = off[::-1].copy()
    n = diag.shape[0]
    b = rng.normal(size=(n, 6))
    sol, iterations, _ = solve_resistance_in_order(
        diag, off_flipped, flipped, b, np.zeros((n, 6)), 1e-10, 1000
    )
    assert iterations > 1
    np.testing.assert_allclose(block_matvec(diag, off_flipped, flipped, sol), b, rtol=1e-8, atol=1e-8)


def test_any_labelling_of_a_tree_is_solved_exactly() -> None:
    """Shuffled labels, reversed pair order and swapped pair ends: the elimination order recovers the
    tree, so DILU is again the exact factorisation and PCG converges in one iteration (to 1e-10)."""
    diag, off, pairs, rng = _chain_system(6, n=40)
    n = diag.shape[0]
    labels = rng.permutation(n)
    shuffled_pairs = labels[pairs][::-1].copy()
    shuffled_off = off[::-1].copy()
    swap = rng.random(len(pairs)) < 0.5
    shuffled_pairs[swap] = shuffled_pairs[swap][:, ::-1]
    shuffled_off[swap] = np.transpose(shuffled_off[swap], (0, 2, 1))
    shuffled_diag = np.empty_like(diag)
    shuffled_diag[labels] = diag
    b = rng.normal(size=(n, 6))
    _, in_label_order, _ = solve_resistance_in_order(
        shuffled_diag, shuffled_off, shuffled_pairs, b, np.zeros((n, 6)), 1e-10, 1000
    )
    sol, iterations, residual = solve_resistance(
        shuffled_diag, shuffled_off, shuffled_pairs, b, np.zeros((n, 6)), 1e-10, 100
    )
    assert in_label_order > 1
    assert iterations == 1 and residual <= 1e-10
    np.testing.assert_allclose(
        block_matvec(shuffled_diag, shuffled_off, shuffled_pairs, sol), b, rtol=1e-9, atol=1e-9
    )


@pytest.mark.parametrize("seed", [7, 8])
def test_eisenstat_iteration_matches_plain_pcg(seed: int) -> None:
    """Eisenstat's form of DILU-PCG has the same iterates as plain PCG in exact arithmetic: same answer
    (dense solve, 1e-7 relative, i.e. condition number x tolerance), true residual within the tolerance,
    and iteration counts within 2 (the transformed residual only decides when to check the true one)."""
    diag, off, pairs, dense, rng = _random_system(seed, n=30, m=70)
    n = diag.shape[0]
    b = rng.normal(size=(n, 6))
    exact = np.linalg.solve(dense, b.ravel())
    results = {}
    for eisenstat in (False, True):
        sol, iterations, residual = solve_resistance_in_order(
            diag, off, pairs, b, np.zeros((n, 6)), 1e-10, 10000, eisenstat
        )
        true = np.linalg.norm(b.ravel() - dense @ sol.ravel()) / np.linalg.norm(b)
        assert iterations > 0 and residual <= 1e-10 and true <= 1e-10
        assert np.linalg.norm(sol.ravel() - exact) / np.linalg.norm(exact) < 1e-7
        results[eisenstat] = iterations
    assert abs(results[True] - results[False]) <= 2


def _dense_dilu(diag, off, pairs):
    """DILU diagonal ``D~_p = A_pp - sum_{i<p} A_pi D~_i^-1 A_ip`` by dense numpy (independent twin)."""
    d_tilde = [blk.copy() for blk in diag]
    for p in range(diag.shape[0]):
        for k, (i, j) in enumerate(pairs):
            if j == p:
                d_tilde[p] -= off[k].T @ np.linalg.solve(d_tilde[i], off[k])
    return np.array(d_tilde)


@pytest.mark.parametrize("seed", [10, 11])
def test_scaled_dilu_factor_matches_dense_construction(seed: int) -> None:
    """The scaled system against numpy: ``C C^T = D~`` (DILU recurrence), ``A^_ij = C_i^-1 A_ij C_j^-T``,
    ``E^_p = 2 I - C_p^-1 A_pp C_p^-T`` and ``1/diag(C)``, all to 1e-12 relative."""
    diag, off, pairs, _, _ = _random_system(seed, n=25, m=60)
    n = diag.shape[0]
    lstart, lorder = group_by_particle(pairs[:, 1], np.arange(pairs.shape[0]), n)
    chol, inv_diag, scaled, e_hat, ok = scaled_dilu_factor(diag, off, pairs, lstart, lorder)
    assert ok
    d_tilde = _dense_dilu(diag, off, pairs)
    scale = np.abs(d_tilde).max()
    np.testing.assert_allclose(chol @ np.transpose(chol, (0, 2, 1)), d_tilde, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(inv_diag, 1.0 / np.diagonal(chol, axis1=1, axis2=2), rtol=1e-14)
    inv = np.linalg.inv(chol)
    for k, (i, j) in enumerate(pairs):
        expected = inv[i] @ off[k] @ inv[j].T
        np.testing.assert_allclose(scaled[k], expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    for p in range(n):
        expected = 2.0 * np.eye(6) - inv[p] @ diag[p] @ inv[p].T
        np.testing.assert_allclose(e_hat[p], expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("seed", [3, 4])
def test_solve_of_a_dense_packing_matches_dense_solve(seed: int) -> None:
    """The simulator's own system (N = 64, phi = 0.45, gaps down to 1e-4: lubrication condition
    ~1e3-1e4), solved in elimination order by the scaled Eisenstat PCG at tolerance 1e-14, equals a
    dense LAPACK solve to 1e-10 relative; plain DILU-PCG (the reference path) agrees as well."""
    config = SimulationConfig(n_particles=64, volume_fraction=0.45, strain=1.0, seed=seed)
    params = step_parameters(config)
    positions = random_packing(64, 0.45, seed, min_gap=1e-4)
    pairs, _, _, _, diag, off, _, _ = pair_system(positions, 0.0, params)
    order = elimination_order(off, pairs, 64)
    diag, off, pairs = relabel_system(diag, off, pairs, order)
    rng = np.random.default_rng(seed)
    b = rng.normal(size=(64, 6))
    dense = np.zeros((384, 384))
    for p in range(64):
        dense[6 * p : 6 * p + 6, 6 * p : 6 * p + 6] = diag[p]
    for k, (i, j) in enumerate(pairs):
        dense[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = off[k]
        dense[6 * j : 6 * j + 6, 6 * i : 6 * i + 6] = off[k].T
    exact = np.linalg.solve(dense, b.ravel())
    for eisenstat in (True, False):
        sol, iterations, residual = solve_resistance_in_order(
            diag, off, pairs, b, np.zeros((64, 6)), 1e-14, 10000, eisenstat
        )
        assert iterations > 0 and residual <= 1e-14
        assert np.linalg.norm(sol.ravel() - exact) / np.linalg.norm(exact) < 1e-10
