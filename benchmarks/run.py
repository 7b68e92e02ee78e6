"""Pure-shear step cost against system size: one command, one table.

    python benchmarks/run.py [--phi 0.45] [--sizes 100,250,500,1000,2000] [--steps 500] [--warmup-strain 3]

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
import os
import resource
import subprocess
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure(n: int, phi: float, steps: int, warmup_strain: float) -> dict:
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
    from sim.stepper import simple_shear_strain_rate

    # JIT warm-up on a tiny system, then the memory baseline
    Simulation(SimulationConfig(n_particles=30, volume_fraction=0.3, strain=0.01)).advance(3)
    baseline = _rss_mib()

    config = SimulationConfig(n_particles=n, volume_fraction=phi, strain=warmup_strain + 1.0, seed=1)
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
    e = simple_shear_strain_rate()
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--phi", type=float, default=0.45)
    parser.add_argument("--sizes", default="100,250,500,1000,2000")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--warmup-strain", type=float, default=3.0)
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        print(json.dumps(measure(args.child, args.phi, args.steps, args.warmup_strain)))
        return
    rows = []
    for n in (int(x) for x in args.sizes.split(",")):
        cmd = [
            sys.executable,
            __file__,
            "--child",
            str(n),
            "--phi",
            str(args.phi),
            "--steps",
            str(args.steps),
            "--warmup-strain",
            str(args.warmup_strain),
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        print(f"  N = {n} done", file=sys.stderr, flush=True)
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
    if len(rows) >= 2:
        import math

        first = next((r for r in rows if r["n"] == 250), rows[0])
        last = rows[-1]
        slope = math.log(last["ms_step"] / first["ms_step"]) / math.log(last["n"] / first["n"])
        print(f"\ncost per step grows as N^{slope:.2f} from N = {first['n']} to N = {last['n']}")


if __name__ == "__main__":
    main()
