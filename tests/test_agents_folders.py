"""Issue 45's run-folder protocol in the agents commands and the scripts (agents.folders over sim.runs):
each command claims its output folder with a manifest written first, refuses another command's folder or
its own with other parameters (exit 2 naming the folder) instead of writing into it, continues a rerun of
the same identity, adopts the folders it wrote before manifests (the committed results) and only those,
and ``--overwrite`` deletes the whole previous run."""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
from pathlib import Path
from typing import Any

import pytest
from agents_helpers import ENV, ROOT, TINY, load_script, refused

from agents import controllers, evaluate, open_loop, train
from sim.runs import MANIFEST, claim, read_manifest

SHORT = ["n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32"]
TRAIN = ["--env", ENV, "--n-envs", "1", "--no-progress", "--algo", "ppo", "--timesteps", "64"]


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` with its contents."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A two-point open-loop baseline on one test state, a 64-step PPO run (``--seed 0``) and an
    evaluation of it, all in the tiny env."""
    root = tmp_path_factory.mktemp("agents_folders")
    baseline, run, evaluation = root / "open_loop", root / "ppo", root / "evaluation"
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1", "--episodes", "1"])
    train.main([*TRAIN, "--seed", "0", "--out", str(run), "--hyperparams", *SHORT])
    evaluate.main([str(run), "--baseline", str(baseline), "--out", str(evaluation)])
    return {"baseline": baseline, "run": run, "evaluation": evaluation}


def test_every_folder_holds_its_manifest(made: dict[str, Path]) -> None:
    for name, command in (
        ("baseline", "agents.open_loop"),
        ("run", "agents.train"),
        ("evaluation", "agents.evaluate"),
    ):
        manifest = read_manifest(made[name])
        assert manifest is not None and manifest.command == command, name
    assert read_manifest(made["baseline"]).params == {  # type: ignore[union-attr]
        "env_id": ENV,
        "env_kwargs": {},
        "split": "test",
        "episodes": 1,
    }
    params = read_manifest(made["run"]).params  # type: ignore[union-attr]
    assert params["seed"] == 0 and params["n_timesteps"] == 64 and params["gamma"] == 0.9
    assert not list(made["baseline"].rglob("*.tmp"))  # atomic writes leave no temporaries behind


def test_train_refuses_a_sim_run_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Was: ``agents.train --out`` into a ``sim run`` folder replaced its ``result.json``."""
    legacy = tmp_path / "legacy_run"  # made before manifests
    legacy.mkdir()
    for name in ("result.json", "params.json", "checkpoint.npz"):
        (legacy / name).write_text(f"{name} of sim run\n")
    owned = tmp_path / "owned_run"
    claim(owned, "sim run", {"mason_number": math.inf})
    (owned / "result.json").write_text("{}\n")
    for folder, needle in (
        (legacy, "holds no manifest.json"),
        (owned, "belongs to another command ('sim run'"),
    ):
        before = snapshot(folder)
        err = refused(capsys, train.main, [*TRAIN, "--out", str(folder), "--hyperparams", *SHORT])
        assert f"--out {folder}" in err and needle in err, err
        assert snapshot(folder) == before


def test_commands_refuse_one_anothers_folders(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: open_loop, train and evaluate into one another's folders overwrote ``command.txt`` (and
    ``pareto.png``); the controllers dropped their point into an open-loop folder's ``points/``."""
    folders = {name: tmp_path / name for name in made}
    for name, folder in folders.items():
        shutil.copytree(made[name], folder)
    before = {name: snapshot(folder) for name, folder in folders.items()}
    attempts = {
        "baseline": [
            (train.main, [*TRAIN, "--hyperparams", *SHORT]),
            (evaluate.main, [str(made["run"]), "--baseline", str(made["baseline"])]),
            (controllers.main, ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1"]),
        ],
        "run": [
            (open_loop.main, ["--env", ENV, "--mason", "off,1", "--episodes", "1"]),
            (evaluate.main, [str(made["run"]), "--baseline", str(made["baseline"])]),
        ],
        "evaluation": [
            (open_loop.main, ["--env", ENV, "--mason", "off,1", "--episodes", "1"]),
            (train.main, [*TRAIN, "--hyperparams", *SHORT]),
        ],
    }
    for name, calls in attempts.items():
        owner = read_manifest(folders[name]).command  # type: ignore[union-attr]
        for main, arguments in calls:
            err = refused(capsys, main, [*arguments, "--out", str(folders[name])])
            assert f"--out {folders[name]} belongs to another command ('{owner}'" in err, err
            assert "--overwrite" in err
    assert {name: snapshot(folder) for name, folder in folders.items()} == before


def test_a_rerun_with_other_parameters_is_refused_and_the_same_continues(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    baseline = tmp_path / "open_loop"
    shutil.copytree(made["baseline"], baseline)
    before = snapshot(baseline)
    err = refused(
        capsys, open_loop.main, ["--env", ENV, "--out", str(baseline), "--mason", "off", "--episodes", "2"]
    )
    assert (
        "holds a run of agents.open_loop with other parameters: episodes=1 there, episodes=2 requested" in err
    )
    assert snapshot(baseline) == before
    stamp = (baseline / "points" / "Mn1.json").stat().st_mtime_ns
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "1", "--episodes", "1", "--resume"])
    assert (baseline / "points" / "Mn1.json").stat().st_mtime_ns == stamp  # continued: nothing replayed
    err = refused(capsys, open_loop.main, ["--env", ENV, "--out", str(tmp_path / "new"), "--resume"])
    assert "--resume: --out" in err and "holds no run to continue" in err
    # training: a longer run continues, a shorter one is refused
    identity = {"n_timesteps": 64, "gamma": 0.9, "seed": 0}
    assert train.compare_identities(identity, {**identity, "n_timesteps": 128}) == []
    assert train.compare_identities(identity, {**identity, "n_timesteps": 16}) == ["n_timesteps"]
    assert train.compare_identities(identity, {**identity, "gamma": 0.8}) == ["gamma"]
    run = tmp_path / "ppo"
    shutil.copytree(made["run"], run)
    err = refused(
        capsys, train.main, [*TRAIN[:-1], "16", "--seed", "0", "--out", str(run), "--hyperparams", *SHORT]
    )
    assert "holds a run of 64 steps, longer than the 16 requested" in err
    # evaluate: other arguments in the same folder are refused; the same spelled otherwise continue
    evaluation = tmp_path / "evaluation"
    shutil.copytree(made["evaluation"], evaluation)
    err = refused(
        capsys,
        evaluate.main,
        [str(made["run"]), "--baseline", str(made["baseline"]), "--out", str(evaluation), "--repeats", "2"],
    )
    assert "policy_repeats=1, repeats=1 there, policy_repeats=2, repeats=2 requested" in err
    from agents.folders import compare_paths

    same = compare_paths(evaluate.PATH_KEYS)
    saved = {"runs": ["results/x/ppo"], "baseline": "results/x/open_loop", "repeats": 1}
    assert same(saved, {**saved, "runs": [str(Path("results/x/ppo/").absolute())]}) == []
    assert same(saved, {**saved, "baseline": "results/y/open_loop"}) == ["baseline"]


def test_overwrite_deletes_the_whole_previous_run(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "evaluation"
    shutil.copytree(made["evaluation"], folder)
    open_loop.main(["--env", ENV, "--out", str(folder), "--mason", "off", "--episodes", "1", "--overwrite"])
    assert read_manifest(folder).command == "agents.open_loop"  # type: ignore[union-attr]
    assert not (folder / "runs").exists() and not (folder / "verdict.md").exists()
    assert sorted(p.name for p in (folder / "points").iterdir()) == ["off.json"]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("precious")
    err = refused(capsys, open_loop.main, ["--env", ENV, "--out", str(mine), "--mason", "off", "--overwrite"])
    assert "holds no manifest.json" in err and (mine / "thesis.tex").read_text() == "precious"
    err = refused(capsys, open_loop.main, ["--env", ENV, "--out", str(mine), "--resume", "--overwrite"])
    assert "not allowed with argument" in err


def test_evaluate_refuses_a_polluted_baseline(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: a controller's point dropped into an open-loop folder's ``points/`` was read as a constant
    field ("on the constant-field front"). The baseline must be an open-loop folder (its manifest, or before
    manifests its files) of constant-field points only."""
    polluted = tmp_path / "legacy_baseline"
    shutil.copytree(made["baseline"], polluted)
    (polluted / MANIFEST).unlink()  # a baseline made before manifests
    point = json.loads((polluted / "points" / "Mn1.json").read_text())
    stray = polluted / "points" / "pi_kp2_ki0.5_setpoint6.json"
    stray.write_text(json.dumps({**point, "controller": "pi", "mason_number": "nan", "label": stray.stem}))
    arguments = [str(made["run"]), "--out", str(tmp_path / "evaluation"), "--baseline"]
    err = refused(capsys, evaluate.main, [*arguments, str(polluted)])
    assert f"{stray} is the pi controller's point, not a constant field's" in err, err
    stray.unlink()
    (polluted / "command.txt").write_text("python -m agents.controllers --controller pi --out x\n")
    err = refused(capsys, evaluate.main, [*arguments, str(polluted)])
    assert "its command.txt is not an agents.open_loop command" in err
    owned = tmp_path / "owned"
    shutil.copytree(made["baseline"], owned)
    manifest = json.loads((owned / MANIFEST).read_text())
    (owned / MANIFEST).write_text(json.dumps({**manifest, "command": "agents.controllers"}))
    err = refused(capsys, evaluate.main, [*arguments, str(owned)])
    assert f"--baseline {owned} was made by agents.controllers, not agents.open_loop" in err
    err = refused(
        capsys,
        evaluate.main,
        [
            "--controllers",
            str(made["baseline"]),
            "--baseline",
            str(made["baseline"]),
            "--out",
            str(tmp_path / "e"),
        ],
    )
    assert f"--controllers: {made['baseline']} was made by agents.open_loop" in err
    assert not (tmp_path / "evaluation").exists() and not (tmp_path / "e").exists()


def test_evaluate_names_a_truncated_evaluation_log(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: ``BadZipFile`` (after every episode was played, when learning.png was drawn)."""
    run = tmp_path / "ppo"
    shutil.copytree(made["run"], run)
    log = run / "eval" / "evaluations.npz"
    log.write_bytes(log.read_bytes()[:60])
    out = tmp_path / "evaluation"
    err = refused(capsys, evaluate.main, [str(run), "--baseline", str(made["baseline"]), "--out", str(out)])
    assert f"RUN_DIRS: {log} cannot be read as an evaluation log" in err and "truncated?" in err
    assert not out.exists()


def test_a_controllers_rerun_with_another_grid_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: a rerun with another ``--grid`` silently replaced ``controller.json`` and ``tuning.csv``. Now
    refused (exit 2), also in a folder made before manifests, unless ``--overwrite``."""
    out = tmp_path / "ff"
    common = ["--env", TINY, "--controller", "feedforward", "--tune-episodes", "1", "--episodes", "1"]
    common += ["--out", str(out)]
    controllers.main([*common, "--grid", "mason_star=1"])
    before = snapshot(out)
    err = refused(capsys, controllers.main, [*common, "--grid", "mason_star=2"])
    assert "with other parameters: grid={'mason_star': [1.0]} there" in err and "--overwrite" in err
    (out / MANIFEST).unlink()  # as before manifests
    err = refused(capsys, controllers.main, [*common, "--grid", "mason_star=2"])
    assert f"{out} holds a run made with other parameters (controller.json records grid" in err
    assert {k: v for k, v in snapshot(out).items() if k != MANIFEST} == {
        k: v for k, v in before.items() if k != MANIFEST
    }
    summary = controllers.main([*common, "--grid", "mason_star=2", "--overwrite"])
    assert summary["grid"] == {"mason_star": [2.0]}
    assert [p.name for p in (out / "tuning").iterdir()] == ["feedforward_mason_star2.json"]


# -- folders made before manifests (the committed results) ---------------------------------------------------

V1 = ROOT / "results" / "thickening_control" / "v1"
V2 = ROOT / "results" / "thickening_control" / "v2"


def legacy_markers(*args: Any, **kwargs: Any) -> list[str]:
    from agents.folders import legacy_markers

    return legacy_markers(*args, **kwargs)


MARKERS = {
    "agents.open_loop": lambda folder: legacy_markers(folder, open_loop.LEGACY, "agents.open_loop"),
    "agents.controllers": lambda folder: legacy_markers(folder, controllers.LEGACY, "agents.controllers"),
    "agents.evaluate": lambda folder: legacy_markers(folder, evaluate.LEGACY, "agents.evaluate"),
    "agents.train": lambda folder: legacy_markers(folder, train.RUN_LEGACY),
}
COMMITTED = [
    (V1 / "open_loop", "agents.open_loop"),
    (V1 / "open_loop_validation", "agents.open_loop"),
    (ROOT / "results" / "open_loop" / "FieldMagnitude-v0", "agents.open_loop"),
    (V2 / "pulse", "agents.controllers"),
    (V2 / "feedforward", "agents.controllers"),
    (V2 / "pi_stress_only", "agents.controllers"),
    (V2 / "evaluation_final", "agents.evaluate"),
    (V2 / "evaluation_final_sac_sampled", "agents.evaluate"),
    (ROOT / "results" / "ppo" / "FieldMagnitude-v0" / "evaluation", "agents.evaluate"),
    (V2 / "rl" / "ppo" / "seed0", "agents.train"),
    (V2 / "rl" / "sac" / "seed3", "agents.train"),
]


@pytest.mark.parametrize(("folder", "command"), COMMITTED, ids=[f"{c}:{f.name}" for f, c in COMMITTED])
def test_committed_folders_are_adopted_by_their_own_command_only(folder: Path, command: str, tmp_path: Path):
    """The results committed before manifests still resume (``scripts/thickening_evaluation.sh`` reruns
    evaluation_final): their command finds its own files in them, no other command does. A copy of the
    folder's top-level files is adopted by a claim, which adds the manifest and keeps every file."""
    assert folder.is_dir() and not (folder / MANIFEST).exists()
    for other, markers in MARKERS.items():
        found = [name for name in markers(folder) if (folder / name).exists()]
        assert bool(found) == (other == command), (other, found)
    copy = tmp_path / folder.name
    copy.mkdir()
    for path in folder.iterdir():
        if path.is_file():
            shutil.copy2(path, copy / path.name)
    before = snapshot(copy)
    result = claim(copy, command, {"any": "identity"}, legacy=MARKERS[command](copy))
    assert result.state == "adopted"
    assert {k: v for k, v in snapshot(copy).items() if k != MANIFEST} == before


def test_committed_studies_pass_their_commands_own_checks() -> None:
    """The checks that run before a pre-manifest folder is adopted accept the committed folders with the
    parameters they were made with: the v1 baseline's points (ThickeningControl-v1, 16 test states), the
    v2 training runs' config.yml (the study's command) and the seed folders of a ``--seeds`` study."""
    identity = open_loop.folder_identity("dipenv/ThickeningControl-v1", {}, "test", 16)
    assert open_loop.legacy_problem(V1 / "open_loop", identity) is None
    other = open_loop.folder_identity("dipenv/ThickeningControl-v1", {}, "test", 8)
    assert "episodes: 16 there, 8 requested" in str(open_loop.legacy_problem(V1 / "open_loop", other))
    summary = json.loads((V2 / "pulse" / "controller.json").read_text())
    identity = controllers.folder_identity(
        summary["env_id"],
        summary["env_kwargs"],
        "pulse",
        summary["grid"],
        {"tune_split": "validation", "tune_episodes": 8, "split": "test", "episodes": 16},
    )
    assert controllers.legacy_problem(V2 / "pulse", identity) is None
    grid = {**summary["grid"], "rate_on": [9.0]}
    changed = controllers.folder_identity(summary["env_id"], summary["env_kwargs"], "pulse", grid, {})
    assert "controller.json records grid" in str(controllers.legacy_problem(V2 / "pulse", changed))
    study = V2 / "rl" / "ppo"
    assert sorted(p.parent.name for p in study.glob("seed*/config.yml")) == [f"seed{k}" for k in range(5)]
    import yaml

    config = yaml.safe_load((study / "seed0" / "config.yml").read_text())
    identity = train.run_identity(
        config["env_id"], config["env_kwargs"], config["env_settings"], "ppo", 0, config["hyperparams"]
    )
    assert train.run_conflict(study / "seed0", identity) is None
    shorter = {**config["hyperparams"], "n_timesteps": 10}
    conflict = train.run_conflict(
        study / "seed0",
        train.run_identity(config["env_id"], config["env_kwargs"], config["env_settings"], "ppo", 0, shorter),
    )
    assert conflict is not None and "longer than the 10 requested" in conflict


# -- scripts -------------------------------------------------------------------------------------------------


def test_pulse_train_refuses_another_rate_in_its_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: a rerun with another ``--rate`` replaced the stored episodes of the first one."""
    pulse_train = load_script("pulse_train")
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    setup = {"env": "dipenv/ThickeningControl-v2", "rate": 4.0, "intervals": 16}
    (legacy / "episodes.json").write_text(json.dumps({"steady:0.2/0": {"setup": setup, "eta_r": [1.0]}}))
    before = snapshot(legacy)
    err = refused(capsys, pulse_train.main, ["--out", str(legacy), "--rate", "2"])
    assert f"--out {legacy} holds episodes of another setup" in err and "'rate': 4.0" in err
    assert snapshot(legacy) == before
    owned = tmp_path / "owned"
    claim(owned, "scripts/pulse_train.py", setup)
    err = refused(capsys, pulse_train.main, ["--out", str(owned), "--rate", "2"])
    assert "rate=4.0 there, rate=2.0 requested" in err
    err = refused(
        capsys, pulse_train.main, ["--out", str(tmp_path / "x"), "--env", "dipenv/FieldMagnitude-v0"]
    )
    assert "--env must be a thickening-control environment" in err and not (tmp_path / "x").exists()


def test_report_scripts_write_beside_their_sweep_or_into_a_folder_of_their_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from agents.folders import report_folder

    parser = argparse.ArgumentParser(prog="report", allow_abbrev=False)
    sweep = tmp_path / "runs" / "sweep"
    claim(sweep, "sim sweep", {"phi": [0.45]})
    # the default: beside the sweep's points, the sweep's folder not claimed
    assert report_folder(parser, sweep, None, "report.py", ("values.md",), argv=[]) == sweep
    assert read_manifest(sweep).command == "sim sweep"  # type: ignore[union-attr]
    # a folder of its own: claimed with the sweep as identity; another sweep's report is refused there
    out = tmp_path / "reports"
    assert report_folder(parser, sweep, out, "report.py", ("values.md",), argv=[]) == out
    assert read_manifest(out).command == "scripts/report.py"  # type: ignore[union-attr]
    assert report_folder(parser, Path(os.path.relpath(sweep)), out, "report.py", (), argv=[]) == out
    err = refused(
        capsys, lambda a: report_folder(parser, tmp_path / "other", out, "report.py", (), argv=a), []
    )
    assert "with other parameters: source=" in err
    # another command's folder, and a copy of a sweep made before manifests, are not a report's folder
    err = refused(capsys, lambda a: report_folder(parser, out, sweep, "report.py", (), argv=a), [])
    assert "belongs to another command ('sim sweep'" in err
    copy = tmp_path / "copy"
    copy.mkdir()
    for name in ("sweep.json", "values.md"):
        (copy / name).write_text("{}")
    err = refused(
        capsys, lambda a: report_folder(parser, sweep, copy, "report.py", ("values.md",), argv=a), []
    )
    assert "holds no manifest.json" in err


def test_collect_training_runs_claims_its_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    collect = load_script("collect_training_runs")
    study, evaluation = tmp_path / "study", tmp_path / "evaluation"
    (study / "seed0").mkdir(parents=True)
    (study / "seed0" / "model.zip").write_bytes(b"")
    evaluation.mkdir()
    for name in collect.EVALUATION_FILES:
        (evaluation / name).write_text(name)
    out = tmp_path / "open_loop"
    claim(out, "agents.open_loop", {"env_id": ENV})
    before = snapshot(out)
    err = refused(capsys, collect.main, [str(study), str(evaluation), "--out", str(out)])
    assert "belongs to another command ('agents.open_loop'" in err and snapshot(out) == before
    (evaluation / "table.md").unlink()
    err = refused(capsys, collect.main, [str(study), str(evaluation), "--out", str(tmp_path / "new")])
    assert "is no finished agents.evaluate folder: it lacks" in err and not (tmp_path / "new").exists()


def test_delta_dependence_claims_its_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    delta = load_script("delta_dependence")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    err = refused(capsys, delta.cli, [str(mine)])
    assert f"OUT {mine} is not empty (notes.txt) and holds no manifest.json" in err


def test_atomic_writes_keep_the_old_file_when_writing_fails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    from agents.folders import write_text_atomic

    path = tmp_path / "command.txt"
    path.write_text("old\n")

    def failing(source: str, target: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(OSError, match="disk full"):
        write_text_atomic(path, "new\n")
    assert path.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["command.txt"]
