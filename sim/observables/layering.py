"""Layer order along the field: the density structure factor at the wavevectors of layers normal to it.

Under a field the spheres form sheets normal to the field, about ``2.45 a`` apart
(``docs/validation.md#published-results``:
layers normal to ``y`` at ``phi = 0.3, Mn = 1`` and ``phi = 0.45, Mn = 0.1``). Their order is measured by
the density structure factor (Hansen & McDonald, Theory of Simple Liquids, 4th ed. 2013, eq. 4.1.3 and
§4.1)::

    S(k) = |sum_j exp(-i k . r_j)|^2 / N,        k = (2 pi m / L) e_axis  (m = 1, 2, ...),

at the wavevectors of the periodic box along the box axis ``e_axis`` of the field (``x``, ``y`` or
``z``), over the harmonics ``m`` whose plane spacing ``L/m`` lies in
:data:`LAYER_SPACING_RANGE` = [1.8, 4] a (``ceil(L/4) <= m <= floor(L/1.8)``; the ``m`` nearest
``L / 2.45`` when that range holds no integer). Reported: ``S_peak = max_m S(k_m)``, its ``k_peak``
(units 1/a), the spacing ``2 pi / k_peak`` (units a) and the normalised order parameter
``psi = S_peak / N``, in ``[0, 1]``: 1 when every particle lies on planes ``L/m`` apart, and of order
``1/N`` for uncorrelated positions (an ideal gas has ``<S(k)> = 1`` at every allowed ``k != 0``; the
maximum over the ``M`` harmonics of such exponentially distributed values averages ``(1 + 1/2 + ... +
1/M)/N``); a dense liquid's first peak ``S ~ 2-3`` also gives ``psi ~ 3/N``.

Lees–Edwards boundaries: the periodic images of the sheared box sit at the lattice vectors ``a1 = (L, 0,
0)``, ``a2 = (delta, L, 0)``, ``a3 = (0, 0, L)`` (``delta`` the offset, :mod:`sim.geometry.box`), and
``S(k)`` is a property of the suspension, independent of which image represents a particle, only for
``k`` in the reciprocal lattice, ``k . a_i`` a multiple of ``2 pi``. For ``k`` along ``y`` or ``z``
(``k_x = 0``), ``k . a2 = k_y L`` does not involve ``delta``: the offset does not matter. A ``k`` along
``x`` is *not* such a vector unless ``m delta / L`` is an integer (``k . a2 = 2 pi m delta / L``): the
box is plain periodic in ``x`` at fixed ``y``, but a particle crossing ``y = L`` reappears shifted by
``delta`` in ``x``, so ``S(k_x)`` would jump when one does. For the field along ``x`` the wavevector is
therefore projected onto the nearest reciprocal vector of the sheared lattice,
``k = (2 pi / L) (m, n - m delta / L, 0)`` with ``n = round(m delta / L)``: planes normal to ``x`` tilted
by the shear just enough to be periodic across ``y = L`` (``|k|`` grows by at most ``sqrt(1 + 1/4)``;
at ``delta = 0`` it is the unsheared ``k``). Field directions that are not box axes are refused by
:func:`layer_axis` (``ValueError`` naming ``field_direction``); :func:`nearest_layer_axis` picks the
axis closest to them for a run that must sample something (see :mod:`sim.runs.observables`).

Cost (numpy, vectorised over particles and harmonics; shared 2-core VM, ``phi = 0.45``): 0.1 ms per
configuration at N = 500 (5 harmonics, L = 16.7 a) and 1.3 ms at N = 4000 (10 harmonics), against about
8 ms for one time step at N = 500; sampled every 25 steps that is < 0.1% of a run.

References:
    Hansen, J.-P. & McDonald, I. R. (2013) Theory of Simple Liquids, 4th ed., Academic Press, §4.1
    (static structure factor, eq. 4.1.3; ideal gas ``S(k) = 1``).
    Lees, A. W. & Edwards, S. F. (1972) J. Phys. C 5, 1921 (sheared periodic lattice).
    Mirfendereski, S. & Park, J. S. (2024) J. Fluid Mech., §3 (layers normal to the field).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.geometry.box import lees_edwards_offset
from sim.observables.stress import block_average

LAYER_SPACING_RANGE = (1.8, 4.0)
"""Plane spacings (units a) whose harmonics are searched: around the observed 2.45 a, excluding the
contact shell below 1.8 a (< 2 a is closer than touching planes could be in a dense layer) and the
box-scale modes above 4 a."""

TYPICAL_LAYER_SPACING = 2.45
"""Layer spacing seen in simulations (units a); picks the harmonic when :data:`LAYER_SPACING_RANGE`
holds none (boxes smaller than 3.3 a)."""

AXIS_TOLERANCE = 1e-9
"""A direction counts as a box axis when its other components are below this (it is normalised)."""

LAYERED_MIN_STRUCTURE_FACTOR = 10.0
"""A run counts as layered when the mean of ``S_peak`` after the transient is at least 10: ten times
the ideal-gas value 1 and three to five times the first peak of a dense hard-sphere liquid (``S ~ 2-3``
at ``phi = 0.45``), so liquid-like structure and noise do not qualify."""

LAYERED_MIN_GAIN = 3.0
"""... and at least three times ``psi`` at the start of the run (the mean of its first
:data:`ONSET_PERSISTENCE` samples): structure that was there from the start (the initial packing's, or a
liquid's near its first peak, ``k ~ 3.5/a``, which the shortest searched spacings reach) has no onset. A
liquid's ``S_peak`` fluctuates by a factor of about 2 between samples, so 3 separates it from an ordering
run (measured: box-size study at ``phi = 0.45, Mn = 1``: gains 6-90 for runs that ordered, 1.6 for an
``N = 500`` run whose peak stayed at ``S ~ 12-20`` from strain 0)."""

ONSET_FRACTION = 0.5
"""The onset is where ``psi`` first reaches this fraction of its plateau (the mean after the transient)."""

ONSET_PERSISTENCE = 5
"""... and stays at or above it for this many consecutive samples (0.25 strain at the default interval),
so a single fluctuation does not count."""

AXIS_NAMES = ("x", "y", "z")


def layer_axis(field_direction: Sequence[float] | np.ndarray) -> int:
    """Index (0, 1, 2 for x, y, z) of the box axis along ``field_direction``.

    Args:
        field_direction: (3,) direction of the field (any length > 0; sign irrelevant).

    Raises:
        ValueError: the direction is not along a box axis (periodic wavevectors exist only along the
            axes of the cubic box); the message names ``field_direction``.
    """
    direction = np.asarray(field_direction, dtype=np.float64).reshape(-1)
    norm = float(np.linalg.norm(direction)) if direction.size == 3 else 0.0
    if direction.size != 3 or not math.isfinite(norm) or norm == 0.0:
        raise ValueError(
            f"field_direction must be three finite numbers, not all zero, got {field_direction!r}"
        )
    unit = np.abs(direction) / norm
    axis = int(np.argmax(unit))
    if np.max(np.delete(unit, axis)) > AXIS_TOLERANCE:
        raise ValueError(
            "field_direction must be along x, y or z for the layer order (the periodic box has wavevectors "
            f"only along its axes), got {tuple(float(c) for c in direction)}"
        )
    return axis


def nearest_layer_axis(field_direction: Sequence[float] | np.ndarray) -> int:
    """Index of the box axis closest to ``field_direction`` (its largest component; the first on ties)."""
    direction = np.abs(np.asarray(field_direction, dtype=np.float64).reshape(3))
    return int(np.argmax(direction))


def layer_harmonics(box_length: float) -> np.ndarray:
    """Harmonics ``m`` with ``L/m`` in :data:`LAYER_SPACING_RANGE`: ``ceil(L/4) .. floor(L/1.8)``.

    Args:
        box_length: box side ``L`` (units a), > 0.

    Returns:
        (M,) int64, ``M >= 1``: when the range holds no integer (``L`` below about 3.3 a), the single
        ``m = max(round(L / 2.45), 1)``.
    """
    low, high = LAYER_SPACING_RANGE
    first = max(math.ceil(box_length / high - 1e-12), 1)
    last = math.floor(box_length / low + 1e-12)
    if last < first:
        return np.array([max(round(box_length / TYPICAL_LAYER_SPACING), 1)], dtype=np.int64)
    return np.arange(first, last + 1, dtype=np.int64)


def layer_wavevectors(box_length: float, axis: int, strain: float, harmonics: np.ndarray) -> np.ndarray:
    """Reciprocal-lattice wavevectors of layers normal to ``axis`` (module docstring).

    ``k_m = (2 pi m / L) e_axis`` for ``axis`` 1 (y) or 2 (z); for ``axis`` 0 (x) the nearest vector of
    the sheared reciprocal lattice, ``(2 pi / L) (m, n - m delta / L, 0)``, ``n = round(m delta / L)``,
    ``delta = lees_edwards_offset(strain, L)``.

    Args:
        box_length: box side ``L`` (units a).
        axis: 0, 1 or 2.
        strain: accumulated strain (sets the Lees–Edwards offset; used only for ``axis`` 0).
        harmonics: (M,) integers ``m``.

    Returns:
        (M, 3) float64 wavevectors (units 1/a).
    """
    m = np.asarray(harmonics, dtype=np.float64)
    k = np.zeros((m.size, 3))
    k[:, axis] = 2.0 * math.pi * m / box_length
    if axis == 0:
        tilt = m * lees_edwards_offset(float(strain), float(box_length)) / box_length
        k[:, 1] = 2.0 * math.pi * (np.round(tilt) - tilt) / box_length
    return k


def structure_factor(positions: np.ndarray, wavevectors: np.ndarray) -> np.ndarray:
    """``S(k) = |sum_j exp(-i k . r_j)|^2 / N`` at each wavevector (Hansen & McDonald eq. 4.1.3).

    Args:
        positions: (N, 3) float64 centres (units a).
        wavevectors: (M, 3) float64 (units 1/a).

    Returns:
        (M,) float64 ``S(k)`` (dimensionless, in ``[0, N]``).
    """
    positions = np.asarray(positions, dtype=np.float64)
    phase = positions @ np.asarray(wavevectors, dtype=np.float64).T  # (N, M)
    cos_sum = np.cos(phase).sum(axis=0)
    sin_sum = np.sin(phase).sum(axis=0)
    return (cos_sum * cos_sum + sin_sum * sin_sum) / positions.shape[0]


@dataclass(frozen=True)
class LayerOrder:
    """Layer order of one configuration.

    Attributes:
        psi: ``S_peak / N`` in ``[0, 1]``.
        s_peak: ``max_m S(k_m)`` (dimensionless).
        k_peak: ``|k|`` of the maximum (units 1/a).
        spacing: ``2 pi / k_peak`` (units a).
        harmonic: its ``m``.
    """

    psi: float
    s_peak: float
    k_peak: float
    spacing: float
    harmonic: int


def layer_order(
    positions: np.ndarray,
    box_length: float,
    field_direction: Sequence[float] | np.ndarray | int,
    strain: float = 0.0,
) -> LayerOrder:
    """``S_peak``, ``k_peak``, spacing and ``psi`` of layers normal to the field (module docstring).

    Args:
        positions: (N, 3) float64 centres (units a), any periodic images.
        box_length: box side ``L`` (units a).
        field_direction: (3,) field direction along a box axis, or the axis index (0, 1, 2).
        strain: accumulated strain of the Lees–Edwards box (matters only for a field along x).

    Returns:
        The :class:`LayerOrder`; ties between harmonics go to the smallest ``m``.

    Raises:
        ValueError: ``field_direction`` is not along a box axis.
    """
    axis = field_direction if isinstance(field_direction, int) else layer_axis(field_direction)
    if axis not in (0, 1, 2):
        raise ValueError(f"field_direction as an axis index must be 0, 1 or 2, got {axis!r}")
    harmonics = layer_harmonics(box_length)
    k = layer_wavevectors(box_length, axis, strain, harmonics)
    s = structure_factor(positions, k)
    best = int(np.argmax(s))
    k_peak = float(np.linalg.norm(k[best]))
    s_peak = float(s[best])
    return LayerOrder(
        psi=s_peak / positions.shape[0],
        s_peak=s_peak,
        k_peak=k_peak,
        spacing=2.0 * math.pi / k_peak,
        harmonic=int(harmonics[best]),
    )


def layer_onset_index(psi: np.ndarray, plateau: float, n_particles: int) -> int | None:
    """Index of the sample at which layering sets in; None if the run has not layered.

    The run has layered when ``plateau * N >= LAYERED_MIN_STRUCTURE_FACTOR`` (the mean ``S_peak`` after
    the transient is at least 10) and ``plateau >= LAYERED_MIN_GAIN * psi_start``, ``psi_start`` the mean
    of the first ``ONSET_PERSISTENCE`` samples (the order grew during the run). The onset is then the
    first sample ``i`` with ``psi_j >= ONSET_FRACTION * plateau`` for every ``j`` in ``i .. i +
    ONSET_PERSISTENCE - 1`` (all of them samples of the run); None when no such stretch of samples
    exists.

    Args:
        psi: (K,) ``psi`` of the samples, in time order (from the start of the run).
        plateau: mean ``psi`` after the transient.
        n_particles: ``N``.
    """
    psi = np.asarray(psi, dtype=np.float64)
    if not (math.isfinite(plateau) and plateau * n_particles >= LAYERED_MIN_STRUCTURE_FACTOR):
        return None
    width = ONSET_PERSISTENCE
    if psi.size < width or plateau < LAYERED_MIN_GAIN * float(psi[:width].mean()):
        return None
    above = (psi >= ONSET_FRACTION * plateau).astype(np.int64)
    runs = np.convolve(above, np.ones(width, dtype=np.int64), mode="valid")  # runs[i] = sum above[i:i+w]
    hits = np.flatnonzero(runs == width)
    return int(hits[0]) if hits.size else None


def harmonic_of(k_peak: np.ndarray | float, box_length: float) -> np.ndarray:
    """The harmonic ``m`` of a peak wavevector: ``round(k_peak L / 2 pi)``.

    Exact for the tilted ``x`` wavevectors too: ``|k| L / 2 pi = sqrt(m^2 + t^2)`` with ``|t| <= 1/2``
    lies in ``[m, m + 1/2)`` for ``m >= 1``.
    """
    return np.rint(np.asarray(k_peak, dtype=np.float64) * box_length / (2.0 * math.pi)).astype(np.int64)


LAYER_COLUMNS = ("time", "strain", "psi", "s_peak", "k_peak", "spacing")
"""Columns of a :class:`LayerOrderSeries` row and of ``layering.csv``."""


@dataclass
class LayerOrderSeries:
    """``psi``, ``S_peak``, ``k_peak`` and spacing of configurations sampled along a run.

    Attributes:
        box_length: ``L`` (units a).
        axis: the box axis of the field (0, 1, 2).
        n_particles: ``N``.
        rows: one tuple per sample, :data:`LAYER_COLUMNS` (time in 1/gammadot_ref, strain, psi,
            S_peak, k_peak in 1/a, spacing in a).
    """

    box_length: float
    axis: int
    n_particles: int
    rows: list[tuple[float, float, float, float, float, float]]

    def add(self, positions: np.ndarray, time: float, strain: float) -> LayerOrder:
        """Append the layer order of ``positions`` at clock ``time`` and ``strain``; return it."""
        order = layer_order(positions, self.box_length, self.axis, strain)
        self.rows.append((float(time), float(strain), order.psi, order.s_peak, order.k_peak, order.spacing))
        return order

    def table(self) -> np.ndarray:
        """(K, 6) float64 of the rows."""
        return np.array(self.rows, dtype=np.float64).reshape(-1, len(LAYER_COLUMNS))

    def arrays(self, prefix: str = "layer_") -> dict[str, np.ndarray]:
        """Arrays for the checkpoint (exact)."""
        return {
            f"{prefix}box_length": np.array(self.box_length, dtype=np.float64),
            f"{prefix}axis": np.array(self.axis, dtype=np.int64),
            f"{prefix}n_particles": np.array(self.n_particles, dtype=np.int64),
            f"{prefix}rows": self.table(),
        }

    @classmethod
    def from_arrays(cls, data: Mapping[str, Any], prefix: str = "layer_") -> LayerOrderSeries:
        """Inverse of :meth:`arrays` (``data`` a mapping of arrays, e.g. an open ``.npz``)."""
        table = np.asarray(data[f"{prefix}rows"], dtype=np.float64).reshape(-1, len(LAYER_COLUMNS))
        return cls(
            box_length=float(data[f"{prefix}box_length"]),
            axis=int(data[f"{prefix}axis"]),
            n_particles=int(data[f"{prefix}n_particles"]),
            rows=[(r[0], r[1], r[2], r[3], r[4], r[5]) for r in table.tolist()],
        )

    def write_csv(self, path: Path) -> None:
        """``layering.csv``: a header of :data:`LAYER_COLUMNS`, one row per sample (``%.10g``)."""
        np.savetxt(
            path,
            self.table(),
            delimiter=",",
            header=",".join(LAYER_COLUMNS),
            comments="",
            fmt="%.10g",
        )


@dataclass(frozen=True)
class LayerSummary:
    """Layer order of a run (:func:`summarise_layering`).

    Attributes:
        order: mean ``psi`` of the samples at clock ``>= from_time`` (the plateau).
        order_stderr: its block-average standard error (NaN with fewer samples than blocks).
        spacing: spacing (units a) of the most frequent peak harmonic among those samples (ties: the
            smaller ``m``), averaged over the samples that have it: exactly ``L/m`` for a field along
            ``y`` or ``z``; NaN without samples.
        onset_time: clock of the onset (:func:`layer_onset_index`), NaN if the run has not layered.
        onset_strain: strain of that sample, NaN likewise.
        samples: how many samples the averages hold.
    """

    order: float
    order_stderr: float
    spacing: float
    onset_time: float
    onset_strain: float
    samples: int


def summarise_layering(series: LayerOrderSeries, from_time: float, n_blocks: int = 10) -> LayerSummary:
    """Plateau, standard error, spacing and onset of ``series`` (averages over clock ``>= from_time``).

    The standard error comes from ``n_blocks`` contiguous blocks
    (:func:`sim.observables.stress.block_average`, Flyvbjerg & Petersen 1989), as for the stress; the
    samples are equally spaced in time, so unweighted.
    """
    table = series.table()
    window = table[:, 0] >= from_time - 1e-12
    psi = table[window, 2]
    average = block_average(psi, n_blocks)
    spacing = math.nan
    if psi.size:
        harmonics = harmonic_of(table[window, 4], series.box_length)
        values, counts = np.unique(harmonics, return_counts=True)
        modal = values[int(np.argmax(counts))]
        spacing = float(table[window, 5][harmonics == modal].mean())
    onset = layer_onset_index(table[:, 2], average.mean, series.n_particles)
    return LayerSummary(
        order=average.mean,
        order_stderr=average.stderr,
        spacing=spacing,
        onset_time=float(table[onset, 0]) if onset is not None else math.nan,
        onset_strain=float(table[onset, 1]) if onset is not None else math.nan,
        samples=int(psi.size),
    )
