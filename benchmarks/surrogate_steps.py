"""Environment steps per second of the surrogate ids (issue 43: at least 10^3 on one core), the tracking
surrogate's (issue 44; three action components: strength, polar and azimuthal angle) among them.

    python benchmarks/surrogate_steps.py [--ids ...] [--models PATH ...] [--steps 20000] [--seeds 3]
        [--policy gaussian]

Each id is made with ``gymnasium.make`` (its default wrappers: the passive checker and the order
enforcer, as an agent meets it) and takes ``--steps`` actions from a seeded policy (``random``: uniform in
the box; ``gaussian``: a unit Gaussian clipped to the box, as an untrained PPO acts), resetting after every
48-step episode (resets are timed too). ``--models`` adds a row per model file (e.g. the other route's).
One process, one thread. The table gives wall-clock steps/s and CPU-time steps/s (``time.process_time``;
on a loaded machine the wall clock also counts the other processes' share of the core), with the
1-minute load average.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import dipenv  # noqa: E402,F401  (registers the ids)

IDS = (
    "dipenv/ThickeningControlSurrogate-v0",
    "dipenv/ThickeningControlSurrogateStressOnly-v0",
    "dipenv/ViscosityTrackingSurrogate-v0",
)


def actions(policy: str, n: int, seed: int, width: int = 1) -> np.ndarray:
    """``n`` actions of ``width`` components in [-1, 1] (every id here has a box of that range)."""
    rng = np.random.default_rng(seed)
    if policy == "random":
        return rng.uniform(-1.0, 1.0, size=(n, width)).astype(np.float32)
    return np.clip(rng.normal(size=(n, width)), -1.0, 1.0).astype(np.float32)


def measure(env_id: str, model: str | None, steps: int, policy: str, seed: int) -> tuple[float, float, str]:
    kwargs = {} if model is None else {"model": model}
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    plan = actions(policy, steps, seed, width=int(np.prod(env.action_space.shape)))
    wall, cpu = time.perf_counter(), time.process_time()
    for action in plan:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    kind = env.unwrapped.model.kind  # type: ignore[attr-defined]
    env.close()
    return steps / wall, steps / cpu, kind


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("--ids", nargs="+", default=list(IDS))
    parser.add_argument("--models", nargs="*", default=[], help="further model files (rows on the first id)")
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--policy", choices=("random", "gaussian"), default="gaussian")
    args = parser.parse_args(argv)
    rows: list[tuple[str, str | None]] = [(i, None) for i in args.ids]
    rows += [(args.ids[0], m) for m in args.models]
    load = os.getloadavg()[0]
    print(f"steps per run {args.steps}, {args.seeds} seeds, policy {args.policy}, 1-min load {load:.1f}")
    print()
    print("| id | model | wall steps/s (per seed) | CPU steps/s (per seed) |")
    print("|---|---|---|---|")
    for env_id, model in rows:
        walls, cpus, kind = [], [], ""
        for seed in range(args.seeds):
            w, c, kind = measure(env_id, model, args.steps, args.policy, seed)
            walls.append(w)
            cpus.append(c)
        label = f"{kind} ({Path(model).name})" if model else f"{kind} (shipped)"
        print(
            f"| `{env_id}` | {label} | {np.mean(walls):.0f} ({', '.join(f'{w:.0f}' for w in walls)}) | "
            f"{np.mean(cpus):.0f} ({', '.join(f'{c:.0f}' for c in cpus)}) |"
        )
    print(f"\n1-min load at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
