"""Solve ``R_FU . V' = b`` for the block-sparse, symmetric positive-definite resistance matrix.

``R_FU`` is stored as N diagonal 6x6 blocks plus one 6x6 block per lubrication pair (the (i, j) block;
the (j, i) block is its transpose), as produced by
:func:`sim.hydrodynamics.lubrication.assemble_resistance`. It is SPD: the Stokes drag diagonal is positive
definite and each pair's lubrication matrix is positive semi-definite (tested).

The solver is the preconditioned conjugate-gradient method (Hestenes & Stiefel 1952) with a block
DILU preconditioner (Saad 2003 §10.3: incomplete LDL^T on the pair pattern that modifies only the diagonal
blocks, ``M = (D~ + L) D~^-1 (D~ + L^T)`` with ``D~_p = A_pp - sum_{k<p} A_pk D~_k^-1 A_kp``). The
particles are eliminated leaves first along a maximum spanning forest of the pair couplings
(:mod:`sim.hydrodynamics.elimination_order`), so M is exact on the forest and only loop-closing pairs
are approximated. The DILU iteration uses Eisenstat's (1981) trick, which folds the product with
``R_FU`` into the two preconditioner sweeps (10-15% faster per solve, same iterates), on the system
scaled by the Cholesky factors ``C`` of the modified diagonal blocks, ``C^-1 R_FU C^-T``
(:func:`scaled_dilu_factor`): its DILU diagonal is the identity, so the sweeps are plain 6x6 block
products, with no triangular solves and no divisions on the critical path (issue 22, N = 300 at the
environments' settings: 5.0 -> 1.7 ms per solve, same iteration counts, solutions equal to 1e-13
relative at tolerance 1e-12). If a modified
block is not positive definite the block-Jacobi preconditioner (exact
6x6 Cholesky solves of the diagonal blocks) is used instead. The initial guess comes from the caller
(a warm start); when its residual exceeds ``||b||`` it is dropped for zero. That happens when the
forcing falls by orders of magnitude between steps, as in a quiescent run whose only forcing, the
short-range repulsion (range 1e-3 a), fades as pairs part: a warm start at the old scale then leaves
a residual that rounding cannot bring to ``tol * ||b||`` (a DIP run at phi = 0.1 failed that way with
a largest repulsion of 1e-15). A forcing below :data:`NEGLIGIBLE_FORCING` gives ``V' = 0``. The
iteration stops when ``||b - R V'||_2 <= tol * ||b||_2``; the default
``tol = 1e-8`` makes the solver error far below the statistical error of any stress average. Failure
to converge is reported, never hidden.

References:
    Hestenes, M. R. & Stiefel, E. (1952) J. Res. Natl. Bur. Stand. 49, 409-436.
    Saad, Y. (2003) Iterative Methods for Sparse Linear Systems, 2nd ed., SIAM, §9.2 (PCG).
    Eisenstat, S. C. (1981) SIAM J. Sci. Stat. Comput. 2, 1-4.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.neighbors import group_by_particle
from sim.hydrodynamics.elimination_order import elimination_order, relabel_system

NEGLIGIBLE_FORCING = 1e-150
"""``||b||`` (units 6 pi eta a^2 gammadot, or eps E0^2 a^2 when quiescent) below which the solution is
taken as zero: the velocities it would give are far below any resolvable displacement, and the CG
inner products of such a ``b`` would underflow."""


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
def _cholesky_6(a: np.ndarray, low: np.ndarray) -> bool:
    """Lower Cholesky factor of one 6x6 SPD block into ``low``; False if not positive definite."""
    for r in range(6):
        for c in range(r + 1):
            s = a[r, c]
            for k in range(c):
                s -= low[r, k] * low[c, k]
            if r == c:
                if not s > 0.0:  # also catches NaN
                    return False
                low[r, r] = math.sqrt(s)
            else:
                low[r, c] = s / low[c, c]
    return True


@njit(cache=True)
def _cholesky_solve_6(low: np.ndarray, b: np.ndarray, out: np.ndarray, tmp: np.ndarray) -> None:
    """``out = (low low^T)^-1 b`` for one 6-vector (``tmp`` is a 6-vector work buffer)."""
    for a in range(6):
        s = b[a]
        for k in range(a):
            s -= low[a, k] * tmp[k]
        tmp[a] = s / low[a, a]
    for a in range(5, -1, -1):
        s = tmp[a]
        for k in range(a + 1, 6):
            s -= low[k, a] * out[k]
        out[a] = s / low[a, a]


@njit(cache=True)
def cholesky_blocks(diag: np.ndarray) -> tuple[np.ndarray, bool]:
    """Lower Cholesky factors of every 6x6 diagonal block.

    Returns:
        (N, 6, 6) factors and a flag that is False if some block is not positive definite.
    """
    n = diag.shape[0]
    chol = np.zeros((n, 6, 6))
    for p in range(n):
        if not _cholesky_6(diag[p], chol[p]):
            return chol, False
    return chol, True


@njit(cache=True)
def _apply_block_jacobi(chol: np.ndarray, r: np.ndarray, z: np.ndarray, buf: np.ndarray) -> None:
    """``z = D^-1 r`` using the Cholesky factors of the diagonal blocks (``buf``: 6-vector work buffer)."""
    for p in range(chol.shape[0]):
        _cholesky_solve_6(chol[p], r[p], z[p], buf)


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum a * b`` of two (N, 6) arrays, one partial sum per column (six independent chains of
    additions instead of one; the association is fixed by the source, so results are reproducible)."""
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    for p in range(a.shape[0]):
        s0 += a[p, 0] * b[p, 0]
        s1 += a[p, 1] * b[p, 1]
        s2 += a[p, 2] * b[p, 2]
        s3 += a[p, 3] * b[p, 3]
        s4 += a[p, 4] * b[p, 4]
        s5 += a[p, 5] * b[p, 5]
    return ((s0 + s1) + (s2 + s3)) + (s4 + s5)


@njit(cache=True)
def _initial_residual(
    diag: np.ndarray, off: np.ndarray, pairs: np.ndarray, rhs: np.ndarray, x: np.ndarray, bnorm: float
) -> tuple[np.ndarray, float]:
    """Residual ``rhs - A x`` of the warm start ``x`` and its norm; a warm start worse than none
    (residual above ``||rhs||``, module docstring) is replaced by zero in place."""
    r = rhs - block_matvec(diag, off, pairs, x)
    rnorm = math.sqrt(_dot(r, r))
    if rnorm > bnorm:
        x[:, :] = 0.0
        return rhs.copy(), bnorm
    return r, rnorm


@njit(cache=True)
def pairs_are_sorted(pairs: np.ndarray) -> bool:
    """True if every pair has ``i < j`` and ``i`` never decreases (the DILU sweeps need this order)."""
    for k in range(pairs.shape[0]):
        if pairs[k, 0] >= pairs[k, 1]:
            return False
        if k > 0 and pairs[k, 0] < pairs[k - 1, 0]:
            return False
    return True


@njit(cache=True)
def dilu_factor(diag: np.ndarray, off: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, bool]:
    """Cholesky factors of the DILU-modified diagonal blocks ``D~_p = A_pp - sum_{i<p} A_pi D~_i^-1 A_ip``.

    Pairs must be sorted with ``i < j`` and increasing ``i`` (as the neighbour list returns them).

    Returns:
        (N, 6, 6) lower Cholesky factors of ``D~`` and False if some ``D~_p`` is not positive definite.
    """
    lstart, lorder = group_by_particle(pairs[:, 1], np.arange(pairs.shape[0]), diag.shape[0])
    chol, _, _, _, ok = scaled_dilu_factor(diag, off, pairs, lstart, lorder)
    return chol, ok


@njit(cache=True)
def _lower_solve_columns(low: np.ndarray, inv_diag: np.ndarray, blk: np.ndarray, out: np.ndarray) -> None:
    """``out = low^-1 blk`` for a 6x6 ``blk`` (forward substitution on the six columns at once).

    ``inv_diag`` holds ``1/low[a, a]``: no division, and the six columns are independent chains."""
    for a in range(6):
        for c in range(6):
            s = blk[a, c]
            for k in range(a):
                s -= low[a, k] * out[k, c]
            out[a, c] = s * inv_diag[a]


@njit(cache=True)
def _lower_solve_rows(low: np.ndarray, inv_diag: np.ndarray, blk: np.ndarray, out: np.ndarray) -> None:
    """``out = blk low^-T`` for a 6x6 ``blk`` (row ``r`` solves ``low out[r] = blk[r]``; six rows at once)."""
    for a in range(6):
        for r in range(6):
            s = blk[r, a]
            for k in range(a):
                s -= low[a, k] * out[r, k]
            out[r, a] = s * inv_diag[a]


@njit(cache=True)
def scaled_dilu_factor(
    diag: np.ndarray, off: np.ndarray, pairs: np.ndarray, lstart: np.ndarray, lorder: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """DILU factor and the system scaled by it: ``A^ = C^-1 A C^-T`` with ``D~_p = C_p C_p^T``.

    ``D~_p = A_pp - sum_{i<p} W_ip^T W_ip`` with ``W_ip = C_i^-1 A_ip`` (the DILU recurrence of the
    module docstring, ``A_pi D~_i^-1 A_ip = W_ip^T W_ip``), then ``A^_ip = W_ip C_p^-T`` and
    ``E^_p = 2 I - C_p^-1 A_pp C_p^-T``. In the scaled system the DILU diagonal is the identity, so
    the preconditioner sweeps of :func:`_eisenstat_pcg` are plain block products with no 6x6 solves
    (the congruence leaves the DILU recurrence and the PCG iterates unchanged in exact arithmetic).
    Triangular solves multiply by the stored reciprocals of ``diag(C_p)``.

    Args:
        diag: (N, 6, 6) diagonal blocks of ``A``.
        off: (M, 6, 6) pair blocks ``A[i, j]`` of ``pairs[k] = (i, j)``, sorted with ``i < j`` and
            ``i`` non-decreasing (:func:`pairs_are_sorted`).
        pairs: (M, 2) int64.
        lstart, lorder: the pairs grouped by their larger index (``group_by_particle(pairs[:, 1], ...)``).

    Returns:
        ``C`` (N, 6, 6) lower Cholesky factors of ``D~``, ``1/diag(C)`` (N, 6), ``A^`` pair blocks
        (M, 6, 6) in the order of ``pairs``, ``E^`` (N, 6, 6), and False if some ``D~_p`` is not
        positive definite (the other outputs are then incomplete).
    """
    n = diag.shape[0]
    chol = np.zeros((n, 6, 6))
    inv_diag = np.ones((n, 6))
    scaled = np.empty_like(off)
    e_hat = np.empty_like(diag)
    work = np.empty((6, 6))
    tmp = np.empty((6, 6))
    for p in range(n):
        work[:, :] = diag[p]
        for q in range(lstart[p], lstart[p + 1]):
            k = lorder[q]
            w = scaled[k]
            _lower_solve_columns(chol[pairs[k, 0]], inv_diag[pairs[k, 0]], off[k], w)  # W = C_i^-1 A_ip
            for r in range(6):  # work -= W^T W (lower triangle: all _cholesky_6 reads)
                for c in range(r + 1):
                    acc = 0.0
                    for m in range(6):
                        acc += w[m, r] * w[m, c]
                    work[r, c] -= acc
        if not _cholesky_6(work, chol[p]):
            return chol, inv_diag, scaled, e_hat, False
        for a in range(6):
            inv_diag[p, a] = 1.0 / chol[p, a, a]
        for q in range(lstart[p], lstart[p + 1]):
            k = lorder[q]
            tmp[:, :] = scaled[k]
            _lower_solve_rows(chol[p], inv_diag[p], tmp, scaled[k])  # A^_ip = W C_p^-T
        _lower_solve_columns(chol[p], inv_diag[p], diag[p], tmp)
        _lower_solve_rows(chol[p], inv_diag[p], tmp, work)  # C_p^-1 A_pp C_p^-T
        for a in range(6):
            for b in range(6):
                e_hat[p, a, b] = (2.0 if a == b else 0.0) - 0.5 * (work[a, b] + work[b, a])
    return chol, inv_diag, scaled, e_hat, True


@njit(cache=True)
def _apply_dilu(
    chol: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    lstart: np.ndarray,
    lorder: np.ndarray,
    ustart: np.ndarray,
    r: np.ndarray,
    z: np.ndarray,
    y: np.ndarray,
    acc: np.ndarray,
    tmp: np.ndarray,
    buf: np.ndarray,
) -> None:
    """``z = M^-1 r`` with ``M = (D~ + L) D~^-1 (D~ + L^T)``: a forward and a backward block sweep.

    ``y`` (N, 6) and ``acc``, ``tmp``, ``buf`` (6,) are work buffers (no allocation in the sweeps)."""
    n = chol.shape[0]
    _forward_solve(chol, off, pairs, lstart, lorder, r, y, acc, tmp, buf)  # (D~ + L) y = r
    for p in range(n - 1, -1, -1):  # (D~ + L^T) z = D~ y  <=>  z_p = y_p - D~_p^-1 sum_{j>p} A_pj z_j
        for a in range(6):
            acc[a] = 0.0
        for k in range(ustart[p], ustart[p + 1]):
            j = pairs[k, 1]
            blk = off[k]  # A[p, j]
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += blk[a, b] * z[j, b]
                acc[a] += s
        _cholesky_solve_6(chol[p], acc, tmp, buf)
        for a in range(6):
            z[p, a] = y[p, a] - tmp[a]


@njit(cache=True)
def _forward_solve(
    chol: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    lstart: np.ndarray,
    lorder: np.ndarray,
    w: np.ndarray,
    u: np.ndarray,
    acc: np.ndarray,
    tmp: np.ndarray,
    buf: np.ndarray,
) -> None:
    """``u = K^-1 w`` with ``K = D~ + L``: ``u_p = D~_p^-1 (w_p - sum_{i<p} A_pi u_i)``, p ascending."""
    for p in range(chol.shape[0]):
        for a in range(6):
            acc[a] = w[p, a]
        for q in range(lstart[p], lstart[p + 1]):
            k = lorder[q]
            i = pairs[k, 0]
            blk = off[k]  # A[i, p]; A[p, i] = blk^T
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += blk[b, a] * u[i, b]
                acc[a] -= s
        _cholesky_solve_6(chol[p], acc, tmp, buf)
        for a in range(6):
            u[p, a] = tmp[a]


@njit(cache=True)
def _unit_backward_sweep(
    scaled: np.ndarray, pairs: np.ndarray, ustart: np.ndarray, v: np.ndarray, t: np.ndarray
) -> None:
    """``t = (I + L^)^-T v``: ``t_p = v_p - sum_{j>p} A^_pj t_j``, p descending (pairs sorted by i)."""
    for p in range(v.shape[0] - 1, -1, -1):
        a0 = v[p, 0]
        a1 = v[p, 1]
        a2 = v[p, 2]
        a3 = v[p, 3]
        a4 = v[p, 4]
        a5 = v[p, 5]
        for k in range(ustart[p], ustart[p + 1]):
            j = pairs[k, 1]
            blk = scaled[k]
            t0 = t[j, 0]
            t1 = t[j, 1]
            t2 = t[j, 2]
            t3 = t[j, 3]
            t4 = t[j, 4]
            t5 = t[j, 5]
            a0 -= (
                blk[0, 0] * t0
                + blk[0, 1] * t1
                + blk[0, 2] * t2
                + blk[0, 3] * t3
                + blk[0, 4] * t4
                + blk[0, 5] * t5
            )
            a1 -= (
                blk[1, 0] * t0
                + blk[1, 1] * t1
                + blk[1, 2] * t2
                + blk[1, 3] * t3
                + blk[1, 4] * t4
                + blk[1, 5] * t5
            )
            a2 -= (
                blk[2, 0] * t0
                + blk[2, 1] * t1
                + blk[2, 2] * t2
                + blk[2, 3] * t3
                + blk[2, 4] * t4
                + blk[2, 5] * t5
            )
            a3 -= (
                blk[3, 0] * t0
                + blk[3, 1] * t1
                + blk[3, 2] * t2
                + blk[3, 3] * t3
                + blk[3, 4] * t4
                + blk[3, 5] * t5
            )
            a4 -= (
                blk[4, 0] * t0
                + blk[4, 1] * t1
                + blk[4, 2] * t2
                + blk[4, 3] * t3
                + blk[4, 4] * t4
                + blk[4, 5] * t5
            )
            a5 -= (
                blk[5, 0] * t0
                + blk[5, 1] * t1
                + blk[5, 2] * t2
                + blk[5, 3] * t3
                + blk[5, 4] * t4
                + blk[5, 5] * t5
            )
        t[p, 0] = a0
        t[p, 1] = a1
        t[p, 2] = a2
        t[p, 3] = a3
        t[p, 4] = a4
        t[p, 5] = a5


@njit(cache=True)
def _unit_forward_sweep(scaled: np.ndarray, pairs: np.ndarray, ustart: np.ndarray, u: np.ndarray) -> None:
    """``u <- (I + L^)^-1 u`` in place, p ascending: once ``u_p`` is final, ``A^_pj^T u_p`` is taken off
    every later ``u_j`` (the pairs of row ``p`` are contiguous, so both sweeps stream ``A^`` in order)."""
    for p in range(u.shape[0]):
        u0 = u[p, 0]
        u1 = u[p, 1]
        u2 = u[p, 2]
        u3 = u[p, 3]
        u4 = u[p, 4]
        u5 = u[p, 5]
        for k in range(ustart[p], ustart[p + 1]):
            j = pairs[k, 1]
            blk = scaled[k]
            for b in range(6):
                u[j, b] -= (
                    blk[0, b] * u0
                    + blk[1, b] * u1
                    + blk[2, b] * u2
                    + blk[3, b] * u3
                    + blk[4, b] * u4
                    + blk[5, b] * u5
                )


@njit(cache=True)
def _scale_forward(chol: np.ndarray, inv_diag: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """``out_p = C_p^-1 v_p`` for every particle."""
    for p in range(v.shape[0]):
        for a in range(6):
            s = v[p, a]
            for k in range(a):
                s -= chol[p, a, k] * out[p, k]
            out[p, a] = s * inv_diag[p, a]


@njit(cache=True)
def _unscale(chol: np.ndarray, inv_diag: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """``out_p = C_p^-T v_p`` for every particle (back substitution)."""
    for p in range(v.shape[0]):
        for a in range(5, -1, -1):
            s = v[p, a]
            for k in range(a + 1, 6):
                s -= chol[p, k, a] * out[p, k]
            out[p, a] = s * inv_diag[p, a]


@njit(cache=True)
def _eisenstat_pcg(
    diag: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    chol: np.ndarray,
    inv_diag: np.ndarray,
    scaled: np.ndarray,
    e_hat: np.ndarray,
    ustart: np.ndarray,
    rhs: np.ndarray,
    x: np.ndarray,
    bnorm: float,
    tolerance: float,
    max_iterations: int,
) -> tuple[int, float]:
    """DILU-PCG by Eisenstat's trick on the scaled system of :func:`scaled_dilu_factor`.

    With ``A^ = C^-1 A C^-T``, ``K^ = I + L^`` (``L^`` its strictly lower block part) and
    ``E^ = 2 I - D^`` (``D^`` its diagonal blocks), ``A^ = K^ + K^T - E^``, so the preconditioned operator
    ``K^-1 A^ K^-T v = K^-T v + K^-1 (v - E^ K^-T v)`` costs one backward and one forward sweep of
    plain 6x6 block products per iteration and no separate product with ``A`` (Eisenstat 1981), and the
    DILU diagonal solves are gone (the scaling took them). CG runs on ``y = K^T C^T x``; the direction
    ``t = K^-T p`` updates ``x^ = C^T x``, which is unscaled (``x = C^-T x^``) only to check the true
    residual and at the end. The transformed residual ``rh = K^-1 C^-1 r`` decides when to check; the
    stopping rule itself is on the true residual ``||rhs - A x||`` (one product with ``A`` per check,
    usually one or two checks per solve). In exact arithmetic the iterates equal those of plain PCG with
    ``M = (D~ + L) D~^-1 (D~ + L^T)`` (:func:`solve_resistance_in_order` with ``eisenstat=False``).
    ``x`` holds the initial guess and receives the solution. Returns (iterations or -1, relative residual).

    Reference: Eisenstat, S. C. (1981) SIAM J. Sci. Stat. Comput. 2, 1-4.
    """
    n = diag.shape[0]
    r, rnorm = _initial_residual(diag, off, pairs, rhs, x, bnorm)
    if rnorm <= tolerance * bnorm:
        return 0, rnorm / bnorm
    rh = np.empty((n, 6))  # transformed residual K^-1 C^-1 r
    _scale_forward(chol, inv_diag, r, rh)
    _unit_forward_sweep(scaled, pairs, ustart, rh)
    xh = np.empty((n, 6))  # C^T x
    for p in range(n):
        for a in range(6):
            s = 0.0
            for m in range(a, 6):
                s += chol[p, m, a] * x[p, m]
            xh[p, a] = s
    rr = _dot(rh, rh)
    # First check when ||rh|| falls to the tolerance times 10 * (||rh|| / ||r|| now): the ratio of the
    # two norms grows as CG removes the modes the preconditioner captures well, so the ratio measured at
    # the start would overshoot (~5x below the tolerance at phi = 0.45). After a failed check the target
    # is rescaled by the ratio measured then.
    target = 10.0 * tolerance * bnorm * math.sqrt(rr) / rnorm
    ph = rh.copy()
    t = np.empty((n, 6))
    u = np.empty((n, 6))
    for it in range(1, max_iterations + 1):
        _unit_backward_sweep(scaled, pairs, ustart, ph, t)
        for p in range(n):  # u = ph - E^ t
            for a in range(6):
                s = ph[p, a]
                for b in range(6):
                    s -= e_hat[p, a, b] * t[p, b]
                u[p, a] = s
        _unit_forward_sweep(scaled, pairs, ustart, u)
        for p in range(n):  # qh = t + u = (transformed A) ph, kept in u
            for a in range(6):
                u[p, a] += t[p, a]
        pq = _dot(ph, u)
        if not pq > 0.0:  # also catches NaN
            _unscale(chol, inv_diag, xh, x)
            return -1, rnorm / bnorm
        alpha = rr / pq
        for p in range(n):
            for a in range(6):
                xh[p, a] += alpha * t[p, a]
                rh[p, a] -= alpha * u[p, a]
        rr_new = _dot(rh, rh)
        if math.sqrt(rr_new) <= target:
            _unscale(chol, inv_diag, xh, x)
            r = rhs - block_matvec(diag, off, pairs, x)
            rnorm = math.sqrt(_dot(r, r))
            if rnorm <= tolerance * bnorm:
                return it, rnorm / bnorm
            target = 0.8 * math.sqrt(rr_new) * tolerance * bnorm / rnorm
        beta = rr_new / rr
        rr = rr_new
        for p in range(n):
            for a in range(6):
                ph[p, a] = rh[p, a] + beta * ph[p, a]
    _unscale(chol, inv_diag, xh, x)
    return -1, rnorm / bnorm


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
    """Preconditioned conjugate gradients for ``R_FU . x = rhs``.

    The particles are first renamed in the leaves-first order of the maximum spanning forest of the
    pair couplings (:mod:`sim.hydrodynamics.elimination_order`); PCG with block DILU (block-Jacobi
    fallback) then runs on the renamed system, and the solution is returned in the caller's labels.
    The pairs may come in any order and orientation.

    Args:
        diag, off, pairs: block-sparse R_FU (see :func:`block_matvec`).
        rhs: (N, 6) right-hand side (forces and torques).
        initial_guess: (N, 6) warm start (e.g. extrapolated from the previous steps' solutions).
        tolerance: relative residual target ``||r|| / ||rhs||``.
        max_iterations: iteration cap.

    Returns:
        solution (N, 6), iterations used (-1 if the cap was reached or a diagonal block was not
        positive definite), final relative residual.
    """
    n = diag.shape[0]
    order = elimination_order(off, pairs, n)
    ordered_diag, ordered_off, ordered_pairs = relabel_system(diag, off, pairs, order)
    ordered_rhs = np.empty((n, 6))
    ordered_guess = np.empty((n, 6))
    for t in range(n):
        ordered_rhs[t] = rhs[order[t]]
        ordered_guess[t] = initial_guess[order[t]]
    ordered_x, iterations, residual = solve_resistance_in_order(
        ordered_diag, ordered_off, ordered_pairs, ordered_rhs, ordered_guess, tolerance, max_iterations
    )
    x = np.empty((n, 6))
    for t in range(n):
        x[order[t]] = ordered_x[t]
    return x, iterations, residual


@njit(cache=True)
def solve_resistance_in_order(
    diag: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    rhs: np.ndarray,
    initial_guess: np.ndarray,
    tolerance: float,
    max_iterations: int,
    eisenstat: bool = True,
) -> tuple[np.ndarray, int, float]:
    """PCG (block DILU, block-Jacobi fallback) for ``R_FU . x = rhs``, eliminating in label order.

    DILU is used when the pairs are sorted (``i < j``, ``i`` non-decreasing; :func:`pairs_are_sorted`)
    and every modified diagonal block is positive definite; otherwise block-Jacobi. With DILU the
    iteration uses Eisenstat's trick (:func:`_eisenstat_pcg`) unless ``eisenstat`` is False (plain PCG
    with the same preconditioner, kept as its reference).

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
    bnorm = math.sqrt(_dot(rhs, rhs))
    x = initial_guess.copy()
    if not math.isfinite(bnorm):
        return x, -1, np.inf
    all_pairs = np.arange(pairs.shape[0])
    lstart, lorder = group_by_particle(pairs[:, 1], all_pairs, n)  # pairs (i, p) with i < p
    ustart, _ = group_by_particle(pairs[:, 0], all_pairs, n)  # pairs (p, j): contiguous, pairs sorted by i
    chol = np.empty((0, 6, 6))
    inv_diag = np.empty((0, 6))
    scaled = np.empty((0, 6, 6))
    e_hat = np.empty((0, 6, 6))
    use_dilu = False
    if pairs_are_sorted(pairs):
        chol, inv_diag, scaled, e_hat, use_dilu = scaled_dilu_factor(diag, off, pairs, lstart, lorder)
    if not use_dilu:  # block-Jacobi fallback, which also checks that the diagonal blocks are SPD
        chol, ok = cholesky_blocks(diag)
        if not ok:
            return x, -1, np.inf
    if bnorm < NEGLIGIBLE_FORCING:
        return np.zeros((n, 6)), 0, 0.0
    if use_dilu and eisenstat:
        iterations, residual = _eisenstat_pcg(
            diag, off, pairs, chol, inv_diag, scaled, e_hat, ustart, rhs, x, bnorm, tolerance, max_iterations
        )
        return x, iterations, residual
    y_buf = np.empty((n, 6))
    acc_buf = np.empty(6)
    tmp_buf = np.empty(6)
    work_buf = np.empty(6)
    r, rnorm = _initial_residual(diag, off, pairs, rhs, x, bnorm)
    if rnorm <= tolerance * bnorm:
        return x, 0, rnorm / bnorm
    z = np.empty((n, 6))
    if use_dilu:
        _apply_dilu(chol, off, pairs, lstart, lorder, ustart, r, z, y_buf, acc_buf, tmp_buf, work_buf)
    else:
        _apply_block_jacobi(chol, r, z, work_buf)
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
        if use_dilu:
            _apply_dilu(chol, off, pairs, lstart, lorder, ustart, r, z, y_buf, acc_buf, tmp_buf, work_buf)
        else:
            _apply_block_jacobi(chol, r, z, work_buf)
        rz_new = _dot(r, z)
        beta = rz_new / rz
        rz = rz_new
        for q in range(n):
            for c in range(6):
                p[q, c] = z[q, c] + beta * p[q, c]
    return x, -1, rnorm / bnorm
