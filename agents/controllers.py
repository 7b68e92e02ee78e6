"""Hand-made controllers for the thickening-control environments, tuned on validation, run on test.

    python -m agents.controllers --env dipenv/ThickeningControl-v2 --controller feedforward --out DIR
        [--grid mason_star=0.5,1,2] [--tune-split validation] [--split test] [--episodes N]
        [--tune-episodes N] [--repeats K] [--tune-repeats K] [--schedules FILE] [--tune-schedules FILE]
        [--env-kwargs JSON] [--model FILE] [--workers W] [--scheduler ADDRESS] [--resume | --overwrite]

Four controllers, each a policy ``obs -> action`` over the raw observation of a
:class:`dipenv.envs.thickening_control.ThickeningControlEnv` (read by label, so ``history_length`` does
not matter):

* :class:`FeedForwardController` ("feedforward"): the field follows the known shear rate,
  ``eps E0^2 ∝ gammadot``, i.e. ``Mn_ref = Mn* / gammadot`` so that the instantaneous Mason number
  ``Mn = gammadot Mn_ref`` is held at ``Mn*`` (``docs/units.md``). The rate is the observed one at the end
  of the previous interval (``log10_shear_rate``), so the controller lags a ramp by one interval. It needs
  the rate in the observation: ``ThickeningControl`` (not the stress-only env).
* :class:`PIController` ("pi"): proportional–integral feedback on the log of the measured interval-averaged
  ``eta_r`` (``ThickeningControl``) or shear stress ``Sigma_xy`` (``ThickeningControlStressOnly``)
  against a setpoint, acting on the strength action ``u`` (``u = 1`` strongest field, ``u < -0.9`` off):
  ``e_k = log10(y_k / y*)``, ``u_k = u_0 + K_p e_k + K_i sum_{j<=k} e_j`` with the integral frozen while
  ``u`` is saturated in the direction of the error (anti-windup; Åström & Murray, *Feedback Systems*,
  2008, §10.4).

* :class:`agents.mpc.MPCController` ("mpc"): model-predictive control through the surrogate model
  (:mod:`agents.mpc`): each interval the best of sampled action sequences over a horizon, scored by the
  env's reward on the surrogate's rollouts, the first action applied. It reads the frame's ``eta_r``,
  normal stresses and microstructure (``ThickeningControl``, not the stress-only env) and the episode's
  rate schedule. ``--model FILE`` names the surrogate it plans with (default: the surrogate env's own model,
  or the shipped one on the simulator); the file's SHA-256 joins the identity.

* :class:`RatePulseController` ("pulse"): a hand-built version of what the trained PPO policies do
  (``results/thickening_control/v2/README.md``): at observed rates at or above ``rate_on`` the field
  alternates every interval between the strongest field (``Mn_min``) and off; below, it holds
  ``Mn_ref = mason_steady``. Like the feed-forward it reads the rate, so it runs on ``ThickeningControl``.

The feed-forward and PI controllers saturate at the env's field range (``[Mn_min, Mn_max]`` or off): that
is the actuator's limit, not a clamp of the user's input.

The command runs every point of ``--grid`` (the Cartesian product of the listed values; defaults per
controller in :data:`DEFAULT_GRIDS`) on the first ``--tune-episodes`` states of ``--tune-split``, picks
the point with the highest mean return, and plays it on ``--split``. Output, in the layout of
``agents.open_loop`` so that ``agents.evaluate --controllers DIR`` reads it as a row: ``DIR/tuning/``
(one JSON per grid point), ``DIR/tuning.csv``, ``DIR/points/<label>.json`` (the tuned controller on the
test split), ``DIR/controller.json`` and ``DIR/command.txt``. Points whose stored identity matches are
reused, so a killed run resumes point by point (episode by episode). ``--repeats`` (``--tune-repeats``)
plays each state of ``--split`` (``--tune-split``) K times, realisations 0 .. K-1 of
:mod:`dipenv.realisations`; a rerun with a larger K adds the missing realisations to the stored ones.
The identity leaves out the energy weight ``w_E``: a rerun
with another ``energy_weight`` rescores the stored returns (:func:`agents.open_loop.rescore_stored`),
picks the tuning point again and plays only a newly picked one on ``--split``.

The folder follows the run-folder protocol (:mod:`agents.folders`): it is claimed, ``manifest.json`` written
first, after the arguments are checked and before any episode; its identity is the env id and arguments
(less ``energy_weight``, rescored), the controller, the resolved grid, the tuning split and its number of
states, the split and its number of states (not ``--repeats``/``--tune-repeats``: more realisations are
added). A rerun with another grid, say, is refused (exit 2) unless ``--overwrite`` deletes the whole
previous run; another command's folder (an open-loop baseline's, whose ``points/`` it would share) is
refused. A folder made before manifests (``controller.json``, ``tuning.csv``, ``tuning/`` or an
``agents.controllers`` ``command.txt``) is adopted when its ``controller.json`` records the same parameters.
The splits are those with fixed schedules, ``validation``, ``test`` and ``fresh`` (the training split draws
a new schedule every episode); the tuning split is ``validation`` or ``test``, never ``fresh``.

``--schedules FILE`` plays the tuned controller on the schedules of a file of your own instead of the
split's (:mod:`agents.schedules`; start states of ``--split``, ``--episodes N`` the first N entries); the
tuning stays on ``--tune-split``'s own schedules unless ``--tune-schedules FILE`` names a file for it too
(start states of ``--tune-split``). Each file's digest joins the identity, and ``controller.json`` records
it (``agents.evaluate --schedules`` checks it).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.folders import (
    add_folder_options,
    claim_out,
    command_line,
    legacy_conflict,
    legacy_markers,
    write_command,
    write_text_atomic,
)
from agents.open_loop import _finite, play_missing, read_json, rescore_stored, write_json
from agents.repeats import per_state
from agents.rollout import library_key, make_env
from agents.schedules import (
    ScheduleSet,
    episode_count,
    episodes_payload,
    load_schedules,
    prepare_states,
)
from agents.tasks import run_tasks
from agents.usage import (
    checked_env,
    compile_notice,
    directory,
    integer_at_least,
    json_object,
    output_directory,
    scheduler_address,
    usage_error,
)

PROG = "python -m agents.controllers"

CONTROLLERS = ("feedforward", "pi", "pulse", "mpc")

DEFAULT_GRIDS: dict[str, dict[str, list[float]]] = {
    "feedforward": {"mason_star": [0.25, 0.5, 1.0, 2.0, 4.0]},
    "pi": {"kp": [2.0, 6.0], "ki": [0.5, 2.0]},
    "pulse": {"rate_on": [1.5, 2.5], "mason_steady": [0.5, 1.0]},
    "mpc": {"horizon": [4.0, 8.0], "candidates": [64.0], "iterations": [2.0], "samples": [4.0], "seed": [0]},
}
"""Grids searched on the validation split when ``--grid`` is not given. ``mason_star`` spans the paper's
thickening window (Mn 0.25–4, Fig. 3b). The pulse's ``rate_on`` brackets the rate 2 above which the
trained PPO policies pulse (``results/thickening_control/v2/README.md``), ``mason_steady`` the best
constant field (0.5) and the feed-forward's tuned ``Mn*`` (1). The PI gains are in action units per
decade of error; its setpoints default to :data:`DEFAULT_SETPOINT_FRACTIONS` of the env's cap. The model-
predictive controller (:mod:`agents.mpc`) tunes its horizon (intervals)."""

DEFAULT_SETPOINT_FRACTIONS = (0.7, 0.85, 1.0)
"""Default PI setpoints as fractions of the env's ``eta_cap`` (the cap depends on the box: 6.5 at N = 64,
:data:`dipenv.rewards.DEFAULT_VISCOSITY_CAP`). The setpoint is in the measured quantity's units: ``eta_r``
on ``ThickeningControl``, ``Sigma_xy`` in ``eta gammadot_ref`` on the stress-only env (the same numbers:
the schedules' rates are log-uniform around ``gammadot_ref``)."""


def observation_index(unwrapped: Any, label: str) -> int:
    """Position of ``label`` in an env's observation (``observation_labels``); ``ValueError`` naming the
    labels it has when it lacks it (a controller bound to an env that does not observe what it reads)."""
    labels = list(unwrapped.observation_labels)
    if label not in labels:
        raise ValueError(
            f"the observation of {type(unwrapped).__name__} has no {label!r} "
            f"(it holds {', '.join(l for l in labels if '[' not in l)})"
        )
    return labels.index(label)


@dataclass
class FeedForwardController:
    """Hold the instantaneous Mason number at ``mason_star``: ``Mn_ref = mason_star / gammadot``.

    Attributes:
        mason_star: the instantaneous Mn to hold (> 0). ``Mn_ref`` outside the env's
            ``[Mn_min, Mn_max]`` saturates there (its weakest and strongest field).
    """

    mason_star: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mason_star) and self.mason_star > 0.0):
            raise ValueError(f"mason_star must be finite and > 0, got {self.mason_star!r}")
        self._rate_index = -1
        self._mapping: Any = None

    def bind(self, env: Any) -> FeedForwardController:
        """Find the rate in ``env``'s observation; ``ValueError`` if the env does not observe it."""
        unwrapped = env.unwrapped
        self._rate_index = observation_index(unwrapped, "log10_shear_rate")
        self._mapping = unwrapped.mapping
        return self

    def mason_for_rate(self, rate: float) -> float:
        """``Mn_ref`` the controller sets at shear rate ``rate`` (saturated at the field range)."""
        mapping = self._mapping
        return min(max(self.mason_star / rate, mapping.mason_min), mapping.mason_max)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self._mapping is None:
            raise RuntimeError("bind(env) the controller before use")
        rate = 10.0 ** float(np.asarray(obs).reshape(-1)[self._rate_index])
        return np.array([self._mapping.action_for(self.mason_for_rate(rate))], dtype=np.float32)


@dataclass
class PIController:
    """PI feedback on ``log10`` of the measured ``eta_r`` or shear stress, acting on the strength action.

    Attributes:
        setpoint: target of the measured quantity (``eta_r``, or ``Sigma_xy`` in ``eta gammadot_ref``), > 0.
        kp: proportional gain (action units per decade of error), >= 0.
        ki: integral gain (action units per decade per interval), >= 0.
        u0: action with zero error and zero integral (default 0: ``Mn_ref`` 1.17 in the map of ``-v1``,
            1.63 in that of ``-v2``).
    """

    setpoint: float
    kp: float
    ki: float
    u0: float = 0.0
    integral: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.setpoint) and self.setpoint > 0.0):
            raise ValueError(f"setpoint must be finite and > 0, got {self.setpoint!r}")
        for name in ("kp", "ki"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.u0) and -1.0 <= self.u0 <= 1.0):
            raise ValueError(f"u0 must be in [-1, 1], got {self.u0!r}")
        self._index = -1

    def bind(self, env: Any) -> PIController:
        """Measure ``eta_r`` where the env observes it, else the shear stress."""
        unwrapped = env.unwrapped
        labels = list(unwrapped.observation_labels)
        self.measured = "slog_eta_r" if "slog_eta_r" in labels else "slog_shear_stress"
        self._index = observation_index(unwrapped, self.measured)
        return self

    def reset(self) -> None:
        self.integral = 0.0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self._index < 0:
            raise RuntimeError("bind(env) the controller before use")
        slog = float(np.asarray(obs).reshape(-1)[self._index])
        measured = math.copysign(10.0 ** abs(slog) - 1.0, slog)  # inverse of dipenv's signed log
        error = math.log10(max(measured, 1e-6) / self.setpoint)
        raw = self.u0 + self.kp * error + self.ki * (self.integral + error)
        saturated = (raw > 1.0 and error > 0) or (raw < -1.0 and error < 0)
        if not saturated:
            self.integral += error
        u = self.u0 + self.kp * error + self.ki * self.integral
        return np.array([min(1.0, max(-1.0, u))], dtype=np.float32)


@dataclass
class RatePulseController:
    """Pulse the field at high shear rates, hold a steady one at low rates.

    At an observed rate (the rate at the end of the previous interval) ``>= rate_on`` the field alternates
    every interval between the strongest field (action ``u = 1``, ``Mn_ref = Mn_min``) and off, starting
    with the strongest; below ``rate_on`` it holds ``Mn_ref = mason_steady`` (saturated at the field range)
    and the next pulse starts with the strongest field again.

    Attributes:
        rate_on: shear rate (``gammadot_ref``) from which the field pulses, > 0.
        mason_steady: ``Mn_ref`` held below ``rate_on``, > 0 (``inf``: field off).
    """

    rate_on: float
    mason_steady: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_on) and self.rate_on > 0.0):
            raise ValueError(f"rate_on must be finite and > 0, got {self.rate_on!r}")
        if not (self.mason_steady > 0.0):  # inf allowed: field off
            raise ValueError(f"mason_steady must be > 0 (inf: off), got {self.mason_steady!r}")
        self._rate_index = -1
        self._mapping: Any = None
        self._pulse_on = True

    def bind(self, env: Any) -> RatePulseController:
        """Find the rate in ``env``'s observation; ``ValueError`` if the env does not observe it."""
        unwrapped = env.unwrapped
        self._rate_index = observation_index(unwrapped, "log10_shear_rate")
        self._mapping = unwrapped.mapping
        return self

    def reset(self) -> None:
        self._pulse_on = True

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        mapping = self._mapping
        if mapping is None:
            raise RuntimeError("bind(env) the controller before use")
        rate = 10.0 ** float(np.asarray(obs).reshape(-1)[self._rate_index])
        if rate >= self.rate_on:
            u = 1.0 if self._pulse_on else -1.0
            self._pulse_on = not self._pulse_on
            return np.array([u], dtype=np.float32)
        self._pulse_on = True
        mason = min(max(self.mason_steady, mapping.mason_min), mapping.mason_max)
        if math.isinf(self.mason_steady):
            mason = math.inf
        return np.array([mapping.action_for(mason)], dtype=np.float32)


def make_controller(kind: str, params: dict[str, float], model: str | None = None) -> Any:
    """A controller of ``kind`` (one of :data:`CONTROLLERS`; ``"mpc"``: :class:`agents.mpc.MPCController`)
    with ``params``; ``model``: the surrogate model file MPC plans with (``"mpc"`` only; default: the
    env's own or the shipped one); ``ValueError`` naming a bad kind or parameter."""
    if model is not None and kind != "mpc":
        raise ValueError(f"--model is the planner's surrogate model: mpc only, not {kind}")
    if kind == "mpc":
        from agents.mpc import MPCController

        settings: dict[str, Any] = dict(params)  # the grid's floats; MPCController checks them
        return MPCController(**settings, model=model)
    if kind == "feedforward":
        return FeedForwardController(**params)
    if kind == "pi":
        return PIController(**params)
    if kind == "pulse":
        return RatePulseController(**params)
    raise ValueError(f"controller must be one of {', '.join(CONTROLLERS)}, got {kind!r}")


def point_label(kind: str, params: dict[str, float]) -> str:
    return kind + "_" + "_".join(f"{k}{v:g}" for k, v in params.items())


def run_point(payload: dict[str, Any]) -> dict[str, Any]:
    """One controller over the first ``episodes`` states of a split, ``repeats`` realisations each (a
    task); reuses the episodes of a stored record with the same identity and plays the missing ones
    (:func:`agents.open_loop.play_missing`)."""
    env = make_env(payload["env_id"], payload["env_kwargs"])
    controller = make_controller(payload["controller"], payload["params"], payload.get("model")).bind(env)
    record = {
        "identity": _finite(payload["identity"]),
        "label": payload["label"],
        "controller": payload["controller"],
        "params": payload["params"],
        "mason_number": math.nan,
        "direction": None,
        "action": [],
        "episodes": [],
    }
    record = play_missing(record, payload, env, lambda: controller, lambda old: _finite(old.get("identity")))
    env.close()
    return record


def parse_grid(kind: str, items: Sequence[str], eta_cap: float) -> dict[str, list[float]]:
    """``["name=v1,v2", ...]`` to ``{name: [v1, v2]}``, each parameter not listed taking its default
    (:data:`DEFAULT_GRIDS`; the PI setpoints :data:`DEFAULT_SETPOINT_FRACTIONS` of ``eta_cap``, rounded
    to 0.01); ``ValueError`` naming a malformed item, a parameter ``kind`` does not take, or a parameter or
    value listed twice (argparse would keep only the last ``name=...``)."""
    defaults = {k: list(v) for k, v in DEFAULT_GRIDS[kind].items()}
    if kind == "pi":
        defaults["setpoint"] = [round(f * eta_cap, 2) for f in DEFAULT_SETPOINT_FRACTIONS]
    grid: dict[str, list[float]] = {}
    allowed = set(defaults) | ({"u0"} if kind == "pi" else set())
    for item in items:
        name, sep, values = item.partition("=")
        name = name.strip()
        if not sep or not values.strip():
            raise ValueError(f"--grid takes name=v1,v2,..., got {item!r}")
        if name not in allowed:
            raise ValueError(f"--grid: {kind} takes {', '.join(sorted(allowed))}, not {name!r}")
        if name in grid:
            raise ValueError(
                f"--grid lists {name} twice ({item!r}); give its values once, separated by commas: "
                f"{name}=v1,v2"
            )
        try:
            grid[name] = [float(v) for v in values.split(",")]
        except ValueError:
            raise ValueError(f"--grid {name}: numbers separated by commas, got {values!r}") from None
        twice = sorted({v for v in grid[name] if grid[name].count(v) > 1})
        if twice:
            listed = ", ".join(f"{v:g}" for v in twice)
            raise ValueError(f"--grid {name} lists {listed} twice (each point once)")
    for name in set(defaults) - set(grid):
        grid[name] = defaults[name]
    return grid


def grid_points(grid: dict[str, list[float]]) -> list[dict[str, float]]:
    names = sorted(grid)
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*(grid[n] for n in names))]


def schedule_digest(unwrapped: Any, split: str, episodes: int) -> str:
    """SHA-256 (16 hex digits) of the first ``episodes`` fixed schedules of ``split`` in ``unwrapped``."""
    from dipenv.schedules import schedule_to_dict

    knots = [schedule_to_dict(unwrapped.fixed_schedule(split, k)) for k in range(episodes)]
    return hashlib.sha256(json.dumps(knots).encode()).hexdigest()[:16]


def mean_return(record: dict[str, Any]) -> float:
    """Mean return over the states (each state's realisations averaged first)."""
    returns = per_state(record["episodes"], "return")[1]
    return float(np.mean(returns)) if returns.size else -math.inf


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2")
    parser.add_argument("--controller", required=True, choices=CONTROLLERS)
    parser.add_argument(
        "--grid",
        nargs="*",
        action="extend",
        default=[],
        help="name=v1,v2 ... (default: DEFAULT_GRIDS; PI setpoints 0.7, 0.85, 1 x the env's cap); each "
        "name once",
    )
    parser.add_argument(
        "--tune-split",
        default="validation",
        choices=TUNING_SPLITS,
        help="split the grid is tuned on (validation or test; never the fresh split, which only the final "
        "evaluation plays)",
    )
    parser.add_argument("--tune-episodes", type=int, default=None, help="default: the whole tuning split")
    parser.add_argument(
        "--split", default="test", choices=SPLITS, help="split the tuned controller is played on"
    )
    parser.add_argument("--episodes", type=int, default=None, help="default: the whole split")
    parser.add_argument(
        "--repeats",
        type=integer_at_least(1),
        default=1,
        help="realisations per --split state for the tuned controller (dipenv.realisations), >= 1",
    )
    parser.add_argument(
        "--tune-repeats",
        type=integer_at_least(1),
        default=1,
        help="realisations per --tune-split state for every grid point, >= 1",
    )
    parser.add_argument(
        "--schedules",
        type=Path,
        default=None,
        metavar="FILE",
        help="play the tuned controller on this JSON list of shear-rate schedules (start states of --split) "
        "instead of the split's own (agents.schedules; docs/agents.md#your-own-schedules)",
    )
    parser.add_argument(
        "--tune-schedules",
        type=Path,
        default=None,
        metavar="FILE",
        help="tune on this schedules file (start states of --tune-split) instead of the tuning split's own "
        "schedules (default: the split's own)",
    )
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of env arguments")
    parser.add_argument(
        "--model",
        default=None,
        metavar="FILE",
        help="mpc only: the surrogate model (.npz) the planner rolls out, e.g. dipenv/data/surrogate_v1.npz "
        "(default: the surrogate env's own model, or the shipped one on the simulator); its SHA-256 joins "
        "the identity",
    )
    parser.add_argument("--out", required=True, type=directory)
    parser.add_argument("--workers", type=integer_at_least(1), default=1, help="local worker processes, >= 1")
    parser.add_argument("--scheduler", type=scheduler_address, default=None, help="Dask scheduler address")
    add_folder_options(parser)
    return parser


SPLITS = ("validation", "test", "fresh")
"""The splits a controller is played on: those with fixed rate schedules
(``ThickeningControlEnv.fixed_schedule``; the training split draws a new schedule every episode)."""

TUNING_SPLITS = ("validation", "test")
"""The splits a controller may be tuned on: nothing is tuned on the fresh split
(docs/thickening_control.md)."""

LEGACY = ("controller.json", "tuning.csv", "tuning")
"""Files of a controllers folder written before manifests (``points/`` is no marker: an open-loop
baseline has one too)."""


def folder_identity(
    env_id: str,
    env_kwargs: dict[str, Any],
    controller: str,
    grid: dict[str, list[float]],
    counts: dict[str, Any],
) -> dict[str, Any]:
    """The identity in a controllers folder's manifest (the module docstring); ``counts``: the number of
    states of ``tune_split``/``split`` by those names, and the digests of the schedules files
    (``schedules``, ``tune_schedules``) where given."""
    return {
        "env_id": env_id,
        "env_kwargs": {k: v for k, v in env_kwargs.items() if k != "energy_weight"},
        "controller": controller,
        "grid": {k: grid[k] for k in sorted(grid)},
        **counts,
    }


def legacy_problem(folder: Path, requested: dict[str, Any]) -> str | None:
    """Why a pre-manifest controllers ``folder`` cannot be adopted for ``requested``, or None: its
    ``controller.json`` records other parameters (``tune_split``, ``tune_episodes``, ``split``, the env,
    controller and grid)."""
    summary_file = folder / "controller.json"
    if (folder / "manifest.json").exists() or not summary_file.exists():
        return None
    try:
        summary = read_json(summary_file)
        recorded = {
            "env_id": summary["env_id"],
            "env_kwargs": {k: v for k, v in summary["env_kwargs"].items() if k != "energy_weight"},
            "controller": summary["controller"],
            "grid": {k: summary["grid"][k] for k in sorted(summary["grid"])},
            "tune_split": summary["tune_split"],
            "tune_episodes": summary["tune_episodes"],
            "split": summary["split"],
        }
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
        return f"--out {folder}: {summary_file} cannot be read ({type(error).__name__}: {error})"
    return legacy_conflict(folder, summary_file, recorded, requested)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = build_parser().parse_args(argv)
    if str(args.out) in ("", "."):
        usage_error(PROG, "--out must name a folder for the results, got the current directory")
    output_directory(PROG, args.out)
    env_kwargs = json_object(PROG, "--env-kwargs", args.env_kwargs)
    model = None if args.model is None else str(args.model)
    if model is not None and args.controller != "mpc":
        usage_error(
            PROG, f"--model is the planner's surrogate model: --controller mpc only, not {args.controller}"
        )
    if model is not None and not Path(model).is_file():
        usage_error(
            PROG, f"--model {model}: no such file (a surrogate model .npz, e.g. dipenv/data/surrogate_v1.npz)"
        )
    model_sha = None if model is None else hashlib.sha256(Path(model).read_bytes()).hexdigest()[:16]
    try:
        for params in grid_points(parse_grid(args.controller, args.grid, eta_cap=1.0)):
            make_controller(args.controller, params, model)  # the arguments, checked before the env is made
    except ValueError as error:
        usage_error(PROG, str(error))
    env = checked_env(PROG, args.env, env_kwargs, progress=False)
    unwrapped: Any = env.unwrapped
    if not hasattr(unwrapped, "fixed_schedule"):
        usage_error(PROG, f"--env {args.env} is not a thickening-control environment")
    grid = parse_grid(args.controller, args.grid, eta_cap=unwrapped.reward_function.target_viscosity)
    points = grid_points(grid)
    try:
        make_controller(args.controller, points[0], model).bind(env)
    except ValueError as error:
        usage_error(PROG, f"--controller {args.controller} on --env {args.env}: {error}")
    sizes = unwrapped.split_sizes
    counts = {}
    files: dict[str, ScheduleSet | None] = {"--tune-split": None, "--split": None}
    for option, split, count, path, flag in (
        ("--tune-split", args.tune_split, args.tune_episodes, args.tune_schedules, "--tune-schedules"),
        ("--split", args.split, args.episodes, args.schedules, "--schedules"),
    ):
        if split not in sizes:
            usage_error(PROG, f"{option} must be one of {', '.join(sizes)}, got {split!r}")
        if path is not None:
            played = load_schedules(PROG, path, unwrapped, args.env, split, flag)
            files[option] = played
            counts[split, option] = episode_count(PROG, played, count)
            continue
        n = sizes[split] if count is None else count
        if not 1 <= n <= sizes[split]:
            count_flag = "--tune-episodes" if option == "--tune-split" else "--episodes"
            usage_error(
                PROG,
                f"{count_flag} must be in [1, {sizes[split]}] (the {split} split of {option} has "
                f"{sizes[split]} states), got {n}",
            )
        counts[split, option] = n
    library = getattr(unwrapped, "library", None)  # a surrogate env has no start-state library
    key = library_key(unwrapped)
    reward = unwrapped.reward_function
    # A controller's trajectories do not depend on the energy weight: the identity holds the physics, the
    # cap (the episode metrics are measured against it) and the failure penalty (a stored failed step
    # keeps it); stored returns are rescored below with the reward in use, so that another energy weight
    # re-picks the tuned point without simulating.
    settings = unwrapped.settings()
    reward_settings = settings.pop("reward")
    settings["eta_cap"] = reward_settings["eta_cap"]
    settings["failure_penalty"] = reward_settings["failure_penalty"]
    # The split's shear-rate schedules are part of a point's identity: the library key covers the start
    # states only, and the shipped validation schedules changed once (2026-12-03). A schedules file's
    # digest covers its schedules and start states.
    digests = {}
    for (split, option), n in counts.items():
        given = files[option]
        digests[option] = schedule_digest(unwrapped, split, n) if given is None else given.digest
    tune_n, test_n = counts[args.tune_split, "--tune-split"], counts[args.split, "--split"]
    tune_file, test_file = files["--tune-split"], files["--split"]
    identity = folder_identity(
        args.env,
        env_kwargs,
        args.controller,
        grid,
        {
            "tune_split": args.tune_split,
            "tune_episodes": tune_n,
            "split": args.split,
            "episodes": test_n,
            **({"tune_schedules": tune_file.digest} if tune_file is not None else {}),
            **({"schedules": test_file.digest} if test_file is not None else {}),
            **({"model_sha256": model_sha} if model_sha is not None else {}),
        },
    )
    if not args.overwrite:
        problem = legacy_problem(args.out, identity)
        if problem is not None:
            usage_error(PROG, problem)
    claim_out(
        PROG,
        args.out,
        "agents.controllers",
        identity,
        argv=command_line("agents.controllers", argv),
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, LEGACY, "agents.controllers"),
    )
    write_command(args.out, "agents.controllers", argv)
    for folder in ("tuning", "points"):
        (args.out / folder).mkdir(parents=True, exist_ok=True)
    compile_notice(args.scheduler)
    fixed: dict[str, int] = {}  # split -> the states played from it (its first n)
    for (split, option), n in counts.items():
        if files[option] is None:
            fixed[split] = max(n, fixed.get(split, 0))
    if callable(library):
        for split in sorted(fixed):
            library().ensure([split], progress=True, count=fixed[split])
    for (_, option), n in counts.items():
        given = files[option]
        if given is not None:
            name = "tune_schedules.json" if option == "--tune-split" else "schedules.json"
            write_json(args.out / name, given.resolved())
            prepare_states(unwrapped, given, n)
    env.close()

    def payload(
        params: dict[str, float], split: str, episodes: int, folder: str, repeats: int, option: str
    ) -> dict[str, Any]:
        label = point_label(args.controller, params)
        played = files[option]
        scheduled = episodes_payload(played)
        return {
            **({"schedules": scheduled[:episodes]} if scheduled is not None else {}),
            "repeats": repeats,
            "env_id": args.env,
            "env_kwargs": {**env_kwargs, "progress": False},
            "controller": args.controller,
            "params": params,
            **({"model": model} if model is not None else {}),
            "split": split,
            "episodes": episodes,
            "label": label,
            "path": str(args.out / folder / f"{label}.json"),
            "identity": {
                "env_id": args.env,
                "env_kwargs": {k: v for k, v in env_kwargs.items() if k != "energy_weight"},
                "env_settings": settings,
                "library_key": key,
                "controller": args.controller,
                "params": params,
                "split": split,
                "episodes": episodes,
                "schedules": digests[option],
                **({"model_sha256": model_sha} if model_sha is not None else {}),
            },
        }

    tuning = run_tasks(
        run_point,
        [payload(p, args.tune_split, tune_n, "tuning", args.tune_repeats, "--tune-split") for p in points],
        workers=args.workers,
        scheduler=args.scheduler,
    )
    tuning = [rescore_stored(r, reward, args.out / "tuning" / f"{r['label']}.json") for r in tuning]
    lines = [",".join([*sorted(grid), "return", "time_above_cap", "excess_viscosity", "energy_mean"])]
    for record in tuning:
        eps = record["episodes"]
        lines.append(
            ",".join(
                [f"{record['params'][k]:g}" for k in sorted(grid)]
                + [
                    f"{mean_return(record):.4f}",
                    *(
                        f"{np.nanmean([e.get(m, math.nan) for e in eps]):.4f}"  # equal repeats per state
                        for m in ("time_above_cap", "excess_viscosity", "energy_mean")
                    ),
                ]
            )
        )
    write_text_atomic(args.out / "tuning.csv", "\n".join(lines) + "\n")
    best = max(tuning, key=mean_return)
    tuned = run_tasks(
        run_point,
        [payload(best["params"], args.split, test_n, "points", args.repeats, "--split")],
        workers=1,
        scheduler=args.scheduler,
    )[0]
    tuned = rescore_stored(tuned, reward, args.out / "points" / f"{tuned['label']}.json")
    summary = {
        "env_id": args.env,
        "env_kwargs": env_kwargs,
        "controller": args.controller,
        "grid": grid,
        "tune_split": args.tune_split,
        "tune_episodes": tune_n,
        "tuned_params": best["params"],
        **({"model": model, "model_sha256": model_sha} if model is not None else {}),
        "tune_return": mean_return(best),
        "split": args.split,
        "label": tuned["label"],
        "test_return": mean_return(tuned),
        "library_key": key,
        "energy_weight": reward.energy_weight,
        **({"tune_schedules": tune_file.summary()} if tune_file is not None else {}),
        **({"schedules": test_file.summary()} if test_file is not None else {}),
    }
    write_json(args.out / "controller.json", summary)
    print("\n".join(lines))
    tuned_on = f"{tune_n} {args.tune_split} schedules" if tune_file is None else tune_file.label()
    played_on = args.split if test_file is None else f"{test_file.label()} ({args.split} start states)"
    print(
        f"tuned on {tuned_on}: {tuned['label']} (return {mean_return(best):.2f}); "
        f"on {played_on}: {mean_return(tuned):.2f}"
    )
    return summary


__all__ = [
    "CONTROLLERS",
    "DEFAULT_GRIDS",
    "DEFAULT_SETPOINT_FRACTIONS",
    "FeedForwardController",
    "PIController",
    "RatePulseController",
    "make_controller",
    "main",
    "parse_grid",
]

if __name__ == "__main__":
    main()
