"""Command line of the simulator.

    python -m sim run --phi 0.40 --n-particles 200 --mason inf --strain 30 --seed 1 --out DIR [--json]
    python -m sim sweep --phi 0.15,0.30,0.45 --mason 0.1,1,10,inf --seeds 3 --out DIR [--workers 2]
    python -m sim sweep --spec sweep.yml --out DIR        (or --preset small)
    python -m sim figures DIR [--out FIGURES]
    python -m sim flow-curve --phi 0.45 --n-particles 100 --mason 1 --rates 0.1,0.3,1,3,10 \
                             --strain-per-rate 10 --out DIR [--down] [--seed S] [--quiet]
    python -m sim run ... --initial-state FILE[:FRAME] [--field-from-state] [--snapshot-every S]
                          [--trajectory-every S]
    python -m sim movie RUN [--out FILE.gif|.mp4] [--fps 10] [--every 1]

``run`` and ``sweep`` share one table of simulation options (:data:`SIMULATION_OPTIONS`); in ``sweep``
``--phi``, ``--n-particles``, ``--mason`` and ``--mechanism`` take comma lists (the sweep is their
cartesian product with ``--seeds``), the other options one value for every point.

Every command's ``--out`` follows the run-folder protocol (:mod:`sim.runs.folder`): ``manifest.json``
first; a rerun of the same command and parameters continues; ``--resume`` insists on a run to continue;
``--overwrite`` deletes the previous run; another command's folder, other parameters or a non-empty
folder without a manifest are refused. Flags must be spelled out (no parser takes a prefix of a flag).

Exit status 0 on success, 2 on bad input (``python -m sim <command>: error: ...`` after the command's
usage; the message names the flag and its valid range) and on an ``--out`` the command may not use or
continue (naming the folder, or the damaged file), 1 when a simulation fails (for ``sweep``: when any
point failed; the others still run, and ``error.json`` in the failed point's folder holds the
traceback), 130 when a run, sweep or flow curve is interrupted (Ctrl-C; the last checkpoint is kept:
rerun the same command to continue). With ``--json`` the last line on stdout is one JSON object
(``run``: ``result.json``; ``sweep``: ``sweep.json``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, NoReturn

from sim.config import (
    DEFAULT_MAX_DISPLACEMENT,
    DEFAULT_TIME_STEP,
    MAX_PARTICLES,
    MAX_SHEAR_RATE,
    MAX_STEPS,
    MECHANISMS,
    MIN_SHEAR_RATE,
    NEAR_FIELD_MODELS,
    SimulationConfig,
)
from sim.geometry.configurations import MAX_VOLUME_FRACTION, MIN_VOLUME_FRACTION
from sim.runs.tasks import MAX_SEEDS, parse_seeds

FLAGS = {
    "n_particles": "--n-particles",
    "volume_fraction": "--phi",
    "mason_number": "--mason",
    "field_direction": "--field-direction",
    "mechanism": "--mechanism",
    "shear_rate": "--shear-rate",
    "strain": "--strain",
    "seed": "--seed",
    "time_step": "--dt",
    "transient_strain": "--transient",
    "max_displacement": "--max-displacement",
    "near_field_cutoff": "--near-field-cutoff",
    "near_field": "--near-field",
    "ewald_accuracy": "--ewald-accuracy",
    "out_dir": "--out",
    "resume": "--resume",
    "overwrite": "--overwrite",
    "rates": "--rates",
    "strain_per_rate": "--strain-per-rate",
    "state": "--initial-state",
    "initial_state": "--initial-state",
    "field_from_state": "--field-from-state",
    "snapshot_every": "--snapshot-every",
    "trajectory_every": "--trajectory-every",
}
"""The flag of each ``SimulationConfig`` field (and ``run_simulation`` argument) the command line sets."""


def _field_pattern(field: str) -> re.Pattern[str]:
    """Where ``field`` names a parameter in a message.

    A name with an underscore is an identifier wherever it stands as a whole word; a plain word
    (``strain``, ``seed``, ...) only at the start of the message or as ``name=value``, so that the same
    word in prose ("the strain already reached") is left alone.
    """
    word = re.escape(field)
    if "_" in field:
        return re.compile(rf"(?<![\w-]){word}(?!\w)")
    return re.compile(rf"^{word}(?![\w-])|(?<![\w-]){word}(?==)")


_FLAG_PATTERNS = [(_field_pattern(field), flag) for field, flag in FLAGS.items()]


def with_flags(message: str) -> str:
    """``message`` with the parameter names of ``SimulationConfig`` replaced by this command's flags."""
    for pattern, flag in _FLAG_PATTERNS:
        message = pattern.sub(flag, message)
    return message


class _Parser(argparse.ArgumentParser):
    """Argument parser whose errors print its usage and ``<prog>: error: <message>``, exit status 2.

    A flag must be spelled out: argparse's prefix matching (``allow_abbrev``) is off, so that
    ``flow-curve --strain 5`` is refused instead of being taken as ``--strain-per-rate 5``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _mason_number(text: str) -> float:
    """``--mason``: a number in (0, inf] or ``inf``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number in (0, inf] or 'inf', got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be in (0, inf], got {text!r}")
    return value


def _shear_rate(text: str) -> float:
    """``--shear-rate``: 0 (quiescent, field only) or a number in [MIN_SHEAR_RATE, MAX_SHEAR_RATE], in
    units of the reference rate."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (value == 0.0 or MIN_SHEAR_RATE <= value <= MAX_SHEAR_RATE):
        raise argparse.ArgumentTypeError(
            f"must be 0 (quiescent) or in [{MIN_SHEAR_RATE:g}, {MAX_SHEAR_RATE:g}] (units of the reference "
            f"rate gammadot_ref), got {text!r}"
        )
    return value


def _direction(text: str) -> tuple[float, float, float]:
    """``--field-direction``: three comma-separated finite numbers, not all zero."""
    try:
        values = tuple(float(p) for p in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or all(v == 0 for v in values):
        raise argparse.ArgumentTypeError(
            f"must be three comma-separated finite numbers, not all zero (e.g. 0,1,0), got {text!r}"
        )
    return (values[0], values[1], values[2])


_KINDS: dict[Any, str] = {float: "a number", int: "an integer"}


def _comma_list(
    convert: Callable[[str], Any], choices: Sequence[str] | None = None
) -> Callable[[str], list[Any]]:
    """The ``sweep`` type of a listable option: ``a,b,c`` -> [convert(a), ...], distinct values."""

    def parse(text: str) -> list[Any]:
        values: list[Any] = []
        for part in (p.strip() for p in text.split(",")):
            if choices is not None and part not in choices:
                raise argparse.ArgumentTypeError(
                    f"invalid choice: {part!r} (choose from {', '.join(choices)})"
                )
            try:
                value = convert(part)
            except argparse.ArgumentTypeError as exc:
                raise argparse.ArgumentTypeError(f"{exc} (in the list {text!r})") from None
            except ValueError:
                kind = _KINDS.get(convert, "a value")
                raise argparse.ArgumentTypeError(
                    f"must be a comma list of {kind.split(' ', 1)[1]}s, got {part!r} in {text!r}"
                ) from None
            if value in values:
                raise argparse.ArgumentTypeError(f"{part!r} is listed twice in {text!r}")
            values.append(value)
        return values

    parse.__name__ = f"list of {getattr(convert, '__name__', 'values')}"
    return parse


def _seed_list(text: str) -> list[int]:
    """``--seeds``: a count (``3`` = seeds 1, 2, 3), or a list and ranges (``1,4``, ``0-4``, ``0,2,5-7``)."""
    text = text.strip()
    if text.isdigit():
        count = int(text)
        if not 1 <= count <= MAX_SEEDS:
            raise argparse.ArgumentTypeError(
                f"a count of seeds must be in [1, {MAX_SEEDS}] (3 = seeds 1, 2, 3), got {text!r}"
            )
        return list(range(1, count + 1))
    try:
        seeds = parse_seeds(text)
        listed = [seed for item in text.split(",") for seed in parse_seeds(item)]
    except ValueError as exc:
        if str(exc).startswith("at most"):
            raise argparse.ArgumentTypeError(str(exc)) from None
        raise argparse.ArgumentTypeError(
            "must be a count (3 = seeds 1, 2, 3), a list (1,4) or ranges (0-4, 0,2,5-7) of non-negative "
            f"integers, got {text!r}"
        ) from None
    twice = sorted({seed for seed in listed if listed.count(seed) > 1})
    if twice:  # as the other lists of a sweep: each value once
        raise argparse.ArgumentTypeError(
            f"lists seed {', '.join(str(seed) for seed in twice)} twice in {text!r} (each seed once)"
        )
    return seeds


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1 (``--workers``; also the benchmark's ``--steps``)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


def _directory(text: str) -> str:
    """``--out``: a folder's path; an empty one (which would mean the current folder) is refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"must name a directory, got {text!r}")
    return text


def check_output_directory(parser: argparse.ArgumentParser, flag: str, path: str | Path) -> Path:
    """Exit 2 naming ``flag`` unless ``path`` is a folder, or can be created as one, and can be written.

    Nothing is created: the nearest existing folder above ``path`` must be a writable folder. The one
    check of the output folders of ``sweep``, ``figures`` and ``flow-curve``."""
    out = Path(path)
    if not str(path).strip():
        parser.error(f"{flag} must name a directory, got {str(path)!r}")
    if out.exists() and not out.is_dir():
        parser.error(f"{flag} {out} exists and is not a directory")
    existing = next((p for p in (out, *out.absolute().parents) if p.exists()), None)
    if existing is None or not existing.is_dir():
        parser.error(f"{flag} {out} cannot be created: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        parser.error(f"{flag} {out} cannot be written: {existing} is read-only")
    return out


def output_error(parser: argparse.ArgumentParser, flag: str, exc: OSError) -> NoReturn:
    """Exit 2 for an ``OSError`` raised while writing into ``flag``'s folder, naming the file."""
    where = exc.filename if exc.filename is not None else "it"
    parser.error(f"{flag}: cannot write {where}: {exc.strerror or exc}")


def _scheduler(text: str) -> str:
    """``--scheduler``: a Dask scheduler address, ``tcp://HOST:PORT`` (or another ``protocol://`` form)."""
    if not re.fullmatch(r"[a-z][a-z0-9+.-]*://\S+", text):
        raise argparse.ArgumentTypeError(
            f"must be a Dask scheduler address like tcp://HOST:8786, got {text!r}"
        )
    return text


@dataclass(frozen=True)
class _Option:
    """One simulation option of ``run`` and ``sweep``.

    Attributes:
        flag: the flag.
        help: its help text (``%`` doubled, as argparse formats it).
        type: converts one value.
        default: the default (``sweep`` wraps it in a list when ``listable``).
        choices: allowed values.
        listable: in ``sweep``, the option takes a comma list of values (one point per value).
        nargs_zero: a switch (``store_true``).
    """

    flag: str
    help: str
    type: Callable[[str], Any] | None = None
    default: Any = None
    choices: tuple[str, ...] | None = None
    listable: bool = False
    nargs_zero: bool = False


SIMULATION_OPTIONS = (
    _Option(
        "--phi",
        f"volume fraction in [{MIN_VOLUME_FRACTION}, {MAX_VOLUME_FRACTION}] (default 0.40)",
        float,
        0.40,
        listable=True,
    ),
    _Option(
        "--n-particles", f"number of spheres, in [2, {MAX_PARTICLES}] (default 200)", int, 200, listable=True
    ),
    _Option(
        "--mason",
        "Mason number at the reference rate eta*gammadot_ref/(eps*E0^2) in (0, inf]; inf = no field, pure "
        "shear (default inf)",
        _mason_number,
        math.inf,
        listable=True,
    ),
    _Option(
        "--field-direction",
        "electric field direction x,y,z (normalised; default 0,1,0)",
        _direction,
        (0.0, 1.0, 0.0),
    ),
    _Option(
        "--mechanism",
        "dipolophoresis mechanism: dip (ICEP + DEP), icep, or dep alone (default dip)",
        str,
        "dip",
        choices=MECHANISMS,
        listable=True,
    ),
    _Option(
        "--shear-rate",
        f"shear rate in units of the reference rate gammadot_ref: 0 (quiescent, field only, needs a finite "
        f"--mason) or in [{MIN_SHEAR_RATE:g}, {MAX_SHEAR_RATE:g}]; --mason is the Mason number at the "
        "reference rate (default 1)",
        _shear_rate,
        1.0,
    ),
    _Option(
        "--strain",
        "run length, > 0: accumulated strain (time in units 1/gammadot_ref with --shear-rate 0); the run "
        "ends there exactly (with run --initial-state: counted from the file's strain) (default 30)",
        float,
        30.0,
    ),
    _Option(
        "--dt",
        f"largest time step (steps may adapt below it), in (0, 0.05]; --strain/--dt at most {MAX_STEPS:.0e} "
        f"(default {DEFAULT_TIME_STEP})",
        float,
        DEFAULT_TIME_STEP,
    ),
    _Option(
        "--max-displacement",
        "largest non-affine displacement per step as a fraction of the mean spacing, in (0, 0.05]; sets the "
        f"adaptive step (default {DEFAULT_MAX_DISPLACEMENT}, the paper's 0.4%%)",
        float,
        DEFAULT_MAX_DISPLACEMENT,
    ),
    _Option(
        "--near-field",
        "dipolophoresis of close pairs: exact two-sphere functions blended into the far field, or none "
        "(far-field kernels only) (default exact)",
        str,
        "exact",
        choices=NEAR_FIELD_MODELS,
    ),
    _Option(
        "--near-field-cutoff",
        "centre distance (units a) below which the exact near field replaces the far field, in (2.5, 10] "
        "and below half the box (default 4)",
        float,
        4.0,
    ),
    _Option(
        "--ewald-accuracy",
        "relative accuracy of the periodic far-field sums, in [1e-12, 1e-2] (default 1e-6)",
        float,
        1e-6,
    ),
    _Option(
        "--transient",
        "strain discarded before averaging, in [0, --strain) (default 10, or half of runs shorter than 20)",
        float,
        None,
    ),
    _Option(
        "--out",
        "output directory (created; must not be a file): the run's files, or one folder per sweep point "
        "and sweep.json; manifest.json names its owner (a rerun of the same command and parameters "
        "continues; anything else there is refused)",
        _directory,
    ),
    _Option(
        "--json",
        "print the result as one JSON object on the last line (run: result.json; sweep: sweep.json)",
        nargs_zero=True,
    ),
    _Option(
        "--quiet", "no progress bar and no compile notice (sweep: nor a line per point)", nargs_zero=True
    ),
)
"""The options ``run`` and ``sweep`` share, in the order of their help."""

LISTABLE = tuple(option.flag for option in SIMULATION_OPTIONS if option.listable)
"""Options that take comma lists in ``sweep``."""


def _add_simulation_options(parser: argparse.ArgumentParser, lists: bool) -> None:
    """Add :data:`SIMULATION_OPTIONS` to ``parser``; with ``lists`` the listable ones take comma lists."""
    for option in SIMULATION_OPTIONS:
        if option.nargs_zero:
            parser.add_argument(option.flag, action="store_true", help=option.help)
        elif lists and option.listable:
            convert = option.type or str
            parser.add_argument(
                option.flag,
                type=_comma_list(convert, option.choices),
                default=[option.default],
                metavar="LIST",
                help=option.help + "; a comma list: one point per value",
            )
        else:
            parser.add_argument(
                option.flag,
                type=option.type or str,
                default=option.default,
                choices=option.choices,
                help=option.help,
                required=option.flag == "--out" and not lists,
            )


def _add_run_arguments(run: argparse.ArgumentParser) -> None:
    """The flags of ``python -m sim run``."""
    _add_simulation_options(run, lists=False)
    run.add_argument("--seed", type=int, default=1, help="seed of the initial packing, >= 0 (default 1)")
    run.add_argument(
        "--initial-state",
        metavar="FILE",
        default=None,
        help="start from the configuration in FILE instead of a random packing: a run's checkpoint.npz, "
        "final_state.npz or snapshots/*.npz, or a GSD file (its last frame; FILE.gsd:K for frame K, "
        "negative from the end). Its positions, time and strain are taken (the run adds --strain to "
        "them; its transient counts from there); its N must be --n-particles and its box the one --phi "
        "and --n-particles give. Rerun and --resume with the same FILE",
    )
    run.add_argument(
        "--field-from-state",
        action="store_true",
        help="take the field (Mason number, direction) and the shear rate from --initial-state's file "
        "instead of --mason, --field-direction and --shear-rate",
    )
    run.add_argument(
        "--snapshot-every",
        type=float,
        default=None,
        metavar="S",
        help="keep the state at every multiple of S strain (time with --shear-rate 0) after the start as "
        "OUT/snapshots/strain_XXXX.npz (files --initial-state reads), S > 0, at most 1e5 of them",
    )
    run.add_argument(
        "--trajectory-every",
        type=float,
        default=None,
        metavar="S",
        help="write a frame at every multiple of S strain (time with --shear-rate 0) into OUT/trajectory.gsd "
        "(GSD, HOOMD schema: sheared box tilt xy = offset/L, diameter 2a, time/strain/field/rate in log/), "
        "S > 0, at most 1e5 frames; python -m sim movie OUT draws it",
    )
    _add_folder_arguments(
        run,
        "continue the run in OUT from its checkpoint (refused if OUT holds no run); only --strain may "
        "differ from that run (to extend it). A rerun of the same parameters continues without it",
    )


def _add_folder_arguments(parser: argparse.ArgumentParser, resume_help: str) -> None:
    """``--resume`` and ``--overwrite`` (mutually exclusive), the same in every command
    (:mod:`sim.runs.folder`)."""
    existing = parser.add_mutually_exclusive_group()
    existing.add_argument("--resume", action="store_true", help=resume_help)
    existing.add_argument(
        "--overwrite",
        action="store_true",
        help="delete the previous run in OUT (everything in it, whichever command made it) and start "
        "afresh; a folder that no command owns (no manifest.json) is never deleted",
    )


def preset_names() -> list[str]:
    """Names of the packaged sweep presets (``sim/presets/<name>.yml``)."""
    folder = resources.files("sim") / "presets"
    return sorted(p.name[: -len(".yml")] for p in folder.iterdir() if p.name.endswith(".yml"))


def _add_sweep_arguments(sweep: argparse.ArgumentParser) -> None:
    """The flags of ``python -m sim sweep``."""
    _add_simulation_options(sweep, lists=True)
    sweep.add_argument(
        "--seeds",
        type=_seed_list,
        default=[1],
        metavar="SEEDS",
        help="seeds of the initial packings: a count (3 = seeds 1, 2, 3), or a list and ranges (1,4 or "
        "0-4 or 0,2,5-7; one seed k alone: k-k) (default 1)",
    )
    sweep.add_argument(
        "--workers",
        type=positive_int,
        default=2,
        help="points at once in local worker processes, >= 1 (1: in this process) (default 2)",
    )
    sweep.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        metavar="ADDRESS",
        help="run the points on the Dask cluster whose scheduler is at ADDRESS (tcp://HOST:8786) instead of "
        "local processes; needs dask[distributed] and the same sim sources on every worker",
    )
    _add_folder_arguments(
        sweep,
        "insist on continuing the sweep in OUT (refused if OUT holds none); a rerun of the same sweep "
        "continues without it (it may add points and lengthen --strain)",
    )
    source = sweep.add_mutually_exclusive_group()
    source.add_argument(
        "--spec",
        metavar="FILE",
        help="YAML file whose keys are this command's flags without '--' (phi: [0.3, 0.45], n-particles: "
        "64, seeds: 2, ...); flags on the command line override it",
    )
    source.add_argument(
        "--preset",
        metavar="NAME",
        help="a packaged spec: small (2 cores, under an hour) or full (the paper's grid, for a cluster); "
        "flags on the command line override it",
    )


def build_parser() -> argparse.ArgumentParser:
    """Parser of ``python -m sim``; a parsed namespace carries ``parser``, the subcommand's own parser."""
    parser = _Parser(prog="python -m sim", description="Stokesian dynamics of sheared conductive spheres.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    run = sub.add_parser(
        "run",
        help="run one simulation and write its results to --out",
        description="Run one simulation and write its results to --out. Bad input exits with status 2.",
    )
    _add_run_arguments(run)
    run.set_defaults(parser=run)
    sweep = sub.add_parser(
        "sweep",
        help="run the cartesian product of comma lists of parameters, one folder per point, resumable",
        description=(
            "Run every combination of the comma lists given to "
            + ", ".join(LISTABLE)
            + " and --seeds into OUT/<point> (python -m sim run's options; the others hold for every "
            "point). A rerun skips finished points, resumes interrupted ones from their checkpoint, adds "
            "new points, extends the points to a longer --strain and reruns points whose sim sources "
            "changed; other shared options (or a shorter --strain) are refused unless --overwrite deletes "
            "the previous sweep. OUT/sweep.json lists the points and their status. Exit status: 0 all "
            "points finished, 1 some point failed (error.json in its folder; the others still ran), 2 bad "
            "input (or an OUT that holds something else), 130 interrupted (rerun to resume)."
        ),
    )
    _add_sweep_arguments(sweep)
    sweep.set_defaults(parser=sweep)
    figures = sub.add_parser(
        "figures",
        help="plot a sweep's results (eta_r, N1, N2, U_rms ratio, g(x, y), D_yy) into DIR/figures",
        description="Read every point's result.json in a sweep folder, average over seeds and draw the "
        "sweep's figures and figures/summary.csv.",
    )
    figures.add_argument("directory", metavar="DIR", help="a sweep folder (python -m sim sweep --out DIR)")
    figures.add_argument(
        "--out", type=_directory, default=None, help="folder of the figures (default DIR/figures)"
    )
    figures.add_argument("--quiet", action="store_true", help="no notes on stdout")
    figures.set_defaults(parser=figures)
    flow_curve = sub.add_parser(
        "flow-curve",
        help="a rheometer's rate sweep at fixed field: eta_r, shear stress, N1, N2 per shear rate",
        description="Hold each shear rate of --rates (units of the reference rate) for --strain-per-rate, "
        "each starting from the state the previous one left, and average over the second half of each "
        "hold; --down adds the way back. --mason is the Mason number at the reference rate, so the "
        "instantaneous Mn is rate x --mason. One curve per --mason value (in OUT/Mn<value>/ when there "
        "are several); OUT/flow_curve.csv and OUT/flow_curve.png hold them all. A rerun of the same "
        "command continues after the last finished hold; --overwrite deletes the previous run in OUT. "
        "Exit status: 0 done, 1 a curve failed, 2 bad input (or an OUT that holds something else), 130 "
        "interrupted (Ctrl-C: the finished holds are kept; rerun to continue).",
    )
    _add_flow_curve_arguments(flow_curve)
    flow_curve.set_defaults(parser=flow_curve)
    movie = sub.add_parser(
        "movie",
        help="draw a run's trajectory.gsd as a movie of the layers forming and melting (GIF or MP4)",
        description="Draw every --every-th frame of RUN/trajectory.gsd (python -m sim run ... "
        "--trajectory-every S) as a movie: a side view (layer axis up, against the flow) and the view "
        "along the field, spheres to scale coloured by their coordinate along the layer axis (nearest the "
        "field; y without one), the strain, Mason number and layer order in the title. Bad input exits "
        "with status 2.",
    )
    movie.add_argument("run", metavar="RUN", help="a run folder holding trajectory.gsd, or a GSD file")
    movie.add_argument(
        "--out",
        default=None,
        help="the movie file: .gif (Pillow) or .mp4 (needs ffmpeg) (default RUN/movie.gif)",
    )
    movie.add_argument(
        "--fps", type=int, default=10, help="frames per second, an integer in [1, 100] (default 10)"
    )
    movie.add_argument(
        "--every", type=int, default=1, help="draw every K-th frame, an integer >= 1 (default 1: all)"
    )
    movie.add_argument("--quiet", action="store_true", help="do not print the file written")
    movie.set_defaults(parser=movie)
    return parser


def _option(flag: str) -> _Option:
    """The entry of :data:`SIMULATION_OPTIONS` for ``flag``."""
    return next(option for option in SIMULATION_OPTIONS if option.flag == flag)


def _add_flow_curve_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of ``python -m sim flow-curve``: the suspension and numerics options of ``run`` (one
    value each, ``--mason`` a comma list), the rates, and the task options of ``sweep``."""
    from sim.runs.flow_curve import MIN_HOLD_STEPS

    helps = {
        "--dt": f"largest time step (steps may adapt below it), in (0, 0.05]; every hold must take at least "
        f"{MIN_HOLD_STEPS} and at most {MAX_STEPS:.0e} of them (default {DEFAULT_TIME_STEP})",
    }
    for flag in ("--phi", "--n-particles", "--field-direction", "--mechanism", "--dt", "--max-displacement",
                 "--near-field", "--near-field-cutoff", "--ewald-accuracy"):
        option = _option(flag)
        parser.add_argument(
            flag, type=option.type or str, default=option.default, choices=option.choices,
            help=helps.get(flag, option.help),
        )
    parser.add_argument(
        "--mason", type=_comma_list(_mason_number), default=[1.0], metavar="LIST",
        help="Mason number at the reference rate eta*gammadot_ref/(eps*E0^2) in (0, inf]; a comma list: "
        "one curve per field (default 1)",
    )
    parser.add_argument(
        "--rates", type=_comma_list(_positive_rate), default=[0.1, 0.3, 1.0, 3.0, 10.0], metavar="LIST",
        help=f"shear rates of the upward sweep in units of gammadot_ref, in [{MIN_SHEAR_RATE:g}, "
        f"{MAX_SHEAR_RATE:g}] and increasing (default 0.1,0.3,1,3,10)",
    )
    parser.add_argument(
        "--strain-per-rate", type=float, default=10.0,
        help=f"strain each rate is held for, > 0; the second half is averaged; the hold at the highest rate "
        f"must take at least {MIN_HOLD_STEPS} steps of --dt (default 10)",
    )
    parser.add_argument("--down", action="store_true", help="add the sweep back down (hysteresis)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the initial packing, >= 0 (default 1)")
    parser.add_argument(
        "--out", type=_directory, required=True,
        help="output directory (created; must not be a file); manifest.json names its owner (a rerun of "
        "the same curve continues after its last finished hold; anything else there is refused)",
    )
    _add_folder_arguments(
        parser,
        "insist on continuing the curve in OUT after its last finished hold (refused if OUT holds none); "
        "a rerun of the same curve continues without it",
    )
    parser.add_argument(
        "--workers", type=positive_int, default=1,
        help="curves at once in local worker processes, >= 1 (1: in this process) (default 1)",
    )
    parser.add_argument(
        "--scheduler", type=_scheduler, default=None, metavar="ADDRESS",
        help="run the curves on the Dask cluster at ADDRESS (tcp://HOST:8786)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar and no compile notice")


def _positive_rate(text: str) -> float:
    """``--rates``: one shear rate, a number in [MIN_SHEAR_RATE, MAX_SHEAR_RATE]."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not MIN_SHEAR_RATE <= value <= MAX_SHEAR_RATE:
        raise argparse.ArgumentTypeError(
            f"must be in [{MIN_SHEAR_RATE:g}, {MAX_SHEAR_RATE:g}] (units of the reference rate gammadot_ref; "
            f"a flow curve has no rate-0 point), got {text!r}"
        )
    return value


def _parse(argv: list[str]) -> argparse.Namespace:
    """Parse ``argv``; unknown options are reported by the subcommand's parser (with its usage)."""
    args, unknown = build_parser().parse_known_args(argv)
    if unknown:
        args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    return args


def _spec_text(value: Any, flag: str) -> str:
    """A YAML value as this flag's command-line text (lists as comma lists, ``.inf`` as ``inf``)."""
    if isinstance(value, list):
        if flag == "--seeds" and len(value) == 1:  # [3] is seed 3, not a count of 3
            return f"{_spec_text(value[0], flag)}-{_spec_text(value[0], flag)}"
        return ",".join(_spec_text(v, flag) for v in value)
    if isinstance(value, float):
        return "inf" if value == math.inf else repr(value)
    return str(value)


def _spec_arguments(args: argparse.Namespace) -> list[str]:
    """The flags and values of ``--spec FILE`` (or ``--preset NAME``), to go before the command line's own."""
    parser: argparse.ArgumentParser = args.parser
    if args.preset is not None:
        names = preset_names()
        if args.preset not in names:
            parser.error(f"--preset: no preset {args.preset!r} (available: {', '.join(names)})")
        flag, where = "--preset", args.preset
        text = (resources.files("sim") / "presets" / f"{args.preset}.yml").read_text()
    else:
        flag, where = "--spec", args.spec
        try:
            text = Path(args.spec).read_text(encoding="utf-8")
        except OSError as exc:
            parser.error(f"--spec {args.spec}: cannot be read: {exc.strerror or exc}")
        except UnicodeDecodeError as exc:
            parser.error(f"--spec {args.spec}: not a YAML text file (not UTF-8 at byte {exc.start})")
    import yaml

    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        parser.error(f"{flag} {where}: not valid YAML: {exc}")
    data = {} if data is None else data
    if not isinstance(data, dict):
        parser.error(f"{flag} {where}: must be a mapping of flags (without '--') to values")
    switches = {a.option_strings[0]: a.nargs == 0 for a in parser._actions if a.option_strings}
    allowed = [f for f in switches if f.startswith("--") and f not in ("--help", "--spec", "--preset")]
    tokens: list[str] = []
    for key, value in data.items():
        option = "--" + str(key).replace("_", "-")
        if option not in allowed:
            valid = ", ".join(f[2:] for f in allowed)
            parser.error(
                f"{flag} {where}: unknown key {key!r} (keys are sweep's flags without '--': {valid})"
            )
        if switches[option]:
            if not isinstance(value, bool):
                parser.error(f"{flag} {where}: {key} must be true or false, got {value!r}")
            tokens += [option] if value else []
        elif value is not None:
            tokens += [option, _spec_text(value, option)]
    return tokens


def _check_run_values(parser: argparse.ArgumentParser, strain: float, transient: float | None) -> None:
    """Checks of ``--strain`` and ``--transient`` before any configuration is built (they assume a
    positive strain)."""
    if not strain > 0:
        parser.error(f"--strain must be > 0 for a run, got {strain!r}")
    if transient is not None and math.isfinite(strain) and transient >= strain:
        parser.error(f"--transient must be below --strain ({strain!r}), got {transient!r}")


def _make_config(args: argparse.Namespace, **point: Any) -> SimulationConfig:
    """A ``SimulationConfig`` from ``args``'s single-valued options and ``point``'s ``volume_fraction``,
    ``n_particles``, ``mason_number``, ``mechanism``, ``seed``; bad values exit 2 naming the flag."""
    try:
        return SimulationConfig(
            field_direction=args.field_direction,
            shear_rate=args.shear_rate,
            strain=args.strain,
            time_step=args.dt,
            transient_strain=args.transient,
            max_displacement=args.max_displacement,
            near_field=args.near_field,
            near_field_cutoff=args.near_field_cutoff,
            ewald_accuracy=args.ewald_accuracy,
            **point,
        )
    except ValueError as exc:
        parser: argparse.ArgumentParser = args.parser
        parser.error(with_flags(str(exc)))


def _config(args: argparse.Namespace) -> SimulationConfig:
    """The run's ``SimulationConfig``; bad values exit 2 with a message naming the flag."""
    _check_run_values(args.parser, args.strain, args.transient)
    return _make_config(
        args,
        volume_fraction=args.phi,
        n_particles=args.n_particles,
        mason_number=args.mason,
        mechanism=args.mechanism,
        seed=args.seed,
    )


def _sweep_configs(args: argparse.Namespace) -> list[SimulationConfig]:
    """Every point of the sweep (``--phi`` x ``--mason`` x ``--n-particles`` x ``--mechanism`` x ``--seeds``),
    checked as ``run`` checks one (each refused value exits 2 naming its flag) before anything runs."""
    from sim.runs.run import check_run_length
    from sim.runs.sweep import check_unique_names

    parser: argparse.ArgumentParser = args.parser
    _check_run_values(parser, args.strain, args.transient)
    configs = [
        _make_config(
            args, volume_fraction=phi, n_particles=n, mason_number=mason, mechanism=mechanism, seed=seed
        )
        for phi, mason, n, mechanism, seed in itertools.product(
            args.phi, args.mason, args.n_particles, args.mechanism, args.seeds
        )
    ]
    try:
        for config in configs:
            check_run_length(config, FLAGS)
        check_unique_names(configs)
    except ValueError as exc:
        parser.error(with_flags(str(exc)))
    return configs


def _stderr_text(value: float) -> str:
    """A standard error for the summary; NaN (fewer samples than blocks) said plainly."""
    return f"{value:.4f}" if math.isfinite(value) else "n/a"


def _summary(config: SimulationConfig, result: dict[str, Any], out: str) -> str:
    """The human-readable result printed without ``--json``."""
    units = "eps*E0^2" if config.quiescent else "eta*gammadot"
    eta_error = _stderr_text(result["relative_viscosity_stderr"])
    lines = [
        f"phi = {config.volume_fraction}, N = {config.n_particles}, strain = {result['strain']:.2f} "
        f"({result['steps']} steps, {result['wall_seconds']:.1f} s); averaged from strain "
        f"{result['averaged_from_strain']:g} over {result['averaged_samples']} samples",
        f"  eta_r = {result['relative_viscosity']:.4f} +/- {eta_error}",
        f"  N1    = {result['n1']:.4f} +/- {_stderr_text(result['n1_stderr'])}  (units {units})",
        f"  N2    = {result['n2']:.4f} +/- {_stderr_text(result['n2_stderr'])}",
        f"  Pi    = {result['particle_pressure']:.4f} +/- {_stderr_text(result['particle_pressure_stderr'])}"
        "  (particle pressure -tr(Sigma^p)/3)",
    ]
    if not math.isfinite(result["relative_viscosity_stderr"]):
        lines.append(
            f"  (no standard errors: they need at least {config.n_blocks} samples after the transient)"
        )
    if not config.pure_shear:
        ratio = result["u_rms_dip"] / result["u_rms_shear"] if result["u_rms_shear"] > 0 else math.inf
        lines.append(
            f"  Mn = {config.mason_number:g} ({config.mechanism}, near field {config.near_field}): "
            f"U_rms^DIP = {result['u_rms_dip']:.4g}, U_rms^shear = {result['u_rms_shear']:.4g}, "
            f"ratio {ratio:.3g}"
        )
    lines.append(f"  min gap = {result['min_gap']:.3g} a; results in {out}")
    return "\n".join(lines)


def _run(args: argparse.Namespace, args_list: list[str]) -> int:
    """``python -m sim run``."""
    parser: argparse.ArgumentParser = args.parser
    config = _config(args)

    from sim.runs.initial_state import InitialState, read_initial_state, with_field_of
    from sim.runs.run import run_simulation
    from sim.simulation import SimulationError

    initial: InitialState | None = None
    if args.field_from_state and args.initial_state is None:
        parser.error("--field-from-state needs --initial-state FILE (the file whose field it takes)")
    if args.initial_state is not None:
        try:
            initial = read_initial_state(args.initial_state, FLAGS)
            if args.field_from_state:
                config = with_field_of(config, initial, FLAGS)
        except ValueError as exc:
            parser.error(with_flags(str(exc)))
    try:
        result = run_simulation(
            config,
            args.out,
            progress=False if args.quiet else None,
            resume=args.resume,
            overwrite=args.overwrite,
            command=["python", "-m", "sim", *args_list],
            parameter_names=FLAGS,
            state=initial,
            snapshot_every=args.snapshot_every,
            trajectory_every=args.trajectory_every,
        )
    except (FileNotFoundError, ValueError, NotImplementedError) as exc:
        parser.error(with_flags(str(exc)))
    except SimulationError as exc:
        print(f"{parser.prog}: simulation failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        checkpoint = Path(args.out) / "checkpoint.npz"
        kept = (
            f"the last checkpoint, {checkpoint}, is kept: rerun with --resume to continue"
            if checkpoint.exists()
            else "no checkpoint had been written yet"
        )
        print(f"{parser.prog}: interrupted; {kept}", file=sys.stderr)
        return 130
    if args.json:
        from sim.runs.io import json_ready

        print(json.dumps(json_ready(result)))
    else:
        print(_summary(config, result, args.out))
    return 0


def _log(line: str) -> None:
    """A line on stderr that leaves a tqdm bar intact."""
    from tqdm import tqdm

    tqdm.write(line, file=sys.stderr)


def _sweep(args: argparse.Namespace, args_list: list[str]) -> int:
    """``python -m sim sweep``."""
    parser: argparse.ArgumentParser = args.parser
    if args.out is None:
        parser.error("the following arguments are required: --out")
    configs = _sweep_configs(args)
    out = check_output_directory(parser, "--out", args.out)

    from sim.runs.folder import RunFolderError
    from sim.runs.io import json_ready, read_json
    from sim.runs.run import COMPILE_NOTICE, compiled_kernels_cached
    from sim.runs.sweep import MANIFEST, manifest_text, run_points

    if not args.quiet and args.scheduler is None and not compiled_kernels_cached():
        print(COMPILE_NOTICE, file=sys.stderr, flush=True)
    arguments = {k: v for k, v in vars(args).items() if k != "parser"}
    try:
        points = run_points(
            configs,
            out,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=not args.quiet and sys.stderr.isatty(),
            command=["python", "-m", "sim", *args_list],
            arguments=arguments,
            log=None if args.quiet else _log,
            resume=args.resume,
            overwrite=args.overwrite,
        )
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted; rerun the same command to resume", file=sys.stderr)
        return 130
    except RunFolderError as exc:
        parser.error(with_flags(str(exc)))
    except (OSError, RuntimeError) as exc:
        if args.scheduler is None:
            raise
        parser.error(f"--scheduler {args.scheduler}: {exc}")
    failed = [p for p in points if p.failure is not None]
    if args.json:
        print(json.dumps(json_ready(read_json(out / MANIFEST))))
    else:
        print(f"{manifest_text(points)}; {out / MANIFEST}")
        print(f"figures: python -m sim figures {out}")
    for point in failed:
        assert point.failure is not None
        print(
            f"{parser.prog}: {point.name} failed: {point.failure.error}: {point.failure.message} "
            f"(traceback in {out / point.name / 'error.json'})",
            file=sys.stderr,
        )
    return 1 if failed else 0


def _flow_curve(args: argparse.Namespace, args_list: list[str]) -> int:
    """``python -m sim flow-curve``."""
    from sim.runs.flow_curve import (
        COMMAND,
        CSV_NAME,
        PLOT_NAME,
        FlowCurveSpec,
        check_curve_folder,
        curve_folder,
        curve_identity,
        read_rows,
        resume_point,
        run_flow_curve_task,
        write_combined,
    )
    from sim.runs.folder import RunFolderError, claim
    from sim.runs.run import COMPILE_NOTICE, compiled_kernels_cached
    from sim.runs.tasks import TaskFailure, run_tasks

    parser: argparse.ArgumentParser = args.parser
    out = check_output_directory(parser, "--out", args.out)
    specs = []
    for mason in args.mason:
        try:
            config = SimulationConfig(
                n_particles=args.n_particles, volume_fraction=args.phi, mason_number=mason,
                field_direction=args.field_direction, mechanism=args.mechanism, seed=args.seed,
                time_step=args.dt, max_displacement=args.max_displacement, near_field=args.near_field,
                near_field_cutoff=args.near_field_cutoff, ewald_accuracy=args.ewald_accuracy,
            )
            specs.append(FlowCurveSpec(config, tuple(args.rates), args.strain_per_rate, args.down))
        except ValueError as exc:
            parser.error(with_flags(str(exc)))
    several = len(specs) > 1
    folders = [out / curve_folder(s.config.mason_number) if several else out for s in specs]
    command = ["python", "-m", "sim", *args_list]
    # every folder and every file a rerun continues from is checked before any work
    try:
        found, legacy = check_curve_folder(out, specs, args.resume, args.overwrite, "--out")
        if found in ("same", "adopted"):
            for spec, folder in zip(specs, folders, strict=True):
                if several and check_curve_folder(folder, [spec], flag="--out")[0] not in ("same", "adopted"):
                    continue
                try:
                    resume_point(folder, spec)
                except ValueError as exc:
                    raise RunFolderError(
                        f"--out {out}: {exc}; give --overwrite to delete the previous run and start afresh"
                    ) from None
        if several:  # the folder of the curves (each curve claims its own sub-folder)
            claim(out, COMMAND, curve_identity(specs), resume=args.resume, overwrite=args.overwrite,
                  argv=command, legacy=legacy)
    except RunFolderError as exc:
        parser.error(with_flags(str(exc)))
    if not args.quiet and args.scheduler is None and not compiled_kernels_cached():
        print(COMPILE_NOTICE, file=sys.stderr, flush=True)
    show_bar = not args.quiet and sys.stderr.isatty()
    payloads = [
        {
            **spec.to_dict(), "out": str(folder), "progress": show_bar and not several, "command": command,
            "resume": args.resume and not several, "overwrite": args.overwrite and not several,
            "flag": "--out",
        }
        for spec, folder in zip(specs, folders, strict=True)
    ]

    def written() -> str:
        """The csv files that hold finished holds now, with their counts."""
        kept = []
        for folder, spec in zip(folders, specs, strict=True):
            path = folder / CSV_NAME
            try:
                done = len(read_rows(path)) if path.is_file() else 0
            except (OSError, ValueError, TypeError):
                done = 0
            if done:
                kept.append(f"{path} ({min(done, len(spec.holds))} of {len(spec.holds)} holds)")
        return "; ".join(kept)

    try:
        results = run_tasks(
            run_flow_curve_task, payloads, workers=args.workers, scheduler=args.scheduler, on_error="record",
            progress=show_bar and several, description="flow curves",
        )
    except KeyboardInterrupt:
        kept = written()
        what = f"the finished holds are kept in {kept}" if kept else "no hold had finished"
        print(f"{parser.prog}: interrupted; {what}; rerun the same command to continue", file=sys.stderr)
        return 130
    curves = {
        spec.config.mason_number: rows
        for spec, rows in zip(specs, results, strict=True)
        if not isinstance(rows, TaskFailure)
    }
    if several and curves:
        write_combined(out, curves)
    failed = 0
    for spec, rows in zip(specs, results, strict=True):
        if isinstance(rows, TaskFailure):
            failed += 1
            print(f"{parser.prog}: Mn_ref {spec.config.mason_number:g} failed: {rows.error}: {rows.message}",
                  file=sys.stderr)
            continue
        if not args.quiet:
            for row in rows:
                print(
                    f"Mn_ref {spec.config.mason_number:g} {row['direction']:>4} rate {row['shear_rate']:<6g} "
                    f"Mn {row['mason_number']:<8.3g} eta_r {row['relative_viscosity']:.3f} "
                    f"+- {row['relative_viscosity_stderr']:.3f}  N1 {row['n1']:.3g}  N2 {row['n2']:.3g}"
                )
    if curves and not args.quiet:  # only the files written (none when every curve failed)
        print(", ".join(str(path) for path in (out / CSV_NAME, out / PLOT_NAME) if path.is_file()))
    return 1 if failed else 0


def _movie(args: argparse.Namespace) -> int:
    """``python -m sim movie``."""
    from sim.plots.movie import render_movie

    parser: argparse.ArgumentParser = args.parser
    try:
        written = render_movie(args.run, args.out, fps=args.fps, every=args.every)
    except (FileNotFoundError, ValueError) as exc:
        parser.error(str(exc))
    except OSError as exc:
        output_error(parser, "--out", exc)
    if not args.quiet:
        print(written)
    return 0


def _figures(args: argparse.Namespace) -> int:
    """``python -m sim figures``."""
    from sim.plots.sweep import make_figures

    parser: argparse.ArgumentParser = args.parser
    out = Path(args.directory) / "figures" if args.out is None else Path(args.out)
    flag = "--out" if args.out is not None else "DIR"
    if args.out is not None or Path(args.directory).is_dir():  # else make_figures names DIR
        check_output_directory(parser, flag, out)
    try:
        written = make_figures(args.directory, out, log=None if args.quiet else print)
    except (FileNotFoundError, ValueError) as exc:
        parser.error(str(exc))
    except OSError as exc:
        output_error(parser, flag, exc)
    if not args.quiet:
        print(f"{len(written)} files in {Path(written[0]).parent if written else args.out}")
    return 0


def parse_arguments(argv: Sequence[str]) -> argparse.Namespace:
    """Parse a command line (without ``python -m sim``); for ``sweep``, ``--spec``/``--preset`` merged.

    The spec's flags go before the command line's own, and argparse keeps the last value of a flag, so
    flags given on the command line override the spec. Bad input exits 2 naming the flag.
    """
    args_list = list(argv)
    args = _parse(args_list)
    if args.command == "sweep" and (args.spec is not None or args.preset is not None):
        args = _parse([args_list[0], *_spec_arguments(args), *args_list[1:]])
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m sim``; returns the exit status (bad input exits 2 via ``SystemExit``)."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    args = parse_arguments(args_list)
    if args.command == "run":
        return _run(args, args_list)
    if args.command == "sweep":
        return _sweep(args, args_list)
    if args.command == "flow-curve":
        return _flow_curve(args, args_list)
    if args.command == "movie":
        return _movie(args)
    return _figures(args)
