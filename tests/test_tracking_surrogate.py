"""The tracking surrogate (issue 44): the direction block of the inputs, the old models' bit identity, the
tracking data script on the tiny id (writes and resumes), the fit with the direction block, and the env
``dipenv/ViscosityTrackingSurrogate-v0`` (Gymnasium's checkers, the simulator env's draws and frame, the
tracking reward on a known step), and the acceptance check ``scripts/surrogate_check.py`` on the tiny
tracking id."""

from __future__ import annotations

import contextlib
import io
import json
import math
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from agents_helpers import load_script, refused
from gymnasium.utils.env_checker import check_env
from surrogate_reference import reference_values

import dipenv
from dipenv.actions import canonical_direction
from dipenv.envs.viscosity_tracking import field_orientation, tracking_direction
from dipenv.schedules import schedule_from_dict
from dipenv.surrogate import EnsembleModel, ViscosityTrackingSurrogateEnv, load_model, surrogate_kwargs
from dipenv.surrogate.data import load_episodes
from dipenv.surrogate.features import (
    DIRECTION_COMPONENTS,
    DIRECTION_INPUT_LABELS,
    MLP_INPUT_LABELS,
    N_DIRECTION,
    N_DIRECTION_INPUTS,
    N_DYNAMIC,
    N_MLP_INPUTS,
    direction_features,
    direction_tensor,
    field_stress_features,
    interval_table,
    mlp_input_labels,
    mlp_inputs,
    mlp_inputs_into,
    signed_log,
)
from dipenv.tracking import validate_target

ROOT = Path(__file__).resolve().parents[1]
TINY = "dipenv/ViscosityTrackingTiny-v0"
TINY_SETTINGS = {"control_interval": 0.02, "n_particles": 32, "volume_fraction": 0.45}
SURROGATE_ID = "dipenv/ViscosityTrackingSurrogate-v0"
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def script(name: str) -> ModuleType:
    return load_script(name, cached=True)


def unit_vectors(count: int, seed: int = 0) -> np.ndarray:
    e = np.random.default_rng(seed).standard_normal((count, 3))
    return e / np.linalg.norm(e, axis=1, keepdims=True)


# -- the direction block -------------------------------------------------------------------------------------
@pytest.mark.parametrize("axis", sorted(AXES))
def test_direction_block_of_the_axes(axis: str) -> None:
    """``e e^T - I/3`` along x, y, z: 2/3 on the axis' diagonal entry, -1/3 on the others, no
    off-diagonal entry; the same for ``-e``."""
    e = np.array(AXES[axis])
    block = direction_features(e)
    diagonal = np.full(3, -1.0 / 3.0)
    diagonal["xyz".index(axis)] = 2.0 / 3.0
    assert block.shape == (N_DIRECTION,)
    np.testing.assert_allclose(block, [diagonal[0], diagonal[1], 0.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(direction_tensor(block), np.diag(diagonal), atol=1e-15)
    assert np.array_equal(direction_features(-e), block)


def test_direction_block_is_the_traceless_symmetric_tensor() -> None:
    """For random unit vectors (batched): the 5 components are those of ``outer(e, e) - I/3``, which is
    symmetric and traceless (its ``zz`` is ``-(xx + yy)``), and ``e -> -e`` changes nothing."""
    e = unit_vectors(64)
    block = direction_features(e)
    assert block.shape == (64, N_DIRECTION)
    full = np.einsum("bi,bj->bij", e, e) - np.eye(3) / 3.0
    assert np.allclose(np.trace(full, axis1=1, axis2=2), 0.0, atol=1e-15)
    np.testing.assert_allclose(direction_tensor(block), full, atol=1e-15)
    tensor = direction_tensor(block)
    assert np.array_equal(tensor, np.swapaxes(tensor, 1, 2))
    assert np.allclose(np.trace(tensor, axis1=1, axis2=2), 0.0, atol=1e-15)
    assert np.array_equal(direction_features(-e), block)
    assert direction_features(e.reshape(8, 8, 3)).shape == (8, 8, N_DIRECTION)


def test_inputs_carry_the_block_only_when_asked() -> None:
    """Without the block the inputs are the 22 of before; with it 15 more (previous, then this interval's
    direction, then this interval's field stress scale; ``None`` is ``y``). The env's scalar path writes
    the block as the batched one does (the direction bits exactly; the field stress's logs to round-off,
    ``math.log10`` against ``np.log10``)."""
    assert N_DIRECTION_INPUTS == 15 and len(DIRECTION_INPUT_LABELS) == 15
    assert mlp_input_labels(False) == MLP_INPUT_LABELS and len(mlp_input_labels(True)) == N_MLP_INPUTS + 15
    rng = np.random.default_rng(1)
    dynamic = rng.normal(size=(5, N_DYNAMIC))
    before, now = unit_vectors(5, 2), unit_vectors(5, 3)
    masons = np.array([np.inf, 0.3, 2.0, np.inf, 15.0])
    rates = (np.full(5, 0.7), np.full(5, 1.1), np.full(5, 2.0))
    plain = mlp_inputs(dynamic, np.roll(masons, 1), masons, *rates)
    with_block = mlp_inputs(dynamic, np.roll(masons, 1), masons, *rates, before, now, direction_block=True)
    assert plain.shape == (5, N_MLP_INPUTS) and with_block.shape == (5, N_MLP_INPUTS + N_DIRECTION_INPUTS)
    assert np.array_equal(with_block[:, :N_MLP_INPUTS], plain)
    assert np.array_equal(with_block[:, N_MLP_INPUTS : N_MLP_INPUTS + 5], direction_features(before))
    assert np.array_equal(with_block[:, N_MLP_INPUTS + 5 : N_MLP_INPUTS + 10], direction_features(now))
    stress = with_block[:, N_MLP_INPUTS + 10 :]
    assert np.array_equal(stress, field_stress_features(now, masons, rates[1]))
    assert np.all(stress[np.isinf(masons)] == 0.0)  # off: no field stress (the direction is still given)
    default = mlp_inputs(dynamic, np.roll(masons, 1), masons, *rates, direction_block=True)
    y_block = direction_features(np.array(AXES["y"]))
    assert np.array_equal(default[:, N_MLP_INPUTS : N_MLP_INPUTS + 10], np.tile(y_block, (5, 2)))
    for row in range(5):  # the old inputs agree to round-off (math.log10 against np.log10), as before
        args = (dynamic[row], float(np.roll(masons, 1)[row]), float(masons[row]), 0.7, 1.1, 2.0)
        np.testing.assert_allclose(mlp_inputs_into(np.empty(N_MLP_INPUTS), *args), plain[row], rtol=1e-15)
        scalar = mlp_inputs_into(np.empty(N_MLP_INPUTS + N_DIRECTION_INPUTS), *args, before[row], now[row])
        np.testing.assert_allclose(scalar, with_block[row], rtol=1e-15)
        assert np.array_equal(
            scalar[N_MLP_INPUTS : N_MLP_INPUTS + 10], with_block[row, N_MLP_INPUTS : N_MLP_INPUTS + 10]
        )


def test_field_stress_scale_is_the_dipole_to_viscous_stress_ratio() -> None:
    """``field_stress_features``: the signed log of ``(e e^T - I/3) / (Mn_ref x rate)``, checked by hand on
    the shear plane's diagonals (``xy = -+1/2``) and the vorticity axis (``zz = 2/3``, no ``xy``): at
    ``Mn_ref`` 0.1 and rate 0.5 (``Mn`` 0.05) the compressional diagonal gives ``xy = -10``, i.e.
    ``-log10 11``; the sign of ``e`` does not matter (quadratic in the field); off gives zeros."""
    h = np.sqrt(0.5)
    comp, ext, z = np.array([h, -h, 0.0]), np.array([h, h, 0.0]), np.array(AXES["z"])
    got = field_stress_features(np.stack([comp, -comp, ext, z]), np.full(4, 0.1), np.full(4, 0.5))
    xy = DIRECTION_COMPONENTS.index("xy")
    np.testing.assert_allclose(
        got[:, xy], [-np.log10(11.0), -np.log10(11.0), np.log10(11.0), 0.0], atol=1e-14
    )
    xx, yy = DIRECTION_COMPONENTS.index("xx"), DIRECTION_COMPONENTS.index("yy")
    np.testing.assert_allclose(got[3, [xx, yy]], -np.log10(1.0 + (1.0 / 3.0) / 0.05), rtol=1e-14)
    assert np.array_equal(field_stress_features(comp, np.inf, 0.5), np.zeros(5))


# -- the old models ------------------------------------------------------------------------------------------
def test_shipped_models_are_bit_identical_to_mains_code() -> None:
    """``surrogate_v0`` and ``surrogate_v1`` (fitted without the block): the env's step path, the batched
    one-step and rollout paths and a whole seeded ``ThickeningControlSurrogate-v0`` episode give exactly
    the values ``main``'s code gave before the block existed (``tests/surrogate_reference.py``)."""
    stored = json.loads((ROOT / "tests" / "reference_data" / "surrogate_bit_identity.json").read_text())
    now = reference_values(ROOT / "dipenv" / "data")
    assert set(now) == set(stored)
    for name, values in stored.items():
        assert not load_model(ROOT / "dipenv" / "data" / name).direction
        for key, expected in values.items():
            assert now[name][key] == expected, f"{name}: {key} differs from main's code"


# -- a direction-aware model for the env tests ---------------------------------------------------------------
V0_SETTINGS = {"control_interval": 0.25, "n_particles": 300, "volume_fraction": 0.45}


def random_direction_model(settings: dict[str, Any], seed: int = 0) -> EnsembleModel:
    """A two-member ensemble with the direction block and small random weights (an untrained model: the
    env tests need the interface, not the physics)."""
    rng = np.random.default_rng(seed)
    inputs, hidden, members = N_MLP_INPUTS + N_DIRECTION_INPUTS, 8, 2
    frames = np.tile(np.array([1.0, 0.5, -0.3, *([0.0] * 5), 5.0, 2.0, 1.5, 1.0]), (4, 1))
    arrays = {
        "w1": rng.normal(0.0, 0.1, (members, inputs, hidden)),
        "b1": np.zeros((members, hidden)),
        "w2": rng.normal(0.0, 0.1, (members, hidden, hidden)),
        "b2": np.zeros((members, hidden)),
        "w3": rng.normal(0.0, 0.1, (members, hidden, 2 * N_DYNAMIC)),
        "b3": np.zeros((members, 2 * N_DYNAMIC)),
        "x_mean": np.zeros(inputs),
        "x_std": np.ones(inputs),
        "y_mean": np.zeros(N_DYNAMIC),
        "y_std": np.full(N_DYNAMIC, 0.02),
        "max_logvar": np.zeros(N_DYNAMIC),
        "min_logvar": np.full(N_DYNAMIC, -4.0),
        "start_frames": frames,
        "start_indices": np.arange(4),
        "low": frames[0] - 1.0,
        "high": frames[0] + 1.0,
    }
    return EnsembleModel(arrays, {"settings": settings, "direction_inputs": True})


def tiny_surrogate(model: Any, **kwargs: Any) -> ViscosityTrackingSurrogateEnv:
    return ViscosityTrackingSurrogateEnv(**surrogate_kwargs(TINY, model=model, **kwargs))


# -- the data script and the fit on the tiny id --------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[list[str]]]:
    """Tracking episodes 0-3 of the tiny id (one per behaviour), then a rerun over 0-5 (resume)."""
    data = script("surrogate_data")
    out = tmp_path_factory.mktemp("tracking") / "data"
    runs = []
    for seeds in ("0-3", "0-5"):
        buffer = io.StringIO()
        with contextlib.redirect_stdout(buffer):
            assert data.main(["--out", str(out), "--seeds", seeds, "--env-id", TINY]) == 0
        runs.append(buffer.getvalue().splitlines())
    return out, runs


def test_data_script_writes_tracking_episodes_and_resumes(tiny_data) -> None:
    out, (first, second) = tiny_data
    data = script("surrogate_data")
    records = [json.loads(line) for line in first]
    assert [r["status"] for r in records] == ["finished"] * 4
    assert [r["behaviour"] for r in records] == list(data.TRACKING_BEHAVIOURS)
    again = [json.loads(line) for line in second]
    assert [r["status"] for r in again] == ["reused"] * 4 + ["finished"] * 2
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["params"] == {"env_id": TINY, "data_version": data.TRACKING_DATA_VERSION}
    env = gym.make(TINY, progress=False).unwrapped
    for seed in range(6):
        with np.load(out / "episodes" / f"ep{seed:05d}.npz") as d:
            steps = env.episode_steps
            assert d["obs"].shape == (steps + 1, 21) and d["action"].shape == (steps, 3)
            assert int(d["start_index"]) == seed % env.split_sizes["train"]
            directions = d["field_direction"]
            for action, e in zip(d["action"], directions, strict=True):  # as the env reports it
                expected = field_orientation(canonical_direction(tracking_direction(action[1], action[2])))
                np.testing.assert_allclose(e, expected, atol=1e-7)
            np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=1e-12)
            np.testing.assert_array_equal(d["obs"][1:, 14:17], directions.astype(np.float32))
            target = validate_target(
                {"times": d["target_times"].tolist(), "values": d["target_values"].tolist()}
            )
            means = [target.mean(k * 0.02, (k + 1) * 0.02) for k in range(steps)]
            np.testing.assert_allclose(d["target_eta_r"], means, rtol=1e-12)
            penalty = np.abs(d["eta_r"] - d["target_eta_r"]) + 0.1 * d["field_energy"]
            np.testing.assert_allclose(d["reward"], -penalty, rtol=1e-12, atol=1e-12)
            params = json.loads(str(d["behaviour_params"]))
            if str(d["behaviour"]) == "switch":  # the parameters as drawn: the first leg's axis and length
                polar = -1.0 if params["first"] == "y" else 1.0
                legs = min(params["first_leg"], steps)
                assert np.all(d["action"][:legs, 1] == polar) and np.all(d["action"][:legs, 2] == 0.5)
                if legs < steps:
                    assert d["action"][legs, 1] == -polar
    env.close()


def test_data_script_refuses_the_fixed_splits_seeds(capsys, tmp_path: Path) -> None:
    main = script("surrogate_data").main
    for seeds, what in (("998-1001", "validation schedules"), ("2005", "test schedules")):
        err = refused(capsys, main, ["--out", str(tmp_path / "x"), "--seeds", seeds, "--env-id", TINY])
        assert what in err
    assert not (tmp_path / "x").exists()
    check = script("surrogate_data").check_seeds
    with pytest.raises(ValueError, match="validation targets"):
        check([4_000_003], {"train": 64, "validation": 8, "test": 16})
    check([4_000_003], {"train": 64}, tracking=False)  # no targets in ThickeningControl
    check(list(range(100)), {"train": 64, "validation": 8, "test": 16})  # the documented range


@pytest.fixture(scope="module")
def tiny_fit(tiny_data, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    folder, _ = tiny_data
    out = tmp_path_factory.mktemp("fit") / "tracking.npz"
    argv = [str(folder), "--out", str(out), "--members", "2", "--hidden", "8", "--max-epochs", "3"]
    summary = script("fit_surrogate").main([*argv, "--samples", "3", "--patience", "2"])
    return out, summary


def test_fit_takes_the_direction_block(tiny_data, tiny_fit, capsys) -> None:
    folder, _ = tiny_data
    out, summary = tiny_fit
    model = load_model(out)
    assert model.kind == "ensemble" and model.direction and model.metadata["direction_inputs"]
    assert model.w[0].shape == (2, N_MLP_INPUTS + N_DIRECTION_INPUTS, 8)
    assert summary["kept"] == "ensemble" and summary["settings"]["task"] == "tracking"
    fit = script("fit_surrogate")
    episodes = load_episodes(folder, 0.02, 0.01)
    held = [e for e in episodes if e.seed % 5 == 4]
    metrics = summary["routes"]["ensemble"]["held_out"]
    # the simulator's returns are the tracking reward's, as the env charged them
    assert metrics["return_simulator_mean"] == pytest.approx(
        np.mean([e.reward.sum() for e in held]), rel=1e-12
    )
    x, y = fit.transitions(episodes[:1], direction=True)
    e = episodes[0]
    assert x.shape == (e.steps, N_MLP_INPUTS + N_DIRECTION_INPUTS) and y.shape == (e.steps, N_DYNAMIC)
    np.testing.assert_array_equal(
        x[0, N_MLP_INPUTS : N_MLP_INPUTS + 5], direction_features(np.array(AXES["y"]))
    )
    np.testing.assert_array_equal(
        x[1:, N_MLP_INPUTS : N_MLP_INPUTS + 5], direction_features(e.direction[:-1])
    )
    np.testing.assert_array_equal(x[:, N_MLP_INPUTS + 5 : N_MLP_INPUTS + 10], direction_features(e.direction))
    np.testing.assert_array_equal(
        x[:, N_MLP_INPUTS + 10 :], field_stress_features(e.direction, e.mason, e.table.rate_mean)
    )
    np.testing.assert_array_equal(x[:, :N_MLP_INPUTS], fit.transitions(episodes[:1])[0])
    # the model's batched paths read the directions: another direction, another prediction
    dyn, masons = e.dynamic[None], e.mason[None]
    turned = np.tile([1.0, 0.0, 0.0], (1, e.steps, 1))
    a = model.one_step(dyn, masons, [e.table], directions=e.direction[None])
    b = model.one_step(dyn, masons, [e.table], directions=turned)
    assert not np.array_equal(a, b)
    err = refused(capsys, fit.main, [str(folder), "--out", str(out.parent / "x.npz"), "--routes", "lambda"])
    assert "fields along y only" in err


# -- the surrogate env ---------------------------------------------------------------------------------------
def test_registered_id_has_the_tracking_ids_settings(tmp_path: Path) -> None:
    spec = gym.spec(SURROGATE_ID)
    assert spec.kwargs == gym.spec("dipenv/ViscosityTracking-v0").kwargs
    assert SURROGATE_ID in dipenv.TRACKING_SURROGATE_IDS and SURROGATE_ID not in dipenv.SURROGATE_IDS
    path = tmp_path / "model.npz"
    random_direction_model(V0_SETTINGS).save(path)
    env = gym.make(SURROGATE_ID, model=str(path)).unwrapped
    simulator = gym.make("dipenv/ViscosityTracking-v0", progress=False).unwrapped
    assert env.observation_space == simulator.observation_space
    assert env.action_space == simulator.action_space
    assert env.observation_labels == simulator.observation_labels
    assert env.reward_function == simulator.reward_function  # ViscosityTargetReward(15, 0.1, 50) before reset
    assert env.mapping == simulator.mapping and env.energy_weight == 0.1
    assert env.settings()["target"] == simulator.settings()["target"]


def test_gymnasium_env_checkers_pass(tmp_path: Path) -> None:
    path = tmp_path / "model.npz"
    random_direction_model(V0_SETTINGS).save(path)
    assert load_model(path).direction  # the flag survives the file
    check_env(gym.make(SURROGATE_ID, model=str(path)).unwrapped, skip_render_check=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the passive checker warns; make any warning fail
        env = gym.make(SURROGATE_ID, model=str(path), disable_env_checker=False)
        env.reset(seed=0)
        for _ in range(48):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert truncated and not terminated
        env.close()


def test_reward_is_the_tracking_reward_on_a_known_step() -> None:
    """``r = -(|eta_r - target| + w_E / Mn_ref)``: ``eta_r`` the model's interval value, the target's exact
    mean over the interval (from the episode's knots), ``w_E = 0.1``, the field of the action."""
    env = gym.make(SURROGATE_ID, model=random_direction_model(V0_SETTINGS)).unwrapped
    _, info = env.reset(seed=4)
    target = validate_target(info["target"])
    action = np.array([0.5, 0.0, 0.5], dtype=np.float32)  # a field along (y+z)/sqrt2
    mason = env.mapping.mason_number(0.5)
    for k in range(3):
        obs, reward, terminated, truncated, step_info = env.step(action)
        target_mean = target.mean(0.25 * k, 0.25 * (k + 1))
        expected = -(abs(step_info["eta_r"] - target_mean) + 0.1 / mason)
        assert reward == pytest.approx(expected, rel=1e-14, abs=1e-14) and step_info["reward"] == reward
        assert step_info["target_eta_r"] == pytest.approx(target_mean, rel=1e-14)
        assert step_info["reward_viscosity"] == pytest.approx(
            -abs(step_info["eta_r"] - target_mean), rel=1e-14
        )
        assert step_info["reward_energy"] == pytest.approx(-0.1 / mason, rel=1e-14)
        assert step_info["tracking_error"] == pytest.approx(step_info["eta_r"] - target_mean, rel=1e-14)
        np.testing.assert_allclose(
            step_info["field_direction"], [0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-15
        )
        assert float(obs[0]) == pytest.approx(float(signed_log(step_info["eta_r"])), abs=1e-6)
        now = 0.25 * (k + 1)
        np.testing.assert_allclose(
            obs[18:], signed_log([target(now), target.mean(now, now + 0.25), target(now + 1.0)]), atol=1e-6
        )
        assert not terminated and not truncated


def test_draws_and_frame_are_the_simulator_envs() -> None:
    """Same seed: same start index, rate schedule and target as ``ViscosityTrackingTiny-v0`` (train), the
    fixed ones on validation; after the same actions, the same frame outside its dynamic part (field,
    direction, rate, target), bit for bit in float32."""
    env = tiny_surrogate(random_direction_model(TINY_SETTINGS))
    simulator = gym.make(TINY, progress=False).unwrapped
    for options in ({}, {"split": "validation", "index": 1}):
        obs, info = env.reset(seed=3, options=options)
        sim_obs, sim_info = simulator.reset(seed=3, options=options)
        for key in ("split", "index", "schedule", "target", "target_eta_r", "target_viscosity"):
            assert info[key] == sim_info[key], key
        assert "eta_cap" not in info
        assert np.array_equal(obs[N_DYNAMIC:], sim_obs[N_DYNAMIC:])
        rng = np.random.default_rng(0)
        for _ in range(3):
            action = rng.uniform(-1, 1, 3).astype(np.float32)
            obs, _, _, _, step_info = env.step(action)
            sim_obs, _, _, _, sim_step = simulator.step(action)
            assert np.array_equal(obs[N_DYNAMIC:], sim_obs[N_DYNAMIC:])
            assert np.array_equal(step_info["field_direction"], sim_step["field_direction"])
            for key in ("target_eta_r", "target_eta_r_end", "mason_number", "field_energy", "shear_rate_end"):
                assert step_info[key] == pytest.approx(sim_step[key], rel=1e-12), key
    simulator.close()


def test_same_seed_same_episode_and_a_controller_plays_it() -> None:
    from agents.tracking_controllers import AnglePIController

    def episode(seed: int) -> list[float]:
        env = tiny_surrogate(random_direction_model(TINY_SETTINGS))
        controller = AnglePIController(1.0, 0.2, 1.0, 0.0, 0.5, "next").bind(env)
        obs, _ = env.reset(seed=seed)
        rewards, done = [], False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(controller(obs))
            rewards.append(reward)
            done = terminated or truncated
        return rewards

    a, b, c = episode(2), episode(2), episode(5)
    assert len(a) == 10 and a == b and a != c


def test_bad_arguments_are_refused(tmp_path: Path) -> None:
    tiny = TINY_SETTINGS
    with pytest.raises(ValueError, match="fields along y only"):
        gym.make(SURROGATE_ID, model=str(ROOT / "dipenv" / "data" / "surrogate_v1.npz"))
    shipped = gym.make(SURROGATE_ID).unwrapped  # the default: the shipped model, with the direction block
    assert shipped.model.direction and shipped.model.w[0].shape[1] == N_MLP_INPUTS + N_DIRECTION_INPUTS
    with pytest.raises(ValueError, match="take no eta_cap"):
        tiny_surrogate(random_direction_model(tiny), eta_cap=7.0)
    with pytest.raises(ValueError, match="n_particles=300"):
        gym.make(SURROGATE_ID, model=random_direction_model(tiny))
    env = tiny_surrogate(random_direction_model(tiny))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3, dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="polar, azimuth"):
        env.step(np.zeros(1, dtype=np.float32))
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"cap": 1.0})
    with pytest.raises(ValueError, match="target"):
        env.reset(options={"target": {"times": [0.0], "values": [-1.0]}})
    own = {"times": [0.0, 0.2], "values": [12.0, 20.0]}
    _, info = env.reset(seed=0, options={"target": own})
    assert info["target"] == own
    schedule = info["schedule"]
    assert interval_table(schedule_from_dict(schedule), 10, 0.02, 0.01).rate_mean.shape == (10,)


# -- the acceptance check (scripts/surrogate_check.py), tracking, on the tiny id -----------------------------
def hand_made_ppo_run(folder: Path, model_path: Path) -> Path:
    """An ``agents.train``-shaped PPO run on the tiny id (untrained: random weights) with ``history_length``
    1 and VecNormalize statistics far from the identity, so that a run played without its history or its
    statistics would act otherwise."""
    import yaml
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    folder.mkdir(parents=True)
    venv = VecNormalize(
        DummyVecEnv([lambda: tiny_surrogate(load_model(model_path), history_length=1)]), norm_reward=False
    )
    rng = np.random.default_rng(3)
    size = venv.observation_space.shape
    venv.obs_rms.mean = rng.normal(0.0, 1.0, size)
    venv.obs_rms.var = rng.uniform(0.01, 0.1, size)
    PPO("MlpPolicy", venv, n_steps=16, batch_size=16, seed=0, device="cpu").save(folder / "model.zip")
    venv.save(str(folder / "vecnormalize.pkl"))
    config = {
        "algo": "ppo",
        "env_id": TINY,
        "env_kwargs": {"history_length": 1},
        "hyperparams": {"normalize": True},
        "seed": 0,
    }
    (folder / "config.yml").write_text(yaml.safe_dump(config))
    venv.close()
    return folder


def test_surrogate_check_tracking_runs_resumes_and_compares_on_the_tiny_id(tmp_path: Path, capsys) -> None:
    """``scripts/surrogate_check.py --env dipenv/ViscosityTrackingTiny-v0``: both fidelities play the
    held-out episodes' schedules and targets (seeds outside every split); the rows' actions are the
    controllers' and the trained run's (its history and statistics); the numbers are the files'; a rerun
    replays nothing; other settings, bad rows, seeds and models are refused."""
    import pickle

    from stable_baselines3 import PPO

    from agents.tracking_controllers import AnglePIController
    from dipenv.actions import action_from_direction
    from dipenv.tracking import draw_target

    check = script("surrogate_check")
    model = tmp_path / "tiny_tracking.npz"
    random_direction_model({**TINY_SETTINGS, "env_id": TINY}).save(model)
    run = hand_made_ppo_run(tmp_path / "ppo" / "seed0", model)
    out = tmp_path / "check"
    rows = ["constant:yz:5", "map_feedforward", "angle_pi:3:1:1", f"ppo:{run}"]
    argv = ["--out", str(out), "--env", TINY, "--model", str(model), "--episodes", "2", "--realisations", "2",
            "--samples", "2", "--rows", *rows]  # fmt: skip
    summary = check.main(argv)
    assert summary is not None and list(summary["rows"]) == rows and summary["task"] == "tracking"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["task"] == "tracking" and manifest["target_seed"] == check.TARGET_SEED == 45_000_000

    simulator = gym.make(TINY, progress=False).unwrapped
    size = simulator.split_sizes["validation"]
    targets = []
    for j in range(2):  # the episodes' start states, schedules and targets, in both fidelities
        target = draw_target(
            np.random.default_rng(45_000_000 + j),
            simulator.episode_duration,
            simulator.target_range,
            simulator.target_hold_range,
            simulator.target_ramp_range,
        )
        targets.append(target)
        means = [target.mean(0.02 * k, 0.02 * (k + 1)) for k in range(10)]
        for label in ("constant_yz_5", "map_feedforward", "angle_pi_3_1_1", "ppo_seed0"):
            sur = json.loads((out / "surrogate" / label / f"ep{j:02d}.json").read_text())
            sims = [
                json.loads((out / "simulator" / label / f"ep{j:02d}_r{r}.json").read_text()) for r in (0, 1)
            ]
            for record in (sur, *sims):
                assert record["index"] == j % size and record["target_seed"] == 45_000_000 + j
                assert record["schedule_seed"] == check.SCHEDULE_SEED + j
                assert validate_target(record["target"]) == target
            for played in (*sur["samples"], *sims):
                assert not played["failed"] and len(played["eta_r"]) == 10
                np.testing.assert_allclose(played["target_eta_r"], means, rtol=1e-12)
                assert all(len(a) == 3 for a in played["action"])
    # the constant row: one field, Mn_ref 5 along (y + z)/sqrt2, in both fidelities
    mapping = simulator.mapping
    expected = np.array(
        [mapping.action_for(5.0), *action_from_direction((0.0, math.sqrt(0.5), math.sqrt(0.5)))],
        dtype=np.float32,
    )
    constant = json.loads((out / "simulator/constant_yz_5/ep01_r1.json").read_text())
    constant_sur = json.loads((out / "surrogate/constant_yz_5/ep01.json").read_text())["samples"][1]
    for played in (constant, constant_sur):
        assert np.array_equal(np.array(played["action"], dtype=np.float32), np.tile(expected, (10, 1)))
        np.testing.assert_allclose(played["field_direction"], [[0.0, math.sqrt(0.5), math.sqrt(0.5)]] * 10)
        np.testing.assert_allclose(played["mason_number"], 5.0)
    # the angle PI (kp 3, ki 1, Mn* 1) replayed by hand in the simulator: episode 1, realisation 1
    pi = AnglePIController(3.0, 1.0, 1.0).bind(simulator)
    obs, _ = simulator.reset(
        options={"split": "validation", "index": 1 % size, "realisation": 1, "target": targets[1]}
        | {"schedule": constant["schedule"]}
    )
    stored = json.loads((out / "simulator/angle_pi_3_1_1/ep01_r1.json").read_text())
    for k in range(10):
        action = pi(obs)
        obs, _, _, _, info = simulator.step(action)
        assert [float(a) for a in action] == stored["action"][k] and info["eta_r"] == stored["eta_r"][k]
    simulator.close()
    # the trained run: mean action on the observation (history 1) normalised by its statistics, by hand on
    # the surrogate's first sample of episode 0
    ppo = PPO.load(str(run / "model.zip"), device="cpu")
    with open(run / "vecnormalize.pkl", "rb") as handle:
        normaliser = pickle.load(handle)
    normaliser.training = False
    env = tiny_surrogate(load_model(model), history_length=1)
    spec = json.loads((out / "surrogate/ppo_seed0/ep00.json").read_text())
    obs, _ = env.reset(
        seed=check.SURROGATE_SEED,
        options={"split": "validation", "index": 0, "schedule": spec["schedule"], "target": spec["target"]},
    )
    for k in range(10):
        action = ppo.predict(normaliser.normalize_obs(obs), deterministic=True)[0]
        obs, _, _, _, info = env.step(action)
        assert [float(a) for a in action] == spec["samples"][0]["action"][k]
        assert info["eta_r"] == spec["samples"][0]["eta_r"][k]
    # the numbers are the files': mean |eta_r - target| per episode and realisation (or sample), averaged
    errors: dict[str, list[float]] = {"simulator": [], "surrogate": []}
    for row in rows:
        label = check.row_label(row)
        for fidelity in errors:
            per_episode = []
            for j in range(2):
                if fidelity == "simulator":
                    files = [out / "simulator" / label / f"ep{j:02d}_r{r}.json" for r in (0, 1)]
                    played = [json.loads(p.read_text()) for p in files]
                else:
                    played = json.loads((out / "surrogate" / label / f"ep{j:02d}.json").read_text())[
                        "samples"
                    ]
                per_episode.append(
                    np.mean([np.mean(np.abs(np.subtract(p["eta_r"], p["target_eta_r"]))) for p in played])
                )
            value = summary["rows"][row][f"{fidelity}_mean_abs_error"]
            assert value == pytest.approx(np.mean(per_episode), rel=1e-12)
            errors[fidelity].append(value)
    assert summary["error_order_simulator"] == [
        rows[k] for k in np.argsort(errors["simulator"], kind="stable")
    ]
    from scipy import stats

    tau = stats.kendalltau(errors["simulator"], errors["surrogate"]).statistic
    assert summary["error_kendall_tau"] == pytest.approx(tau)
    text = (out / "summary.md").read_text()
    assert "target seeds 45000000 + j" in text and "Order by mean abs(eta_r - target)" in text

    # resumes: nothing replayed, the same numbers; other settings in the folder refused
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("ep*.json")}
    assert check.main(argv) == summary
    assert {p: p.stat().st_mtime_ns for p in out.rglob("ep*.json")} == stamps
    capsys.readouterr()
    assert "other settings" in refused(capsys, check.main, [*argv, "--target-seed", "46000000"])
    # refusals before anything is played
    new = ["--out", str(tmp_path / "never"), "--env", TINY, "--model", str(model), "--episodes", "2"]
    for extra, words in (
        (["--target-seed", "4000005"], "validation targets' seeds"),
        (["--target-seed", str(check.SCHEDULE_SEED + 1)], "check's schedule seeds"),
        (["--target-seed", str(check.SURROGATE_SEED)], "surrogate's sample seeds"),
        (["--target-seed", "2001"], "test split's schedule seeds 2000..2015"),
        (["--schedule-seed", "6000000"], "fresh targets' seeds"),
        (["--rows", "pulse:2.5:0.5"], "unknown tracking row"),
        (["--rows", "constant:w:5"], "must be one of"),
        (["--rows", "angle_pi:3:1"], "three numbers"),
        (["--rows", f"ppo:{tmp_path}"], "config.yml"),
    ):
        assert words in refused(capsys, check.main, [*new, *extra]), extra
    thickening = ["--model", str(ROOT / "dipenv" / "data" / "surrogate_v1.npz")]
    assert "fields along y only" in refused(capsys, check.main, [*new[:-4], *thickening])
    assert "stress-only" in refused(
        capsys,
        check.main,
        ["--out", str(tmp_path / "never"), "--env", "dipenv/ViscosityTrackingStressOnly-v0"],
    )
    assert "--target-seed" in refused(
        capsys,
        check.main,
        ["--out", str(tmp_path / "never"), "--env", "dipenv/ThickeningControlTiny-v0", "--target-seed", "1"],
    )
    assert not (tmp_path / "never").exists()
