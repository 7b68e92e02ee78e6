"""End-to-end demo: open-loop baseline, brief PPO training and evaluation on the tiny environment.

    python -m agents.demo --out runs/demo [--timesteps 2048] [--seeds 0-1] [--resume | --overwrite]

1. ``agents.open_loop`` on ``dipenv/FieldMagnitudeTiny-v0``: constant fields (off, Mn = 5, 1, 0.3, 0.1)
   on the test start states -> ``OUT/open_loop``, and on the validation states -> ``OUT/open_loop_validation``
   (the states on which training validates: the learning curve's baseline);
2. ``agents.train`` PPO for ``--timesteps`` environment steps per seed -> ``OUT/ppo/seed<k>``;
3. ``agents.evaluate`` of the PPO runs against the baseline -> ``OUT/evaluation`` (a compact table printed;
   the full tables in ``OUT/evaluation/table.md`` and ``verdict.md``, the plots beside them).

Everything is resumable (a rerun reuses finished parts). ``OUT`` follows the run-folder protocol
(:mod:`agents.folders`): its ``manifest.json`` records ``--timesteps`` and ``--seeds``, so a rerun with
other values is refused (exit 2) instead of reusing runs of another length; ``--overwrite`` deletes the
whole previous demo. The tiny env (N = 32, 0.2-strain episodes) shows the machinery, not the physics: its
episodes are shorter than the microstructure's relaxation strain.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents import evaluate, open_loop, train
from agents.folders import add_folder_options, claim_out, command_line, legacy_markers
from agents.usage import directory, integer_at_least, output_directory, seed_list

ENV_ID = "dipenv/FieldMagnitudeTiny-v0"
PROG = "python -m agents.demo"
MASON = "off,5,1,0.3,0.1"


def legacy(out: Path) -> list[str]:
    """A demo folder made before manifests: its open-loop stage's ``command.txt`` names the tiny env."""
    stage = out / "open_loop" / "command.txt"
    markers = legacy_markers(out / "open_loop", (), "agents.open_loop")
    try:
        tiny = ENV_ID in stage.read_text()
    except (OSError, UnicodeDecodeError):
        tiny = False
    return ["open_loop/command.txt"] if markers and tiny else []


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--out", type=directory, default=Path("runs/demo"))
    parser.add_argument("--timesteps", type=integer_at_least(1), default=2048, help="per seed, >= 1")
    parser.add_argument("--seeds", type=seed_list, default="0-1", help="training seeds: 0-1 or 0,2,5-7")
    add_folder_options(parser)
    args = parser.parse_args(argv)  # every argument checked here, before any stage runs
    output_directory(PROG, args.out)
    seeds = ",".join(str(s) for s in args.seeds)
    claim_out(
        PROG,
        args.out,
        "agents.demo",
        {"env_id": ENV_ID, "mason": MASON, "timesteps": args.timesteps, "seeds": args.seeds},
        argv=command_line("agents.demo", argv),
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy(args.out),
    )
    tic = time.perf_counter()
    print("== 1/3 open-loop baselines (constant fields; test and validation states) ==", flush=True)
    open_loop.main(["--env", ENV_ID, "--out", str(args.out / "open_loop"), "--mason", MASON])
    validation = args.out / "open_loop_validation"
    open_loop.main(["--env", ENV_ID, "--out", str(validation), "--mason", MASON, "--split", "validation"])
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
            "--validation-baseline",
            str(validation),
            "--out",
            str(args.out / "evaluation"),
        ]
    )
    print(f"demo finished in {time.perf_counter() - tic:.0f} s; plots in {args.out / 'evaluation'}")


if __name__ == "__main__":
    main()
