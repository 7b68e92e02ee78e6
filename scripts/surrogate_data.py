"""Training data for the thickening-control surrogate (issue 43): simulator episodes under varied fields.

Plays ``ThickeningControl-v2`` (N = 300) from the **train** split's start states, with the schedules the
environment draws for training episodes (never the validation, test or fresh schedules), under a mixture
of behaviour policies chosen per episode from its seed, so that the data cover what a controller may do:

============ ===========================================================================================
``hold``     piecewise-constant random fields: each interval keeps the previous action with probability
             0.7, else draws a new one (off with probability 0.2, else ``u`` uniform in ``[-0.9, 1]``)
``pulse``    a strong field (``u`` in ``[0.2, 1]``) on for ``k_on`` and off (or weak) for ``k_off``
             intervals (1-3 each), the pulse controllers' and PPO's pattern at high rates
``constant`` one action, drawn as in ``hold``, for the whole episode
``follow``   a rate-following field ``u = c0 + c1 log10(rate)`` with random ``c0``, ``c1`` and per-interval
             noise (the feed-forward's pattern)
============ ===========================================================================================

Episode ``s`` uses train start state ``s mod 64`` (the train split's size), the env seed ``s`` (which
draws its schedule) and behaviour ``BEHAVIOURS[s mod 4]`` with parameters drawn from
``numpy.random.default_rng(s)``: a pure function of ``s``.

Seeds from :data:`POLICY_SEED0` (100,000) on play a **trained policy** instead (``--policies DIR``, an
``agents.train`` folder with ``seed<k>/model.zip`` and ``vecnormalize.pkl``): episode ``s`` uses the
policy of the ``(s - 100000) mod K``-th seed folder (sorted), its actions sampled (not the mean), with
``torch.manual_seed(s)``. These episodes cover the states the trained policies visit, which the four
behaviours above do not (the surrogate scored the PPO policies 13-23 too low, ``docs/surrogate.md``).
Their files record ``behaviour`` ``policy:<seed folder>`` and the model's sha256 (``policy_digest``); a
rerun with other models at the same seeds is refused. Each episode is written to
``OUT/episodes/ep<s>.npz`` (atomically) with:

* ``obs`` (49, 15): the observation before the first action and after each of the 48 intervals;
* ``action`` (48,); ``reward`` (48,);
* per interval: ``eta_r``, ``n1``, ``n2``, ``shear_stress`` (eta gammadot_ref), ``shear_rate`` (interval
  mean), ``shear_rate_end``, ``instantaneous_mason_number``, ``mason_number`` (Mn_ref; inf: off),
  ``field_energy`` (<1/Mn_ref>), ``time`` (end of the interval, since the episode start);
* ``schedule_times``, ``schedule_rates``: the episode's rate schedule; ``behaviour``, ``start_index``,
  ``library_key``.

Finished episodes are skipped on a rerun (resume). Usage::

    python scripts/surrogate_data.py --out runs/surrogate_data --seeds 0-199 --workers 1
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

import sim
from sim.runs import RunFolderError, claim
from sim.runs.io import atomic_file

ENV_ID = "dipenv/ThickeningControl-v2"
BEHAVIOURS = ("hold", "pulse", "constant", "follow")
INFO_KEYS = (
    "eta_r",
    "n1",
    "n2",
    "shear_stress",
    "shear_rate",
    "shear_rate_end",
    "instantaneous_mason_number",
    "mason_number",
    "field_energy",
    "time",
)
DATA_VERSION = 1
POLICY_SEED0 = 100_000
"""Bump when the behaviours or the file layout change (part of the folder's identity)."""


def _draw_action(rng: np.random.Generator) -> float:
    return -1.0 if rng.random() < 0.2 else float(rng.uniform(-0.9, 1.0))


class Behaviour:
    """The behaviour policy of one episode (module docstring); ``rate`` is the observed rate."""

    def __init__(self, kind: str, rng: np.random.Generator) -> None:
        self.kind, self.rng = kind, rng
        self.current = _draw_action(rng)
        self.high = float(rng.uniform(0.2, 1.0))
        self.low = -1.0 if rng.random() < 0.6 else float(rng.uniform(-0.9, -0.4))
        self.k_on, self.k_off = int(rng.integers(1, 4)), int(rng.integers(1, 4))
        self.phase = int(rng.integers(0, self.k_on + self.k_off))
        self.c0, self.c1 = float(rng.uniform(-0.8, 0.6)), float(rng.uniform(0.0, 1.5))
        self.noise = float(rng.uniform(0.0, 0.3))

    def __call__(self, rate: float) -> float:
        if self.kind == "hold":
            if self.rng.random() > 0.7:
                self.current = _draw_action(self.rng)
            return self.current
        if self.kind == "constant":
            return self.current
        if self.kind == "pulse":
            on = self.phase % (self.k_on + self.k_off) < self.k_on
            self.phase += 1
            return self.high if on else self.low
        u = self.c0 + self.c1 * math.log10(rate) + self.noise * float(self.rng.standard_normal())
        return float(np.clip(u, -1.0, 1.0))


def policy_runs(folder: Path) -> list[Path]:
    """The seed folders of an ``agents.train`` folder that hold a model, sorted by name."""
    return sorted(p for p in folder.iterdir() if p.is_dir() and (p / "model.zip").is_file())


def _digest(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


class PolicyBehaviour:
    """A trained SB3 policy with sampled actions (``rate`` ignored; it reads the observation)."""

    def __init__(self, run: Path, seed: int) -> None:
        import pickle

        import torch
        import yaml
        from stable_baselines3 import PPO, SAC

        torch.set_num_threads(1)
        config = yaml.safe_load((run / "config.yml").read_text())
        self.model = (PPO if config["algo"] == "ppo" else SAC).load(str(run / "model.zip"), device="cpu")
        self.normaliser = None
        stats = run / "vecnormalize.pkl"
        if stats.is_file():
            with open(stats, "rb") as handle:
                self.normaliser = pickle.load(handle)
            self.normaliser.training = False
        torch.manual_seed(seed)
        self.kind = f"policy:{run.name}"
        self.digest = _digest(run / "model.zip")

    def act(self, obs: np.ndarray) -> float:
        x = self.normaliser.normalize_obs(obs) if self.normaliser is not None else obs
        action, _ = self.model.predict(x, deterministic=False)
        return float(np.asarray(action).reshape(-1)[0])


def play(payload: dict[str, Any]) -> dict[str, Any]:
    """Play episode ``payload["seed"]`` and write its file (a pure function of the seed)."""
    import gymnasium as gym

    import dipenv  # noqa: F401  (registers the ids)

    seed = int(payload["seed"])
    path = Path(payload["out"]) / "episodes" / f"ep{seed:05d}.npz"
    policy: PolicyBehaviour | None = None
    if seed >= POLICY_SEED0:
        runs = policy_runs(Path(payload["policies"]))
        policy = PolicyBehaviour(runs[(seed - POLICY_SEED0) % len(runs)], seed)
    if path.exists():
        if policy is not None:
            with np.load(path) as old:
                recorded = str(old["policy_digest"]) if "policy_digest" in old.files else ""
            if recorded != policy.digest:
                raise ValueError(
                    f"{path} was played by the model with digest {recorded or '(none)'}, --policies gives "
                    f"{policy.digest}: use another --out or other seeds"
                )
        return {"seed": seed, "status": "reused"}
    kind = policy.kind if policy is not None else BEHAVIOURS[seed % len(BEHAVIOURS)]
    behaviour = Behaviour(BEHAVIOURS[seed % len(BEHAVIOURS)], np.random.default_rng(seed))
    env = gym.make(payload.get("env_id", ENV_ID))
    index = seed % env.unwrapped.split_sizes["train"]
    obs, info = env.reset(seed=seed, options={"split": "train", "index": index})
    schedule, library_key = info["schedule"], str(info.get("library_key", ""))
    observations, actions, rewards = [np.asarray(obs, dtype=np.float64)], [], []
    columns: dict[str, list[float]] = {key: [] for key in INFO_KEYS}
    done = False
    while not done:
        rate = 10.0 ** float(obs[14])
        action = policy.act(obs) if policy is not None else behaviour(rate)
        obs, reward, terminated, truncated, info = env.step(np.array([action], dtype=np.float32))
        if info.get("simulation_failed"):
            return {"seed": seed, "status": "failed", "message": str(info.get("failure_message"))}
        done = terminated or truncated
        observations.append(np.asarray(obs, dtype=np.float64))
        actions.append(action)
        rewards.append(float(reward))
        for key in INFO_KEYS:
            columns[key].append(float(info[key]))
    env.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as handle:
        np.savez(
            handle,
            obs=np.array(observations),
            action=np.array(actions),
            reward=np.array(rewards),
            schedule_times=np.array(schedule["times"], dtype=float),
            schedule_rates=np.array(schedule["rates"], dtype=float),
            behaviour=np.array(kind),
            start_index=np.array(index),
            library_key=np.array(library_key),
            policy_digest=np.array(policy.digest if policy is not None else ""),
            **{key: np.array(values) for key, values in columns.items()},
        )
    return {"seed": seed, "status": "finished", "return": float(np.sum(rewards))}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], allow_abbrev=False)
    parser.add_argument("--out", required=True, type=Path, help="output folder (reruns resume)")
    parser.add_argument("--seeds", required=True, help="episode seeds: 0-199, or 0,5,10-20")
    parser.add_argument("--env-id", default=ENV_ID, help=f"env id (default {ENV_ID}; a Tiny id for tests)")
    parser.add_argument("--workers", type=int, default=1, help="local processes (default 1)")
    parser.add_argument(
        "--policies",
        type=Path,
        default=None,
        help=f"agents.train folder whose seed<k>/ policies play the seeds >= {POLICY_SEED0} (docstring)",
    )
    parser.add_argument("--overwrite", action="store_true", help="delete the folder's previous run first")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        seeds = sim.parse_seeds(args.seeds)
    except ValueError as exc:
        parser.error(f"--seeds: {exc}")
    if args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    if any(s >= POLICY_SEED0 for s in seeds):
        if args.policies is None:
            parser.error(f"--policies: seeds >= {POLICY_SEED0} play trained policies; name their folder")
        if not args.policies.is_dir() or not policy_runs(args.policies):
            parser.error(f"--policies: {args.policies} holds no seed folder with a model.zip")
    elif args.policies is not None:
        parser.error(f"--policies is used only by seeds >= {POLICY_SEED0}; none was given")
    try:
        claim(
            args.out,
            "scripts/surrogate_data.py",
            {"env_id": args.env_id, "data_version": DATA_VERSION},
            overwrite=args.overwrite,
            argv=[sys.executable, *sys.argv],
        )
    except RunFolderError as exc:
        parser.exit(2, f"surrogate_data.py: error: {exc}\n")
    payloads = [
        {"seed": s, "out": str(args.out), "env_id": args.env_id, "policies": str(args.policies)}
        for s in seeds
    ]

    def report(index: int, result: Any) -> None:
        line = result if isinstance(result, dict) else {"seed": seeds[index], "error": str(result)}
        print(json.dumps(line))
        sys.stdout.flush()

    sim.run_tasks(play, payloads, workers=args.workers, on_error="record", on_result=report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
