"""The rows of ``python -m agents.tracking`` (issue 44): the baselines' grids, trained runs, and the task that
plays one row's episodes and resumes them.

* **Grids** (``--grid [KIND.]NAME=V1,V2``): :data:`PARAMETERS` says what each controller of
  :mod:`agents.tracking_controllers` takes and how a value is read; :data:`DEFAULT_GRIDS` what is tuned
  otherwise. A constant field's direction is a name of the direction map (:data:`DIRECTIONS`); a constant
  without a field is one point whatever its direction.
* **Trained runs** (``--run``): an ``agents.train`` run folder (``config.yml``, ``model.zip``, and
  ``vecnormalize.pkl`` where it normalised its observations) is played with its mean action
  (``deterministic=True``) on its observation normalised by the statistics it was trained with, in its
  training env or another id with the same spaces (``--play-env``), checked to have ``--env``'s physics,
  reward and start states (:func:`agents.evaluate.physics_difference`: only the observation and the action
  map may differ). A run is identified by its files' contents (SHA-256), not by where it lies.
* **A row's episodes** (:func:`play_point`, a task of :func:`agents.tasks.run_tasks`): one JSON file per
  grid point or row, holding its identity and its episodes
  (:func:`agents.tracking_controllers.play_episode`), rewritten after every episode; a rerun keeps the
  stored episodes of the same identity and plays only the missing ``(state, realisation)`` pairs.
"""

from __future__ import annotations

import csv
import hashlib
import io
import itertools
import json
import math
import pickle
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.evaluate import file_digest, physics_difference
from agents.folders import normalise, run_folders
from agents.folders import read_run_config as folders_read_run_config
from agents.open_loop import read_json, write_json
from agents.repeats import episode_key, missing, per_state, select
from agents.residual import RESIDUAL_KEY
from agents.rollout import library_key, make_env, statistics_file, trained_policy
from agents.tracking_controllers import (
    CONSTANT_GRID,
    TARGET_LABELS,
    load_direction_map,
    make_tracking_controller,
    play_episode,
)

HALF = math.sqrt(0.5)
DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "y": (0.0, 1.0, 0.0),
    "x": (1.0, 0.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "ext": (HALF, HALF, 0.0),
    "comp": (HALF, -HALF, 0.0),
    "yz": (0.0, HALF, HALF),
}
"""Field directions a constant's ``--grid direction=...`` names: the direction map's
(``results/direction_map/phi0.45_<name>``; ``ext`` and ``comp`` the shear's extensional and compressional
axes, ``(x+y)/sqrt2`` and ``(x-y)/sqrt2``; ``E`` and ``-E`` are one field)."""


def direction_name(direction: Sequence[float]) -> str:
    """The name in :data:`DIRECTIONS` of ``direction`` or its opposite (``ValueError`` for another)."""
    e = np.asarray(direction, dtype=float)
    for name, known in DIRECTIONS.items():
        if min(np.abs(e - known).max(), np.abs(e + known).max()) < 1e-9:
            return name
    raise ValueError(f"direction {tuple(direction)} is none of {', '.join(DIRECTIONS)}")


def _mason(text: str) -> float:
    value = math.inf if text.strip().lower() in ("inf", "off") else float(text)
    if not value > 0:
        raise ValueError(f"must be > 0 or inf (off), got {text!r}")
    return value


def _choice(options: Sequence[str]) -> Any:
    def parse(text: str) -> str:
        if text not in options:
            raise ValueError(f"must be one of {', '.join(options)}, got {text!r}")
        return text

    return parse


def _flag(text: str) -> bool:
    if text.lower() not in ("true", "false"):
        raise ValueError(f"must be true or false, got {text!r}")
    return text.lower() == "true"


PARAMETERS: dict[str, dict[str, Any]] = {
    "constant": {"mason_ref": _mason, "direction": _choice(tuple(DIRECTIONS))},
    "map_feedforward": {
        "target": _choice(tuple(TARGET_LABELS)),
        "points_per_decade": int,
        "interpolate": _flag,
    },
    "angle_pi": {
        **{name: float for name in ("kp", "ki", "mason_star", "polar0", "azimuth")},
        "target": _choice(tuple(TARGET_LABELS)),
    },
}
"""What ``--grid`` sets per controller, and how each value is read."""

DEFAULT_GRIDS: dict[str, dict[str, list[Any]]] = {
    "constant": {
        "mason_ref": list(CONSTANT_GRID["mason_ref"]),
        "direction": [direction_name(d) for d in CONSTANT_GRID["direction"]],
    },
    "map_feedforward": {"target": ["now", "next", "ahead"]},
    "angle_pi": {"kp": [1.0, 3.0], "ki": [0.3, 1.0], "mason_star": [0.5, 1.0]},
}
"""Grids tuned when ``--grid`` does not set a parameter: the constant fields of
:data:`agents.tracking_controllers.CONSTANT_GRID` (31 fields: 5 strengths x 6 directions and off), the
feed-forward's choice of the target it reads, and a starting grid of the angle PI's gains (polar action
units per decade of error; the y->z angle spans 2 units) and held Mn (not tuned on anything yet)."""

IDENTITY_KEYS = ("controller", "params", "algo", "model_sha256", "stats_sha256")
"""What a grid point's or a trained run's file identity holds beside the env and the episodes."""


def parse_grids(kinds: Sequence[str], items: Sequence[str]) -> dict[str, dict[str, list[Any]]]:
    """``[KIND.]NAME=V1,V2`` items to a grid per controller of ``kinds`` (defaults :data:`DEFAULT_GRIDS`);
    ``ValueError`` naming ``--grid``, the item and what is wrong."""
    grids: dict[str, dict[str, list[Any]]] = {kind: {} for kind in kinds}
    for item in items:
        name, sep, values = item.partition("=")
        kind, dot, name = name.strip().rpartition(".")
        if not sep or not values.strip() or not name:
            raise ValueError(f"--grid takes [KIND.]NAME=V1,V2,..., got {item!r}")
        if dot and kind not in kinds:
            raise ValueError(
                f"--grid {item!r}: {kind!r} is not a --controller of this command ({', '.join(kinds)})"
            )
        targets = [kind] if dot else [k for k in kinds if name in PARAMETERS[k]]
        if not targets or name not in PARAMETERS[targets[0]]:
            takes = "; ".join(f"{k} takes {', '.join(sorted(PARAMETERS[k]))}" for k in (targets or kinds))
            raise ValueError(f"--grid {item!r}: no --controller takes {name!r} ({takes})")
        for k in targets:
            if name in grids[k]:
                raise ValueError(f"--grid sets {k}'s {name} twice; give its values once: {name}=V1,V2")
            try:
                parsed = [PARAMETERS[k][name](v.strip()) for v in values.split(",")]
            except ValueError as error:
                raise ValueError(f"--grid {item!r}: {name} {error}") from None
            if len(set(parsed)) < len(parsed):
                raise ValueError(f"--grid {item!r} lists a value twice (each point once)")
            grids[k][name] = parsed
    for kind in kinds:
        for parameter, defaults in DEFAULT_GRIDS[kind].items():
            grids[kind].setdefault(parameter, list(defaults))
        grids[kind] = {name: grids[kind][name] for name in sorted(grids[kind])}
    return grids


def grid_points(kind: str, grid: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of ``grid``; a constant without a field (``mason_ref`` inf) once, with the
    first direction listed."""
    names = sorted(grid)
    points = [
        dict(zip(names, values, strict=True)) for values in itertools.product(*(grid[n] for n in names))
    ]
    if kind == "constant":
        off = [p for p in points if math.isinf(p["mason_ref"])]
        points = [p for p in points if not math.isinf(p["mason_ref"]) or p is off[0]]
    return points


def build_controller(kind: str, params: dict[str, Any]) -> Any:
    """:func:`agents.tracking_controllers.make_tracking_controller` with a named direction resolved."""
    if kind == "constant":
        params = {**params, "direction": DIRECTIONS[params["direction"]]}
    return make_tracking_controller(kind, params)


def point_label(kind: str, params: dict[str, Any]) -> str:
    if kind == "constant" and math.isinf(params["mason_ref"]):
        return "constant_off"
    text = {k: format(v, "g") if isinstance(v, float) else str(v) for k, v in params.items()}
    return kind + "_" + "_".join(f"{k}{v}" for k, v in text.items())


def describe(kind: str, params: dict[str, Any]) -> str:
    """A tuned controller's row name."""
    if kind == "constant":
        if math.isinf(params["mason_ref"]):
            return "best constant (off)"
        return f"best constant (Mn_ref {params['mason_ref']:g}, {params['direction']})"
    shown = ", ".join(f"{k} {format(v, 'g') if isinstance(v, float) else v}" for k, v in params.items())
    return f"{'map feed-forward' if kind == 'map_feedforward' else 'angle PI'} ({shown})"


def map_digest() -> str:
    """SHA-256 (16 hex digits) of the direction map the feed-forward reads (its branches' points)."""
    branches = load_direction_map()
    content = [[b.name, b.direction, b.mason, b.eta] for _, b in sorted(branches.items())]
    return hashlib.sha256(json.dumps(content).encode()).hexdigest()[:16]


# -- trained runs ------------------------------------------------------------------------------------------


def find_runs(paths: Sequence[Path]) -> dict[str, tuple[str, list[Path]]]:
    """Each ``--run`` argument as a row: label -> (name, run folders with ``model.zip``); ``ValueError``
    naming ``--run`` when one holds none or two rows would share a label."""
    rows: dict[str, tuple[str, list[Path]]] = {}
    for path in paths:
        key, runs = run_folders(path, "model.zip", "--run")
        algo = read_run_config(runs[0])["algo"]
        label = f"{algo}_{key.resolve().name}"
        if label in rows:
            raise ValueError(f"--run {path}: another --run is also named {label} (runs of one folder name)")
        rows[label] = (f"{algo} ({key.resolve().name})", runs)
    return rows


def read_run_config(run: Path) -> dict[str, Any]:
    """A run's ``config.yml`` (:func:`agents.folders.read_run_config`); ``ValueError`` naming ``--run``."""
    return folders_read_run_config(run, "--run")


def run_play(run: Path, play_env: str | None, env_id: str, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """How run ``run`` is played (env, arguments, model, statistics, digests); ``ValueError`` naming
    ``--run`` or ``--play-env`` when it cannot be played on ``env_id``'s episodes: other physics, reward or
    start states (:func:`agents.evaluate.physics_difference`), other spaces, files that do not load."""
    from stable_baselines3 import PPO, SAC

    config = read_run_config(run)
    played = play_env or config["env_id"]
    kwargs = {} if play_env else dict(config.get("env_kwargs") or {})
    if play_env and RESIDUAL_KEY in (config.get("env_kwargs") or {}):  # the controller is part of the policy
        kwargs[RESIDUAL_KEY] = config["env_kwargs"][RESIDUAL_KEY]
    if "ViscosityTracking" not in played:
        where = f"--play-env {play_env}" if play_env else f"--run {run}: trained on {played}, which"
        raise ValueError(f"{where} is no viscosity-tracking env (its episodes have no target)")
    try:
        target = make_env(played, {**kwargs, "progress": False})
    except Exception as error:  # an unknown id or argument, in Gymnasium's or the env's words
        where = "--play-env" if play_env else f"--run {run}"
        raise ValueError(f"{where}: {played} cannot be made ({error})") from None
    if play_env:
        source = make_env(config["env_id"], {**(config.get("env_kwargs") or {}), "progress": False})
        spaces = (source.observation_space, source.action_space)
        source.close()
        if spaces != (target.observation_space, target.action_space):
            raise ValueError(
                f"--play-env {play_env}: {run} was trained on {config['env_id']} with observation space "
                f"{spaces[0]} and action space {spaces[1]}; {play_env} has {target.observation_space} and "
                f"{target.action_space}",
            )
    reference = make_env(env_id, {**env_kwargs, "progress": False})
    mine: Any = target.unwrapped
    theirs: Any = reference.unwrapped
    problems = (
        []
        if (played, kwargs) == (env_id, env_kwargs)
        else physics_difference(played, kwargs, env_id, env_kwargs)
    )
    if mine.settings()["reward"] != theirs.settings()["reward"]:
        problems.append("reward")
    if library_key(mine) != library_key(theirs):
        problems.append("start-state library")
    if problems:
        raise ValueError(
            f"--run {run}: played on {played} with {kwargs}, which differs from --env {env_id} in "
            f"{', '.join(sorted(set(problems)))} (only the observation and the action map may differ)",
        )
    target.close()
    reference.close()
    model_file = run / "model.zip"
    stats_file = statistics_file(config, run / "vecnormalize.pkl")
    try:
        (PPO if config["algo"] == "ppo" else SAC).load(str(model_file), device="cpu")
        if stats_file is not None:
            with open(stats_file, "rb") as handle:
                if not hasattr(pickle.load(handle), "normalize_obs"):
                    raise ValueError("no VecNormalize statistics")
    except Exception as error:
        kind = type(error).__name__
        raise ValueError(f"--run {run}: its model or statistics cannot be loaded ({kind}: {error})") from None
    folder = run.resolve()
    return {
        "label": f"{folder.parent.name}_{folder.name}",
        "run": str(run),
        "algo": config["algo"],
        "seed": config.get("seed"),
        "env_id": played,
        "env_kwargs": kwargs,
        "model_file": str(model_file),
        "stats_file": None if stats_file is None else str(stats_file),
        "model_sha256": file_digest(model_file),
        "stats_sha256": None if stats_file is None else file_digest(stats_file),
    }


def run_policy(payload: dict[str, Any]) -> Any:
    """A trained run's mean action on its normalised observation (``deterministic=True``;
    :func:`agents.rollout.trained_policy`)."""
    import torch

    torch.set_num_threads(1)
    return trained_policy(payload["algo"], payload["model_file"], payload["stats_file"])


# -- one row's episodes (a task) ---------------------------------------------------------------------------


def play_point(payload: dict[str, Any]) -> dict[str, Any]:
    """The episodes of one grid point or row on a split (a task): those stored in ``payload["path"]`` with
    the same identity are kept, the missing ones played (:func:`agents.tracking_controllers.play_episode`)
    and the file rewritten after each. Returns the record with the requested episodes only."""
    from tqdm.auto import tqdm

    path = Path(payload["path"])
    identity = normalise(payload["identity"])
    stored: list[dict[str, Any]] = []
    if path.exists():
        old = read_json(path)
        if isinstance(old, dict) and normalise(old.get("identity") or {}) == identity:
            stored = list(old["episodes"])
    indices, repeats = range(payload["episodes"]), payload["realisations"]
    record = {**payload["meta"], "identity": payload["identity"], "episodes": stored}
    todo = missing(stored, indices, repeats)
    if todo:
        env = make_env(payload["env_id"], {**payload["env_kwargs"], "progress": False})
        if "controller" in payload:
            policy = build_controller(payload["controller"], payload["params"]).bind(env)
        else:
            policy = run_policy(payload)
        scheduled = payload.get("schedules")
        bar = tqdm(
            todo, desc=payload["meta"]["label"], unit="episode", leave=False, disable=not payload["progress"]
        )
        for index, realisation in bar:
            if scheduled is None:
                episode = play_episode(
                    env, policy, payload["split"], index, realisation, final_evaluation=payload["final"]
                )
            else:
                entry = scheduled[index]
                schedule = {"times": entry["times"], "rates": entry["rates"]}
                episode = play_episode(
                    env,
                    policy,
                    payload["split"],
                    entry["start_index"],
                    realisation,
                    schedule,
                    payload["final"],
                )
                episode.update(
                    index=index,
                    entry=index,
                    start_index=entry["start_index"],
                    schedule_digest=entry["schedule_digest"],
                )
            stored.append(episode)
            stored.sort(key=episode_key)
            write_json(path, record)
        env.close()
    return {**record, "episodes": select(stored, indices, repeats)}


def mean_return(record: dict[str, Any]) -> float:
    """Mean return over the states, each state's realisations averaged first."""
    return float(np.mean(per_state(record["episodes"], "return")[1]))


def tuning_table(
    records: Sequence[dict[str, Any]], previous: str | None = None
) -> tuple[str, dict[str, dict[str, Any]]]:
    """``tuning.csv`` (a line per grid point: controller, point, parameters, mean return, mean
    ``|eta_r - target|``, mean energy, ``chosen``) and the chosen record per controller: the highest mean
    return (each state's realisations averaged first; the first of equal ones). The lines of ``previous``
    (the folder's ``tuning.csv``) for controllers that ``records`` do not hold are kept (tuned by an
    earlier command into the same folder)."""
    best: dict[str, dict[str, Any]] = {}
    for record in records:
        kind = record["controller"]
        if kind not in best or mean_return(record) > mean_return(best[kind]):
            best[kind] = record
    text = io.StringIO()
    table = csv.writer(text, lineterminator="\n")
    table.writerow(["controller", "point", "params", "return", "mean_abs_error", "mean_energy", "chosen"])
    kept = list(csv.reader(io.StringIO(previous)))[1:] if previous else []
    table.writerows(line for line in kept if line and line[0] not in best)
    for record in records:
        means = [
            float(np.mean(per_state(record["episodes"], m)[1])) for m in ("mean_abs_error", "mean_energy")
        ]
        table.writerow(
            [
                record["controller"],
                record["label"],
                json.dumps(normalise(record["params"])),
                f"{mean_return(record):.4f}",
                *(f"{m:.4f}" for m in means),
                "yes" if record is best[record["controller"]] else "",
            ]
        )
    return text.getvalue(), best


__all__ = [
    "DEFAULT_GRIDS",
    "DIRECTIONS",
    "IDENTITY_KEYS",
    "PARAMETERS",
    "build_controller",
    "describe",
    "direction_name",
    "find_runs",
    "grid_points",
    "map_digest",
    "mean_return",
    "parse_grids",
    "play_point",
    "point_label",
    "run_play",
    "run_policy",
    "tuning_table",
]
