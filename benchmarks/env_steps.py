"""Environment steps per second of every dipenv id at its defaults: one process, and a SubprocVecEnv.

    python benchmarks/env_steps.py [--ids ...] [--steps 16] [--tiny-steps 100] [--n-envs 2] [--policy random]
        [--seeds 1]

Each env takes ``--steps`` actions (``--tiny-steps`` for the tiny ids) from a seeded policy: ``random``
(uniform in the action box; it spends time at low Mn, where the simulator takes up to 14x more steps per
strain), ``gaussian`` (a unit Gaussian clipped to the box, as an untrained SB3 PPO policy acts: 16% of its
actions sit at each end, ``u = 1`` being the strongest field) or ``constant:U`` (e.g. ``constant:-1`` = no
field). ``--n-envs 1`` skips the ``SubprocVecEnv`` column (for a machine whose other core is busy);
``--seeds K`` repeats the one-process run from K start states and action sequences, the ids interleaved
(so that a drifting load hits them alike), and prints the mean and each seed's steps/s.
Start states are generated first (not timed). The last column projects the wall time of 10^4 steps with
``--n-envs`` processes (the issue's target: under one hour on the 2-core machine). Measurements on a
shared machine are indicative; the table says how loaded it was (1-minute load average).
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import time

import numpy as np
from stable_baselines3.common.vec_env import SubprocVecEnv

import dipenv
from agents.rollout import make_env


def policy_actions(spec: str, shape: tuple[int, ...], n: int, seed: int) -> np.ndarray:
    if spec == "random":
        return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(n, *shape)).astype(np.float32)
    if spec == "gaussian":
        return np.clip(np.random.default_rng(seed).normal(size=(n, *shape)), -1.0, 1.0).astype(np.float32)
    value = float(spec.split(":", 1)[1])
    return np.full((n, *shape), value, dtype=np.float32)


def one_process(env_id: str, steps: int, policy: str, seed: int = 0) -> tuple[float, float]:
    env = make_env(env_id, {"progress": True})
    env.reset(seed=seed)
    actions = policy_actions(policy, env.action_space.shape, steps, seed=seed)
    strain = 0.0
    tic = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, info = env.step(action)
        strain += env.unwrapped.control_interval  # type: ignore[attr-defined]
        if terminated or truncated:
            env.reset()
    seconds = time.perf_counter() - tic
    return steps / seconds, strain / seconds


def vectorised(env_id: str, steps: int, policy: str, n_envs: int) -> float:
    venv = SubprocVecEnv([functools.partial(make_env, env_id, {"progress": False}) for _ in range(n_envs)])
    venv.seed(0)
    venv.reset()
    actions = policy_actions(policy, venv.action_space.shape, steps * n_envs, seed=1).reshape(
        steps, n_envs, *venv.action_space.shape
    )
    venv.step(actions[0])  # start-up (imports, compiled-kernel cache) not timed
    tic = time.perf_counter()
    for action in actions[1:]:
        venv.step(action)
    seconds = time.perf_counter() - tic
    venv.close()
    return (steps - 1) * n_envs / seconds


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--ids", nargs="*", default=list(dipenv.ENV_IDS))
    parser.add_argument("--steps", type=int, default=16)
    parser.add_argument("--tiny-steps", type=int, default=100)
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--policy", default="random", help="random, gaussian or constant:U")
    parser.add_argument("--seeds", type=int, default=1, help="one-process repeats (start states, actions)")
    args = parser.parse_args()
    for name in ("steps", "tiny_steps", "n_envs", "seeds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")  # exit 2
    if args.policy not in ("random", "gaussian"):
        prefix, _, value = args.policy.partition(":")
        try:
            constant = float(value) if prefix == "constant" else math.nan
        except ValueError:
            constant = math.nan
        if not -1.0 <= constant <= 1.0:
            parser.error(
                f"--policy must be random, gaussian or constant:U with U in [-1, 1], got {args.policy!r}"
            )
    for env_id in args.ids:  # generate the start states first, untimed
        env = make_env(env_id, {"progress": True})
        env.unwrapped.library().ensure(["train"])  # type: ignore[attr-defined]
        env.close()
    print(f"policy {args.policy}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at start")
    print(f"| env id | steps/s (1 process) | strain/s | steps/s ({args.n_envs} processes) | 10^4 steps |")
    print("|---|---|---|---|---|")
    single: dict[str, list[tuple[float, float]]] = {env_id: [] for env_id in args.ids}
    for seed in range(args.seeds):
        for env_id in args.ids:
            steps = args.tiny_steps if "Tiny" in env_id else args.steps
            single[env_id].append(one_process(env_id, steps, args.policy, seed))
    for env_id in args.ids:
        steps = args.tiny_steps if "Tiny" in env_id else args.steps
        rate, strain_rate = (float(np.mean(column)) for column in zip(*single[env_id], strict=True))
        label = env_id
        if args.seeds > 1:
            label += " (seeds: " + ", ".join(f"{r:.3g}" for r, _ in single[env_id]) + ")"
        if args.n_envs == 1:
            print(f"| {label} | {rate:.3g} | {strain_rate:.3g} | | {1e4 / rate / 3600:.2f} h |", flush=True)
            continue
        vec_rate = vectorised(env_id, max(steps // args.n_envs, 2), args.policy, args.n_envs)
        hours = 1e4 / vec_rate / 3600
        print(f"| {label} | {rate:.3g} | {strain_rate:.3g} | {vec_rate:.3g} | {hours:.2f} h |", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
