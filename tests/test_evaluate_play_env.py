"""agents.evaluate --play-env: policies trained in one env are judged in another with the same spaces."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from agents import evaluate, open_loop, train
from agents.rollout import make_env, run_episode

ENV = "dipenv/FieldMagnitudeTiny-v0"
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32"]
TRAINED_WITH = {"simulation_overrides": {"max_displacement": 0.001}}


def _train(out: Path, env: str, kwargs: dict) -> None:
    train.main(
        ["--env", env, "--timesteps", "64", "--n-envs", "1", "--no-progress", "--algo", "ppo", "--seeds", "0"]
        + ["--env-kwargs", json.dumps(kwargs), "--out", str(out), "--hyperparams", *SHORT]
    )


def test_play_env_plays_the_policy_in_the_named_env_with_its_defaults(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run trained in other physics (a tighter displacement bound, standing in for the surrogate) is
    played in the named env with that env's defaults: its episode equals a replay of its policy by hand
    in the default env, bit for bit, and differs from one in its training env."""
    from stable_baselines3 import PPO

    baseline = tmp_path / "open_loop"
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1", "--episodes", "1"])
    ppo = tmp_path / "ppo"
    _train(ppo, ENV, TRAINED_WITH)
    out = tmp_path / "evaluation"
    evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), "--play-env", ENV])
    played = json.loads((out / "runs" / "ppo_seed0.json").read_text())["episodes"][0]["trace"]["eta_r"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["params"]["play_env"] == ENV

    model = PPO.load(str(ppo / "seed0" / "model.zip"), device="cpu")
    with open(ppo / "seed0" / "vecnormalize.pkl", "rb") as handle:
        normaliser = pickle.load(handle)
    normaliser.training = False

    def replay(kwargs: dict) -> list[float]:
        env = make_env(ENV, {**kwargs, "progress": False})
        trace = run_episode(
            env,
            lambda obs: np.asarray(model.predict(normaliser.normalize_obs(obs), deterministic=True)[0]),
            "test",
            0,
        ).to_dict()
        env.close()
        return list(trace["eta_r"])

    assert played == replay({})
    assert played != replay(TRAINED_WITH)


def test_play_env_with_other_spaces_is_refused_naming_both(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    baseline = tmp_path / "open_loop"
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1", "--episodes", "1"])
    ppo = tmp_path / "ppo"
    _train(ppo, ENV, {})
    capsys.readouterr()
    out = tmp_path / "evaluation"
    other = "dipenv/FieldVectorTiny-v0"  # a 3-entry action: another action space
    with pytest.raises(SystemExit) as refused:
        evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), "--play-env", other])
    message = capsys.readouterr().err
    assert refused.value.code == 2
    assert "--play-env" in message and "action space" in message and other in message
    assert not out.exists()  # refused before the folder is claimed
    with pytest.raises(SystemExit) as refused:
        evaluate.main(
            [str(ppo), "--baseline", str(baseline), "--out", str(out), "--play-env", "dipenv/Nope-v0"]
        )
    assert refused.value.code == 2 and "cannot be made" in capsys.readouterr().err
