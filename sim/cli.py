"""Command line of the simulator.

    python -m sim run --phi 0.40 --n-particles 200 --mason inf --strain 30 --seed 1 --out DIR [--json]

Exit status 0 on success, 2 on bad input (the message names the parameter and its valid range), 1 when
the simulation itself fails. With ``--json`` the last line on stdout is one JSON object (``result.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence

from sim.config import DEFAULT_TIME_STEP, SimulationConfig
from sim.geometry.configurations import MAX_VOLUME_FRACTION


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_or_inf(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--mason must be a number in (0, inf] or 'inf', got {text!r}"
        ) from None
    if not (value > 0):
        raise argparse.ArgumentTypeError(f"--mason must be in (0, inf], got {text!r}")
    return value


def _direction(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or all(v == 0 for v in values):
        raise argparse.ArgumentTypeError(
            "--field-direction must be three comma-separated finite numbers, not all zero "
            f"(e.g. 0,1,0), got {text!r}"
        )
    return values  # type: ignore[return-value]


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m sim", description="Stokesian dynamics of sheared conductive spheres.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    run = sub.add_parser("run", help="run one simulation and write its results to --out")
    run.add_argument(
        "--phi",
        type=float,
        default=0.40,
        help=f"volume fraction in (0, {MAX_VOLUME_FRACTION}] (default 0.40)",
    )
    run.add_argument("--n-particles", type=int, default=200, help="number of spheres, >= 2 (default 200)")
    run.add_argument(
        "--mason",
        type=_positive_or_inf,
        default=math.inf,
        help="Mason number eta*gammadot/(eps*E0^2) in (0, inf]; only 'inf' (pure shear) runs today",
    )
    run.add_argument(
        "--field-direction",
        type=_direction,
        default=(0.0, 1.0, 0.0),
        help="electric field direction x,y,z (normalised; default 0,1,0)",
    )
    run.add_argument("--strain", type=float, default=30.0, help="total strain, >= 0 (default 30)")
    run.add_argument("--seed", type=int, default=1, help="seed of the initial packing, >= 0 (default 1)")
    run.add_argument(
        "--dt",
        type=float,
        default=DEFAULT_TIME_STEP,
        help=f"time step in strain units, in (0, 0.05] (default {DEFAULT_TIME_STEP})",
    )
    run.add_argument(
        "--transient",
        type=float,
        default=None,
        help="strain discarded before averaging (default 10, or half of runs shorter than 20)",
    )
    run.add_argument("--out", required=True, help="output directory")
    run.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.npz")
    run.add_argument(
        "--json", action="store_true", help="print the result as one JSON object on the last line"
    )
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(args_list)
    try:
        config = SimulationConfig(
            n_particles=args.n_particles,
            volume_fraction=args.phi,
            mason_number=args.mason,
            field_direction=args.field_direction,
            strain=args.strain,
            seed=args.seed,
            time_step=args.dt,
            transient_strain=args.transient,
        )
    except ValueError as exc:
        message = str(exc)
        for field, flag in (
            ("n_particles", "--n-particles"),
            ("volume_fraction", "--phi"),
            ("strain", "--strain"),
            ("seed", "--seed"),
            ("time_step", "--dt"),
            ("transient_strain", "--transient"),
            ("mason_number", "--mason"),
            ("field_direction", "--field-direction"),
        ):
            message = message.replace(field, flag)
        parser.exit(2, f"python -m sim: error: {message}\n")
    if not config.pure_shear:
        parser.exit(
            2,
            f"python -m sim: error: --mason {args.mason}: dipolophoresis (finite Mason number) is not "
            "implemented yet; only --mason inf (pure shear) is supported\n",
        )

    from sim.run import run_simulation
    from sim.simulation import SimulationError

    try:
        result = run_simulation(
            config,
            args.out,
            progress=False if args.quiet else None,
            resume=args.resume,
            command=["python", "-m", "sim", *args_list],
        )
    except (FileNotFoundError, ValueError) as exc:
        parser.exit(2, f"python -m sim: error: {exc}\n")
    except SimulationError as exc:
        print(f"python -m sim: simulation failed: {exc}", file=sys.stderr)
        return 1
    if args.json:
        from sim.io import json_ready

        print(json.dumps(json_ready(result)))
    else:
        print(
            f"phi = {config.volume_fraction}, N = {config.n_particles}, strain = {result['strain']:.2f} "
            f"({result['steps']} steps, {result['wall_seconds']:.1f} s); averaged from strain "
            f"{result['averaged_from_strain']:.1f}\n"
            f"  eta_r = {result['relative_viscosity']:.4f} +/- {result['relative_viscosity_stderr']:.4f}\n"
            f"  N1    = {result['n1']:.4f} +/- {result['n1_stderr']:.4f}  (units eta*gammadot)\n"
            f"  N2    = {result['n2']:.4f} +/- {result['n2_stderr']:.4f}\n"
            f"  min gap = {result['min_gap']:.3g} a; results in {args.out}"
        )
    return 0
