"""Simulator steps and seconds of whole episodes at several displacement bounds (issue 21, issue 22).

    python benchmarks/episode_cost.py [--env dipenv/ThickeningControl-v2] [--bounds 0.004,0.008]
        [--policies 0.5,random] [--split test] [--index 0]

Each row plays one whole episode of ``--env`` from start state ``--index`` of ``--split`` (the same
schedule and state in every row) with the simulator's displacement bound ``max_displacement`` set to
one of ``--bounds`` (a ``simulation_overrides`` env argument: the start states stay those of the
library) and one of ``--policies``: a constant ``Mn_ref`` (a number, or ``off``) or ``random`` (uniform
actions from a generator seeded with 0, what an untrained policy plays). Printed: simulator steps, wall
seconds, the second-half mean of the interval eta_r (one episode: chaotic noise of about 0.8, not a bias
test; ``benchmarks/displacement_bound.py`` is that), and per row the ratio of steps and seconds to the
first bound's. This is what training with a coarser step saves (docs/thickening_control.md#coarse-training).
One process; the header prints the 1-minute load average (timings under load scatter; step counts do not).
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

import sim
from agents.open_loop import constant_action, parse_mason
from agents.rollout import make_env

_STEPS = [0]
_advance_to = sim.Simulation.advance_to


def _counting_advance_to(self: sim.Simulation, *args: Any, **kwargs: Any) -> sim.StepRecords:
    """``Simulation.advance_to`` that counts the steps it takes (the env does not report them)."""
    records = _advance_to(self, *args, **kwargs)
    _STEPS[0] += len(records.time)
    return records


def play(env_id: str, bound: float, policy: str, split: str, index: int) -> dict[str, float]:
    """One episode; returns simulator steps, wall seconds and the second-half mean eta_r."""
    env = make_env(env_id, {"progress": False, "simulation_overrides": {"max_displacement": bound}})
    unwrapped: Any = env.unwrapped
    env.reset(seed=0, options={"split": split, "index": index})
    rng = np.random.default_rng(0)
    fixed = None
    if policy != "random":
        fixed = np.asarray(constant_action(unwrapped, parse_mason(policy)[0], None), dtype=np.float32)
    sim.Simulation.advance_to = _counting_advance_to  # type: ignore[method-assign]
    _STEPS[0] = 0
    etas, done = [], False
    start = time.perf_counter()
    while not done:
        action = fixed if fixed is not None else rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        etas.append(info["eta_r"])
        done = terminated or truncated
    seconds = time.perf_counter() - start
    env.close()
    sim.Simulation.advance_to = _advance_to  # type: ignore[method-assign]
    return {"steps": _STEPS[0], "seconds": seconds, "eta": float(np.mean(etas[len(etas) // 2 :]))}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2")
    parser.add_argument("--bounds", default="0.004,0.008", help="max_displacement values (units of a)")
    parser.add_argument("--policies", default="0.5,random", help="constant Mn_ref values, off, or random")
    parser.add_argument("--split", default="test", choices=("train", "validation", "test"))
    parser.add_argument("--index", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        bounds = [float(b) for b in args.bounds.split(",")]
    except ValueError:
        parser.error(f"--bounds must be comma-separated numbers, got {args.bounds!r}")
    if not all(b > 0 for b in bounds):
        parser.error(f"--bounds must be > 0, got {args.bounds!r}")
    policies = args.policies.split(",")
    for policy in policies:
        if policy != "random":
            try:
                parse_mason(policy)
            except ValueError as error:
                parser.error(f"--policies: {error}")
    print(f"# {args.env}, {args.split} state {args.index}, one process, load {os.getloadavg()[0]:.2f}")
    print(
        "| policy | bound | simulator steps | seconds | eta_r, 2nd half | steps / first | seconds / first |"
    )
    print("|---|---|---|---|---|---|---|")
    for policy in policies:
        first: dict[str, float] | None = None
        for bound in bounds:
            row = play(args.env, bound, policy, args.split, args.index)
            first = first or row
            print(
                f"| {policy} | {bound:g} | {row['steps']:.0f} | {row['seconds']:.1f} | {row['eta']:.3f} | "
                f"{row['steps'] / first['steps']:.2f} | {row['seconds'] / first['seconds']:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
