"""Target viscosity schedules of the viscosity-tracking environments (issue 44): holds and ramps of eta_r.

A target is a :class:`sim.PiecewiseLinear` of the relative viscosity ``eta_r`` the suspension should show,
against the time since the episode start (units ``1/gammadot_ref``, as the shear-rate schedules of
:mod:`dipenv.schedules`). It is drawn by the same generator, :func:`dipenv.schedules.draw_schedule`, with its
own parameters: holds at a value drawn log-uniformly in :data:`TARGET_RANGE`, ramps (linear in time) to a
new value, and so on until the episode is covered.

**Range, 9 to 25 (phi = 0.45).** The direction map (``docs/direction.md``, N = 500, phi = 0.45) spans eta_r
7.8 (field along the velocity gradient ``y`` at Mn 0.5) to 32 (along the vorticity ``z`` at Mn 0.2); the
strength alone, along ``y``, spans 7.8-12, the flow direction ``x`` 11.5-14.4 and ``z`` 14.6-32; no field
gives 10. The range keeps a margin at both ends:

* 9 lies about one unit (one interval's noise at N = 300, sd 0.8-1.4) above the lowest plateau a field
  along ``y`` holds in the N = 300 box (7.4-8.0 over the second half of an episode at Mn 0.5-1, 8.0-8.9 over
  the first half; ``docs/environments.md#box-size``), so a low target is reachable early in an episode too;
* 25 lies 2-7 units below the ``z`` branch at Mn 0.2-1 (27-32), so a controller can overdrive the slow
  build-up of the high state (1-2 strains, ``docs/direction.md#switching-time``) and still settle; the map's
  z branch is one seed of N = 500 and unmeasured at N = 300, whose box may hold it lower.

Both ends are reachable at every rate of the schedules (0.2-5) within the actions' ``Mn_ref`` range
(0.1-20): the instantaneous ``Mn = rate x Mn_ref`` then covers 0.5-2 (z: 21.6-30; y: 7.8-9.6) at rate 5
and at rate 0.2 alike. Values are log-uniform, so that the ``z`` branch (above 14.6) gets 58% of the time
and the rest (9-14.6) 42% (200 draws; uniform values would give ``z`` two thirds).

**Holds of 2-4, ramps of 0.5-2 time units.** A hold is at least as long as the slow build-up of the high
state at rate 1 (1-2 strains), so a controller can settle on a hold except at the lowest rates (where one
strain takes up to 5 time units); a 12-time-unit episode sees 3-5 target levels.

**Fixed splits.** Validation, test and fresh episodes pair start state ``k`` and rate schedule ``k``
(:meth:`dipenv.envs.thickening_control.ThickeningControlEnv.fixed_schedule`) with target ``k`` drawn from
the seed ``first_seed + k`` (:data:`TARGET_SPLITS`): 4,000,000 + k (validation), 5,000,000 + k (test),
6,000,000 + k (fresh). These ranges are disjoint from each other (a split holds at most 100,000 states) and
from every rate-schedule seed (below 3,100,000; ``dipenv.schedules.FRESH_SCHEDULES``): a target drawn from a
rate schedule's seed would repeat its uniform draws and move with its rate. The default parameters' targets
are shipped in ``dipenv/data/tracking_targets.json`` (:func:`write_fixed_targets`, regenerated bit for bit by
a test), as the rate schedules are, so that every controller in every version meets the same episodes even
if the generator changes. The fresh split is held out: played only in a final evaluation, never tuned,
selected or designed on (``docs/thickening_control.md#the-fresh-split``).
"""

from __future__ import annotations

import functools
import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

import sim
from dipenv.checks import is_real_number, real_number, real_pair
from dipenv.schedules import FRESH_SPLIT, draw_schedule, validate_schedule

TARGET_RANGE = (9.0, 25.0)
"""Target eta_r values (log-uniform); see the module docstring for why."""
TARGET_HOLD_RANGE = (2.0, 4.0)
"""Durations of the target's holds (time units, uniform)."""
TARGET_RAMP_RANGE = (0.5, 2.0)
"""Durations of the target's ramps (time units, uniform)."""
TARGET_PREVIEW = 1.0
"""How far ahead (time units) the observation's ``slog_target_eta_r_ahead`` looks: the high state builds
over 1-2 strains, four to eight control intervals at rate 1, so a controller must see a step coming."""
TARGET_SPLITS = {"validation": (8, 4_000_000), "test": (16, 5_000_000), FRESH_SPLIT: (128, 6_000_000)}
"""Fixed targets per split: (count shipped, seed of target 0); target ``k`` uses seed ``first + k`` for any
``k`` (an enlarged split draws on from the same seed range)."""
DEFAULT_DURATION = 12.0
"""Episode duration (time units) of the shipped targets: 48 intervals of 0.25."""
DATA_FILE = "tracking_targets.json"
MIN_TARGET = 1.0
"""Smallest target a user may pass: a suspension's relative viscosity is at least the solvent's, 1."""
MAX_TARGET = 1000.0
"""Largest target a user may pass (the observation's bounds hold its signed log: 3.0 < 6)."""


def check_target_ranges(
    target_range: object, hold_range: object, ramp_range: object
) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    """The three ranges of the target generator as float pairs, or ``ValueError`` naming the argument:
    ``target_range`` within ``[MIN_TARGET, MAX_TARGET]`` with low <= high, the durations > 0 with
    low <= high."""
    values = real_pair("target_range", target_range)
    if not MIN_TARGET <= values[0] <= values[1] <= MAX_TARGET:
        raise ValueError(
            f"target_range must be [low, high] with {MIN_TARGET:g} <= low <= high <= {MAX_TARGET:g} (target "
            f"relative viscosities eta_r), got {target_range!r}"
        )
    durations = []
    for name, value in (("target_hold_range", hold_range), ("target_ramp_range", ramp_range)):
        pair = real_pair(name, value)
        if not 0.0 < pair[0] <= pair[1]:
            raise ValueError(
                f"{name} must be [low, high] durations with 0 < low <= high (time units), got {value!r}"
            )
        durations.append(pair)
    return values, durations[0], durations[1]


TrackingArguments = tuple[tuple[float, float], tuple[float, float], tuple[float, float], float]


def check_tracking_arguments(
    kwargs: dict[str, Any],
    target_range: object,
    hold_range: object,
    ramp_range: object,
    target_preview: object,
) -> TrackingArguments:
    """The target arguments of a viscosity-tracking env (the simulator's or the surrogate's) checked:
    ``ValueError`` when ``kwargs`` (the env's other arguments) hold a fixed target (``eta_cap``,
    ``target_viscosity``), else the three ranges of :func:`check_target_ranges` and ``target_preview``
    (time units, >= 0)."""
    for name in ("eta_cap", "target_viscosity"):
        if name in kwargs:
            raise ValueError(
                f"the viscosity-tracking environments take no {name} (their target follows a schedule): "
                "set target_range, target_hold_range and target_ramp_range"
            )
    ranges = check_target_ranges(target_range, hold_range, ramp_range)
    return (*ranges, real_number("target_preview", target_preview, 0.0))


def draw_target(
    rng: np.random.Generator,
    duration: float,
    target_range: tuple[float, float] = TARGET_RANGE,
    hold_range: tuple[float, float] = TARGET_HOLD_RANGE,
    ramp_range: tuple[float, float] = TARGET_RAMP_RANGE,
) -> sim.PiecewiseLinear:
    """A random target covering ``[0, duration]``: :func:`dipenv.schedules.draw_schedule` with the
    target's ranges (holds at log-uniform values, linear ramps between them)."""
    return draw_schedule(rng, duration, target_range, hold_range, ramp_range)


def target_seed(split: str, index: int) -> int:
    """Seed of fixed target ``index`` of ``split`` (validation, test or fresh)."""
    if split not in TARGET_SPLITS:
        raise ValueError(f"split must be one of {', '.join(TARGET_SPLITS)} for fixed targets, got {split!r}")
    return TARGET_SPLITS[split][1] + int(index)


def _values(name: str, field: str, values: object) -> list[float]:
    if isinstance(values, np.ndarray):
        if values.ndim != 1 or values.dtype.kind not in "iuf":
            raise ValueError(
                f"{name}: {field} must be a list of real numbers, got an array of shape {values.shape}"
            )
        return [float(x) for x in values.tolist()]
    if not isinstance(values, list | tuple):
        raise ValueError(f"{name}: {field} must be a list of real numbers, got {values!r:.80}")
    for k, value in enumerate(values):
        if not is_real_number(value):
            raise ValueError(f"{name}: {field}[{k}] must be a real number, got {value!r:.80}")
    return [float(x) for x in values]


def validate_target(data: Any, name: str = "target") -> sim.PiecewiseLinear:
    """The one check of a target schedule: ``data`` as a :class:`sim.PiecewiseLinear`, or ``ValueError``
    naming ``name`` and what is wrong.

    Accepted forms: ``{"times": [...], "values": [...]}`` (exactly these keys), a ``(times, values)`` pair
    or a :class:`sim.PiecewiseLinear`. The times follow the rules of the rate schedules
    (:func:`dipenv.schedules.validate_schedule`: from 0, increasing, two equal times make a jump, at most
    :data:`dipenv.schedules.MAX_SCHEDULE_KNOTS` knots); the values are relative viscosities, finite and in
    ``[MIN_TARGET, MAX_TARGET]`` = [1, 1000]. The target is linear between knots and holds its last value
    after the last knot."""
    if isinstance(data, sim.PiecewiseLinear):
        times, values = list(data.times), list(data.values)
    elif isinstance(data, dict):
        if set(data) != {"times", "values"}:
            raise ValueError(
                f"{name} must have exactly the keys 'times' and 'values', got keys {sorted(map(str, data))}"
            )
        times, values = data["times"], _values(name, "values", data["values"])
    elif isinstance(data, list | tuple) and len(data) == 2:
        times, values = data[0], _values(name, "values", data[1])
    else:
        raise ValueError(
            f"{name} must be {{'times': [...], 'values': [...]}}, a (times, values) pair or a "
            f"sim.PiecewiseLinear, got {data!r:.80}"
        )
    # the times' rules are the rate schedules' (their values are checked below, in the target's range)
    checked = validate_schedule(
        {
            "times": times,
            "rates": [1.0] * (len(times) if isinstance(times, list | tuple | np.ndarray) else 0),
        },
        name,
    )
    if len(values) != len(checked.times):
        raise ValueError(
            f"{name} must have as many times as values, got {len(checked.times)} times and {len(values)} "
            "values"
        )
    for k, value in enumerate(values):
        if not (math.isfinite(value) and MIN_TARGET <= value <= MAX_TARGET):
            raise ValueError(
                f"{name}: values[{k}] must be a finite relative viscosity in "
                f"[{MIN_TARGET:g}, {MAX_TARGET:g}], "
                f"got {value!r}"
            )
    return sim.PiecewiseLinear(checked.times, tuple(values))


def target_to_dict(target: sim.PiecewiseLinear) -> dict[str, list[float]]:
    """JSON-ready knots ``{"times": [...], "values": [...]}``."""
    return {"times": list(target.times), "values": list(target.values)}


def write_fixed_targets(path: str | Path, duration: float = DEFAULT_DURATION) -> None:
    """Write the fixed validation, test and fresh targets (:data:`TARGET_SPLITS`, default parameters)
    covering ``duration``, with the generator's parameters and each split's count and first seed."""
    out: dict[str, Any] = {
        "duration": duration,
        "target_range": list(TARGET_RANGE),
        "hold_range": list(TARGET_HOLD_RANGE),
        "ramp_range": list(TARGET_RAMP_RANGE),
        "generator": "dipenv.tracking.draw_target(np.random.default_rng(seed), duration)",
        "seeds": "target k of a split: first_seed + k",
        "splits": {
            split: {"count": count, "first_seed": seed} for split, (count, seed) in TARGET_SPLITS.items()
        },
        "held_out": {
            FRESH_SPLIT: "played only in the final evaluation; never tuned, selected or designed on"
        },
    }
    for split, (count, _) in TARGET_SPLITS.items():
        out[split] = [
            {
                "seed": target_seed(split, k),
                **target_to_dict(draw_target(np.random.default_rng(target_seed(split, k)), duration)),
            }
            for k in range(count)
        ]
    Path(path).write_text(json.dumps(out, indent=1) + "\n")


@functools.cache
def shipped_targets(split: str) -> tuple[sim.PiecewiseLinear, ...]:
    """The shipped targets of ``split`` (validation, test or fresh), read and checked once."""
    if split not in TARGET_SPLITS:
        raise ValueError(f"split must be one of {', '.join(TARGET_SPLITS)} for fixed targets, got {split!r}")
    data = json.loads((resources.files("dipenv") / "data" / DATA_FILE).read_text())
    return tuple(
        validate_target({"times": t["times"], "values": t["values"]}, f"{DATA_FILE}[{split!r}][{k}]")
        for k, t in enumerate(data[split])
    )


def fixed_target(
    split: str,
    index: int,
    duration: float = DEFAULT_DURATION,
    target_range: tuple[float, float] = TARGET_RANGE,
    hold_range: tuple[float, float] = TARGET_HOLD_RANGE,
    ramp_range: tuple[float, float] = TARGET_RAMP_RANGE,
) -> sim.PiecewiseLinear:
    """Target ``index`` of a validation, test or fresh split: the shipped one at the default parameters and
    duration, else drawn from the same seed with the given ones."""
    seed = target_seed(split, index)
    defaults = (duration, target_range, hold_range, ramp_range) == (
        DEFAULT_DURATION,
        TARGET_RANGE,
        TARGET_HOLD_RANGE,
        TARGET_RAMP_RANGE,
    )
    count = TARGET_SPLITS[split][0]
    if defaults and 0 <= index < count:
        return shipped_targets(split)[index]
    return draw_target(np.random.default_rng(seed), duration, target_range, hold_range, ramp_range)
