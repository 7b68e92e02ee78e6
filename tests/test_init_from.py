"""agents.train --init-from (issue 43: pretrain on the surrogate, fine-tune in the simulator): a fine-tuned
run starts from exactly its source's weights and normalisation statistics, seed k from the study's
seed<k>; mismatched spaces and frames are refused; the source joins the identity, so a rerun from another
source is refused while the same one resumes."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path
from typing import Any

import pytest
import torch
import yaml
from stable_baselines3 import PPO
from stable_baselines3.common.save_util import load_from_zip_file

import dipenv
from agents import train

SURROGATE = dipenv.SURROGATE_IDS[0]
TINY = "dipenv/ThickeningControlTiny-v0"
SHORT = [
    "n_envs=1",
    "n_steps=64",
    "batch_size=32",
    "n_epochs=1",
    "eval_freq=128",
    "checkpoint_freq=64",
    "policy_kwargs={net_arch: [32, 32]}",  # the tiny ids' network, so a surrogate source fits them
]


@pytest.fixture(scope="module", autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory) -> Any:
    root = tmp_path_factory.mktemp("dipenv_cache_init_from")
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(root))
    yield root
    patcher.undo()


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-seed PPO study on the surrogate (128 steps each): source/seed0, source/seed1."""
    out = tmp_path_factory.mktemp("init") / "source"
    argv = ["--env", SURROGATE, "--seeds", "0-1", "--out", str(out), "--timesteps", "128", "--hyperparams"]
    train.main([*argv, *SHORT])
    return out


def policy_of(model_file: Path) -> dict[str, torch.Tensor]:
    policy: Any = load_from_zip_file(model_file, device="cpu", load_data=False)[1]["policy"]
    return dict(policy)


def test_a_fine_tuned_run_starts_from_its_sources_weights_seed_by_seed(
    source: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before its first update each seed's policy is its source seed's, parameter for parameter, and its
    VecNormalize statistics continue the source's (their count is the source's plus one rollout)."""
    first: list[tuple[int, dict[str, torch.Tensor], float]] = []
    update = PPO.train

    def spy(self: PPO) -> None:
        if not getattr(self, "_spied", False):
            self._spied = True  # type: ignore[attr-defined]
            params = {k: v.detach().clone() for k, v in self.policy.state_dict().items()}
            stats: Any = self.get_vec_normalize_env()
            first.append((self.seed, params, float(stats.obs_rms.count)))  # type: ignore[arg-type]
        update(self)

    monkeypatch.setattr(PPO, "train", spy)
    out = tmp_path / "fine"
    argv = ["--env", TINY, "--seeds", "0-1", "--out", str(out), "--init-from", str(source)]
    train.main([*argv, "--timesteps", "64", "--hyperparams", *SHORT])
    assert [seed for seed, _, _ in first] == [0, 1]
    for seed, params, count in first:
        expected = policy_of(source / f"seed{seed}" / "model.zip")
        assert params.keys() == expected.keys()
        for key, value in expected.items():
            assert torch.equal(params[key], value), (seed, key)
        with open(source / f"seed{seed}" / "vecnormalize.pkl", "rb") as stream:
            source_stats = pickle.load(stream)
        assert count == pytest.approx(source_stats.obs_rms.count + 1 + 64)  # the reset, one rollout
    # the two seeds started from different sources (seed k from seed<k>)
    zero, one = (policy_of(source / f"seed{k}" / "model.zip") for k in (0, 1))
    assert any(not torch.equal(zero[k], one[k]) for k in zero)
    for seed in (0, 1):
        manifest = json.loads((out / f"seed{seed}" / "manifest.json").read_text())["params"]
        assert manifest["init_from"]["seed"] == seed and manifest["init_from"]["env_id"] == SURROGATE
        assert manifest["init_from"]["run"].endswith(f"source/seed{seed}")
        result = json.loads((out / f"seed{seed}" / "result.json").read_text())
        assert result["init_from"] == manifest["init_from"] and result["timesteps"] == 64
    study = json.loads((out / "manifest.json").read_text())["params"]["init_from"]
    assert study["layout"] == "seed k from SOURCE/seed<k>" and study["source"] == str(source)


def test_mismatched_spaces_and_frames_are_refused(
    source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a source whose config.yml records another frame of the same shape (a stress-only frame, say)
    doctored = tmp_path / "doctored"
    shutil.copytree(source / "seed0", doctored)
    config = yaml.safe_load((doctored / "config.yml").read_text())
    config["env_settings"]["observation"][0] = "slog_shear_stress"
    (doctored / "config.yml").write_text(yaml.safe_dump(config))
    cases = [
        # 14 entries against the surrogate's 15 (the field-control frame; the stress-only one): both spaces
        ("dipenv/FieldMagnitudeTiny-v0", source / "seed0", ["observation space Box(", "against Box(", "14,"]),
        (dipenv.SURROGATE_IDS[1], source / "seed0", ["observation space Box(", "(15,)", "(14,)"]),
        (SURROGATE, doctored, ["the frames differ", "slog_shear_stress"]),
    ]
    for env_id, given, words in cases:
        out = tmp_path / env_id.split("/")[1]
        with pytest.raises(SystemExit) as refused:
            train.main(
                ["--env", env_id, "--seed", "0", "--out", str(out), "--init-from", str(given)]
                + ["--hyperparams", *SHORT]
            )
        err = capsys.readouterr().err
        assert refused.value.code == 2 and "--init-from" in err, err
        for word in words:
            assert word in err, (word, err)
        assert not out.exists()  # refused before the folder is claimed
    # a network of another shape is refused, naming the policy
    with pytest.raises(SystemExit) as refused:
        train.main(
            ["--env", SURROGATE, "--seed", "0", "--out", str(tmp_path / "wide"), "--init-from"]
            + [str(source / "seed0"), "--hyperparams", *SHORT[:-1], "policy_kwargs={net_arch: [16]}"]
        )
    assert refused.value.code == 2 and "do not fit the policy" in capsys.readouterr().err
    # seed 2 has no source in a two-seed study
    with pytest.raises(SystemExit) as refused:
        argv = ["--env", SURROGATE, "--seeds", "1-2", "--out", str(tmp_path / "s")]
        train.main([*argv, "--init-from", str(source)])
    assert refused.value.code == 2 and "no run for seed2" in capsys.readouterr().err


def test_the_source_is_in_the_identity_and_a_fine_tuned_run_resumes(
    source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "fine"
    base = ["--env", SURROGATE, "--seed", "0", "--out", str(out), "--no-progress", "--hyperparams", *SHORT]
    model = source / "seed0" / "model.zip"
    train.main([*base, "--init-from", str(model), "--timesteps", "64"])
    config = (out / "config.yml").read_text()
    assert "model_sha256" in config and "init_from" in config
    # another source (seed 1's run), or none, is another run
    for other in (["--init-from", str(source / "seed1")], []):
        with pytest.raises(SystemExit) as refused:
            train.main([*base, *other, "--timesteps", "64"])
        assert refused.value.code == 2 and "init_from" in capsys.readouterr().err
    # the same source spelled otherwise (its run folder) continues, and a larger n_timesteps resumes from
    # the run's last checkpoint
    result = train.main([*base, "--init-from", str(source / "seed0"), "--timesteps", "128"])[0]
    assert result["resumed_from"] == 64 and result["timesteps"] == 128
