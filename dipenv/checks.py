"""Small argument checks shared by the environments and the schedules: each names the argument and what
is wrong in a ``ValueError``, instead of letting Python's own message (or a silent conversion) through."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def is_real_number(value: object) -> bool:
    """A real number that is not a bool (``True`` would read as 1) nor a string."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def real_number(name: str, value: object, low: float = -math.inf, low_open: bool = False) -> float:
    """``value`` as a finite float ``>= low`` (``> low`` when ``low_open``), or ``ValueError`` naming
    ``name``."""
    bound = f"> {low:g}" if low_open else f">= {low:g}"
    bound = "" if math.isinf(low) else f" {bound}"
    ok = is_real_number(value) and math.isfinite(float(value))  # type: ignore[arg-type]
    if ok:
        number = float(value)  # type: ignore[arg-type]
        ok = number > low if low_open else number >= low
    if not ok:
        raise ValueError(f"{name} must be a finite real number{bound}, got {value!r}")
    return number


def real_pair(name: str, value: object) -> tuple[float, float]:
    """``value`` as two finite floats ``(low, high)``, or ``ValueError`` naming ``name`` (the range
    itself is checked by the caller)."""
    if (
        isinstance(value, str | bytes)
        or not isinstance(value, Sequence | np.ndarray)
        or len(value) != 2
        or not all(is_real_number(x) and math.isfinite(float(x)) for x in value)
    ):
        raise ValueError(f"{name} must be two finite real numbers [low, high], got {value!r}")
    return float(value[0]), float(value[1])


def check_episode_arguments(
    episode_steps: object, history_length: object, split: object, start_state: object, splits: Sequence[str]
) -> None:
    """The episode arguments both kinds of env take (the simulator's and the surrogate's): ``episode_steps``
    an integer >= 1, ``history_length`` an integer in [0, 64], ``split`` one of ``splits``, ``start_state``
    ``"random"`` or ``"cycle"``; ``ValueError`` naming the first one that is not."""
    if isinstance(episode_steps, bool) or not isinstance(episode_steps, int) or episode_steps < 1:
        raise ValueError(f"episode_steps must be an integer >= 1, got {episode_steps!r}")
    if (
        isinstance(history_length, bool)
        or not isinstance(history_length, int)
        or not 0 <= history_length <= 64
    ):
        raise ValueError(f"history_length must be an integer in [0, 64], got {history_length!r}")
    if split not in splits:
        raise ValueError(f"split must be one of {', '.join(splits)}, got {split!r}")
    if start_state not in ("random", "cycle"):
        raise ValueError(f"start_state must be 'random' or 'cycle', got {start_state!r}")
