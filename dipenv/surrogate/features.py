"""What the surrogate models see: the frame's dynamic part, the field, and the interval's rates.

Shared by the fit (``scripts/fit_surrogate.py``), the environment (:mod:`dipenv.surrogate.env`) and the
checks, so that a model is always fed the inputs it was fitted on.

* **Dynamic part** of an observation frame: indices 0-11 of ``ThickeningControl``'s frame, i.e.
  ``slog eta_r``, ``slog N1``, ``slog N2`` (interval means) and the 9 microstructure features of the end
  state (:data:`DYNAMIC_LABELS`). The field entries (12, 13) follow from the action and the rate entry
  (14) from the schedule, so no model predicts them.
* **The interval's rates**, from the schedule exactly as :func:`sim.follow` runs it: the interval is cut
  at the schedule's knots and, where the rate is not constant, into pieces of at most ``max_piece``, each
  held at the schedule's mean over it (:func:`interval_table`). The simulator reports the time-weighted
  mean rate (``info["shear_rate"]``) and observes the last piece's rate (``log10_shear_rate``).
* **The field**: ``Mn_ref`` (``inf``: off) of the interval and of the one before it, as
  ``(on, log10 Mn_ref, 1/Mn_ref)`` (:func:`field_features`); these do not depend on the action map, so a
  model serves ``-v1`` and ``-v2`` alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import sim

N_DYNAMIC = 12
"""Length of the dynamic part of a frame (indices 0-11)."""

DYNAMIC_LABELS = (
    "slog_eta_r",
    "slog_n1",
    "slog_n2",
    "fabric_xx",
    "fabric_yy",
    "fabric_xy",
    "fabric_xz",
    "fabric_yz",
    "contact_number",
    "g_equator",
    "g_middle",
    "g_pole",
)

OFF_LOG_MASON = 2.5
"""``log10 Mn`` fed to a model for a field that is off (above the action map's weakest field, 20)."""

LOG_INSTANT_RANGE = (-2.5, 2.5)
"""Clip of ``log10`` of the instantaneous Mason number ``rate x Mn_ref`` in the model inputs."""

MAX_PIECES = 16
"""Columns of :class:`IntervalTable`'s piece arrays (an interval of 0.25 at ``max_piece`` 0.05 with two
knots inside has at most 7 pieces)."""


def signed_log(x: np.ndarray | float) -> np.ndarray:
    """``sign(x) log10(1 + |x|)`` elementwise (as :func:`dipenv.observations.signed_log`)."""
    x = np.asarray(x, dtype=np.float64)
    return np.sign(x) * np.log10(1.0 + np.abs(x))


def inverse_signed_log(s: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`signed_log`."""
    s = np.asarray(s, dtype=np.float64)
    return np.sign(s) * (10.0 ** np.abs(s) - 1.0)


@dataclass(frozen=True)
class IntervalTable:
    """The rates of an episode's control intervals (time units ``1/gammadot_ref``).

    Attributes:
        rate_start: (n,) rate of each interval's first piece.
        rate_mean: (n,) time-weighted mean rate (the simulator's ``info["shear_rate"]``).
        rate_end: (n,) rate of the last piece, in force at the end (observed as ``log10_shear_rate``).
        piece_rate: (n, MAX_PIECES) rate of each piece (0 past the last).
        piece_time: (n, MAX_PIECES) duration of each piece (0 past the last).
        rate_initial: the rate at reset, ``schedule(0)`` (observed before the first action).
        parts: per interval, the ``(rate, duration)`` of its pieces as Python floats (the env's fast path).
    """

    rate_start: np.ndarray
    rate_mean: np.ndarray
    rate_end: np.ndarray
    piece_rate: np.ndarray
    piece_time: np.ndarray
    rate_initial: float
    parts: tuple[tuple[tuple[float, float], ...], ...]

    def window(self, start: int, stop: int) -> IntervalTable:
        """Intervals ``start .. stop - 1`` as a table of their own (a rollout from interval ``start``;
        ``rate_initial`` becomes the rate in force at its start, the previous interval's last piece's)."""
        if not 0 <= start < stop <= len(self.rate_mean):
            raise ValueError(f"window [{start}, {stop}) outside the table's {len(self.rate_mean)} intervals")
        initial = self.rate_initial if start == 0 else float(self.rate_end[start - 1])
        return IntervalTable(
            self.rate_start[start:stop],
            self.rate_mean[start:stop],
            self.rate_end[start:stop],
            self.piece_rate[start:stop],
            self.piece_time[start:stop],
            initial,
            self.parts[start:stop],
        )


def interval_table(
    schedule: sim.PiecewiseLinear, n_intervals: int, interval: float, max_piece: float
) -> IntervalTable:
    """The pieces :func:`sim.follow` runs in each of ``n_intervals`` intervals of length ``interval``
    (:func:`sim.pieces`, each at the schedule's mean over it)."""
    if not (math.isfinite(max_piece) and max_piece > 0.0):
        raise ValueError(f"max_piece must be finite and > 0, got {max_piece!r}")
    start = np.empty(n_intervals)
    mean = np.empty(n_intervals)
    end = np.empty(n_intervals)
    piece_rate = np.zeros((n_intervals, MAX_PIECES))
    piece_time = np.zeros((n_intervals, MAX_PIECES))
    lists = []
    for k in range(n_intervals):
        parts = sim.pieces(schedule, k * interval, (k + 1) * interval, max_piece)
        if len(parts) > MAX_PIECES:  # merge the tail into the last column (never at the defaults)
            parts = [*parts[: MAX_PIECES - 1], (parts[MAX_PIECES - 1][0], parts[-1][1])]
        rates = [schedule.mean(a, b) for a, b in parts]
        times = [b - a for a, b in parts]
        count = len(parts)
        piece_rate[k, :count] = rates
        piece_time[k, :count] = times
        start[k] = rates[0]
        end[k] = rates[-1]
        mean[k] = sum(r * t for r, t in zip(rates, times, strict=True)) / sum(times)
        lists.append(tuple(zip(rates, times, strict=True)))
    return IntervalTable(start, mean, end, piece_rate, piece_time, schedule(0.0), tuple(lists))


def field_features_into(out: np.ndarray, offset: int, mason: float) -> None:
    """Write :func:`field_features` of one ``Mn_ref`` into ``out[offset : offset + 3]`` (no allocation)."""
    if math.isinf(mason):
        out[offset], out[offset + 1], out[offset + 2] = 0.0, OFF_LOG_MASON, 0.0
    else:
        out[offset], out[offset + 1], out[offset + 2] = 1.0, math.log10(mason), 1.0 / mason


def mlp_inputs_into(
    out: np.ndarray,
    dynamic: np.ndarray,
    previous_mason: float,
    mason: float,
    rate_start: float,
    rate_mean: float,
    rate_end: float,
) -> np.ndarray:
    """:func:`mlp_inputs` of one interval written into ``out`` (N_MLP_INPUTS,), for the env's step."""
    out[:N_DYNAMIC] = dynamic
    field_features_into(out, N_DYNAMIC, previous_mason)
    field_features_into(out, N_DYNAMIC + 3, mason)
    out[N_DYNAMIC + 6] = math.log10(rate_start)
    out[N_DYNAMIC + 7] = math.log10(rate_mean)
    out[N_DYNAMIC + 8] = math.log10(rate_end)
    if math.isinf(mason):
        out[N_DYNAMIC + 9] = LOG_INSTANT_RANGE[1]
    else:
        value = math.log10(mason * rate_mean)
        out[N_DYNAMIC + 9] = min(max(value, LOG_INSTANT_RANGE[0]), LOG_INSTANT_RANGE[1])
    return out


def field_features(mason: np.ndarray | float) -> np.ndarray:
    """``(..., 3)``: ``(on, log10 Mn_ref, 1/Mn_ref)`` of a field ``Mn_ref`` (``inf``: off, ``(0,
    OFF_LOG_MASON, 0)``)."""
    mason = np.asarray(mason, dtype=np.float64)
    on = np.isfinite(mason)
    safe = np.where(on, mason, 1.0)
    return np.stack(
        [on.astype(np.float64), np.where(on, np.log10(safe), OFF_LOG_MASON), np.where(on, 1.0 / safe, 0.0)],
        axis=-1,
    )


def log_instant_mason(mason: np.ndarray | float, rate: np.ndarray | float) -> np.ndarray:
    """``log10(rate x Mn_ref)`` clipped into :data:`LOG_INSTANT_RANGE` (off: its top)."""
    mason = np.asarray(mason, dtype=np.float64)
    on = np.isfinite(mason)
    value = np.log10(np.where(on, mason, 1.0) * np.asarray(rate, dtype=np.float64))
    return np.where(on, np.clip(value, *LOG_INSTANT_RANGE), LOG_INSTANT_RANGE[1])


N_MLP_INPUTS = N_DYNAMIC + 3 + 3 + 3 + 1
"""Inputs of the ensemble's networks (:func:`mlp_inputs`)."""

MLP_INPUT_LABELS = (
    *DYNAMIC_LABELS,
    "prev_on",
    "prev_log10_mason",
    "prev_field_energy",
    "on",
    "log10_mason",
    "field_energy",
    "log10_rate_start",
    "log10_rate_mean",
    "log10_rate_end",
    "log10_instant_mason",
)


def mlp_inputs(
    dynamic: np.ndarray,
    previous_mason: np.ndarray | float,
    mason: np.ndarray | float,
    rate_start: np.ndarray | float,
    rate_mean: np.ndarray | float,
    rate_end: np.ndarray | float,
) -> np.ndarray:
    """``(..., N_MLP_INPUTS)`` ensemble inputs (:data:`MLP_INPUT_LABELS`), unscaled."""
    dynamic = np.asarray(dynamic, dtype=np.float64)
    batch = dynamic.shape[:-1]
    rates = np.stack(
        [
            np.broadcast_to(np.log10(np.asarray(r, dtype=np.float64)), batch)
            for r in (rate_start, rate_mean, rate_end)
        ],
        axis=-1,
    )
    return np.concatenate(
        [
            dynamic,
            np.broadcast_to(field_features(previous_mason), (*batch, 3)),
            np.broadcast_to(field_features(mason), (*batch, 3)),
            rates,
            np.broadcast_to(log_instant_mason(mason, rate_mean), batch)[..., None],
        ],
        axis=-1,
    )


def strain_of(table: IntervalTable) -> np.ndarray:
    """(n,) strain of each interval, ``sum(rate x time)`` over its pieces."""
    return np.sum(table.piece_rate * table.piece_time, axis=1)
