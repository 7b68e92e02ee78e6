"""Tune and play the viscosity-tracking baselines, and play trained policies on the same episodes (issue 44).

    python -m agents.tracking --env dipenv/ViscosityTracking-v0 --out DIR
        [--controller map_feedforward angle_pi constant] [--grid [KIND.]NAME=V1,V2 ...]
        [--run RUN_DIR ...] [--play-env ID]
        [--tune-split validation] [--tune-episodes N] [--tune-realisations R]
        [--split test] [--episodes N] [--realisations R] [--final-evaluation] [--schedules FILE]
        [--env-kwargs JSON] [--workers W] [--scheduler ADDRESS] [--no-progress] [--resume | --overwrite]

Rows, all played on the same episodes of ``--split`` (start state ``k``, rate schedule ``k`` and target
``k``, realisations ``0 .. R-1``; ``env.reset(seed=0, options={"split", "index"[, "realisation"]})`` as
:func:`agents.tracking_controllers.play_episodes`):

* ``--controller KIND ...``: the baselines of :mod:`agents.tracking_controllers`. Each point of its grid (the
  Cartesian product of ``--grid``'s values; defaults :data:`agents.tracking_rows.DEFAULT_GRIDS`) plays the
  first ``--tune-episodes`` states of ``--tune-split`` (validation or test, never fresh); the point with the
  highest mean return (each state's realisations averaged first) is the tuned controller, played on
  ``--split``. ``--grid NAME=V1,V2`` sets NAME for every listed controller that takes it, ``--grid
  KIND.NAME=V1,V2`` for one (:data:`agents.tracking_rows.PARAMETERS`; a constant's directions by the direction
  map's names, ``y x z ext comp yz``; ``mason_ref=inf``: no field, one point whatever the direction).
* ``--run RUN_DIR ...``: trained ``agents.train`` runs (a run folder with ``model.zip``, or a folder of
  seeds): each argument is one row, its seeds its samples, each played with its mean action and the
  ``VecNormalize`` statistics it was trained with, in its training env (same physics, reward and
  start states as ``--env``: checked) or, with ``--play-env ID``, in that env with its default arguments
  (a run trained on a surrogate id played in the simulator; the spaces must be the same).

**The surrogate fidelity.** ``--env dipenv/ViscosityTrackingSurrogate-v0``
(:data:`dipenv.TRACKING_SURROGATE_IDS`; default model the shipped ``dipenv/data/tracking_surrogate_v0.npz``,
``--env-kwargs '{"model": PATH}'`` another) plays the same command over the fitted model, at no simulator
cost: the same start indices, rate schedules and targets (the simulator env's fixed splits), so that
``scripts/tracking_fidelity.py`` can compare the two folders point by point. Realisation ``k`` of an episode
is one sample of the model: ``k = 0`` the env's draws at seed 0, ``k >= 1`` a generator of its own per
``(split, state, k)`` (:class:`dipenv.surrogate.env.ThickeningControlSurrogateEnv`, Realisations), so
``--realisations R`` averages ``R`` independent samples. Realisation 0 of every state starts from the same
stored frame and meets the same draws (common random numbers across the states, not independent ones). A
trained run plays there as in the simulator (its training env, e.g. a run trained on the surrogate; or
``--play-env``).

``--split fresh`` needs ``--final-evaluation`` (the fresh split is held out,
``docs/thickening_control.md#the-fresh-split``). ``--schedules FILE`` plays the rows on rate schedules of
your own (:mod:`agents.schedules`; start states of ``--split``, each episode's target the split's target of
its start state); the tuning stays on ``--tune-split``'s own episodes.

Output (``--out``): ``manifest.json`` (the run-folder protocol, :mod:`agents.folders`), ``command.txt``,
``tuning/<point>.json`` and ``tuning.csv`` (every grid point on the tuning split; ``chosen`` marks the tuned
ones), ``points/<label>.json`` (each row's episodes on ``--split``: return, ``mean_abs_error``,
``mean_energy`` and the per-interval traces; a policy has one file per seed), written after every episode,
so an interrupted command resumes at the next one; ``table.md``, ``results.json``
(:mod:`agents.tracking_summary`: mean ``|eta_r - target|``, return and energy with 95% bootstrap
intervals; each row's gaps to the best constant and to the map feed-forward, paired per episode, and the
error reduction against the issue's 30% / 15%) and ``traces.png`` (eta_r and the target on the first
episode).

The folder's identity (``manifest.json`` ``params``): the env id and ``--env-kwargs`` (the energy weight too:
the tuning depends on it), the start-state library key (None on the surrogate, which has no library; its
``surrogate`` entry instead: the model's kind and the SHA-256 of its file, so that a refitted model at the
same path is another folder), the tuning split and states, the split and states, the digest of
``--schedules``, and one entry per row: a controller's grid (the feed-forward's with the direction map's
digest), a policy's algorithm, played env and the SHA-256 of each seed's model and statistics. A rerun
continues (finished episodes are reused); one that adds rows (another controller, a trained run) extends the
folder, and the table then holds every row of the folder; one that changes the env, the episodes or a row
already there is refused (exit 2, naming what differs) unless ``--overwrite`` deletes the previous run. The
realisations are no part of it: a rerun with more adds the missing episodes. Bad input exits 2 naming the
argument and its valid range, before the folder is claimed.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from agents.folders import (
    add_folder_options,
    claim_out,
    command_line,
    normalise,
    write_command,
    write_text_atomic,
)
from agents.open_loop import write_json
from agents.rollout import library_key
from agents.schedules import ScheduleSet, episode_count, episodes_payload, load_schedules, prepare_states
from agents.tasks import run_tasks
from agents.tracking_controllers import TRACKING_CONTROLLERS
from agents.tracking_rows import (
    IDENTITY_KEYS,
    build_controller,
    describe,
    find_runs,
    grid_points,
    map_digest,
    mean_return,
    parse_grids,
    play_point,
    point_label,
    run_play,
    tuning_table,
)
from agents.tracking_summary import write_summary
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
from sim.runs import RunFolderError, read_manifest

PROG = "python -m agents.tracking"
COMMAND = "agents.tracking"

ROW_PREFIXES = ("controller_", "run_")
"""Identity keys of rows (``controller_<kind>``, ``run_<label>``): a rerun may add rows; a row in both the
stored and the requested identity must be the same."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument(
        "--env", default="dipenv/ViscosityTracking-v0", help="a ViscosityTracking id, or its surrogate's"
    )
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of env arguments")
    parser.add_argument(
        "--controller", nargs="+", default=[], choices=TRACKING_CONTROLLERS, help="baselines to tune and play"
    )
    parser.add_argument(
        "--grid", nargs="+", action="extend", default=[], help="[KIND.]NAME=V1,V2 (default: DEFAULT_GRIDS)"
    )
    parser.add_argument(
        "--run", nargs="+", type=Path, default=[], help="agents.train run folders, or folders of seeds"
    )
    parser.add_argument(
        "--play-env", default=None, metavar="ID", help="play the runs in this id, with its default arguments"
    )
    parser.add_argument("--tune-split", default="validation", choices=("validation", "test"))
    parser.add_argument("--tune-episodes", type=integer_at_least(1), default=None, help="default: the split")
    parser.add_argument("--tune-realisations", type=integer_at_least(1), default=1, help="per state, >= 1")
    parser.add_argument("--split", default="test", choices=("validation", "test", "fresh"))
    parser.add_argument("--episodes", type=integer_at_least(1), default=None, help="default: the split")
    parser.add_argument("--realisations", type=integer_at_least(1), default=1, help="per state, >= 1")
    parser.add_argument("--final-evaluation", action="store_true", help="allows --split fresh (held out)")
    parser.add_argument(
        "--schedules", type=Path, default=None, metavar="FILE", help="rate schedules of your own for --split"
    )
    parser.add_argument("--out", required=True, type=directory)
    parser.add_argument("--workers", type=integer_at_least(1), default=1, help="local worker processes, >= 1")
    parser.add_argument("--scheduler", type=scheduler_address, default=None, help="Dask scheduler address")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_folder_options(parser)
    return parser


def surrogate_identity(settings: dict[str, Any]) -> dict[str, Any]:
    """``{"surrogate": {"kind", "digest"}}`` for a surrogate env's ``settings()`` (its model's kind and the
    SHA-256 of the model file, as ``agents.train`` records them in ``env_settings.surrogate``), ``{}`` for a
    simulator env (whose identity is unchanged). Not the model's path: ``--env-kwargs`` holds it where
    given, and the same file elsewhere plays the same episodes."""
    surrogate = settings.get("surrogate")
    if not isinstance(surrogate, dict):
        return {}
    return {"surrogate": {"kind": surrogate["kind"], "digest": surrogate["digest"]}}


def compare_rows(saved: Any, requested: Any) -> list[str]:
    """The identity keys that forbid continuing: any but a row's, and a row's that both hold and that
    differs (a rerun may add rows)."""
    a, b = normalise(saved), normalise(requested)
    return sorted(
        k
        for k in set(a) | set(b)
        if (not k.startswith(ROW_PREFIXES) or (k in a and k in b)) and a.get(k) != b.get(k)
    )


def check_arguments(args: argparse.Namespace) -> None:
    """Exit 2 for arguments that contradict each other (before anything is made)."""
    import dipenv

    ids = (*(i for i in dipenv.ENV_IDS if "ViscosityTracking" in i), *dipenv.TRACKING_SURROGATE_IDS)
    if args.env not in ids:
        usage_error(PROG, f"--env must be one of {', '.join(ids)}, got {args.env!r}")
    if not args.controller and not args.run:
        usage_error(
            PROG, "give --controller KIND ... (baselines) or --run RUN_DIR ... (trained runs), or both"
        )
    if len(set(args.controller)) < len(args.controller):
        usage_error(PROG, f"--controller lists a kind twice: {' '.join(args.controller)}")
    if args.play_env is not None and not args.run:
        usage_error(PROG, "--play-env applies to trained runs (--run); none were given")
    if args.split == "fresh" and not args.final_evaluation:
        usage_error(
            PROG,
            "--split fresh is held out for the final evaluation "
            "(docs/thickening_control.md#the-fresh-split): give --final-evaluation there only",
        )


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = build_parser().parse_args(argv)
    output_directory(PROG, args.out)
    check_arguments(args)
    env_kwargs = json_object(PROG, "--env-kwargs", args.env_kwargs)
    try:
        grids = parse_grids(args.controller, args.grid)
        points = {kind: grid_points(kind, grid) for kind, grid in grids.items()}
        for kind, kind_points in points.items():
            for params in kind_points:
                build_controller(kind, params)  # the values, checked before the env is made
    except ValueError as error:
        usage_error(PROG, str(error))
    env = checked_env(PROG, args.env, env_kwargs, progress=False)
    unwrapped: Any = env.unwrapped
    for kind in points:
        try:
            build_controller(kind, points[kind][0]).bind(env)
        except ValueError as error:
            usage_error(PROG, f"--controller {kind} on --env {args.env}: {error}")
    sizes = unwrapped.split_sizes
    counts = {}
    for option, split, count in (
        ("--tune-episodes", args.tune_split, args.tune_episodes),
        ("--episodes", args.split, args.episodes),
    ):
        n = sizes[split] if count is None else count
        if not 1 <= n <= sizes[split]:
            usage_error(
                PROG, f"{option} must be in [1, {sizes[split]}] (the {split} split's states), got {n}"
            )
        counts[option] = n
    schedules: ScheduleSet | None = None
    if args.schedules is not None:
        schedules = load_schedules(PROG, args.schedules, unwrapped, args.env, args.split)
        counts["--episodes"] = episode_count(PROG, schedules, args.episodes)
    try:
        runs = find_runs(args.run)
        played = {
            label: [run_play(r, args.play_env, args.env, env_kwargs) for r in rs]
            for label, (_, rs) in runs.items()
        }
    except ValueError as error:
        usage_error(PROG, str(error))
    key = library_key(unwrapped)
    settings = unwrapped.settings()
    identity: dict[str, Any] = {
        "env_id": args.env,
        "env_kwargs": env_kwargs,
        "library_key": key,
        **surrogate_identity(settings),
        "tune_split": args.tune_split,
        "tune_episodes": counts["--tune-episodes"],
        "split": args.split,
        "episodes": counts["--episodes"],
        **({"schedules": schedules.digest} if schedules is not None else {}),
    }
    for kind, grid in grids.items():
        extra = {"direction_map": map_digest()} if kind == "map_feedforward" else {}
        identity[f"controller_{kind}"] = {"grid": grid, **extra}
    for label, plays in played.items():
        seeds = {
            p["label"]: {"model_sha256": p["model_sha256"], "stats_sha256": p["stats_sha256"]} for p in plays
        }
        identity[f"run_{label}"] = {"algo": plays[0]["algo"], "env_id": plays[0]["env_id"], "runs": seeds}
    if not args.overwrite:  # the rows stored before join the identity: a rerun may add rows
        try:
            manifest = read_manifest(args.out) if args.out.is_dir() else None
        except RunFolderError as error:
            usage_error(PROG, str(error))
        if manifest is not None and manifest.command == COMMAND:
            stored = {k: v for k, v in manifest.params.items() if k.startswith(ROW_PREFIXES)}
            identity = {**stored, **identity}
    claim_out(
        PROG,
        args.out,
        COMMAND,
        identity,
        argv=command_line(COMMAND, argv),
        resume=args.resume,
        overwrite=args.overwrite,
        compare=compare_rows,
    )
    write_command(args.out, COMMAND, argv)
    for folder in ("tuning", "points"):
        (args.out / folder).mkdir(parents=True, exist_ok=True)
    progress = not args.no_progress
    if key is not None:  # the simulator's kernels (a surrogate env compiles nothing)
        compile_notice(args.scheduler)
    library = unwrapped.library() if key is not None else None  # a surrogate env has none: nothing to shear
    if points and library is not None:
        library.ensure([args.tune_split], progress=progress, count=counts["--tune-episodes"])
    if schedules is None:
        if library is not None:
            library.ensure([args.split], progress=progress, count=counts["--episodes"])
    else:
        write_json(args.out / "schedules.json", schedules.resolved())
        if library is not None:
            prepare_states(unwrapped, schedules, counts["--episodes"])
    env.close()
    scheduled = episodes_payload(schedules)

    def payload(meta: dict[str, Any], folder: str, **source: Any) -> dict[str, Any]:
        """A task: ``meta`` (stored in the record) played by ``source`` (a controller's kind and
        parameters, or a trained run's :func:`agents.tracking_rows.run_play`) on the tuning split's
        episodes (``folder`` tuning) or ``--split``'s (``points``)."""
        tuning = folder == "tuning"
        n = counts["--tune-episodes" if tuning else "--episodes"]
        split = args.tune_split if tuning else args.split
        env_id, kwargs = source.get("env_id", args.env), source.get("env_kwargs", env_kwargs)
        what = {k: v for k, v in source.items() if k in IDENTITY_KEYS}
        if source.get("controller") == "map_feedforward":
            what["direction_map"] = map_digest()
        if not tuning and schedules is not None:
            what["schedules"] = schedules.digest
        return {
            **source,
            "meta": meta,
            "env_id": env_id,
            "env_kwargs": kwargs,
            "split": split,
            "episodes": n,
            "realisations": args.tune_realisations if tuning else args.realisations,
            "final": args.final_evaluation,
            "progress": progress and args.workers == 1 and args.scheduler is None,  # bars in this process
            "path": str(args.out / folder / f"{meta['label']}.json"),
            **({"schedules": scheduled[:n]} if scheduled is not None and not tuning else {}),
            "identity": {
                "env_id": env_id,
                "env_kwargs": kwargs,
                "env_settings": settings,
                "library_key": key,
                "split": split,
                "episodes": n,
                **what,
            },
        }

    tuning = [
        payload(
            {"label": point_label(kind, p), "controller": kind, "params": p},
            "tuning",
            controller=kind,
            params=p,
        )
        for kind, kind_points in points.items()
        for p in kind_points
    ]
    tuned = run_tasks(
        play_point,
        tuning,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=progress and bool(tuning),
        description="tuning",
    )
    final = []
    if tuned:
        stored = args.out / "tuning.csv"
        text, best = tuning_table(tuned, stored.read_text() if stored.exists() else None)
        write_text_atomic(args.out / "tuning.csv", text)
        for kind, record in best.items():
            params = record["params"]
            meta = {
                "label": kind,
                "controller": kind,
                "params": params,
                "name": describe(kind, params),
                "tune_return": mean_return(record),
            }
            final.append(payload(meta, "points", controller=kind, params=params))
    for label, plays in played.items():
        for p in plays:
            meta = {"label": p["label"], "row": label, "run": p["run"], "seed": p["seed"], "algo": p["algo"]}
            final.append(payload(meta, "points", **p))
    run_tasks(
        play_point,
        final,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=progress,
        description="rows",
    )
    return write_summary(args.out, identity, args.realisations)


__all__ = ["COMMAND", "PROG", "build_parser", "compare_rows", "main", "surrogate_identity"]

if __name__ == "__main__":
    main()
