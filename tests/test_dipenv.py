"""dipenv: registration, Gymnasium and SB3 checks, determinism, open-loop consistency, bad actions, the
failure path, flat memory, rendering, history, reset options.

The standard ids are checked with short intervals and a 1/1/1-state library (same classes and code path,
only the arguments that set the cost changed); the tiny ids at their defaults. Start states go to a
temporary cache (``DIPENV_CACHE_DIR``).
"""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import dipenv
import sim
from dipenv.envs.field_control import FieldMagnitudeEnv
from dipenv.observations import observation_features
from dipenv.rewards import DEFAULT_TARGET_VISCOSITY, DEFAULT_VISCOSITY_CAP

TINY_IDS = ["dipenv/FieldMagnitudeTiny-v0", "dipenv/FieldVectorTiny-v0"]
FAST = {
    "control_interval": 0.01,
    "preshear_strain": 0.4,
    "split_sizes": {"train": 1, "validation": 1, "test": 1},
    "mason_min": 0.2,
}
"""Cheap arguments for checking the API of the standard ids (N = 64, phi = 0.45 kept)."""


@pytest.fixture(scope="module", autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("dipenv_cache")
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(root))
    yield root
    patcher.undo()


def make(env_id: str, **kwargs: object) -> gym.Env:
    extra = dict(FAST) if "Tiny" not in env_id else {}
    extra.update(kwargs)
    return gym.make(env_id, progress=False, **extra)


def test_every_id_is_registered() -> None:
    assert set(dipenv.ENV_IDS) == {
        "dipenv/FieldMagnitude-v0",
        "dipenv/FieldVector-v0",
        "dipenv/FieldMagnitudeTiny-v0",
        "dipenv/FieldVectorTiny-v0",
        "dipenv/ThickeningControl-v0",
        "dipenv/ThickeningControlStressOnly-v0",
        "dipenv/ThickeningControlTiny-v0",
        "dipenv/FieldMagnitude-v1",
        "dipenv/FieldVector-v1",
        "dipenv/ThickeningControl-v1",
        "dipenv/ThickeningControlStressOnly-v1",
        "dipenv/ThickeningControl-v2",
        "dipenv/ThickeningControlStressOnly-v2",
        "dipenv/ViscosityTracking-v0",
        "dipenv/ViscosityTrackingStressOnly-v0",
        "dipenv/ViscosityTrackingTiny-v0",
    }
    for env_id in dipenv.ENV_IDS:
        assert gym.spec(env_id).max_episode_steps is None  # the envs truncate at their own episode_steps


V0_IDS = [
    env_id
    for env_id in dipenv.ENV_IDS
    if env_id.endswith("-v0") and gym.spec(env_id).kwargs.get("n_particles", 64) <= 64
]
"""The ids whose API is checked by running them (a ``-v1`` id is its ``-v0`` class in a bigger box). The
viscosity-tracking ``-v0`` ids hold N = 300 from their first version: tests/test_viscosity_tracking.py runs
their classes in the tiny box."""


@pytest.mark.parametrize("env_id", [i for i in dipenv.ENV_IDS if i.endswith("-v1")])
def test_v1_is_v0_in_the_box_of_the_box_size_study(env_id: str) -> None:
    """Same class and arguments as ``-v0`` but N = 300 (and, for thickening control, the energy weight
    re-chosen for that box), and the reward's default target or cap is the one tabulated for (0.45, 300),
    not N = 64's (checked at make: no start state is generated)."""
    v0 = gym.spec(env_id.replace("-v1", "-v0"))
    v1 = gym.spec(env_id)
    assert v1.entry_point == v0.entry_point
    changed = {"n_particles": 300}
    if "Thickening" in env_id:
        changed["energy_weight"] = dipenv.THICKENING_ENERGY_WEIGHT_V1
    assert v1.kwargs == {**v0.kwargs, **changed}
    env = gym.make(env_id, progress=False).unwrapped
    v0_weight = gym.make(env_id.replace("-v1", "-v0"), progress=False).unwrapped.reward_function.energy_weight
    assert env.reward_function.energy_weight == changed.get("energy_weight", v0_weight)
    assert env.base_config.n_particles == 300
    assert env.base_config.volume_fraction == 0.45
    table = DEFAULT_VISCOSITY_CAP if "Thickening" in env_id else DEFAULT_TARGET_VISCOSITY
    assert env.reward_function.target_viscosity == table[(0.45, 300)]
    assert table[(0.45, 300)] != table[(0.45, 64)]


@pytest.mark.parametrize("env_id", [i for i in dipenv.ENV_IDS if i.endswith("-v2")])
def test_v2_is_v1_with_the_strongest_field_at_mn_0_1(env_id: str) -> None:
    """``-v2`` changes only the strongest field of the action map (``u = 1``: ``Mn_ref`` 0.1, not 0.05);
    the physics, and so the start-state library and every constant field's episodes, are ``-v1``'s."""
    v1 = gym.spec(env_id.replace("-v2", "-v1"))
    v2 = gym.spec(env_id)
    assert v2.entry_point == v1.entry_point
    assert v2.kwargs == {**v1.kwargs, "mason_min": 0.1}
    env1 = gym.make(v1.id, progress=False).unwrapped
    env2 = gym.make(env_id, progress=False).unwrapped
    assert env1.mapping.mason_number(1.0) == pytest.approx(0.05, rel=1e-12)
    assert env2.mapping.mason_number(1.0) == pytest.approx(0.1, rel=1e-12)
    assert env2.mapping.mason_number(-0.9) == pytest.approx(20.0, rel=1e-12)
    assert env2.mapping.mason_number(-1.0) == math.inf
    assert env2.library().key == env1.library().key
    s1, s2 = env1.settings(), env2.settings()
    assert (s1.pop("mason_min"), s2.pop("mason_min")) == (0.05, 0.1) and s1 == s2


def _wrapper_names(env: gym.Env) -> list[str]:
    names = []
    while isinstance(env, gym.Wrapper):
        names.append(type(env).__name__)
        env = env.env
    return names


@pytest.mark.parametrize("env_id", dipenv.ENV_IDS)
def test_episode_steps_given_to_make_is_the_episode_length(env_id: str) -> None:
    """``gym.make(id, episode_steps=20)`` used to be cut at the registered limit (TimeLimit) while
    ``settings()`` said 20; now no time limit is registered and the env truncates itself."""
    env = make(env_id, episode_steps=20)
    assert "TimeLimit" not in _wrapper_names(env), _wrapper_names(env)
    assert env.unwrapped.settings()["episode_steps"] == 20
    assert env.spec is not None and env.spec.max_episode_steps is None


@pytest.mark.parametrize(
    ("split_sizes", "needle"),
    [
        ({"train": 0, "validation": 1, "test": 1}, "split_sizes['train'] must be an integer in [1, 100000]"),
        ({"train": 1, "validation": 1, "test": 1, "bogus": 2}, "split_sizes has unknown split 'bogus'"),
        ({"train": 1, "validation": 1}, "split_sizes['test'] must be an integer in [1, 100000], got 0"),
        ({"train": 1.5, "validation": 1, "test": 1}, "split_sizes['train'] must be an integer"),
        ([1, 1, 1], "split_sizes must be a dict of train, validation, test to sizes"),
    ],
)
def test_bad_split_sizes_are_refused_at_make(split_sizes: object, needle: str) -> None:
    """They used to be accepted at ``make`` and fail only at ``reset``."""
    for env_id in ("dipenv/FieldMagnitudeTiny-v0", "dipenv/ThickeningControlTiny-v0"):
        with pytest.raises(ValueError) as caught:
            make(env_id, split_sizes=split_sizes)
        assert needle in str(caught.value), caught.value


@pytest.mark.parametrize("env_id", V0_IDS)
def test_gymnasium_and_sb3_check_env(env_id: str) -> None:
    env = make(env_id, render_mode="rgb_array")
    gym_check_env(env.unwrapped, skip_render_check=False)
    sb3_check_env(make(env_id), warn=True)


def test_determinism_same_seed_same_actions() -> None:
    """Two envs, the same seed and actions: bit-identical observations, rewards and physics."""
    actions = [np.array([a], dtype=np.float32) for a in (0.9, -1.0, 0.3, 0.6, -0.5)]
    runs = []
    for _ in range(2):
        env = make("dipenv/FieldMagnitudeTiny-v0")
        obs, info = env.reset(seed=11)
        trace = [obs, info["index"]]
        for a in actions:
            obs, reward, *_, info = env.step(a)
            trace += [obs, reward, info["eta_r"], info["n1"]]
        runs.append(trace)
    for x, y in zip(*runs, strict=True):
        np.testing.assert_array_equal(x, y)
    env = make("dipenv/FieldMagnitudeTiny-v0")
    indices = {env.reset(seed=s)[1]["index"] for s in range(20)}
    assert len(indices) > 1  # the start state is drawn from the split


def test_constant_action_reproduces_open_loop_run() -> None:
    """A constant action over 3 intervals equals a plain Simulation at that Mn from the same state."""
    env = make("dipenv/FieldMagnitudeTiny-v0")
    unwrapped = env.unwrapped
    u = np.float32(0.4)
    mn = unwrapped.mapping.mason_number(float(u))  # of the float32 action the env receives
    env.reset(seed=0, options={"split": "test", "index": 1})
    etas, energies = [], []
    for _ in range(3):
        _, _, _, _, info = env.step(np.array([u], dtype=np.float32))
        etas.append(info["eta_r"])
        energies.append(info["field_energy"])
    start = unwrapped.library().load("test", 1)
    config = unwrapped._simulation.config
    simulation = sim.Simulation(config, state=start.state, keep_records=False)
    simulation.set_field(mn, (0.0, 1.0, 0.0))
    t0 = simulation.state.strain
    for k in range(3):
        records = simulation.advance_to(t0 + (k + 1) * unwrapped.control_interval)
        eta = sim.rheology(records.stress.sum(axis=1))[0]
        expected = float(np.sum(records.time_step * eta) / records.time_step.sum())
        assert etas[k] == pytest.approx(expected, rel=1e-12)
        assert energies[k] == pytest.approx(1.0 / mn, rel=1e-12)


@pytest.mark.parametrize(
    "action",
    [
        np.array([np.nan], dtype=np.float32),
        np.array([np.inf]),
        np.array([0.1, 0.2]),
        np.array(0.5),
        np.zeros((1, 1)),
        np.array(["a"]),
    ],
)
def test_bad_actions_are_rejected(action: np.ndarray) -> None:
    env = FieldMagnitudeEnv(**{**dipenv.TINY_KWARGS, "progress": False})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


def test_out_of_range_action_is_clipped_and_flagged() -> None:
    env = make("dipenv/FieldMagnitudeTiny-v0")
    env.reset(seed=0)
    *_, info = env.unwrapped.step(np.array([3.0]))
    assert info["action_clipped"] and info["mason_number"] == pytest.approx(env.unwrapped.mapping.mason_min)
    *_, info = env.unwrapped.step(np.array([0.0]))
    assert not info["action_clipped"]


def test_failure_path_terminates_with_flag_and_penalty() -> None:
    """A solver that cannot converge (10 iterations to 1e-14) fails the first step: terminated, flagged."""
    env = make(
        "dipenv/FieldMagnitudeTiny-v0",
        simulation_overrides={"solver_max_iterations": 10, "solver_tolerance": 1e-14},
    )
    env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(np.array([1.0], dtype=np.float32))
    assert terminated and not truncated
    assert info["simulation_failed"] and info["failure_message"]
    steps = env.unwrapped.episode_steps
    assert reward == pytest.approx(-env.unwrapped.failure_penalty * steps)
    assert env.observation_space.contains(obs)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.array([0.0]))
    env.reset(seed=1)  # usable again


def test_truncation_after_episode_steps() -> None:
    env = make("dipenv/FieldMagnitudeTiny-v0", episode_steps=3)
    env.reset(seed=0)
    flags = [env.step(np.array([-1.0], dtype=np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]


def test_memory_stays_flat() -> None:
    """Python allocations do not grow with the number of steps (records are not kept)."""
    env = make("dipenv/FieldMagnitudeTiny-v0", control_interval=0.004, episode_steps=10_000)
    env.reset(seed=0)
    action = np.array([-1.0], dtype=np.float32)
    for _ in range(20):
        env.step(action)
    tracemalloc.start()
    for _ in range(50):
        env.step(action)
    first, _ = tracemalloc.get_traced_memory()
    for _ in range(250):
        env.step(action)
    second, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert second - first < 100_000, (first, second)


def test_render_rgb_array() -> None:
    env = make("dipenv/FieldVectorTiny-v0", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
    image = env.render()
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    assert image.std() > 0


def test_history_stacks_previous_frames() -> None:
    env = make("dipenv/FieldMagnitudeTiny-v0", history_length=2)
    frame = len(observation_features(False))
    assert env.observation_space.shape == (3 * frame,)
    obs0, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs0[:frame], obs0[frame : 2 * frame])
    obs1, *_ = env.step(np.array([0.5], dtype=np.float32))
    np.testing.assert_array_equal(obs1[frame : 2 * frame], obs0[:frame])
    assert len(env.unwrapped.observation_labels) == 3 * frame


def _documented_observation(doc: str) -> tuple[list[int], list[str]]:
    """(indices, names) of the table in the docstring's "## Observation Space" section (the lines up to the
    next "## " heading): each row's index cell ("3" or "3-7") and its comma-separated names, in order."""
    lines = [line.strip() for line in doc.splitlines()]
    headings = [i for i, line in enumerate(lines) if line.startswith("## ")]
    start = next(i for i in headings if lines[i] == "## Observation Space")
    end = next((i for i in headings if i > start), len(lines))
    rows = [
        [c.strip() for c in line.strip("|").split("|")] for line in lines[start + 1 : end] if line[:1] == "|"
    ]
    assert rows[0][:2] == ["index", "name"] and set(rows[1][0]) == {"-"}, rows[:2]
    indices: list[int] = []
    names: list[str] = []
    for index, cell, *_ in rows[2:]:
        first, _, last = index.partition("-")
        row_indices = list(range(int(first), int(last or first) + 1))
        row_names = [name.strip() for name in cell.split(",")]
        assert len(row_indices) == len(row_names), (index, cell)
        indices += row_indices
        names += row_names
    return indices, names


def test_observation_layout_is_documented() -> None:
    """Every registered env class's docstring documents its observation frame: the table of its "##
    Observation Space" section names every feature, by its full name, at its index, in order."""
    classes = set()
    for env_id in dipenv.ENV_IDS:
        wrapped = make(env_id)
        env = wrapped.unwrapped
        cls = type(env)
        classes.add(cls)
        names = [f.name for f in env.frame_features()]
        assert env.observation_labels == names  # history_length 0: one frame
        if cls in (dipenv.FieldMagnitudeEnv, dipenv.FieldVectorEnv):
            assert names == [f.name for f in observation_features(cls is dipenv.FieldVectorEnv)]
        doc = cls.__doc__ or ""
        sections = ["Description", "Observation Space"]
        if cls is not dipenv.ThickeningControlStressOnlyEnv:  # which refers to ThickeningControlEnv for them
            sections += ["Action Space", "Rewards", "Starting State", "Episode End"]
        for section in sections:
            assert f"## {section}" in doc, (cls.__name__, section)
        indices, documented = _documented_observation(doc)
        missing, extra = [n for n in names if n not in documented], [n for n in documented if n not in names]
        assert documented == names, f"{cls.__name__}: missing {missing}, not features {extra}: {documented}"
        assert indices == list(range(len(names))), (cls.__name__, indices)
        wrapped.close()
    assert classes == {
        dipenv.FieldMagnitudeEnv,
        dipenv.FieldVectorEnv,
        dipenv.ThickeningControlEnv,
        dipenv.ThickeningControlStressOnlyEnv,
        dipenv.ViscosityTrackingEnv,
        dipenv.ViscosityTrackingStressOnlyEnv,
    }


def test_reset_options() -> None:
    env = make("dipenv/FieldMagnitudeTiny-v0")
    _, info = env.reset(seed=0, options={"split": "validation", "index": 1})
    assert (info["split"], info["index"], info["packing_seed"]) == ("validation", 1, 100_001)
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"phi": 0.4})
    with pytest.raises(ValueError, match="index"):
        env.reset(options={"index": 99})
    cycle = make("dipenv/FieldMagnitudeTiny-v0", split="test", start_state="cycle")
    assert [cycle.reset()[1]["index"] for _ in range(3)] == [0, 1, 0]
    _, info = env.reset(seed=0, options={"volume_fraction": 0.40, "index": 0})
    assert info["volume_fraction"] == 0.40 and info["library_key"] != env.unwrapped.library().key


def test_actuator_lag_and_vector_direction() -> None:
    env = make("dipenv/FieldVectorTiny-v0", actuator_time_constant=0.02)
    env.reset(seed=0)
    mapping = env.unwrapped.mapping
    *_, info = env.step(np.array([1.0, 1.0, 0.0], dtype=np.float32))  # strongest field along x
    command = mapping.amplitude(info["mason_number_command"])
    expected = command * (1.0 - math.exp(-env.unwrapped.control_interval / 0.02))
    assert mapping.amplitude(info["mason_number"]) == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(info["field_direction"], [1.0, 0.0, 0.0], atol=1e-12)
    assert 0.0 < info["field_energy"] < 1.0 / info["mason_number_command"]
