"""Pair distribution function ``g(r)`` and its projection on the shear (x–y) plane (paper §3.3, Fig. 5).

Both are histograms of pair separations, minimum image under Lees–Edwards (offset
``delta = strain L mod L``, :func:`sim.geometry.box.lees_edwards_offset`), normalised by the count an
ideal gas (``N`` independent uniform points in the same box) has in the same bin, so an ideal gas gives
``g = 1`` in every bin:

* radial: pairs ``i < j`` with ``r = |r_j - r_i|`` in the shell ``r_k <= r < r_{k+1}``
  (``r_K = r_max <= L/2``),

      ``g(r_k) = C_k / [S (N (N - 1) / 2) (4/3) pi (r_{k+1}^3 - r_k^3) / V]``;

* shear plane: separations ``(dx, dy)`` of pairs inside the slab ``|dz| < h`` (``h``:
  ``slab_half_thickness``, default ``1 a``), on the square grid ``[-R, R)^2`` of ``M x M`` bins of side
  ``w = 2R/M``, each pair counted at ``+r`` and at ``-r`` (ordered pairs: the histogram is symmetric under
  ``r -> -r`` by construction),

      ``g_xy[i, j] = C_ij / [S N (N - 1) w^2 (2 h) / V]``,

  with ``i`` the ``x`` bin and ``j`` the ``y`` bin (as ``np.histogram2d(dx, dy)``; plot ``g_xy.T`` with the
  origin at the lower left to have ``y`` upwards).

``S`` is the number of configurations accumulated and ``V = L^3``. Why a slab and not all pairs projected:
the slab keeps pairs whose centres lie within one radius of the reference sphere's shear plane, so the
excluded disc ``r_xy < 2`` and the contact ring around it stay sharp (pairs in the slab touch at
``2 <= r_xy < 2.24``) and the compressional/extensional and pole/equator anisotropy of paper Fig. 5 is not
washed out by the many pairs far out of the plane, which a projection of all ``dz`` would add (and which
fill the excluded disc). Its ideal count is that of the slab volume ``w^2 (2h)`` per bin.

Exactness of the normalisation: for two independent uniform points the separation is uniform on the
periodic (sheared) cell, and both the ball ``r < L/2`` and the box ``|dx|, |dy| < R <= L/2``,
``|dz| < h <= L/2`` embed in it without overlap (every non-zero lattice vector ``(n1 L + n2 delta, n2 L,
n3 L)`` has a component of size ``>= L``), so the probability of a bin is its volume over ``V``; the
minimum image (:func:`sim.geometry.box.minimum_image`) returns the one image inside them.

The histograms are computed by :func:`pair_histograms` on the Lees–Edwards cell list
(:func:`sim.geometry.neighbors.build_pair_list`, O(N)) when its reach
``max(r_max, sqrt(2 R^2 + h^2))`` is at most ``L/2``, and otherwise by the all-pairs loop of its twin
:func:`pair_histograms_brute_force` (O(N^2)). :class:`PairDistributionAccumulator` sums counts over
configurations and normalises at the end.

Units: lengths in ``a``; ``g`` is dimensionless.

References:
    Allen & Tildesley (2017), Computer Simulation of Liquids, 2nd ed., §2.6 (pair distribution and its
    ideal-gas normalisation) and ch. 8 (accumulating histograms); Foss & Brady (2000), J. Fluid Mech. 407, 167
    (pair distribution of sheared suspensions in the plane of shear); Mirfendereski & Park (2024),
    J. Fluid Mech., §3.3 and Fig. 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from sim.geometry.box import lees_edwards_offset, pair_separation
from sim.geometry.neighbors import build_pair_list
from sim.observables.microstructure import check_configuration

__all__ = [
    "DEFAULT_RADIAL_BIN_WIDTH",
    "DEFAULT_RADIAL_RANGE",
    "DEFAULT_SHEAR_PLANE_BIN_WIDTH",
    "DEFAULT_SHEAR_PLANE_RANGE",
    "DEFAULT_SLAB_HALF_THICKNESS",
    "PairDistributionAccumulator",
    "pair_histograms",
    "pair_histograms_brute_force",
]

DEFAULT_RADIAL_RANGE = 6.0
"""Largest ``r`` of ``g(r)`` in a run (units a): three diameters, the first three coordination shells."""

DEFAULT_RADIAL_BIN_WIDTH = 0.02
"""Shell width of ``g(r)`` in a run (units a): resolves the contact peak at ``r = 2`` (1% of a diameter)."""

DEFAULT_SHEAR_PLANE_RANGE = 5.0
"""Half-width ``R`` of the x–y histogram in a run (units a): ``[-5, 5)^2`` as in paper Fig. 5."""

DEFAULT_SHEAR_PLANE_BIN_WIDTH = 0.1
"""Bin side of the x–y histogram in a run (units a): 100 x 100 bins over ``[-5, 5)^2``."""

DEFAULT_SLAB_HALF_THICKNESS = 1.0
"""Half-thickness ``h`` of the slab ``|dz| < h`` of the x–y projection (units a): one radius."""


@njit(cache=True)
def _check_histogram_arguments(
    positions: np.ndarray,
    box_length: float,
    strain: float,
    r_max: float,
    n_radial_bins: int,
    xy_half_width: float,
    n_xy_bins: int,
    slab_half_thickness: float,
) -> None:
    """``ValueError`` naming the first bad argument (compiled code takes constant messages)."""
    check_configuration(positions, box_length, strain)
    half = 0.5 * box_length
    if not (r_max > 0.0) or r_max > half:
        raise ValueError("r_max must be in (0, L/2] (minimum image)")
    if n_radial_bins < 1:
        raise ValueError("n_radial_bins must be >= 1")
    if not (xy_half_width > 0.0) or xy_half_width > half:
        raise ValueError("xy_half_width must be in (0, L/2] (minimum image)")
    if n_xy_bins < 1:
        raise ValueError("n_xy_bins must be >= 1")
    if not (slab_half_thickness > 0.0) or slab_half_thickness > half:
        raise ValueError("slab_half_thickness must be in (0, L/2] (minimum image)")
    for p in range(positions.shape[0]):
        for c in range(3):
            v = positions[p, c]
            if not (v >= 0.0 and v < box_length):
                raise ValueError("positions must be finite and wrapped into [0, L)^3")


@njit(cache=True)
def _bin_pair(
    dx: float,
    dy: float,
    dz: float,
    r_max: float,
    xy_half_width: float,
    slab_half_thickness: float,
    radial: np.ndarray,
    planar: np.ndarray,
) -> None:
    """Count one pair separation in the radial shells and (twice, at ``+r`` and ``-r``) in the x–y grid."""
    n_r = radial.shape[0]
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    if r < r_max:
        k = int(r * (n_r / r_max))
        if k >= n_r:
            k = n_r - 1
        radial[k] += 1
    if abs(dz) < slab_half_thickness and -xy_half_width <= dx < xy_half_width:
        if -xy_half_width <= dy < xy_half_width:
            m = planar.shape[0]
            scale = m / (2.0 * xy_half_width)
            ix = int((dx + xy_half_width) * scale)
            iy = int((dy + xy_half_width) * scale)
            if ix >= m:
                ix = m - 1
            if iy >= m:
                iy = m - 1
            planar[ix, iy] += 1
            planar[m - 1 - ix, m - 1 - iy] += 1  # the same pair seen from the other sphere (-r)


@njit(cache=True)
def _add_all_pairs(
    radial: np.ndarray,
    planar: np.ndarray,
    positions: np.ndarray,
    box_length: float,
    offset: float,
    r_max: float,
    xy_half_width: float,
    slab_half_thickness: float,
) -> None:
    n = positions.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy, dz, _ = pair_separation(positions, i, j, box_length, offset)
            _bin_pair(dx, dy, dz, r_max, xy_half_width, slab_half_thickness, radial, planar)


@njit(cache=True)
def _add_pair_histograms(
    radial: np.ndarray,
    planar: np.ndarray,
    positions: np.ndarray,
    box_length: float,
    strain: float,
    r_max: float,
    xy_half_width: float,
    slab_half_thickness: float,
    brute_force: bool,
) -> None:
    """Add one configuration's counts to ``radial`` (K,) and ``planar`` (M, M) int64, in place."""
    _check_histogram_arguments(
        positions,
        box_length,
        strain,
        r_max,
        radial.shape[0],
        xy_half_width,
        planar.shape[0],
        slab_half_thickness,
    )
    if planar.shape[1] != planar.shape[0]:
        raise ValueError("the x-y counts must be square (M, M)")
    offset = lees_edwards_offset(strain, box_length)
    reach = max(r_max, math.sqrt(2.0 * xy_half_width**2 + slab_half_thickness**2))
    if brute_force or reach > 0.5 * box_length:
        _add_all_pairs(
            radial, planar, positions, box_length, offset, r_max, xy_half_width, slab_half_thickness
        )
        return
    _, separations = build_pair_list(positions, box_length, offset, reach)
    for k in range(separations.shape[0]):
        _bin_pair(
            separations[k, 0],
            separations[k, 1],
            separations[k, 2],
            r_max,
            xy_half_width,
            slab_half_thickness,
            radial,
            planar,
        )


@njit(cache=True)
def _new_pair_histograms(
    positions: np.ndarray,
    box_length: float,
    strain: float,
    r_max: float,
    n_radial_bins: int,
    xy_half_width: float,
    n_xy_bins: int,
    slab_half_thickness: float,
    brute_force: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed ``(K,)`` and ``(M, M)`` int64 counts filled by :func:`_add_pair_histograms` (see there)."""
    if n_radial_bins < 1:
        raise ValueError("n_radial_bins must be >= 1")
    if n_xy_bins < 1:
        raise ValueError("n_xy_bins must be >= 1")
    radial = np.zeros(n_radial_bins, dtype=np.int64)
    planar = np.zeros((n_xy_bins, n_xy_bins), dtype=np.int64)
    _add_pair_histograms(
        radial, planar, positions, box_length, strain, r_max, xy_half_width, slab_half_thickness, brute_force
    )
    return radial, planar


@njit(cache=True)
def pair_histograms(
    positions: np.ndarray,
    box_length: float,
    strain: float,
    r_max: float,
    n_radial_bins: int,
    xy_half_width: float,
    n_xy_bins: int,
    slab_half_thickness: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Pair counts of one configuration: radial shells and the x–y grid of the slab ``|dz| < h``.

    The raw counts ``C_k`` and ``C_ij`` of the module docstring (divide by the ideal-gas counts, or use
    :class:`PairDistributionAccumulator`, to get ``g``). Pairs come from the Lees–Edwards cell list
    within ``max(r_max, sqrt(2 R^2 + h^2))`` when that is at most ``L/2``, else from all pairs; both give
    the same counts as :func:`pair_histograms_brute_force`.

    Args:
        positions: (N, 3) float64 centres wrapped into ``[0, L)^3`` (units a).
        box_length: box side ``L`` (units a).
        strain: accumulated strain ``gammadot t`` (sets the Lees–Edwards offset; 0 when quiescent).
        r_max: outer radius of the last shell (units a), in ``(0, L/2]``.
        n_radial_bins: number ``K >= 1`` of shells of width ``r_max / K``.
        xy_half_width: ``R`` (units a), in ``(0, L/2]``: the grid covers ``-R <= dx, dy < R``.
        n_xy_bins: number ``M >= 1`` of bins per side (side ``2R / M``).
        slab_half_thickness: ``h`` (units a), in ``(0, L/2]``: pairs with ``|dz| < h`` enter the grid.

    Returns:
        ``(radial, planar)``: (K,) int64 pairs ``i < j`` per shell; (M, M) int64 ordered pairs per x–y bin
        (index ``[x bin, y bin]``).

    References:
        Allen & Tildesley (2017), §2.6 and ch. 8; Foss & Brady (2000), J. Fluid Mech. 407, 167.
    """
    return _new_pair_histograms(
        positions,
        box_length,
        strain,
        r_max,
        n_radial_bins,
        xy_half_width,
        n_xy_bins,
        slab_half_thickness,
        False,
    )


@njit(cache=True)
def pair_histograms_brute_force(
    positions: np.ndarray,
    box_length: float,
    strain: float,
    r_max: float,
    n_radial_bins: int,
    xy_half_width: float,
    n_xy_bins: int,
    slab_half_thickness: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Twin of :func:`pair_histograms` over all ``N (N - 1) / 2`` pairs (O(N^2); same arguments and result).

    Each pair's separation is :func:`sim.geometry.box.minimum_image` of ``x_j - x_i`` (``i < j``), the same
    floating-point operations as the cell list's, so the counts are identical.

    References:
        Allen & Tildesley (2017), §2.6 and ch. 8.
    """
    return _new_pair_histograms(
        positions,
        box_length,
        strain,
        r_max,
        n_radial_bins,
        xy_half_width,
        n_xy_bins,
        slab_half_thickness,
        True,
    )


def _positive(name: str, value: float, upper: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and 0.0 < value <= upper):
        raise ValueError(
            f"{name} must be in (0, {upper:g}] (half the box side L = {2 * upper:g}), got {value!r}"
        )
    return value


def _count(name: str, value: int, low: int) -> int:
    if isinstance(value, bool) or int(value) != value or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


@dataclass
class PairDistributionAccumulator:
    """Pair counts summed over configurations; ``g(r)`` and the x–y projection ``g_xy`` at the end.

    Attributes:
        n_particles: ``N >= 2``.
        box_length: ``L`` (units a).
        r_max: outer radius of the last shell (units a), ``<= L/2``.
        xy_half_width: ``R`` of the x–y grid ``[-R, R)^2`` (units a), ``<= L/2``.
        slab_half_thickness: ``h`` of the slab ``|dz| < h`` (units a), ``<= L/2``.
        radial_counts: (K,) int64 pairs per shell, summed over configurations.
        planar_counts: (M, M) int64 ordered pairs per x–y bin ``[x bin, y bin]``, summed.
        samples: number of configurations ``S`` added.

    References:
        Allen & Tildesley (2017), §2.6; paper §3.3 and Fig. 5.
    """

    n_particles: int
    box_length: float
    r_max: float
    xy_half_width: float
    slab_half_thickness: float
    radial_counts: np.ndarray
    planar_counts: np.ndarray
    samples: int = 0

    @classmethod
    def create(
        cls,
        n_particles: int,
        box_length: float,
        r_max: float,
        n_radial_bins: int,
        xy_half_width: float,
        n_xy_bins: int,
        slab_half_thickness: float = DEFAULT_SLAB_HALF_THICKNESS,
    ) -> PairDistributionAccumulator:
        """An empty accumulator (arguments as in :func:`pair_histograms`; ``n_particles >= 2``).

        Raises:
            ValueError: naming the argument and its valid range.
        """
        n = _count("n_particles", n_particles, 2)
        length = float(box_length)
        if not (math.isfinite(length) and length > 0.0):
            raise ValueError(f"box_length must be finite and > 0, got {box_length!r}")
        half = 0.5 * length
        return cls(
            n_particles=n,
            box_length=length,
            r_max=_positive("r_max", r_max, half),
            xy_half_width=_positive("xy_half_width", xy_half_width, half),
            slab_half_thickness=_positive("slab_half_thickness", slab_half_thickness, half),
            radial_counts=np.zeros(_count("n_radial_bins", n_radial_bins, 1), dtype=np.int64),
            planar_counts=np.zeros((_count("n_xy_bins", n_xy_bins, 1),) * 2, dtype=np.int64),
        )

    @classmethod
    def for_box(cls, n_particles: int, box_length: float) -> PairDistributionAccumulator:
        """The run's default binning, limited by the box (every range at most ``L/2``).

        Shells of :data:`DEFAULT_RADIAL_BIN_WIDTH` up to :data:`DEFAULT_RADIAL_RANGE`; x–y bins of
        :data:`DEFAULT_SHEAR_PLANE_BIN_WIDTH` over ``[-R, R)^2`` with ``R`` up to
        :data:`DEFAULT_SHEAR_PLANE_RANGE`; slab :data:`DEFAULT_SLAB_HALF_THICKNESS`. A smaller box keeps
        the bin widths and takes as many whole bins as fit in ``L/2``.
        """
        half = 0.5 * float(box_length)
        n_radial = max(int(math.floor(min(DEFAULT_RADIAL_RANGE, half) / DEFAULT_RADIAL_BIN_WIDTH + 1e-9)), 1)
        per_side = int(
            math.floor(min(DEFAULT_SHEAR_PLANE_RANGE, half) / DEFAULT_SHEAR_PLANE_BIN_WIDTH + 1e-9)
        )
        per_side = max(per_side, 1)
        return cls.create(
            n_particles,
            box_length,
            min(n_radial * DEFAULT_RADIAL_BIN_WIDTH, half),
            n_radial,
            min(per_side * DEFAULT_SHEAR_PLANE_BIN_WIDTH, half),
            2 * per_side,
            min(DEFAULT_SLAB_HALF_THICKNESS, half),
        )

    def add(self, positions: np.ndarray, strain: float) -> None:
        """Add one configuration: (N, 3) float64 wrapped positions (units a) at accumulated ``strain``."""
        positions = np.ascontiguousarray(positions, dtype=np.float64)
        if positions.shape != (self.n_particles, 3):
            raise ValueError(f"positions must have shape ({self.n_particles}, 3), got {positions.shape}")
        _add_pair_histograms(
            self.radial_counts,
            self.planar_counts,
            positions,
            self.box_length,
            float(strain),
            self.r_max,
            self.xy_half_width,
            self.slab_half_thickness,
            False,
        )
        self.samples += 1

    @property
    def r_edges(self) -> np.ndarray:
        """(K + 1,) shell edges ``0 .. r_max`` (units a)."""
        return np.linspace(0.0, self.r_max, self.radial_counts.shape[0] + 1)

    @property
    def x_edges(self) -> np.ndarray:
        """(M + 1,) bin edges ``-R .. R`` of ``dx`` (units a)."""
        return np.linspace(-self.xy_half_width, self.xy_half_width, self.planar_counts.shape[0] + 1)

    @property
    def y_edges(self) -> np.ndarray:
        """(M + 1,) bin edges ``-R .. R`` of ``dy`` (units a); the same as :attr:`x_edges`."""
        return self.x_edges

    @property
    def radial_ideal_counts(self) -> np.ndarray:
        """(K,) ideal-gas pairs per shell in one configuration:
        ``N (N - 1)/2 (4/3) pi (r_{k+1}^3 - r_k^3) / V``."""
        edges = self.r_edges
        n = self.n_particles
        return 0.5 * n * (n - 1) * (4.0 / 3.0) * math.pi * np.diff(edges**3) / self.box_length**3

    @property
    def planar_ideal_count(self) -> float:
        """Ideal-gas ordered pairs per x–y bin in one configuration: ``N (N - 1) w^2 (2 h) / V``."""
        n = self.n_particles
        width = 2.0 * self.xy_half_width / self.planar_counts.shape[0]
        return n * (n - 1) * width * width * 2.0 * self.slab_half_thickness / self.box_length**3

    @property
    def g_r(self) -> np.ndarray:
        """(K,) ``g`` per shell (dimensionless); NaN before any configuration."""
        if self.samples == 0:
            return np.full(self.radial_counts.shape, np.nan)
        return self.radial_counts / (self.samples * self.radial_ideal_counts)

    @property
    def g_xy(self) -> np.ndarray:
        """(M, M) ``g`` per x–y bin ``[x bin, y bin]`` (dimensionless); NaN before any configuration."""
        if self.samples == 0:
            return np.full(self.planar_counts.shape, np.nan)
        return self.planar_counts / (self.samples * self.planar_ideal_count)

    def result_arrays(self) -> dict[str, np.ndarray]:
        """The arrays of ``pair_distribution.npz``: ``r_edges``, ``g_r``, ``x_edges``, ``y_edges``, ``g_xy``
        (index ``[x bin, y bin]``), ``samples``, and the raw counts and parameters behind them."""
        return {
            "r_edges": self.r_edges,
            "g_r": self.g_r,
            "x_edges": self.x_edges,
            "y_edges": self.y_edges,
            "g_xy": self.g_xy,
            "samples": np.array(self.samples, dtype=np.int64),
            "radial_counts": self.radial_counts,
            "planar_counts": self.planar_counts,
            "slab_half_thickness": np.array(self.slab_half_thickness),
            "n_particles": np.array(self.n_particles, dtype=np.int64),
            "box_length": np.array(self.box_length),
        }

    def arrays(self, prefix: str = "pair_") -> dict[str, np.ndarray]:
        """Arrays for ``np.savez`` (exact); keys start with ``prefix``."""
        return {
            f"{prefix}n_particles": np.array(self.n_particles, dtype=np.int64),
            f"{prefix}box_length": np.array(self.box_length, dtype=np.float64),
            f"{prefix}r_max": np.array(self.r_max, dtype=np.float64),
            f"{prefix}xy_half_width": np.array(self.xy_half_width, dtype=np.float64),
            f"{prefix}slab_half_thickness": np.array(self.slab_half_thickness, dtype=np.float64),
            f"{prefix}radial_counts": self.radial_counts,
            f"{prefix}planar_counts": self.planar_counts,
            f"{prefix}samples": np.array(self.samples, dtype=np.int64),
        }

    @classmethod
    def from_arrays(cls, data: Any, prefix: str = "pair_") -> PairDistributionAccumulator:
        """Inverse of :meth:`arrays`."""
        return cls(
            n_particles=int(data[f"{prefix}n_particles"]),
            box_length=float(data[f"{prefix}box_length"]),
            r_max=float(data[f"{prefix}r_max"]),
            xy_half_width=float(data[f"{prefix}xy_half_width"]),
            slab_half_thickness=float(data[f"{prefix}slab_half_thickness"]),
            radial_counts=np.array(data[f"{prefix}radial_counts"], dtype=np.int64),
            planar_counts=np.array(data[f"{prefix}planar_counts"], dtype=np.int64),
            samples=int(data[f"{prefix}samples"]),
        )
