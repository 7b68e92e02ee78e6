"""Issue 45: what the agents commands and the scripts did silently wrong or let escape, each refused now
(exit 2 naming the argument or file) before any folder is written, and what a newcomer meets (the compile
note, the demo's folder identity and its learning curve's baselines). Nothing here simulates."""

from __future__ import annotations

import ast
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from agents_helpers import ENV, ROOT, TINY, load_script, refused

import sim
from agents import controllers, demo, evaluate, open_loop, train, usage
from sim.runs import claim

# -- silently wrong ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("module", "arguments"),
    [
        (controllers, ["--env", TINY, "--controller", "feedforward", "--env-kwargs", '{"eta_cap": -1}']),
        (controllers, ["--env", TINY, "--controller", "pi", "--env-kwargs", '{"eta_cap": 0}']),
        (open_loop, ["--env", TINY, "--mason", "off", "--env-kwargs", '{"eta_cap": -1}']),
        (open_loop, ["--env", ENV, "--mason", "off", "--env-kwargs", '{"target_viscosity": -1}']),
    ],
)
def test_a_negative_viscosity_cap_is_refused(
    module: Any, arguments: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: ``eta_cap = -1`` accepted by the controllers and open_loop (every interval "thickened")."""
    out = tmp_path / "out"
    err = refused(capsys, module.main, [*arguments, "--out", str(out)])
    name = "target_viscosity" if "target_viscosity" in arguments[-1] else "eta_cap"
    assert f"{name} must be" in err and "> 0" in err and "--env-kwargs" in err
    assert not out.exists()


def test_the_demo_refuses_other_timesteps_in_its_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """Was: ``agents.demo --timesteps 16`` into a demo folder of 2048 steps announced 16 steps and reused
    the 2048-step runs. The demo's manifest holds ``--timesteps`` and ``--seeds``."""
    out = tmp_path / "demo"
    identity = {"env_id": demo.ENV_ID, "mason": demo.MASON, "timesteps": 2048, "seeds": [0, 1]}
    claim(out, "agents.demo", identity)
    (out / "ppo").mkdir()
    err = refused(capsys, demo.main, ["--out", str(out), "--timesteps", "16"])
    assert f"--out {out} holds a run of agents.demo with other parameters: timesteps=2048 there" in err
    assert "timesteps=16 requested" in err and "--overwrite" in err
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "ppo"]


def test_paired_rows_refuses_negative_energies_and_infinite_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: a negative field energy printed an energy saving of "600%", an infinite one a finite gap."""
    paired_rows = load_script("paired_rows")

    def write(name: str, energy: Any, excess: Any = 0.1) -> Path:
        episode = {"split": "test", "index": 0, "failed": False, "return": -1.0}
        episode |= {"excess_viscosity": excess, "energy_mean": energy}
        path = tmp_path / name
        path.write_text(json.dumps({"episodes": [episode]}))
        return path

    good = write("good.json", 1.0)
    for name, energy, excess in (
        ("negative.json", -0.5, 0.1),
        ("infinite.json", "inf", 0.1),
        ("nan_excess.json", 1.0, "nan"),
        ("negative_excess.json", 1.0, -1.0),
    ):
        bad = write(name, energy, excess)
        err = refused(capsys, paired_rows.main, ["--a", str(bad), "--b", str(good)])
        assert f"--a: {bad}: state 0: " in err and "must be finite" in err, err
    assert paired_rows.main(["--a", str(good), "--b", str(good)]) == 0


def test_a_grid_parameter_given_twice_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Was: ``--grid mason_star=1 mason_star=2`` dropped the first value (and ``--grid a=1 --grid b=2`` the
    first option)."""
    with pytest.raises(ValueError, match="--grid lists mason_star twice"):
        controllers.parse_grid("feedforward", ["mason_star=1", "mason_star=2"], eta_cap=6.5)
    with pytest.raises(ValueError, match="--grid mason_star lists 1 twice"):
        controllers.parse_grid("feedforward", ["mason_star=1,2,1.0"], eta_cap=6.5)
    common = ["--env", TINY, "--controller", "feedforward", "--out", str(tmp_path / "ff")]
    assert "lists mason_star twice" in refused(
        capsys, controllers.main, [*common, "--grid", "mason_star=1", "mason_star=2"]
    )
    assert "lists mason_star twice" in refused(
        capsys, controllers.main, [*common, "--grid", "mason_star=1", "--grid", "mason_star=2"]
    )
    assert not (tmp_path / "ff").exists()


def test_a_negative_entropy_coefficient_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: ``ent_coef=-1`` accepted (a bonus for a collapsed policy)."""
    with pytest.raises(train.HyperparameterError, match=r"ent_coef must be a number in \[0.0, inf\]"):
        train.check_hyperparameters("ppo", {"ent_coef": -1.0}, "x")
    for bad in ("auto_-1", "auto_x", "manual"):
        with pytest.raises(train.HyperparameterError, match="'auto' or 'auto_X' with X > 0"):
            train.check_hyperparameters("sac", {"ent_coef": bad}, "x")
    for good in ("auto", "auto_0.1", 0.0, 0.05):
        train.check_hyperparameters("sac", {"ent_coef": good}, "x")
    with pytest.raises(train.HyperparameterError, match="ent_coef must be a number"):
        train.check_hyperparameters("ppo", {"ent_coef": "auto"}, "x")
    err = refused(
        capsys, train.main, ["--env", ENV, "--out", str(tmp_path / "o"), "--hyperparams", "ent_coef=-1"]
    )
    assert "--hyperparams: ent_coef must be a number in [0.0, inf], got -1" in err


# -- escapes -------------------------------------------------------------------------------------------------


def test_controllers_split_train_is_refused_by_the_parser(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """Was: ``--split train`` gave ``KeyError: 'train'`` (the training split has no fixed schedules)."""
    choices = {"--split": "'validation', 'test', 'fresh'", "--tune-split": "'validation', 'test'"}
    for option, allowed in choices.items():
        err = refused(
            capsys,
            controllers.main,
            ["--env", TINY, "--controller", "feedforward", "--out", str(tmp_path / "o"), option, "train"],
        )
        assert f"argument {option}: invalid choice: 'train' (choose from {allowed})" in err
    err = refused(  # nothing is tuned on the fresh split
        capsys,
        controllers.main,
        ["--env", TINY, "--controller", "feedforward", "--out", str(tmp_path / "o"), "--tune-split", "fresh"],
    )
    assert "argument --tune-split: invalid choice: 'fresh'" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("items", "needle"),
    [
        (["gamma=[0.9"], "--hyperparams 'gamma=[0.9': the value is not YAML"),
        (["policy_kwargs={net_arch: [-4]}"], "ppo cannot be built with these hyperparameters (RuntimeError"),
        (["policy_kwargs={bogus_argument: 1}"], "unexpected keyword argument 'bogus_argument'"),
        (["=1"], "--hyperparams takes key=value, got '=1' (no key)"),
    ],
)
def test_bad_hyperparameters_are_refused_before_the_folder(
    items: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: a yaml ``ParserError`` traceback, and a torch ``RuntimeError`` after the folder was written."""
    out = tmp_path / "out"
    err = refused(capsys, train.main, ["--env", ENV, "--out", str(out), "--hyperparams", *items])
    assert needle in err, err
    assert not out.exists()


def test_every_hyperparams_option_counts() -> None:
    """Was: a second ``--hyperparams`` option replaced the first one's keys (argparse's ``nargs="*"``)."""
    argv = ["--env", ENV, "--out", "x", "--hyperparams", "gamma=0.9", "--hyperparams", "n_epochs=2"]
    args = train.build_parser().parse_args(argv)
    assert train.parse_overrides(args.hyperparams) == {"gamma": 0.9, "n_epochs": 2}
    assert train.parse_overrides(["gamma=0.9", "gamma=0.8"]) == {"gamma": 0.8}  # the later one, as before


def _evaluation_log(path: Path, **arrays: Any) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "timesteps": np.array([64, 128]),
        "results": np.array([[-1.0, -2.0], [-0.5, -1.5]]),
        "ep_lengths": np.array([[3, 3], [3, 3]]),
    }
    np.savez(path, **{**data, **arrays})
    return path


def test_a_bad_evaluation_log_is_named(tmp_path: Path) -> None:
    """Was: ``BadZipFile`` from a truncated ``eval/evaluations.npz`` (agents.evaluate, --model best and the
    learning curve; agents.train's resume)."""
    from agents.folders import read_evaluation_log

    good = _evaluation_log(tmp_path / "good" / "evaluations.npz")
    assert read_evaluation_log(good)["timesteps"].tolist() == [64, 128]
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[:100])
    with pytest.raises(
        ValueError, match=rf"{truncated} cannot be read as an evaluation log \(.*truncated\?\)"
    ):
        read_evaluation_log(truncated)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip at all")
    with pytest.raises(ValueError, match=f"{garbage} cannot be read as an evaluation log"):
        read_evaluation_log(garbage)
    lacking = tmp_path / "lacking.npz"
    np.savez(lacking, timesteps=np.array([1]))
    with pytest.raises(ValueError, match="lacks results, ep_lengths"):
        read_evaluation_log(lacking)
    skewed = _evaluation_log(tmp_path / "skewed" / "evaluations.npz", timesteps=np.array([64]))
    with pytest.raises(ValueError, match="do not match"):
        read_evaluation_log(skewed)
    # agents.train refuses to resume from a run whose log is truncated, naming it
    run = tmp_path / "run"
    log = _evaluation_log(run / "eval" / "evaluations.npz")
    (run / "checkpoints").mkdir()
    with zipfile.ZipFile(run / "checkpoints" / "ckpt_64_steps.zip", "w") as model:  # a whole SB3 archive
        model.writestr("data", "{}")
    assert train.evaluation_log_problem(run) is None
    log.write_bytes(log.read_bytes()[:50])
    problem = train.evaluation_log_problem(run)
    assert problem is not None and str(log) in problem and "--overwrite" in problem


@pytest.mark.skipif(not Path("/sys").is_dir(), reason="no /sys")
@pytest.mark.parametrize("module", [open_loop, demo])
def test_an_out_under_sys_is_refused(module: Any, capsys: pytest.CaptureFixture[str]) -> None:
    """Was: a ``PermissionError`` traceback (after the start states were made, in open_loop), even for root,
    whom ``os.access`` lets write anywhere."""
    arguments = ["--out", "/sys/dipsim_probe/run"]
    if module is open_loop:
        arguments += ["--env", ENV, "--mason", "off", "--episodes", "1"]
    err = refused(capsys, module.main, arguments)
    assert "--out /sys/dipsim_probe/run" in err
    assert not Path("/sys/dipsim_probe").exists()


def _parsers(path: Path) -> list[ast.Call]:
    tree = ast.parse(path.read_text())
    return [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "ArgumentParser"
    ]


def test_every_parser_refuses_abbreviations(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Was: argparse's prefix matching (``--strain`` read as ``--strain-per-rate`` in sim; here ``--ou`` as
    ``--out``, ``--time`` as ``--timesteps``)."""
    files = sorted([*(ROOT / "agents").glob("*.py"), *(ROOT / "scripts").glob("*.py")])
    found = {path.name: _parsers(path) for path in files}
    assert sum(len(calls) for calls in found.values()) >= 20
    lacking = [
        name
        for name, calls in found.items()
        for call in calls
        if not any(
            k.arg == "allow_abbrev" and getattr(k.value, "value", None) is False for k in call.keywords
        )
    ]
    assert lacking == []
    err = refused(capsys, open_loop.main, ["--env", ENV, "--ou", str(tmp_path / "o")])
    assert "the following arguments are required: --out" in err or "unrecognized arguments: --ou" in err
    err = refused(capsys, demo.main, ["--out", str(tmp_path / "d"), "--time", "16"])
    assert "unrecognized arguments: --time" in err
    assert not (tmp_path / "d").exists()


# -- what a newcomer meets -----------------------------------------------------------------------------------


def test_the_compile_notice_is_sims(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Was: the agents commands compiled the kernels silently, for up to 3 minutes under a 0% bar. They
    print ``sim run``'s note through sim's public API (``COMPILE_NOTICE``, ``compiled_kernels_cached``)."""
    notice = "compiling kernels (first run only, about a minute)..."
    monkeypatch.setattr(sim, "COMPILE_NOTICE", notice, raising=False)
    monkeypatch.setattr(sim, "compiled_kernels_cached", lambda: False, raising=False)
    public = [*sim.__all__, "COMPILE_NOTICE", "compiled_kernels_cached"]
    monkeypatch.setattr(sim, "__all__", public)
    assert usage.compile_notice() is True and capsys.readouterr().err == notice + "\n"
    assert usage.compile_notice("tcp://host:8786") is False  # the Dask workers compile, not this process
    monkeypatch.setattr(sim, "compiled_kernels_cached", lambda: True, raising=False)
    assert usage.compile_notice() is False and capsys.readouterr().err == ""


def test_train_prints_the_compile_notice_before_training(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    notice = "compiling kernels (first run only, about a minute)..."
    monkeypatch.setattr(sim, "COMPILE_NOTICE", notice, raising=False)
    monkeypatch.setattr(sim, "compiled_kernels_cached", lambda: False, raising=False)
    monkeypatch.setattr(sim, "__all__", [*sim.__all__, "COMPILE_NOTICE", "compiled_kernels_cached"])
    order: list[str] = []

    def tasks(function: Any, payloads: list[dict[str, Any]], **_: Any) -> list[dict[str, Any]]:
        order.append("train")
        assert notice in capsys.readouterr().err  # printed before the first task
        return []

    monkeypatch.setattr(train, "run_tasks", tasks)
    train.main(["--env", ENV, "--out", str(tmp_path / "ppo"), "--timesteps", "64"])
    assert order == ["train"]


def test_the_demo_draws_its_learning_curve_over_validation_baselines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Was: learning.png drew the runs' validation returns above the best constant's test-state return
    (a win the table then denied). The demo makes an open-loop baseline on the validation states and
    passes it to the evaluation; without one, the test-state lines say so."""
    calls: dict[str, list[list[str]]] = {"open_loop": [], "train": [], "evaluate": []}
    for name, module in (("open_loop", open_loop), ("train", train), ("evaluate", evaluate)):
        monkeypatch.setattr(module, "main", lambda argv, name=name: calls[name].append(list(argv)))
    demo.main(["--out", str(tmp_path / "demo"), "--timesteps", "16", "--seeds", "0"])
    validation = [
        a for a in calls["open_loop"] if "--split" in a and a[a.index("--split") + 1] == "validation"
    ]
    assert len(validation) == 1
    folder = validation[0][validation[0].index("--out") + 1]
    (arguments,) = calls["evaluate"]
    assert arguments[arguments.index("--validation-baseline") + 1] == folder

    row = {"name": "best constant (Mn1)", "return": {"mean": -3.0}}
    assert evaluate.learning_lines([row], [("best constant (Mn1), validation states", -4.0)]) == [
        ("best constant (Mn1), validation states", -4.0)
    ]
    ((label, value),) = evaluate.learning_lines([row], [])
    assert value == -3.0 and "test states (not the curves' validation states)" in label


def test_the_printed_table_is_compact() -> None:
    """Was: the printed table had ~20 columns of ~600 characters per row; now policy, eta_r and return
    with their intervals, and the energy (the full table stays in table.md)."""

    def stats(mean: float) -> dict[str, float]:
        return {"mean": mean, "ci_low": mean - 0.1, "ci_high": mean + 0.1}

    rows = [
        {"name": "no field", "eta": stats(6.0), "energy": stats(0.0), "return": stats(-10.0)},
        {"name": "ppo (ppo)", "eta": stats(5.5), "energy": stats(0.4), "return": stats(-9.0)},
    ]
    table = evaluate.compact_table(rows)
    lines = table.splitlines()
    assert lines[0] == "| policy | eta_r, 2nd half [95% CI] | field energy | return [95% CI] |"
    assert lines[3] == "| ppo (ppo) | 5.500 [5.400, 5.600] | 0.400 | -9.00 [-9.10, -8.90] |"
    assert max(len(line) for line in lines) < 100
