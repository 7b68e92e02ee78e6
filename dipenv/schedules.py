"""Shear-rate schedules of the thickening-control environments: random holds and ramps, fixed test sets.

A schedule is a :class:`sim.PiecewiseLinear` of the rate ``gammadot / gammadot_ref`` against the time since
the episode start (units ``1/gammadot_ref``; ``docs/units.md``). :func:`draw_schedule` draws one as a
process would see it: a hold at a rate drawn log-uniformly in ``[rate_min, rate_max]`` for a duration
drawn uniformly in ``hold_range``, then a ramp (linear in time) to a new log-uniform rate over a duration
in ``ramp_range``, then a hold, and so on until the episode is covered.

Training episodes draw their schedule with the environment's ``np_random``. The validation, test and
fresh splits use fixed schedules (:func:`fixed_schedules`), shipped as package data
(``dipenv/data/schedules.json``, made by :func:`write_fixed_schedules` from fixed seeds) so that every
controller, in every version, meets the same ones. The test and fresh schedules are the first draws of
their seeds. The validation schedules are stratified by mean rate (:func:`split_seeds`): from a pool of
draws, the ones at the midpoints of equal-count bins of the pool's mean rates, so that tuning on 8
schedules sees the generator's spread of rates (8 plain draws had a mean rate of 0.86 against the
generator's 1.49).

The ``fresh`` split (:data:`FRESH_SPLIT`, issue 43) is held out from every decision: nothing is tuned,
selected or designed on it; it is played only in the final evaluation (``docs/thickening_control.md``).

Every schedule a user passes (``reset(options={"schedule": ...})``) and every shipped one goes through
:func:`validate_schedule`, the one check. :func:`schedule_window` gives the environments an exact,
short copy of the knots around one control interval, so that a long schedule costs no more per interval
than a short one (``docs/thickening_control.md#long-schedules``).
"""

from __future__ import annotations

import bisect
import functools
import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

import sim
from dipenv.checks import is_real_number

RATE_RANGE = (0.2, 5.0)
"""Shear rates of the schedules (units gammadot_ref), drawn log-uniformly."""
HOLD_RANGE = (1.0, 4.0)
"""Durations of the holds (time units), drawn uniformly."""
RAMP_RANGE = (0.5, 2.0)
"""Durations of the ramps (time units), drawn uniformly."""
FRESH_SPLIT = "fresh"
"""The held-out split of the final evaluation (issue 43): no tuning, selection or design decision may look
at it."""
FRESH_SCHEDULES = (128, 3_000_000)
"""The fresh split's schedules: (count, seed of the first draw); schedule k is the plain draw of seed
``3_000_000 + k``. The base is far beyond every seed another split can reach: validation draws from
1000 and test from 2000, and a split enlarged past its shipped schedules (``split_sizes`` up to
:data:`dipenv.state_library.MAX_SPLIT_SIZE` = 100,000) draws ``seed + pool + index``, so below 102,000.
128 schedules are shipped so that an evaluation can take the first ``n`` (64 or more) and still grow."""
FIXED_SPLITS = {"validation": (8, 1_000), "test": (16, 2_000), FRESH_SPLIT: FRESH_SCHEDULES}
"""Fixed schedules per split: (count, seed of the first draw). Test and fresh schedule k use seed + k;
the validation schedules are chosen from the draws of seeds ``seed .. seed + pool - 1``
(:data:`STRATIFIED_POOLS`, :func:`split_seeds`)."""
STRATIFIED_POOLS = {"validation": 64}
"""Pool size of the splits whose schedules are stratified by mean rate."""
DATA_FILE = "schedules.json"
MAX_SCHEDULE_KNOTS = 100_000
"""The most knots a schedule may have (:func:`validate_schedule`). 100,000 knots over the standard
12-time-unit episode are one every 1.2e-4 time units, 16 per simulator step (2e-3 at rate 1): detail
finer than the simulator can follow (:func:`sim.follow` skips a piece that the previous step went
past). A schedule at the cap costs about what a short one costs per interval (:func:`schedule_window`);
the cap bounds the memory and the ``info["schedule"]`` copy made at every reset."""


def _check_range(name: str, bounds: Sequence[float], lowest: float) -> tuple[float, float]:
    low, high = (float(x) for x in bounds)
    if not (math.isfinite(low) and math.isfinite(high) and lowest < low <= high):
        raise ValueError(f"{name} must be two finite numbers with {lowest} < low <= high, got {list(bounds)}")
    return low, high


def draw_schedule(
    rng: np.random.Generator,
    duration: float,
    rate_range: Sequence[float] = RATE_RANGE,
    hold_range: Sequence[float] = HOLD_RANGE,
    ramp_range: Sequence[float] = RAMP_RANGE,
) -> sim.PiecewiseLinear:
    """A random hold–ramp–hold... schedule covering ``[0, duration]`` (see the module docstring).

    Args:
        rng: the generator (an environment passes its ``np_random``).
        duration: time to cover, > 0 (the last segment may run past it).
        rate_range: ``[low, high]`` of the log-uniform rates, 0 < low <= high.
        hold_range, ramp_range: ``[low, high]`` of the uniform segment durations, 0 < low <= high.
    """
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"duration must be finite and > 0, got {duration!r}")
    rate_low, rate_high = _check_range("rate_range", rate_range, 0.0)
    holds = _check_range("hold_range", hold_range, 0.0)
    ramps = _check_range("ramp_range", ramp_range, 0.0)

    def rate() -> float:
        return float(math.exp(rng.uniform(math.log(rate_low), math.log(rate_high))))

    segments: list[tuple[str, float, float]] = []
    start = rate()
    elapsed, current, hold = 0.0, start, True
    while elapsed < duration:
        if hold:
            length = float(rng.uniform(*holds))
            segments.append(("hold", length, current))
        else:
            length = float(rng.uniform(*ramps))
            current = rate()
            segments.append(("ramp", length, current))
        elapsed += length
        hold = not hold
    return sim.schedule_from_segments(segments, start)


def mean_rate(schedule: sim.PiecewiseLinear, duration: float) -> float:
    """Time average of the rate over ``[0, duration]`` (units gammadot_ref)."""
    return schedule.integral(0.0, duration) / duration


def spread_order(count: int) -> list[int]:
    """``0 .. count-1`` in an order whose every prefix spreads over the range: the bit-reversal
    (van der Corput) permutation for a power of two, e.g. ``[0, 4, 2, 6, 1, 5, 3, 7]`` for 8 (other counts:
    the order of the bit-reversed values of the next power of two, skipping those >= count)."""
    bits = max(1, (count - 1).bit_length())
    reverse = [int(format(k, f"0{bits}b")[::-1], 2) for k in range(2**bits)]
    return [r for r in reverse if r < count]


def split_seeds(
    split: str,
    duration: float = 12.0,
    rate_range: Sequence[float] = RATE_RANGE,
    hold_range: Sequence[float] = HOLD_RANGE,
    ramp_range: Sequence[float] = RAMP_RANGE,
) -> list[int]:
    """Seeds of the fixed schedules of ``split`` drawn with these parameters (schedule ``k`` is
    ``draw_schedule(np.random.default_rng(seeds[k]), duration, ...)``).

    Test: ``seed + k``. Validation (:data:`STRATIFIED_POOLS`): the ``pool`` draws of ``seed .. seed+pool-1``
    sorted by :func:`mean_rate` (ties by seed); schedule ``k`` is the one at rank
    ``floor((j + 1/2) pool / count)`` with ``j = spread_order(count)[k]``, the midpoint of the ``j``-th of
    ``count`` equal-count bins. Any prefix of the split (``--tune-episodes 4``) then spreads over the rates.
    """
    if split not in FIXED_SPLITS:
        raise ValueError(f"split must be one of {', '.join(FIXED_SPLITS)} for fixed schedules, got {split!r}")
    count, seed = FIXED_SPLITS[split]
    pool = STRATIFIED_POOLS.get(split)
    if pool is None:
        return [seed + k for k in range(count)]
    draws = {}
    for s in range(seed, seed + pool):
        drawn = draw_schedule(np.random.default_rng(s), duration, rate_range, hold_range, ramp_range)
        draws[s] = mean_rate(drawn, duration)
    ranked = sorted(draws, key=lambda s: (draws[s], s))
    return [ranked[int((j + 0.5) * pool / count)] for j in spread_order(count)]


_SCHEDULE_FORMS = (
    "{'times': [...], 'rates': [...]} (lists of real numbers), a (times, rates) pair or a sim.PiecewiseLinear"
)


def _numbers(name: str, field: str, values: object) -> list[float]:
    """``values`` (the ``field`` of the schedule ``name``) as a list of floats, or ``ValueError`` naming
    both and what is wrong."""
    if isinstance(values, np.ndarray):
        if values.ndim != 1 or values.dtype.kind not in "iuf":
            raise ValueError(
                f"{name}: {field} must be a list of real numbers, got an array of shape {values.shape} and "
                f"dtype {values.dtype}"
            )
        return [float(x) for x in values.tolist()]
    if not isinstance(values, list | tuple):
        raise ValueError(f"{name}: {field} must be a list of real numbers, got {_short(values)}")
    for k, value in enumerate(values):
        if not is_real_number(value):
            raise ValueError(f"{name}: {field}[{k}] must be a real number, got {_short(value)}")
    return [float(x) for x in values]


def _short(value: object) -> str:
    text = repr(value)
    text = text if len(text) <= 80 else text[:77] + "..."
    return f"{text} ({type(value).__name__})"


def validate_schedule(data: Any, name: str = "schedule") -> sim.PiecewiseLinear:
    """The one check of a shear-rate schedule: ``data`` as a :class:`sim.PiecewiseLinear`, or
    ``ValueError`` naming ``name`` and what is wrong.

    Accepted forms: ``{"times": [...], "rates": [...]}`` (exactly these keys; lists, tuples or 1-D numeric
    arrays), a ``(times, rates)`` pair of such sequences, or a :class:`sim.PiecewiseLinear`. Rules:

    * between 1 and :data:`MAX_SCHEDULE_KNOTS` knots, as many times as rates;
    * real numbers only (no strings, booleans, ``None`` or nested lists);
    * times finite, the first 0 (the episode start), and increasing, except that two knots at one time
      make a jump of the rate (as in :class:`sim.PiecewiseLinear`; the agents' tests step the rate so):
      never at time 0, where the rate before the jump would never apply, and never three at one time;
    * rates finite and within ``[sim.MIN_SHEAR_RATE, sim.MAX_SHEAR_RATE]`` = [1e-3, 1e3] ``gammadot_ref``,
      the simulator's range. Rate 0 is refused: a thickening schedule needs shear. Its reward charges
      ``eta_r = Sigma_xy / (eta gammadot)``, which has no value without flow, and its episodes start with
      the field off, where a quiescent suspension has nothing to move it. A rate below the floor
      (1e-9 gave ``eta_r = -2.7e7``) divides a finite stress by nearly nothing.

    The rate is linear between knots and holds its last value after the last knot.
    """
    if isinstance(data, sim.PiecewiseLinear):
        times, rates = list(data.times), list(data.values)
    elif isinstance(data, dict):
        if set(data) != {"times", "rates"}:
            raise ValueError(
                f"{name} must have exactly the keys 'times' and 'rates', got keys {sorted(map(str, data))}"
            )
        times = _numbers(name, "times", data["times"])
        rates = _numbers(name, "rates", data["rates"])
    elif isinstance(data, list | tuple) and len(data) == 2:
        times = _numbers(name, "times", data[0])
        rates = _numbers(name, "rates", data[1])
    else:
        raise ValueError(f"{name} must be {_SCHEDULE_FORMS}, got {_short(data)}")
    if not times or len(times) != len(rates):
        raise ValueError(
            f"{name} must have as many times as rates, at least one, got {len(times)} times and "
            f"{len(rates)} rates"
        )
    if len(times) > MAX_SCHEDULE_KNOTS:
        raise ValueError(
            f"{name} has {len(times)} knots, more than the cap of {MAX_SCHEDULE_KNOTS} "
            "(dipenv.schedules.MAX_SCHEDULE_KNOTS: finer than the simulator's step can follow)"
        )
    times_array = np.asarray(times)
    rates_array = np.asarray(rates)
    if not np.all(np.isfinite(times_array)):
        k = int(np.flatnonzero(~np.isfinite(times_array))[0])
        raise ValueError(f"{name}: times[{k}] must be finite, got {times[k]!r}")
    if times[0] != 0.0:
        raise ValueError(f"{name}: times must start at 0 (the episode start), got {times[0]!r}")
    steps = np.diff(times_array)
    if np.any(steps < 0.0):
        k = int(np.flatnonzero(steps < 0.0)[0]) + 1
        raise ValueError(
            f"{name}: times must increase (two equal times make a jump), got times[{k}] = {times[k]!r} "
            f"after {times[k - 1]!r}"
        )
    if len(times) > 1 and times[1] == 0.0:
        raise ValueError(
            f"{name}: no jump at time 0 (the rate before it would never apply): start with the rate after "
            f"it, got times {times[:3]!r}"
        )
    repeated = (steps[:-1] == 0.0) & (steps[1:] == 0.0)
    if np.any(repeated):
        k = int(np.flatnonzero(repeated)[0])
        raise ValueError(
            f"{name}: at most two knots may share a time (a jump), got three at times[{k}] = {times[k]!r}"
        )
    low, high = sim.MIN_SHEAR_RATE, sim.MAX_SHEAR_RATE
    outside = ~(np.isfinite(rates_array) & (rates_array >= low) & (rates_array <= high))
    if np.any(outside):
        k = int(np.flatnonzero(outside)[0])
        why = (
            " (a thickening schedule needs shear: eta_r = Sigma_xy / (eta gammadot) has no value without "
            "flow, and the episode starts with the field off)"
            if rates[k] == 0.0
            else ""
        )
        raise ValueError(
            f"{name}: rates[{k}] must be a finite rate in [sim.MIN_SHEAR_RATE, sim.MAX_SHEAR_RATE] = "
            f"[{low:g}, {high:g}] gammadot_ref, got {rates[k]!r}{why}"
        )
    return sim.PiecewiseLinear(tuple(times), tuple(rates))


def schedule_window(schedule: sim.PiecewiseLinear, start: float, end: float) -> sim.PiecewiseLinear:
    """The knots of ``schedule`` that :func:`sim.follow` reads between the schedule times ``start`` and
    ``end`` (the last knot at or before ``start``, all inside, the first at or after ``end``, and one more
    on each side), as a schedule equal to ``schedule`` on ``[start, end]`` bit for bit.

    ``sim.PiecewiseLinear`` bisects its knots, so a long schedule is cheap to follow as it is (a
    100,000-knot schedule once took minutes per interval, when each look-up scanned every knot); the
    window keeps each interval's work independent of the schedule's length all the same."""
    times = schedule.times
    lo = max(0, bisect.bisect_left(times, start) - 2)
    hi = min(len(times), bisect.bisect_right(times, end) + 2)
    return sim.PiecewiseLinear(times[lo:hi], schedule.values[lo:hi])


def schedule_to_dict(schedule: sim.PiecewiseLinear) -> dict[str, list[float]]:
    """JSON-ready knots ``{"times": [...], "rates": [...]}``."""
    return {"times": list(schedule.times), "rates": list(schedule.values)}


def schedule_from_dict(data: Any) -> sim.PiecewiseLinear:
    """Inverse of :func:`schedule_to_dict`; also takes a :class:`sim.PiecewiseLinear` or ``(times, rates)``.
    Checked by :func:`validate_schedule` (``ValueError`` names what is wrong)."""
    return validate_schedule(data)


def write_fixed_schedules(path: str | Path, duration: float = 12.0) -> None:
    """Write the fixed validation, test and fresh schedules (:data:`FIXED_SPLITS`) covering ``duration``,
    with the generator's parameters and each split's count, first seed and rule."""
    out: dict[str, Any] = {
        "duration": duration,
        "rate_range": list(RATE_RANGE),
        "hold_range": list(HOLD_RANGE),
        "ramp_range": list(RAMP_RANGE),
        "generator": "dipenv.schedules.draw_schedule(np.random.default_rng(seed), duration)",
        "seeds": (
            "dipenv.schedules.split_seeds(split, duration): test and fresh seed + k, validation by mean rate"
        ),
        "splits": {
            split: {"count": count, "first_seed": seed, "pool": STRATIFIED_POOLS.get(split)}
            for split, (count, seed) in FIXED_SPLITS.items()
        },
        "held_out": {
            FRESH_SPLIT: "played only in the final evaluation; never tuned, selected or designed on"
        },
    }
    for split in FIXED_SPLITS:
        out[split] = [
            {"seed": s, **schedule_to_dict(draw_schedule(np.random.default_rng(s), duration))}
            for s in split_seeds(split, duration)
        ]
    Path(path).write_text(json.dumps(out, indent=1) + "\n")


def fixed_schedules(split: str) -> list[sim.PiecewiseLinear]:
    """The shipped schedules of ``split`` (``validation``, ``test`` or ``fresh``)."""
    if split not in FIXED_SPLITS:
        raise ValueError(f"split must be one of {', '.join(FIXED_SPLITS)} for fixed schedules, got {split!r}")
    return list(_shipped_schedules(split))


@functools.cache
def _shipped_schedules(split: str) -> tuple[sim.PiecewiseLinear, ...]:
    """The package data of ``split``, read and checked once (the schedules are immutable)."""
    data = json.loads((resources.files("dipenv") / "data" / DATA_FILE).read_text())
    return tuple(
        validate_schedule({"times": s["times"], "rates": s["rates"]}, f"{DATA_FILE}[{split!r}][{k}]")
        for k, s in enumerate(data[split])
    )
