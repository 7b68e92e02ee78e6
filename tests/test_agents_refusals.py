"""agents.evaluate and agents.train refuse what would make their numbers silently wrong: a policy trained
with observation normalisation whose statistics are missing (evaluate; train on resume), and policies
compared with a baseline played on other start states (another split, another start-state library)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from agents import evaluate, open_loop, train

ENV = "dipenv/FieldMagnitudeTiny-v0"
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32"]
COMMON = ["--env", ENV, "--n-envs", "1", "--no-progress", "--algo", "ppo", "--seed", "0"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A one-state open-loop baseline (test split) and a 64-step PPO run: (baseline, run)."""
    root = tmp_path_factory.mktemp("agents_refusals")
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(root / "cache"))
    baseline, run = root / "open_loop", root / "ppo"
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1", "--episodes", "1"])
    train.main([*COMMON, "--timesteps", "64", "--out", str(run), "--hyperparams", *SHORT])
    yield baseline, run
    patcher.undo()


def _refused(capsys: pytest.CaptureFixture[str], module: object, arguments: list[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        module.main(arguments)  # type: ignore[attr-defined]
    err = capsys.readouterr().err
    assert exit_.value.code == 2, err
    assert f"python -m agents.{module.__name__.split('.')[-1]}: error: " in err  # type: ignore[attr-defined]
    return err


def test_evaluate_refuses_a_run_without_its_normalisation(trained, tmp_path: Path, capsys) -> None:
    """Was: without vecnormalize.pkl the policy played raw observations and a verdict was printed."""
    baseline, run = trained
    copy = tmp_path / "ppo"
    shutil.copytree(run, copy)
    (copy / "vecnormalize.pkl").unlink()
    out = tmp_path / "evaluation"
    err = _refused(capsys, evaluate, [str(copy), "--baseline", str(baseline), "--out", str(out)])
    assert f"{copy / 'vecnormalize.pkl'} are missing" in err and "VecNormalize" in err
    assert not out.exists()


def test_evaluate_refuses_other_start_states(trained, tmp_path: Path, capsys) -> None:
    """Was: ``--split train`` against a test-split baseline, and a baseline of another start-state
    library, were compared "on the same states" (the library only warned)."""
    baseline, run = trained
    out = tmp_path / "evaluation"
    err = _refused(
        capsys, evaluate, [str(run), "--baseline", str(baseline), "--out", str(out), "--split", "train"]
    )
    assert "--split train: the --baseline" in err and "was played on the test start states" in err
    other = tmp_path / "other_baseline"
    shutil.copytree(baseline, other)
    pareto = json.loads((other / "pareto.json").read_text())
    (other / "pareto.json").write_text(json.dumps({**pareto, "library_key": "0123456789abcdef"}))
    err = _refused(capsys, evaluate, [str(run), "--baseline", str(other), "--out", str(out)])
    assert "the --baseline those of library 0123456789abcdef" in err and "RUN_DIRS: " in err
    assert not out.exists()
    # the same states: accepted
    result = evaluate.main([str(run), "--baseline", str(baseline), "--out", str(out)])
    assert any(r["name"].startswith("ppo (") for r in result["rows"])


def test_train_refuses_to_resume_without_the_checkpoints_normalisation(
    trained, tmp_path: Path, capsys
) -> None:
    """Was: a resumed run started from fresh VecNormalize statistics when the checkpoint's were missing."""
    _, run = trained
    copy = tmp_path / "ppo"
    shutil.copytree(run, copy)
    train.main([*COMMON, "--timesteps", "64", "--out", str(copy), "--hyperparams", *SHORT])  # finished: fine
    for stats in (copy / "checkpoints").glob("ckpt_vecnormalize_*_steps.pkl"):
        stats.unlink()
    (copy / "result.json").unlink()  # interrupted: it would resume from its latest checkpoint
    before = sorted(p.name for p in copy.rglob("*"))
    err = _refused(
        capsys, train, [*COMMON, "--timesteps", "128", "--out", str(copy), "--hyperparams", *SHORT]
    )
    assert "ckpt_vecnormalize_64_steps.pkl, which is missing" in err and f"--out {copy}" in err
    assert sorted(p.name for p in copy.rglob("*")) == before


def test_train_without_a_validation_and_after_a_failed_attempt(trained, tmp_path: Path) -> None:
    """A policy argument SB3 refuses no longer fails after config.yml was written (it blocked the corrected
    command): the model is built before the folder is claimed, and the refusal exits 2 naming it; a run
    too short for a validation writes null, not -Infinity (invalid JSON)."""
    out = tmp_path / "short"
    first = [*COMMON, "--timesteps", "32", "--out", str(out), "--hyperparams", *SHORT]
    with pytest.raises(SystemExit) as refused:
        train.main([*first, "policy_kwargs={bogus_argument: 1}"])
    assert refused.value.code == 2 and not out.exists()
    train.main([*first, "eval_freq=1000"])
    text = (out / "result.json").read_text()

    def strict(constant: str) -> None:
        raise AssertionError(f"result.json holds {constant}, which is not JSON")

    result = json.loads(text, parse_constant=strict)
    assert result["best_validation_return"] is None and result["last_validation_return"] is None
    assert result["timesteps"] >= 32


EVALUATE_BAD = [
    ("model.zip", b"PK\x03\x04 truncated", "cannot be loaded as a ppo model"),
    ("vecnormalize.pkl", b"\x80\x04 truncated", "vecnormalize.pkl cannot be loaded"),
    ("config.yml", b"\x89PNG\x00\xff", "config.yml cannot be read (UnicodeDecodeError"),
    ("config.yml", b"just a string\n", "config.yml is not an agents.train config.yml"),
]


@pytest.mark.parametrize(
    ("name", "content", "needle"), EVALUATE_BAD, ids=[f"{n}-{c!r}" for n, c, _ in EVALUATE_BAD]
)
def test_evaluate_names_a_corrupt_run_file(
    trained, name: str, content: bytes, needle: str, tmp_path: Path, capsys
) -> None:
    """Were tracebacks (zipfile, pickle, yaml errors), some from a worker after the episodes began."""
    baseline, run = trained
    copy = tmp_path / "ppo"
    shutil.copytree(run, copy)
    (copy / name).write_bytes(content)
    out = tmp_path / "evaluation"
    err = _refused(capsys, evaluate, [str(copy), "--baseline", str(baseline), "--out", str(out)])
    assert f"{copy / name}" in err and needle in err, err
    assert not out.exists()


def test_evaluate_refuses_bad_arguments(trained, tmp_path: Path, capsys) -> None:
    baseline, run = trained
    out = tmp_path / "evaluation"
    empty = tmp_path / "empty"
    empty.mkdir()
    afile = tmp_path / "notes.txt"
    afile.write_text("keep\n")
    cases = [
        (["--baseline", str(tmp_path / "missing")], f"--baseline {tmp_path / 'missing'} is not a folder"),
        (["--baseline", str(empty)], f"--baseline {empty}: {empty / 'pareto.json'} cannot be read"),
        (["--baseline", str(baseline), "--split", "bogus"], "argument --split: invalid choice: 'bogus'"),
        (["--baseline", str(baseline), "--workers", "0"], "argument --workers: must be an integer >= 1"),
        (["--baseline", str(baseline), "--episodes", "0"], "argument --episodes: must be an integer >= 1"),
    ]
    for arguments, needle in cases:
        err = _refused(capsys, evaluate, [str(run), "--out", str(out), *arguments])
        assert needle in err, err
    assert not out.exists()
    err = _refused(capsys, evaluate, [str(run), "--baseline", str(baseline), "--out", str(afile)])
    assert f"--out {afile} exists and is not a directory" in err
