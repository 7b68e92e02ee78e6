"""Simulator episodes for the surrogate: read the files of ``scripts/surrogate_data.py``.

Each ``DIR/episodes/ep<seed>.npz`` holds one ``ThickeningControl`` or ``ViscosityTracking`` episode (layout
in that script's docstring; a tracking episode also holds each interval's field direction and the
target). :func:`load_episodes` reads them into :class:`Episode` records with the interval table of
their schedule (:func:`dipenv.surrogate.features.interval_table`), which the fit and the checks feed to
the models exactly as the environment does.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dipenv.schedules import schedule_from_dict
from dipenv.surrogate.features import N_DYNAMIC, IntervalTable, interval_table

EPISODE_PATTERN = re.compile(r"ep(\d+)\.npz$")


@dataclass(frozen=True)
class Episode:
    """One simulator episode (units as ``ThickeningControl``).

    Attributes:
        seed: the episode's seed (its file name).
        obs: (T + 1, 15) observations (tracking: (T + 1, 21)), before the first action and after each
            interval.
        action: (T,) actions (tracking: (T, 3)); ``mason``: (T,) ``Mn_ref`` in force (``inf``: off).
        eta_r, n1, n2, shear_stress, shear_rate, shear_rate_end, field_energy, reward: (T,) per interval.
        schedule: ``{"times": [...], "rates": [...]}``.
        behaviour: the behaviour policy's name; ``start_index``: the train start state.
        table: the interval table of the schedule.
        direction: (T, 3) the field direction of each interval as the env reports it
            (``info["field_direction"]``, also while the field is off), or None (``ThickeningControl``:
            along ``y``).
        target: the target's knots ``{"times": [...], "values": [...]}`` (tracking episodes), or None.
        target_eta_r: (T,) the target's mean over each interval (what the reward charged), or None.
    """

    seed: int
    obs: np.ndarray
    action: np.ndarray
    mason: np.ndarray
    eta_r: np.ndarray
    n1: np.ndarray
    n2: np.ndarray
    shear_stress: np.ndarray
    shear_rate: np.ndarray
    shear_rate_end: np.ndarray
    field_energy: np.ndarray
    reward: np.ndarray
    schedule: dict[str, list[float]]
    behaviour: str
    start_index: int
    table: IntervalTable
    direction: np.ndarray | None = None
    target: dict[str, list[float]] | None = None
    target_eta_r: np.ndarray | None = None

    @property
    def steps(self) -> int:
        return int(self.action.shape[0])

    @property
    def dynamic(self) -> np.ndarray:
        """(T + 1, 12) the dynamic part of every frame."""
        return self.obs[:, :N_DYNAMIC]


def data_settings(data_dir: str | Path) -> dict[str, Any]:
    """The env settings of a data folder (from its ``manifest.json``'s ``env_id``): ``env_id``,
    ``control_interval``, ``episode_steps``, ``max_piece``, ``n_particles``, ``volume_fraction``,
    ``mason_min``, ``mason_max``, ``off_band``, ``eta_cap``, ``energy_weight``, the schedule ranges; for a
    tracking env (``task: "tracking"``) ``eta_cap`` is None and the target's ranges and preview are
    added (``target_range``, ``target_hold_range``, ``target_ramp_range``, ``target_preview``)."""
    import gymnasium as gym

    import dipenv  # noqa: F401  (registers the ids)

    manifest = json.loads((Path(data_dir) / "manifest.json").read_text())
    env_id = manifest["params"]["env_id"]
    env = gym.make(env_id).unwrapped
    try:
        out = {
            "env_id": env_id,
            "control_interval": float(env.control_interval),  # type: ignore[attr-defined]
            "episode_steps": int(env.episode_steps),  # type: ignore[attr-defined]
            "max_piece": float(env.max_piece),  # type: ignore[attr-defined]
            "n_particles": int(env.base_config.n_particles),  # type: ignore[attr-defined]
            "volume_fraction": float(env.base_config.volume_fraction),  # type: ignore[attr-defined]
            "mason_min": float(env.mapping.mason_min),  # type: ignore[attr-defined]
            "mason_max": float(env.mapping.mason_max),  # type: ignore[attr-defined]
            "off_band": float(env.mapping.off_band),  # type: ignore[attr-defined]
            "eta_cap": float(env.reward_function.target_viscosity),  # type: ignore[attr-defined]
            "energy_weight": float(env.energy_weight),  # type: ignore[attr-defined]
            "rate_range": list(env.rate_range),  # type: ignore[attr-defined]
            "hold_range": list(env.hold_range),  # type: ignore[attr-defined]
            "ramp_range": list(env.ramp_range),  # type: ignore[attr-defined]
            "train_states": int(env.split_sizes["train"]),  # type: ignore[attr-defined]
        }
        if hasattr(env, "target_range"):  # ViscosityTracking: a moving target instead of a cap
            out["task"] = "tracking"
            out["eta_cap"] = None
            for name in ("target_range", "target_hold_range", "target_ramp_range"):
                out[name] = list(getattr(env, name))
            out["target_preview"] = float(env.target_preview)  # type: ignore[attr-defined]
    finally:
        env.close()
    return out


def episode_files(data_dir: str | Path) -> list[tuple[int, Path]]:
    """``(seed, path)`` of every finished episode file, by seed."""
    folder = Path(data_dir) / "episodes"
    found = []
    for path in folder.glob("ep*.npz") if folder.is_dir() else []:
        match = EPISODE_PATTERN.search(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return sorted(found)


def load_episode(path: Path, seed: int, interval: float, max_piece: float) -> Episode:
    """One episode file (:class:`Episode`)."""
    with np.load(path) as d:
        schedule = {"times": d["schedule_times"].tolist(), "rates": d["schedule_rates"].tolist()}
        steps = int(d["action"].shape[0])
        table = interval_table(schedule_from_dict(schedule), steps, interval, max_piece)
        return Episode(
            seed=seed,
            obs=np.asarray(d["obs"], dtype=np.float64),
            action=np.asarray(d["action"], dtype=np.float64),
            mason=np.asarray(d["mason_number"], dtype=np.float64),
            eta_r=np.asarray(d["eta_r"], dtype=np.float64),
            n1=np.asarray(d["n1"], dtype=np.float64),
            n2=np.asarray(d["n2"], dtype=np.float64),
            shear_stress=np.asarray(d["shear_stress"], dtype=np.float64),
            shear_rate=np.asarray(d["shear_rate"], dtype=np.float64),
            shear_rate_end=np.asarray(d["shear_rate_end"], dtype=np.float64),
            field_energy=np.asarray(d["field_energy"], dtype=np.float64),
            reward=np.asarray(d["reward"], dtype=np.float64),
            schedule=schedule,
            behaviour=str(d["behaviour"]),
            start_index=int(d["start_index"]),
            table=table,
            direction=np.asarray(d["field_direction"], dtype=np.float64)
            if "field_direction" in d.files
            else None,
            target=(
                {"times": d["target_times"].tolist(), "values": d["target_values"].tolist()}
                if "target_times" in d.files
                else None
            ),
            target_eta_r=np.asarray(d["target_eta_r"], dtype=np.float64)
            if "target_eta_r" in d.files
            else None,
        )


def load_episodes(data_dir: str | Path, interval: float, max_piece: float) -> list[Episode]:
    """Every finished episode of ``data_dir`` (:func:`episode_files`), by seed."""
    return [load_episode(path, seed, interval, max_piece) for seed, path in episode_files(data_dir)]
