"""Evaluate trained policies against the open-loop baseline on held-out start states.

    python -m agents.evaluate [RUN_DIRS...] --baseline OPEN_LOOP_DIR --out DIR [--controllers DIR...]
        [--split test] [--episodes N] [--repeats K] [--policy-repeats K] [--model final|best]
        [--actions mean|sampled|both] [--play-kwargs JSON] [--play-env ID]
        [--validation-baseline OPEN_LOOP_DIR] [--schedules FILE] [--workers 2] [--scheduler ADDRESS]
        [--resume | --overwrite]

``--repeats K`` plays every held-out state K times (realisations 0 .. K-1 of :mod:`dipenv.realisations`:
the state moved by 1e-9 a, so that the chaotic noise of one episode averages out); the baseline and the
controllers must hold those realisations (their commands' ``--repeats``), else exit 2. Every statistic
averages a state's realisations first (:mod:`agents.repeats`): the intervals stay over states and seeds.
``--policy-repeats K`` sets the trained runs' realisations apart (default: ``--repeats``): five training
seeds already play each state five times, each from its own trajectory, so one realisation per seed
resamples the chaotic noise as well as four, at a quarter of the cost.

``--schedules FILE`` (the thickening-control envs) plays the policies on the schedules of a file of your
own (:mod:`agents.schedules`: episode ``j`` follows schedule ``j`` from its start state of the baseline's
split); the ``--baseline`` and every ``--controllers`` folder must have been made with a file of the same
digest (``agents.open_loop --schedules FILE``, ``agents.controllers --schedules FILE``), else exit 2
naming both; a baseline made with a file needs ``--schedules``. The rows are then paired per entry.

``--controllers`` adds each tuned controller of an ``agents.controllers`` folder as a row beside the
constant fields (played on the same split, start states and schedules, else exit 2). Runs and controllers
may come from another env than the baseline's if the two differ only in what the policy observes or in
the map from actions to fields (:func:`physics_difference`): ``ThickeningControlStressOnly-v2``'s rows
share ``ThickeningControl-v2``'s constant fields, and those share ``ThickeningControl-v1``'s. For the
thickening-control environments the table adds the whole-episode metrics of :mod:`agents.rollout`: the
fraction of intervals above the cap, the excess ``eta_r`` over it and the field energy.

``--play-kwargs JSON`` plays the trained runs with these env arguments over the ones they were trained
with: ``'{"simulation_overrides": {}}'`` tests policies trained with a coarser time step
(``{"simulation_overrides": {"max_displacement": 0.008}}``, half the simulator steps) in the reference
physics of the baseline. The physics check above then applies to the arguments played, the table's header
names them, and the per-run results are played again when they change.

``--play-env ID`` plays the trained runs in another env than the one they were trained on, with that env's
default arguments (and ``--play-kwargs``): policies trained on the surrogate
(``dipenv/ThickeningControlSurrogate-v0``) are judged in the simulator with ``--play-env
dipenv/ThickeningControl-v2``. The observation and action spaces must be the same (exit 2 naming both
otherwise). Their ``learning.png`` curves stay those of the training env (the surrogate's returns).

``RUN_DIRS`` are training run folders (with ``model.zip``) or folders of them (``--seeds`` output:
``seed0/``, ``seed1/``, ...); the runs under one argument (or with one parent folder) form one policy,
their training seeds its samples. Each run plays one deterministic episode from each of the first
``--episodes`` start states of ``--split`` (by default the states of the baseline's points), with the
observation normalisation it was trained with; per-run results go to ``DIR/runs/`` (reused on rerun while
the run, its model's and statistics' contents (SHA-256), the states and the play arguments are the same,
so a fresh checkout of committed results replays nothing); a run interrupted part way keeps the episodes it
finished in ``DIR/runs/<run>.partial.json`` and resumes at the next one.
``--model best`` plays, instead of the final policy, each run's checkpoint with the highest mean validation
return (model selection on the validation states, testing on the held-out test states). The baseline's
stored returns are rescored with the reward of the policies' env (that of the first run's config), and the
best constant field is chosen for that reward. ``--actions sampled`` samples
the policy's actions (torch seeded with the start state's index) instead of playing its mean (``both``:
each as its own row): a PPO policy early in training is a wide Gaussian whose mean alone can do much
worse than the policy it was trained as.

Writes ``table.md`` / ``results.json``: per policy, the mean and the interquartile mean (IQM) over its
training seeds and the start states, each with its 95% stratified-bootstrap interval (rliable, Agarwal
et al. 2021; :mod:`agents.statistics`), of the time-averaged ``eta_r`` over the second half of each
episode, the field energy ``<1/Mn>`` over that half and the return; for the baselines (no field, the best
constant field for the reward, and any ``--controllers``) the same over start states. Plots:
``traces.png`` (field and ``eta_r`` against strain on the first state) and ``pareto.png`` (the constant
fields' front with the policies on it). ``verdict.md`` (also in ``results.json``): each controller and
policy against the constant-field front, its return against the best constant field's (paired per seed;
paired per state, the test that resolves a controller; and rliable's probability of improvement over the
states) and its action variation (:mod:`agents.comparison`).
``learning.png``: each run's
return against training steps, on the validation states with the mean action (its ``EvalCallback`` log)
and in its training episodes with sampled actions (TensorBoard logs, or the
``training_returns.csv`` that replaces them in a committed run), with the constant fields' returns on the
same validation states (``--validation-baseline``); without one, the test-state returns of the table's
constants, labelled as such (they are not on the curves' states).

Printed: a compact table (policy, ``eta_r`` and return with their intervals, field energy); the full
tables are in ``table.md`` and ``verdict.md``.

The output folder follows the run-folder protocol (:mod:`agents.folders`): it is claimed, ``manifest.json``
written first, after every argument and input is checked and before any episode is played; its identity is
the command's arguments but ``--workers``/``--scheduler`` (RUN_DIRS, ``--baseline``, ``--controllers``,
``--validation-baseline`` as paths, compared by the files they name; the split, ``--episodes``,
``--repeats``, ``--policy-repeats``, ``--model``, ``--actions``, ``--play-kwargs``, ``--play-env``, and the
digest of ``--schedules``). A rerun of the same
arguments continues (per-run results are reused, matched by the model's and statistics' contents, the
env, states and play arguments, not by where the run folder lies: a committed evaluation resumes in
another checkout); other arguments, or another command's folder, are refused
(exit 2) unless ``--overwrite`` deletes the whole previous evaluation. A folder made before manifests (it
holds ``table.md``, ``verdict.md``, ``results.json`` or an ``agents.evaluate`` ``command.txt``) is adopted.
``--baseline`` (and ``--validation-baseline``) must be an ``agents.open_loop`` folder (by its manifest, or
before manifests by its files) whose points are all constant fields; ``--controllers`` folders must be
``agents.controllers`` folders.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.comparison import (
    ENERGY_SAVING_TARGET,
    action_variation,
    energy_target,
    front_eta,
    front_points,
    paired_front_gap,
    position,
    return_gap,
)
from agents.folders import (
    add_folder_options,
    claim_out,
    command_line,
    compare_paths,
    legacy_markers,
    owner,
    read_evaluation_log,
    run_folders,
    save_figure,
    write_command,
    write_text_atomic,
)
from agents.folders import read_run_config as folders_read_run_config
from agents.open_loop import plot_pareto, read_json, rescore, summarise_points, write_json
from agents.repeats import missing, per_state, realisation_of, select, within_state_sd
from agents.rollout import make_env, run_episode, statistics_file, trained_policy
from agents.schedules import (
    ScheduleSet,
    episodes_payload,
    load_schedules,
    mismatch,
    mismatch_message,
    play,
)
from agents.statistics import interval_estimates, probability_of_improvement
from agents.tasks import run_tasks
from agents.usage import (
    compile_notice,
    directory,
    integer_at_least,
    json_object,
    output_directory,
    scheduler_address,
    usage_error,
)

PROG = "python -m agents.evaluate"


def read_run_config(run: Path) -> dict[str, Any]:
    """A run's ``config.yml`` (:func:`agents.folders.read_run_config`), or exit 2 naming the file."""
    try:
        return folders_read_run_config(run, "RUN_DIRS")
    except ValueError as error:
        usage_error(PROG, str(error))


def read_baseline(folder: Path, option: str = "--baseline") -> tuple[dict[str, Any], list[Path]]:
    """``pareto.json`` and the point files of an ``agents.open_loop`` folder, or exit 2 naming
    ``option`` when the folder is missing, empty or corrupt."""
    path = folder / "pareto.json"
    if not folder.is_dir():
        usage_error(PROG, f"{option} {folder} is not a folder (give an agents.open_loop --out)")
    made_by = owner(PROG, folder, option)
    if made_by is not None and made_by != "agents.open_loop":
        usage_error(PROG, f"{option} {folder} was made by {made_by}, not agents.open_loop (manifest.json)")
    if made_by is None and (folder / "command.txt").exists():
        if "command.txt" not in legacy_markers(folder, (), "agents.open_loop"):
            usage_error(PROG, f"{option} {folder}: its command.txt is not an agents.open_loop command")
    try:
        pareto = read_json(path)
    except (OSError, ValueError) as error:
        usage_error(
            PROG,
            f"{option} {folder}: {path} cannot be read ({type(error).__name__}: {error}); is it an "
            "agents.open_loop --out that has finished?",
        )
    if not isinstance(pareto, dict) or any(k not in pareto for k in ("env_id", "env_kwargs", "split")):
        usage_error(PROG, f"{option} {folder}: {path} is not an agents.open_loop pareto.json")
    points = sorted((folder / "points").glob("*.json"))
    if not points:
        usage_error(PROG, f"{option} {folder}: no points/*.json in it (rerun agents.open_loop)")
    return pareto, points


def read_constant_points(files: list[Path], folder: Path, option: str = "--baseline") -> list[dict[str, Any]]:
    """The constant-field points ``files`` of an open-loop folder, or exit 2 naming ``option`` and the file
    that cannot be read or is no constant field (a controller's point, dropped there by
    ``agents.controllers --out`` into the baseline before folders had owners)."""
    records = []
    for path in files:
        try:
            record = read_json(path)
            mason = record["mason_number"]
            episodes = record["episodes"]
        except (OSError, ValueError, KeyError, TypeError) as error:
            kind = type(error).__name__
            usage_error(PROG, f"{option} {folder}: {path} cannot be read as a point ({kind}: {error})")
        constant = (
            "controller" not in record
            and isinstance(mason, int | float)
            and not isinstance(mason, bool)
            and not math.isnan(mason)
            and mason > 0
            and isinstance(episodes, list)
        )
        if not constant:
            what = f"the {record['controller']} controller's" if "controller" in record else "not a constant"
            usage_error(
                PROG,
                f"{option} {folder}: {path} is {what} point, not a constant field's (an open-loop baseline "
                "holds constant fields only): remove it, or make the baseline again with agents.open_loop",
            )
        records.append(record)
    return records


def validation_lines(folder: Path, pareto: dict[str, Any], reward: Any) -> list[tuple[str, float]]:
    """The no-field and best-constant returns of ``--validation-baseline`` (an ``agents.open_loop`` folder
    on the validation states, rescored with ``reward``), for the learning curves: the validation returns
    of the runs are measured on those states, the table's constants on the test states. Exit 2 unless it
    holds validation states of the test baseline's physics and library."""
    option = "--validation-baseline"
    other, files = read_baseline(folder, option)
    if other["split"] != "validation":
        usage_error(PROG, f"{option} {folder} was played on the {other['split']} states, not validation")
    if other.get("schedules"):
        usage_error(
            PROG,
            f"{option} {folder} was played on the schedules of {other['schedules'].get('file')}, not on the "
            "validation split's own, where the runs' validation returns are measured",
        )
    same = (other["env_id"], other["env_kwargs"]) == (pareto["env_id"], pareto["env_kwargs"])
    differing = (
        []
        if same
        else physics_difference(other["env_id"], other["env_kwargs"], pareto["env_id"], pareto["env_kwargs"])
    )
    differing = [d for d in differing if d != "reward"]  # rescored below
    if differing or other.get("library_key") != pareto.get("library_key"):
        what = ", ".join(differing) if differing else "the start-state library"
        usage_error(PROG, f"{option} {folder} differs from --baseline in {what}")
    points = [rescore(p, reward) for p in read_constant_points(files, folder, option)]
    summary = summarise_points(points)
    best = max(summary, key=lambda r: r["return"])
    lines = [(f"best constant ({best['label']}), validation states", float(best["return"]))]
    off = next((r for r in summary if r["label"] == "off"), None)
    if off is not None and off is not best:
        lines.insert(0, ("no field, validation states", float(off["return"])))
    return lines


def check_loadable(run: Path, algo: str, model_file: Path, stats_file: Path, normalize: bool) -> None:
    """Exit 2 naming the file unless the policy (and its statistics, when used) load: a corrupt or
    truncated ``model.zip`` or ``vecnormalize.pkl`` is refused before any episode is played."""
    from stable_baselines3 import PPO, SAC

    try:
        (PPO if algo == "ppo" else SAC).load(str(model_file), device="cpu")
    except Exception as error:  # a zip error, a pickle error, another algorithm's file: all unloadable
        kind = type(error).__name__
        usage_error(PROG, f"RUN_DIRS: {model_file} cannot be loaded as a {algo} model ({kind}: {error})")
    if normalize:
        try:
            with open(stats_file, "rb") as handle:
                stats = pickle.load(handle)
        except Exception as error:
            usage_error(PROG, f"RUN_DIRS: {stats_file} cannot be loaded ({type(error).__name__}: {error})")
        if not hasattr(stats, "normalize_obs"):
            usage_error(PROG, f"RUN_DIRS: {stats_file} holds no VecNormalize statistics")


def find_runs(paths: list[Path], marker: str = "model.zip") -> dict[str, list[Path]]:
    """Group run folders into policies (see the module docstring); name -> run folders. A run folder is
    one that holds ``marker``: ``model.zip`` (a finished run) or, for ``--model best``,
    ``eval/evaluations.npz`` (a run with a validation, finished or still training)."""
    groups: dict[str, list[Path]] = {}
    for path in paths:
        try:
            key, runs = run_folders(path, marker, "RUN_DIRS")
        except ValueError as error:
            usage_error(PROG, str(error))
        config = read_run_config(runs[0])
        name = f"{config['algo']} ({key.name or key})"
        groups.setdefault(name, []).extend(r for r in runs if r not in groups.get(name, []))
    return groups


def file_digest(path: Path) -> str | None:
    """The SHA-256 of a file's contents (16 hex digits), or None when it does not exist: what identifies a
    played model, since a checkout's modification times are not the training's."""
    if not path.exists():
        return None
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:16]


def model_files(run: Path, which: str) -> tuple[Path, Path]:
    """The policy and its observation statistics: ``final`` (the end of training) or ``best`` (the
    checkpoint at the evaluation with the highest mean validation return; checkpoints and evaluations
    coincide when ``eval_freq`` is a multiple of ``checkpoint_freq``, as in the shipped hyperparameters)."""
    if which == "final":
        return run / "model.zip", run / "vecnormalize.pkl"
    if which != "best":
        raise ValueError(f"model must be 'final' or 'best', got {which!r}")
    log = run / "eval" / "evaluations.npz"
    if not log.exists():
        usage_error(PROG, f"--model best: {run}: no eval/evaluations.npz, so no best-validation checkpoint")
    data = checked_evaluation_log(log)
    if not data["timesteps"].size:
        usage_error(PROG, f"--model best: {log} holds no evaluation yet")
    steps = int(data["timesteps"][int(np.argmax(data["results"].mean(axis=1)))])
    model = run / "checkpoints" / f"ckpt_{steps}_steps.zip"
    if not model.exists():
        usage_error(
            PROG,
            f"--model best: {run}: the best validation return was at {steps} steps, but {model} is missing",
        )
    return model, run / "checkpoints" / f"ckpt_vecnormalize_{steps}_steps.pkl"


def checked_evaluation_log(log: Path) -> dict[str, Any]:
    """A run's ``eval/evaluations.npz`` (:func:`agents.folders.read_evaluation_log`), or exit 2 naming the
    file and what is wrong with it (a truncated file was a ``BadZipFile`` traceback)."""
    try:
        return read_evaluation_log(log)
    except ValueError as error:
        usage_error(PROG, f"RUN_DIRS: {error}")


def start_state_library(config: dict[str, Any]) -> str:
    """Key of the start-state library a run's env plays (``StateLibrary.key`` of dipenv.state_library)."""
    env = make_env(config["env_id"], {**config["env_kwargs"], "progress": False})
    try:
        return str(env.unwrapped.library().key)  # type: ignore[attr-defined]
    finally:
        env.close()


OBSERVATION_SETTINGS = ("observation", "history_length")
"""Env settings that shape only what a policy sees, not the trajectory a given action sequence makes."""

ACTION_MAP_SETTINGS = ("mason_min", "mason_max", "off_band")
"""Env settings of the map from the action ``u`` to ``Mn_ref``. A constant field is named by its
``Mn_ref`` (each env computes its own action for it), so two envs whose maps differ play the same constant
field on the same physics: ``ThickeningControl-v2`` (strongest field 0.1) may share ``-v1``'s baseline
(0.05), whose points at ``Mn_ref`` 0.2 to 2 both envs can hold."""


def physics_difference(
    env_id: str, env_kwargs: dict[str, Any], other_id: str, other_kwargs: dict[str, Any]
) -> list[str]:
    """The ``settings()`` entries in which two envs differ, leaving out what only the observation
    (:data:`OBSERVATION_SETTINGS`), the action map (:data:`ACTION_MAP_SETTINGS`) or the rescored energy
    weight depend on: an empty list means that the same fields make the same episodes and metrics in both
    (e.g. ``ThickeningControl-v2``, its stress-only sibling and ``ThickeningControl-v1``), so that one's
    constant-field baseline serves the other's policies and controllers. One entry is not a setting:
    ``field_direction_action``, whether the action chooses the field's direction (``FieldVector`` ids),
    since such a baseline's constant fields include directions a magnitude policy cannot play. Trained
    runs ignore a ``reward`` entry (the baseline is rescored with their reward); controllers do not (their
    tuned point depends on it). A surrogate env's model is compared by its kind and the digest of its file
    (``settings()["surrogate"]``), not by the path it was named by (``model=PATH`` and the default name
    the shipped file alike), and the simulator-only arguments it ignores (``settings()["ignored"]``) are
    no physics of it."""

    def physics(env_name: str, kwargs: dict[str, Any]) -> dict[str, Any]:
        env = make_env(env_name, {**kwargs, "progress": False})
        try:
            settings = env.unwrapped.settings()  # type: ignore[attr-defined]
            # whether the action sets the field's direction: a vector env's constant fields include
            # directions a magnitude env's policies cannot choose
            settings["field_direction_action"] = bool(getattr(env.unwrapped, "vector_field", False))
        finally:
            env.close()
        for name in OBSERVATION_SETTINGS + ACTION_MAP_SETTINGS:
            settings.pop(name, None)
        settings["reward"] = {k: v for k, v in settings["reward"].items() if k != "energy_weight"}
        settings.pop("ignored", None)
        surrogate = settings.get("surrogate")
        if isinstance(surrogate, dict) and surrogate.get("digest"):  # a file: its contents, not its name
            settings["surrogate"] = {k: v for k, v in surrogate.items() if k != "model"}
        return settings

    ours, theirs = physics(env_id, env_kwargs), physics(other_id, other_kwargs)
    return sorted(k for k in set(ours) | set(theirs) if ours.get(k) != theirs.get(k))


def check_same_states(
    keys: dict[Path, str], pareto: dict[str, Any], configs: dict[Path, dict[str, Any]]
) -> None:
    """Exit 2 unless every run plays the start states of the baseline (the same library key).

    A different key means other start states: other env arguments that shape them (volume fraction,
    particle number, ...), or states regenerated since by other simulator physics; comparing returns on
    them with the baseline's would not be "on the same states"."""
    baseline = pareto.get("library_key")
    differing = {run: key for run, key in keys.items() if key != baseline}
    if not differing:
        return
    run, key = next(iter(differing.items()))
    arguments = configs.get(run, {}).get("env_kwargs")
    message = (
        f"RUN_DIRS: {run} plays the start states of library {key}, the --baseline those of library "
        f"{baseline} ({len(differing)} of {len(keys)} runs differ): the env arguments (the run's "
        f"{arguments!r}, the baseline's {pareto.get('env_kwargs')!r}) or the simulator physics that made "
        "the states differ; make the baseline again with agents.open_loop for these runs"
    )
    usage_error(PROG, message)


def load_controller(
    folder: Path,
    pareto: dict[str, Any],
    split: str,
    indices: list[int],
    reward: Any,
    repeats: int = 1,
    schedules: ScheduleSet | None = None,
) -> tuple[str, dict[str, Any]]:
    """The tuned controller of an ``agents.controllers`` folder as ``(row name, record)``, its returns
    rescored with ``reward``; exit 2 unless it was played in the baseline's env on the same start states
    and schedules (split, library, indices; ``schedules``: a schedules file's digest, None for the split's
    own) and tuned for ``reward``'s energy weight (the tuned point depends on it)."""
    summary_file = folder / "controller.json"
    made_by = owner(PROG, folder, "--controllers")
    if made_by is not None and made_by != "agents.controllers":
        usage_error(PROG, f"--controllers: {folder} was made by {made_by}, not agents.controllers")
    if not summary_file.is_file():
        usage_error(PROG, f"--controllers: {folder} holds no controller.json (an agents.controllers output)")
    summary = read_json(summary_file)
    record_file = folder / "points" / f"{summary['label']}.json"
    if not record_file.is_file():
        usage_error(PROG, f"--controllers: {record_file} is missing (rerun the agents.controllers command)")
    if mismatch(schedules, summary.get("schedules")):
        usage_error(
            PROG,
            mismatch_message(
                "--controllers", folder, schedules, summary.get("schedules"), "agents.controllers"
            ),
        )
    record = read_json(record_file)
    absent = missing(record["episodes"], indices, repeats)
    problems = []
    if (summary["env_id"], summary["env_kwargs"]) != (pareto["env_id"], pareto["env_kwargs"]):
        differing = physics_difference(
            summary["env_id"], summary["env_kwargs"], pareto["env_id"], pareto["env_kwargs"]
        )
        if differing:
            problems.append(
                f"env {summary['env_id']} (the baseline's: {pareto['env_id']}; they differ in "
                f"{', '.join(differing)})"
            )
    if summary["split"] != split:
        problems.append(f"split {summary['split']} (evaluated: {split})")
    if summary.get("library_key") != pareto.get("library_key"):
        problems.append(f"start-state library {summary.get('library_key')} ({pareto.get('library_key')})")
    if absent:
        problems.append(
            f"(state, realisation) {absent[:4]}{' ...' if len(absent) > 4 else ''} missing (needed: states "
            f"{indices}, realisations 0-{repeats - 1}; rerun its agents.controllers command with --repeats "
            f"{repeats})"
        )
    if problems:
        usage_error(PROG, f"--controllers: {folder} was played on other episodes: " + "; ".join(problems))
    tuned_weight = summary.get("energy_weight", reward.energy_weight)
    if tuned_weight != reward.energy_weight:
        usage_error(
            PROG,
            f"--controllers: {folder} was tuned for energy_weight {tuned_weight:g}, the evaluated reward has "
            f"{reward.energy_weight:g}; rerun its agents.controllers command with --env-kwargs "
            f"'{{\"energy_weight\": {reward.energy_weight:g}}}' (it rescores the stored points and re-picks)",
        )
    params = ", ".join(f"{k} {v:g}" for k, v in summary["tuned_params"].items())
    record = {**record, "episodes": select(record["episodes"], indices, repeats)}
    # A controller played in another id than the baseline's (same physics, other observation or action
    # map) names it, so that the same controller on two ids gives two rows one can tell apart.
    where = (
        "" if summary["env_id"] == pareto["env_id"] else f" on {summary['env_id'].removeprefix('dipenv/')}"
    )
    tuned_on = summary["tune_split"]
    if summary.get("tune_schedules"):  # agents.controllers --tune-schedules
        tuned_on = f"{summary['tune_schedules'].get('file')} ({tuned_on} start states)"
    name = f"{summary['controller']}{where} ({params}; tuned on {tuned_on})"
    return name, rescore(record, reward)


def check_play_env(play_env: str, play_kwargs: dict[str, Any], trained: dict[Path, dict[str, Any]]) -> None:
    """Exit 2 unless ``play_env`` exists and every run's training env has its observation and action
    spaces (a policy reads the one and writes the other; nothing else of the env has to agree)."""
    try:
        target = make_env(play_env, {**play_kwargs, "progress": False})
    except Exception as exc:  # an unknown id or a bad argument, in Gymnasium's or the env's words
        usage_error(PROG, f"--play-env {play_env}: cannot be made ({exc})")
    spaces = (target.observation_space, target.action_space)
    target.close()
    made: dict[tuple[str, str], tuple[Any, Any]] = {}
    for run, config in trained.items():
        key = (config["env_id"], json.dumps(config["env_kwargs"], sort_keys=True))
        if key not in made:
            source = make_env(config["env_id"], {**config["env_kwargs"], "progress": False})
            made[key] = (source.observation_space, source.action_space)
            source.close()
        if made[key] != spaces:
            usage_error(
                PROG,
                f"--play-env {play_env}: {run} was trained on {config['env_id']} with observation space "
                f"{made[key][0]} and action space {made[key][1]}; {play_env} has {spaces[0]} and {spaces[1]}",
            )


LOCATION_KEYS = ("run", "model")
"""Keys of a played run's identity that say where its files lie, not what they hold (the model's and the
statistics' SHA-256 say that): left out when stored episodes are matched, so that an evaluation committed
in one checkout resumes in another, or after its run folder was moved."""


def same_play(stored: Any, wanted: dict[str, Any]) -> bool:
    """Whether a stored per-run ``identity`` is that of ``wanted`` up to :data:`LOCATION_KEYS`."""
    if not isinstance(stored, dict):
        return False

    def content(identity: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in identity.items() if k not in LOCATION_KEYS}

    return content(stored) == content(wanted)


def evaluate_run(payload: dict[str, Any]) -> dict[str, Any]:
    """Episodes of one trained run on the given start states (a task; cached in ``payload['path']``)."""
    import torch

    torch.set_num_threads(1)
    path = Path(payload["path"])
    if path.exists():
        old = read_json(path)
        if same_play(old.get("identity"), payload["identity"]):
            return dict(old)
    run = Path(payload["run"])
    config = yaml.safe_load((run / "config.yml").read_text())
    model_file, stats_file = Path(payload["model_file"]), Path(payload["stats_file"])
    normalize = payload.get("normalize", stats_file.exists())
    if normalize and not stats_file.exists():  # main() refuses this first; raw observations are meaningless
        raise FileNotFoundError(f"{run} was trained with VecNormalize, but {stats_file} is missing")
    policy = trained_policy(
        config["algo"], model_file, stats_file if normalize else None, not payload.get("stochastic", False)
    )
    env_id = payload.get("env_id", config["env_id"])  # --play-env: another env than the training one
    env = make_env(env_id, {**payload.get("env_kwargs", config["env_kwargs"]), "progress": False})
    # The episodes played so far are kept in a partial file beside ``path`` after each one, so an
    # interrupted evaluation resumes at the next episode (each episode is a function of its start state,
    # realisation and the torch seed set below, not of the episodes before it).
    partial = path.with_name(path.stem + ".partial.json")
    done: dict[tuple[int, int], dict[str, Any]] = {}
    if partial.exists():
        old = read_json(partial)
        if same_play(old.get("identity"), payload["identity"]):
            done = {(int(e["index"]), int(e["realisation"])): e for e in old["episodes"]}
    episodes = []
    scheduled = payload.get("schedules")  # a schedules file's episodes (agents.schedules), or None
    for index in payload["indices"]:
        for realisation in range(payload.get("repeats", 1)):
            if (index, realisation) not in done:
                # the stochastic policy's samples: reproducible per episode (start state, or the entry of
                # a schedules file) and realisation
                torch.manual_seed(index + 100_003 * realisation)
                if scheduled is None:
                    trace = run_episode(env, policy, payload["split"], index, realisation=realisation)
                    done[(index, realisation)] = {**trace.summary(), "trace": trace.to_dict()}
                else:
                    done[(index, realisation)] = play(
                        env, policy, payload["split"], scheduled[index], realisation
                    )
                write_json(partial, {"identity": payload["identity"], "episodes": list(done.values())})
            episodes.append(done[(index, realisation)])
    key = env.unwrapped.library().key  # type: ignore[attr-defined]
    env.close()
    record = {
        "identity": payload["identity"],
        "run": str(run),
        "seed": config["seed"],
        "algo": config["algo"],
        "env_id": config["env_id"],
        "library_key": key,
        "episodes": episodes,
    }
    write_json(path, record)
    partial.unlink(missing_ok=True)
    return record


def _scores(records: list[dict[str, Any]], key: str) -> np.ndarray:
    """The ``(training seeds, start states)`` matrix of an episode metric (each state's realisations
    averaged); where an episode failed (NaN), the per-seed averages over the finite episodes instead (a
    vector: seeds as runs of one task)."""
    matrix = np.array([per_state(r["episodes"], key)[1] for r in records])
    if matrix.size and np.all(np.isfinite(matrix)):
        return matrix
    return np.array([np.nanmean(row) if np.isfinite(row).any() else np.nan for row in matrix])


THICKENING_METRICS = (
    ("time_above_cap", "time_above_cap"),
    ("excess_viscosity", "excess_viscosity"),
    ("energy_mean", "energy_mean"),
)
"""Whole-episode metrics of the thickening-control environments (:mod:`agents.rollout`), reported where
the episodes carry them."""


TARGET_METRICS = ("energy_mean", "excess_viscosity")
"""The per-state metrics a row keeps (``row["states"]``) for :func:`agents.comparison.energy_target`."""


def _metrics(episodes: list[dict[str, Any]]) -> tuple[tuple[str, str], ...]:
    base = (("eta", "eta_second_half"), ("energy", "energy_second_half"), ("return", "return"))
    if episodes and all("excess_viscosity" in e for e in episodes):
        return base + THICKENING_METRICS
    return base


def _state_means(scores: np.ndarray) -> list[float]:
    """Per start state, the mean over training seeds of a ``(seeds, states)`` matrix from :func:`_scores`
    (empty where :func:`_scores` fell back to per-seed averages: the states cannot be paired)."""
    return scores.mean(axis=0).tolist() if scores.ndim == 2 else []


def aggregate_policy(name: str, records: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean and IQM with 95% stratified-bootstrap intervals over training seeds (runs) and start states
    (tasks) (:mod:`agents.statistics`); ``per_seed`` holds each seed's average over the states."""
    metrics = _metrics([e for r in records for e in r["episodes"]])
    per_seed = {
        metric: [float(np.nanmean(per_state(r["episodes"], key)[1])) for r in records]
        for metric, key in metrics
    }
    return {
        "name": name,
        "samples": f"{len(records)} training seeds",
        "failures": sum(bool(e["failed"]) for r in records for e in r["episodes"]),
        **{metric: interval_estimates(_scores(records, key)) for metric, key in metrics},
        "per_seed": per_seed,
        "returns": _scores(records, "return").tolist(),
        "eta_states": _state_means(_scores(records, "eta_second_half")),
        "states": {m: _state_means(_scores(records, key)) for m, key in metrics if m in TARGET_METRICS},
        "episode_noise": within_state_sd([e for r in records for e in r["episodes"]], "return"),
    }


def aggregate_baseline(name: str, record: dict[str, Any], indices: list[int]) -> dict[str, Any]:
    """A constant field or a controller (deterministic given the state): mean and IQM with their 95%
    bootstrap intervals over the start states (each state's realisations averaged first)."""
    episodes = [e for e in record["episodes"] if e["index"] in indices]
    states = len({e["index"] for e in episodes})
    repeats = len(episodes) // max(states, 1)
    samples = f"{states} start states" + (f" x {repeats} realisations" if repeats > 1 else "")
    means = {metric: per_state(episodes, key)[1] for metric, key in _metrics(episodes)}
    return {
        "name": name,
        "samples": samples,
        "failures": sum(bool(e["failed"]) for e in episodes),
        **{metric: interval_estimates(values.tolist()) for metric, values in means.items()},
        "returns": [means["return"].tolist()],
        "eta_states": means["eta"].tolist(),
        "states": {m: values.tolist() for m, values in means.items() if m in TARGET_METRICS},
        "per_seed": {metric: [float(np.nanmean(values))] for metric, values in means.items()},
        "episode_noise": within_state_sd(episodes, "return"),
    }


def format_interval(mean: float, low: float, high: float, spec: str) -> str:
    """``mean [low, high]`` in the format ``spec``; the mean alone where there is no interval (NaN)."""
    if math.isnan(low):
        return format(mean, spec)
    return f"{mean:{spec}} [{low:{spec}}, {high:{spec}}]"


def format_table(rows: list[dict[str, Any]]) -> str:
    def cell(s: dict[str, float], digits: int = 3) -> str:
        return format_interval(s["mean"], s["ci_low"], s["ci_high"], f".{digits}f")

    thickening = bool(rows) and all("excess_viscosity" in r for r in rows)
    extra_head = (
        " time above cap | excess eta_r over cap | field energy, whole episode |" if thickening else ""
    )

    def iqm(s: dict[str, float], digits: int = 3) -> str:
        return format_interval(s["iqm"], s["iqm_ci_low"], s["iqm_ci_high"], f".{digits}f")

    lines = [
        "| policy | samples | eta_r, 2nd half: mean [95% CI] | IQM [95% CI] | field energy <1/Mn> | return "
        "| IQM return [95% CI] | failures |" + extra_head,
        "|---|---|---|---|---|---|---|---|" + ("---|---|---|" if thickening else ""),
    ]
    for r in rows:
        iqm_eta, iqm_ret = iqm(r["eta"]), iqm(r["return"], 2)
        extra = ""
        if thickening:
            above, excess = cell(r["time_above_cap"], 2), cell(r["excess_viscosity"])
            extra = f" {above} | {excess} | {cell(r['energy_mean'])} |"
        lines.append(
            f"| {r['name']} | {r['samples']} | {cell(r['eta'])} | {iqm_eta} | {cell(r['energy'])} | "
            f"{cell(r['return'], 2)} | {iqm_ret} | {r['failures']} |" + extra
        )
    return "\n".join(lines)


def verdicts(
    rows: list[dict[str, Any]],
    front: list[tuple[float, float]],
    records: list[list[dict[str, Any]]],
    best: dict[str, Any],
    front_states: tuple[list[float], list[list[float]]],
) -> list[dict[str, Any]]:
    """Per policy row (with its runs' records): position against the front, per-seed gaps, the gap to the
    front paired per state (``front_states``: the front points' energies and per-state ``eta_r``,
    :func:`agents.comparison.paired_front_gap`), return against the best constant field's row
    ``best`` on the same states (the per-seed gap, and rliable's probability of improvement over the
    states), variation."""
    out = []
    for row, runs in zip(rows, records, strict=True):
        eta, energy = row["eta"], row["energy"]
        where = position(front, energy["mean"], eta["mean"], eta["ci_low"], eta["ci_high"])
        gaps = [
            e - front_eta(front, en)
            for e, en in zip(row["per_seed"]["eta"], row["per_seed"]["energy"], strict=True)
            if math.isfinite(e) and math.isfinite(en)
        ]
        out.append(
            {
                "name": row["name"],
                "energy": energy["mean"],
                "eta": eta["mean"],
                **where,
                "seeds_below_front": sum(g < 0 for g in gaps),
                "seeds": len(gaps),
                **paired_front_gap(*front_states, row["eta_states"], energy["mean"]),
                **return_gap(row["per_seed"]["return"], best["return"]["mean"]),
                **state_gap(row, best),
                **_improvement(row, best),
                **action_variation([e for r in runs for e in r["episodes"]]),
                **_target(row, best),
            }
        )
    return out


def _target(row: dict[str, Any], best: dict[str, Any]) -> dict[str, Any]:
    """Issue 21's energy target against the best constant (:func:`agents.comparison.energy_target`), for
    rows of the thickening-control envs (those that keep the per-state energy and excess); else nothing."""
    mine, theirs = row.get("states", {}), best.get("states", {})
    if not all(m in mine and m in theirs for m in TARGET_METRICS):
        return {}
    return energy_target(
        mine["energy_mean"], mine["excess_viscosity"], theirs["energy_mean"], theirs["excess_viscosity"]
    )


def _paired_returns(row: dict[str, Any], best: dict[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """The ``(seeds, states)`` returns of ``row`` and of the best constant, or None where they cannot be
    paired state by state (other states, or a failed episode's NaN)."""
    x, y = np.asarray(row["returns"], dtype=float), np.asarray(best["returns"], dtype=float)
    if x.ndim != 2 or x.shape[1] != y.shape[1] or not (np.isfinite(x).all() and np.isfinite(y).all()):
        return None
    return x, y


def state_gap(row: dict[str, Any], best: dict[str, Any]) -> dict[str, Any]:
    """The return minus the best constant field's, paired state by state: per start state the row's
    return (averaged over its seeds and realisations) minus the constant's (averaged over its
    realisations); the mean over the states with its 95% bootstrap interval over them, and the number of
    states where the row is higher. This is the test that resolves a controller (one "seed") against the
    constant; NaN where an episode failed."""
    paired = _paired_returns(row, best)
    if paired is None:
        nan = math.nan
        return {"state_gap": nan, "state_gap_low": nan, "state_gap_high": nan, "states_above": 0, "states": 0}
    x, y = paired
    gaps = x.mean(axis=0) - y.mean(axis=0)
    stats = interval_estimates(gaps.tolist())
    return {
        "state_gap": stats["mean"],
        "state_gap_low": stats["ci_low"],
        "state_gap_high": stats["ci_high"],
        "states_above": int(np.sum(gaps > 0)),
        "states": int(gaps.size),
    }


def _improvement(row: dict[str, Any], best: dict[str, Any]) -> dict[str, float]:
    """rliable's ``P(policy return > best constant's)`` with its bootstrap interval, state by state (the
    policy's seeds against the constant's one run per state); NaN when the episodes failed."""
    paired = _paired_returns(row, best)
    if paired is None:
        return {"improvement": math.nan, "improvement_low": math.nan, "improvement_high": math.nan}
    p = probability_of_improvement(*paired)
    return {"improvement": p["probability"], "improvement_low": p["ci_low"], "improvement_high": p["ci_high"]}


def format_verdicts(items: list[dict[str, Any]]) -> str:
    lines = [
        "| policy | field energy | eta_r | front eta_r at that energy | eta_r - front "
        "| front energy for that eta_r | seeds below the front | action std (2nd half) | field off "
        "| Mn used (10-90%) | verdict | return - best constant [95% CI] | seeds above it | return verdict "
        "| return - best constant, paired per state [95% CI] | states above it "
        "| P(return > best constant) [95% CI] | eta_r - front, paired per state [95% CI] "
        "| states below the front | verdict, paired per state |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for v in items:
        gap = format_interval(v["return_gap"], v["return_gap_low"], v["return_gap_high"], "+.2f")
        improvement = format_interval(v["improvement"], v["improvement_low"], v["improvement_high"], ".2f")
        paired = format_interval(v["state_gap"], v["state_gap_low"], v["state_gap_high"], "+.2f")
        states = f"{v['states_above']}/{v['states']}"
        front_gap = format_interval(v["front_gap"], v["front_gap_low"], v["front_gap_high"], "+.3f")
        below = f"{v['states_below_front']}/{v['front_states']}"
        lines.append(
            f"| {v['name']} | {v['energy']:.3f} | {v['eta']:.3f} | {v['front_eta']:.3f} | "
            f"{v['eta_minus_front']:+.3f} | {v['front_energy']:.3f} | "
            f"{v['seeds_below_front']}/{v['seeds']} | {v['action_std']:.3f} | {100 * v['off_share']:.0f}% | "
            f"{v['mason_p10']:.2g}-{v['mason_p90']:.2g} | {v['verdict']} | {gap} | "
            f"{v['seeds_above']}/{v['seeds']} | {v['return_verdict']} | {paired} | {states} | "
            f"{improvement} | {front_gap} | {below} | {v['paired_verdict']} |"
        )
    targets = [v for v in items if "target_verdict" in v]
    if targets:
        lines += [
            "",
            "Field energy against the best constant field, paired per state (the target: at least "
            f"{100 * ENERGY_SAVING_TARGET:.0f}% less whole-episode field energy at equal or lower excess "
            "eta_r over the cap; agents.comparison.energy_target):",
            "",
            "| policy | field energy saved [95% CI] | energy verdict | excess eta_r - best constant [95% CI] "
            "| states with less excess | excess verdict | target |",
            "|---|---|---|---|---|---|---|",
        ]
        for v in targets:
            saved = format_interval(
                100 * v["energy_saved"], 100 * v["energy_saved_low"], 100 * v["energy_saved_high"], ".0f"
            )
            excess = format_interval(v["excess_gap"], v["excess_gap_low"], v["excess_gap_high"], "+.3f")
            lines.append(
                f"| {v['name']} | {saved} % | {v['energy_verdict']} | {excess} | "
                f"{v['states_less_excess']}/{v['target_states']} | {v['excess_verdict']} | "
                f"{v['target_verdict']} |"
            )
    return "\n".join(lines)


def plot_traces(curves: list[tuple[str, dict[str, Any]]], path: Path) -> None:
    """Field (Mn; off drawn above the top) and eta_r against strain for one start state; for the
    thickening-control environments (traces with a shear rate) against time, with the shear rate on top
    and the cap drawn on the eta_r panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    thickening = bool(curves) and all(trace.get("shear_rate") for _, trace in curves)
    rows = 3 if thickening else 2
    fig, axes = plt.subplots(rows, 1, figsize=(6.5, 2.5 * rows), sharex=True)
    ax_rate = axes[0] if thickening else None
    ax_mn, ax_eta = axes[-2], axes[-1]
    for name, trace in curves:
        x = np.asarray(trace["time"] if thickening else trace["strain"])
        mn = np.array([float(m) for m in trace["mason_number"]])
        shown = np.where(np.isfinite(mn), mn, 100.0)
        ax_mn.step(x, shown, where="pre", label=name)
        ax_eta.plot(x, trace["eta_r"], "-", label=name)
    if ax_rate is not None:
        _, first = curves[0]
        ax_rate.step(first["time"], first["shear_rate"], where="pre", color="0.3")
        ax_rate.set_yscale("log")
        ax_rate.set_ylabel("shear rate (gammadot_ref)")
        cap = float(first.get("eta_cap", math.nan))
        if math.isfinite(cap):
            ax_eta.axhline(cap, color="0.3", ls="--", lw=1, label=f"eta_cap = {cap:g}")
    ax_mn.set_yscale("log")
    ax_mn.set_ylabel("Mn_ref (100 = off)" if thickening else "Mn (100 = off)")
    ax_eta.set_ylabel("eta_r (interval average)")
    ax_eta.set_xlabel(
        "time since the episode start (1/gammadot_ref)" if thickening else "strain since the episode start"
    )
    if ax_rate is not None and math.isfinite(float(curves[0][1].get("eta_cap", math.nan))):
        ax_eta.add_artist(ax_eta.legend(handles=ax_eta.get_lines()[-1:], fontsize=7))  # the cap, inside
    # the policies' legend below the last panel, where it hides no curve (long controller names)
    ax_eta.legend(
        handles=ax_mn.get_lines(), fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.22), frameon=False
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def plot_thickening_front(constants: list[dict[str, Any]], others: list[dict[str, Any]], out: Path) -> None:
    """``thickening_front.png``: the excess ``eta_r`` over the cap against the field energy (whole
    episodes) of every constant field, their front (no other constant has both less), and the controllers
    and policies placed on it, with their 95% intervals. Also ``thickening_front.json``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def point(row: dict[str, Any]) -> dict[str, Any]:
        return {
            "name": row["name"],
            "energy": row["energy_mean"]["mean"],
            "excess": row["excess_viscosity"]["mean"],
            "excess_low": row["excess_viscosity"]["ci_low"],
            "excess_high": row["excess_viscosity"]["ci_high"],
        }

    fixed, placed = [point(r) for r in constants], [point(r) for r in others]
    for p in fixed:
        p["front"] = not any(
            o["energy"] <= p["energy"]
            and o["excess"] <= p["excess"]
            and o != p
            and (o["energy"] < p["energy"] or o["excess"] < p["excess"])
            for o in fixed
        )
    write_json(out / "thickening_front.json", {"constant_fields": fixed, "controllers_and_policies": placed})
    floor = min([p["energy"] for p in fixed + placed if p["energy"] > 0] + [1e-2]) / 3
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for group, style, colour in ((fixed, "o", "0.5"), (placed, "s", None)):
        for p in group:
            low = p["excess"] - p["excess_low"] if math.isfinite(p["excess_low"]) else 0.0
            high = p["excess_high"] - p["excess"] if math.isfinite(p["excess_high"]) else 0.0
            ax.errorbar(
                [max(p["energy"], floor)],
                [p["excess"]],
                yerr=[[low], [high]],
                fmt=style,
                color=colour,
                label=p["name"] if group is placed else None,
            )
            if group is fixed:
                ax.annotate(
                    p["name"],
                    (max(p["energy"], floor), p["excess"]),
                    fontsize=6,
                    xytext=(3, 3),
                    textcoords="offset points",
                )
    front = sorted((max(p["energy"], floor), p["excess"]) for p in fixed if p["front"])
    if front:
        ax.plot(*zip(*front, strict=True), "-", color="0.2", label="front of the constant fields")
    ax.set_xscale("log")
    ax.set_xlabel(f"field energy <eps E0^2> (eta gammadot_ref; off plotted at {floor:.2g})")
    ax.set_ylabel("excess eta_r over the cap, time average")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.14), frameon=False)  # hides no point
    fig.tight_layout()
    save_figure(fig, out / "thickening_front.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


TRAINING_RETURNS_CSV = "training_returns.csv"
"""A run's learning curve as text (columns ``steps,ep_rew_mean``; :func:`write_training_returns`): what a
committed run keeps instead of its TensorBoard logs."""


def tensorboard_returns(run: Path) -> tuple[np.ndarray, np.ndarray]:
    """SB3's ``rollout/ep_rew_mean`` against environment steps from the run's TensorBoard logs
    ``run/tb/*/events.out.tfevents.*`` (all of them, in name order: a resumed run has several, and a later
    log's value at a step replaces an earlier one's)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    points: dict[int, float] = {}
    for events in sorted(run.glob("tb/*/events.out.tfevents.*")):
        accumulator = EventAccumulator(str(events), size_guidance={"scalars": 0})
        accumulator.Reload()
        if "rollout/ep_rew_mean" in accumulator.Tags()["scalars"]:
            points.update({e.step: e.value for e in accumulator.Scalars("rollout/ep_rew_mean")})
    steps = np.array(sorted(points), dtype=float)
    return steps, np.array([points[int(s)] for s in steps])


def training_returns(run: Path) -> tuple[np.ndarray, np.ndarray]:
    """SB3's ``rollout/ep_rew_mean`` (mean return of the last 100 training episodes, sampled actions)
    against environment steps: from ``run/training_returns.csv`` where it exists (a committed run), else
    from the run's TensorBoard logs (:func:`tensorboard_returns`)."""
    table = run / TRAINING_RETURNS_CSV
    if not table.exists():
        return tensorboard_returns(run)
    lines = table.read_text().splitlines()
    if not lines or lines[0].strip() != "steps,ep_rew_mean":
        raise ValueError(f"{table}: expected the header 'steps,ep_rew_mean'")
    rows = [line.split(",") for line in lines[1:] if line.strip()]
    return np.array([float(s) for s, _ in rows]), np.array([float(r) for _, r in rows])


def write_training_returns(run: Path, path: Path | None = None) -> Path:
    """Write the run's TensorBoard learning curve (:func:`tensorboard_returns`) as ``steps,ep_rew_mean``
    text to ``path`` (default ``run/training_returns.csv``), each value written exactly (``repr``), so
    that :func:`training_returns` reads back the same arrays; returns the path. Raises
    ``FileNotFoundError`` if the run has no TensorBoard logs."""
    if not any(run.glob("tb/*/events.out.tfevents.*")):
        raise FileNotFoundError(f"{run}: no TensorBoard logs (tb/*/events.out.tfevents.*)")
    steps, returns = tensorboard_returns(run)
    path = run / TRAINING_RETURNS_CSV if path is None else path
    lines = ["steps,ep_rew_mean", *(f"{int(s)},{float(r)!r}" for s, r in zip(steps, returns, strict=True))]
    write_text_atomic(path, "\n".join(lines) + "\n")
    return path


def plot_learning(groups: dict[str, list[Path]], baselines: list[tuple[str, float]], path: Path) -> None:
    """Return against environment steps, per run: validation episodes with the policy's mean action
    (markers; the EvalCallback's log) and training episodes with sampled actions (thin line)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (name, runs) in enumerate(groups.items()):
        colour = colours[k % len(colours)]
        for j, run in enumerate(runs):
            log = run / "eval" / "evaluations.npz"
            if log.exists():
                data = read_evaluation_log(log)  # main() refuses a bad one before any episode
                steps, returns = data["timesteps"], data["results"].mean(axis=1)
                label = f"{name}: validation, mean action" if j == 0 else None
                ax.plot(steps, returns, "o-", ms=3, lw=1, color=colour, label=label)
            steps, returns = training_returns(run)
            if steps.size:
                label = f"{name}: training, sampled actions" if j == 0 else None
                ax.plot(steps, returns, "-", lw=0.8, alpha=0.5, color=colour, label=label)
    for (name, value), style in zip(baselines, ("--", ":", "-.", (0, (5, 1)), (0, (1, 3))), strict=False):
        ax.axhline(value, color="0.3", ls=style, lw=1, label=name)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def learning_lines(
    test_rows: list[dict[str, Any]], validation: list[tuple[str, float]]
) -> list[tuple[str, float]]:
    """The constant fields' returns drawn across ``learning.png``: those of ``--validation-baseline`` on
    the validation states, where the curves' validation returns are measured (like with like); without
    one, the table's rows (no field, best constant) on the test states, labelled as not on the curves'
    states (a test-state line above or below a validation curve says nothing about the policy)."""
    if validation:
        return list(validation)
    return [
        (f"{r['name']}, test states (not the curves' validation states)", float(r["return"]["mean"]))
        for r in test_rows
    ]


def compact_table(rows: list[dict[str, Any]]) -> str:
    """The table printed on the terminal: per row the policy, ``eta_r`` (second half) and the return with
    their 95% intervals, and the field energy (the full table, with the IQMs, samples, failures and the
    thickening metrics, is ``table.md``)."""

    def cell(stats: dict[str, float], spec: str) -> str:
        return format_interval(stats["mean"], stats["ci_low"], stats["ci_high"], spec)

    lines = [
        "| policy | eta_r, 2nd half [95% CI] | field energy | return [95% CI] |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {r['name']} | {cell(r['eta'], '.3f')} | {r['energy']['mean']:.3f} | {cell(r['return'], '.2f')} |"
        for r in rows
    ]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("runs", nargs="*", type=Path, help="run folders or folders of them")
    parser.add_argument(
        "--controllers",
        nargs="+",
        type=Path,
        default=[],
        help="agents.controllers output folders: each tuned controller is a row",
    )
    parser.add_argument("--baseline", required=True, type=Path, help="an agents.open_loop output folder")
    parser.add_argument("--out", required=True, type=directory)
    parser.add_argument(
        "--validation-baseline",
        type=Path,
        default=None,
        help="an agents.open_loop folder on the validation states: its no-field and best constant returns "
        "join learning.png, where the runs' validation returns are on those states (default: none)",
    )
    parser.add_argument(
        "--split",
        default=None,
        choices=("train", "validation", "test", "fresh"),
        help="start-state split (default: the baseline's)",
    )
    parser.add_argument(
        "--episodes", type=integer_at_least(1), default=None, help="first N states (default: the baseline's)"
    )
    parser.add_argument(
        "--repeats",
        type=integer_at_least(1),
        default=1,
        help="realisations per start state (dipenv.realisations; default 1: the stored states), >= 1",
    )
    parser.add_argument(
        "--policy-repeats",
        type=integer_at_least(1),
        default=None,
        help="realisations per start state for each trained run (default: --repeats); the training seeds "
        "already resample an episode's chaotic noise, so 1 with 5 seeds costs a quarter of 4, >= 1",
    )
    parser.add_argument(
        "--model",
        choices=("final", "best"),
        default="final",
        help="the policy at the end of training, or the checkpoint with the best validation return",
    )
    parser.add_argument(
        "--actions",
        choices=("mean", "sampled", "both"),
        default="mean",
        help="play each policy's mean action, its sampled actions (seeded per start state), or both",
    )
    parser.add_argument(
        "--play-kwargs",
        default=None,
        metavar="JSON",
        help="JSON object of env arguments that replace the trained runs' own when they are played, e.g. "
        "'{\"simulation_overrides\": {}}' for policies trained with a coarser step (default: none)",
    )
    parser.add_argument(
        "--play-env",
        default=None,
        metavar="ID",
        help="play the trained runs in this env id instead of the one they were trained on, with its default "
        "arguments (plus --play-kwargs), e.g. dipenv/ThickeningControl-v2 for policies trained on "
        "dipenv/ThickeningControlSurrogate-v0; the observation and action spaces must be the same",
    )
    parser.add_argument(
        "--schedules",
        type=Path,
        default=None,
        metavar="FILE",
        help="play on this JSON list of shear-rate schedules (agents.schedules) instead of the split's own; "
        "--baseline and --controllers must have been made with the same file (checked by digest)",
    )
    parser.add_argument("--workers", type=integer_at_least(1), default=1, help="local worker processes, >= 1")
    parser.add_argument("--scheduler", type=scheduler_address, default=None, help="Dask scheduler address")
    add_folder_options(parser)
    return parser


PATH_KEYS = ("runs", "baseline", "controllers", "validation_baseline")
"""Identity keys that hold paths (compared by the files they name: :func:`agents.folders.compare_paths`;
``runs`` also by the policies the folders hold, so that a run folder copied elsewhere is the same run)."""


def folder_identity(
    args: argparse.Namespace,
    split: str,
    policy_repeats: int,
    play: dict[str, Any],
    schedules: ScheduleSet | None = None,
) -> dict:
    """The identity in an evaluation folder's manifest (the module docstring)."""

    def spelled(path: Path | None) -> str | None:
        return None if path is None else os.path.normpath(str(path))

    return {
        "runs": [spelled(p) for p in args.runs],
        "baseline": spelled(args.baseline),
        "controllers": [spelled(p) for p in args.controllers],
        "validation_baseline": spelled(args.validation_baseline),
        "split": split,
        "episodes": args.episodes,
        "repeats": args.repeats,
        "policy_repeats": policy_repeats,
        "model": args.model,
        "actions": args.actions,
        "play_kwargs": play,
        **({"play_env": args.play_env} if args.play_env is not None else {}),
        **({"schedules": schedules.digest} if schedules is not None else {}),
    }


LEGACY = ("table.md", "verdict.md", "results.json")
"""Files of an evaluation folder written before manifests (``runs/`` alone is no marker)."""


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = build_parser().parse_args(argv)
    if not args.runs and not args.controllers:
        usage_error(
            PROG, "give RUN_DIRS (trained runs) or --controllers (agents.controllers folders), or both"
        )
    output_directory(PROG, args.out)
    pareto, point_files = read_baseline(args.baseline)
    marker = "eval/evaluations.npz" if args.model == "best" else "model.zip"
    groups = find_runs(args.runs, marker) if args.runs else {}
    play_kwargs = json_object(PROG, "--play-kwargs", args.play_kwargs) if args.play_kwargs else {}
    if play_kwargs and not args.runs:
        usage_error(PROG, "--play-kwargs applies to trained runs (RUN_DIRS); none were given")
    trained = {run: read_run_config(run) for runs in groups.values() for run in runs}
    if args.play_env is not None and not args.runs:
        usage_error(PROG, "--play-env applies to trained runs (RUN_DIRS); none were given")
    # What each run plays with: its training env and arguments overridden by --play-kwargs, or (--play-env)
    # another env with its defaults overridden by --play-kwargs.
    configs = {
        run: (
            {**config, "env_id": args.play_env, "env_kwargs": dict(play_kwargs)}
            if args.play_env is not None
            else {**config, "env_kwargs": {**config["env_kwargs"], **play_kwargs}}
        )
        for run, config in trained.items()
    }
    if args.play_env is not None:
        check_play_env(args.play_env, play_kwargs, trained)
    elif play_kwargs:  # a bad argument is named now, not as a traceback from the first episode
        tried: set[tuple[str, str]] = set()  # the seeds of a study share their env: make it once
        for run, config in configs.items():
            key = (config["env_id"], json.dumps(config["env_kwargs"], sort_keys=True))
            if key in tried:
                continue
            tried.add(key)
            try:
                make_env(config["env_id"], {**config["env_kwargs"], "progress": False}).close()
            except Exception as exc:
                usage_error(
                    PROG, f"--play-kwargs: {config['env_id']} refuses {play_kwargs!r} for {run}: {exc}"
                )
    for run, run_config in configs.items():
        env_id = run_config["env_id"]
        if (env_id, run_config["env_kwargs"]) == (pareto["env_id"], pareto["env_kwargs"]):
            continue
        # The baseline is rescored with the runs' reward below, so only the physics has to match.
        differing = [
            name
            for name in physics_difference(
                env_id, run_config["env_kwargs"], pareto["env_id"], pareto["env_kwargs"]
            )
            if name != "reward"
        ]
        if differing:
            usage_error(
                PROG,
                f"RUN_DIRS: {run} was trained on {env_id}"
                + (f" and is played with {run_config['env_kwargs']!r}" if play_kwargs else "")
                + f", the --baseline is for {pareto['env_id']}, and they differ in {', '.join(differing)} "
                "(beyond what the policy observes and the map from actions to fields"
                + ("" if play_kwargs else "; --play-kwargs plays a run with other env arguments")
                + ")",
            )
    split = args.split or pareto["split"]
    if split != pareto["split"]:
        usage_error(
            PROG,
            f"--split {split}: the --baseline {args.baseline} was played on the {pareto['split']} start "
            f"states, and policies are compared with it on the same states (omit --split, or give "
            f"--split {pareto['split']}, or make a baseline on the {split} states with agents.open_loop)",
        )
    library_keys = {run: start_state_library(run_config) for run, run_config in configs.items()}
    check_same_states(library_keys, pareto, configs)
    # The baseline's stored returns belong to the reward it was last scored with; rescore them with the
    # reward of the env the policies were trained in (the physics of a constant field does not depend on it).
    config = next(iter(configs.values())) if configs else pareto
    probe = make_env(config["env_id"], {**config["env_kwargs"], "progress": False})
    reward = probe.unwrapped.reward_function  # type: ignore[attr-defined]
    schedules: ScheduleSet | None = None
    if args.schedules is not None:
        schedules = load_schedules(PROG, args.schedules, probe.unwrapped, str(config["env_id"]), split)
    probe.close()
    if mismatch(schedules, pareto.get("schedules")):
        usage_error(
            PROG,
            mismatch_message(
                "--baseline", args.baseline, schedules, pareto.get("schedules"), "agents.open_loop"
            ),
        )
    try:
        points = [rescore(p, reward) for p in read_constant_points(point_files, args.baseline)]
    except (OSError, ValueError, KeyError, TypeError) as error:
        kind = type(error).__name__
        usage_error(PROG, f"--baseline {args.baseline}: a point file cannot be read ({kind}: {error})")
    validation = (
        validation_lines(args.validation_baseline, pareto, reward) if args.validation_baseline else []
    )
    baseline_indices = sorted({e["index"] for e in points[0]["episodes"]})
    if args.episodes is not None and not 1 <= args.episodes <= len(baseline_indices):
        usage_error(PROG, f"--episodes must be in [1, {len(baseline_indices)}] (the baseline's states)")
    indices = baseline_indices if args.episodes is None else baseline_indices[: args.episodes]
    absent = [p["label"] for p in points if missing(p["episodes"], indices, 1)]
    if absent:
        usage_error(PROG, f"--baseline {args.baseline}: the points {', '.join(absent)} lack states {indices}")
    # The front and the choice of the best constant use the realisations each point holds (up to K); the
    # rows (no field, the best constant) must hold all K.
    points = [{**p, "episodes": select(p["episodes"], indices, args.repeats)} for p in points]
    summary = summarise_points(points)
    # One policy per training group and way of acting: its mean action and/or its sampled actions.
    sampling = {"mean": [False], "sampled": [True], "both": [False, True]}[args.actions]
    best_suffix = ", best validation" if args.model == "best" else ""
    policies = {
        f"{name}{best_suffix}{', sampled' if sampled else ''}": (runs, sampled)
        for name, runs in groups.items()
        for sampled in sampling
    }
    policy_repeats = args.repeats if args.policy_repeats is None else args.policy_repeats
    scheduled = episodes_payload(schedules)
    payloads, owners = [], []
    for name, (runs, sampled) in policies.items():
        for run in runs:
            label = f"{run.parent.name}_{run.name}".replace("/", "_")
            label += ("_best" if args.model == "best" else "") + ("_stochastic" if sampled else "")
            model_file, stats_file = model_files(run, args.model)
            normalize = statistics_file(configs[run], stats_file) is not None
            if normalize and not stats_file.exists():
                usage_error(
                    PROG,
                    f"RUN_DIRS: {run} was trained with observation normalisation (VecNormalize), but its "
                    f"statistics {stats_file} are missing; its policy cannot be played on raw "
                    "observations (restore the file, or evaluate another --model)",
                )
            check_loadable(run, configs[run]["algo"], model_file, stats_file, normalize)
            payloads.append(
                {
                    "run": str(run),
                    "model_file": str(model_file),
                    "stats_file": str(stats_file),
                    "normalize": normalize,
                    "stochastic": sampled,
                    "split": split,
                    "indices": indices,
                    "repeats": policy_repeats,
                    "env_id": configs[run]["env_id"],
                    "env_kwargs": configs[run]["env_kwargs"],
                    "path": str(args.out / "runs" / f"{label}.json"),
                    **({"schedules": scheduled} if scheduled is not None else {}),
                    "identity": {
                        "run": str(run.resolve()),
                        "split": split,
                        "indices": indices,
                        "model": str(model_file.resolve()),
                        "model_sha256": file_digest(model_file),
                        "stats_sha256": file_digest(stats_file) if normalize else None,
                        "library_key": library_keys[run],  # start states regenerated: played again
                        **({"stochastic": True} if sampled else {}),
                        **({"repeats": policy_repeats} if policy_repeats > 1 else {}),
                        **({"play_kwargs": play_kwargs} if play_kwargs else {}),
                        **({"play_env": args.play_env} if args.play_env is not None else {}),
                        **({"schedules": schedules.digest} if schedules is not None else {}),
                    },
                }
            )
            owners.append(name)
    # learning.png reads every run's validation log: a bad one is refused now, not after the episodes
    for runs in groups.values():
        for run in runs:
            if (run / "eval" / "evaluations.npz").exists():
                checked_evaluation_log(run / "eval" / "evaluations.npz")
    controllers = [
        load_controller(folder, pareto, split, indices, reward, args.repeats, schedules)
        for folder in args.controllers
    ]
    claim_out(
        PROG,
        args.out,
        "agents.evaluate",
        folder_identity(args, split, policy_repeats, play_kwargs, schedules),
        argv=command_line("agents.evaluate", argv),
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, LEGACY, "agents.evaluate"),
        compare=compare_paths(PATH_KEYS, content_keys=("runs",)),
    )
    write_command(args.out, "agents.evaluate", argv)
    (args.out / "runs").mkdir(parents=True, exist_ok=True)
    if schedules is not None:
        write_json(args.out / "schedules.json", schedules.resolved())
    if payloads:
        compile_notice(args.scheduler)
    records = run_tasks(evaluate_run, payloads, workers=args.workers, scheduler=args.scheduler)
    check_same_states({Path(r["run"]): r["library_key"] for r in records}, pareto, configs)
    by_label = {p["label"]: p for p in points}
    best = max(summary, key=lambda r: r["return"])  # for this reward
    best_name = f"best constant ({best['label']})"
    short = [
        label
        for label in ("off", best["label"])
        if label in by_label and missing(by_label[label]["episodes"], indices, args.repeats)
    ]
    if short:
        masons = ",".join("off" if label == "off" else label.removeprefix("Mn") for label in short)
        usage_error(
            PROG,
            f"--repeats {args.repeats}: the --baseline's rows {', '.join(short)} (no field, best constant) "
            f"lack realisations; rerun its agents.open_loop command with --mason {masons} --repeats "
            f"{args.repeats} (stored episodes are reused)",
        )
    baselines = [("no field", by_label.get("off")), (best_name, by_label.get(best["label"]))]
    baselines += controllers
    baseline_rows = [
        aggregate_baseline(name, record, indices) for name, record in baselines if record is not None
    ]
    played = {name: [r for r, o in zip(records, owners, strict=True) if o == name] for name in policies}
    policy_rows = [aggregate_policy(name, own) for name, own in played.items()]
    rows = baseline_rows + policy_rows
    table = format_table(rows)
    realisations = f" x {args.repeats} realisations each (averaged per state)" if args.repeats > 1 else ""
    if policies and policy_repeats != args.repeats:
        realisations += f" ({policy_repeats} per state and training seed for the policies)"
    played_ids = sorted({str(configs[run]["env_id"]) for runs, _ in policies.values() for run in runs})
    envs = (
        f" (the constant fields' env; the policies' {', '.join(played_ids)}, checked to differ from it only "
        "in the observation, the action map or the reward)"
        if any(env_id != pareto["env_id"] for env_id in played_ids)
        else ""
    )
    played_on = (
        f"{len(indices)} {split} start states"
        if schedules is None
        else f"{len(indices)} episodes of the {schedules.label()}, from start states of the {split} split "
        "(each episode is a 'state' below: the rows are paired per entry of the file)"
    )
    header = (
        f"Environment {pareto['env_id']}{envs}, {played_on}{realisations}; eta_r and "
        "energy are time averages over the second half of each episode (energy in eta gammadot per unit "
        "strain); intervals "
        "are 95% stratified-bootstrap intervals (rliable) over training seeds and states (policies) or over "
        "start states (constant fields, controllers). Returns for "
        f"the reward of the policies' env: target eta_r {reward.target_viscosity:g}, energy weight "
        f"{reward.energy_weight:g} (the baseline rescored with it)."
        + (
            f" The trained policies are played with the env arguments {json.dumps(play_kwargs)} over "
            "those they were trained with."
            if play_kwargs and policies
            else ""
        )
        + "\n\n"
    )
    write_text_atomic(args.out / "table.md", header + table + "\n")
    best_row = next(r for r in baseline_rows if r["name"] == best_name)
    controller_rows = baseline_rows[len(baseline_rows) - len(controllers) :]
    members = sorted((r for r in summary if r["pareto"]), key=lambda r: float(r["energy"]))
    front_states = (
        [float(r["energy"]) for r in members],
        [per_state(by_label[r["label"]]["episodes"], "eta_second_half")[1].tolist() for r in members],
    )
    items = verdicts(
        controller_rows + policy_rows,
        front_points(summary),
        [[record] for _, record in controllers] + list(played.values()),
        best_row,
        front_states,
    )
    verdict = (
        "Against the constant-field front (Pareto points joined linearly, held flat beyond the last; "
        "agents.comparison); action statistics over the second half of the episodes; the return against "
        f"the {best_row['name']}'s on the same states, paired per seed (a controller is one seed) and "
        "paired per state (each state's seeds and realisations averaged).\n\n" + format_verdicts(items)
    )
    write_text_atomic(args.out / "verdict.md", verdict + "\n")
    write_json(
        args.out / "results.json",
        {
            "split": split,
            "indices": indices,
            **({"schedules": schedules.summary()} if schedules is not None else {}),
            "rows": rows,
            "verdicts": items,
        },
    )
    markers = [
        {
            "name": r["name"],
            "eta": r["eta"]["mean"],
            "eta_ci_low": r["eta"]["ci_low"],
            "eta_ci_high": r["eta"]["ci_high"],
            "energy": r["energy"]["mean"],
        }
        for r in policy_rows
    ]
    for p in markers:
        for k in ("eta_ci_low", "eta_ci_high"):
            if math.isnan(p[k]):
                p[k] = p["eta"]
    plot_pareto(summary, args.out / "pareto.png", markers)
    if all("excess_viscosity" in r for r in rows):
        constants = [aggregate_baseline(p["label"], p, indices) for p in points]
        plot_thickening_front(constants, controller_rows + policy_rows, args.out)
    first = indices[0]
    curves = []
    for name, record in baselines:
        if record is not None:
            curves += [
                (name, e["trace"])
                for e in record["episodes"]
                if e["index"] == first and realisation_of(e) == 0
            ]
    for name, own in played.items():
        curves += [
            (f"{name} seed {own[0]['seed']}", e["trace"])
            for e in own[0]["episodes"]
            if e["index"] == first and realisation_of(e) == 0
        ]
    plot_traces(curves, args.out / "traces.png")
    plot_learning(groups, learning_lines(baseline_rows[:2], validation), args.out / "learning.png")
    realisations = f" x {args.repeats} realisations" if args.repeats > 1 else ""
    thickening = ", thickening metrics" if all("excess_viscosity" in r for r in rows) else ""
    print(
        f"{pareto['env_id']}, {played_on}{realisations}; returns for target "
        f"{reward.target_viscosity:g}, energy weight {reward.energy_weight:g}\n\n"
        + compact_table(rows)
        + f"\n\nThe full table (IQMs, failures{thickening}): {args.out / 'table.md'}; each policy against "
        f"the constant-field front and the best constant: {args.out / 'verdict.md'}"
    )
    return {"rows": rows, "verdicts": items}


if __name__ == "__main__":
    main()
