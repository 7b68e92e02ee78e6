"""Hand-made baselines for the viscosity-tracking environments (``dipenv/ViscosityTracking*``, issue 44).

Each is a policy ``obs -> action`` over the raw observation of a
:class:`dipenv.envs.viscosity_tracking.ViscosityTrackingEnv` (read by label, so ``history_length`` does not
matter), with ``bind(env)`` and ``reset()`` as the controllers of :mod:`agents.controllers`:

* :class:`MapFeedForwardController` ("map_feedforward"): a look-up table of the bulk direction map
  (``results/direction_map``: eta_r against direction and Mn at phi = 0.45, N = 500, read from the committed
  ``result.json`` files, so it grows with the map) and the field-free value. Each interval it picks the
  direction and instantaneous Mn whose map value is closest to the observed target (ties: the least field
  energy), among those the action range reaches at the observed rate, and sets ``Mn_ref = Mn / rate``. Open
  loop: it never looks at the measured eta_r. It needs the rate (``ViscosityTracking``, not the stress-only
  id).
* :class:`AnglePIController` ("angle_pi"): PI feedback on ``log10(target / eta_r)`` acting on the polar
  angle from ``y`` toward ``z`` (``azimuth = 0.5``), at a strength that holds the instantaneous Mn at
  ``mason_star`` (feed-forward on the rate, as :class:`agents.controllers.FeedForwardController`).
  **Why the angle, not the strength:** at one Mn the y->z angle spans the whole target range (Mn 1: 8.7
  along y to 27 along z), while the strength along any one direction does not: 7.8-12 along y, 11.5-14.4
  along x, 14.6-32 along z (and that only between Mn 10 and 0.2, at 50 times the energy). The angle's
  gain is in action units (``polar``: -1 is y, 1 the equator) per decade of error; the integral is frozen
  while the angle saturates in the error's direction (anti-windup, as :class:`agents.controllers.
  PIController`). That eta_r rises with the angle is measured at three angles (phi 0.45, seed 1: y,
  ``(y+z)/sqrt2``, z give 8.7, 17.2, 27.0 at Mn 1, and rise at every Mn of the map), not between them. It
  needs eta_r and the rate.
* :class:`ConstantFieldController` ("constant"): one field for the whole episode (``Mn_ref`` and a
  direction); the best constant is tuned over a grid (:data:`CONSTANT_GRID`) on the validation split.

**Evaluation.** The machinery of :mod:`agents.controllers` and :mod:`agents.open_loop` rescores stored
episodes with ``reward(eta_r, energy)`` at one fixed target and reports time above a cap; the tracking
reward's target changes every interval, so these controllers are not registered there. Instead
:func:`play_episode` plays one episode of a policy (a controller, or a trained policy) and returns its
return, mean ``|eta_r - target|``, mean field energy, failure flag and per-interval traces;
:func:`play_episodes` plays N episodes of a controller on a split and :func:`summarise` averages them. The
fresh split is refused unless ``final_evaluation=True`` (``docs/thickening_control.md#the-fresh-split``).
The command ``python -m agents.tracking`` tunes these controllers on validation and plays them, and trained
policies, on the same episodes (:mod:`agents.tracking`).
"""

from __future__ import annotations

import json
import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.controllers import observation_index
from dipenv.actions import action_from_direction

DIRECTION_MAP_ROOT = Path(__file__).resolve().parents[1] / "results" / "direction_map"
"""The committed direction map: ``phi<phi>_<direction>/<point>/result.json`` (made by
``scripts/direction_map.sh``)."""

MAP_SEEDS = (1,)
"""The map's seeds the feed-forward reads: seed 1, the whole map when the tracking baselines were tuned
(2026-12-07). Seeds 2 and 3 arrive later (``scripts/direction_map.sh``); read by default, they would change
the feed-forward, and the map digest in ``agents.tracking``'s folder identity, between its tuning on
validation and its fresh evaluation."""

NO_FIELD_ETA = {0.45: 10.0}
"""eta_r without a field by volume fraction: 10.0 at phi = 0.45 (N = 500, strains 20-100, the box-size study;
``scripts/direction_map_table.py`` uses the same number)."""

OFF = "off"
"""The name of the field-free choice of :class:`MapFeedForwardController`."""

TARGET_LABELS = {
    "now": "slog_target_eta_r",
    "next": "slog_target_eta_r_next",
    "ahead": "slog_target_eta_r_ahead",
}
"""Which observed target a controller follows: now, the mean over the coming interval (what the next
reward charges), or ``target_preview`` ahead."""

_FOLDER = re.compile(r"^phi(?P<phi>[0-9.]+)_(?P<direction>[a-z]+)$")


def _unslog(value: float) -> float:
    """Inverse of dipenv's ``slog(x) = sign(x) log10(1 + |x|)``."""
    return math.copysign(10.0 ** abs(value) - 1.0, value)


@dataclass(frozen=True)
class MapBranch:
    """One direction of the map: eta_r (seed means) at increasing Mn.

    Attributes:
        name: the map's key (``x``, ``y``, ``z``, ``ext``, ``comp``, ``yz``).
        direction: the unit field direction of its runs.
        mason: the Mn of its points, increasing.
        eta: eta_r at each (mean over the seeds present).
        seeds: the number of seeds behind each point.
    """

    name: str
    direction: tuple[float, float, float]
    mason: tuple[float, ...]
    eta: tuple[float, ...]
    seeds: tuple[int, ...]

    def eta_at(self, mason: float) -> float:
        """eta_r at ``mason`` within the branch's points, linear in ``log Mn`` between them."""
        logs = np.log(self.mason)
        if not self.mason[0] <= mason <= self.mason[-1]:
            raise ValueError(f"Mn {mason!r} is outside the map's [{self.mason[0]:g}, {self.mason[-1]:g}]")
        return float(np.interp(math.log(mason), logs, self.eta))


def load_direction_map(
    root: str | Path | None = None, phi: float = 0.45, seeds: tuple[int, ...] | None = MAP_SEEDS
) -> dict[str, MapBranch]:
    """The finished points of the direction map at ``phi`` by direction (``ValueError`` if there are none).

    Reads ``root/phi<phi>_<direction>/*/result.json`` (default :data:`DIRECTION_MAP_ROOT`): each point's
    ``mason_number``, ``relative_viscosity``, ``field_direction`` and ``seed``, of the ``seeds`` (default
    :data:`MAP_SEEDS`; None: every seed); seeds of one (direction, Mn) are averaged, as
    ``scripts/direction_map_table.py`` does for ``results/direction_map/table.md``."""
    folder = DIRECTION_MAP_ROOT if root is None else Path(root)
    if not folder.is_dir():
        raise ValueError(
            f"map_root {str(folder)!r} is not a folder of the direction map (results/direction_map of a "
            "checkout)"
        )
    branches: dict[str, MapBranch] = {}
    for sub in sorted(folder.iterdir()):
        match = _FOLDER.match(sub.name)
        if not match or not sub.is_dir() or abs(float(match["phi"]) - phi) > 1e-6:
            continue
        points: dict[float, list[float]] = defaultdict(list)
        directions = set()
        for result in sorted(sub.glob("*/result.json")):
            data = json.loads(result.read_text())
            if seeds is not None and int(data["seed"]) not in seeds:
                continue
            points[float(data["mason_number"])].append(float(data["relative_viscosity"]))
            e = np.asarray(data["field_direction"], dtype=float)
            directions.add(tuple(float(x) for x in np.round(e / np.linalg.norm(e), 12)))
        if not points:
            continue
        if len(directions) != 1:
            raise ValueError(f"{sub}: points with different field directions {sorted(directions)}")
        masons = sorted(points)
        direction = next(iter(directions))
        branches[match["direction"]] = MapBranch(
            match["direction"],
            (direction[0], direction[1], direction[2]),
            tuple(masons),
            tuple(float(np.mean(points[m])) for m in masons),
            tuple(len(points[m]) for m in masons),
        )
    if not branches:
        raise ValueError(f"no direction-map points at phi = {phi:g} under {folder}")
    return branches


@dataclass
class MapFeedForwardController:
    """Set the field whose bulk map value is closest to the target (see the module docstring).

    Attributes:
        target: which observed target to follow: ``"now"``, ``"next"`` (default: the coming interval's
            mean, which the next reward charges) or ``"ahead"``.
        interpolate: if True (default), eta_r between the map's Mn is interpolated linearly in ``log Mn``
            (a grid of :attr:`points_per_decade`); if False only the map's own points are candidates.
        points_per_decade: density of the interpolated candidates (>= 1).
        map_root: the direction map's folder (default :data:`DIRECTION_MAP_ROOT`).
        phi: the volume fraction of the map to read (its no-field value must be in :data:`NO_FIELD_ETA`).
    """

    target: str = "next"
    interpolate: bool = True
    points_per_decade: int = 50
    map_root: str | None = None
    phi: float = 0.45
    branches: dict[str, MapBranch] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.target not in TARGET_LABELS:
            raise ValueError(f"target must be one of {', '.join(TARGET_LABELS)}, got {self.target!r}")
        if isinstance(self.points_per_decade, bool) or not isinstance(self.points_per_decade, int):
            raise ValueError(f"points_per_decade must be an integer >= 1, got {self.points_per_decade!r}")
        if self.points_per_decade < 1:
            raise ValueError(f"points_per_decade must be an integer >= 1, got {self.points_per_decade!r}")
        if self.phi not in NO_FIELD_ETA:
            raise ValueError(
                f"phi must be one of {sorted(NO_FIELD_ETA)} (no-field eta_r known), got {self.phi!r}"
            )
        self.branches = load_direction_map(self.map_root, self.phi)
        names, masons, etas = [OFF], [math.inf], [NO_FIELD_ETA[self.phi]]
        for name, branch in self.branches.items():
            grid = list(branch.mason)
            if self.interpolate and len(grid) > 1:
                decades = math.log10(grid[-1] / grid[0])
                n = max(2, round(decades * self.points_per_decade) + 1)
                grid = sorted(set(grid) | set(np.geomspace(grid[0], grid[-1], n).tolist()))
            for mason in grid:
                names.append(name)
                masons.append(float(mason))
                etas.append(branch.eta_at(mason))
        self._names = names
        self._masons = np.array(masons)
        self._etas = np.array(etas)
        self._target_index = -1
        self._rate_index = -1
        self._mapping: Any = None

    def bind(self, env: Any) -> MapFeedForwardController:
        """Find the target and the rate in ``env``'s observation; ``ValueError`` if it lacks either."""
        unwrapped = env.unwrapped
        self._target_index = observation_index(unwrapped, TARGET_LABELS[self.target])
        self._rate_index = observation_index(unwrapped, "log10_shear_rate")
        self._mapping = unwrapped.mapping
        return self

    def reset(self) -> None:
        """Nothing to reset (no state)."""

    def choose(self, target: float, rate: float) -> tuple[str, float, float]:
        """``(direction name or "off", instantaneous Mn, map eta_r)`` for ``target`` at ``rate``: the closest
        map value among the fields the action range reaches at this rate (``Mn`` in
        ``rate x [Mn_min, Mn_max]``); ties within 1e-9 go to the least field energy ``rate / Mn``."""
        mapping = self._mapping
        if mapping is None:
            raise RuntimeError("bind(env) the controller before use")
        low, high = rate * mapping.mason_min * (1 - 1e-12), rate * mapping.mason_max * (1 + 1e-12)
        reachable = np.isinf(self._masons) | ((self._masons >= low) & (self._masons <= high))
        error = np.where(reachable, np.abs(self._etas - target), np.inf)
        best = np.flatnonzero(error <= error.min() + 1e-9)
        k = int(best[np.argmax(self._masons[best])])  # the weakest field among the ties (off: inf)
        return self._names[k], float(self._masons[k]), float(self._etas[k])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        mapping = self._mapping
        if mapping is None:
            raise RuntimeError("bind(env) the controller before use")
        flat = np.asarray(obs).reshape(-1)
        target = _unslog(float(flat[self._target_index]))
        rate = 10.0 ** float(flat[self._rate_index])
        name, mason, _ = self.choose(target, rate)
        if name == OFF:
            return np.array([-1.0, -1.0, 0.0], dtype=np.float32)
        mason_ref = min(max(mason / rate, mapping.mason_min), mapping.mason_max)
        polar, azimuth = action_from_direction(self.branches[name].direction)
        return np.array([mapping.action_for(mason_ref), polar, azimuth], dtype=np.float32)


@dataclass
class AnglePIController:
    """PI feedback on ``log10(target / eta_r)`` acting on the polar angle from ``y`` toward ``z``.

    ``e_k = log10(target_k / eta_k)``, ``polar_k = polar0 + kp e_k + ki sum_{j<=k} e_j`` clipped to
    ``[-1, 1]`` (``-1``: y, ``1``: z), at ``azimuth`` (0.5: the y-z plane) and ``Mn_ref = mason_star / rate``
    (saturated at the env's field range). The integral is frozen while the angle saturates in the error's
    direction (anti-windup).

    Attributes:
        kp: proportional gain (polar action units per decade of error), >= 0.
        ki: integral gain (per decade per interval), >= 0.
        mason_star: the instantaneous Mn held (> 0); default 1, where the y->z angle spans 8.7-27.
        polar0: angle with zero error and zero integral (default 0: 45 degrees from y).
        azimuth: the plane of the angle (default 0.5: y-z).
        target: which observed target to follow (:data:`TARGET_LABELS`).
    """

    kp: float
    ki: float
    mason_star: float = 1.0
    polar0: float = 0.0
    azimuth: float = 0.5
    target: str = "next"
    integral: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        for name in ("kp", "ki"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.mason_star) and self.mason_star > 0.0):
            raise ValueError(f"mason_star must be finite and > 0, got {self.mason_star!r}")
        for name in ("polar0", "azimuth"):
            value = getattr(self, name)
            if not (math.isfinite(value) and -1.0 <= value <= 1.0):
                raise ValueError(f"{name} must be in [-1, 1], got {value!r}")
        if self.target not in TARGET_LABELS:
            raise ValueError(f"target must be one of {', '.join(TARGET_LABELS)}, got {self.target!r}")
        self._indices: tuple[int, int, int] | None = None
        self._mapping: Any = None

    def bind(self, env: Any) -> AnglePIController:
        """Find eta_r, the target and the rate in ``env``'s observation; ``ValueError`` if one is missing
        (the stress-only id observes neither eta_r nor the rate)."""
        unwrapped = env.unwrapped
        self._indices = (
            observation_index(unwrapped, "slog_eta_r"),
            observation_index(unwrapped, TARGET_LABELS[self.target]),
            observation_index(unwrapped, "log10_shear_rate"),
        )
        self._mapping = unwrapped.mapping
        return self

    def reset(self) -> None:
        self.integral = 0.0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self._indices is None:
            raise RuntimeError("bind(env) the controller before use")
        flat = np.asarray(obs).reshape(-1)
        eta_index, target_index, rate_index = self._indices
        eta = max(_unslog(float(flat[eta_index])), 1e-6)
        target = max(_unslog(float(flat[target_index])), 1e-6)
        error = math.log10(target / eta)
        raw = self.polar0 + self.kp * error + self.ki * (self.integral + error)
        saturated = (raw > 1.0 and error > 0) or (raw < -1.0 and error < 0)
        if not saturated:
            self.integral += error
        polar = min(1.0, max(-1.0, self.polar0 + self.kp * error + self.ki * self.integral))
        mapping = self._mapping
        rate = 10.0 ** float(flat[rate_index])
        mason_ref = min(max(self.mason_star / rate, mapping.mason_min), mapping.mason_max)
        return np.array([mapping.action_for(mason_ref), polar, self.azimuth], dtype=np.float32)


@dataclass
class ConstantFieldController:
    """One field for the whole episode: ``Mn_ref = mason_ref`` (``inf``: off) along ``direction``.

    Attributes:
        mason_ref: the field's Mason number at the reference rate, in the env's ``[Mn_min, Mn_max]`` (a
            value outside saturates there), or ``inf`` for no field.
        direction: the field direction (three numbers, not all zero; default y).
    """

    mason_ref: float
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def __post_init__(self) -> None:
        if not (self.mason_ref > 0.0):  # inf allowed: off; NaN refused
            raise ValueError(f"mason_ref must be > 0 (inf: no field), got {self.mason_ref!r}")
        self._polar, self._azimuth = action_from_direction(self.direction)  # ValueError for a bad direction
        self._action: np.ndarray | None = None

    def bind(self, env: Any) -> ConstantFieldController:
        mapping = env.unwrapped.mapping
        if math.isinf(self.mason_ref):
            u = -1.0
        else:
            u = mapping.action_for(min(max(self.mason_ref, mapping.mason_min), mapping.mason_max))
        self._action = np.array([u, self._polar, self._azimuth], dtype=np.float32)
        return self

    def reset(self) -> None:
        """Nothing to reset (no state)."""

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self._action is None:
            raise RuntimeError("bind(env) the controller before use")
        return self._action.copy()


CONSTANT_GRID: dict[str, list[Any]] = {
    "mason_ref": [0.2, 0.5, 1.0, 2.0, 5.0, math.inf],
    "direction": [
        (0.0, 1.0, 0.0),
        (1.0, 0.0, 0.0),
        (0.0, 0.0, 1.0),
        (math.sqrt(0.5), math.sqrt(0.5), 0.0),
        (-math.sqrt(0.5), math.sqrt(0.5), 0.0),
        (0.0, math.sqrt(0.5), math.sqrt(0.5)),
    ],
}
"""The constant fields to tune the best one over (on validation): the map's directions (y, x, z, the shear
plane's diagonals, (y+z)/sqrt2) x ``Mn_ref`` 0.2-5 and off (off is one field whatever the direction)."""

TRACKING_CONTROLLERS = ("map_feedforward", "angle_pi", "constant")


def make_tracking_controller(
    kind: str, params: dict[str, Any]
) -> MapFeedForwardController | AnglePIController | ConstantFieldController:
    """A controller of ``kind`` (one of :data:`TRACKING_CONTROLLERS`) with ``params``; ``ValueError`` naming a
    bad kind or parameter."""
    if kind == "map_feedforward":
        return MapFeedForwardController(**params)
    if kind == "angle_pi":
        return AnglePIController(**params)
    if kind == "constant":
        return ConstantFieldController(**params)
    raise ValueError(f"controller must be one of {', '.join(TRACKING_CONTROLLERS)}, got {kind!r}")


def _check_split(split: str, final_evaluation: bool) -> None:
    """``ValueError`` unless ``split`` has fixed rate schedules and targets; ``fresh`` only with
    ``final_evaluation``."""
    if split not in ("validation", "test", "fresh"):
        raise ValueError(
            f"split must be validation, test or fresh (fixed schedules and targets), got {split!r}"
        )
    if split == "fresh" and not final_evaluation:
        raise ValueError(
            "the fresh split is held out for the final evaluation "
            "(docs/thickening_control.md#the-fresh-split): "
            "pass final_evaluation=True only there"
        )


def play_episode(
    env: Any,
    policy: Any,
    split: str,
    index: int,
    realisation: int = 0,
    schedule: dict[str, Any] | None = None,
    final_evaluation: bool = False,
) -> dict[str, Any]:
    """One episode of ``policy`` (``obs -> action``; a controller must be bound to ``env`` first, and its
    ``reset()``, where it has one, is called here) from start state ``index`` of ``split``, realisation
    ``realisation``: ``env.reset(seed=0, options={"split", "index"[, "realisation"][, "schedule"]})``.
    ``schedule`` (``{"times", "rates"}``) replaces the split's rate schedule ``index``; the target stays
    the split's target ``index``.

    Returns ``split``, ``index``, ``realisation``, ``steps``, ``failed``, ``return``, ``mean_abs_error``
    (mean over intervals of ``|eta_r - target_eta_r|``; NaN for a failed episode), ``mean_energy`` (mean
    ``<eps E0^2>``; NaN for a failed episode) and the per-interval traces ``eta_r``, ``target_eta_r``,
    ``reward`` (with a failed step's penalty), ``time`` (since the episode start, at each interval's end),
    ``shear_rate`` (interval mean), ``mason_number`` (``Mn_ref``; inf: off), ``field_direction``,
    ``field_energy`` and ``action``. ``fresh`` only with ``final_evaluation=True``."""
    _check_split(split, final_evaluation)
    options: dict[str, Any] = {"split": split, "index": index}
    if realisation:
        options["realisation"] = realisation
    if schedule is not None:
        options["schedule"] = schedule
    obs, _ = env.reset(seed=0, options=options)
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset()
    traces: dict[str, list[Any]] = {
        key: []
        for key in (
            "eta_r",
            "target_eta_r",
            "reward",
            "time",
            "shear_rate",
            "mason_number",
            "field_direction",
            "field_energy",
            "action",
        )
    }
    failed = False
    done = False
    while not done:
        action = policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        traces["reward"].append(float(reward))
        done = terminated or truncated
        if info.get("simulation_failed"):
            failed = True
            break
        traces["eta_r"].append(float(info["eta_r"]))
        traces["target_eta_r"].append(float(info["target_eta_r"]))
        traces["field_energy"].append(float(info["field_energy"]))
        traces["time"].append(float(info["time"]))
        traces["shear_rate"].append(float(info["shear_rate"]))
        traces["mason_number"].append(float(info["mason_number"]))
        traces["field_direction"].append([float(x) for x in np.asarray(info["field_direction"]).reshape(-1)])
        traces["action"].append([float(x) for x in np.asarray(action).reshape(-1)])
    errors = np.abs(np.subtract(traces["eta_r"], traces["target_eta_r"]))
    energies = traces["field_energy"]
    return {
        "split": split,
        "index": index,
        "realisation": realisation,
        "steps": len(traces["reward"]),
        "failed": failed,
        "return": float(np.sum(traces["reward"])),
        "mean_abs_error": float(errors.mean()) if errors.size and not failed else math.nan,
        "mean_energy": float(np.mean(energies)) if energies and not failed else math.nan,
        **traces,
    }


def play_episodes(
    env: Any,
    controller: Any,
    split: str = "validation",
    episodes: int | None = None,
    realisations: int = 1,
    final_evaluation: bool = False,
) -> list[dict[str, Any]]:
    """Play ``controller`` (bound here) on the first ``episodes`` states of ``split`` (default all),
    ``realisations`` times each (:mod:`dipenv.realisations`), and return per episode what
    :func:`play_episode` returns: ``split``, ``index``, ``realisation``, ``steps``, ``failed``, ``return``,
    ``mean_abs_error`` (mean over intervals of ``|eta_r - target_eta_r|``), ``mean_energy`` (mean
    ``<eps E0^2>``) and the per-interval ``eta_r``, ``target_eta_r``, ``reward`` (and the field, rate and
    time traces).

    ``split`` is ``validation``, ``test`` or ``fresh`` (fixed rate schedules and targets); ``fresh`` only
    with ``final_evaluation=True``: nothing may be tuned or selected on it."""
    unwrapped = env.unwrapped
    _check_split(split, final_evaluation)
    size = unwrapped.split_sizes[split]
    count = size if episodes is None else episodes
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= size:
        raise ValueError(f"episodes must be an integer in [1, {size}] for split {split!r}, got {episodes!r}")
    if isinstance(realisations, bool) or not isinstance(realisations, int) or realisations < 1:
        raise ValueError(f"realisations must be an integer >= 1, got {realisations!r}")
    controller.bind(env)
    return [
        play_episode(env, controller, split, index, realisation, final_evaluation=final_evaluation)
        for index in range(count)
        for realisation in range(realisations)
    ]


def summarise(episodes: list[dict[str, Any]]) -> dict[str, float]:
    """Mean return, mean ``|eta_r - target|`` and mean field energy over ``episodes`` (of
    :func:`play_episodes`; failed episodes count in the return only), and the number that failed."""
    ok = [e for e in episodes if not e["failed"]]
    return {
        "episodes": float(len(episodes)),
        "failed": float(len(episodes) - len(ok)),
        "return": float(np.mean([e["return"] for e in episodes])) if episodes else math.nan,
        "mean_abs_error": float(np.mean([e["mean_abs_error"] for e in ok])) if ok else math.nan,
        "mean_energy": float(np.mean([e["mean_energy"] for e in ok])) if ok else math.nan,
    }


__all__ = [
    "CONSTANT_GRID",
    "DIRECTION_MAP_ROOT",
    "NO_FIELD_ETA",
    "TRACKING_CONTROLLERS",
    "AnglePIController",
    "ConstantFieldController",
    "MapBranch",
    "MAP_SEEDS",
    "MapFeedForwardController",
    "load_direction_map",
    "make_tracking_controller",
    "play_episode",
    "play_episodes",
    "summarise",
]
