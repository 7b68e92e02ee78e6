"""Step cost against system size, pure shear and with the field: one command, two tables.

    python benchmarks/run.py [--phi 0.45] [--sizes 64,250,500,1000,2000,4000] [--steps 500]
                             [--warmup-strain 3] [--mason inf,1,0.1] [--near-field exact|none|both]
    python benchmarks/run.py --quick   # N = 64, 250, 500; Mn = inf, 1; shorter warm-up and timing

Rows with a finite Mason number add the dipolophoretic velocity (Ewald far field, exact near field
unless ``--near-field none``); for them the table gives the two velocity terms of the step timed whole
(``hydrodynamic_term``: lubrication solve + stress; ``dipolophoresis_term``: Ewald/SPME sums, near-field
blend, DIP stresses), the steps per strain of the adaptive step and the seconds per strain.

For each N a fresh process builds a random packing, shears it for ``--warmup-strain`` (JIT compilation
happens here and is excluded), then times ``--steps`` full compiled steps (``sim.stepper.advance``) and,
on the final configuration, each phase on its own: neighbour list, assembly (lubrication scalars,
blocks, strain forcing, repulsion), solve (ordering + PCG), stress (pair stresslets). Memory:
``working set`` adds up the arrays one step allocates (pair list, lubrication scalars, 6x6 blocks and
their copy in elimination order, the DILU factors and ``2 D~ - D`` blocks, right-hand side, the PCG work
vectors) and the state; ``RSS growth`` is the peak resident set size minus its value after import and
JIT warm-up (``ru_maxrss``; it stays near 0 while the system is smaller than the compiler's own peak).
One core (numba kernels are serial).

The warm-up matters: the shear-induced contact network builds up over the first ~2 strains, and the
PCG iteration count with it (at phi = 0.45 from ~10 per step at strain 0.5 to a plateau of ~25-40
from strain 2 on), so shorter warm-ups understate the steady-state cost.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from typing import NamedTuple

os.environ.setdefault("NUMBA_NUM_THREADS", "1")


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure(
    n: int, phi: float, steps: int, warmup_strain: float, mason: float = math.inf, near_field: str = "exact"
) -> dict:
    import numpy as np

    from sim import Simulation, SimulationConfig
    from sim.contacts.repulsion import repulsive_forces
    from sim.geometry.box import lees_edwards_offset
    from sim.geometry.neighbors import build_pair_list
    from sim.hydrodynamics.lubrication import (
        assemble_resistance,
        pair_scalars,
        pair_stresslets,
        strain_forcing,
    )
    from sim.hydrodynamics.resistance_solver import solve_resistance
    from sim.hydrodynamics.stokes_drag import FORCE_DRAG, TORQUE_DRAG
    from sim.observables.stress import N_CONTRIBUTIONS
    from sim.step_parameters import field_parameters
    from sim.stepper import dipolophoresis_term, hydrodynamic_term, shear_strain_rate

    # JIT warm-up on a tiny system, then the memory baseline
    Simulation(SimulationConfig(n_particles=30, volume_fraction=0.3, strain=0.01)).advance(3)
    baseline = _rss_mib()

    config = SimulationConfig(
        n_particles=n,
        volume_fraction=phi,
        strain=warmup_strain + 1.0,
        seed=1,
        mason_number=mason,
        near_field=near_field,
    )
    sim = Simulation(config)
    t0 = time.perf_counter()
    sim.advance_to(warmup_strain)
    warm_seconds = time.perf_counter() - t0

    t0 = time.perf_counter()
    chunk = sim.advance(steps)
    total = (time.perf_counter() - t0) / steps

    # phases, re-run on the final configuration (same kernels as the step)
    s = sim.state
    length = config.box_length
    e = shear_strain_rate(1.0)
    reps = max(3, steps // 5)
    timings = {"neighbours": 0.0, "assembly": 0.0, "solve": 0.0, "stress": 0.0}
    for rep in range(reps + 1):  # rep 0 is untimed: first calls from Python load the cached kernels
        if rep == 1:
            timings = dict.fromkeys(timings, 0.0)
        t = time.perf_counter()
        offset = lees_edwards_offset(s.strain, length)
        pairs, seps = build_pair_list(s.positions, length, offset, 2.0 + config.lubrication_cutoff)
        timings["neighbours"] += time.perf_counter() - t
        t = time.perf_counter()
        sc, units, gaps = pair_scalars(
            pairs, seps, config.lubrication_cutoff, config.lubrication_regularisation
        )
        diag, off = assemble_resistance(n, pairs, units, sc, FORCE_DRAG, TORQUE_DRAG)
        rhs = strain_forcing(n, pairs, units, sc, e)
        forces, _ = repulsive_forces(n, pairs, units, gaps, 6 * np.pi / 5000.0, config.repulsion_range)
        rhs[:, :3] += forces
        timings["assembly"] += time.perf_counter() - t
        t = time.perf_counter()
        # the same initial guess the step uses: extrapolation of the last two solutions
        guess = 2.0 * s.warm_start - s.previous_warm_start
        sol, iters, _ = solve_resistance(diag, off, pairs, rhs, guess, config.solver_tolerance, 20000)
        timings["solve"] += time.perf_counter() - t
        t = time.perf_counter()
        pair_stresslets(n, pairs, units, sc, sol, e)
        timings["stress"] += time.perf_counter() - t
    out = {k: 1e3 * v / reps for k, v in timings.items()}
    # the two velocity terms of the step, timed whole on the final configuration
    stress = np.zeros((N_CONTRIBUTIONS, 3, 3))
    field = field_parameters(config, s.mason_number, s.field_direction, sim._plan)
    hydro_guess = s.warm_start + (s.warm_start - s.previous_warm_start)
    term_seconds = {"shear_term": 0.0, "dip_term": 0.0}
    for rep in range(reps + 1):
        t = time.perf_counter()
        hydrodynamic_term(s.positions, s.strain, hydro_guess, sim._params, stress)
        t1 = time.perf_counter()
        if not math.isinf(mason):
            dipolophoresis_term(s.positions, s.strain, sim._params, field, stress)
        t2 = time.perf_counter()
        if rep > 0:
            term_seconds["shear_term"] += t1 - t
            term_seconds["dip_term"] += t2 - t1
    out.update({k: 1e3 * v / reps for k, v in term_seconds.items()})
    step_arrays = [pairs, seps, sc, units, gaps, diag, off, rhs, forces, sol]
    working = (
        sum(a.nbytes for a in step_arrays)
        + diag.nbytes
        + off.nbytes
        + pairs.nbytes  # the system in elimination order
        + 2 * diag.nbytes  # DILU factors, 2 D~ - D
        + 10 * sol.nbytes  # PCG work vectors
    )
    working += sum(a.nbytes for a in s.arrays().values())
    return {
        "n": n,
        "phi": phi,
        "mason": "inf" if math.isinf(mason) else mason,
        "near_field": near_field,
        "ms_shear_term": out["shear_term"],
        "ms_dip_term": out["dip_term"],
        "mean_dt": float(chunk.time_step.mean()),
        "seconds_per_strain": total / float(chunk.time_step.mean()),
        "pairs": int(pairs.shape[0]),
        "ms_step": 1e3 * total,
        "ms_neighbours": out["neighbours"],
        "ms_assembly": out["assembly"],
        "ms_solve": out["solve"],
        "ms_stress": out["stress"],
        "iterations_mean": float(chunk.solver_iterations.mean()),
        "particle_steps_per_s": n / total,
        "working_mib": working / 2**20,
        "peak_mib": _rss_mib() - baseline,
        "warmup_seconds": warm_seconds,
    }


class Plan(NamedTuple):
    """Default sizes, timed steps, warm-up strain and Mason numbers of a benchmark run."""

    sizes: str
    steps: int
    warmup_strain: float
    masons: str


DEFAULTS = Plan(sizes="64,250,500,1000,2000,4000", steps=500, warmup_strain=3.0, masons="inf,1,0.1")
"""The measurement of the table in docs/benchmarks.md."""

QUICK = Plan(sizes="64,250,500", steps=300, warmup_strain=2.0, masons="inf,1")
"""``--quick``: the same measurement, smaller (about 20 s with compiled kernels, a minute more without);
2 strains of warm-up reach the plateau of the PCG iterations, but fewer timed steps make it noisier."""


def _sizes(text: str) -> list[int]:
    """``--sizes``: comma-separated integers >= 2."""
    try:
        sizes = [int(part) for part in text.split(",")]
    except ValueError:
        sizes = []
    if not sizes or any(n < 2 for n in sizes):
        raise argparse.ArgumentTypeError(f"must be comma-separated integers >= 2, e.g. 100,250; got {text!r}")
    return sizes


def _masons(text: str) -> list[float]:
    """``--mason``: comma-separated numbers > 0 or ``inf``."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if not values or any(not v > 0 for v in values):
        raise argparse.ArgumentTypeError(
            f"must be comma-separated numbers > 0 or inf, e.g. inf,1; got {text!r}"
        )
    return values


def _non_negative(text: str) -> float:
    """``--warmup-strain``: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """Options of the benchmark (defaults shown by ``--help``)."""
    from sim.runs.cli import positive_int  # here: sim loads numba, which must see NUMBA_NUM_THREADS set above

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--phi", type=float, default=0.45, help="volume fraction (default 0.45)")
    parser.add_argument(
        "--sizes",
        type=_sizes,
        default=None,
        help=f"comma-separated particle numbers, one fresh process each (default {DEFAULTS.sizes}; "
        f"--quick: {QUICK.sizes})",
    )
    parser.add_argument(
        "--steps",
        type=positive_int,
        default=None,
        help=f"timed steps per size, after the warm-up (default {DEFAULTS.steps}; --quick: {QUICK.steps})",
    )
    parser.add_argument(
        "--warmup-strain",
        type=_non_negative,
        default=None,
        help=f"strain sheared before timing; includes JIT loading and the build-up of the contact network "
        f"(default {DEFAULTS.warmup_strain}; --quick: {QUICK.warmup_strain})",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smaller defaults for a check that finishes in under a minute once the kernels are compiled "
        "(explicit options still win); noisier than the table in docs/benchmarks.md",
    )
    parser.add_argument(
        "--mason",
        type=_masons,
        default=None,
        help=f"comma-separated Mason numbers ('inf' = pure shear) (default {DEFAULTS.masons}; "
        f"--quick: {QUICK.masons})",
    )
    parser.add_argument(
        "--near-field",
        choices=("exact", "none", "both"),
        default="exact",
        help="near-field dipolophoresis of the field rows: exact, none (far field only), or both "
        "(default exact)",
    )
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--child-mason", type=float, default=math.inf, help=argparse.SUPPRESS)
    parser.add_argument("--child-near-field", default="exact", help=argparse.SUPPRESS)
    return parser


def _resolve(args: argparse.Namespace) -> None:
    """Fill the options left unset from ``--quick`` or the defaults."""
    base = QUICK if args.quick else DEFAULTS
    if args.sizes is None:
        args.sizes = _sizes(base.sizes)
    if args.steps is None:
        args.steps = base.steps
    if args.warmup_strain is None:
        args.warmup_strain = base.warmup_strain
    if args.mason is None:
        args.mason = _masons(base.masons)


def scaling_exponent(rows: list[dict], start: int = 250) -> tuple[int, int, float] | None:
    """``(N_first, N_last, p)`` with cost per step ~ N^p between two rows, or None without two sizes.

    The fit starts at N = ``start`` when that row exists and is not the last (smaller systems are
    dominated by per-step overheads), else at the first row, and ends at the last row.
    """
    if len(rows) < 2:
        return None
    candidates = [r for r in rows[:-1] if r["n"] == start]
    first = candidates[0] if candidates else rows[0]
    last = rows[-1]
    if first["n"] == last["n"] or first["ms_step"] <= 0.0 or last["ms_step"] <= 0.0:
        return None
    slope = math.log(last["ms_step"] / first["ms_step"]) / math.log(last["n"] / first["n"])
    return first["n"], last["n"], slope


def _run_child(n: int, mason: float, near_field: str, args: argparse.Namespace) -> dict:
    cmd = [
        sys.executable,
        __file__,
        "--child",
        str(n),
        "--child-mason",
        str(mason),
        "--child-near-field",
        near_field,
        "--phi",
        str(args.phi),
        "--steps",
        str(args.steps),
        "--warmup-strain",
        str(args.warmup_strain),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"N = {n}, Mn = {mason} failed (exit status {proc.returncode}):\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    args = build_parser().parse_args()
    _resolve(args)
    if args.child is not None:
        result = measure(
            args.child, args.phi, args.steps, args.warmup_strain, args.child_mason, args.child_near_field
        )
        print(json.dumps(result))
        return
    near_fields = ["exact", "none"] if args.near_field == "both" else [args.near_field]
    rows: list[dict] = []
    field_rows: list[dict] = []
    for mason in args.mason:
        for near_field in near_fields if not math.isinf(mason) else ["none"]:
            for n in args.sizes:
                row = _run_child(n, mason, near_field, args)
                (rows if math.isinf(mason) else field_rows).append(row)
                print(f"  N = {n}, Mn = {mason:g}, near field {near_field} done", file=sys.stderr, flush=True)
    if rows:
        _print_shear_table(rows, args)
    if field_rows:
        _print_field_table(field_rows, args)


def _print_shear_table(rows: list[dict], args: argparse.Namespace) -> None:
    print(
        f"\nPure shear, phi = {args.phi}, one core, after {args.warmup_strain} strain of warm-up "
        f"(ms per step; phases timed separately on the same configuration)\n"
    )
    header = (
        "| N | pairs | ms/step | neighbours | assembly | solve | stress | PCG iters | particle-steps/s "
        "| working set MiB | RSS growth MiB |"
    )
    print(header)
    print("|" + "---|" * 11)
    for r in rows:
        print(
            f"| {r['n']} | {r['pairs']} | {r['ms_step']:.2f} | {r['ms_neighbours']:.2f} "
            f"| {r['ms_assembly']:.2f} "
            f"| {r['ms_solve']:.2f} | {r['ms_stress']:.2f} | {r['iterations_mean']:.0f} "
            f"| {r['particle_steps_per_s']:,.0f} | {r['working_mib']:.2f} | {r['peak_mib']:.1f} |"
        )
    fit = scaling_exponent(rows)
    if fit is not None:
        print(f"\ncost per step grows as N^{fit[2]:.2f} from N = {fit[0]} to N = {fit[1]}")


def _print_field_table(rows: list[dict], args: argparse.Namespace) -> None:
    print(
        f"\nWith the field (dipolophoresis along y), phi = {args.phi}, one core, after {args.warmup_strain} "
        "strain of warm-up; the shear and DIP terms are timed whole on the final configuration\n"
    )
    print(
        "| N | Mn | near field | ms/step | shear term ms | DIP term ms | PCG iters | steps/strain "
        "| s/strain | particle-steps/s |"
    )
    print("|" + "---|" * 10)
    for r in rows:
        print(
            f"| {r['n']} | {r['mason']:g} | {r['near_field']} | {r['ms_step']:.2f} "
            f"| {r['ms_shear_term']:.2f} "
            f"| {r['ms_dip_term']:.2f} | {r['iterations_mean']:.0f} | {1.0 / r['mean_dt']:.0f} "
            f"| {r['seconds_per_strain']:.2f} | {r['particle_steps_per_s']:,.0f} |"
        )
    for mason in sorted({r["mason"] for r in rows}):
        for near_field in sorted({r["near_field"] for r in rows}):
            subset = [r for r in rows if r["mason"] == mason and r["near_field"] == near_field]
            fit = scaling_exponent(subset, start=500)
            if fit is not None:
                print(
                    f"Mn = {mason:g}, near field {near_field}: cost per step grows as N^{fit[2]:.2f} "
                    f"from N = {fit[0]} to N = {fit[1]}"
                )


if __name__ == "__main__":
    main()
