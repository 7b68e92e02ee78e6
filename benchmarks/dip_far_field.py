"""Cost and accuracy of the periodic far-field DIP sums: one command, one table.

    python benchmarks/dip_far_field.py [--sizes 64,250,500,1000,2000,4000] [--phi 0.45] [--accuracy 1e-6]
                                       [--repeats 20] [--methods ewald,spme]

For each N a random hard-sphere packing at ``phi`` (``sim.geometry.configurations.random_packing``,
seed 1, cached under ``/tmp/dip_far_field_bench``) in the box ``L = (N (4/3) pi / phi)^(1/3)`` is
sheared to strain 0.37 (Lees–Edwards offset ``0.37 L``), and ``dip_far_field`` (DIP, field along ``y``,
velocities and both stress sums) is timed for each method with the plan ``ewald_plan(L, N, accuracy,
method)`` (JIT compilation excluded; median CPU time of ``--repeats`` calls, one thread: equal to the
wall time on an idle core, and robust on a shared machine). ``error`` is the rms
velocity error relative to the rms velocity against a reference Ewald sum at ``accuracy = 1e-11``;
``stress err`` is the largest stress-component error relative to the largest component.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

CACHE = Path("/tmp/dip_far_field_bench")


def configuration(n: int, phi: float) -> np.ndarray:
    from sim.geometry.configurations import random_packing

    CACHE.mkdir(parents=True, exist_ok=True)
    path = CACHE / f"packing_n{n}_phi{phi:.3f}_seed1.npy"
    if path.exists():
        return np.load(path)
    positions = random_packing(n, phi, 1)
    np.save(path, positions)
    return positions


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", default="64,250,500,1000,2000,4000")
    parser.add_argument("--phi", type=float, default=0.45)
    parser.add_argument("--accuracy", type=float, default=1e-6)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--methods", default="ewald,spme")
    args = parser.parse_args()

    from sim.dipolophoresis.ewald import dip_far_field, ewald_plan
    from sim.geometry.box import lees_edwards_offset
    from sim.geometry.configurations import box_length_for

    direction = np.array([0.0, 1.0, 0.0])
    print(f"phi = {args.phi}, accuracy = {args.accuracy:g}, strain 0.37, DIP, e = y")
    header = f"{'N':>6} {'method':>7} {'ms/call':>9} {'error':>9} {'stress err':>10}  plan"
    print(header)
    print("-" * len(header))
    for n in [int(s) for s in args.sizes.split(",")]:
        box = box_length_for(n, args.phi)
        positions = configuration(n, args.phi)
        offset = float(lees_edwards_offset(0.37, box))
        reference_plan = ewald_plan(box, n, 1e-11, "ewald", mechanism="all")
        ref_velocity, ref_icep, ref_dep = dip_far_field(
            positions, box, offset, direction, 1.0, 1.0, reference_plan
        )
        ref_rms = float(np.sqrt(np.mean(np.sum(ref_velocity**2, axis=1))))
        ref_stress = np.concatenate([ref_icep.ravel(), ref_dep.ravel()])
        for method in args.methods.split(","):
            plan = ewald_plan(box, n, args.accuracy, method)
            velocity, icep, dep = dip_far_field(positions, box, offset, direction, 1.0, 1.0, plan)
            times = []
            for _ in range(args.repeats):
                t0 = time.process_time()
                dip_far_field(positions, box, offset, direction, 1.0, 1.0, plan)
                times.append(time.process_time() - t0)
            error = float(np.sqrt(np.mean(np.sum((velocity - ref_velocity) ** 2, axis=1)))) / ref_rms
            stress = np.concatenate([icep.ravel(), dep.ravel()])
            stress_error = float(np.max(np.abs(stress - ref_stress)) / np.max(np.abs(ref_stress)))
            desc = f"xi={plan.splitting:.3f} rc={plan.real_cutoff:.2f} kc={plan.k_cutoff:.2f}"
            if plan.method == 1:
                desc += f" mesh={plan.mesh} p={plan.order}"
            ms = 1e3 * float(np.median(times))
            print(f"{n:>6} {method:>7} {ms:>9.3f} {error:>9.2e} {stress_error:>10.2e}  {desc}", flush=True)


if __name__ == "__main__":
    main()
