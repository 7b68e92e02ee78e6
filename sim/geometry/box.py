"""Cubic Lees–Edwards box: offset, minimum image and wrapping.

Conventions (docs/units.md, docs/model.md#lees-edwards-box): sphere radius ``a = 1``; axes ``x`` flow, ``y``
velocity
gradient, ``z`` vorticity; shear rate ``gammadot``. The periodic images at ``y +/- L`` are shifted by
``+/- delta`` in ``x`` and move with ``+/- gammadot*L`` in ``x``, where the offset
``delta = strain*L mod L`` is kept in ``[-L/2, L/2)``. The equivalent sheared lattice has basis
vectors (rows)

    a1 = (L, 0, 0),   a2 = (delta, L, 0),   a3 = (0, 0, L).

Positions are stored wrapped in ``[0, L)^3``. The numba kernels take the scalars
``(box_length, offset)``; :class:`LeesEdwardsBox` is the value handed to Python-level consumers.

References:
    Lees, A. W. & Edwards, S. F. (1972) "The computer study of transport processes under extreme
    conditions", J. Phys. C 5, 1921. Allen, M. P. & Tildesley, D. J. (2017) "Computer Simulation of
    Liquids", 2nd ed., OUP, §11.3 (sliding-brick boundary conditions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = [
    "LeesEdwardsBox",
    "lees_edwards_offset",
    "minimum_image",
    "minimum_image_array",
    "wrap_positions",
]


@njit(cache=True)
def lees_edwards_offset(strain: float, box_length: float) -> float:
    """Lees–Edwards image shift ``delta = strain*L`` reduced modulo ``L`` into ``[-L/2, L/2)``.

    Args:
        strain: Accumulated shear strain ``gammadot*t`` (dimensionless, any finite value).
        box_length: Box side ``L`` (units of ``a``), ``> 0``.

    Returns:
        The offset ``delta`` in ``[-L/2, L/2)`` (units of ``a``). Strains ``s`` and ``s + 1`` give
        the same offset (up to rounding), so the lattice is periodic in strain with period 1.

    References:
        Lees & Edwards (1972), J. Phys. C 5, 1921; ``docs/model.md#lees-edwards-box``.
    """
    shift = strain * box_length
    delta = shift - box_length * math.floor(shift / box_length + 0.5)
    # Guard the half-open interval against rounding in floor(shift/L + 0.5).
    half = 0.5 * box_length
    if delta >= half:
        delta -= box_length
    elif delta < -half:
        delta += box_length
    return delta


@njit(cache=True)
def minimum_image(
    dx: float, dy: float, dz: float, box_length: float, offset: float
) -> tuple[float, float, float]:
    """Minimum image of one separation vector in the sheared (Lees–Edwards) lattice.

    Whole periods are removed in ``y`` first (``ny = round(dy/L)``, ``dy -= ny*L``,
    ``dx -= ny*delta``), then in ``x`` and ``z`` by rounding.

    Why this is exact for ``|r| < L/2``: the lattice vectors are ``n1*a1 + n2*a2 + n3*a3`` with
    ``y`` component ``n2*L``. If some image ``r*`` has ``|r*| < L/2``, then ``|r*_y| < L/2`` and
    ``n2`` is the unique integer putting ``dy`` in ``(-L/2, L/2)``, which rounding returns; with
    ``n2`` fixed, ``x`` and ``z`` are plain period-``L`` problems and rounding likewise returns
    the unique ``n1``, ``n3`` with ``|r*_x|, |r*_z| < L/2``. Every non-zero lattice vector has
    length ``>= L`` (``|n2| >= 1`` gives ``|y| >= L``; ``n2 = 0`` gives ``(n1*L, 0, n3*L)``), so
    any other image has length ``> L - L/2 = L/2``: ``r*`` is the unique shortest image. For
    images longer than ``L/2`` the result is an image inside the sheared cell but not always the
    shortest one.

    Args:
        dx, dy, dz: Raw separation components (units of ``a``), any finite values.
        box_length: Box side ``L`` (units of ``a``), ``> 0``.
        offset: Lees–Edwards offset ``delta`` (units of ``a``), from :func:`lees_edwards_offset`.

    Returns:
        ``(dx, dy, dz)`` of the minimum image (units of ``a``).

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, §11.3; ``docs/model.md#lees-edwards-box``.
    """
    ny = np.round(dy / box_length)
    dy = dy - ny * box_length
    dx = dx - ny * offset
    nx = np.round(dx / box_length)
    dx = dx - nx * box_length
    nz = np.round(dz / box_length)
    dz = dz - nz * box_length
    return dx, dy, dz


@njit(cache=True)
def separation_between(
    first: np.ndarray, i: int, second: np.ndarray, j: int, box_length: float, offset: float
) -> tuple[float, float, float]:
    """Minimum image of ``second[j] - first[i]`` (rows of two ``(N, 3)`` position arrays, units a)."""
    return minimum_image(
        second[j, 0] - first[i, 0],
        second[j, 1] - first[i, 1],
        second[j, 2] - first[i, 2],
        box_length,
        offset,
    )


@njit(cache=True)
def pair_separation(
    positions: np.ndarray, i: int, j: int, box_length: float, offset: float
) -> tuple[float, float, float, float]:
    """Minimum-image separation ``x_j - x_i`` of particles ``i`` and ``j`` and its length ``r`` (units a)."""
    dx, dy, dz = separation_between(positions, i, positions, j, box_length, offset)
    return dx, dy, dz, math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def minimum_image_array(dr: np.ndarray, box_length: float, offset: float) -> np.ndarray:
    """Minimum image of many separation vectors (see :func:`minimum_image`).

    Args:
        dr: Raw separations, shape ``(M, 3)``, float64 (units of ``a``). Not modified.
        box_length: Box side ``L`` (units of ``a``), ``> 0``.
        offset: Lees–Edwards offset ``delta`` (units of ``a``).

    Returns:
        New array of shape ``(M, 3)``, float64: the minimum images (exact where ``|r| < L/2``).

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, §11.3.
    """
    m = dr.shape[0]
    out = np.empty((m, 3), dtype=np.float64)
    for k in range(m):
        x, y, z = minimum_image(dr[k, 0], dr[k, 1], dr[k, 2], box_length, offset)
        out[k, 0] = x
        out[k, 1] = y
        out[k, 2] = z
    return out


@njit(cache=True)
def _wrap_coordinate(value: float, box_length: float) -> tuple[float, int]:
    """Reduce one coordinate into ``[0, L)``; return it and the number of periods removed."""
    n = int(math.floor(value / box_length))
    value = value - n * box_length
    # Rounding can give exactly L (tiny negative input) or a tiny negative value.
    if value >= box_length:
        value -= box_length
        n += 1
    elif value < 0.0:
        value += box_length
        n -= 1
    return value, n


@njit(cache=True)
def wrap_positions(positions: np.ndarray, box_length: float, offset: float) -> np.ndarray:
    """Wrap positions in place into ``[0, L)^3`` with the Lees–Edwards rule.

    A particle whose ``y`` lies ``n`` periods above the box (``n = floor(y/L)``) is replaced by its
    image ``(x - n*delta, y - n*L, z)``; then ``x`` and ``z`` are wrapped normally. The image moves
    with velocity ``u - n*gammadot*L*x_hat``, so the caller must shift the stored velocity of a
    particle with ``n != 0`` by ``-n*L*gammadot`` in ``x``. Already-wrapped coordinates are left
    bit-identical.

    Args:
        positions: Particle centres, shape ``(N, 3)``, float64 (units of ``a``); modified in place.
        box_length: Box side ``L`` (units of ``a``), ``> 0``.
        offset: Lees–Edwards offset ``delta`` (units of ``a``).

    Returns:
        crossings: shape ``(N,)``, int64: periods ``n`` removed in ``y`` per particle (positive
        when the particle had gone above ``y = L``).

    References:
        Lees & Edwards (1972), J. Phys. C 5, 1921; ``docs/model.md#lees-edwards-box``.
    """
    n_particles = positions.shape[0]
    crossings = np.zeros(n_particles, dtype=np.int64)
    for i in range(n_particles):
        y, ny = _wrap_coordinate(positions[i, 1], box_length)
        x = positions[i, 0]
        if ny != 0:
            x = x - ny * offset
        x, _ = _wrap_coordinate(x, box_length)
        z, _ = _wrap_coordinate(positions[i, 2], box_length)
        positions[i, 0] = x
        positions[i, 1] = y
        positions[i, 2] = z
        crossings[i] = ny
    return crossings


@dataclass(frozen=True)
class LeesEdwardsBox:
    """A cubic Lees–Edwards box: the boundary condition passed to every consumer.

    Attributes:
        length: Box side ``L`` (units of ``a``), finite and ``> 0``.
        strain: Accumulated shear strain (dimensionless, finite; any sign or magnitude).

    References:
        Lees & Edwards (1972), J. Phys. C 5, 1921; ``docs/model.md#lees-edwards-box``.
    """

    length: float
    strain: float = 0.0

    def __post_init__(self) -> None:
        length = float(self.length)
        strain = float(self.strain)
        if not (math.isfinite(length) and length > 0.0):
            raise ValueError(f"length must be finite and > 0, got {self.length!r}")
        if not math.isfinite(strain):
            raise ValueError(f"strain must be finite, got {self.strain!r}")
        object.__setattr__(self, "length", length)
        object.__setattr__(self, "strain", strain)

    @property
    def offset(self) -> float:
        """Lees–Edwards offset ``delta = strain*L mod L`` in ``[-L/2, L/2)`` (units of ``a``)."""
        return float(lees_edwards_offset(self.strain, self.length))

    @property
    def volume(self) -> float:
        """Box volume ``L^3`` (units of ``a^3``)."""
        return self.length**3

    @property
    def lattice_vectors(self) -> np.ndarray:
        """Sheared lattice basis, shape ``(3, 3)`` (units of ``a``).

        Rows ``a1 = (L, 0, 0)``, ``a2 = (delta, L, 0)``, ``a3 = (0, 0, L)``.
        """
        length = self.length
        return np.array(
            [[length, 0.0, 0.0], [self.offset, length, 0.0], [0.0, 0.0, length]], dtype=np.float64
        )

    def minimum_image(self, dr: np.ndarray) -> np.ndarray:
        """Minimum image of separation vectors (exact where ``|r| < L/2``).

        Args:
            dr: Separations, shape ``(3,)`` or ``(M, 3)`` (units of ``a``). Not modified.

        Returns:
            New float64 array of the same shape as ``dr``.
        """
        arr = np.asarray(dr, dtype=np.float64)
        if arr.ndim == 1 and arr.shape[0] == 3:
            return minimum_image_array(arr.reshape(1, 3), self.length, self.offset)[0]
        if arr.ndim == 2 and arr.shape[1] == 3:
            return minimum_image_array(np.ascontiguousarray(arr), self.length, self.offset)
        raise ValueError(f"dr must have shape (3,) or (M, 3), got {arr.shape}")

    def wrap(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wrapped copy of ``positions`` and the ``y`` crossings (see :func:`wrap_positions`).

        Args:
            positions: Particle centres, shape ``(N, 3)`` (units of ``a``). Not modified.

        Returns:
            ``(wrapped, crossings)``: wrapped positions, shape ``(N, 3)`` float64 in ``[0, L)^3``,
            and periods removed in ``y``, shape ``(N,)`` int64.
        """
        arr = np.array(positions, dtype=np.float64, copy=True, order="C")
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise ValueError(f"positions must have shape (N, 3), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("positions must be finite")
        crossings = wrap_positions(arr, self.length, self.offset)
        return arr, crossings

    def with_strain(self, strain: float) -> LeesEdwardsBox:
        """The same box at another accumulated strain."""
        return LeesEdwardsBox(self.length, strain)
