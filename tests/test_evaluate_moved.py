"""agents.evaluate resumes a committed evaluation in another checkout: a played run's stored episodes are
matched by what its files hold (model and statistics SHA-256, env, states, play arguments), not by the
absolute paths of its run folder and model, which differ from checkout to checkout. Another model at the
same path is played again."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch
from stable_baselines3 import PPO

from agents import evaluate, open_loop, train

ENV = "dipenv/FieldMagnitudeTiny-v0"


@pytest.fixture(autouse=True)
def state_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DIPENV_CACHE_DIR", str(tmp_path / "cache"))


def _stored(checkout: Path) -> Path:
    return checkout / "evaluation" / "runs" / "ppo_seed0.json"


def test_a_committed_evaluation_resumes_in_another_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = tmp_path / "checkout_a"
    first.mkdir()
    monkeypatch.chdir(first)  # every path below is relative to the checkout, as in the repository
    open_loop.main(["--env", ENV, "--out", "open_loop", "--mason", "off,1", "--episodes", "1"])
    train.main(
        ["--env", ENV, "--algo", "ppo", "--seeds", "0-0", "--timesteps", "32", "--n-envs", "1"]
        + ["--out", "ppo", "--no-progress", "--hyperparams", "n_steps=32", "batch_size=32", "n_epochs=1"]
        + ["eval_freq=32", "checkpoint_freq=32"]
    )
    args = ["ppo", "--baseline", "open_loop", "--out", "evaluation"]
    evaluate.main(args)
    record = json.loads(_stored(first).read_text())
    assert record["identity"]["run"].startswith(str(first))  # an absolute path of this checkout

    second = tmp_path / "checkout_b"
    shutil.copytree(first, second)
    # mark the stored episode: a replay would drop the mark
    record["episodes"][0]["mark"] = 1
    _stored(second).write_text(json.dumps(record))
    monkeypatch.chdir(second)
    evaluate.main(args)
    assert json.loads(_stored(second).read_text())["episodes"][0].get("mark") == 1

    # another model behind the same path is another policy: played again
    model_file = second / "ppo" / "seed0" / "model.zip"
    model = PPO.load(str(model_file), device="cpu")
    with torch.no_grad():
        next(model.policy.parameters()).add_(0.5)
    model.save(str(model_file))
    evaluate.main(args)
    assert "mark" not in json.loads(_stored(second).read_text())["episodes"][0]


def test_same_play_ignores_locations_only() -> None:
    stored = {"run": "/a/ppo/seed0", "model": "/a/ppo/seed0/model.zip", "model_sha256": "1", "split": "test"}
    assert evaluate.same_play(stored, {**stored, "run": "/b/ppo/seed0", "model": "/b/ppo/seed0/model.zip"})
    assert not evaluate.same_play(stored, {**stored, "model_sha256": "2"})
    assert not evaluate.same_play(stored, {**stored, "split": "fresh"})
    assert not evaluate.same_play(None, stored)


def test_a_run_copied_elsewhere_is_the_same_run_for_the_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The evaluation folder's manifest names the run folders it was given; a rerun naming a copy of them
    (a scratch run copied into the repository) is accepted and replays nothing; a copy holding another
    model is refused."""
    monkeypatch.chdir(tmp_path)
    open_loop.main(["--env", ENV, "--out", "open_loop", "--mason", "off,1", "--episodes", "1"])
    train.main(
        ["--env", ENV, "--algo", "ppo", "--seeds", "0-0", "--timesteps", "32", "--n-envs", "1"]
        + ["--out", "scratch/ppo", "--no-progress", "--hyperparams", "n_steps=32", "batch_size=32"]
        + ["n_epochs=1", "eval_freq=32", "checkpoint_freq=32"]
    )
    evaluate.main(["scratch/ppo", "--baseline", "open_loop", "--out", "evaluation"])
    shutil.copytree("scratch/ppo", "results/ppo", ignore=shutil.ignore_patterns("checkpoints", "tb"))
    stored = json.loads(_stored(tmp_path).read_text())
    stored["episodes"][0]["mark"] = 1
    _stored(tmp_path).write_text(json.dumps(stored))
    evaluate.main(["results/ppo", "--baseline", "open_loop", "--out", "evaluation"])
    assert json.loads(_stored(tmp_path).read_text())["episodes"][0].get("mark") == 1  # nothing replayed

    # a copy holding another model is another run: refused
    shutil.copytree("results/ppo", "other/ppo")
    model_file = tmp_path / "other" / "ppo" / "seed0" / "model.zip"
    model = PPO.load(str(model_file), device="cpu")
    with torch.no_grad():
        next(model.policy.parameters()).add_(0.5)
    model.save(str(model_file))
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main(["other/ppo", "--baseline", "open_loop", "--out", "evaluation"])
    assert exit_info.value.code == 2
    assert "other parameters" in capsys.readouterr().err
