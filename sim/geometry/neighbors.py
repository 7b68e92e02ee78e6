"""Pair lists under Lees–Edwards boundary conditions: cell list and its brute-force twin.

Both builders return every pair ``(i, j)`` with ``i < j`` whose minimum-image separation is
shorter than the cut-off, once, sorted lexicographically by ``(i, j)``, with
``separations[k] = minimum_image(x_j - x_i)``. The two outputs are bit-identical (the separation
is computed by the same :func:`~sim.geometry.box.minimum_image` call on the same raw difference).

Cell list with a sheared boundary: the box is cut into ``n_cells**3`` cubic cells of side
``w = L/n_cells >= cutoff``. A neighbour of particle ``i`` lies in one of the three ``y`` rows and
three ``z`` layers around ``i``'s cell. When the ``y`` row crosses the ``y`` boundary, its particles
are seen through the image shifted by ``+/- delta`` in ``x``, so the ``x`` cells searched are those
covering ``[x_i - s - cutoff, x_i - s + cutoff]`` (``s = +/- delta`` the shift of that row; at most
three cells because ``2*cutoff <= 2*w``), instead of ``cx - 1 .. cx + 1``. The same particle-
specific ``x`` window is used for unshifted rows (``s = 0``), and is widened by a relative
``1e-9`` so that rounding in the cell assignment cannot drop a pair.

References:
    Allen, M. P. & Tildesley, D. J. (2017) "Computer Simulation of Liquids", 2nd ed., OUP, §5.3
    (cell lists) and §11.3 (Lees–Edwards cell lists). Bhupathiraju, R., Cummings, P. T. & Cochran,
    H. D. (1996) "An efficient parallel algorithm for non-equilibrium molecular dynamics
    simulations of very large systems in planar Couette flow", Mol. Phys. 88, 1665.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.box import LeesEdwardsBox, minimum_image

__all__ = ["build_pair_list", "build_pair_list_brute_force", "pair_list"]

# Relative margin by which cells are made larger than the cut-off and search windows wider than
# needed, so that floating-point rounding in the cell assignment can never lose a pair.
_CELL_MARGIN = 1e-9


@njit(cache=True)
def build_pair_list_brute_force(
    positions: np.ndarray, box_length: float, offset: float, cutoff: float
) -> tuple[np.ndarray, np.ndarray]:
    """All pairs closer than ``cutoff`` by an O(N^2) search (reference twin of :func:`build_pair_list`).

    Args:
        positions: Particle centres, shape ``(N, 3)``, float64 (units of ``a``), any finite values.
        box_length: Box side ``L`` (units of ``a``), ``> 0``.
        offset: Lees–Edwards offset ``delta`` (units of ``a``).
        cutoff: Pair cut-off distance (units of ``a``), ``0 < cutoff <= L/2``.

    Returns:
        ``(pairs, separations)``: ``pairs`` shape ``(M, 2)`` int64 with ``i < j`` sorted by
        ``(i, j)``; ``separations`` shape ``(M, 3)`` float64, minimum image of ``x_j - x_i``,
        with ``|separation| < cutoff``.

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, §5.3.
    """
    n = positions.shape[0]
    cutoff_sq = cutoff * cutoff
    capacity = max(16, 8 * n)
    pairs = np.empty((capacity, 2), dtype=np.int64)
    seps = np.empty((capacity, 3), dtype=np.float64)
    m = 0
    for i in range(n):
        xi = positions[i, 0]
        yi = positions[i, 1]
        zi = positions[i, 2]
        for j in range(i + 1, n):
            dx, dy, dz = minimum_image(
                positions[j, 0] - xi, positions[j, 1] - yi, positions[j, 2] - zi, box_length, offset
            )
            if dx * dx + dy * dy + dz * dz < cutoff_sq:
                if m == capacity:
                    capacity *= 2
                    pairs, seps = _grow(pairs, seps, capacity)
                pairs[m, 0] = i
                pairs[m, 1] = j
                seps[m, 0] = dx
                seps[m, 1] = dy
                seps[m, 2] = dz
                m += 1
    return pairs[:m].copy(), seps[:m].copy()


@njit(cache=True)
def _grow(pairs: np.ndarray, seps: np.ndarray, capacity: int) -> tuple[np.ndarray, np.ndarray]:
    """Copy the pair buffers into new ones of the given (larger) capacity."""
    new_pairs = np.empty((capacity, 2), dtype=np.int64)
    new_seps = np.empty((capacity, 3), dtype=np.float64)
    m = pairs.shape[0]
    new_pairs[:m] = pairs
    new_seps[:m] = seps
    return new_pairs, new_seps


@njit(cache=True)
def _cell_index(value: float, inv_width: float, n_cells: int) -> int:
    """Cell index of a wrapped coordinate, clamped into ``[0, n_cells)``."""
    c = int(math.floor(value * inv_width))
    if c < 0:
        c = 0
    elif c >= n_cells:
        c = n_cells - 1
    return c


@njit(cache=True)
def _scan_cell_pair(
    sorted_pos: np.ndarray,
    cell_particles: np.ndarray,
    a0: int,
    a1: int,
    b0: int,
    b1: int,
    x_image: float,
    y_image: float,
    z_image: float,
    round_x: bool,
    positions: np.ndarray,
    box_length: float,
    offset: float,
    screen_sq: float,
    cutoff_sq: float,
    buf_i: np.ndarray,
    buf_j: np.ndarray,
    buf_sep: np.ndarray,
    m: int,
) -> int:
    """Test every particle of run ``a0:a1`` against every particle of run ``b0:b1`` (two cells).

    The candidate separation ``x_b + image - x_a`` uses the image implied by the cells (with the
    ``x`` image rounded to the nearest one when ``round_x``); survivors of the screen get the
    exact minimum image of ``x_j - x_i`` (``i < j``) and are appended to the buffers if closer
    than the cut-off. Returns the new number of buffered pairs (buffers must have room).
    """
    for a in range(a0, a1):
        xa = sorted_pos[a, 0] - x_image
        ya = sorted_pos[a, 1] - y_image
        za = sorted_pos[a, 2] - z_image
        for b in range(b0, b1):
            ex = sorted_pos[b, 0] - xa
            if round_x:
                ex -= box_length * np.round(ex / box_length)
            ey = sorted_pos[b, 1] - ya
            ez = sorted_pos[b, 2] - za
            if ex * ex + ey * ey + ez * ez >= screen_sq:
                continue
            i = cell_particles[a]
            j = cell_particles[b]
            if i > j:
                i, j = j, i
            dx, dy, dz = minimum_image(
                positions[j, 0] - positions[i, 0],
                positions[j, 1] - positions[i, 1],
                positions[j, 2] - positions[i, 2],
                box_length,
                offset,
            )
            if dx * dx + dy * dy + dz * dz < cutoff_sq:
                buf_i[m] = i
                buf_j[m] = j
                buf_sep[m, 0] = dx
                buf_sep[m, 1] = dy
                buf_sep[m, 2] = dz
                m += 1
    return m


@njit(cache=True)
def _grow_buffers(
    buf_i: np.ndarray, buf_j: np.ndarray, buf_sep: np.ndarray, m: int, capacity: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Copy the first ``m`` buffered pairs into new buffers of the given capacity."""
    new_i = np.empty(capacity, dtype=np.int64)
    new_j = np.empty(capacity, dtype=np.int64)
    new_sep = np.empty((capacity, 3), dtype=np.float64)
    new_i[:m] = buf_i[:m]
    new_j[:m] = buf_j[:m]
    new_sep[:m] = buf_sep[:m]
    return new_i, new_j, new_sep


@njit(cache=True)
def build_pair_list(
    positions: np.ndarray, box_length: float, offset: float, cutoff: float
) -> tuple[np.ndarray, np.ndarray]:
    """All pairs closer than ``cutoff`` by a Lees–Edwards cell list (O(N)).

    Half-shell sweep over pairs of cells: each cell is paired with itself, with ``(dx, dz, dy) =
    (+1, 0, 0)``, with the three ``x`` neighbours in the layer ``dz = +1`` (``dy = 0``) and with
    the row ``dy = +1``: nine cells when that row is inside the box; when it lies across the
    ``y = L`` boundary it is seen through the image shifted by ``+delta`` in ``x``, and the ``x``
    cells searched are those overlapping ``[x_lo - delta - cutoff, x_hi - delta + cutoff]`` for the
    home cell ``[x_lo, x_hi)`` (up to four cells; the whole row, with the ``x`` image rounded per
    pair, when that covers every cell). With three or more cells per side every unordered cell
    pair, and hence every particle pair, is visited exactly once. Found pairs are then ordered by
    ``(i, j)`` with a counting sort on ``i`` and an insertion sort on ``j``.

    Falls back to :func:`build_pair_list_brute_force` when fewer than three cells fit per side.
    The output is identical to the brute-force twin (same pairs, same order, bit-identical
    separations).

    Args:
        positions: Particle centres, shape ``(N, 3)``, float64 (units of ``a``), wrapped into
            ``[0, L)^3`` (e.g. by :func:`~sim.geometry.box.wrap_positions`); unwrapped input
            gives an incomplete list.
        box_length: Box side ``L`` (units of ``a``), ``> 0``.
        offset: Lees–Edwards offset ``delta`` (units of ``a``), in ``[-L/2, L/2)``.
        cutoff: Pair cut-off distance (units of ``a``), ``0 < cutoff <= L/2`` (checked by
            :func:`pair_list`, not here).

    Returns:
        ``(pairs, separations)``: ``pairs`` shape ``(M, 2)`` int64 with ``i < j`` sorted by
        ``(i, j)``; ``separations`` shape ``(M, 3)`` float64, minimum image of ``x_j - x_i``,
        with ``|separation| < cutoff``.

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, §5.3 and §11.3;
        Bhupathiraju, Cummings & Cochran (1996), Mol. Phys. 88, 1665.
    """
    n = positions.shape[0]
    n_cells = int(box_length / (cutoff * (1.0 + _CELL_MARGIN)))
    if n_cells < 3:
        return build_pair_list_brute_force(positions, box_length, offset, cutoff)
    width = box_length / n_cells
    inv_width = 1.0 / width
    n_cells_total = n_cells * n_cells * n_cells

    # Counting sort of particles into cells, cell index (cy*n + cz)*n + cx, so that the cells
    # of one (y, z) row are contiguous; coordinates are copied in cell order (cache locality).
    cell_of = np.empty(n, dtype=np.int64)
    cell_start = np.zeros(n_cells_total + 1, dtype=np.int64)
    for i in range(n):
        cx = _cell_index(positions[i, 0], inv_width, n_cells)
        cy = _cell_index(positions[i, 1], inv_width, n_cells)
        cz = _cell_index(positions[i, 2], inv_width, n_cells)
        c = (cy * n_cells + cz) * n_cells + cx
        cell_of[i] = c
        cell_start[c + 1] += 1
    for c in range(n_cells_total):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:-1].copy()
    cell_particles = np.empty(n, dtype=np.int64)
    sorted_pos = np.empty((n, 3), dtype=np.float64)
    for i in range(n):
        c = cell_of[i]
        k = fill[c]
        cell_particles[k] = i
        sorted_pos[k, 0] = positions[i, 0]
        sorted_pos[k, 1] = positions[i, 1]
        sorted_pos[k, 2] = positions[i, 2]
        fill[c] += 1
    max_occupancy = 0
    for c in range(n_cells_total):
        occupancy = cell_start[c + 1] - cell_start[c]
        if occupancy > max_occupancy:
            max_occupancy = occupancy

    cutoff_sq = cutoff * cutoff
    reach = cutoff * (1.0 + _CELL_MARGIN)
    # Candidates are screened with the image implied by the cells, with a radius a relative 1e-9
    # larger than the cut-off; survivors get the exact minimum image, as in the brute-force twin.
    screen_sq = reach * reach
    capacity = max(64, 8 * n)
    buf_i = np.empty(capacity, dtype=np.int64)
    buf_j = np.empty(capacity, dtype=np.int64)
    buf_sep = np.empty((capacity, 3), dtype=np.float64)
    # Pairs one home cell can add at most: itself, 13 neighbour cells, 1 extra in a shifted row.
    per_cell_bound = 15 * max_occupancy * max_occupancy
    m = 0
    for cy in range(n_cells):
        crossing = cy == n_cells - 1
        for cz in range(n_cells):
            for cx in range(n_cells):
                c = (cy * n_cells + cz) * n_cells + cx
                a0 = cell_start[c]
                a1 = cell_start[c + 1]
                if a0 == a1:
                    continue
                if m + per_cell_bound > capacity:
                    while m + per_cell_bound > capacity:
                        capacity *= 2
                    buf_i, buf_j, buf_sep = _grow_buffers(buf_i, buf_j, buf_sep, m, capacity)
                # Same cell: pairs a < b of the run (the direct difference is the only image
                # shorter than the cut-off).
                for a in range(a0, a1):
                    m = _scan_cell_pair(
                        sorted_pos, cell_particles, a, a + 1, a + 1, a1, 0.0, 0.0, 0.0, False,
                        positions, box_length, offset, screen_sq, cutoff_sq, buf_i, buf_j, buf_sep, m,
                    )
                # (dx, dz, dy) = (+1, 0, 0).
                cxn = cx + 1
                x_image = 0.0
                if cxn == n_cells:
                    cxn = 0
                    x_image = box_length
                cn = (cy * n_cells + cz) * n_cells + cxn
                m = _scan_cell_pair(
                    sorted_pos, cell_particles, a0, a1, cell_start[cn], cell_start[cn + 1],
                    x_image, 0.0, 0.0, False,
                    positions, box_length, offset, screen_sq, cutoff_sq, buf_i, buf_j, buf_sep, m,
                )
                # Layer dz = +1 (dy = 0), x neighbours -1, 0, +1.
                czn = cz + 1
                z_image = 0.0
                if czn == n_cells:
                    czn = 0
                    z_image = box_length
                row = (cy * n_cells + czn) * n_cells
                for dcx in range(-1, 2):
                    cxu = cx + dcx
                    cxn = cxu % n_cells
                    x_image = (cxu - cxn) // n_cells * box_length
                    cn = row + cxn
                    m = _scan_cell_pair(
                        sorted_pos, cell_particles, a0, a1, cell_start[cn], cell_start[cn + 1],
                        x_image, 0.0, z_image, False,
                        positions, box_length, offset, screen_sq, cutoff_sq, buf_i, buf_j, buf_sep, m,
                    )
                # Row dy = +1, layers dz = -1, 0, +1.
                if crossing:
                    # Row 0 seen through the image at y + L, shifted by +delta in x: cells holding
                    # x_j with x_j + delta within reach of the home cell (mod L).
                    y_image = box_length
                    shift = offset
                    lo = int(math.floor((cx * width - offset - reach) * inv_width))
                    hi = int(math.floor(((cx + 1) * width - offset + reach) * inv_width))
                    full_row = hi - lo + 1 >= n_cells
                    cyn = 0
                else:
                    y_image = 0.0
                    shift = 0.0
                    lo = cx - 1
                    hi = cx + 1
                    full_row = False
                    cyn = cy + 1
                for dcz in range(-1, 2):
                    czu = cz + dcz
                    czn = czu % n_cells
                    z_image = (czu - czn) // n_cells * box_length
                    row = (cyn * n_cells + czn) * n_cells
                    if full_row:
                        m = _scan_cell_pair(
                            sorted_pos, cell_particles, a0, a1, cell_start[row],
                            cell_start[row + n_cells], shift, y_image, z_image, True,
                            positions, box_length, offset, screen_sq, cutoff_sq, buf_i, buf_j, buf_sep, m,
                        )
                        continue
                    # Cells lo..hi (unwrapped) span at most three periods in x; the cells of one
                    # period are contiguous, so each period is one run of particles.
                    for period in range(-1, 2):
                        c0 = max(lo, period * n_cells) - period * n_cells
                        c1 = min(hi, period * n_cells + n_cells - 1) - period * n_cells
                        if c0 > c1:
                            continue
                        m = _scan_cell_pair(
                            sorted_pos, cell_particles, a0, a1, cell_start[row + c0],
                            cell_start[row + c1 + 1], shift + period * box_length, y_image, z_image,
                            False,
                            positions, box_length, offset, screen_sq, cutoff_sq, buf_i, buf_j, buf_sep, m,
                        )

    # Order by (i, j): counting sort on i, then insertion sort on j inside each i (short runs).
    start = np.zeros(n + 1, dtype=np.int64)
    for k in range(m):
        start[buf_i[k] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    slot = start[:-1].copy()
    pairs = np.empty((m, 2), dtype=np.int64)
    seps = np.empty((m, 3), dtype=np.float64)
    for k in range(m):
        i = buf_i[k]
        t = slot[i]
        slot[i] += 1
        pairs[t, 0] = i
        pairs[t, 1] = buf_j[k]
        seps[t, 0] = buf_sep[k, 0]
        seps[t, 1] = buf_sep[k, 1]
        seps[t, 2] = buf_sep[k, 2]
    for i in range(n):
        for a in range(start[i] + 1, start[i + 1]):
            jj = pairs[a, 1]
            sx = seps[a, 0]
            sy = seps[a, 1]
            sz = seps[a, 2]
            b = a - 1
            while b >= start[i] and pairs[b, 1] > jj:
                pairs[b + 1, 1] = pairs[b, 1]
                seps[b + 1, 0] = seps[b, 0]
                seps[b + 1, 1] = seps[b, 1]
                seps[b + 1, 2] = seps[b, 2]
                b -= 1
            pairs[b + 1, 1] = jj
            seps[b + 1, 0] = sx
            seps[b + 1, 1] = sy
            seps[b + 1, 2] = sz
    return pairs, seps


def pair_list(
    positions: np.ndarray, box: LeesEdwardsBox, cutoff: float
) -> tuple[np.ndarray, np.ndarray]:
    """Validated pair list for a :class:`~sim.geometry.box.LeesEdwardsBox` (see :func:`build_pair_list`).

    Args:
        positions: Particle centres, shape ``(N, 3)`` (units of ``a``), wrapped into ``[0, L)^3``.
        box: The Lees–Edwards box.
        cutoff: Pair cut-off distance (units of ``a``), in ``(0, L/2]``.

    Returns:
        ``(pairs, separations)``: shape ``(M, 2)`` int64 (``i < j``, sorted) and ``(M, 3)``
        float64 (minimum image of ``x_j - x_i``, ``|separation| < cutoff``).

    Raises:
        ValueError: If ``cutoff`` is outside ``(0, L/2]`` or ``positions`` is not a finite
            ``(N, 3)`` array wrapped into ``[0, L)^3``.

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, §5.3 and §11.3.
    """
    cutoff = float(cutoff)
    half = 0.5 * box.length
    if not (math.isfinite(cutoff) and 0.0 < cutoff <= half):
        raise ValueError(f"cutoff must be in (0, L/2] = (0, {half}], got {cutoff!r}")
    arr = np.ascontiguousarray(positions, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"positions must have shape (N, 3), got {arr.shape}")
    if arr.size and not (np.all(arr >= 0.0) and np.all(arr < box.length)):
        raise ValueError(f"positions must be finite and wrapped into [0, L)^3 with L = {box.length}")
    return build_pair_list(arr, box.length, box.offset, cutoff)
