"""Shear-rate schedules of the thickening-control environments: random holds and ramps, fixed test sets.

A schedule is a :class:`sim.PiecewiseLinear` of the rate ``gammadot / gammadot_ref`` against the time since
the episode start (units ``1/gammadot_ref``; ``docs/units.md``). :func:`draw_schedule` draws one as a
process would see it: a hold at a rate drawn log-uniformly in ``[rate_min, rate_max]`` for a duration
drawn uniformly in ``hold_range``, then a ramp (linear in time) to a new log-uniform rate over a duration
in ``ramp_range``, then a hold, and so on until the episode is covered.

Training episodes draw their schedule with the environment's ``np_random``. The validation and test
splits use fixed schedules (:func:`fixed_schedules`), shipped as package data
(``dipenv/data/schedules.json``, made by :func:`write_fixed_schedules` from fixed seeds) so that every
controller, in every version, meets the same ones. The test schedules are the first draws of their seeds.
The validation schedules are stratified by mean rate (:func:`split_seeds`): from a pool of draws, the
ones at the midpoints of equal-count bins of the pool's mean rates, so that tuning on 8 schedules sees
the generator's spread of rates (8 plain draws had a mean rate of 0.86 against the generator's 1.49).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

import sim

RATE_RANGE = (0.2, 5.0)
"""Shear rates of the schedules (units gammadot_ref), drawn log-uniformly."""
HOLD_RANGE = (1.0, 4.0)
"""Durations of the holds (time units), drawn uniformly."""
RAMP_RANGE = (0.5, 2.0)
"""Durations of the ramps (time units), drawn uniformly."""
FIXED_SPLITS = {"validation": (8, 1_000), "test": (16, 2_000)}
"""Fixed schedules per split: (count, seed of the first draw). Test schedule k uses seed + k; the
validation schedules are chosen from the draws of seeds ``seed .. seed + pool - 1``
(:data:`STRATIFIED_POOLS`, :func:`split_seeds`)."""
STRATIFIED_POOLS = {"validation": 64}
"""Pool size of the splits whose schedules are stratified by mean rate."""
DATA_FILE = "schedules.json"


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


def schedule_to_dict(schedule: sim.PiecewiseLinear) -> dict[str, list[float]]:
    """JSON-ready knots ``{"times": [...], "rates": [...]}``."""
    return {"times": list(schedule.times), "rates": list(schedule.values)}


def schedule_from_dict(data: Any) -> sim.PiecewiseLinear:
    """Inverse of :func:`schedule_to_dict`; also takes a :class:`sim.PiecewiseLinear` or ``(times, rates)``.

    Rates must be finite and > 0 within ``[0, inf)`` time (a schedule with no shear has no viscosity to
    control); ``ValueError`` names what is wrong.
    """
    if isinstance(data, sim.PiecewiseLinear):
        schedule = data
    elif isinstance(data, dict) and set(data) == {"times", "rates"}:
        schedule = sim.PiecewiseLinear(tuple(data["times"]), tuple(data["rates"]))
    elif isinstance(data, list | tuple) and len(data) == 2:
        schedule = sim.PiecewiseLinear(tuple(data[0]), tuple(data[1]))
    else:
        raise ValueError(
            "a schedule must be a sim.PiecewiseLinear, {'times': [...], 'rates': [...]} or (times, rates), "
            f"got {data!r}"
        )
    if min(schedule.values) <= 0.0:
        raise ValueError(f"schedule rates must be > 0, got {list(schedule.values)}")
    return schedule


def write_fixed_schedules(path: str | Path, duration: float = 12.0) -> None:
    """Write the fixed validation and test schedules (:data:`FIXED_SPLITS`) covering ``duration``."""
    out: dict[str, Any] = {
        "duration": duration,
        "rate_range": list(RATE_RANGE),
        "hold_range": list(HOLD_RANGE),
        "ramp_range": list(RAMP_RANGE),
        "generator": "dipenv.schedules.draw_schedule(np.random.default_rng(seed), duration)",
        "seeds": "dipenv.schedules.split_seeds(split, duration): test seed + k, validation by mean rate",
    }
    for split in FIXED_SPLITS:
        out[split] = [
            {"seed": s, **schedule_to_dict(draw_schedule(np.random.default_rng(s), duration))}
            for s in split_seeds(split, duration)
        ]
    Path(path).write_text(json.dumps(out, indent=1) + "\n")


def fixed_schedules(split: str) -> list[sim.PiecewiseLinear]:
    """The shipped schedules of ``split`` (``validation`` or ``test``)."""
    if split not in FIXED_SPLITS:
        raise ValueError(f"split must be one of {', '.join(FIXED_SPLITS)} for fixed schedules, got {split!r}")
    data = json.loads((resources.files("dipenv") / "data" / DATA_FILE).read_text())
    return [schedule_from_dict({"times": s["times"], "rates": s["rates"]}) for s in data[split]]
