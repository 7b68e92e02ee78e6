"""The thickening-control surrogate (issue 43): its inputs, its fit, its environment and its check.

The independent check of the fit: episodes made by a known structural-kinetics system, integrated here by
the midpoint rule in time (not by the model's exact exponentials), with a known AR(1) noise; the fit must
recover its parameters, its deterministic viscosity and its noise within the tolerances stated in
:func:`test_lambda_fit_recovers_a_known_system`. A known linear-Gaussian system does the same for the
ensemble's training and its numpy export. The environment tests use the known system as the model, so
they need neither the simulator's data nor a fit.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from agents_helpers import load_script
from gymnasium.utils.env_checker import check_env

import dipenv
import sim
from dipenv.actions import FieldStrengthMapping
from dipenv.rewards import ThickeningPenaltyReward
from dipenv.schedules import draw_schedule
from dipenv.surrogate import (
    LambdaModel,
    ThickeningControlSurrogateEnv,
    ThickeningControlSurrogateStressOnlyEnv,
    default_model_path,
    load_model,
    surrogate_kwargs,
)
from dipenv.surrogate.features import N_DYNAMIC, interval_table, inverse_signed_log, signed_log
from dipenv.surrogate.models import (
    N_LAMBDA_FEATURES,
    initial_lambda_features,
    lambda_interval,
    lambda_interval_scalar,
    lambda_trajectories,
)
from sim.variants import pieces

ROOT = Path(__file__).resolve().parents[1]
V2 = "dipenv/ThickeningControl-v2"
TINY = "dipenv/ThickeningControlTiny-v0"


def script(name: str) -> ModuleType:
    return load_script(name, cached=True)


# -- the known system ----------------------------------------------------------------------------------------
THETA = np.array([0.0, 2.0, 0.5, 2.5, 0.4, 1.5, 0.6, 1.2, 0.4])
"""log10 Mn_F, p_F, log10 Mn_T, p_T, gamma_F on/off, gamma_T on/off, q (dipenv.surrogate.models)."""
READOUT = np.random.default_rng(123).normal(0.0, 0.1, (N_LAMBDA_FEATURES, N_DYNAMIC))
READOUT[:, 0] = [6.5, 1.0, 3.5, 0.8, 0.3, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0]  # eta_r = 10.0 off, ~7.5 at best
READOUT[0, 1:] += [-0.5, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 3.0, 2.5, 3.0]
RHO_A, RHO_B = np.full(N_DYNAMIC, 0.2), np.full(N_DYNAMIC, 0.5)
SD0 = np.full(N_DYNAMIC, 0.02)
SD0[0] = 0.3
SD1 = np.zeros(N_DYNAMIC)
SD1[0] = 0.4
"""Innovation variance ``SD0^2 + SD1^2 x mean lambda_F`` (eta_r: sd 0.3 off, 0.5 in a full field)."""


def truth_model(settings: dict[str, Any]) -> LambdaModel:
    """The known system as a :class:`LambdaModel` (for the env tests)."""
    frames = np.stack([initial_lambda_features(1)[0] @ READOUT] * 4)
    frames[:, 0] = signed_log(frames[:, 0])
    low = np.full(N_DYNAMIC, -100.0)
    low[0] = 0.0
    arrays = {
        "start_frames": frames,
        "start_indices": np.arange(4),
        "low": low,
        "high": np.full(N_DYNAMIC, 100.0),
        "theta": THETA,
        "readout": READOUT,
        "rho_a": RHO_A,
        "rho_b": RHO_B,
        "var_coef": np.stack([SD0**2, SD1**2, np.zeros(N_DYNAMIC)]),
        "var_floor": np.full(N_DYNAMIC, 1e-6),
        "chol": np.eye(N_DYNAMIC),
    }
    return LambdaModel(arrays, {"settings": settings})


V2_SETTINGS = {"control_interval": 0.25, "n_particles": 300, "volume_fraction": 0.45}
TINY_SETTINGS = {"control_interval": 0.02, "n_particles": 32, "volume_fraction": 0.45}


def known_episode(
    seed: int, steps: int = 48, interval: float = 0.25, max_piece: float = 0.05
) -> dict[str, Any]:
    """One episode of the known system under the data generator's behaviour policy of ``seed``,
    integrated by the midpoint rule (40 steps per piece of the schedule's staircase)."""
    data = script("surrogate_data")
    rng = np.random.default_rng(seed + 10_000)
    schedule = draw_schedule(np.random.default_rng(seed), steps * interval)
    behaviour = data.Behaviour(data.BEHAVIOURS[seed % 4], np.random.default_rng(seed))
    mapping = FieldStrengthMapping(0.1)
    log_mf, p_f, log_mt, p_t, g_f_on, g_f_off, g_t_on, g_t_off, q = THETA
    lam_f, lam_t = 0.0, 1.0
    residual = rng.normal(size=N_DYNAMIC) * SD0
    first = initial_lambda_features(1)[0] @ READOUT + residual
    rows = [np.concatenate([[signed_log(first[0])], first[1:], [0.0, -1.0, math.log10(schedule(0.0))]])]
    masons, etas, actions, rates, ends, phis, strains = [], [], [], [], [], [], []
    for k in range(steps):
        action = behaviour(10.0 ** rows[-1][14])
        mason = mapping.mason_number(action)
        on = math.isfinite(mason)
        s_f = s_t = s_fe = s_e = strain = total = 0.0
        parts = pieces(schedule, k * interval, (k + 1) * interval, max_piece)
        for a, b in parts:
            rate, dt = schedule.mean(a, b), b - a
            if on:
                log_mn = math.log10(mason * rate)
                ss_f = 1.0 / (1.0 + 10.0 ** (p_f * (log_mn - log_mf)))
                ss_t = 1.0 / (1.0 + 10.0 ** (p_t * (log_mt - log_mn)))
                field, g_f, g_t = 10.0 ** (-q * log_mn), g_f_on, g_t_on
            else:
                ss_f, ss_t, field, g_f, g_t = 0.0, 1.0, 0.0, g_f_off, g_t_off
            h = dt / 40
            for _ in range(40):
                mid_f = lam_f + 0.5 * h * rate * (ss_f - lam_f) / g_f
                mid_t = lam_t + 0.5 * h * rate * (ss_t - lam_t) / g_t
                s_f, s_t, s_fe, s_e = (
                    s_f + h * mid_f,
                    s_t + h * mid_t,
                    s_fe + h * mid_f * field,
                    s_e + h * field,
                )
                lam_f += h * rate * (ss_f - mid_f) / g_f
                lam_t += h * rate * (ss_t - mid_t) / g_t
            strain, total = strain + rate * dt, total + dt
        log_rate = math.log10(strain / total)
        m_f, m_t = s_f / total, s_t / total
        phi = np.array([1, m_f, m_t, s_fe / total, s_e / total, lam_f, lam_t, float(on), log_rate,
                        m_f * log_rate, m_t * log_rate])  # fmt: skip
        residual = np.exp(-(RHO_A + RHO_B * strain)) * residual + np.sqrt(SD0**2 + SD1**2 * m_f) * rng.normal(
            size=N_DYNAMIC
        )
        out = phi @ READOUT + residual
        end = schedule.mean(*parts[-1])
        fraction = min(1.0, 0.1 / mason) if on else 0.0
        rows.append(
            np.concatenate(
                [[signed_log(out[0])], out[1:], [fraction, mapping.coordinate(mason), math.log10(end)]]
            )
        )
        masons.append(mason)
        etas.append(out[0])
        actions.append(action)
        rates.append(strain / total)
        ends.append(end)
        phis.append(phi)
        strains.append(strain)
    mason_a, eta_a = np.array(masons), np.array(etas)
    energy = np.array([0.0 if math.isinf(m) else 1.0 / m for m in masons])
    return {
        "obs": np.array(rows),
        "action": np.array(actions),
        "reward": -(np.maximum(0.0, eta_a - 7.7) + 0.3 * energy),
        "schedule_times": np.array(schedule.times),
        "schedule_rates": np.array(schedule.values),
        "behaviour": np.array(data.BEHAVIOURS[seed % 4]),
        "start_index": np.array(seed % 64),
        "library_key": np.array("known-system"),
        "eta_r": eta_a,
        "n1": np.zeros(steps),
        "n2": np.zeros(steps),
        "shear_stress": eta_a * np.array(rates),
        "shear_rate": np.array(rates),
        "shear_rate_end": np.array(ends),
        "instantaneous_mason_number": mason_a * np.array(rates),
        "mason_number": mason_a,
        "field_energy": energy,
        "time": interval * np.arange(1, steps + 1),
        "_phi": np.array(phis),
        "_strain": np.array(strains),
    }


def write_data(folder: Path, episodes: dict[int, dict[str, Any]], env_id: str = V2) -> Path:
    (folder / "episodes").mkdir(parents=True, exist_ok=True)
    (folder / "manifest.json").write_text(json.dumps({"params": {"env_id": env_id, "data_version": 1}}))
    for seed, episode in episodes.items():
        np.savez(
            folder / "episodes" / f"ep{seed:05d}.npz", **{k: v for k, v in episode.items() if k[0] != "_"}
        )
    return folder


@pytest.fixture(scope="module")
def known_data(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[int, dict[str, Any]]]:
    episodes = {seed: known_episode(seed) for seed in range(50)}
    return write_data(tmp_path_factory.mktemp("known"), episodes), episodes


@pytest.fixture(scope="module")
def fitted_known(
    known_data: tuple[Path, dict[int, dict[str, Any]]], tmp_path_factory: pytest.TempPathFactory
):
    folder, _ = known_data
    out = tmp_path_factory.mktemp("fit") / "model.npz"
    argv = [str(folder), "--out", str(out), "--routes", "lambda", "--starts", "1", "--samples", "8"]
    summary = script("fit_surrogate").main(argv)
    return out, summary


# -- inputs ----------------------------------------------------------------------------------------------
def test_interval_table_runs_the_pieces_sim_follow_runs() -> None:
    """Each interval's pieces and rates are :func:`sim.variants.pieces` at the schedule's means, bit for bit;
    the mean rate is their time average, the end rate the last piece's."""
    for seed in range(40):
        schedule = draw_schedule(np.random.default_rng(seed), 12.0)
        table = interval_table(schedule, 48, 0.25, 0.05)
        assert table.rate_initial == schedule(0.0)
        for k in range(48):
            expected = [
                (schedule.mean(a, b), b - a) for a, b in pieces(schedule, 0.25 * k, 0.25 * (k + 1), 0.05)
            ]
            assert list(table.parts[k]) == expected
            assert table.rate_end[k] == expected[-1][0] and table.rate_start[k] == expected[0][0]
            assert table.rate_mean[k] == pytest.approx(schedule.mean(0.25 * k, 0.25 * (k + 1)), rel=1e-12)


def test_the_scalar_and_batched_structure_updates_agree() -> None:
    rng = np.random.default_rng(0)
    for seed in range(5):
        table = interval_table(draw_schedule(np.random.default_rng(seed), 12.0), 48, 0.25, 0.05)
        for k in range(0, 48, 7):
            mason = float(rng.choice([math.inf, 0.1, 0.5, 3.0]))
            lam = rng.uniform(0, 1, 2)
            f_b, t_b, phi_b, strain_b = lambda_interval(
                THETA,
                lam[:1],
                lam[1:],
                np.array([mason]),
                table.piece_rate[k : k + 1],
                table.piece_time[k : k + 1],
            )
            phi = np.zeros(N_LAMBDA_FEATURES)
            f_s, t_s, strain_s = lambda_interval_scalar(
                tuple(THETA), lam[0], lam[1], mason, table.parts[k], phi
            )
            assert (f_s, t_s, strain_s) == pytest.approx((f_b[0], t_b[0], strain_b[0]), rel=1e-12, abs=1e-14)
            np.testing.assert_allclose(phi, phi_b[0], rtol=1e-12, atol=1e-14)


# -- the fits recover known systems -----------------------------------------------------------------------
def test_lambda_fit_recovers_a_known_system(known_data, fitted_known) -> None:
    """Fit on the 40 episodes of seeds ``s % 5 != 4`` of the known system. Tolerances: each Mason-number
    midpoint within 0.1 decade, each build/loss strain within 20%, the steepnesses within 35% and ``q``
    within 25%; the fitted deterministic eta_r within RMS 0.1 of the truth's over the 50 episodes (within
    0.25 on each; the noise of eta_r: sd 0.3-0.5); the innovation sd of eta_r within 10% (RMS relative)
    and its AR(1) coefficient within 0.08 at strains 0.25 and 1."""
    _, episodes = known_data
    path, summary = fitted_known
    model = load_model(path)
    assert isinstance(model, LambdaModel)
    theta = model.theta
    assert abs(theta[0] - THETA[0]) < 0.1 and abs(theta[2] - THETA[2]) < 0.1, theta
    np.testing.assert_allclose(theta[4:8], THETA[4:8], rtol=0.2)
    np.testing.assert_allclose(theta[[1, 3]], THETA[[1, 3]], rtol=0.35)
    assert theta[8] == pytest.approx(THETA[8], rel=0.25)
    phis = np.stack([e["_phi"] for e in episodes.values()])
    true_eta = phis @ READOUT[:, 0]
    masons = np.stack([e["mason_number"] for e in episodes.values()])
    schedules = [
        sim.PiecewiseLinear(tuple(e["schedule_times"]), tuple(e["schedule_rates"])) for e in episodes.values()
    ]
    tables = [interval_table(schedule, 48, 0.25, 0.05) for schedule in schedules]
    fitted_phi, strains = lambda_trajectories(theta, masons, tables)
    fitted_eta = fitted_phi @ model.readout[:, 0]
    per_episode = np.sqrt(np.mean((fitted_eta - true_eta) ** 2, axis=1))
    assert np.sqrt(np.mean(per_episode**2)) < 0.1 and per_episode.max() < 0.25, per_episode
    true_sd = np.sqrt(SD0[0] ** 2 + SD1[0] ** 2 * phis[..., 1])
    fitted_sd = model.sigma(fitted_phi)[..., 0]
    assert np.sqrt(np.mean((fitted_sd / true_sd - 1) ** 2)) < 0.1
    for strain in (0.25, 1.0):
        assert model.rho(np.array(strain))[0] == pytest.approx(
            math.exp(-(RHO_A[0] + RHO_B[0] * strain)), abs=0.08
        )
    # provenance and the held-out metrics travel with the weights
    assert model.metadata["episodes"] == 50 and model.metadata["fit_episodes"] == 40
    assert model.metadata["held_out_episodes"] == list(range(4, 50, 5))
    assert "fit_surrogate.py" in model.metadata["command"] and model.metadata["seed"] == 0
    # the data's place: absolute outside the repository (here a temporary folder), relative inside it, so
    # that a fit made in a worktree or another clone records the same path
    assert model.metadata["data"] == str(known_data[0].resolve())
    fit = script("fit_surrogate")
    assert fit.data_path(ROOT / "results" / "surrogate_data") == "results/surrogate_data"
    metrics = json.loads(path.with_suffix(".metrics.json").read_text())
    assert metrics["kept"] == "lambda" and metrics["routes"]["lambda"]["held_out"]["episodes"] == 10
    held = metrics["routes"]["lambda"]["held_out"]
    assert held["one_step_rmse_eta"] < held["persistence_rmse_eta"]
    assert 0.67 < held["spread_ratio"] < 1.5, held


def test_ensemble_fit_recovers_a_linear_gaussian_system(tmp_path: Path, known_data) -> None:
    """Frames whose dynamic part changes each interval by ``c + d x on + e x log10(rate) + sigma xi``
    (a linear-Gaussian system): the trained ensemble's mean change is within 0.3 sigma (RMS) of the truth
    for every output (0.2 on average; 1440 intervals of 30 episodes) and its predicted sd within 20% of
    sigma, through the numpy export."""
    _, base = known_data
    rng = np.random.default_rng(7)
    c, d, e = rng.normal(0, 0.05, N_DYNAMIC), rng.normal(0, 0.1, N_DYNAMIC), rng.normal(0, 0.05, N_DYNAMIC)
    sigma = np.linspace(0.02, 0.1, N_DYNAMIC)
    episodes = {}
    for seed in range(30):
        episode = dict(base[seed])
        obs = episode["obs"].copy()
        on = np.isfinite(episode["mason_number"]).astype(float)
        for k in range(48):
            change = (
                c + d * on[k] + e * np.log10(episode["shear_rate"][k]) + sigma * rng.normal(size=N_DYNAMIC)
            )
            obs[k + 1, :N_DYNAMIC] = obs[k, :N_DYNAMIC] + change
        obs[:, 0] = np.clip(obs[:, 0], 0.5, 1.5)  # keep slog eta in a physical range
        episode["obs"] = obs
        episode["eta_r"] = inverse_signed_log(obs[1:, 0])
        episodes[seed] = episode
    folder = write_data(tmp_path / "linear", episodes)
    fit = script("fit_surrogate")
    settings = script("fit_surrogate").data_settings(folder)
    from dipenv.surrogate.data import load_episodes

    loaded = load_episodes(folder, settings["control_interval"], settings["max_piece"])
    arrays, info = fit.fit_ensemble(loaded, seed=0, members=2, hidden=32, max_epochs=150, patience=15)
    common = fit.common_arrays(loaded, loaded)
    common["low"], common["high"] = np.full(N_DYNAMIC, -1e3), np.full(N_DYNAMIC, 1e3)
    from dipenv.surrogate import EnsembleModel

    model = EnsembleModel({**common, **arrays}, {"settings": settings})
    x_episode = loaded[0]
    dyn = np.stack([ep.dynamic for ep in loaded[:10]])
    masons = np.stack([ep.mason for ep in loaded[:10]])
    pred = model.one_step(dyn, masons, [ep.table for ep in loaded[:10]]) - dyn[:, :-1]
    truth = (
        c
        + d * np.isfinite(masons)[..., None]
        + e * np.log10(np.stack([ep.shear_rate for ep in loaded[:10]]))[..., None]
    )
    ok = (dyn[:, 1:, 0] > 0.5) & (dyn[:, 1:, 0] < 1.5)  # eta_r's clip breaks linearity at its bounds
    rel = np.sqrt(np.mean(((pred - truth)[ok] / sigma) ** 2, axis=0))
    assert rel[1:].max() < 0.3 and rel[1:].mean() < 0.2, rel
    inputs = script("fit_surrogate").transitions([x_episode])[0]
    _, var = model._forward(inputs, 0)
    predicted_sd = np.sqrt(var).mean(axis=0) * model.y_std
    np.testing.assert_allclose(predicted_sd[1:], sigma[1:], rtol=0.2)
    assert info["epochs"] <= 150


# -- the environment ---------------------------------------------------------------------------------------
def surrogate(
    settings: dict[str, Any], env_id: str = V2, stress_only: bool = False, **kwargs: Any
) -> gym.Env:
    cls = ThickeningControlSurrogateStressOnlyEnv if stress_only else ThickeningControlSurrogateEnv
    return cls(**surrogate_kwargs(env_id, model=truth_model(settings), **kwargs))


@pytest.mark.parametrize("stress_only", [False, True])
def test_spaces_are_the_simulator_envs(stress_only: bool) -> None:
    sim_id = "dipenv/ThickeningControlStressOnly-v2" if stress_only else V2
    simulator = gym.make(sim_id, progress=False).unwrapped
    env = surrogate(V2_SETTINGS, sim_id, stress_only, history_length=2)
    simulator_h = gym.make(sim_id, progress=False, history_length=2).unwrapped
    assert env.observation_space == simulator_h.observation_space
    assert env.action_space == simulator.action_space
    assert env.observation_labels == simulator_h.observation_labels
    assert env.reward_function == simulator.reward_function  # ThickeningPenaltyReward(7.7, 0.3, 50)
    assert env.reward_function.energy_weight == 0.3 and env.reward_function.target_viscosity == 7.7
    assert env.mapping == simulator.mapping


def test_registered_ids_have_v2s_settings() -> None:
    for env_id, cls in zip(
        dipenv.SURROGATE_IDS,
        (ThickeningControlSurrogateEnv, ThickeningControlSurrogateStressOnlyEnv),
        strict=True,
    ):
        spec = gym.spec(env_id)
        assert spec.kwargs == gym.spec(V2).kwargs and spec.entry_point.endswith(cls.__name__)
        assert spec.max_episode_steps is None


def test_gymnasium_env_checkers_pass(tmp_path: Path) -> None:
    path = tmp_path / "truth.npz"
    truth_model(V2_SETTINGS).save(path)
    for stress_only in (False, True):
        check_env(surrogate(V2_SETTINGS, stress_only=stress_only), skip_render_check=True)
    for env_id in dipenv.SURROGATE_IDS:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the passive checker warns; make any warning fail
            env = gym.make(env_id, model=str(path))
            env.reset(seed=0)
            for _ in range(48):
                _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            assert truncated and not terminated
            env.close()


def test_same_seed_same_episode() -> None:
    def episode(seed: int) -> tuple[list[np.ndarray], list[float]]:
        env = surrogate(V2_SETTINGS)
        obs, _ = env.reset(seed=seed)
        observations, rewards = [obs], []
        for u in np.linspace(-1, 1, 48):
            obs, reward, *_ = env.step(np.array([u], dtype=np.float32))
            observations.append(obs)
            rewards.append(reward)
        return observations, rewards

    a, b, c = episode(3), episode(3), episode(4)
    assert all(np.array_equal(x, y) for x, y in zip(a[0], b[0], strict=True)) and a[1] == b[1]
    assert a[1] != c[1]


def test_reward_is_the_reward_objects_on_the_models_eta_and_the_fields_energy() -> None:
    env = surrogate(V2_SETTINGS)
    reward_object = ThickeningPenaltyReward(7.7, 0.3, 50.0)
    env.reset(seed=1)
    total = 0.0
    for u in np.random.default_rng(1).uniform(-1, 1, 48):
        obs, reward, _, truncated, info = env.step(np.array([u], dtype=np.float32))
        mason = env.mapping.mason_number(float(np.float32(u)))
        energy = 0.0 if math.isinf(mason) else 1.0 / mason
        assert info["field_energy"] == energy and info["mason_number"] == mason
        assert reward == reward_object(info["eta_r"], energy)[0] == info["reward"]
        assert float(obs[0]) == pytest.approx(signed_log(info["eta_r"]), abs=1e-6)
        assert info["reward_viscosity"] + info["reward_energy"] == pytest.approx(reward)
        total += reward
    assert truncated and math.isfinite(total)


def test_stress_only_frame_holds_the_shear_stress() -> None:
    env = surrogate(V2_SETTINGS, "dipenv/ThickeningControlStressOnly-v2", stress_only=True)
    obs, info = env.reset(seed=2)
    assert obs.shape == (14,) and float(obs[0]) == pytest.approx(signed_log(info["eta_r"]), abs=1e-6)
    obs, _, _, _, info = env.step(np.array([0.5], dtype=np.float32))
    assert float(obs[0]) == pytest.approx(signed_log(info["eta_r"] * info["shear_rate"]), abs=1e-6)
    assert info["shear_stress"] == info["eta_r"] * info["shear_rate"]


def test_schedules_and_start_indices_are_the_simulator_envs() -> None:
    """Training resets draw the start index, then the schedule, from ``np_random`` as the simulator env
    does (the same seed gives both); the fixed splits' schedules are the simulator env's."""
    simulator = gym.make(TINY, progress=False)
    env = surrogate(TINY_SETTINGS, TINY)
    for seed in (0, 5):
        obs_s, info_s = simulator.reset(seed=seed)
        obs, info = env.reset(seed=seed)
        assert info["index"] == info_s["index"] and info["schedule"] == info_s["schedule"]
        assert obs[14] == obs_s[14]  # log10 of the first rate
        for _ in range(3):
            action = np.array([0.3], dtype=np.float32)
            obs_s, _, _, _, info_s = simulator.step(action)
            obs, _, _, _, info = env.step(action)
            assert obs[12:] == pytest.approx(obs_s[12:])  # field entries and the observed rate
            assert info["shear_rate"] == pytest.approx(
                info_s["shear_rate"], rel=0.2
            )  # the simulator overshoots
    simulator.close()
    v2 = gym.make(V2, progress=False).unwrapped
    env = surrogate(V2_SETTINGS)
    for split, count in (("validation", 8), ("test", 16)):
        for index in range(count):
            assert env.fixed_schedule(split, index) == v2.fixed_schedule(split, index)
        _, info = env.reset(options={"split": split, "index": 3})
        assert info["schedule"] == {"times": list(v2.fixed_schedule(split, 3).times),
                                    "rates": list(v2.fixed_schedule(split, 3).values)}  # fmt: skip
    own = {"times": [0.0, 12.0], "rates": [2.0, 2.0]}
    _, info = env.reset(options={"schedule": own})
    assert info["schedule"] == own


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="control_interval"):
        surrogate(V2_SETTINGS, control_interval=0.1)
    with pytest.raises(ValueError, match="n_particles"):
        surrogate(V2_SETTINGS, n_particles=64)
    with pytest.raises(TypeError, match="bogus"):
        surrogate(V2_SETTINGS, bogus=1)
    env = surrogate(V2_SETTINGS, simulation_overrides={"max_displacement": 0.008}, progress=False)
    assert env.settings()["ignored"] == ["progress", "simulation_overrides"]
    with pytest.raises(RuntimeError):
        env.step(np.zeros(1, dtype=np.float32))
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"bogus": 1})


def test_the_shipped_model_drives_the_registered_ids() -> None:
    path = default_model_path()
    model = load_model(path)
    meta = model.metadata
    for key in ("data", "episodes", "command", "seed", "held_out_episodes", "metrics", "settings"):
        assert key in meta, key
    assert meta["settings"]["env_id"] == V2 and meta["settings"]["n_particles"] == 300
    assert path.stat().st_size < 1_000_000
    for env_id in dipenv.SURROGATE_IDS:
        env = gym.make(env_id)
        env.reset(seed=0)
        etas = []
        for u in np.random.default_rng(0).uniform(-1, 1, 48):
            _, reward, _, truncated, info = env.step(np.array([u], dtype=np.float32))
            etas.append(info["eta_r"])
            assert math.isfinite(reward)
        assert truncated and 3.0 < np.mean(etas) < 15.0


# -- the acceptance check, on the tiny id --------------------------------------------------------------------
def test_surrogate_check_runs_resumes_and_compares_on_the_tiny_id(tmp_path: Path) -> None:
    check = script("surrogate_check")
    model = tmp_path / "tiny.npz"
    truth_model({**TINY_SETTINGS, "env_id": TINY}).save(model)
    out = tmp_path / "check"
    argv = ["--out", str(out), "--env", TINY, "--model", str(model), "--episodes", "1", "--realisations", "2",
            "--samples", "3", "--rows", "constant:0.5", "pulse:2.5:0.5"]  # fmt: skip
    summary = check.main(argv)
    assert summary is not None and set(summary["rows"]) == {"constant:0.5", "pulse:2.5:0.5"}
    # the model is recorded repo-relative when inside the repository (any clone reads the same), else absolute
    assert summary["model"] == str(model.resolve())
    assert check.recorded_path(check.ROOT / "dipenv" / "data" / "x.npz") == "dipenv/data/x.npz"
    row = summary["rows"]["constant:0.5"]
    assert row["realisations"] == 2 and row["samples"] == 3 and row["episodes"] == [0]
    files = sorted(p.relative_to(out) for p in out.rglob("*.json"))
    assert (
        Path("simulator/constant_0.5/ep00_r1.json") in files
        and Path("surrogate/pulse_2.5_0.5/ep00.json") in files
    )
    record = json.loads((out / "simulator/constant_0.5/ep00_r0.json").read_text())
    assert (
        record["index"] == 0 and record["schedule_seed"] == check.SCHEDULE_SEED and len(record["eta_r"]) == 10
    )
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("ep*.json")}
    again = check.main(argv)  # resumes: nothing replayed, the same numbers
    assert {p: p.stat().st_mtime_ns for p in out.rglob("ep*.json")} == stamps and again == summary
    with pytest.raises(SystemExit):
        check.main([*argv[:-6], "--samples", "4", "--rows", "constant:0.5"])  # other settings, same folder
    with pytest.raises(ValueError, match="overlap"):
        check.check_seeds(2000, 4)


@pytest.mark.parametrize("normalize", [True, False])
def test_surrogate_check_plays_a_thickening_run_as_the_agents_do(tmp_path: Path, normalize: bool) -> None:
    """Was: the check's ``ppo:RUN`` row (thickening) loaded the run by its own rule, normalising whenever
    ``vecnormalize.pkl`` existed, so a run trained without ``normalize`` but holding the file was played on
    rescaled observations. Now it is :func:`agents.rollout.trained_policy` with the statistics rule of
    ``agents.evaluate``: the run's config decides. The statistics here are far from the identity, so the
    two readings act differently."""
    import yaml
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    check = script("surrogate_check")
    env = surrogate(TINY_SETTINGS, TINY)
    venv = VecNormalize(DummyVecEnv([lambda: surrogate(TINY_SETTINGS, TINY)]), norm_reward=False)
    rng = np.random.default_rng(5)
    venv.obs_rms.mean = rng.normal(0.0, 1.0, venv.observation_space.shape)
    venv.obs_rms.var = rng.uniform(0.01, 0.1, venv.observation_space.shape)
    run = tmp_path / "seed0"
    run.mkdir()
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, seed=0, device="cpu")
    model.save(run / "model.zip")
    venv.save(str(run / "vecnormalize.pkl"))
    config = {
        "algo": "ppo",
        "env_id": TINY,
        "env_kwargs": {},
        "hyperparams": {"normalize": normalize},
        "seed": 0,
    }
    (run / "config.yml").write_text(yaml.safe_dump(config))
    policy, _ = check.make_policy(f"ppo:{run}", env)
    obs, _ = env.reset(seed=0)
    venv.training = False
    seen = venv.normalize_obs(obs) if normalize else obs
    expected = model.predict(seen, deterministic=True)[0]
    other = model.predict(obs if normalize else venv.normalize_obs(obs), deterministic=True)[0]
    assert not np.allclose(expected, other)  # the test can tell the readings apart
    got = policy(obs)
    assert got.dtype == np.float32 and np.allclose(got, expected, atol=1e-6)
