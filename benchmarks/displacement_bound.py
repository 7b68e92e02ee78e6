"""Does a looser displacement bound change what an environment measures? Bias against noise at low Mn.

    python benchmarks/displacement_bound.py [--mason 0.2,0.1] [--bounds 0.004,0.008,0.016] [--states 8]
        [--strain 12] [--env dipenv/FieldMagnitude-v0] [--out FILE.json]

At low Mn the adaptive step, which keeps every particle's non-affine displacement per step below
``max_displacement`` times the mean spacing (the paper's 0.4%), sets the cost of an environment step
(1500-3800 steps per strain at Mn <= 0.2 against 500 at Mn >= 1). For each field and each bound, every one
of the first ``--states`` test start states of the environment's library holds the field for ``--strain``
strains (an episode), from the same state, with the environment's other simulator settings. Per run: the
time-averaged eta_r, N1 and N2 over the second half (what the environment's episode metric sees) and the
simulator steps per strain. Printed per field and bound: the mean over states, the paired difference from
the tightest bound with its standard error over states, the noise (the standard deviation over states of
an episode's average, what one episode shows an agent), and the cost. A bound is harmless where the
paired bias is much smaller than that noise. One process; the load is printed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import replace
from typing import Any

import numpy as np

import sim
from agents.open_loop import parse_mason
from agents.rollout import make_env


def run(env_id: str, mason: float, bound: float, index: int, strain: float) -> dict[str, float]:
    env = make_env(env_id, {"progress": False})
    unwrapped: Any = env.unwrapped
    unwrapped.library().ensure(["test"], progress=False)
    start = unwrapped.library().load("test", index, progress=False)
    config = replace(unwrapped.base_config, max_displacement=bound)
    env.close()
    simulation = sim.Simulation(config, state=start.state)
    simulation.set_field(mason, (0.0, 1.0, 0.0))
    t0 = simulation.state.time
    tic = time.perf_counter()
    records = simulation.advance_to(t0 + strain)
    seconds = time.perf_counter() - tic
    result = sim.summarise(records, from_time=t0 + strain / 2)
    return {
        "eta": result.relative_viscosity,
        "n1": result.n1,
        "n2": result.n2,
        "steps_per_strain": records.time.size / strain,
        "seconds_per_strain": seconds / strain,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", default="dipenv/FieldMagnitude-v0")
    parser.add_argument("--mason", default="0.2,0.1")
    parser.add_argument("--bounds", default="0.004,0.008,0.016")
    parser.add_argument("--states", type=int, default=8)
    parser.add_argument("--strain", type=float, default=12.0)
    parser.add_argument("--out", default=None, help="write every run's numbers here (JSON)")
    args = parser.parse_args()
    masons = parse_mason(args.mason)
    bounds = [float(b) for b in args.bounds.split(",")]
    if any(not (0 < b <= 0.05) for b in bounds):
        parser.error(f"--bounds must lie in (0, 0.05], got {args.bounds}")
    if not 1 <= args.states <= 16:
        parser.error(f"--states must be in [1, 16] (the test split), got {args.states}")
    print(f"# {args.env}, {args.states} test states, {args.strain} strains, load {os.getloadavg()[0]:.2f}")
    runs: dict[str, Any] = {}
    print(
        "| Mn | bound | eta_r | d eta_r vs tightest (paired, ± se) | N1 | d N1 | N2 | d N2 | noise of eta_r "
        "(sd over states) | steps/strain | s/strain |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for mason in masons:
        table = {b: [run(args.env, mason, b, i, args.strain) for i in range(args.states)] for b in bounds}
        runs[str(mason)] = {str(b): rows for b, rows in table.items()}
        reference = table[bounds[0]]
        for b in bounds:
            rows = table[b]

            def values(key: str, rows: list[dict[str, float]] = rows) -> np.ndarray:
                return np.array([r[key] for r in rows])

            def paired(
                key: str, rows: list[dict[str, float]] = rows, reference: list[dict[str, float]] = reference
            ) -> str:
                d = values(key, rows) - np.array([r[key] for r in reference])
                se = d.std(ddof=1) / math.sqrt(d.size) if d.size > 1 else math.nan
                return f"{d.mean():+.3f} ± {se:.3f}"

            print(
                f"| {mason:g} | {b:g} | {values('eta').mean():.3f} | {paired('eta')} "
                f"| {values('n1').mean():.2f} | {paired('n1')} "
                f"| {values('n2').mean():.2f} | {paired('n2')} | "
                f"{values('eta').std(ddof=1) if len(rows) > 1 else math.nan:.3f} | "
                f"{values('steps_per_strain').mean():.0f} | {values('seconds_per_strain').mean():.2f} |",
                flush=True,
            )
    if args.out:
        with open(args.out, "w") as handle:
            json.dump({"args": vars(args), "runs": runs}, handle, indent=1)


if __name__ == "__main__":
    main()
