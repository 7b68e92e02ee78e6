"""Bad command-line input to the agents commands exits 2 naming the argument and its valid range, before
any set-up (nothing simulated, no output folder), through the shared checks of :mod:`agents.usage`."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

from agents import demo, open_loop, train
from agents.train import HyperparameterError, check_hyperparameters, run_conflict

ENV = "dipenv/FieldMagnitudeTiny-v0"


def refused(capsys: pytest.CaptureFixture[str], module: object, arguments: list[str]) -> str:
    """Run ``module.main(arguments)``; assert exit 2 with the module's prefix; return stderr."""
    tic = time.perf_counter()
    with pytest.raises(SystemExit) as exit_:
        module.main(arguments)  # type: ignore[attr-defined]
    err = capsys.readouterr().err
    assert exit_.value.code == 2, err
    assert f"python -m agents.{module.__name__.split('.')[-1]}: error: " in err  # type: ignore[attr-defined]
    assert time.perf_counter() - tic < 30, "refused only after set-up"
    return err


TRAIN_BAD = [
    (["--seeds", "0-99999999999"], "argument --seeds: at most 10000 seeds are allowed, got 100000000000"),
    (["--timesteps", "0"], "argument --timesteps: must be an integer >= 1, got '0'"),  # was exit 0, -Infinity
    (["--timesteps", "-5"], "argument --timesteps: must be an integer >= 1, got '-5'"),
    (["--n-envs", "0"], "argument --n-envs: must be an integer >= 1, got '0'"),
    (["--seed", "-1"], "argument --seed: must be an integer >= 0, got '-1'"),
    (["--workers", "0"], "argument --workers: must be an integer >= 1, got '0'"),
    (["--scheduler", "localhost"], "argument --scheduler: must be a Dask scheduler address"),
    (["--hyperparams", "bogus=1"], "--hyperparams: unknown hyperparameter 'bogus' for ppo (the keys: "),
    (["--hyperparams", "learning_rate=fast"], "--hyperparams: learning_rate must be a number, got 'fast'"),
    (["--hyperparams", "learning_rate=-1"], "--hyperparams: learning_rate must be a number in (0.0, inf]"),
    (["--hyperparams", "n_steps=0"], "--hyperparams: n_steps must be an integer in [1, inf], got 0"),
    (["--hyperparams", "n_epochs=2.5"], "--hyperparams: n_epochs must be an integer, got 2.5"),
    (["--hyperparams", "normalize=3"], "--hyperparams: normalize must be true or false, got 3"),
    (["--hyperparams", "policy_kwargs=[1]"], "--hyperparams: policy_kwargs must be a mapping, got [1]"),
    (["--env-kwargs", '{"bogus": 1}'], '--env-kwargs {"bogus": 1}: '),
    (["--env-kwargs", '{"episode_steps": 0}'], "episode_steps must be an integer >= 1, got 0"),
    (["--env-kwargs", '{"split_sizes": {"train": 0}}'], "--env-kwargs"),
]


@pytest.mark.parametrize(("arguments", "needle"), TRAIN_BAD, ids=[" ".join(a) for a, _ in TRAIN_BAD])
def test_train_refuses_before_any_set_up(
    arguments: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    err = refused(capsys, train, ["--env", ENV, "--out", str(out), *arguments])
    assert needle in err, err
    assert not out.exists()


def test_train_refuses_an_out_that_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    afile = tmp_path / "notes.txt"
    afile.write_text("keep\n")
    err = refused(capsys, train, ["--env", ENV, "--out", str(afile)])
    assert f"--out {afile} exists and is not a directory" in err
    err = refused(capsys, train, ["--env", ENV, "--out", str(afile / "sub")])
    assert f"--out {afile / 'sub'} cannot be created: {afile} is not a directory" in err


def test_sac_keys_and_ranges() -> None:
    check_hyperparameters("sac", {"ent_coef": "auto", "tau": 0.02, "train_freq": 1}, "x")
    check_hyperparameters("sac", {"ent_coef": 0.1}, "x")
    with pytest.raises(HyperparameterError, match=r"x: tau must be a number in \(0.0, 1.0\], got 0"):
        check_hyperparameters("sac", {"tau": 0}, "x")
    with pytest.raises(HyperparameterError, match="x: unknown hyperparameter 'n_epochs' for sac"):
        check_hyperparameters("sac", {"n_epochs": 3}, "x")
    with pytest.raises(HyperparameterError, match=r"n_steps \* n_envs must be >= 2"):
        check_hyperparameters("ppo", {"n_steps": 1, "n_envs": 1}, "x")


def test_a_failed_attempts_config_does_not_block_the_corrected_command(tmp_path: Path) -> None:
    """A config.yml alone (an attempt that failed before its first checkpoint) is replaced; one beside
    a checkpoint, a model or a result names the differing fields."""
    identity = train.run_identity(ENV, {}, {}, "ppo", 0, {})
    (tmp_path / "config.yml").write_text("env_id: other\nseed: 0\nalgo: ppo\n")
    assert run_conflict(tmp_path, identity) is None
    (tmp_path / "model.zip").write_bytes(b"")
    message = run_conflict(tmp_path, identity)
    assert message is not None and "holds a different run (config.yml differs in env_id" in message


def test_a_run_recorded_with_sacs_injected_use_sde_false_is_the_same_run(tmp_path: Path) -> None:
    """Runs made before train_run deep-copied its hyperparameters recorded ``use_sde: false`` (SB3's
    default, written by SAC into shared ``policy_kwargs``); a rerun without it resumes them, while a
    recorded ``use_sde: true`` is a different run."""
    hp = {"n_timesteps": 10, "policy_kwargs": {"net_arch": [8]}}
    identity = train.run_identity(ENV, {}, {}, "sac", 1, hp)
    (tmp_path / "model.zip").write_bytes(b"")
    for use_sde, conflict in ((False, False), (True, True)):
        old = train.run_identity(
            ENV, {}, {}, "sac", 1, {**hp, "policy_kwargs": {"net_arch": [8], "use_sde": use_sde}}
        )
        (tmp_path / "config.yml").write_text(yaml.safe_dump(old))
        message = run_conflict(tmp_path, identity)
        assert (message is not None) == conflict, message
        if conflict:
            assert "config.yml differs in hyperparams" in str(message)


OPEN_LOOP_BAD = [
    (["--env", "dipenv/Unknown-v0"], "--env must be one of dipenv/FieldMagnitude-v0, "),  # was a traceback
    (["--env", "CartPole-v1"], "--env must be one of dipenv/FieldMagnitude-v0, "),  # a foreign env
    (["--workers", "0"], "argument --workers: must be an integer >= 1, got '0'"),
    (["--scheduler", "nowhere"], "argument --scheduler: must be a Dask scheduler address"),
    (["--env-kwargs", '{"bogus": 1}'], '--env-kwargs {"bogus": 1}: '),
    (["--env-kwargs", '{"mason_min": -1}'], '--env-kwargs {"mason_min": -1}: '),
    (["--out", ""], "argument --out: must name a directory, got ''"),
    (["--directions", "x"], "--directions is for the vector-field envs; --env dipenv/FieldMagnitudeTiny-v0"),
    (["--mason", "1,off,1.0"], "--mason lists Mn1 twice in '1,off,1.0' (each point once)"),
    (["--mason", "off,inf"], "--mason lists off twice"),
    (["--episodes", "0"], "--episodes must be in [1, 2] for --split test, got 0"),
]


@pytest.mark.parametrize(("arguments", "needle"), OPEN_LOOP_BAD, ids=[" ".join(a) for a, _ in OPEN_LOOP_BAD])
def test_open_loop_refuses_before_any_set_up(
    arguments: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    err = refused(capsys, open_loop, ["--env", ENV, "--out", str(out), *arguments])
    assert needle in err, err
    assert not out.exists()


def test_open_loop_refuses_an_out_below_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    afile = tmp_path / "notes.txt"
    afile.write_text("keep\n")
    err = refused(capsys, open_loop, ["--env", ENV, "--out", str(afile / "sub")])
    assert f"--out {afile / 'sub'} cannot be created: {afile} is not a directory" in err


def test_open_loop_refuses_a_repeated_direction(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(
        capsys,
        open_loop,
        ["--env", "dipenv/FieldVectorTiny-v0", "--out", str(tmp_path / "o"), "--directions", "x,y,x"],
    )
    assert "--directions lists a direction twice: 'x,y,x'" in err


DEMO_BAD = [
    (["--seeds", "5-2"], "argument --seeds: seeds must look like 0-4 or 0,2,5-7 (non-negative), got '5-2'"),
    (["--timesteps", "0"], "argument --timesteps: must be an integer >= 1, got '0'"),
    (["--out", ""], "argument --out: must name a directory, got ''"),
]


@pytest.mark.parametrize(("arguments", "needle"), DEMO_BAD, ids=[" ".join(a) for a, _ in DEMO_BAD])
def test_demo_checks_every_argument_before_any_stage(
    arguments: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--seeds 5-2`` was refused only after the open-loop stage had run, as agents.train's error."""
    out = tmp_path / "demo"
    with pytest.raises(SystemExit) as exit_:
        demo.main(["--out", str(out), *arguments])
    captured = capsys.readouterr()
    assert exit_.value.code == 2
    assert f"python -m agents.demo: error: {needle}" in captured.err, captured.err
    assert "open-loop" not in captured.out and not out.exists()


def test_demo_refuses_an_out_that_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    afile = tmp_path / "notes.txt"
    afile.write_text("keep\n")
    with pytest.raises(SystemExit) as exit_:
        demo.main(["--out", str(afile)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"python -m agents.demo: error: --out {afile} exists and is not a directory" in err


HYPERPARAMETER_FILES = [
    ("phi: [0.3\n", "cannot be read as YAML"),  # was a yaml traceback
    ("- 1\n", "must map env ids to hyperparameters"),  # was a TypeError
    (f"{ENV}: 3\n", f"the entry {ENV} must be a mapping of hyperparameters, got 3"),
    (f"{ENV}:\n  n_timesteps: 10\n", f"the entry {ENV} lacks n_envs, policy, normalize"),
    (
        f"{ENV}:\n  n_timesteps: 10\n  n_envs: 1\n  policy: MlpPolicy\n  normalize: true\n  eval_freq: 5\n"
        "  checkpoint_freq: 5\n  n_stepz: 8\n",
        f"entry {ENV}: unknown hyperparameter 'n_stepz' for ppo",  # was blamed on --env, or a traceback
    ),
]


@pytest.mark.parametrize(("text", "needle"), HYPERPARAMETER_FILES, ids=[n for _, n in HYPERPARAMETER_FILES])
def test_an_invalid_hyperparameter_file_is_named(
    text: str,
    needle: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    folder = tmp_path / "hyperparams"
    folder.mkdir()
    (folder / "ppo.yml").write_text(text)
    monkeypatch.setattr(train, "HYPERPARAMS_DIR", folder)
    err = refused(capsys, train, ["--env", ENV, "--out", str(tmp_path / "out")])
    assert f"error: hyperparameter file {folder / 'ppo.yml'}" in err and needle in err, err
    assert "--env" not in err


def test_the_packaged_hyperparameter_files_pass_the_checks() -> None:
    import dipenv

    for algo in train.ALGOS:
        for env_id in dipenv.ENV_IDS:
            train.load_hyperparams(algo, env_id)
