"""Cost of one environment per strain at each constant field: simulator steps, seconds, solver work.

    python benchmarks/env_cost.py [--env dipenv/FieldMagnitude-v0] [--mason off,20,5,2,1,0.5,0.2,0.1,0.05]
        [--intervals 8] [--states 2] [--skip 2] [--rates 0.2,1,5]

``--rates`` (thickening-control ids only) holds each shear rate constant over the episode (a one-hold
schedule given to ``reset``) and adds a row per rate and field: the cost per unit *time* grows with the
rate (more strain per interval), the cost per strain much less. Strain and time are both reported.

For each field, ``--states`` training start states each hold the constant field for ``--skip`` untimed
intervals (the structure adapts to the field: switching on at low Mn costs more at first) and then
``--intervals`` timed ones. Printed per field: simulator steps per strain (the adaptive step at low Mn),
seconds per strain and per simulator step, mean PCG iterations and overlap-removal sweeps per step. One
process; the numbers are for the machine and load printed in the header (1-minute load average).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from typing import Any

import numpy as np

from agents.open_loop import constant_action, parse_mason
from agents.rollout import make_env


def measure(
    env_id: str, mason: float, states: int, skip: int, intervals: int, rate: float | None = None
) -> dict[str, float]:
    env = make_env(env_id, {"progress": False})
    seconds = strain = duration = 0.0
    steps = 0
    iterations, sweeps = [], []
    unwrapped: Any = env.unwrapped
    # the vector env's field along y, the magnitude env's direction
    direction = "y" if unwrapped.vector_field else None
    action = np.array(constant_action(unwrapped, mason, direction), dtype=np.float32)
    for index in range(states):
        options: dict[str, Any] = {"split": "train", "index": index}
        if rate is not None:
            options["schedule"] = {"times": [0.0, 1e6], "rates": [rate, rate]}
        env.reset(seed=0, options=options)
        for _ in range(skip):
            env.step(action)
        for _ in range(intervals):
            tic = time.perf_counter()
            _, _, terminated, truncated, info = env.step(action)
            seconds += time.perf_counter() - tic
            if info["simulation_failed"]:
                raise RuntimeError(f"Mn {mason}: {info['failure_message']}")
            interval = env.unwrapped.control_interval  # type: ignore[attr-defined]
            duration += interval
            strain += interval * (1.0 if rate is None else rate)
            steps += info["sim_steps"]
            iterations.append(info["solver_iterations"] * info["sim_steps"])
            sweeps.append(info["overlap_sweeps"] * info["sim_steps"])
    env.close()
    return {
        "steps_per_strain": steps / strain,
        "seconds_per_strain": seconds / strain,
        "seconds_per_time": seconds / duration,
        "ms_per_step": 1e3 * seconds / steps,
        "iterations": float(np.sum(iterations)) / steps,
        "sweeps": float(np.sum(sweeps)) / steps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", default="dipenv/FieldMagnitude-v0")
    parser.add_argument("--mason", default="off,20,5,2,1,0.5,0.2,0.1,0.05")
    parser.add_argument("--intervals", type=int, default=8)
    parser.add_argument("--states", type=int, default=2)
    parser.add_argument("--skip", type=int, default=2)
    parser.add_argument("--rates", default=None, help="constant shear rates (thickening-control ids)")
    args = parser.parse_args()
    rates: list[float | None] = [None]
    if args.rates is not None:
        try:
            rates = [float(r) for r in args.rates.split(",")]
        except ValueError:
            parser.error(f"--rates takes numbers separated by commas, got {args.rates!r}")
        if any(not (math.isfinite(r) and r > 0) for r in rates if r is not None):
            parser.error(f"--rates must be finite and > 0, got {args.rates!r}")
    for name in ("intervals", "states"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    if args.skip < 0:
        parser.error(f"--skip must be >= 0, got {args.skip}")
    try:
        masons = parse_mason(args.mason)
    except ValueError:
        parser.error(f"--mason takes 'off' or numbers separated by commas, got {args.mason!r}")
    if any(not (m > 0) for m in masons):
        parser.error(f"--mason values must be > 0 (or 'off'), got {args.mason!r}")
    env = make_env(args.env, {"progress": True})
    if args.rates is not None and not hasattr(env.unwrapped, "fixed_schedule"):
        parser.error(f"--rates needs a thickening-control env, not {args.env}")
    env.unwrapped.library().ensure(["train"])  # type: ignore[attr-defined]
    env.close()
    measure(args.env, 1.0, 1, 0, 1)  # compiled-kernel cache loaded, not timed
    print(
        f"{args.env}; {args.states} states x {args.intervals} intervals after {args.skip} untimed; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at start"
    )
    print(
        "| rate | Mn_ref | steps/strain | s/strain | s/time | ms/step | PCG iterations/step "
        "| overlap sweeps/step |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for rate in rates:
        for mason in masons:
            r = measure(args.env, mason, args.states, args.skip, args.intervals, rate)
            label = "off" if math.isinf(mason) else f"{mason:g}"
            print(
                f"| {'1 (fixed)' if rate is None else f'{rate:g}'} | {label} | {r['steps_per_strain']:.0f} "
                f"| {r['seconds_per_strain']:.2f} | {r['seconds_per_time']:.2f} | {r['ms_per_step']:.2f} "
                f"| {r['iterations']:.0f} | {r['sweeps']:.2f} |",
                flush=True,
            )
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
