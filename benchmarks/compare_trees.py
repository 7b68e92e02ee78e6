"""Before/after timing of two source trees on a shared machine: interleaved runs, minimum and median.

    python benchmarks/compare_trees.py BEFORE_TREE AFTER_TREE [--jobs 64:1:6,64:inf:4,500:1:3,500:inf:2]
                                       [--term-sizes 64,250,500] [--term-reps 1000,150,150]
                                       [--env-jobs 300:1:3,300:0.2:3,64:1:3] [--env-steps 100]

``BEFORE_TREE`` and ``AFTER_TREE`` are checkouts of this project (e.g. ``git archive COMMIT | tar -x -C
DIR``); each is imported through ``PYTHONPATH`` with this interpreter (numba caches are per source hash,
so both compile once). Part 1: the children of ``benchmarks/run.py`` (``N:Mn:repeats``; 3 strains of
warm-up, 500 timed steps, phi = 0.45), alternating the trees (before/after, then after/before, ...);
prints min/median of ms per step, the two velocity terms, s per strain and PCG iterations. Part 2: the
DIP term alone (``sim.stepper.dipolophoresis_term``, Mn = 1, field along y) on one fixed random packing
per N at strains 0.37, 0.5, 0.68: minimum over ``--term-reps`` calls, the number least disturbed by
other processes on the machine. Part 3 (``--env-jobs N:Mn:repeats``, none by default): whole compiled
steps at the environments' settings (solver tolerance 1e-6, Ewald accuracy 1e-4) from the same warmed
states in both trees, by ``benchmarks/step_profile.py --whole-only`` of *this* checkout run against each
tree (states made once in ``/tmp/step_profile_states``), alternating the trees as in part 1; each run
takes the minimum of 3 repeats of ``--env-steps`` steps.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

TERM_SCRIPT = r"""
import os, sys, time
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
import numpy as np
from sim import Simulation, SimulationConfig
from sim.geometry.configurations import random_packing
from sim.observables.stress import N_CONTRIBUTIONS
from sim.step_parameters import field_parameters
from sim.stepper import dipolophoresis_term
n, reps = int(sys.argv[1]), int(sys.argv[2])
config = SimulationConfig(n_particles=n, volume_fraction=0.45, strain=1.0, seed=1, mason_number=1.0)
sim = Simulation(config)
positions = random_packing(n, 0.45, 1)
field = field_parameters(config, 1.0, sim.state.field_direction, sim._plan)
stress = np.zeros((N_CONTRIBUTIONS, 3, 3))
dipolophoresis_term(positions, 0.37, sim._params, field, stress)
best = []
for strain in (0.37, 0.5, 0.68):
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        dipolophoresis_term(positions, strain, sim._params, field, stress)
        times.append(time.perf_counter() - t0)
    best.append(1e3 * min(times))
print(min(best), sim._plan.splitting, sim._plan.real_cutoff, sim._plan.k_cutoff)
"""


def _env(tree: str) -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=tree, NUMBA_NUM_THREADS="1")


def _env_jobs(trees: dict[str, str], jobs: str, steps: int) -> None:
    """Part 3 of the module docstring: whole steps at the environments' settings, both trees interleaved."""
    script = str(Path(__file__).resolve().parent / "step_profile.py")
    rows: dict[tuple[int, float, str], list[dict]] = {}
    for job in [j for j in jobs.split(",") if j]:
        n_text, mason, reps_text = job.split(":")
        for rep in range(int(reps_text)):
            for tag in ("before", "after") if rep % 2 == 0 else ("after", "before"):
                cmd = [
                    sys.executable,
                    script,
                    "--whole-only",
                    "--n",
                    n_text,
                    "--mason",
                    mason,
                    "--steps",
                    str(steps),
                ]
                proc = subprocess.run(
                    cmd, cwd=trees[tag], env=_env(trees[tag]), capture_output=True, text=True
                )
                if proc.returncode != 0:
                    sys.exit(proc.stderr)
                rows.setdefault((int(n_text), float(mason), tag), []).append(
                    json.loads(proc.stdout.strip().splitlines()[-1])
                )
    if not rows:
        return
    print(
        "\n| N | Mn | tree | runs | ms/step min / median | steps/strain | s/strain min / median | PCG iters |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for (n, mason, tag), rs in sorted(rows.items(), key=lambda item: (item[0][0], -item[0][1], item[0][2])):
        ms = [r["ms_step"] for r in rs]
        sps = [r["seconds_per_strain"] for r in rs]
        print(
            f"| {n} | {mason:g} | {tag} | {len(rs)} | {min(ms):.2f} / {statistics.median(ms):.2f} "
            f"| {rs[0]['steps_per_strain']:.0f} | {min(sps):.2f} / {statistics.median(sps):.2f} "
            f"| {rs[0]['iterations_mean']:.1f} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("--jobs", default="64:1:6,64:inf:4,500:1:3,500:inf:2")
    parser.add_argument("--term-sizes", default="64,250,500")
    parser.add_argument("--term-reps", default="1000,150,150")
    parser.add_argument("--env-jobs", default="")
    parser.add_argument("--env-steps", type=int, default=100)
    args = parser.parse_args()
    trees = {"before": str(Path(args.before).resolve()), "after": str(Path(args.after).resolve())}
    rows: dict[tuple[int, str, str], list[dict]] = {}
    for job in [j for j in args.jobs.split(",") if j]:
        n_text, mason, reps_text = job.split(":")
        for rep in range(int(reps_text)):
            for tag in ("before", "after") if rep % 2 == 0 else ("after", "before"):
                cmd = [
                    sys.executable,
                    "benchmarks/run.py",
                    "--child",
                    n_text,
                    "--child-mason",
                    mason,
                    "--child-near-field",
                    "none" if mason == "inf" else "exact",
                    "--phi",
                    "0.45",
                    "--steps",
                    "500",
                    "--warmup-strain",
                    "3",
                ]
                proc = subprocess.run(
                    cmd, cwd=trees[tag], env=_env(trees[tag]), capture_output=True, text=True
                )
                if proc.returncode != 0:
                    sys.exit(proc.stderr)
                rows.setdefault((int(n_text), mason, tag), []).append(
                    json.loads(proc.stdout.strip().splitlines()[-1])
                )
    if rows:
        print(
            "| N | Mn | tree | runs | ms/step min / median | shear term ms | DIP term ms | s/strain "
            "| PCG iters |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for (n, mason, tag), rs in sorted(rows.items()):

            def stat(key: str, rs: list[dict] = rs) -> str:
                values = [r[key] for r in rs]
                return f"{min(values):.2f} / {statistics.median(values):.2f}"

            print(
                f"| {n} | {mason} | {tag} | {len(rs)} | {stat('ms_step')} | {stat('ms_shear_term')} "
                f"| {stat('ms_dip_term')} | {stat('seconds_per_strain')} | {rs[0]['iterations_mean']:.1f} |"
            )
    _env_jobs(trees, args.env_jobs, args.env_steps)
    sizes = [int(s) for s in args.term_sizes.split(",") if s]
    reps = [int(s) for s in args.term_reps.split(",") if s]
    if sizes:
        print("\n| N | tree | DIP term ms (min) | xi | r_c | k_c |")
        print("|---|---|---|---|---|---|")
        for n, r in zip(sizes, reps, strict=True):
            for tag in ("before", "after"):
                proc = subprocess.run(
                    [sys.executable, "-c", TERM_SCRIPT, str(n), str(r)],
                    cwd=trees[tag],
                    env=_env(trees[tag]),
                    capture_output=True,
                    text=True,
                )
                if proc.returncode != 0:
                    sys.exit(proc.stderr)
                ms, xi, rc, kc = (float(v) for v in proc.stdout.split())
                print(f"| {n} | {tag} | {ms:.3f} | {xi:.3f} | {rc:.2f} | {kc:.2f} |", flush=True)


if __name__ == "__main__":
    main()
