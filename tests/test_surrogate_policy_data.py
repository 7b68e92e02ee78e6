"""scripts/surrogate_data.py's policy behaviour (seeds >= 100,000): trained policies play the data."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import gymnasium as gym
import numpy as np
import pytest
import yaml
from agents_helpers import load_script

import dipenv  # noqa: F401  (registers the ids)

ROOT = Path(__file__).resolve().parents[1]
TINY = "dipenv/ThickeningControlTiny-v0"


def data_script() -> ModuleType:
    return load_script("surrogate_data")


def policy_folder(root: Path, seed: int) -> Path:
    """An agents.train-like folder with one untrained PPO policy of the Tiny id's spaces."""
    from stable_baselines3 import PPO

    run = root / f"seed{seed}"
    run.mkdir(parents=True)
    env = gym.make(TINY, progress=False)
    PPO("MlpPolicy", env, seed=seed, n_steps=8, batch_size=8, device="cpu").save(str(run / "model.zip"))
    env.close()
    (run / "config.yml").write_text(yaml.safe_dump({"algo": "ppo", "env_id": TINY, "seed": seed}))
    return run


def test_policy_seeds_play_the_policy_and_record_it(tmp_path: Path) -> None:
    data = data_script()
    policies = tmp_path / "policies"
    policy_folder(policies, 0)
    out = tmp_path / "data"
    argv = ["--out", str(out), "--seeds", "100000", "--env-id", TINY, "--policies", str(policies)]
    assert data.main(argv) == 0
    episode = out / "episodes" / "ep100000.npz"
    with np.load(episode) as d:
        assert str(d["behaviour"]) == "policy:seed0"
        assert len(str(d["policy_digest"])) == 16
        actions = np.array(d["action"])
    # sampled, not the mean: an untrained policy's mean is ~0 (SB3 initialises the action head with gain
    # 0.01) and its Gaussian has sd 1, so the clipped samples spread over [-1, 1]; the mean action would
    # give a spread of ~0.01
    assert actions.std() > 0.3
    # same seed, same episode (torch seeded by the episode seed)
    again = tmp_path / "again"
    assert data.main(["--out", str(again), *argv[2:]]) == 0
    with np.load(again / "episodes" / "ep100000.npz") as d:
        np.testing.assert_array_equal(d["action"], actions)


def test_other_models_at_the_same_seeds_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = data_script()
    first, second = tmp_path / "first", tmp_path / "second"
    policy_folder(first, 0)
    policy_folder(second, 1)  # another initialisation: another digest
    (second / "seed1").rename(second / "seed0")
    out = tmp_path / "data"
    base = ["--out", str(out), "--seeds", "100000", "--env-id", TINY]
    assert data.main([*base, "--policies", str(first)]) == 0
    capsys.readouterr()
    data.main([*base, "--policies", str(second)])
    assert "was played by the model with digest" in capsys.readouterr().out


def test_policy_seeds_need_policies(tmp_path: Path) -> None:
    data = data_script()
    with pytest.raises(SystemExit) as exc:
        data.main(["--out", str(tmp_path / "d"), "--seeds", "100000", "--env-id", TINY])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        data.main(
            ["--out", str(tmp_path / "d"), "--seeds", "0", "--env-id", TINY, "--policies", str(tmp_path)]
        )
    assert exc.value.code == 2
