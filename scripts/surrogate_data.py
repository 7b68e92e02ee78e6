"""Training data for the surrogates (issues 43, 44): simulator episodes under varied fields.

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

**Tracking episodes** (issue 44): with ``--env-id dipenv/ViscosityTracking-v0`` (or its Tiny id) the
episodes are the tracking task's, from the train start states with the env's own training draws (start
state ``s mod 64`` given, then the rate schedule and the target drawn from the env seed ``s``), and the
behaviours set the field's strength **and direction** (action ``[u, polar, azimuth]``), chosen per episode
as ``TRACKING_BEHAVIOURS[s mod 4]`` with parameters drawn from ``numpy.random.default_rng(s)``:

============ ===========================================================================================
``hold``     random holds: each interval keeps the field with probability ``1 - p`` (``p`` in
             ``[0.15, 0.4]`` per episode), else changes its strength, its direction or both (a third each;
             strength off with probability 0.2, else ``u`` uniform in ``[-0.9, 1]``; direction by
             :func:`draw_direction`: uniform on the half-sphere 40%, on the y-z arc 30%, one of the map's
             axes x, y, z, (x+-y)/sqrt2, (y+z)/sqrt2 30%)
``switch``   switches between y and z: legs of 2-12 intervals alternating y and z at a strength ``u`` in
             ``[-0.6, 1]`` (redrawn with probability 0.3 per leg; a leg is off with probability 0.1)
``map``      the map feed-forward (:class:`agents.tracking_controllers.MapFeedForwardController`, following
             the target now, over the next interval or ahead), with Gaussian noise on ``u`` and the angles
             (sd up to 0.25) and, with probability up to 0.15 per interval, a random field instead
``angle_pi`` the angle PI (:class:`agents.tracking_controllers.AnglePIController`, ``kp`` 0.5-4, ``ki``
             0.05-0.6, ``mason_star`` 0.3-3 log-uniform, ``polar0`` -0.5-0.5), noised as ``map``
============ ===========================================================================================

A tracking file also holds ``action`` (T, 3), ``field_direction`` (T, 3: the direction of each interval's
field as ``info["field_direction"]`` reports it, one of +-e, also while the field is off),
``target_eta_r`` and ``target_eta_r_end`` (T,: the target's mean over each interval, which the reward
charged, and its value at the end), ``target_times`` and ``target_values`` (the target's knots) and
``behaviour_params`` (JSON); ``obs`` has the tracking frame (21 entries). Its folder's identity is the env
id and :data:`TRACKING_DATA_VERSION`.

**Seeds.** A train reset with env seed ``s`` draws its rate schedule (and target) from
``default_rng(s)``'s stream, as a fixed split draws schedule ``k`` from ``default_rng(seed_k)``; the seeds
of every fixed split's schedules (and, for a tracking env, targets) are therefore refused
(:func:`check_seeds`), so that no data episode repeats a validation, test or fresh schedule: validation
1000-1071 (the pool of 64 and the 8), test 2000-2015, fresh 3,000,000-3,000,127 (each further by an
enlarged split's size), and the tracking targets 4,000,000, 5,000,000 and 6,000,000 on (validation, test,
fresh; :data:`MAX_SPLIT_STATES` each). The tracking data use seeds **0-99** (the command below; more from
100 on, below 1000), so they never meet them; their start states are the train split's (``s mod 64``).

Finished episodes are skipped on a rerun (resume). Usage::

    python scripts/surrogate_data.py --out runs/surrogate_data --seeds 0-199 --workers 1
    python scripts/surrogate_data.py --out runs/tracking_surrogate_data --seeds 0-99 \
        --env-id dipenv/ViscosityTracking-v0 --workers 2
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
from dipenv.actions import action_from_direction
from dipenv.schedules import FIXED_SPLITS, STRATIFIED_POOLS
from dipenv.tracking import TARGET_SPLITS
from sim.runs import RunFolderError, claim
from sim.runs.io import atomic_file

ENV_ID = "dipenv/ThickeningControl-v2"
BEHAVIOURS = ("hold", "pulse", "constant", "follow")
TRACKING_BEHAVIOURS = ("hold", "switch", "map", "angle_pi")
"""The behaviours of tracking episodes (module docstring), by ``seed mod 4``."""
TRACKING_DATA_VERSION = 1
"""Bump when the tracking behaviours or the tracking file layout change (part of the folder's identity)."""
TRACKING_INFO_KEYS = ("target_eta_r", "target_eta_r_end")
_HALF = math.sqrt(0.5)
MAP_AXES = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "ext": (_HALF, _HALF, 0.0),
    "comp": (-_HALF, _HALF, 0.0),
    "yz": (0.0, _HALF, _HALF),
}
"""The direction map's axes (``results/direction_map``): x, y, z, (x+-y)/sqrt2, (y+z)/sqrt2."""
MAX_SPLIT_STATES = 100_000
"""A split holds at most this many states (:mod:`dipenv.tracking`): the seed ranges :func:`check_seeds`
refuses run this far past each split's first seed."""
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


def draw_direction(rng: np.random.Generator) -> tuple[float, float]:
    """``(polar, azimuth)`` of a random field direction: uniform on the half-sphere (probability 0.4), on the
    y-z arc (0.3: ``azimuth = 0.5``, ``polar`` uniform) or one of :data:`MAP_AXES` (0.3)."""
    draw = rng.random()
    if draw < 0.4:
        while True:  # an isotropic Gaussian vector is uniform on the sphere; e and -e are one field
            e = rng.standard_normal(3)
            if np.linalg.norm(e) > 1e-6:
                return action_from_direction(e)
    if draw < 0.7:
        return float(rng.uniform(-1.0, 1.0)), 0.5
    names = sorted(MAP_AXES)
    return action_from_direction(MAP_AXES[names[int(rng.integers(len(names)))]])


class TrackingBehaviour:
    """The behaviour policy of one tracking episode (module docstring): ``bind(env)``, then
    ``behaviour(obs)`` gives the action ``[u, polar, azimuth]``. Every parameter is drawn from ``rng`` at
    construction, in one order whatever the kind, so that an episode is a pure function of its seed."""

    def __init__(self, kind: str, rng: np.random.Generator) -> None:
        if kind not in TRACKING_BEHAVIOURS:
            raise ValueError(f"kind must be one of {', '.join(TRACKING_BEHAVIOURS)}, got {kind!r}")
        self.kind, self.rng = kind, rng
        self.p_change = float(rng.uniform(0.15, 0.4))
        self.u = _draw_action(rng)
        self.polar, self.azimuth = draw_direction(rng)
        self.leg_u = float(rng.uniform(-0.6, 1.0))
        self.leg_left = int(rng.integers(2, 13))
        self.on_z = bool(rng.random() < 0.5)
        self.leg_off = False  # the first leg is on
        self.target = str(rng.choice(["now", "next", "ahead"]))
        self.noise_u, self.noise_angle = float(rng.uniform(0.0, 0.25)), float(rng.uniform(0.0, 0.25))
        self.epsilon = float(rng.uniform(0.0, 0.15))
        self.kp, self.ki = float(rng.uniform(0.5, 4.0)), float(rng.uniform(0.05, 0.6))
        self.mason_star = float(10.0 ** rng.uniform(math.log10(0.3), math.log10(3.0)))
        self.polar0 = float(rng.uniform(-0.5, 0.5))
        self.controller: Any = None

    def params(self) -> dict[str, Any]:
        """The parameters this kind uses (recorded in the episode's file, as drawn before its first
        interval)."""
        if self.kind == "hold":
            return {"p_change": self.p_change}
        if self.kind == "switch":
            return {"u": self.leg_u, "first_leg": self.leg_left, "first": "z" if self.on_z else "y"}
        noise = {"noise_u": self.noise_u, "noise_angle": self.noise_angle, "epsilon": self.epsilon}
        if self.kind == "map":
            return {"target": self.target, **noise}
        return {"kp": self.kp, "ki": self.ki, "mason_star": self.mason_star, "polar0": self.polar0,
                "target": self.target, **noise}  # fmt: skip

    def bind(self, env: Any) -> TrackingBehaviour:
        """Bind the controller of ``map`` and ``angle_pi`` to ``env`` (it reads the observation by label)."""
        from agents.tracking_controllers import AnglePIController, MapFeedForwardController

        if self.kind == "map":
            self.controller = MapFeedForwardController(target=self.target).bind(env)
        elif self.kind == "angle_pi":
            self.controller = AnglePIController(
                self.kp, self.ki, self.mason_star, self.polar0, 0.5, self.target
            ).bind(env)
        return self

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        rng = self.rng
        if self.kind == "hold":
            if rng.random() < self.p_change:
                what = int(rng.integers(3))  # 0: strength, 1: direction, 2: both
                if what != 1:
                    self.u = _draw_action(rng)
                if what != 0:
                    self.polar, self.azimuth = draw_direction(rng)
            return np.array([self.u, self.polar, self.azimuth])
        if self.kind == "switch":
            if self.leg_left <= 0:
                self.on_z = not self.on_z
                self.leg_left = int(rng.integers(2, 13))
                if rng.random() < 0.3:
                    self.leg_u = float(rng.uniform(-0.6, 1.0))
                self.leg_off = bool(rng.random() < 0.1)
            self.leg_left -= 1
            return np.array([-1.0 if self.leg_off else self.leg_u, 1.0 if self.on_z else -1.0, 0.5])
        if rng.random() < self.epsilon:
            polar, azimuth = draw_direction(rng)
            return np.array([_draw_action(rng), polar, azimuth])
        action = np.asarray(self.controller(obs), dtype=np.float64).copy()
        noise = rng.standard_normal(3) * np.array([self.noise_u, self.noise_angle, self.noise_angle])
        if action[0] < -0.9:  # off stays off (the direction of an off field is the one it asks for)
            noise[0] = 0.0
        return np.clip(action + noise, -1.0, 1.0)


def check_seeds(seeds: list[int], split_sizes: dict[str, int], tracking: bool = True) -> None:
    """Refuse episode seeds that draw a fixed split's schedule or target (module docstring): for each
    fixed split, the schedule seeds ``seed .. seed + pool + size`` (the shipped ones, the stratified pool
    and an enlarged split's) and, for a ``tracking`` env, the target seeds ``first .. first +
    MAX_SPLIT_STATES``."""
    ranges = []
    for split, (count, first) in FIXED_SPLITS.items():
        size = max(count, split_sizes.get(split, count))
        ranges.append((f"{split} schedules", first, first + STRATIFIED_POOLS.get(split, 0) + size))
    for split, (_, first) in TARGET_SPLITS.items() if tracking else ():
        ranges.append((f"{split} targets", first, first + MAX_SPLIT_STATES))
    for name, low, high in ranges:
        bad = [s for s in seeds if low <= s < high]
        if bad:
            raise ValueError(
                f"seeds {bad[:5]}{' ...' if len(bad) > 5 else ''} overlap the {name}' seeds [{low}, {high}): "
                "a train reset from them would repeat a fixed split's draws"
            )


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
        return float(self.act_vector(obs)[0])

    def act_vector(self, obs: np.ndarray) -> np.ndarray:
        """The whole sampled action (the tracking envs' three components)."""
        x = self.normaliser.normalize_obs(obs) if self.normaliser is not None else obs
        action, _ = self.model.predict(x, deterministic=False)
        return np.asarray(action, dtype=np.float64).reshape(-1)


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
    env = gym.make(payload.get("env_id", ENV_ID))
    if is_tracking(env):
        return play_tracking(env, seed, path, policy)
    kind = policy.kind if policy is not None else BEHAVIOURS[seed % len(BEHAVIOURS)]
    behaviour = Behaviour(BEHAVIOURS[seed % len(BEHAVIOURS)], np.random.default_rng(seed))
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


def is_tracking(env: Any) -> bool:
    """Whether ``env`` is a viscosity-tracking env (a target to follow, a direction to set)."""
    return hasattr(env.unwrapped, "target_range")


def play_tracking(env: Any, seed: int, path: Path, policy: PolicyBehaviour | None) -> dict[str, Any]:
    """:func:`play` for a tracking env: episode ``seed`` under ``TRACKING_BEHAVIOURS[seed mod 4]`` (or
    ``policy``), written to ``path`` (module docstring)."""
    behaviour = TrackingBehaviour(
        TRACKING_BEHAVIOURS[seed % len(TRACKING_BEHAVIOURS)], np.random.default_rng(seed)
    )
    kind = policy.kind if policy is not None else behaviour.kind
    index = seed % env.unwrapped.split_sizes["train"]
    obs, info = env.reset(seed=seed, options={"split": "train", "index": index})
    if policy is None:
        behaviour.bind(env)
    params = behaviour.params() if policy is None else {}  # before the episode changes the legs
    schedule, target, library_key = info["schedule"], info["target"], str(info.get("library_key", ""))
    observations, actions, rewards, directions = [np.asarray(obs, dtype=np.float64)], [], [], []
    keys = (*INFO_KEYS, *TRACKING_INFO_KEYS)
    columns: dict[str, list[float]] = {key: [] for key in keys}
    done = False
    while not done:
        action = policy.act_vector(obs) if policy is not None else behaviour(obs)
        obs, reward, terminated, truncated, info = env.step(np.asarray(action, dtype=np.float32))
        if info.get("simulation_failed"):
            return {"seed": seed, "status": "failed", "message": str(info.get("failure_message"))}
        done = terminated or truncated
        observations.append(np.asarray(obs, dtype=np.float64))
        actions.append(np.asarray(action, dtype=np.float32).astype(np.float64))
        rewards.append(float(reward))
        directions.append(np.asarray(info["field_direction"], dtype=np.float64))
        for key in keys:
            columns[key].append(float(info[key]))
    env.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as handle:
        np.savez(
            handle,
            obs=np.array(observations),
            action=np.array(actions),
            reward=np.array(rewards),
            field_direction=np.array(directions),
            schedule_times=np.array(schedule["times"], dtype=float),
            schedule_rates=np.array(schedule["rates"], dtype=float),
            target_times=np.array(target["times"], dtype=float),
            target_values=np.array(target["values"], dtype=float),
            behaviour=np.array(kind),
            behaviour_params=np.array(json.dumps(params)),
            start_index=np.array(index),
            library_key=np.array(library_key),
            policy_digest=np.array(policy.digest if policy is not None else ""),
            **{key: np.array(values) for key, values in columns.items()},
        )
    return {"seed": seed, "status": "finished", "return": float(np.sum(rewards)), "behaviour": kind}


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
    import gymnasium as gym

    import dipenv  # noqa: F401  (registers the ids)

    try:
        probe = gym.make(args.env_id)
    except gym.error.Error as exc:
        parser.error(f"--env-id: {exc}")
    tracking = is_tracking(probe)
    sizes = dict(probe.unwrapped.split_sizes)
    probe.close()
    try:
        check_seeds(seeds, sizes, tracking)
    except ValueError as exc:
        parser.error(f"--seeds: {exc}")
    try:
        claim(
            args.out,
            "scripts/surrogate_data.py",
            {"env_id": args.env_id, "data_version": TRACKING_DATA_VERSION if tracking else DATA_VERSION},
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
