"""scripts/surrogate_pretrain.py (issue 43's pretrain -> fine-tune protocol), a smoke version: two PPO seeds
pretrained briefly on the surrogate, each fine-tuned from its own pretrained seed on the tiny thickening
id; the summary records each seed's simulator steps; a rerun resumes (nothing retrained) and other
settings are refused."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from agents_helpers import load_script

ROOT = Path(__file__).resolve().parents[1]
TINY = [
    "n_envs=1",
    "n_steps=64",
    "batch_size=32",
    "n_epochs=1",
    "eval_freq=64",
    "checkpoint_freq=64",
]


def script() -> ModuleType:
    return load_script("surrogate_pretrain", cached=True)


@pytest.fixture(autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Any:
    monkeypatch.setenv("DIPENV_CACHE_DIR", str(tmp_path_factory.mktemp("dipenv_cache_pretrain")))


def test_pretrain_then_fine_tune_records_the_simulator_steps_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "protocol"
    argv = [
        "--out",
        str(out),
        "--seeds",
        "0-1",
        "--pretrain-steps",
        "128",
        "--finetune-steps",
        "64",
        "--env",
        "dipenv/ThickeningControlTiny-v0",
        "--pretrain-hyperparams",
        *TINY,
        "policy_kwargs={net_arch: [32, 32]}",  # the tiny id's network
        "--finetune-hyperparams",
        *TINY,
    ]
    summary = script().main(argv)
    rows = summary["rows"]
    assert [row["seed"] for row in rows] == [0, 1]
    for row in rows:
        assert row["pretrain_steps"] == 128 and row["finetune_training_steps"] == 64
        # one validation pass at step 64: the tiny id's 2 validation episodes of 10 intervals
        assert row["finetune_validation_passes"] == 1 and row["finetune_validation_steps"] == 20
        assert row["simulator_steps"] == 84 and row["simulated_time"] == pytest.approx(84 * 0.02)
    for seed in (0, 1):
        manifest = json.loads((out / "finetune" / f"seed{seed}" / "manifest.json").read_text())
        assert manifest["params"]["init_from"]["run"].endswith(f"pretrain/seed{seed}")
    assert (out / "summary.md").read_text().startswith("| seed |")
    # a rerun continues: both stages are finished, nothing is trained again
    before = {p: p.stat().st_mtime_ns for p in out.glob("*/seed*/model.zip")}
    assert script().main(argv)["rows"] == rows
    assert {p: p.stat().st_mtime_ns for p in out.glob("*/seed*/model.zip")} == before
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        script().main([*argv[:7], "65", *argv[8:]])  # another --finetune-steps
    assert refused.value.code == 2 and "finetune_steps" in capsys.readouterr().err
