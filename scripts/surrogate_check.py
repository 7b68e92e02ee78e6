"""Issue 43's acceptance check of the surrogate: held-out episodes of four rows, simulator against surrogate.

    python scripts/surrogate_check.py --out DIR [--env dipenv/ThickeningControl-v2] [--model FILE.npz]
        [--rows constant:0.5 feedforward:1 pulse:2.5:0.5 ppo:RUN_DIR] [--episodes 16] [--realisations 4]
        [--samples 32] [--phase all|simulator|surrogate|compare]
    python scripts/surrogate_check.py --out DIR --env dipenv/ViscosityTracking-v0 --model FILE.npz
        [--rows constant:yz:5 map_feedforward angle_pi:3:1:1 ppo:RUN_DIR] [--target-seed 45000000] ...

A viscosity-tracking ``--env`` (``dipenv/ViscosityTracking-v0``, or its tiny id) checks the tracking surrogate
(:class:`dipenv.surrogate.tracking_env.ViscosityTrackingSurrogateEnv`) instead; see **Tracking** below.
Everything else (the thickening ids, their rows, files and numbers) is as described here.

**Episodes.** Episode ``j`` (``0 .. episodes-1``) starts from **validation** start state ``j % 8`` (the
split's size) and follows the schedule ``dipenv.schedules.draw_schedule(numpy.random.default_rng(
SCHEDULE_SEED + j), duration)`` with the env's schedule parameters. :data:`SCHEDULE_SEED` is 43 000 000:
outside every split (test schedules use seeds 2000-2015, the validation pool 1000-1063, the surrogate's
training data the env seeds 0-399, which draw the train schedules); the script refuses seeds that a
fixed split of :data:`dipenv.schedules.FIXED_SPLITS` uses. No ``fresh`` or ``test`` episode is played.

**Rows** (``KIND:PARAMS``): ``constant:MN`` (``Mn_ref``, ``off`` for no field), ``feedforward:MN_STAR``,
``pulse:RATE_ON:MN_STEADY`` (:mod:`agents.controllers`), ``ppo:RUN_DIR`` (an ``agents.train`` run: its
``model.zip``, ``vecnormalize.pkl`` when its config normalised, and its ``history_length``; mean action,
:func:`agents.rollout.trained_policy`). Each row plays
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

**Tracking** (issue 44; ``--env dipenv/ViscosityTracking-v0``, surrogate ``ViscosityTrackingSurrogate-v0``
with ``--model``, default: the shipped ``dipenv/data/tracking_surrogate_v0.npz``). Episodes as above, and
episode ``j`` also follows the target ``dipenv.tracking.draw_target(numpy.random.default_rng(TARGET_SEED +
j), duration)`` with the env's target parameters; schedule and target go to both fidelities as the reset
options ``schedule`` and ``target``. :data:`TARGET_SEED` is 45 000 000: refused are target seeds that a fixed
split's rate schedules use, the tracking targets' seeds (4 000 000, 5 000 000, 6 000 000 + k, k below
:data:`MAX_SPLIT_STATES`), the check's own schedule seeds and the surrogate's sample seeds (a generator seeded
``s`` repeats the draws of every other one seeded ``s``, an env's ``np_random`` included), and schedule seeds
in the tracking targets' ranges. Rows: ``constant:DIR:MN`` (a constant field along ``DIR``, a name of
:data:`agents.tracking_rows.DIRECTIONS`: y x z ext comp yz, at ``Mn_ref`` ``MN``; ``constant:off`` no field),
``map_feedforward[:TARGET]`` (the target it reads: now, next, ahead; default next), ``angle_pi:KP:KI:MN_STAR``
(:mod:`agents.tracking_controllers`) and ``ppo:RUN_DIR`` (an ``agents.train`` run played as
:mod:`agents.tracking_rows` plays it: mean action on the observation normalised by its ``vecnormalize.pkl``,
with its ``history_length``). The files add per interval the interval's target ``target_eta_r`` and the field
direction, and hold the whole action ``[u, polar, azimuth]``; ``manifest.json`` adds ``task`` and
``target_seed``. The numbers add, per row, the mean ``|eta_r - target|`` (over intervals, then realisations or
samples, then episodes) in each fidelity and whether the two fidelities rank the rows alike by it (Kendall's
tau, and the order, smallest error first); the return's ranking is kept beside it.
"""

from __future__ import annotations

import argparse
import json
import math
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
from dipenv.surrogate.tracking_env import (  # noqa: E402
    ViscosityTrackingSurrogateEnv,
    default_tracking_model_path,
)
from dipenv.tracking import TARGET_SPLITS, draw_target, target_to_dict  # noqa: E402
from sim.runs.io import atomic_file  # noqa: E402

SCHEDULE_SEED = 43_000_000
"""First schedule seed of the check's episodes (module docstring)."""
SURROGATE_SEED = 44_000_000
"""First env seed of the surrogate's samples."""
DEFAULT_ROWS = ("constant:0.5", "feedforward:1", "pulse:2.5:0.5")
CHECK_VERSION = 1
TARGET_SEED = 45_000_000
"""First target seed of the tracking check's episodes (module docstring). Not 44 000 000: the surrogate's
sample seeds start there, and an env seeded ``s`` draws from the stream of ``default_rng(s)``, so target ``j``
would share its draws with the first sample of episode ``j``."""
TRACKING_ROWS = ("constant:yz:5", "map_feedforward", "angle_pi:3:1:1")
"""The tracking check's rows without ``--rows`` (a trained run needs its folder: ``ppo:RUN_DIR``)."""
TRACKING_KINDS = ("constant", "map_feedforward", "angle_pi", "ppo")
THICKENING_KINDS = ("constant", "feedforward", "pulse", "ppo")
MAX_SPLIT_STATES = 100_000
"""A split holds at most this many states (:mod:`dipenv.tracking`, ``scripts/surrogate_data.py``): the
tracking targets' seeds run this far past each split's first seed."""


def is_tracking(env_id: str) -> bool:
    """Whether ``env_id`` is a viscosity-tracking id (the tracking check, module docstring)."""
    return "ViscosityTracking" in env_id


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


def check_tracking_seeds(schedule_seed: int, target_seed: int, count: int, samples: int) -> None:
    """Refuse the tracking check's seeds that repeat another draw (module docstring): target seeds that a
    fixed split's rate schedules use (the ranges of :func:`check_seeds`), target or schedule seeds in a
    tracking target split's range, and target seeds among the check's schedule seeds or the surrogate's
    sample seeds (``ValueError`` naming both ranges)."""
    targets = range(target_seed, target_seed + count)
    schedules = range(schedule_seed, schedule_seed + count)
    reserved = [
        (f"{split} targets' seeds", range(first, first + MAX_SPLIT_STATES))
        for split, (_, first) in TARGET_SPLITS.items()
    ]
    fixed = [  # the ranges check_seeds refuses for schedules
        (f"{split} split's schedule seeds", range(seed, seed + max(size, STRATIFIED_POOLS.get(split, 0))))
        for split, (size, seed) in FIXED_SPLITS.items()
    ]
    checks = [("target", targets, name, used) for name, used in fixed + reserved]
    checks += [("schedule", schedules, name, used) for name, used in reserved]
    checks.append(("target", targets, "check's schedule seeds", schedules))
    samples_used = range(SURROGATE_SEED, SURROGATE_SEED + 1000 * (count - 1) + samples)
    checks.append(("target", targets, "surrogate's sample seeds", samples_used))
    for kind, seeds, name, used in checks:
        if seeds.start < used.stop and used.start < seeds.stop:
            raise ValueError(
                f"{kind} seeds {seeds.start}..{seeds.stop - 1} overlap the {name} "
                f"{used.start}..{used.stop - 1}"
            )


def episode_specs(
    env: Any, count: int, first_seed: int, target_seed: int | None = None
) -> list[dict[str, Any]]:
    """Start state and schedule of each check episode (module docstring), and its target when
    ``target_seed`` is given (the tracking check; its seeds are checked by :func:`check_tracking_seeds`)."""
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
        spec = {"index": j % size, "schedule_seed": first_seed + j, "schedule": schedule_to_dict(schedule)}
        if target_seed is not None:
            target = draw_target(
                np.random.default_rng(target_seed + j),
                u.episode_duration,
                u.target_range,
                u.target_hold_range,
                u.target_ramp_range,
            )
            spec.update(target_seed=target_seed + j, target=target_to_dict(target))
        out.append(spec)
    return out


def row_label(row: str) -> str:
    kind, _, params = row.partition(":")
    if kind == "ppo":
        return "ppo_" + Path(params).name
    if not params:  # a tracking row without parameters (map_feedforward)
        return kind
    return kind + "_" + params.replace(":", "_")


def tracking_row(row: str) -> tuple[str, Any]:
    """``(kind, arguments)`` of a tracking row (module docstring): the controller's arguments of
    :func:`agents.tracking_controllers.make_tracking_controller`, or the run folder of ``ppo``;
    ``ValueError`` naming the row and what is wrong."""
    from agents.tracking_rows import DIRECTIONS, PARAMETERS, read_run_config

    kind, _, text = row.partition(":")
    parts = text.split(":") if text else []
    usage = {
        "constant": "constant:DIR:MN (DIR one of " + " ".join(DIRECTIONS) + ", MN an Mn_ref or off) or "
        "constant:off",
        "map_feedforward": "map_feedforward or map_feedforward:TARGET (now, next, ahead)",
        "angle_pi": "angle_pi:KP:KI:MN_STAR",
        "ppo": "ppo:RUN_DIR",
    }
    if kind not in usage:
        raise ValueError(f"unknown tracking row {row!r}: the rows are {'; '.join(usage.values())}")
    try:
        if kind == "ppo":
            if not text:
                raise ValueError("no run folder")
            run = Path(text)
            read_run_config(run)
            if not (run / "model.zip").is_file():
                raise ValueError(f"{run} holds no model.zip")
            return kind, run
        params: dict[str, Any]
        if kind == "constant":
            if parts == ["off"]:
                params = {"mason_ref": math.inf}
            elif len(parts) == 2:
                direction = PARAMETERS[kind]["direction"](parts[0])
                mason = PARAMETERS[kind]["mason_ref"](parts[1])
                params = {"mason_ref": mason, "direction": DIRECTIONS[direction]}
            else:
                raise ValueError("takes a direction and an Mn_ref")
        elif kind == "map_feedforward":
            if len(parts) > 1:
                raise ValueError("takes at most the target it reads")
            params = {"target": PARAMETERS[kind]["target"](parts[0])} if parts else {}
        else:
            if len(parts) != 3:
                raise ValueError("takes three numbers")
            params = {"kp": float(parts[0]), "ki": float(parts[1]), "mason_star": float(parts[2])}
        make_tracking_row_controller(kind, params)  # the controller's own checks
    except ValueError as error:
        raise ValueError(f"row {row!r} ({usage[kind]}): {error}") from None
    return kind, params


def make_tracking_row_controller(kind: str, params: dict[str, Any]) -> Any:
    """:func:`agents.tracking_controllers.make_tracking_controller` (imported when a tracking row is used)."""
    from agents.tracking_controllers import make_tracking_controller

    return make_tracking_controller(kind, params)


def run_payload(run: Path) -> dict[str, Any]:
    """What :func:`agents.tracking_rows.run_policy` loads of an ``agents.train`` run: its algorithm, model and
    statistics (``vecnormalize.pkl`` when its config normalised, or, without the setting, when the file
    exists: the rule of :func:`agents.tracking_rows.run_play`)."""
    from agents.rollout import statistics_file
    from agents.tracking_rows import read_run_config

    config = read_run_config(run)
    stats = statistics_file(config, run / "vecnormalize.pkl")
    return {
        "algo": config["algo"],
        "model_file": str(run / "model.zip"),
        "stats_file": None if stats is None else str(stats),
    }


def make_tracking_policy(row: str, env: Any) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[], None]]:
    """``(policy, reset)`` of a tracking row bound to ``env``."""
    kind, params = tracking_row(row)
    if kind == "ppo":
        from agents.tracking_rows import run_policy

        return run_policy(run_payload(params)), (lambda: None)
    controller = make_tracking_row_controller(kind, params).bind(env)
    return controller, controller.reset


def row_env_kwargs(row: str) -> dict[str, Any]:
    """Env arguments a row needs (a PPO run's ``history_length``)."""
    kind, _, params = row.partition(":")
    if kind != "ppo":
        return {}
    from agents.tracking_rows import read_run_config

    history = read_run_config(Path(params))["env_kwargs"].get("history_length", 0)
    return {"history_length": history} if history else {}


def make_policy(row: str, env: Any) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[], None]]:
    """``(policy, reset)`` of a row bound to ``env`` (a tracking env: :func:`make_tracking_policy`)."""
    from agents.controllers import FeedForwardController, RatePulseController

    if hasattr(env.unwrapped, "fixed_target"):
        return make_tracking_policy(row, env)
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
    if kind == "ppo":  # loaded as the tracking rows load a run (agents.rollout.trained_policy)
        from agents.tracking_rows import run_policy

        played = run_policy(run_payload(Path(params)))
        return (lambda obs: np.asarray(played(obs), dtype=np.float32)), (lambda: None)
    raise ValueError(f"row must be constant:MN, feedforward:MN, pulse:RATE:MN or ppo:RUN_DIR, got {row!r}")


def play(
    env: Any,
    policy: Callable[[np.ndarray], np.ndarray],
    reset: Callable[[], None],
    seed: int | None,
    options: dict[str, Any],
    tracking: bool = False,
) -> dict[str, Any]:
    """One episode's per-interval record (``tracking``: with the whole action, the interval's target and
    the field direction)."""
    reset()
    obs, _ = env.reset(seed=seed, options=options)
    keys: tuple[str, ...] = ("eta_r", "action", "mason_number", "reward", "shear_rate")
    if tracking:
        keys += ("target_eta_r", "field_direction")
    record: dict[str, list[Any]] = {k: [] for k in keys}
    done = False
    while not done:
        action = policy(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        record["eta_r"].append(float(info["eta_r"]))
        if tracking:
            record["action"].append([float(x) for x in np.asarray(action).reshape(-1)])
            record["target_eta_r"].append(float(info["target_eta_r"]))
            direction = np.asarray(info["field_direction"]).reshape(-1)
            record["field_direction"].append([float(x) for x in direction])
        else:
            record["action"].append(float(np.asarray(action).reshape(-1)[0]))
        record["mason_number"].append(float(info["mason_number"]))
        record["reward"].append(float(reward))
        record["shear_rate"].append(float(info["shear_rate"]))
        if info.get("simulation_failed"):
            return {**record, "failed": True}
    return {**record, "failed": False}


def recorded_path(path: Path) -> str:
    """``path`` as the check records it (manifest, summaries): relative to the repository root when inside
    it (``dipenv/data/surrogate_v1.npz``, the same in any clone or worktree), else absolute."""
    resolved = path.resolve()
    try:
        return resolved.relative_to(ROOT).as_posix()
    except ValueError:
        return str(resolved)


def surrogate_env(env_id: str, model: Path, extra: dict[str, Any]) -> gym.Env:
    """The surrogate of the simulator id ``env_id`` (its settings) with ``model``."""
    if is_tracking(env_id):
        return ViscosityTrackingSurrogateEnv(**surrogate_kwargs(env_id, model=str(model), **extra))
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
                if "target" in spec:
                    options["target"] = spec["target"]
                record = play(env, policy, reset, None, options, "target" in spec)
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
            if "target" in spec:
                options["target"] = spec["target"]
            samples = [
                play(env, policy, reset, SURROGATE_SEED + 1000 * j + k, options, "target" in spec)
                for k in range(args.samples)
            ]
            write_json(path, {"row": row, "episode": j, **spec, "samples": samples})
        env.close()


def compare(args: argparse.Namespace, specs: list[dict[str, Any]]) -> dict[str, Any]:
    """The acceptance numbers of the module docstring over the episodes both fidelities hold."""
    from scipy import stats

    tracking = is_tracking(args.env)
    rows: dict[str, Any] = {}
    for row in args.rows:
        label = row_label(row)
        sim_eta, sim_ret, sur_eta, sur_ret, used = [], [], [], [], []
        sim_err, sur_err = [], []  # tracking: mean |eta_r - target| per realisation or sample
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
            if tracking:
                sim_err.append([mean_abs_error(s) for s in sims])
                sur_err.append([mean_abs_error(s) for s in surs])
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
        if tracking:
            rows[row].update(
                simulator_mean_abs_error=float(np.mean(sim_err)),
                surrogate_mean_abs_error=float(np.mean(sur_err)),
            )
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
        "model": recorded_path(args.model),
        "rows": rows,
        "order_simulator": order_sim,
        "order_surrogate": order_sur,
        "same_order": order_sim == order_sur,
        "kendall_tau": tau,
    }
    if tracking:
        error_sim = sorted(names, key=lambda r: rows[r]["simulator_mean_abs_error"])
        error_sur = sorted(names, key=lambda r: rows[r]["surrogate_mean_abs_error"])
        tau_error = (
            float(
                stats.kendalltau(
                    [rows[r]["simulator_mean_abs_error"] for r in names],
                    [rows[r]["surrogate_mean_abs_error"] for r in names],
                ).statistic
            )
            if len(names) > 1
            else math.nan
        )
        summary.update(
            task="tracking",
            target_seed=args.target_seed,
            error_order_simulator=error_sim,
            error_order_surrogate=error_sur,
            error_same_order=error_sim == error_sur,
            error_kendall_tau=tau_error,
        )
    write_json(args.out / "summary.json", summary)
    if tracking:
        write_tracking_summary(args, summary)
        return summary
    lines = [
        f"Surrogate check: {args.env}, model {recorded_path(args.model)}; episodes from validation start "
        f"states, schedule seeds {args.schedule_seed} + j.",
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


def mean_abs_error(record: dict[str, Any]) -> float:
    """Mean over an episode's intervals of ``|eta_r - target_eta_r|``."""
    return float(np.mean(np.abs(np.subtract(record["eta_r"], record["target_eta_r"]))))


def write_tracking_summary(args: argparse.Namespace, summary: dict[str, Any]) -> None:
    """``summary.md`` of the tracking check: the thickening check's table with each fidelity's mean
    ``|eta_r - target|``, and both rankings."""
    rows = summary["rows"]
    lines = [
        f"Surrogate check (tracking): {args.env}, model {recorded_path(args.model)}; episodes from "
        f"validation start states, schedule seeds {args.schedule_seed} + j, target seeds "
        f"{args.target_seed} + j.",
        "",
        "| row | episodes | eta_r error (RMS) | simulator sd | surrogate sd | spread ratio | error < sd | "
        "mean abs(eta_r - target), simulator | mean abs(eta_r - target), surrogate | return, simulator | "
        "return, surrogate |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r, m in rows.items():
        lines.append(
            f"| {r} | {len(m['episodes'])} | {m['eta_rms_error']:.2f} | {m['simulator_eta_sd']:.2f} | "
            f"{m['surrogate_eta_sd']:.2f} | {m['spread_ratio']:.2f} | "
            f"{'yes' if m['error_below_spread'] else 'no'} | "
            f"{m['simulator_mean_abs_error']:.2f} | {m['surrogate_mean_abs_error']:.2f} | "
            f"{m['simulator_return']:.1f} | {m['surrogate_return']:.1f} |"
        )
    lines += [
        "",
        f"Order by mean abs(eta_r - target), smallest first, simulator: "
        f"{', '.join(summary['error_order_simulator'])}; "
        f"surrogate: {', '.join(summary['error_order_surrogate'])} "
        f"(same: {summary['error_same_order']}, Kendall tau {summary['error_kendall_tau']:.2f}).",
        f"Order by return, simulator: {', '.join(summary['order_simulator'])}; surrogate: "
        f"{', '.join(summary['order_surrogate'])} (same: {summary['same_order']}, Kendall tau "
        f"{summary['kendall_tau']:.2f}).",
    ]
    (args.out / "summary.md").write_text("\n".join(lines) + "\n")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0], allow_abbrev=False)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--env", default="dipenv/ThickeningControl-v2", help="the simulator id")
    parser.add_argument("--model", type=Path, default=None, help="surrogate model (default: the shipped one)")
    parser.add_argument(
        "--rows",
        nargs="+",
        default=None,
        help=f"default: {' '.join(DEFAULT_ROWS)} (a tracking --env: {' '.join(TRACKING_ROWS)})",
    )
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--realisations", type=int, default=4)
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--schedule-seed", type=int, default=SCHEDULE_SEED)
    parser.add_argument(
        "--target-seed",
        type=int,
        default=None,
        help=f"first target seed of a tracking --env (default {TARGET_SEED})",
    )
    parser.add_argument("--phase", choices=("all", "simulator", "surrogate", "compare"), default="all")
    return parser


def main(argv: list[str] | None = None) -> dict[str, Any] | None:
    parser = build_parser()
    args = parser.parse_args(argv)
    tracking = is_tracking(args.env)
    if tracking:
        check_tracking_arguments(parser, args)
    else:
        if args.target_seed is not None:
            parser.error("--target-seed applies to a viscosity-tracking --env only")
        args.rows = list(DEFAULT_ROWS) if args.rows is None else args.rows
        args.model = (args.model or default_model_path()).resolve()
    if args.episodes < 1 or args.realisations < 1 or args.samples < 2:
        parser.error("--episodes and --realisations must be >= 1, --samples >= 2")
    for row in args.rows:
        if row.partition(":")[0] not in (TRACKING_KINDS if tracking else THICKENING_KINDS):
            parser.error(f"--rows: unknown row {row!r}")
    env = gym.make(args.env, progress=False)
    try:
        specs = episode_specs(env, args.episodes, args.schedule_seed, args.target_seed if tracking else None)
    except ValueError as error:
        parser.error(str(error))
    env.close()
    manifest = {
        "version": CHECK_VERSION,
        "env": args.env,
        "model": recorded_path(args.model),
        "schedule_seed": args.schedule_seed,
        "surrogate_seed": SURROGATE_SEED,
        "samples": args.samples,
    }
    if tracking:
        manifest.update(task="tracking", target_seed=args.target_seed)
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


def check_tracking_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """The tracking check's defaults (rows, model, target seed) filled in and its arguments checked before
    anything is played: the id has a surrogate, each row parses (:func:`tracking_row`), the seeds repeat no
    other draw (:func:`check_tracking_seeds`) and the model drives the tracking surrogate."""
    if "StressOnly" in args.env:
        parser.error(f"--env {args.env}: there is no stress-only tracking surrogate (a ViscosityTracking id)")
    args.rows = list(TRACKING_ROWS) if args.rows is None else args.rows
    args.target_seed = TARGET_SEED if args.target_seed is None else args.target_seed
    if args.model is None:
        args.model = default_tracking_model_path()
        if not args.model.is_file():
            parser.error(
                f"the shipped tracking surrogate is missing ({args.model}; reinstall the package): or "
                "pass --model, a model fitted on ViscosityTracking episodes "
                "(docs/surrogate.md#the-tracking-surrogate)"
            )
    args.model = args.model.resolve()
    for row in args.rows:
        try:
            tracking_row(row)
        except ValueError as error:
            parser.error(f"--rows: {error}")
    try:
        check_tracking_seeds(args.schedule_seed, args.target_seed, max(args.episodes, 1), args.samples)
    except ValueError as error:
        parser.error(str(error))
    try:
        surrogate_env(args.env, args.model, {}).close()
    except (OSError, ValueError, KeyError) as error:
        parser.error(f"--model {args.model}: {error}")


if __name__ == "__main__":
    main()
