"""Solve ``R_FU . V' = b`` for the block-sparse, symmetric positive-definite resistance matrix.

``R_FU`` is stored as N diagonal 6x6 blocks plus one 6x6 block per lubrication pair (the (i, j) block;
the (j, i) block is its transpose), as produced by
:func:`sim.hydrodynamics.lubrication.assemble_resistance`. It is SPD: the Stokes drag diagonal is positive
definite and each pair's lubrication matrix is positive semi-definite (tested).

The solver is the preconditioned conjugate-gradient method (Hestenes & Stiefel 1952) with a block-Jacobi
preconditioner (exact 6x6 Cholesky solves of the diagonal blocks) and a warm start from the previous
step's solution. It stops when ``||b - R V'||_2 <= tol * ||b||_2``; the default ``tol = 1e-8`` makes the
solver error far below the statistical error of any stress average. Failure to converge is reported,
never hidden.

References:
    Hestenes, M. R. & Stiefel, E. (1952) J. Res. Natl. Bur. Stand. 49, 409-436.
    Saad, Y. (2003) Iterative Methods for Sparse Linear Systems, 2nd ed., SIAM, §9.2 (PCG).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def block_matvec(diag: np.ndarray, off: np.ndarray, pairs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``y = R_FU . x`` for the block-sparse storage.

    Args:
        diag: (N, 6, 6) diagonal blocks.
        off: (M, 6, 6) blocks R[i, j] for ``pairs[k] = (i, j)``; R[j, i] = off[k]^T.
        pairs: (M, 2) int64.
        x: (N, 6).

    Returns:
        (N, 6) product.
    """
    n = diag.shape[0]
    y = np.zeros((n, 6))
    for p in range(n):
        for r in range(6):
            acc = 0.0
            for c in range(6):
                acc += diag[p, r, c] * x[p, c]
            y[p, r] = acc
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        blk = off[k]
        for r in range(6):
            acc_i = 0.0
            acc_j = 0.0
            for c in range(6):
                acc_i += blk[r, c] * x[j, c]
                acc_j += blk[c, r] * x[i, c]
            y[i, r] += acc_i
            y[j, r] += acc_j
    return y


@njit(cache=True)
def cholesky_blocks(diag: np.ndarray) -> tuple[np.ndarray, bool]:
    """Lower Cholesky factors of every 6x6 diagonal block.

    Returns:
        (N, 6, 6) factors and a flag that is False if some block is not positive definite.
    """
    n = diag.shape[0]
    chol = np.zeros((n, 6, 6))
    ok = True
    for p in range(n):
        a = diag[p]
        low = chol[p]
        for r in range(6):
            for c in range(r + 1):
                s = a[r, c]
                for k in range(c):
                    s -= low[r, k] * low[c, k]
                if r == c:
                    if not s > 0.0:  # also catches NaN
                        ok = False
                        s = 1.0
                    low[r, r] = math.sqrt(s)
                else:
                    low[r, c] = s / low[c, c]
    return chol, ok


@njit(cache=True)
def _apply_block_jacobi(chol: np.ndarray, r: np.ndarray, z: np.ndarray) -> None:
    """``z = D^-1 r`` using the Cholesky factors of the diagonal blocks."""
    n = chol.shape[0]
    tmp = np.empty(6)
    for p in range(n):
        low = chol[p]
        for a in range(6):
            s = r[p, a]
            for k in range(a):
                s -= low[a, k] * tmp[k]
            tmp[a] = s / low[a, a]
        for a in range(5, -1, -1):
            s = tmp[a]
            for k in range(a + 1, 6):
                s -= low[k, a] * z[p, k]
            z[p, a] = s / low[a, a]


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    s = 0.0
    for p in range(a.shape[0]):
        for c in range(a.shape[1]):
            s += a[p, c] * b[p, c]
    return s


@njit(cache=True)
def solve_resistance(
    diag: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    rhs: np.ndarray,
    initial_guess: np.ndarray,
    tolerance: float,
    max_iterations: int,
) -> tuple[np.ndarray, int, float]:
    """Block-Jacobi preconditioned conjugate gradients for ``R_FU . x = rhs``.

    Args:
        diag, off, pairs: block-sparse R_FU (see :func:`block_matvec`).
        rhs: (N, 6) right-hand side (forces and torques).
        initial_guess: (N, 6) warm start (e.g. the previous step's solution).
        tolerance: relative residual target ``||r|| / ||rhs||``.
        max_iterations: iteration cap.

    Returns:
        solution (N, 6), iterations used (-1 if the cap was reached or a diagonal block was not
        positive definite), final relative residual.
    """
    n = diag.shape[0]
    chol, ok = cholesky_blocks(diag)
    bnorm = math.sqrt(_dot(rhs, rhs))
    x = initial_guess.copy()
    if not ok or not math.isfinite(bnorm):
        return x, -1, np.inf
    if bnorm == 0.0:
        return np.zeros((n, 6)), 0, 0.0
    r = rhs - block_matvec(diag, off, pairs, x)
    rnorm = math.sqrt(_dot(r, r))
    if rnorm <= tolerance * bnorm:
        return x, 0, rnorm / bnorm
    z = np.empty((n, 6))
    _apply_block_jacobi(chol, r, z)
    p = z.copy()
    rz = _dot(r, z)
    for it in range(1, max_iterations + 1):
        ap = block_matvec(diag, off, pairs, p)
        pap = _dot(p, ap)
        if not pap > 0.0:  # also catches NaN
            return x, -1, rnorm / bnorm
        alpha = rz / pap
        for q in range(n):
            for c in range(6):
                x[q, c] += alpha * p[q, c]
                r[q, c] -= alpha * ap[q, c]
        rnorm = math.sqrt(_dot(r, r))
        if rnorm <= tolerance * bnorm:
            return x, it, rnorm / bnorm
        _apply_block_jacobi(chol, r, z)
        rz_new = _dot(r, z)
        beta = rz_new / rz
        rz = rz_new
        for q in range(n):
            for c in range(6):
                p[q, c] = z[q, c] + beta * p[q, c]
    return x, -1, rnorm / bnorm
