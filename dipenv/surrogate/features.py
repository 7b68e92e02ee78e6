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
* **The field's direction** (optional; the tracking surrogate's models, ``ViscosityTracking``): the
  traceless symmetric tensor ``e e^T - I/3`` of the direction ``e`` of the interval's field and of the one
  before it, as its 5 independent components ``(xx, yy, xy, xz, yz)`` (:func:`direction_features`). It is
  given also while the field is off, because the frame's angular g bins are taken relative to the
  direction last asked for then too. It is invariant under ``e -> -e``, as the physics is
  (dipolophoresis is quadratic in the field), so the inputs need no choice of sign. The block ends with
  this interval's field stress scale, the same tensor over the instantaneous Mason number
  (:func:`field_stress_features`), signed-logged. The block comes after
  the inputs above (:data:`N_DIRECTION_INPUTS` more, :data:`DIRECTION_INPUT_LABELS`), and only a model
  configured with it is fed it, so that a model fitted without it sees exactly the inputs it was fitted
  on, bit for bit.
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


N_DIRECTION = 5
"""Components of one interval's direction block (:func:`direction_features`)."""

DIRECTION_COMPONENTS = ("xx", "yy", "xy", "xz", "yz")
"""The components of ``e e^T - I/3`` in a direction block (``zz = -(xx + yy)`` is not independent)."""

Y_AXIS = (0.0, 1.0, 0.0)
"""The field direction of ``ThickeningControl`` (the velocity gradient), what a direction-aware model
assumes when it is given no direction (and the direction before an episode's first interval: the envs
reset the field to ``y``, off)."""

THIRD = 1.0 / 3.0


def direction_features(direction: np.ndarray | tuple[float, ...]) -> np.ndarray:
    """``(..., 5)``: ``e e^T - I/3`` of the unit direction ``e`` (``(..., 3)``) as ``(xx, yy, xy, xz, yz)``
    (:data:`DIRECTION_COMPONENTS`; ``zz = -(xx + yy)``). ``e`` and ``-e`` give the same values. ``e`` is
    used as given (the envs' directions are unit vectors). The block does not depend on whether the field
    is on: the on/off flags of the field block say that, and the frame's angular g bins are taken relative
    to the direction last asked for also while the field is off (``ViscosityTracking``), so the model needs
    it then too."""
    e = np.asarray(direction, dtype=np.float64)
    x, y, z = e[..., 0], e[..., 1], e[..., 2]
    return np.stack([x * x - THIRD, y * y - THIRD, x * y, x * z, y * z], axis=-1)


def direction_tensor(block: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)``: the symmetric traceless tensor ``e e^T - I/3`` of a direction block ``(..., 5)``
    (the inverse of :func:`direction_features`' packing)."""
    b = np.asarray(block, dtype=np.float64)
    xx, yy, xy, xz, yz = (b[..., i] for i in range(N_DIRECTION))
    rows = [[xx, xy, xz], [xy, yy, yz], [xz, yz, -(xx + yy)]]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def direction_features_into(out: np.ndarray, offset: int, direction: np.ndarray | tuple[float, ...]) -> None:
    """Write :func:`direction_features` of one interval into ``out[offset : offset + 5]``."""
    x, y, z = float(direction[0]), float(direction[1]), float(direction[2])
    out[offset] = x * x - THIRD
    out[offset + 1] = y * y - THIRD
    out[offset + 2] = x * y
    out[offset + 3] = x * z
    out[offset + 4] = y * z


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
    previous_direction: np.ndarray | tuple[float, ...] | None = None,
    direction: np.ndarray | tuple[float, ...] | None = None,
) -> np.ndarray:
    """:func:`mlp_inputs` of one interval written into ``out`` (the env's step): ``(N_MLP_INPUTS,)``, or
    ``(N_MLP_INPUTS + N_DIRECTION_INPUTS,)`` with the direction block (a direction of ``None``: ``y``)."""
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
    if out.shape[0] > N_MLP_INPUTS:
        direction_features_into(
            out, N_MLP_INPUTS, Y_AXIS if previous_direction is None else previous_direction
        )
        now = N_MLP_INPUTS + N_DIRECTION
        direction_features_into(out, now, Y_AXIS if direction is None else direction)
        scale = 0.0 if math.isinf(mason) else 1.0 / (mason * rate_mean)
        for k in range(N_DIRECTION):
            v = out[now + k] * scale
            out[now + N_DIRECTION + k] = math.copysign(math.log10(1.0 + abs(v)), v)
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


N_DIRECTION_INPUTS = 3 * N_DIRECTION
"""Inputs of the direction block: the previous interval's direction, this one's, and this one's field
stress scale (:func:`field_stress_features`)."""

DIRECTION_INPUT_LABELS = (
    *(f"prev_direction_{c}" for c in DIRECTION_COMPONENTS),
    *(f"direction_{c}" for c in DIRECTION_COMPONENTS),
    *(f"field_stress_{c}" for c in DIRECTION_COMPONENTS),
)


def field_stress_features(
    direction: np.ndarray, mason: np.ndarray | float, rate: np.ndarray | float
) -> np.ndarray:
    """``(..., 5)``: :func:`signed_log` of ``(e e^T - I/3) / (Mn_ref x rate)``, the direction block scaled
    by the inverse of the interval's instantaneous Mason number (0 while the field is off).

    The induced-dipole stress of a field scales as ``eps E0^2 (e e^T)`` and the viscous one as ``eta
    gammadot``, so their ratio is ``(e e^T) / Mn`` (``Mn = Mn_ref x rate``, ``docs/units.md``). With a
    tilted field its ``xy`` part enters the shear stress directly and drives ``eta_r`` far from its
    field-free value at strong fields and slow shear: in the tracking data ``eta_r`` is close to
    ``10 + 7 x`` this ``xy`` part (-95 at -20 on the compressional diagonal, +135 at +15 on the
    extensional one). An MLP fed ``1/Mn_ref``, ``log rate`` and the direction separately has to form the
    product itself; given it (in the signed log of the outputs' own scale), the 5-fold cross-validated
    one-step error of ``eta_r`` improved on every fold (``docs/surrogate.md``, the tracking fit)."""
    mason = np.asarray(mason, dtype=np.float64)
    on = np.isfinite(mason)
    scale = np.where(on, 1.0 / (np.where(on, mason, 1.0) * np.asarray(rate, dtype=np.float64)), 0.0)
    return signed_log(direction_features(direction) * scale[..., None])


def mlp_input_labels(direction: bool) -> tuple[str, ...]:
    """The inputs of an ensemble with (``direction``) or without the direction block."""
    return (*MLP_INPUT_LABELS, *DIRECTION_INPUT_LABELS) if direction else MLP_INPUT_LABELS


def mlp_inputs(
    dynamic: np.ndarray,
    previous_mason: np.ndarray | float,
    mason: np.ndarray | float,
    rate_start: np.ndarray | float,
    rate_mean: np.ndarray | float,
    rate_end: np.ndarray | float,
    previous_direction: np.ndarray | None = None,
    direction: np.ndarray | None = None,
    direction_block: bool = False,
) -> np.ndarray:
    """``(..., N_MLP_INPUTS)`` ensemble inputs (:data:`MLP_INPUT_LABELS`), unscaled; with
    ``direction_block``, ``(..., N_MLP_INPUTS + N_DIRECTION_INPUTS)``: the direction block of the previous
    and this interval appended (``previous_direction``, ``direction``: ``(..., 3)``; ``None``: ``y``)."""
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
        ]
        + (
            [
                np.broadcast_to(direction_features(_or_y(previous_direction)), (*batch, N_DIRECTION)),
                np.broadcast_to(direction_features(_or_y(direction)), (*batch, N_DIRECTION)),
                np.broadcast_to(
                    field_stress_features(
                        _or_y(direction),
                        np.broadcast_to(np.asarray(mason, dtype=np.float64), batch),
                        np.broadcast_to(np.asarray(rate_mean, dtype=np.float64), batch),
                    ),
                    (*batch, N_DIRECTION),
                ),
            ]
            if direction_block
            else []
        ),
        axis=-1,
    )


def _or_y(direction: np.ndarray | None) -> np.ndarray:
    return np.asarray(Y_AXIS if direction is None else direction, dtype=np.float64)


def strain_of(table: IntervalTable) -> np.ndarray:
    """(n,) strain of each interval, ``sum(rate x time)`` over its pieces."""
    return np.sum(table.piece_rate * table.piece_time, axis=1)
