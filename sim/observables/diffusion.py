"""Self-diffusion under shear: non-affine displacements, mean-square displacement, diffusivities.

Three pieces (paper §3.4, Fig. 6; ``docs/model.md#observables``):

* :func:`accumulate_displacement` — called by the compiled step loop (:func:`sim.stepper.advance`) after
  every step: adds the step's non-affine displacement of each sphere, in the unwrapped frame, to the
  state's ``displacement`` (N, 3);
* :func:`mean_square_displacement` and :class:`MsdAccumulator` — the mean-square displacement over all
  time origins of displacement samples taken at a fixed interval (a batch function and a running
  accumulator with a fixed memory, twins of each other);
* :func:`fit_diffusivity` and :func:`diffusivity_fit_window` — the diffusivities ``D_aa`` from the slope of
  ``MSD_aa(tau) ~ 2 D_aa tau`` over the diffusive window.

Unwrapped, non-affine displacement. In the Lees–Edwards box a sphere leaving through a ``y`` face
re-enters as its image shifted by ``-/+ delta`` in ``x``; its unwrapped trajectory ``X(t)`` is the
continuous one. Over a step ``t -> t + dt`` the minimum image (with the offset ``delta`` in force at
``t + dt``) of the difference of the wrapped positions, ``Delta = mi(x_new - x_old)``, is the displacement
of the sphere's image that started the step in the box; the affine displacement of that image is
``gammadot int y dt`` with its own ``y(t) = y_old + (Delta_y / dt)(t' - t)`` (trapezoid rule), so the
non-affine displacement of the step is

    ``d = Delta - gammadot dt (y_old + Delta_y / 2) x_hat``,

which does not depend on which image is followed (a shift by ``L`` in ``y`` moves ``x`` by ``gammadot L``
per unit time and adds ``gammadot L dt`` to the affine part alike). It is exact (to round-off) for pure
affine motion and for any motion whose ``y`` is linear in time over the step (a constant ``U_y``), and it
includes the displacement of the overlap removal (made at the end of the step). Summed over steps,
``D(t) = X(t) - X(0) - gammadot x_hat int_0^t Y dt'``: the non-affine displacement of Foss & Brady (1999)
and Sierou & Brady (2004). Without shear (``gammadot = 0``) ``D = X(t) - X(0)``, and time is in ``a/U0``.

Units: lengths in ``a``; time in strain (``1/gammadot``) when sheared and in ``a/U0`` when quiescent; so
``D`` is in ``gammadot a^2`` (sheared) or ``U0 a`` (quiescent).

References:
    Allen & Tildesley (2017), Computer Simulation of Liquids, 2nd ed., ch. 2 (Einstein relation for the
    self-diffusion coefficient) and ch. 8 (averaging time correlations over all time origins);
    Foss & Brady (1999), J. Fluid Mech. 401, 243 and Sierou & Brady (2004), J. Fluid Mech. 506, 285
    (shear-induced self-diffusion from non-affine displacements, long-time slope of the MSD);
    Mirfendereski & Park (2024), J. Fluid Mech., §3.4 and Fig. 6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from sim.geometry.box import separation_between

__all__ = [
    "DIFFUSIVITY_FIT_START",
    "MIN_INDEPENDENT_SEGMENTS",
    "MsdAccumulator",
    "accumulate_displacement",
    "diffusivity_fit_window",
    "fit_diffusivity",
    "mean_square_displacement",
]

DIFFUSIVITY_FIT_START = 1.0
"""Smallest lag (strain, or ``a/U0`` when quiescent) of the diffusivity fit: the MSD of sheared dense
suspensions leaves its short-time (ballistic) regime after a strain of order one (Sierou & Brady 2004;
paper Fig. 6 inset); a straight line fitted from lag 1 on carries the crossover in its intercept."""

MIN_INDEPENDENT_SEGMENTS = 4
"""The largest lag of the fit is the MSD window over this number: each sphere's path then holds at least
four non-overlapping segments of every fitted lag, so that no fitted MSD rests on one stretch of path."""


@njit(cache=True)
def accumulate_displacement(
    displacement: np.ndarray,
    old_positions: np.ndarray,
    new_positions: np.ndarray,
    time_step: float,
    shear_rate: float,
    box_length: float,
    offset: float,
) -> None:
    """Add one step's non-affine, unwrapped displacement to ``displacement`` (in place).

    ``d = mi(x_new - x_old) - gammadot dt (y_old + Delta_y / 2) x_hat`` per sphere (module docstring), with
    the minimum image ``mi`` taken with the Lees–Edwards offset in force at the end of the step. Exact
    for per-step displacements below ``L/2`` in each component (steps move spheres by less than 1% of
    the spacing). O(N).

    Args:
        displacement: (N, 3) float64 accumulated non-affine displacement (units a); updated in place.
        old_positions: (N, 3) float64 wrapped positions at the start of the step (units a).
        new_positions: (N, 3) float64 wrapped positions at the end of the step, after the Lees–Edwards
            wrap and the overlap removal (units a).
        time_step: step size ``dt`` (time units), >= 0.
        shear_rate: ``gammadot`` (1 sheared, 0 quiescent).
        box_length: box side ``L`` (units a).
        offset: Lees–Edwards offset at the end of the step (:func:`sim.geometry.box.lees_edwards_offset` of
            ``gammadot (t + dt)``), units a.

    References:
        Foss & Brady (1999), J. Fluid Mech. 401, 243 (non-affine displacements under Lees–Edwards
        boundaries); Allen & Tildesley (2017), §11.3.
    """
    affine_rate = shear_rate * time_step
    for p in range(displacement.shape[0]):
        dx, dy, dz = separation_between(old_positions, p, new_positions, p, box_length, offset)
        displacement[p, 0] += dx - affine_rate * (old_positions[p, 1] + 0.5 * dy)
        displacement[p, 1] += dy
        displacement[p, 2] += dz


@njit(cache=True)
def mean_square_displacement(samples: np.ndarray, max_lag: int) -> np.ndarray:
    """Mean-square displacement per component over all time origins and all spheres.

    ``MSD_a(m) = 1 / (N (S - m)) sum_{k=0}^{S-m-1} sum_p [D_pa(t_{k+m}) - D_pa(t_k)]^2`` for samples
    ``D(t_k)`` taken at equal intervals (Allen & Tildesley 2017, ch. 8: all time origins). This is the
    batch twin of :class:`MsdAccumulator`.

    Args:
        samples: (S, N, 3) float64 displacements ``D(t_k)`` (units a), e.g. unwrapped non-affine ones.
        max_lag: largest lag ``M >= 0`` in samples.

    Returns:
        (M + 1, 3) float64: row ``m`` is ``(MSD_xx, MSD_yy, MSD_zz)`` at lag ``m`` (units a^2); row 0 is 0,
        rows with ``m >= S`` (no origin) are NaN.

    References:
        Allen & Tildesley (2017), Computer Simulation of Liquids, 2nd ed., ch. 2 and ch. 8.
    """
    if samples.ndim != 3 or samples.shape[2] != 3:
        raise ValueError("samples must have shape (S, N, 3)")
    if max_lag < 0:
        raise ValueError("max_lag must be >= 0")
    n_samples = samples.shape[0]
    n = samples.shape[1]
    out = np.full((max_lag + 1, 3), np.nan)
    for m in range(min(max_lag + 1, n_samples)):
        sums = np.zeros(3)
        for k in range(n_samples - m):
            for p in range(n):
                for c in range(3):
                    d = samples[k + m, p, c] - samples[k, p, c]
                    sums[c] += d * d
        count = (n_samples - m) * n
        for c in range(3):
            out[m, c] = sums[c] / count if count > 0 else np.nan
    return out


@njit(cache=True)
def _add_msd_sample(
    buffer: np.ndarray,
    times: np.ndarray,
    count: int,
    squared_sums: np.ndarray,
    lag_time_sums: np.ndarray,
    origins: np.ndarray,
    displacement: np.ndarray,
    time: float,
) -> None:
    """Pair the new sample with the (up to) ``M`` previous ones in the ring buffer, then store it."""
    slots = buffer.shape[0]
    n = displacement.shape[0]
    for m in range(1, min(count, slots - 1) + 1):
        previous = (count - m) % slots
        for p in range(n):
            for c in range(3):
                d = displacement[p, c] - buffer[previous, p, c]
                squared_sums[m, c] += d * d
        lag_time_sums[m] += time - times[previous]
        origins[m] += 1
    slot = count % slots
    buffer[slot, :, :] = displacement
    times[slot] = time
    origins[0] += 1


@dataclass
class MsdAccumulator:
    """Running mean-square displacement over all time origins, for lags up to ``max_lag`` samples.

    Samples ``D(t_k)`` (N, 3) are added in time order at (nominally) equal intervals; each is paired with
    the last ``max_lag`` samples, kept in a ring buffer, so memory is ``(max_lag + 1) N 3`` numbers however
    long the run. ``msd[m]`` equals :func:`mean_square_displacement` of all samples at lag ``m`` (up to
    summation order, ~1e-15 relative), and ``lag_times[m]`` is the mean of ``t_{k+m} - t_k`` over the
    origins (the actual clock of each sample, which may pass its nominal time by less than a step).

    Attributes:
        buffer: (max_lag + 1, N, 3) float64 ring buffer of the last samples (units a).
        times: (max_lag + 1,) float64 their clocks (time units).
        count: number of samples added.
        first_time: clock of the first sample (NaN before any).
        squared_sums: (max_lag + 1, 3) float64 ``sum_{origins, p} [D_pa(t_{k+m}) - D_pa(t_k)]^2`` (units a^2).
        lag_time_sums: (max_lag + 1,) float64 ``sum_origins (t_{k+m} - t_k)``.
        origins: (max_lag + 1,) int64 number of origins per lag (``origins[0]`` = ``count``).

    References:
        Allen & Tildesley (2017), ch. 8; Sierou & Brady (2004), J. Fluid Mech. 506, 285.
    """

    buffer: np.ndarray
    times: np.ndarray
    count: int
    first_time: float
    squared_sums: np.ndarray
    lag_time_sums: np.ndarray
    origins: np.ndarray

    @classmethod
    def create(cls, n_particles: int, max_lag: int) -> MsdAccumulator:
        """An empty accumulator for ``n_particles >= 1`` spheres and lags ``1..max_lag >= 1`` (in samples)."""
        if isinstance(n_particles, bool) or int(n_particles) != n_particles or n_particles < 1:
            raise ValueError(f"n_particles must be an integer >= 1, got {n_particles!r}")
        if isinstance(max_lag, bool) or int(max_lag) != max_lag or max_lag < 1:
            raise ValueError(f"max_lag must be an integer >= 1, got {max_lag!r}")
        slots = int(max_lag) + 1
        return cls(
            buffer=np.zeros((slots, int(n_particles), 3)),
            times=np.zeros(slots),
            count=0,
            first_time=math.nan,
            squared_sums=np.zeros((slots, 3)),
            lag_time_sums=np.zeros(slots),
            origins=np.zeros(slots, dtype=np.int64),
        )

    @property
    def max_lag(self) -> int:
        """Largest lag in samples."""
        return int(self.buffer.shape[0] - 1)

    @property
    def n_particles(self) -> int:
        return int(self.buffer.shape[1])

    def add(self, displacement: np.ndarray, time: float) -> None:
        """Add the sample ``D(time)`` (N, 3) float64 (units a); ``time`` must not precede the last sample."""
        displacement = np.ascontiguousarray(displacement, dtype=np.float64)
        if displacement.shape != (self.n_particles, 3):
            raise ValueError(
                f"displacement must have shape ({self.n_particles}, 3), got {displacement.shape}"
            )
        if not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        if self.count > 0 and time < self.times[(self.count - 1) % self.buffer.shape[0]]:
            raise ValueError(f"time must not precede the last sample's, got {time!r}")
        _add_msd_sample(
            self.buffer,
            self.times,
            self.count,
            self.squared_sums,
            self.lag_time_sums,
            self.origins,
            displacement,
            float(time),
        )
        if self.count == 0:
            self.first_time = float(time)
        self.count += 1

    @property
    def last_time(self) -> float:
        """Clock of the last sample (NaN before any sample)."""
        if self.count == 0:
            return math.nan
        return float(self.times[(self.count - 1) % self.buffer.shape[0]])

    @property
    def span(self) -> float:
        """Time between the first and the last sample (0 before two samples)."""
        return 0.0 if self.count < 2 else self.last_time - self.first_time

    @property
    def lag_times(self) -> np.ndarray:
        """(max_lag + 1,) mean lag ``<t_{k+m} - t_k>`` per lag (time units); NaN for lags with no origin."""
        with np.errstate(invalid="ignore", divide="ignore"):
            out = self.lag_time_sums / self.origins
        out[self.origins == 0] = np.nan
        out[0] = 0.0 if self.count else np.nan
        return out

    @property
    def msd(self) -> np.ndarray:
        """(max_lag + 1, 3) ``(MSD_xx, MSD_yy, MSD_zz)`` per lag (units a^2); NaN for lags with no origin."""
        with np.errstate(invalid="ignore", divide="ignore"):
            out = self.squared_sums / (self.origins[:, None] * float(self.n_particles))
        out[self.origins == 0] = np.nan
        return out

    def arrays(self, prefix: str = "msd_") -> dict[str, np.ndarray]:
        """Arrays for ``np.savez`` (exact); keys start with ``prefix``."""
        return {
            f"{prefix}buffer": self.buffer,
            f"{prefix}times": self.times,
            f"{prefix}count": np.array(self.count, dtype=np.int64),
            f"{prefix}first_time": np.array(self.first_time, dtype=np.float64),
            f"{prefix}squared_sums": self.squared_sums,
            f"{prefix}lag_time_sums": self.lag_time_sums,
            f"{prefix}origins": self.origins,
        }

    @classmethod
    def from_arrays(cls, data: Any, prefix: str = "msd_") -> MsdAccumulator:
        """Inverse of :meth:`arrays`."""
        return cls(
            buffer=np.array(data[f"{prefix}buffer"], dtype=np.float64),
            times=np.array(data[f"{prefix}times"], dtype=np.float64),
            count=int(data[f"{prefix}count"]),
            first_time=float(data[f"{prefix}first_time"]),
            squared_sums=np.array(data[f"{prefix}squared_sums"], dtype=np.float64),
            lag_time_sums=np.array(data[f"{prefix}lag_time_sums"], dtype=np.float64),
            origins=np.array(data[f"{prefix}origins"], dtype=np.int64),
        )


def diffusivity_fit_window(
    span: float, max_lag_time: float, start: float = DIFFUSIVITY_FIT_START
) -> tuple[float, float]:
    """The lag window ``[start, end]`` of the diffusivity fit for displacement samples spanning ``span``.

    ``end = min(max_lag_time, span / MIN_INDEPENDENT_SEGMENTS)``: the largest lag of which every sphere's
    path holds :data:`MIN_INDEPENDENT_SEGMENTS` non-overlapping segments, within the lags the MSD was
    accumulated for. A usable window needs ``end >= 2 start`` (a factor two in lag, so that slope and
    intercept are separable); :func:`fit_diffusivity` returns NaN otherwise.

    Args:
        span: time between the first and the last displacement sample (time units), >= 0.
        max_lag_time: largest lag of the accumulated MSD (time units), > 0.
        start: smallest lag of the fit (time units), > 0; default :data:`DIFFUSIVITY_FIT_START`.

    Returns:
        ``(start, end)`` in time units (``end`` may be below ``2 start``: too short a run).
    """
    if not (math.isfinite(span) and span >= 0.0):
        raise ValueError(f"span must be finite and >= 0, got {span!r}")
    if not (math.isfinite(max_lag_time) and max_lag_time > 0.0):
        raise ValueError(f"max_lag_time must be finite and > 0, got {max_lag_time!r}")
    if not (math.isfinite(start) and start > 0.0):
        raise ValueError(f"start must be finite and > 0, got {start!r}")
    return float(start), float(min(max_lag_time, span / MIN_INDEPENDENT_SEGMENTS))


def fit_diffusivity(lag_times: np.ndarray, msd: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    """Diffusivities ``D_aa = slope / 2`` of a least-squares line ``MSD_aa(tau) = 2 D_aa tau + c_a``.

    Fitted over the lags with ``start <= tau <= end`` (unweighted; the intercept ``c_a`` absorbs the
    short-time, ballistic part; Sierou & Brady 2004). Einstein relation
    ``MSD_aa(tau) -> 2 D_aa tau`` for ``tau`` beyond the velocity correlation time (Allen & Tildesley
    2017, ch. 2).

    Args:
        lag_times: (M,) float64 lag times (time units); NaN entries are skipped.
        msd: (M, 3) float64 ``(MSD_xx, MSD_yy, MSD_zz)`` (units a^2); NaN rows are skipped.
        window: ``(start, end)`` of the fit (time units), e.g. from :func:`diffusivity_fit_window`.

    Returns:
        (3,) float64 ``(D_xx, D_yy, D_zz)`` (units a^2 per time unit: ``gammadot a^2`` when sheared, ``U0 a``
        when quiescent); NaN when ``end < 2 start`` or fewer than three lags lie in the window.
    """
    lag_times = np.asarray(lag_times, dtype=np.float64)
    msd = np.asarray(msd, dtype=np.float64)
    if msd.shape != (lag_times.shape[0], 3):
        raise ValueError(f"msd must have shape ({lag_times.shape[0]}, 3), got {msd.shape}")
    start, end = float(window[0]), float(window[1])
    if not (math.isfinite(start) and start > 0.0):
        raise ValueError(f"window start must be finite and > 0, got {start!r}")
    if not math.isfinite(end):
        raise ValueError(f"window end must be finite, got {end!r}")
    if end < 2.0 * start:
        return np.full(3, np.nan)
    valid = np.isfinite(lag_times) & np.all(np.isfinite(msd), axis=1)
    inside = valid & (lag_times >= start) & (lag_times <= end)
    if int(inside.sum()) < 3:
        return np.full(3, np.nan)
    tau = lag_times[inside]
    centred = tau - tau.mean()
    values = msd[inside]
    slopes = centred @ (values - values.mean(axis=0)) / float(centred @ centred)
    return 0.5 * slopes
