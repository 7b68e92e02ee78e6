"""End-to-end demo: open-loop baseline, brief PPO training and evaluation on the tiny environment.

    python -m agents.demo --out runs/demo [--timesteps 2048] [--seeds 0-1]

1. ``agents.open_loop`` on ``dipenv/FieldMagnitudeTiny-v0``: constant fields (off, Mn = 5, 1, 0.3, 0.1)
   on the test start states -> ``OUT/open_loop``;
2. ``agents.train`` PPO for ``--timesteps`` environment steps per seed -> ``OUT/ppo/seed<k>``;
3. ``agents.evaluate`` of the PPO runs against the baseline -> ``OUT/evaluation`` (table printed).

Everything is resumable (a rerun reuses finished parts). The tiny env (N = 32, 0.2-strain episodes) shows
the machinery, not the physics: its episodes are shorter than the microstructure's relaxation strain.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents import evaluate, open_loop, train
from agents.usage import directory, integer_at_least, output_directory, seed_list

ENV_ID = "dipenv/FieldMagnitudeTiny-v0"
PROG = "python -m agents.demo"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--out", type=directory, default=Path("runs/demo"))
    parser.add_argument("--timesteps", type=integer_at_least(1), default=2048, help="per seed, >= 1")
    parser.add_argument("--seeds", type=seed_list, default="0-1", help="training seeds: 0-1 or 0,2,5-7")
    args = parser.parse_args(argv)  # every argument checked here, before any stage runs
    output_directory(PROG, args.out)
    seeds = ",".join(str(s) for s in args.seeds)
    tic = time.perf_counter()
    print("== 1/3 open-loop baseline (constant fields) ==", flush=True)
    open_loop.main(["--env", ENV_ID, "--out", str(args.out / "open_loop"), "--mason", "off,5,1,0.3,0.1"])
    print(f"== 2/3 PPO training ({args.timesteps} steps per seed, seeds {seeds}) ==", flush=True)
    train.main(
        [
            "--env",
            ENV_ID,
            "--algo",
            "ppo",
            "--seeds",
            seeds,
            "--out",
            str(args.out / "ppo"),
            "--timesteps",
            str(args.timesteps),
        ]
    )
    print("== 3/3 evaluation on the test start states ==", flush=True)
    evaluate.main(
        [
            str(args.out / "ppo"),
            "--baseline",
            str(args.out / "open_loop"),
            "--out",
            str(args.out / "evaluation"),
        ]
    )
    print(f"demo finished in {time.perf_counter() - tic:.0f} s; plots in {args.out / 'evaluation'}")


if __name__ == "__main__":
    main()
