"""agents.train takes the surrogate ids (issue 43: pretraining through the fast fidelity): a short PPO run
finishes, writes its files, and records that no start-state library was used."""

from __future__ import annotations

import json

import dipenv
from agents import train


def test_ppo_trains_on_the_surrogate_id(tmp_path) -> None:
    out = tmp_path / "run"
    train.main(
        [
            "--env",
            dipenv.SURROGATE_IDS[0],
            "--algo",
            "ppo",
            "--seed",
            "0",
            "--out",
            str(out),
            "--hyperparams",
            "n_timesteps=256",
            "n_envs=1",
            "n_steps=128",
            "eval_freq=128",
            "checkpoint_freq=128",
        ]
    )
    result = json.loads((out / "result.json").read_text())
    assert result["timesteps"] == 256 and result["library_key"] is None
    assert result["best_validation_return"] is not None
    for name in ("model.zip", "vecnormalize.pkl", "config.yml", "manifest.json"):
        assert (out / name).exists()


def test_ppo_trains_on_the_tracking_surrogate_id(tmp_path) -> None:
    """The tracking surrogate (issue 44) through agents.train, with an untrained direction-aware model named
    by --env-kwargs (in place of the shipped one): the run finishes and validates on the surrogate."""
    from tests.test_tracking_surrogate import V0_SETTINGS, random_direction_model

    model = tmp_path / "model.npz"
    random_direction_model(V0_SETTINGS).save(model)
    out = tmp_path / "run"
    train.main(
        [
            "--env",
            dipenv.TRACKING_SURROGATE_IDS[0],
            "--env-kwargs",
            json.dumps({"model": str(model)}),
            "--algo",
            "ppo",
            "--seed",
            "0",
            "--out",
            str(out),
            "--hyperparams",
            "n_timesteps=128",
            "n_envs=1",
            "n_steps=64",
            "eval_freq=128",
            "checkpoint_freq=128",
        ]
    )
    result = json.loads((out / "result.json").read_text())
    assert result["timesteps"] == 128 and result["library_key"] is None
    assert result["best_validation_return"] is not None


def test_every_surrogate_id_has_ppo_hyperparameters() -> None:
    for env_id in (*dipenv.SURROGATE_IDS, *dipenv.TRACKING_SURROGATE_IDS):
        params = train.load_hyperparams("ppo", env_id)
        assert params["n_timesteps"] == 1_000_000 and params["eval_freq"] == 50_000


def test_open_loop_plays_constant_fields_on_the_surrogate(tmp_path) -> None:
    """agents.open_loop on a surrogate id (no start-state library, strength only): the constant-field
    baseline that surrogate-trained policies are compared with there; its library key is null."""
    from agents import open_loop

    out = tmp_path / "open_loop"
    argv = ["--env", "dipenv/ThickeningControlSurrogate-v0", "--split", "validation", "--mason", "0.5,off"]
    open_loop.main([*argv, "--episodes", "2", "--out", str(out)])
    points = sorted((out / "points").glob("*.json"))
    assert [p.stem for p in points] == ["Mn0.5", "off"]
    record = json.loads(points[0].read_text())
    assert record["identity"]["library_key"] is None
    assert len(record["episodes"]) == 2
