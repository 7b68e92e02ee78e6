"""Issue 43's acceptance check of the surrogate: held-out episodes of four rows, simulator against surrogate.

    python scripts/surrogate_check.py --out DIR [--env dipenv/ThickeningControl-v2] [--model FILE.npz]
        [--rows constant:0.5 feedforward:1 pulse:2.5:0.5 ppo:RUN_DIR] [--episodes 16] [--realisations 4]
        [--samples 32] [--phase all|simulator|surrogate|compare]

**Episodes.** Episode ``j`` (``0 .. episodes-1``) starts from **validation** start state ``j % 8`` (the
split's size) and follows the schedule ``dipenv.schedules.draw_schedule(numpy.random.default_rng(
SCHEDULE_SEED + j), duration)`` with the env's schedule parameters. :data:`SCHEDULE_SEED` is 43 000 000:
outside every split (test schedules use seeds 2000-2015, the validation pool 1000-1063, the surrogate's
training data the env seeds 0-399, which draw the train schedules); the script refuses seeds that a
fixed split of :data:`dipenv.schedules.FIXED_SPLITS` uses. No ``fresh`` or ``test`` episode is played.

**Rows** (``KIND:PARAMS``): ``constant:MN`` (``Mn_ref``, ``off`` for no field), ``feedforward:MN_STAR``,
``pulse:RATE_ON:MN_STEADY`` (:mod:`agents.controllers`), ``ppo:RUN_DIR`` (an ``agents.train`` run: its
``model.zip``, ``vecnormalize.pkl`` when present, and its ``history_length``; mean action). Each row plays
every episode ``--realisations`` times in the simulator (realisations ``0 .. R-1`` of
:mod:`dipenv.realisations`) and ``--samples`` times in the surrogate (seeds ``SURROGATE_SEED + 1000 j +
k``), closed loop: the row acts on what each fidelity shows it.

**Files** (each a pure function of its inputs; a rerun skips the files that exist, so an interrupted run
resumes): ``DIR/manifest.json`` (the settings; a rerun with other settings is refused),
``DIR/simulator/<row>/ep<j>_r<r>.json`` and ``DIR/surrogate/<row>/ep<j>.json`` (per interval: ``eta_r``,
the action, ``Mn_ref``, the reward, the rate), ``DIR/summary.json`` and ``DIR/summary.md``.

**Comparison** (issue 43's acceptance): per row, over episodes and intervals, the RMS difference between
the surrogate's mean interval ``eta_r`` and the simulator's realisation mean, against the RMS of the
simulator's realisation sd (pass: below it); the ratio of the two fidelities' spreads (surrogate sd over
simulator sd; a match is 0.67-1.5); the rows' mean returns in each fidelity and whether they rank the rows
alike (Kendall's tau, and the order).
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import gymnasium as gym  # noqa: E402

import dipenv  # noqa: E402,F401  (registers the ids)
from dipenv.schedules import FIXED_SPLITS, STRATIFIED_POOLS, draw_schedule, schedule_to_dict  # noqa: E402
from dipenv.surrogate.env import (  # noqa: E402
    ThickeningControlSurrogateEnv,
    ThickeningControlSurrogateStressOnlyEnv,
    surrogate_kwargs,
)
from dipenv.surrogate.models import default_model_path  # noqa: E402
from sim.runs.io import atomic_file  # noqa: E402

SCHEDULE_SEED = 43_000_000
"""First schedule seed of the check's episodes (module docstring)."""
SURROGATE_SEED = 44_000_000
"""First env seed of the surrogate's samples."""
DEFAULT_ROWS = ("constant:0.5", "feedforward:1", "pulse:2.5:0.5")
CHECK_VERSION = 1


def write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as handle:
        handle.write((json.dumps(data, indent=1, default=float) + "\n").encode())


def check_seeds(first: int, count: int) -> None:
    """Refuse schedule seeds that a fixed split uses."""
    for split, (size, seed) in FIXED_SPLITS.items():
        used = range(seed, seed + max(size, STRATIFIED_POOLS.get(split, 0)))
        if any(first <= s < first + count for s in used):
            raise ValueError(
                f"schedule seeds {first}..{first + count - 1} overlap the {split} split's {used}"
            )


def episode_specs(env: Any, count: int, first_seed: int) -> list[dict[str, Any]]:
    """Start state and schedule of each check episode (module docstring)."""
    check_seeds(first_seed, count)
    u = env.unwrapped
    size = u.split_sizes["validation"]
    out = []
    for j in range(count):
        schedule = draw_schedule(
            np.random.default_rng(first_seed + j),
            u.episode_duration,
            u.rate_range,
            u.hold_range,
            u.ramp_range,
        )
        out.append(
            {"index": j % size, "schedule_seed": first_seed + j, "schedule": schedule_to_dict(schedule)}
        )
    return out


def row_label(row: str) -> str:
    kind, _, params = row.partition(":")
    if kind == "ppo":
        return "ppo_" + Path(params).name
    return kind + "_" + params.replace(":", "_")


def row_env_kwargs(row: str) -> dict[str, Any]:
    """Env arguments a row needs (a PPO run's ``history_length``)."""
    kind, _, params = row.partition(":")
    if kind != "ppo":
        return {}
    import yaml

    config = yaml.safe_load((Path(params) / "config.yml").read_text())
    history = config.get("env_kwargs", {}).get("history_length", 0)
    return {"history_length": history} if history else {}


def make_policy(row: str, env: Any) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[], None]]:
    """``(policy, reset)`` of a row bound to ``env``."""
    from agents.controllers import FeedForwardController, RatePulseController

    kind, _, params = row.partition(":")
    mapping = env.unwrapped.mapping
    if kind == "constant":
        mason = math.inf if params == "off" else float(params)
        action = np.array([mapping.action_for(mason)], dtype=np.float32)
        return (lambda obs: action), (lambda: None)
    if kind == "feedforward":
        ff = FeedForwardController(float(params)).bind(env)
        return ff, (lambda: None)
    if kind == "pulse":
        rate_on, mason_steady = (float(x) for x in params.split(":"))
        pulse = RatePulseController(rate_on, mason_steady).bind(env)
        return pulse, pulse.reset
    if kind == "ppo":
        import torch
        from stable_baselines3 import PPO

        torch.set_num_threads(1)
        run = Path(params)
        model = PPO.load(str(run / "model.zip"), device="cpu")
        normaliser = None
        if (run / "vecnormalize.pkl").exists():
            with open(run / "vecnormalize.pkl", "rb") as handle:
                normaliser = pickle.load(handle)
            normaliser.training = False

        def policy(obs: np.ndarray) -> np.ndarray:
            x = normaliser.normalize_obs(obs) if normaliser is not None else obs
            action, _ = model.predict(x, deterministic=True)
            return np.asarray(action, dtype=np.float32)

        return policy, (lambda: None)
    raise ValueError(f"row must be constant:MN, feedforward:MN, pulse:RATE:MN or ppo:RUN_DIR, got {row!r}")


def play(
    env: Any,
    policy: Callable[[np.ndarray], np.ndarray],
    reset: Callable[[], None],
    seed: int | None,
    options: dict[str, Any],
) -> dict[str, Any]:
    """One episode's per-interval record."""
    reset()
    obs, _ = env.reset(seed=seed, options=options)
    record: dict[str, list[float]] = {
        k: [] for k in ("eta_r", "action", "mason_number", "reward", "shear_rate")
    }
    done = False
    while not done:
        action = policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        record["eta_r"].append(float(info["eta_r"]))
        record["action"].append(float(np.asarray(action).reshape(-1)[0]))
        record["mason_number"].append(float(info["mason_number"]))
        record["reward"].append(float(reward))
        record["shear_rate"].append(float(info["shear_rate"]))
        if info.get("simulation_failed"):
            return {**record, "failed": True}
    return {**record, "failed": False}


def surrogate_env(env_id: str, model: Path, extra: dict[str, Any]) -> gym.Env:
    """The surrogate of the simulator id ``env_id`` (its settings) with ``model``."""
    stress_only = "StressOnly" in env_id
    cls = ThickeningControlSurrogateStressOnlyEnv if stress_only else ThickeningControlSurrogateEnv
    return cls(**surrogate_kwargs(env_id, model=str(model), **extra))


def run_simulator(args: argparse.Namespace, specs: list[dict[str, Any]]) -> None:
    for row in args.rows:
        extra = row_env_kwargs(row)
        env = gym.make(args.env, progress=False, **extra)
        policy, reset = make_policy(row, env)
        for j, spec in enumerate(specs):
            for r in range(args.realisations):
                path = args.out / "simulator" / row_label(row) / f"ep{j:02d}_r{r}.json"
                if path.exists():
                    continue
                options = {
                    "split": "validation",
                    "index": spec["index"],
                    "schedule": spec["schedule"],
                    "realisation": r,
                }
                record = play(env, policy, reset, None, options)
                write_json(path, {"row": row, "episode": j, "realisation": r, **spec, **record})
                print(
                    json.dumps(
                        {
                            "fidelity": "simulator",
                            "row": row,
                            "episode": j,
                            "realisation": r,
                            "return": sum(record["reward"]),
                        }
                    )
                )
                sys.stdout.flush()
        env.close()


def run_surrogate(args: argparse.Namespace, specs: list[dict[str, Any]]) -> None:
    for row in args.rows:
        env = surrogate_env(args.env, args.model, row_env_kwargs(row))
        policy, reset = make_policy(row, env)
        for j, spec in enumerate(specs):
            path = args.out / "surrogate" / row_label(row) / f"ep{j:02d}.json"
            if path.exists():
                continue
            options = {"split": "validation", "index": spec["index"], "schedule": spec["schedule"]}
            samples = [
                play(env, policy, reset, SURROGATE_SEED + 1000 * j + k, options) for k in range(args.samples)
            ]
            write_json(path, {"row": row, "episode": j, **spec, "samples": samples})
        env.close()


def compare(args: argparse.Namespace, specs: list[dict[str, Any]]) -> dict[str, Any]:
    """The acceptance numbers of the module docstring over the episodes both fidelities hold."""
    from scipy import stats

    rows: dict[str, Any] = {}
    for row in args.rows:
        label = row_label(row)
        sim_eta, sim_ret, sur_eta, sur_ret, used = [], [], [], [], []
        for j in range(len(specs)):
            sim_files = [
                args.out / "simulator" / label / f"ep{j:02d}_r{r}.json" for r in range(args.realisations)
            ]
            sur_file = args.out / "surrogate" / label / f"ep{j:02d}.json"
            if not sur_file.exists() or not all(p.exists() for p in sim_files):
                continue
            sims = [json.loads(p.read_text()) for p in sim_files]
            if any(s["failed"] for s in sims):
                continue
            surs = json.loads(sur_file.read_text())["samples"]
            sim_eta.append([s["eta_r"] for s in sims])
            sim_ret.append([sum(s["reward"]) for s in sims])
            sur_eta.append([s["eta_r"] for s in surs])
            sur_ret.append([sum(s["reward"]) for s in surs])
            used.append(j)
        if not used:
            continue
        se, ss = np.array(sim_eta), np.array(sur_eta)  # (E, R, T), (E, K, T)
        sim_mean, sur_mean = se.mean(axis=1), ss.mean(axis=1)
        sim_sd = se.std(axis=1, ddof=1) if se.shape[1] > 1 else np.full(sim_mean.shape, np.nan)
        sur_sd = ss.std(axis=1, ddof=1)
        error = float(np.sqrt(np.mean((sur_mean - sim_mean) ** 2)))
        spread = float(np.sqrt(np.mean(sim_sd**2)))
        rows[row] = {
            "episodes": used,
            "realisations": int(se.shape[1]),
            "samples": int(ss.shape[1]),
            "eta_rms_error": error,
            "eta_rms_error_noise_corrected": float(math.sqrt(max(0.0, error**2 - spread**2 / se.shape[1]))),
            "simulator_eta_sd": spread,
            "surrogate_eta_sd": float(np.sqrt(np.mean(sur_sd**2))),
            "spread_ratio": float(np.sqrt(np.mean(sur_sd**2)) / spread) if spread > 0 else math.nan,
            "error_below_spread": bool(error < spread),
            "simulator_mean_eta": float(sim_mean.mean()),
            "surrogate_mean_eta": float(sur_mean.mean()),
            "simulator_return": float(np.mean(sim_ret)),
            "surrogate_return": float(np.mean(sur_ret)),
            "simulator_return_sd": float(np.mean(np.std(sim_ret, axis=1, ddof=1)))
            if se.shape[1] > 1
            else math.nan,
            "surrogate_return_sd": float(np.mean(np.std(sur_ret, axis=1, ddof=1))),
        }
    names = list(rows)
    order_sim = sorted(names, key=lambda r: -rows[r]["simulator_return"])
    order_sur = sorted(names, key=lambda r: -rows[r]["surrogate_return"])
    tau = (
        float(
            stats.kendalltau(
                [rows[r]["simulator_return"] for r in names], [rows[r]["surrogate_return"] for r in names]
            ).statistic
        )
        if len(names) > 1
        else math.nan
    )
    summary = {
        "env": args.env,
        "model": str(args.model),
        "rows": rows,
        "order_simulator": order_sim,
        "order_surrogate": order_sur,
        "same_order": order_sim == order_sur,
        "kendall_tau": tau,
    }
    write_json(args.out / "summary.json", summary)
    lines = [
        f"Surrogate check: {args.env}, model {args.model}; episodes from validation start states, "
        f"schedule seeds {args.schedule_seed} + j.",
        "",
        "| row | episodes | eta_r error (RMS) | simulator sd | surrogate sd | spread ratio | error < sd | "
        "return, simulator | return, surrogate |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in names:
        m = rows[r]
        lines.append(
            f"| {r} | {len(m['episodes'])} | {m['eta_rms_error']:.2f} | {m['simulator_eta_sd']:.2f} | "
            f"{m['surrogate_eta_sd']:.2f} | {m['spread_ratio']:.2f} | "
            f"{'yes' if m['error_below_spread'] else 'no'} | "
            f"{m['simulator_return']:.1f} | {m['surrogate_return']:.1f} |"
        )
    lines += [
        "",
        f"Order by return, simulator: {', '.join(order_sim)}; surrogate: {', '.join(order_sur)} "
        f"(same: {summary['same_order']}, Kendall tau {tau:.2f}).",
    ]
    (args.out / "summary.md").write_text("\n".join(lines) + "\n")
    return summary


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2", help="the simulator id")
    parser.add_argument("--model", type=Path, default=None, help="surrogate model (default: the shipped one)")
    parser.add_argument("--rows", nargs="+", default=list(DEFAULT_ROWS))
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--realisations", type=int, default=4)
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--schedule-seed", type=int, default=SCHEDULE_SEED)
    parser.add_argument("--phase", choices=("all", "simulator", "surrogate", "compare"), default="all")
    return parser


def main(argv: list[str] | None = None) -> dict[str, Any] | None:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.model = (args.model or default_model_path()).resolve()
    if args.episodes < 1 or args.realisations < 1 or args.samples < 2:
        parser.error("--episodes and --realisations must be >= 1, --samples >= 2")
    for row in args.rows:
        if row.partition(":")[0] not in ("constant", "feedforward", "pulse", "ppo"):
            parser.error(f"--rows: unknown row {row!r}")
    env = gym.make(args.env, progress=False)
    try:
        specs = episode_specs(env, args.episodes, args.schedule_seed)
    except ValueError as error:
        parser.error(str(error))
    env.close()
    manifest = {
        "version": CHECK_VERSION,
        "env": args.env,
        "model": str(args.model),
        "schedule_seed": args.schedule_seed,
        "surrogate_seed": SURROGATE_SEED,
        "samples": args.samples,
    }
    path = args.out / "manifest.json"
    if path.exists():
        old = json.loads(path.read_text())
        if old != manifest:
            parser.exit(
                2, f"surrogate_check.py: error: {path} holds other settings ({old}); use another --out\n"
            )
    else:
        write_json(path, manifest)
    if args.phase in ("all", "simulator"):
        run_simulator(args, specs)
    if args.phase in ("all", "surrogate"):
        run_surrogate(args, specs)
    if args.phase in ("all", "compare"):
        summary = compare(args, specs)
        print((args.out / "summary.md").read_text())
        return summary
    return None


if __name__ == "__main__":
    main()
