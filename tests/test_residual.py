"""Residual policies (agents.residual): a correction added to a tracking controller's action (issue 44)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from test_tracking_surrogate import TINY_SETTINGS, random_direction_model, tiny_surrogate

from agents.residual import ResidualControllerWrapper, check_residual
from agents.rollout import make_env
from agents.tracking_controllers import make_tracking_controller

TINY = "dipenv/ViscosityTrackingTiny-v0"
PI = {"controller": "angle_pi", "params": {"kp": 3.0, "ki": 1.0}, "scale": 0.5}


def trace(env, act) -> list[tuple[float, list[float]]]:
    """(eta_r, the env's field direction) per step of validation episode 1, seed 0, ``act(obs)``."""
    obs, _ = env.reset(seed=0, options={"split": "validation", "index": 1})
    out, done = [], False
    while not done:
        obs, _, terminated, truncated, info = env.step(act(obs))
        out.append((float(info["eta_r"]), [float(x) for x in info["field_direction"]]))
        done = terminated or truncated
    return out


def test_a_zero_correction_is_the_controller_alone() -> None:
    """With the agent's action 0 the wrapped env plays the angle PI's episode, step for step (the PI keeps
    its integral across the steps and restarts it with each episode, as when it acts alone); a correction
    moves the env's action by ``scale`` times it, clipped to the box."""
    model = random_direction_model(TINY_SETTINGS)
    alone_env = tiny_surrogate(model)
    controller = make_tracking_controller("angle_pi", PI["params"]).bind(alone_env)
    controller.reset()
    alone = trace(alone_env, controller)
    wrapped = ResidualControllerWrapper(tiny_surrogate(model), "angle_pi", PI["params"], 0.5)
    zero = np.zeros(3, dtype=np.float32)
    assert trace(wrapped, lambda obs: zero) == alone
    assert trace(wrapped, lambda obs: zero) == alone  # the second episode restarts the integral
    wrapped.reset(seed=0, options={"split": "validation", "index": 1})
    correction = np.array([0.4, -3.0, 0.2], dtype=np.float32)
    _, _, _, _, info = wrapped.step(correction)
    expected = np.clip(info["controller_action"] + np.float32(0.5) * correction, -1.0, 1.0)
    assert np.array_equal(info["env_action"], expected) and info["env_action"][1] == -1.0


def test_make_env_takes_residual_out_of_the_env_arguments() -> None:
    env = make_env(TINY, {"residual": PI, "progress": False})
    assert isinstance(env, ResidualControllerWrapper) and env.scale == 0.5
    assert env.action_space == env.unwrapped.action_space
    assert not isinstance(make_env(TINY, {"progress": False}), ResidualControllerWrapper)


@pytest.mark.parametrize(
    "spec, message",
    [
        ("angle_pi", "must be a mapping"),
        ({"params": {}}, "must be a mapping"),
        ({"controller": "angle_pi", "gain": 1}, "must be a mapping"),
        ({"controller": "pid"}, "residual.controller must be one of"),
        ({"controller": "angle_pi", "params": [3, 1]}, "residual.params must be a mapping"),
        ({"controller": "angle_pi", "params": {"kp": 1, "ki": 1}, "scale": 0}, r"residual.scale .* \(0, 2\]"),
        ({"controller": "angle_pi", "params": {"kp": 1, "ki": 1}, "scale": 3}, r"residual.scale"),
        ({"controller": "angle_pi", "params": {"kp": 1, "ki": 1}, "scale": True}, r"residual.scale"),
    ],
)
def test_bad_residual_specs_are_refused_by_name(spec, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        check_residual(spec)


def test_bad_controller_parameters_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="residual.params"):
        make_env(
            TINY, {"residual": {"controller": "angle_pi", "params": {"kp": 1, "gain": 2}}, "progress": False}
        )
    with pytest.raises(ValueError, match="kp must be finite and >= 0"):
        make_env(
            TINY, {"residual": {"controller": "angle_pi", "params": {"kp": -1, "ki": 1}}, "progress": False}
        )


def test_a_residual_run_is_played_with_its_controller_on_the_play_env(tmp_path: Path) -> None:
    """The controller is part of the policy: a run trained with ``residual`` and played with ``--play-env``
    (which otherwise takes the play env's default arguments) is played on the wrapped env."""
    from stable_baselines3 import PPO

    from agents.tracking_rows import run_play

    run = tmp_path / "seed0"
    run.mkdir()
    env = make_env(TINY, {"residual": PI, "progress": False})
    PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=0, device="cpu").save(run / "model.zip")
    config = {"algo": "ppo", "env_id": TINY, "env_kwargs": {"residual": PI}, "hyperparams": {}, "seed": 0}
    (run / "config.yml").write_text(yaml.safe_dump(config))
    payload = run_play(run, TINY, TINY, {})
    assert payload["env_kwargs"] == {"residual": PI}
    assert run_play(run, None, TINY, {})["env_kwargs"] == {"residual": PI}
