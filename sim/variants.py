"""Parameters that vary in time (shear rate, field strength): one protocol, after HOOMD-blue's variants.

A variant is a function of the clock ``t`` (units ``1/gammadot_ref``, ``docs/units.md``) with an exact
mean over any interval. The simulator changes a parameter only between ``advance`` calls, so a variant is
applied piecewise constant: :func:`follow` cuts the way to a target time at the variant's knots and into
pieces no longer than ``max_piece`` inside ramps, and sets each piece to the variant's **mean** over that
piece. For the shear rate this makes the strain of every piece the exact integral of the schedule over it
(up to the last step's overshoot, below one step), whatever the piece length; for a hold (a constant
piece) the value is exactly the hold's.

* :class:`PiecewiseLinear`: linear between knots ``(t_k, v_k)``, constant before the first and after the
  last; holds are two knots with one value, ramps two knots with two.
* :func:`constant` and :func:`ramp`: the two building blocks, as :class:`PiecewiseLinear`.

References:
    HOOMD-blue ``hoomd.variant`` (Constant, Ramp, Cycle): Anderson, Glaser & Glotzer (2020), Comput.
    Mater. Sci. 173, 109363.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

from sim.simulation import Simulation, StepRecords

DEFAULT_MAX_PIECE = 0.05
"""Longest piece of a ramp held at one value (time units): a ramp of 0.5 time units is then followed in ten
steps of the rate, each at the ramp's mean over it."""


@dataclass(frozen=True)
class PiecewiseLinear:
    """``v(t)`` linear between the knots ``(times[k], values[k])``, constant outside them.

    Attributes:
        times: knot times, finite and non-decreasing (two equal times make a jump).
        values: the value at each knot, finite.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        times = tuple(float(t) for t in self.times)
        values = tuple(float(v) for v in self.values)
        if not times or len(times) != len(values):
            raise ValueError(
                f"times and values must be non-empty and of one length, got {len(times)} and {len(values)}"
            )
        if not all(math.isfinite(x) for x in (*times, *values)):
            raise ValueError(f"times and values must be finite, got {times} and {values}")
        if any(b < a for a, b in zip(times, times[1:], strict=False)):
            raise ValueError(f"times must not decrease, got {times}")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)

    def __call__(self, time: float) -> float:
        """``v(time)`` (at a jump, the value after it)."""
        times, values = self.times, self.values
        if time < times[0]:
            return values[0]
        k = bisect.bisect_right(times, time) - 1  # O(log n) on the tuple (np.searchsorted copies it)
        if k >= len(times) - 1:
            return values[-1]
        t0, t1 = times[k], times[k + 1]
        return values[k] + (values[k + 1] - values[k]) * (time - t0) / (t1 - t0)

    def integral(self, start: float, end: float) -> float:
        """``int_start^end v dt`` exactly (trapezoids over the linear pieces), ``end >= start``."""
        if end < start:
            raise ValueError(f"end must be >= start, got {start} and {end}")
        cuts = [start, *self.knots_inside(start, end), end]
        total = 0.0
        for a, b in zip(cuts, cuts[1:], strict=False):
            mid = 0.5 * (a + b)
            total += (b - a) * self(mid)  # v is linear on [a, b]: its mean is the midpoint value
        return total

    def mean(self, start: float, end: float) -> float:
        """Mean of ``v`` over ``[start, end]`` (``v(start)`` when the interval is empty)."""
        return self(start) if end <= start else self.integral(start, end) / (end - start)

    def is_constant_on(self, start: float, end: float) -> bool:
        """True when ``v`` takes one value on ``(start, end)``."""
        inside = [self(t) for t in (start, *self.knots_inside(start, end), end)]
        return all(v == inside[0] for v in inside) and self.mean(start, end) == inside[0]

    def knots_inside(self, start: float, end: float) -> tuple[float, ...]:
        """The knot times ``t`` with ``start < t < end``, in order (found by bisection: O(log n))."""
        return self.times[bisect.bisect_right(self.times, start) : bisect.bisect_left(self.times, end)]

    @property
    def duration(self) -> float:
        """Time from the first to the last knot."""
        return self.times[-1] - self.times[0]


def constant(value: float) -> PiecewiseLinear:
    """``v(t) = value`` at all times."""
    return PiecewiseLinear((0.0,), (value,))


def ramp(start_value: float, end_value: float, start_time: float, duration: float) -> PiecewiseLinear:
    """Linear from ``start_value`` at ``start_time`` to ``end_value`` ``duration`` later, constant outside."""
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"duration must be finite and > 0, got {duration!r}")
    return PiecewiseLinear((start_time, start_time + duration), (start_value, end_value))


def pieces(variant: PiecewiseLinear, start: float, end: float, max_piece: float) -> list[tuple[float, float]]:
    """The pieces ``[a, b]`` from ``start`` to ``end``: cut at the variant's knots, and into at most
    ``max_piece`` long parts wherever the variant is not constant."""
    if not (math.isfinite(max_piece) and max_piece > 0.0):
        raise ValueError(f"max_piece must be finite and > 0, got {max_piece!r}")
    cuts = [start, *variant.knots_inside(start, end), end]
    out: list[tuple[float, float]] = []
    for a, b in zip(cuts, cuts[1:], strict=False):
        if b <= a:
            continue
        parts = 1 if variant.is_constant_on(a, b) else max(1, math.ceil((b - a) / max_piece - 1e-9))
        edges = [a + (b - a) * k / parts for k in range(parts)] + [b]
        out.extend(zip(edges, edges[1:], strict=False))
    return out


def follow(
    sim: Simulation,
    end_time: float,
    shear_rate: PiecewiseLinear | None = None,
    max_piece: float = DEFAULT_MAX_PIECE,
    origin: float = 0.0,
) -> StepRecords:
    """Advance ``sim`` to the clock ``end_time`` with its shear rate following ``shear_rate``.

    Args:
        sim: the simulation (its field stays as set; change it with ``sim.set_field`` between calls).
        end_time: the clock to reach (units ``1/gammadot_ref``).
        shear_rate: the rate as a function of ``t - origin``; None keeps the rate in force (a plain
            :meth:`Simulation.advance_to`).
        max_piece: longest stretch of a ramp held at one rate (time units, > 0).
        origin: the clock at which the variant's time 0 lies (an environment's episode start).

    Returns:
        The records of the steps taken (each with the rate in force).

    Each piece ``[a, b]`` runs at the variant's mean over it, until the first step that reaches ``b``
    (:meth:`Simulation.advance_to`), so the strain added over a piece is the schedule's integral over it
    to within the overshoot of that step (below ``rate * time_step``).
    """
    if shear_rate is None:
        return sim.advance_to(end_time)
    start = sim.state.time
    parts: list[StepRecords] = []
    for a, b in pieces(shear_rate, start - origin, end_time - origin, max_piece):
        if sim.state.time >= b + origin:  # the previous piece's last step went past this one
            continue
        sim.set_shear_rate(shear_rate.mean(a, b))
        parts.append(sim.advance_to(b + origin))
    return StepRecords.concatenate(parts)


def schedule_from_segments(
    segments: Sequence[tuple[str, float, float]], start_value: float
) -> PiecewiseLinear:
    """A :class:`PiecewiseLinear` from ``("hold", duration, value)`` and ``("ramp", duration, to_value)``
    segments starting at time 0 from ``start_value`` (a hold's value may differ from the value before it:
    a jump)."""
    times, values = [0.0], [float(start_value)]
    for kind, duration, value in segments:
        if kind not in ("hold", "ramp"):
            raise ValueError(f"segment kind must be 'hold' or 'ramp', got {kind!r}")
        if not (math.isfinite(duration) and duration > 0.0):
            raise ValueError(f"segment duration must be finite and > 0, got {duration!r}")
        t = times[-1]
        if kind == "hold":
            if value != values[-1]:
                times.append(t)
                values.append(float(value))
            times.append(t + duration)
            values.append(float(value))
        else:
            times.append(t + duration)
            values.append(float(value))
    return PiecewiseLinear(tuple(times), tuple(values))
