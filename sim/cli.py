"""Command line of the simulator.

    python -m sim run --phi 0.40 --n-particles 200 --mason inf --strain 30 --seed 1 --out DIR [--json]

Exit status 0 on success, 2 on bad input (``python -m sim run: error: ...`` after ``run``'s usage; the
message names the flag and its valid range), 1 when the simulation itself fails. With ``--json`` the last
line on stdout is one JSON object (``result.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from sim.config import (
    DEFAULT_MAX_DISPLACEMENT,
    DEFAULT_TIME_STEP,
    MAX_PARTICLES,
    MAX_STEPS,
    MECHANISMS,
    NEAR_FIELD_MODELS,
    SimulationConfig,
)
from sim.geometry.configurations import MAX_VOLUME_FRACTION, MIN_VOLUME_FRACTION

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
    """Argument parser whose errors print its usage and ``<prog>: error: <message>``, exit status 2."""

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
    """``--shear-rate``: 1 (sheared) or 0 (quiescent, field only)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if value not in (0.0, 1.0):
        raise argparse.ArgumentTypeError(f"must be 1 (sheared) or 0 (quiescent), got {text!r}")
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


def _add_run_arguments(run: argparse.ArgumentParser) -> None:
    """The flags of ``python -m sim run``."""
    run.add_argument(
        "--phi",
        type=float,
        default=0.40,
        help=f"volume fraction in [{MIN_VOLUME_FRACTION}, {MAX_VOLUME_FRACTION}] (default 0.40)",
    )
    run.add_argument(
        "--n-particles",
        type=int,
        default=200,
        help=f"number of spheres, in [2, {MAX_PARTICLES}] (default 200)",
    )
    run.add_argument(
        "--mason",
        type=_mason_number,
        default=math.inf,
        help="Mason number eta*gammadot/(eps*E0^2) in (0, inf]; inf = no field, pure shear (default inf)",
    )
    run.add_argument(
        "--field-direction",
        type=_direction,
        default=(0.0, 1.0, 0.0),
        help="electric field direction x,y,z (normalised; default 0,1,0)",
    )
    run.add_argument(
        "--mechanism",
        choices=MECHANISMS,
        default="dip",
        help="dipolophoresis mechanism: dip (ICEP + DEP), icep, or dep alone (default dip)",
    )
    run.add_argument(
        "--shear-rate",
        type=_shear_rate,
        default=1.0,
        help="1 (sheared) or 0 (quiescent: field only, needs a finite --mason) (default 1)",
    )
    run.add_argument(
        "--strain",
        type=float,
        default=30.0,
        help="run length, > 0: strain (time in units a/U0 with --shear-rate 0) (default 30)",
    )
    run.add_argument("--seed", type=int, default=1, help="seed of the initial packing, >= 0 (default 1)")
    run.add_argument(
        "--dt",
        type=float,
        default=DEFAULT_TIME_STEP,
        help=f"largest time step (steps may adapt below it), in (0, 0.05]; --strain/--dt at most "
        f"{MAX_STEPS:.0e} (default {DEFAULT_TIME_STEP})",
    )
    run.add_argument(
        "--max-displacement",
        type=float,
        default=DEFAULT_MAX_DISPLACEMENT,
        help="largest non-affine displacement per step as a fraction of the mean spacing, in (0, 0.05]; "
        f"sets the adaptive step (default {DEFAULT_MAX_DISPLACEMENT}, the paper's 0.4%%)",
    )
    run.add_argument(
        "--near-field",
        choices=NEAR_FIELD_MODELS,
        default="exact",
        help="dipolophoresis of close pairs: exact two-sphere functions blended into the far field, or "
        "none (far-field kernels only) (default exact)",
    )
    run.add_argument(
        "--near-field-cutoff",
        type=float,
        default=4.0,
        help="centre distance (units a) below which the exact near field replaces the far field, in "
        "(2.5, 10] and below half the box (default 4)",
    )
    run.add_argument(
        "--ewald-accuracy",
        type=float,
        default=1e-6,
        help="relative accuracy of the periodic far-field sums, in [1e-12, 1e-2] (default 1e-6)",
    )
    run.add_argument(
        "--transient",
        type=float,
        default=None,
        help="strain discarded before averaging, in [0, --strain) (default 10, or half of runs shorter "
        "than 20)",
    )
    run.add_argument("--out", required=True, help="output directory (created; must not be a file)")
    run.add_argument(
        "--resume",
        action="store_true",
        help="continue from OUT/checkpoint.npz; only --strain may differ from that run (to extend it)",
    )
    run.add_argument(
        "--json", action="store_true", help="print the result as one JSON object on the last line"
    )
    run.add_argument("--quiet", action="store_true", help="no progress bar and no compile notice")


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
    return parser


def _parse(argv: list[str]) -> argparse.Namespace:
    """Parse ``argv``; unknown options are reported by the subcommand's parser (with its usage)."""
    args, unknown = build_parser().parse_known_args(argv)
    if unknown:
        args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    return args


def _config(args: argparse.Namespace) -> SimulationConfig:
    """The run's ``SimulationConfig``; bad values exit 2 with a message naming the flag."""
    parser: argparse.ArgumentParser = args.parser
    if not args.strain > 0:  # before the config, whose checks of --transient assume a positive strain
        parser.error(f"--strain must be > 0 for a run, got {args.strain!r}")
    if args.transient is not None and math.isfinite(args.strain) and args.transient >= args.strain:
        parser.error(f"--transient must be below --strain ({args.strain!r}), got {args.transient!r}")
    try:
        return SimulationConfig(
            n_particles=args.n_particles,
            volume_fraction=args.phi,
            mason_number=args.mason,
            field_direction=args.field_direction,
            mechanism=args.mechanism,
            shear_rate=args.shear_rate,
            strain=args.strain,
            seed=args.seed,
            time_step=args.dt,
            transient_strain=args.transient,
            max_displacement=args.max_displacement,
            near_field=args.near_field,
            near_field_cutoff=args.near_field_cutoff,
            ewald_accuracy=args.ewald_accuracy,
        )
    except ValueError as exc:
        parser.error(with_flags(str(exc)))


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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m sim``; returns the exit status (bad input exits 2 via ``SystemExit``)."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    args = _parse(args_list)
    parser: argparse.ArgumentParser = args.parser
    config = _config(args)

    from sim.run import run_simulation
    from sim.simulation import SimulationError

    try:
        result = run_simulation(
            config,
            args.out,
            progress=False if args.quiet else None,
            resume=args.resume,
            command=["python", "-m", "sim", *args_list],
            parameter_names=FLAGS,
        )
    except (FileNotFoundError, ValueError, NotImplementedError) as exc:
        parser.error(with_flags(str(exc)))
    except SimulationError as exc:
        print(f"{parser.prog}: simulation failed: {exc}", file=sys.stderr)
        return 1
    if args.json:
        from sim.io import json_ready

        print(json.dumps(json_ready(result)))
    else:
        print(_summary(config, result, args.out))
    return 0
