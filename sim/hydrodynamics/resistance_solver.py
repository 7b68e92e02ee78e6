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
``R_FU`` into the two preconditioner sweeps (10-15% faster per solve, same iterates). If a modified
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
    s = 0.0
    for p in range(a.shape[0]):
        for c in range(a.shape[1]):
            s += a[p, c] * b[p, c]
    return s


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
    return _dilu_factor_indexed(diag, off, pairs, lstart, lorder)


@njit(cache=True)
def _dilu_factor_indexed(
    diag: np.ndarray, off: np.ndarray, pairs: np.ndarray, lstart: np.ndarray, lorder: np.ndarray
) -> tuple[np.ndarray, bool]:
    """:func:`dilu_factor` with the pairs grouped by their larger index (``group_by_particle``) supplied."""
    n = diag.shape[0]
    chol = np.zeros((n, 6, 6))
    work = np.empty((6, 6))
    col = np.empty(6)
    sol = np.empty(6)
    buf = np.empty(6)
    for p in range(n):
        work[:, :] = diag[p]
        for q in range(lstart[p], lstart[p + 1]):
            k = lorder[q]
            i = pairs[k, 0]
            blk = off[k]  # A[i, p]; A[p, i] = blk^T
            # work -= blk^T D~_i^-1 blk, column by column
            for c in range(6):
                for r in range(6):
                    col[r] = blk[r, c]
                _cholesky_solve_6(chol[i], col, sol, buf)
                for r in range(6):
                    acc = 0.0
                    for m in range(6):
                        acc += blk[m, r] * sol[m]
                    work[r, c] -= acc
        if not _cholesky_6(work, chol[p]):
            return chol, False
    return chol, True


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
def _backward_solve(
    chol: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    ustart: np.ndarray,
    v: np.ndarray,
    t: np.ndarray,
    acc: np.ndarray,
    tmp: np.ndarray,
    buf: np.ndarray,
) -> None:
    """``t = K^-T v``: ``t_p = D~_p^-1 (v_p - sum_{j>p} A_pj t_j)``, p descending (pairs sorted by i)."""
    for p in range(chol.shape[0] - 1, -1, -1):
        for a in range(6):
            acc[a] = v[p, a]
        for k in range(ustart[p], ustart[p + 1]):
            j = pairs[k, 1]
            blk = off[k]  # A[p, j]
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += blk[a, b] * t[j, b]
                acc[a] -= s
        _cholesky_solve_6(chol[p], acc, tmp, buf)
        for a in range(6):
            t[p, a] = tmp[a]


@njit(cache=True)
def _eisenstat_pcg(
    diag: np.ndarray,
    off: np.ndarray,
    pairs: np.ndarray,
    chol: np.ndarray,
    lstart: np.ndarray,
    lorder: np.ndarray,
    ustart: np.ndarray,
    rhs: np.ndarray,
    x: np.ndarray,
    bnorm: float,
    tolerance: float,
    max_iterations: int,
) -> tuple[int, float]:
    """CG on ``K'^-1 A K'^-T`` (``M = K' K'^T``, ``K' = K C^-T``, ``D~ = C C^T``) with Eisenstat's trick.

    ``A = K + K^T - (2 D~ - D)`` gives ``K^-1 A K^-T v = K^-T v + K^-1 (v - (2 D~ - D) K^-T v)``: one
    forward and one backward block sweep per iteration and no separate product with ``A`` (Eisenstat
    1981), a third fewer passes over the pair blocks than plain PCG with the same M (same iterates in
    exact arithmetic). The direction ``t = K^-T C p`` updates ``x`` directly. The transformed residual
    decides when to check; the stopping rule itself is on the true residual ``||rhs - A x||`` (one
    product with A per check, usually one or two checks per solve).
    ``x`` holds the initial guess and is updated in place. Returns (iterations or -1, relative residual).

    Reference: Eisenstat, S. C. (1981) SIAM J. Sci. Stat. Comput. 2, 1-4.
    """
    n = diag.shape[0]
    acc = np.empty(6)
    tmp = np.empty(6)
    buf = np.empty(6)
    # E = 2 D~ - D, block diagonal
    e_blocks = np.empty((n, 6, 6))
    for p in range(n):
        for a in range(6):
            for b in range(6):
                s = 0.0
                for m in range(min(a, b) + 1):
                    s += chol[p, a, m] * chol[p, b, m]
                e_blocks[p, a, b] = 2.0 * s - diag[p, a, b]
    r, rnorm = _initial_residual(diag, off, pairs, rhs, x, bnorm)
    if rnorm <= tolerance * bnorm:
        return 0, rnorm / bnorm
    u = np.empty((n, 6))
    _forward_solve(chol, off, pairs, lstart, lorder, r, u, acc, tmp, buf)
    rh = np.empty((n, 6))  # transformed residual C^T K^-1 r
    for p in range(n):
        for a in range(6):
            s = 0.0
            for m in range(a, 6):
                s += chol[p, m, a] * u[p, m]
            rh[p, a] = s
    rr = _dot(rh, rh)
    # First check when ||rh|| falls to the tolerance times 10 * (||rh|| / ||r|| now): the ratio of the
    # two norms grows as CG removes the modes the preconditioner captures well, so the ratio measured at
    # the start would overshoot (~5x below the tolerance at phi = 0.45). After a failed check the target
    # is rescaled by the ratio measured then.
    target = 10.0 * tolerance * bnorm * math.sqrt(rr) / rnorm
    ph = rh.copy()
    cp = np.empty((n, 6))
    t = np.empty((n, 6))
    w = np.empty((n, 6))
    qh = np.empty((n, 6))
    for it in range(1, max_iterations + 1):
        for p in range(n):  # cp = C ph
            for a in range(6):
                s = 0.0
                for m in range(a + 1):
                    s += chol[p, a, m] * ph[p, m]
                cp[p, a] = s
        _backward_solve(chol, off, pairs, ustart, cp, t, acc, tmp, buf)
        for p in range(n):  # w = C ph - E t
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += e_blocks[p, a, b] * t[p, b]
                w[p, a] = cp[p, a] - s
        _forward_solve(chol, off, pairs, lstart, lorder, w, u, acc, tmp, buf)
        for p in range(n):  # qh = C^T (t + u) = (transformed A) ph
            for a in range(6):
                s = 0.0
                for m in range(a, 6):
                    s += chol[p, m, a] * (t[p, m] + u[p, m])
                qh[p, a] = s
        pq = _dot(ph, qh)
        if not pq > 0.0:  # also catches NaN
            return -1, rnorm / bnorm
        alpha = rr / pq
        for p in range(n):
            for a in range(6):
                x[p, a] += alpha * t[p, a]
                rh[p, a] -= alpha * qh[p, a]
        rr_new = _dot(rh, rh)
        if math.sqrt(rr_new) <= target:
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
    use_dilu = False
    if pairs_are_sorted(pairs):
        chol, use_dilu = _dilu_factor_indexed(diag, off, pairs, lstart, lorder)
    if not use_dilu:  # block-Jacobi fallback, which also checks that the diagonal blocks are SPD
        chol, ok = cholesky_blocks(diag)
        if not ok:
            return x, -1, np.inf
    if bnorm < NEGLIGIBLE_FORCING:
        return np.zeros((n, 6)), 0, 0.0
    if use_dilu and eisenstat:
        iterations, residual = _eisenstat_pcg(
            diag, off, pairs, chol, lstart, lorder, ustart, rhs, x, bnorm, tolerance, max_iterations
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
