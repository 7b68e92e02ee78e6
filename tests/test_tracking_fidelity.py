"""The tracking baselines in the surrogate fidelity (issue 44): ``python -m agents.tracking`` on
``dipenv/ViscosityTrackingSurrogate-v0`` with a tiny direction-aware model (the tiny id's settings through
``--env-kwargs``), the surrogate's realisations, and ``scripts/tracking_fidelity.py`` on hand-made folders
(the numbers by hand, the refusals) and on a real surrogate folder. No simulator episode is played: the
simulator's folders are made by hand."""

from __future__ import annotations

import csv
import io
import json
import math
import shutil
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
import yaml
from agents_helpers import load_script, refused
from test_tracking_surrogate import TINY, TINY_SETTINGS, random_direction_model, tiny_surrogate

import agents.statistics
from agents import train
from agents.open_loop import read_json
from agents.rollout import make_env
from agents.tracking import main
from agents.tracking_controllers import AnglePIController, play_episode
from dipenv.surrogate import load_model, surrogate_kwargs

SURROGATE = "dipenv/ViscosityTrackingSurrogate-v0"
GRID = ["--grid", "mason_ref=1,inf", "direction=y,z", "kp=1,3", "ki=0.3", "mason_star=1"]
"""Five tuning points: the constant along y and z at Mn_ref 1 and off (one point), two angle PIs."""
EPISODES = ["--tune-split", "validation", "--split", "validation", "--no-progress"]
REALISATIONS = ["--tune-realisations", "2", "--realisations", "2"]
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=1", "eval_freq=32", "checkpoint_freq=32"]


def fidelity() -> ModuleType:
    return load_script("tracking_fidelity", cached=True)


def tiny_kwargs(model: Path | str, **extra: Any) -> dict[str, Any]:
    """``--env-kwargs`` that give the surrogate id the tiny id's settings (JSON-ready) and ``model``."""
    return json.loads(json.dumps(surrogate_kwargs(TINY, model=str(model), **extra)))


def command(model: Path | str, out: Path, *extra: str) -> list[str]:
    return [
        "--env",
        SURROGATE,
        "--env-kwargs",
        json.dumps(tiny_kwargs(model)),
        "--controller",
        "constant",
        "angle_pi",
        *GRID,
        *EPISODES,
        *REALISATIONS,
        *extra,
        "--out",
        str(out),
    ]


@pytest.fixture(scope="module", autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """An empty start-state cache (the surrogate must not touch it) and a cheaper bootstrap."""
    cache = tmp_path_factory.mktemp("dipenv_cache_fidelity")
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(cache))
    patcher.setattr(agents.statistics, "BOOTSTRAP_REPS", 200)
    yield cache
    patcher.undo()


@pytest.fixture(scope="module")
def model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("models") / "tiny_tracking.npz"
    random_direction_model(TINY_SETTINGS).save(path)
    return path


@pytest.fixture(scope="module")
def made(model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The constant and the angle PI tuned and played on the 2 validation states, 2 samples each."""
    out = tmp_path_factory.mktemp("tracking_surrogate") / "validation_surrogate"
    main(command(model, out))
    return out


# -- agents.tracking on the surrogate id ---------------------------------------------------------------------
def test_tracking_tunes_and_plays_the_baselines_on_the_surrogate(
    made: Path, model: Path, state_cache: Path
) -> None:
    manifest = json.loads((made / "manifest.json").read_text())
    params = manifest["params"]
    assert params["env_id"] == SURROGATE and params["library_key"] is None
    digest = make_env(SURROGATE, tiny_kwargs(model)).unwrapped.settings()["surrogate"]["digest"]
    assert params["surrogate"] == {"kind": "ensemble", "digest": digest} and len(digest) == 16
    assert not any(state_cache.iterdir())  # no start state pre-sheared: the surrogate has no library
    assert len(list((made / "tuning").glob("*.json"))) == 5
    tuning = list(csv.DictReader(io.StringIO((made / "tuning.csv").read_text())))
    assert sorted(r["controller"] for r in tuning if r["chosen"] == "yes") == ["angle_pi", "constant"]
    for kind in ("constant", "angle_pi"):
        record = read_json(made / "points" / f"{kind}.json")
        keys = [(e["split"], e["index"], e["realisation"]) for e in record["episodes"]]
        assert keys == [("validation", i, k) for i in (0, 1) for k in (0, 1)]
        returns = {(e["index"], e["realisation"]): e["return"] for e in record["episodes"]}
        assert returns[0, 0] != returns[0, 1] and returns[1, 0] != returns[1, 1]  # two samples per state
    # the angle PI's episodes replayed by hand on the env: realisation k is that reset option at seed 0
    record = read_json(made / "tuning" / "angle_pi_ki0.3_kp3_mason_star1.json")
    env = tiny_surrogate(load_model(model))
    controller = AnglePIController(3.0, 0.3, 1.0).bind(env)
    for episode in record["episodes"]:
        by_hand = play_episode(env, controller, "validation", episode["index"], episode["realisation"])
        assert by_hand["eta_r"] == episode["eta_r"] and by_hand["return"] == episode["return"]
    assert "ViscosityTrackingSurrogate-v0" in (made / "table.md").read_text()


def test_same_command_same_numbers_and_a_rerun_plays_nothing(
    made: Path, model: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    again = tmp_path / "again"
    main(command(model, again))
    assert (again / "tuning.csv").read_text() == (made / "tuning.csv").read_text()
    for path in sorted((made / "points").glob("*.json")):
        assert read_json(again / "points" / path.name)["episodes"] == read_json(path)["episodes"]
    import agents.tracking_rows as rows

    monkeypatch.setattr(rows, "play_episode", lambda *a, **k: pytest.fail("played an episode"))
    main(command(model, again))  # resumes: everything is there


def test_the_identity_follows_the_model_file_not_its_name(
    made: Path, model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    own = tmp_path / "model.npz"
    shutil.copyfile(model, own)
    out = tmp_path / "out"
    main(command(own, out, "--tune-episodes", "1", "--episodes", "1", "--realisations", "1"))
    before = json.loads((out / "manifest.json").read_text())["params"]
    assert before["surrogate"] == read_json(made / "manifest.json")["params"]["surrogate"]  # same contents
    random_direction_model(TINY_SETTINGS, seed=1).save(own)  # refitted in place: same path, other contents
    err = refused(capsys, main, command(own, out, "--tune-episodes", "1", "--episodes", "1"))
    assert "surrogate" in err
    main(command(own, out, "--tune-episodes", "1", "--episodes", "1", "--overwrite"))
    after = json.loads((out / "manifest.json").read_text())["params"]
    assert after["surrogate"]["digest"] != before["surrogate"]["digest"]
    assert {k: v for k, v in after.items() if k != "surrogate"} == {
        k: v for k, v in before.items() if k != "surrogate"
    }


def test_the_fresh_split_stays_refused_and_bad_input_exits_2(
    model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    err = refused(capsys, main, [*command(model, out)[:-2], "--split", "fresh", "--out", str(out)])
    assert "--final-evaluation" in err and not out.exists()
    # with it, the surrogate plays the simulator env's fresh episode: its target's interval means
    fresh = [*command(model, out)[:-2], "--split", "fresh", "--final-evaluation", "--episodes", "1"]
    main([*fresh, "--tune-episodes", "1", "--realisations", "1", "--out", str(out)])
    played = read_json(out / "points" / "angle_pi.json")["episodes"]
    simulator = make_env(TINY, {"progress": False}).unwrapped
    target, dt = simulator.fixed_target("fresh", 0), simulator.control_interval
    assert [(e["split"], e["index"]) for e in played] == [("fresh", 0)]
    expected = [target.mean(k * dt, (k + 1) * dt) for k in range(10)]
    assert played[0]["target_eta_r"] == pytest.approx(expected, rel=1e-12)
    simulator.close()
    err = refused(
        capsys,
        main,
        ["--env", "dipenv/ThickeningControlSurrogate-v0", "--controller", "constant"] + ["--out", str(out)],
    )
    assert "ViscosityTrackingSurrogate-v0" in err  # the list of ids names it
    err = refused(capsys, main, [*command(model, out)[:-2], "--episodes", "3", "--out", str(out)])
    assert "--episodes must be in [1, 2]" in err


def test_surrogate_realisations_are_independent_samples_and_realisation_0_is_unchanged(model: Path) -> None:
    env = tiny_surrogate(load_model(model))
    controller = AnglePIController(1.0, 0.3, 1.0).bind(env)

    def episode(realisation: int, index: int = 1) -> dict[str, Any]:
        return play_episode(env, controller, "validation", index, realisation)

    # realisation 0 given or not (play_episode leaves it out) is the env's draws at the seed, as before
    # (the bit identity of a whole surrogate episode: tests/test_surrogate.py, tests/surrogate_reference.py)
    assert episode(0)["eta_r"] == eta_trace(
        env, controller, 0, {"split": "validation", "index": 1, "realisation": 0}
    )
    samples = [episode(k)["eta_r"] for k in range(3)]
    assert samples[0] != samples[1] != samples[2] != samples[0]
    assert episode(2)["eta_r"] == samples[2]  # reproducible
    assert episode(1, index=0)["eta_r"] != samples[1]  # per state
    infos = [
        env.reset(seed=0, options={"split": "validation", "index": 1, "realisation": k})[1] for k in (0, 5)
    ]
    for key in ("schedule", "target", "index"):
        assert infos[0][key] == infos[1][key]  # the episode is the same; only the model's sample differs
    assert infos[1]["realisation"] == 5
    by_seed = [episode_at(env, controller, seed) for seed in (0, 7, 7)]
    assert by_seed[0] != by_seed[1] == by_seed[2]  # the seed still decides the sample


def episode_at(env: Any, controller: Any, seed: int) -> list[float]:
    """eta_r of validation state 1, realisation 1, at ``seed`` under ``controller``."""
    return eta_trace(env, controller, seed, {"split": "validation", "index": 1, "realisation": 1})


def eta_trace(env: Any, controller: Any, seed: int, options: dict[str, Any]) -> list[float]:
    """eta_r of one episode reset with ``seed`` and ``options`` under ``controller`` (reset first)."""
    obs, _ = env.reset(seed=seed, options=options)
    controller.reset()
    out, done = [], False
    while not done:
        obs, _, terminated, truncated, info = env.step(controller(obs))
        out.append(info["eta_r"])
        done = terminated or truncated
    return out


def test_a_run_trained_on_the_surrogate_plays_there(
    made: Path, model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Trained on the surrogate with history 1; played with --env naming the same file by another path
    (the physics check compares the model's contents) and without the history (only the observation
    differs); refused on a model of other contents."""
    ppo = tmp_path / "ppo"
    kwargs = tiny_kwargs(model, history_length=1)
    train.main(
        ["--env", SURROGATE, "--env-kwargs", json.dumps(kwargs), "--timesteps", "32", "--n-envs", "1"]
        + ["--no-progress", "--algo", "ppo", "--seeds", "0", "--out", str(ppo), "--hyperparams", *SHORT]
    )
    config = yaml.safe_load((ppo / "seed0" / "config.yml").read_text())
    assert config["env_id"] == SURROGATE
    copy = tmp_path / "copy.npz"
    shutil.copyfile(model, copy)
    out = tmp_path / "runs"
    episodes = ["--tune-episodes", "1", "--episodes", "1", *EPISODES]
    base = ["--env", SURROGATE, "--env-kwargs", json.dumps(tiny_kwargs(copy)), "--run", str(ppo), *episodes]
    result = main([*base, "--out", str(out)])
    assert [r["name"] for r in result["rows"]] == ["ppo (ppo)"]
    played = read_json(out / "points" / "ppo_seed0.json")
    assert played["identity"]["env_id"] == SURROGATE and len(played["episodes"]) == 1
    other = tmp_path / "other.npz"
    random_direction_model(TINY_SETTINGS, seed=2).save(other)
    err = refused(
        capsys,
        main,
        ["--env", SURROGATE, "--env-kwargs", json.dumps(tiny_kwargs(other)), "--run", str(ppo), *episodes]
        + ["--out", str(tmp_path / "refused")],
    )
    assert "--run" in err and "surrogate" in err


# -- scripts/tracking_fidelity.py ----------------------------------------------------------------------------
SIM_ID = "dipenv/ViscosityTracking-v0"
SETTINGS = {
    "control_interval": 0.25,
    "episode_steps": 48,
    "reward": {"kind": "tracking", "energy_weight": 0.1},
}
CONSTANT_GRID = {"grid": {"direction": ["y"], "mason_ref": [1.0, 2.0, "inf"]}}
PI_GRID = {"grid": {"ki": [0.3], "kp": [1.0, 3.0], "mason_star": [1.0]}}
POINTS = {
    "constant_directiony_mason_ref1": ("constant", {"direction": "y", "mason_ref": 1.0}),
    "constant_directiony_mason_ref2": ("constant", {"direction": "y", "mason_ref": 2.0}),
    "constant_off": ("constant", {"direction": "y", "mason_ref": "inf"}),
    "angle_pi_ki0.3_kp1_mason_star1": ("angle_pi", {"ki": 0.3, "kp": 1.0, "mason_star": 1.0}),
    "angle_pi_ki0.3_kp3_mason_star1": ("angle_pi", {"ki": 0.3, "kp": 3.0, "mason_star": 1.0}),
}
SIM_VALUES = {  # per point, per state: the realisations' (return, mean |error|)
    "constant_directiony_mason_ref1": [[(-10.0, 1.0)], [(-12.0, 1.2)]],  # -11, 1.1
    "constant_directiony_mason_ref2": [[(-20.0, 2.0)], [(-22.0, 2.2)]],  # -21, 2.1
    "constant_off": [[(-30.0, 3.0)], [(-30.0, 3.0)]],  # -30, 3.0
    "angle_pi_ki0.3_kp1_mason_star1": [[(-15.0, 1.5)], [(-15.0, 1.5)]],  # -15, 1.5
    "angle_pi_ki0.3_kp3_mason_star1": [[(-16.0, 1.6)], [(-16.0, 1.6)]],  # -16, 1.6
}
SUR_VALUES = {  # two samples per state
    "constant_directiony_mason_ref1": [[(-5.0, 3.0), (-7.0, 3.0)], [(-8.0, 3.0), (-8.0, 3.0)]],  # -7, 3.0
    "constant_directiony_mason_ref2": [
        [(-18.0, 2.0), (-18.0, 2.0)],
        [(-18.0, 2.0), (-18.0, 2.0)],
    ],  # -18, 2.0
    "constant_off": [[(-25.0, 1.0), (-25.0, 1.0)], [(-25.0, 1.0), (-25.0, 1.0)]],  # -25, 1.0
    "angle_pi_ki0.3_kp1_mason_star1": [[(-12.5, 1.6)] * 2, [(-12.5, 1.6)] * 2],  # -12.5, 1.6
    "angle_pi_ki0.3_kp3_mason_star1": [[(-12.0, 1.5)] * 2, [(-12.0, 1.5)] * 2],  # -12, 1.5
}
"""The surrogate orders the returns as the simulator does but for the two PIs (adjacent in rank: Spearman
1 - 6 x 2 / (5 x 24) = 0.9, Kendall (9 - 1) / 10 = 0.8; among the constants 1 and 1), and the constants'
errors the other way round (-1)."""


def episodes(values: list[list[tuple[float, float]]], split: str = "validation") -> list[dict[str, Any]]:
    return [
        {"split": split, "index": i, "realisation": k, "return": r, "mean_abs_error": e, "mean_energy": 0.0}
        for i, state in enumerate(values)
        for k, (r, e) in enumerate(state)
    ]


def craft(folder: Path, env_id: str, values: dict[str, Any], chosen: dict[str, str], **changes: Any) -> Path:
    """An ``agents.tracking``-shaped folder (what ``tracking_fidelity.py`` reads) with the given episodes;
    ``changes`` edit the manifest's params."""
    (folder / "tuning").mkdir(parents=True)
    (folder / "points").mkdir()
    settings = {**SETTINGS, **({"surrogate": {"digest": "abc"}} if "Surrogate" in env_id else {})}
    params = {
        "env_id": env_id,
        "env_kwargs": {},
        "library_key": None if "Surrogate" in env_id else "key",
        "tune_split": "validation",
        "tune_episodes": 2,
        "split": "validation",
        "episodes": 2,
        "controller_constant": CONSTANT_GRID,
        "controller_angle_pi": PI_GRID,
        **changes,
    }
    params = {k: v for k, v in params.items() if v is not None}  # a change to None removes the entry
    manifest = {"command": "agents.tracking", "params": params}
    (folder / "manifest.json").write_text(json.dumps(manifest))
    for label, (kind, point) in POINTS.items():
        record = {
            "label": label,
            "controller": kind,
            "params": point,
            "identity": {"env_settings": settings},
            "episodes": episodes(values[label]),
        }
        (folder / "tuning" / f"{label}.json").write_text(json.dumps(record))
    write_tuning_csv(folder, chosen)
    for kind, label in chosen.items():
        record = {
            "label": kind,
            "controller": kind,
            "params": POINTS[label][1],
            "name": f"{kind} at {label}",
            "identity": {"env_settings": settings},
            "episodes": episodes(values[label]),
        }
        (folder / "points" / f"{kind}.json").write_text(json.dumps(record))
    return folder


def write_tuning_csv(folder: Path, chosen: dict[str, str]) -> None:
    """``tuning.csv`` with the ``chosen`` column (the other columns are not read)."""
    text = io.StringIO()
    table = csv.writer(text, lineterminator="\n")
    table.writerow(["controller", "point", "params", "return", "mean_abs_error", "mean_energy", "chosen"])
    for label, (kind, point) in POINTS.items():
        table.writerow([kind, label, json.dumps(point), 0, 0, 0, "yes" if chosen.get(kind) == label else ""])
    (folder / "tuning.csv").write_text(text.getvalue())


SIM_CHOSEN = {"constant": "constant_directiony_mason_ref1", "angle_pi": "angle_pi_ki0.3_kp1_mason_star1"}
SUR_CHOSEN = {"constant": "constant_directiony_mason_ref1", "angle_pi": "angle_pi_ki0.3_kp3_mason_star1"}


@pytest.fixture()
def pair(tmp_path: Path) -> tuple[Path, Path]:
    sim = craft(tmp_path / "sim", SIM_ID, SIM_VALUES, SIM_CHOSEN)
    sur = craft(tmp_path / "sur", SURROGATE, SUR_VALUES, SUR_CHOSEN)
    run = {
        "label": "surrogate_ppo_seed0",
        "identity": {},
        "episodes": episodes([[(-1.0, 0.1)], [(-1.0, 0.1)]]),
    }
    (sim / "points" / "surrogate_ppo_seed0.json").write_text(json.dumps(run))  # a row only in SIM_DIR
    return sim, sur


def test_fidelity_numbers_by_hand(
    pair: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sim, sur = pair
    out = tmp_path / "report" / "fidelity.md"
    result = fidelity().main([str(sim), str(sur), "--out", str(out)])
    printed = capsys.readouterr().out
    rows = {r["point"]: r for r in result["tuning"]}
    assert list(rows) == [*list(POINTS)[3:], *list(POINTS)[:3]]  # angle_pi, then constant (sorted kinds)
    one = rows["constant_directiony_mason_ref1"]
    assert one["simulator"]["return"] == pytest.approx(-11.0) and one["surrogate"]["return"] == pytest.approx(
        -7.0
    )
    assert one["difference"]["return"] == pytest.approx(4.0)
    assert one["simulator"]["mean_abs_error"] == pytest.approx(1.1)
    assert one["difference"]["mean_abs_error"] == pytest.approx(1.9)
    assert one["simulator"]["realisations"] == [1, 1] and one["surrogate"]["realisations"] == [2, 2]
    correlations = result["correlations"]
    assert correlations["all"]["return"]["spearman"] == pytest.approx(0.9)
    assert correlations["all"]["return"]["kendall"] == pytest.approx(0.8)
    assert correlations["all"]["return"]["points"] == 5
    assert correlations["constant"]["return"]["spearman"] == pytest.approx(1.0)
    assert correlations["constant"]["return"]["kendall"] == pytest.approx(1.0)
    assert correlations["constant"]["mean_abs_error"]["spearman"] == pytest.approx(-1.0)
    assert "angle_pi" not in correlations  # two points: too few for a correlation of its own
    assert result["chosen"] == {
        "angle_pi": {
            **{f: c["angle_pi"] for f, c in (("simulator", SIM_CHOSEN), ("surrogate", SUR_CHOSEN))},
            "same": False,
        },
        "constant": {"simulator": SIM_CHOSEN["constant"], "surrogate": SUR_CHOSEN["constant"], "same": True},
    }
    assert [r["row"] for r in result["rows"]] == ["angle_pi", "constant"]
    pi = result["rows"][0]
    assert pi["simulator"]["return"] == pytest.approx(-15.0) and pi["surrogate"]["return"] == pytest.approx(
        -12.0
    )
    assert result["rows_only_in"] == {"simulator": ["surrogate_ppo_seed0"]}
    table = out.read_text()
    assert table == printed
    line = "| constant | constant_directiony_mason_ref1 | -11.00 | -7.00 | +4.00 | 1.100 | 3.000 | +1.900 |"
    assert line + " 2x1 | 2x2 |" in table
    assert "| every grid point | 5 | 0.90 | 0.80 |" in table and "| angle_pi |" in table
    numbers = json.loads(out.with_suffix(".json").read_text())
    assert numbers["correlations"]["all"]["return"]["kendall"] == pytest.approx(0.8)


def test_fidelity_refuses_folders_that_differ(
    pair: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sim, sur = pair
    run = fidelity().main

    def edited(name: str, **changes: Any) -> Path:
        return craft(tmp_path / name, SURROGATE, SUR_VALUES, SUR_CHOSEN, **changes)

    err = refused(capsys, run, [str(tmp_path / "nowhere"), str(sur)])
    assert "SIM_DIR" in err and "no such folder" in err
    (tmp_path / "empty").mkdir()
    err = refused(capsys, run, [str(sim), str(tmp_path / "empty")])
    assert "SUR_DIR" in err and "not a python -m agents.tracking output folder" in err
    other = edited("other")
    (other / "manifest.json").write_text(json.dumps({"command": "agents.controllers", "params": {}}))
    err = refused(capsys, run, [str(other), str(sur)])
    assert "SIM_DIR" in err and "agents.controllers" in err
    err = refused(capsys, run, [str(sim), str(edited("fewer", tune_episodes=1))])
    assert "SUR_DIR" in err and "tune_episodes 1 (SIM_DIR: 2)" in err
    err = refused(capsys, run, [str(sim), str(edited("split", split="test"))])
    assert "split 'test'" in err
    grid = {"grid": {"ki": [0.3], "kp": [1.0], "mason_star": [1.0]}}
    err = refused(capsys, run, [str(sim), str(edited("grid", controller_angle_pi=grid))])
    assert "angle_pi's grid" in err
    err = refused(capsys, run, [str(sim), str(edited("kinds", controller_angle_pi=None))])
    assert "controllers ['constant'] (SIM_DIR: ['angle_pi', 'constant'])" in err
    unfinished = edited("unfinished")
    (unfinished / "tuning" / "constant_off.json").unlink()
    err = refused(capsys, run, [str(sim), str(unfinished)])
    assert "SUR_DIR" in err and "no tuning/constant_off.json" in err
    short = edited("short")
    record = json.loads((short / "tuning" / "constant_off.json").read_text())
    record["episodes"] = [e for e in record["episodes"] if e["index"] == 0]
    (short / "tuning" / "constant_off.json").write_text(json.dumps(record))
    err = refused(capsys, run, [str(sim), str(short)])
    assert "SUR_DIR" in err and "holds states [0], not 0-1" in err
    longer = edited("longer")
    for path in (longer / "tuning").glob("*.json"):
        record = json.loads(path.read_text())
        record["identity"]["env_settings"]["episode_steps"] = 10
        path.write_text(json.dumps(record))
    err = refused(capsys, run, [str(sim), str(longer)])
    assert "SUR_DIR" in err and "episode_steps 10 (SIM_DIR: 48)" in err
    err = refused(capsys, run, [str(sim), str(sur), "--out", str(tmp_path / "table.txt")])
    assert "--out" in err
    err = refused(capsys, run, [str(sim), str(sim)])
    assert "SUR_DIR" in err


def test_fidelity_on_a_real_surrogate_folder(made: Path, tmp_path: Path) -> None:
    """SIM_DIR made from the surrogate's own folder (the simulator's id, every return 1 lower, one
    realisation): every difference is +1, the ranks agree (1), and each fidelity tuned the same points."""
    sim = tmp_path / "sim"
    shutil.copytree(made, sim)
    manifest = json.loads((sim / "manifest.json").read_text())
    manifest["params"].update(env_id="dipenv/ViscosityTrackingTiny-v0", library_key="key")
    (sim / "manifest.json").write_text(json.dumps(manifest))
    for path in [*(sim / "tuning").glob("*.json"), *(sim / "points").glob("*.json")]:
        record = json.loads(path.read_text())
        means: dict[int, list[float]] = {}
        for e in record["episodes"]:
            means.setdefault(e["index"], []).append(e["return"])
        record["episodes"] = [
            {**e, "return": float(np.mean(means[e["index"]])) - 1.0}
            for e in record["episodes"]
            if e["realisation"] == 0
        ]
        path.write_text(json.dumps(record))
    result = fidelity().main([str(sim), str(made)])
    assert len(result["tuning"]) == 5 and {r["row"] for r in result["rows"]} == {"constant", "angle_pi"}
    for row in [*result["tuning"], *result["rows"]]:
        assert row["difference"]["return"] == pytest.approx(1.0)
        assert row["simulator"]["realisations"] == [1, 1] and row["surrogate"]["realisations"] == [2, 2]
    returns = [r["simulator"]["return"] for r in result["tuning"]]
    if len(set(returns)) == len(returns):
        assert result["correlations"]["all"]["return"]["spearman"] == pytest.approx(1.0)
    assert all(pick["same"] for pick in result["chosen"].values())
    assert result["surrogate_model"]["kind"] == "ensemble" and not math.isnan(
        result["tuning"][0]["surrogate"]["return"]
    )


def test_validation_passes_are_seeded_so_a_run_repeats_its_log(tmp_path: Path) -> None:
    """Was: SB3's EvalCallback never seeded the validation env, so on a stochastic env (a surrogate) each
    run of the same command wrote another validation log and could keep another best model (seed 0 of the
    tracking PPO validated at -207.1 at step 50000 in one run and -219.2 in a rerun whose training was
    identical). Now every pass is seeded: two callbacks give the same log, pass for pass; unseeded, two
    callbacks of the same policy give different logs (so the test can tell)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.callbacks import AtomicEvalCallback

    torch.set_num_threads(1)
    surrogate_model = random_direction_model(TINY_SETTINGS)

    def venv() -> DummyVecEnv:
        return DummyVecEnv([lambda: tiny_surrogate(surrogate_model, split="validation", start_state="cycle")])

    model = PPO("MlpPolicy", venv(), n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]}, seed=0)
    model.set_logger(configure(None, []))

    def passes(seed: int | None, folder: Path) -> list[list[float]]:
        cb = AtomicEvalCallback(venv(), folder, seed=seed, n_eval_episodes=2, eval_freq=1, verbose=0)
        cb.init_callback(model)
        for _ in range(2):
            cb.on_step()
        return [list(r) for r in cb.evaluations_results]

    seeded = passes(10_000, tmp_path / "a")
    assert passes(10_000, tmp_path / "b") == seeded
    assert passes(None, tmp_path / "c") != passes(None, tmp_path / "d")
