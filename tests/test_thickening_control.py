"""``dipenv/ThickeningControl*``: Gymnasium contract, determinism, the schedule as the simulator sees it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import dipenv  # noqa: F401  (registers the ids)
import sim
from dipenv.envs.thickening_control import ThickeningControlEnv

SCHEDULE = {"times": [0.0, 0.05, 0.1, 0.12, 0.2], "rates": [0.5, 0.5, 3.0, 2.0, 2.0]}
"""Hold 0.5, ramp to 3, ramp down to 2, hold: ten 0.02 intervals of the tiny env."""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("library")
    env = gym.make("dipenv/ThickeningControlTiny-v0", library_root=root, progress=False)
    yield env
    env.close()


def test_checkers(tiny) -> None:
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    gym_check(tiny.unwrapped, skip_render_check=True)
    sb3_check(tiny.unwrapped, warn=False)


def test_constant_action_equals_a_plain_simulation_bit_for_bit(tiny) -> None:
    env: ThickeningControlEnv = tiny.unwrapped
    tiny.reset(seed=0, options={"split": "test", "index": 0, "schedule": SCHEDULE})
    start = env.library().load("test", 0, progress=False)
    action = np.array([0.3], dtype=np.float32)
    mason_ref = env.mapping.mason_number(float(action[0]))  # the float32 action, as the env reads it
    infos = []
    for _ in range(env.episode_steps):
        *_, info = tiny.step(action)
        infos.append(info)
    plain = sim.Simulation(env._simulation.config, start.state, keep_records=False)
    plain.set_field(mason_ref, (0.0, 1.0, 0.0))
    schedule = sim.PiecewiseLinear(tuple(SCHEDULE["times"]), tuple(SCHEDULE["rates"]))
    origin = plain.state.time
    for k in range(env.episode_steps):
        end = origin + k * env.control_interval + env.control_interval  # the env's arithmetic
        sim.follow(plain, end, schedule, env.max_piece, origin=origin)
    np.testing.assert_array_equal(env._simulation.state.positions, plain.state.positions)
    assert env._simulation.state.strain == plain.state.strain
    # the instantaneous Mason number is the rate times Mn_ref; rates follow the schedule
    for info in infos:
        assert info["mason_number"] == mason_ref
        assert info["instantaneous_mason_number"] == pytest.approx(info["shear_rate"] * mason_ref, rel=1e-12)
    assert infos[0]["shear_rate"] == pytest.approx(0.5)
    assert infos[-1]["shear_rate"] == pytest.approx(2.0)
    assert max(i["shear_rate"] for i in infos) > 2.0
    # eta_r is the shear stress over the rate (both interval means; exact on a hold)
    assert infos[-1]["eta_r"] == pytest.approx(infos[-1]["shear_stress"] / 2.0, rel=1e-12)


def test_same_seed_same_episode(tiny) -> None:
    def episode(seed: int) -> tuple[list[float], list[float]]:
        tiny.reset(seed=seed)
        rewards, rates = [], []
        for _ in range(3):
            _, reward, _, _, info = tiny.step(np.array([0.0], dtype=np.float32))
            rewards.append(reward)
            rates.append(info["shear_rate"])
        return rewards, rates

    assert episode(3) == episode(3)
    # training schedules are drawn with the env's generator: another seed, another schedule
    assert tiny.reset(seed=3)[1]["schedule"] != tiny.reset(seed=4)[1]["schedule"]


def test_reward_pays_only_above_the_cap(tiny) -> None:
    env = tiny.unwrapped
    reward = env.reward_function
    assert reward(reward.target_viscosity - 1.0, 0.0)[0] == 0.0
    assert reward(reward.target_viscosity + 2.0, 0.5)[0] == pytest.approx(-2.5)


def test_validation_and_test_splits_use_fixed_schedules(tiny) -> None:
    _, first = tiny.reset(options={"split": "test", "index": 1})
    _, again = tiny.reset(seed=99, options={"split": "test", "index": 1})
    assert first["schedule"] == again["schedule"]
    assert first["shear_rate"] == first["schedule"]["rates"][0]


def test_stress_only_observes_neither_rate_nor_viscosity(tmp_path) -> None:
    env = gym.make(
        "dipenv/ThickeningControlStressOnly-v0",
        **{k: v for k, v in dipenv.THICKENING_TINY_KWARGS.items()},
        library_root=tmp_path,
        progress=False,
    ).unwrapped
    assert env.observation_labels[0] == "slog_shear_stress"
    assert not any("rate" in label or "eta" in label for label in env.observation_labels)
    full = ThickeningControlEnv(**dipenv.THICKENING_TINY_KWARGS, library_root=tmp_path, progress=False)
    assert full.observation_labels[-1] == "log10_shear_rate"
    env.close()
    full.close()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"rate_range": (0.0, 5.0)}, "rate_range"),
        ({"max_piece": 0.0}, "max_piece"),
        ({"actuator_time_constant": 0.1}, "actuator_time_constant"),
        ({"target_viscosity": 6.0}, "eta_cap"),
    ],
)
def test_bad_arguments_are_refused_at_make(tmp_path, kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        ThickeningControlEnv(
            **{**dipenv.THICKENING_TINY_KWARGS, **kwargs}, library_root=tmp_path, progress=False
        )


def test_bad_schedule_option_is_refused(tiny) -> None:
    with pytest.raises(ValueError, match=r"options\['schedule'\]: rates\[1\] .* needs shear"):
        tiny.reset(options={"schedule": {"times": [0.0, 1.0], "rates": [1.0, 0.0]}})
    assert math.isfinite(tiny.reset()[1]["shear_rate"])


def test_viscosity_contributions_sum_to_eta_r(tiny) -> None:
    """``info["eta_r_contributions"]`` splits eta_r by stress contribution: the parts sum to eta_r (the
    same time average of the same stresses, summed in another order: 1e-12), the solvent's part is
    exactly the solvent viscosity (``Sigma_xy = eta gammadot``: 1 at any rate), and the field's parts
    (ICEP, DEP) vanish without a field and not with one."""
    field_parts = ("icep_isolated", "icep_pair", "dep_virial", "dep_stresslet")
    tiny.reset(seed=0, options={"split": "test", "index": 0, "schedule": SCHEDULE})
    for action, field_on in ((-1.0, False), (1.0, True)):
        *_, info = tiny.step(np.array([action], dtype=np.float32))
        parts = info["eta_r_contributions"]
        assert tuple(parts) == sim.STRESS_CONTRIBUTIONS
        assert sum(parts.values()) == pytest.approx(info["eta_r"], rel=1e-12)
        assert parts["solvent"] == pytest.approx(1.0, rel=1e-12)
        assert parts["lubrication"] > 0.0  # the dense suspension's dissipation is mostly lubrication
        field = [parts[name] for name in field_parts]
        if field_on:
            assert any(abs(x) > 1e-6 for x in field)
        else:
            assert field == [0.0] * len(field_parts)
