"""``python -m agents.tracking`` on ``dipenv/ViscosityTrackingTiny-v0`` (issue 44): the baselines tuned on
validation and played on test (the folder, the tuning, the table), resumption (a rerun plays nothing, an
interrupted row only its missing episode, more realisations only those), refusals (another grid, env or
episode count in the same folder, the fresh split without ``--final-evaluation``, bad input), a trained PPO
run played with its mean action beside the stored baselines, ``--schedules``, and the paired gaps against a
hand computation on the stored records. Every episode here is the tiny box's (N = 32, 10 intervals; about
0.1 s each once the kernels are compiled)."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import agents.statistics
import agents.tracking_rows as rows
from agents import train
from agents.open_loop import read_json
from agents.rollout import make_env
from agents.tracking import main
from agents.tracking_controllers import ConstantFieldController, play_episode, play_episodes

ENV = "dipenv/ViscosityTrackingTiny-v0"
GRID = [
    "--grid",
    "mason_ref=1,inf",
    "direction=y,z",
    "kp=1",
    "ki=0.3",
    "mason_star=1",
    "map_feedforward.target=next",
]
"""Five tuning points: the constant along y and z at Mn_ref 1 and off (one point), a PI, a feed-forward."""
BASELINES = ["--env", ENV, "--controller", "constant", "map_feedforward", "angle_pi", *GRID]
EPISODES = ["--tune-episodes", "1", "--episodes", "2", "--no-progress"]
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=1", "eval_freq=32", "checkpoint_freq=32"]


@pytest.fixture(scope="module", autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """The tiny start states in a fresh cache; a cheaper bootstrap (its intervals are not tested here, the
    means are, and they do not depend on it)."""
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(tmp_path_factory.mktemp("dipenv_cache_tracking")))
    patcher.setattr(agents.statistics, "BOOTSTRAP_REPS", 200)
    yield
    patcher.undo()


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The three baselines tuned on the first validation state and played on the first two test states."""
    out = tmp_path_factory.mktemp("tracking") / "baselines"
    main([*BASELINES, *EPISODES, "--out", str(out)])
    return out


def copy_of(folder: Path, tmp_path: Path) -> Path:
    target = tmp_path / folder.name
    shutil.copytree(folder, target)
    return target


def count_episodes(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, int, int]]:
    """Every episode the command plays from now on, as (split, start state, realisation)."""
    calls: list[tuple[str, int, int]] = []

    def counted(
        env: Any, policy: Any, split: str, index: int, realisation: int = 0, *args: Any, **kw: Any
    ) -> Any:
        calls.append((split, index, realisation))
        return play_episode(env, policy, split, index, realisation, *args, **kw)

    monkeypatch.setattr(rows, "play_episode", counted)
    return calls


def refused(capsys: pytest.CaptureFixture[str], arguments: list[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        main(arguments)
    err = capsys.readouterr().err
    assert exit_.value.code == 2, err
    return err


def test_tune_and_play_writes_the_folder_and_the_table(made: Path) -> None:
    manifest = json.loads((made / "manifest.json").read_text())
    assert manifest["command"] == "agents.tracking" and manifest["source_digest"]
    params = manifest["params"]
    assert params["library_key"] and params["split"] == "test" and params["episodes"] == 2
    assert params["controller_constant"]["grid"] == {"direction": ["y", "z"], "mason_ref": [1.0, "inf"]}
    assert "direction_map" in params["controller_map_feedforward"]
    assert "agents.tracking" in (made / "command.txt").read_text()
    assert len(list((made / "tuning").glob("*.json"))) == 5  # off once, whatever its direction
    tuning = (made / "tuning.csv").read_text().splitlines()
    assert len(tuning) == 6 and sum(line.endswith(",yes") for line in tuning) == 3
    # the tuned constant is the grid point with the highest mean return on the tuning state
    points = [read_json(p) for p in (made / "tuning").glob("constant_*.json")]
    best = max(points, key=lambda r: r["episodes"][0]["return"])
    constant = read_json(made / "points" / "constant.json")
    assert constant["params"] == best["params"] and best["episodes"][0]["split"] == "validation"
    for kind in ("constant", "map_feedforward", "angle_pi"):
        record = read_json(made / "points" / f"{kind}.json")
        assert [(e["split"], e["index"], e["realisation"]) for e in record["episodes"]] == [
            ("test", 0, 0),
            ("test", 1, 0),
        ]
        for episode in record["episodes"]:
            assert len(episode["eta_r"]) == len(episode["target_eta_r"]) == len(episode["time"]) == 10
            errors = np.abs(np.subtract(episode["eta_r"], episode["target_eta_r"]))
            assert episode["mean_abs_error"] == pytest.approx(errors.mean(), rel=1e-12)
    # reproducible: the tuned constant replayed by the library function gives the stored episodes
    env = make_env(ENV, {"progress": False})
    direction = rows.DIRECTIONS[constant["params"]["direction"]]
    replay = play_episodes(
        env, ConstantFieldController(constant["params"]["mason_ref"], direction), "test", 2
    )
    env.close()
    assert [e["eta_r"] for e in replay] == [e["eta_r"] for e in constant["episodes"]]
    table = (made / "table.md").read_text()
    assert constant["name"] in table and "map feed-forward (target next)" in table
    assert "Against the best constant" in table and "Against the map feed-forward" in table
    assert (made / "traces.png").stat().st_size > 0 and (made / "results.json").exists()


def test_a_rerun_plays_nothing(made: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = copy_of(made, tmp_path)
    before = {p.name: p.read_text() for p in (out / "points").glob("*.json")}
    calls = count_episodes(monkeypatch)
    main([*BASELINES, *EPISODES, "--out", str(out)])
    assert calls == []
    assert {p.name: p.read_text() for p in (out / "points").glob("*.json")} == before
    # one of the rows alone: nothing played, and the folder's other rows stay in the tables
    tuning = (out / "tuning.csv").read_text()
    constant = ["--env", ENV, "--controller", "constant", "--grid", "mason_ref=1,inf", "direction=y,z"]
    result = main([*constant, *EPISODES, "--out", str(out)])
    assert calls == [] and (out / "tuning.csv").read_text().splitlines()[1:] != []
    assert sorted((out / "tuning.csv").read_text().splitlines()) == sorted(tuning.splitlines())
    assert [r["label"] for r in result["rows"]] == ["constant", "map_feedforward", "angle_pi"]


def test_an_interrupted_row_plays_only_its_missing_episode(
    made: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = copy_of(made, tmp_path)
    path = out / "points" / "angle_pi.json"
    whole = read_json(path)
    cut = {**whole, "episodes": whole["episodes"][:-1]}
    path.write_text(json.dumps(cut))
    calls = count_episodes(monkeypatch)
    main([*BASELINES, *EPISODES, "--out", str(out)])
    assert calls == [("test", 1, 0)]
    assert read_json(path)["episodes"] == whole["episodes"]  # the same episode again, bit for bit
    # more realisations add only the missing ones, in every row
    calls.clear()
    main([*BASELINES, *EPISODES, "--realisations", "2", "--out", str(out)])
    assert sorted(calls) == [("test", 0, 1)] * 3 + [("test", 1, 1)] * 3
    assert "x 2 realisations" in (out / "table.md").read_text()


def test_another_grid_env_or_episode_count_is_refused(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = copy_of(made, tmp_path)
    other_grid = [a.replace("mason_ref=1,inf", "mason_ref=2,inf") for a in BASELINES]
    err = refused(capsys, [*other_grid, *EPISODES, "--out", str(out)])
    assert "other parameters" in err and "controller_constant" in err and "--overwrite" in err
    err = refused(
        capsys, [*BASELINES, *EPISODES, "--env-kwargs", '{"energy_weight": 0.2}', "--out", str(out)]
    )
    assert "env_kwargs" in err
    err = refused(capsys, [*BASELINES, "--tune-episodes", "1", "--episodes", "1", "--out", str(out)])
    assert "episodes=2" in err
    # a folder another command owns
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "manifest.json").write_text(
        (made / "manifest.json").read_text().replace("agents.tracking", "agents.controllers")
    )
    assert "another command" in refused(capsys, [*BASELINES, *EPISODES, "--out", str(tmp_path / "other")])


def test_bad_input_exits_2_naming_the_argument(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = ["--out", str(tmp_path / "never")]
    err = refused(capsys, [*BASELINES, *EPISODES, "--split", "fresh", *out])
    assert "--split fresh" in err and "--final-evaluation" in err
    assert "invalid choice" in refused(capsys, [*BASELINES, *EPISODES, "--tune-split", "fresh", *out])
    assert "--episodes must be in [1, 2]" in refused(capsys, [*BASELINES, "--episodes", "3", *out])
    assert "--tune-episodes must be in [1, 2]" in refused(capsys, [*BASELINES, "--tune-episodes", "5", *out])
    kinds = ["--env", ENV, "--controller", "constant", "angle_pi", *out, "--grid"]
    assert "ki must be finite and >= 0" in refused(capsys, [*kinds, "angle_pi.ki=-1"])
    assert "'map_feedforward' is not a --controller" in refused(
        capsys, [*kinds, "map_feedforward.target=now"]
    )
    err = refused(capsys, [*kinds, "speed=1"])
    assert "no --controller takes 'speed'" in err and "angle_pi takes" in err and "constant takes" in err
    assert "direction must be one of" in refused(capsys, [*kinds, "direction=w"])
    assert "lists a value twice" in refused(capsys, [*kinds, "direction=y,y"])
    assert "sets angle_pi's kp twice" in refused(capsys, [*kinds, "kp=1", "angle_pi.kp=2"])
    err = refused(capsys, ["--env", "dipenv/ThickeningControlTiny-v0", "--controller", "constant", *out])
    assert "--env must be one of" in err and ENV in err
    assert "give --controller" in refused(capsys, ["--env", ENV, *out])
    assert "integer >= 1" in refused(capsys, [*BASELINES, "--realisations", "0", *out])
    err = refused(
        capsys, ["--env", "dipenv/ViscosityTrackingStressOnly-v0", "--controller", "angle_pi", *out]
    )
    assert "--controller angle_pi" in err and "slog_eta_r" in err  # the stress-only id observes no eta_r
    assert "--run" in refused(capsys, ["--env", ENV, "--run", str(tmp_path), *out])
    assert not (tmp_path / "never").exists()  # refused before the folder is claimed


def test_a_trained_run_is_played_with_its_mean_action_beside_the_baselines(
    made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from stable_baselines3 import PPO

    ppo = tmp_path / "ppo"
    train.main(
        ["--env", ENV, "--timesteps", "32", "--n-envs", "1", "--no-progress", "--algo", "ppo", "--seeds", "0"]
        + ["--out", str(ppo), "--hyperparams", *SHORT]
    )
    out = copy_of(made, tmp_path)
    calls = count_episodes(monkeypatch)
    result = main(["--env", ENV, "--run", str(ppo), *EPISODES, "--out", str(out)])  # a row added
    assert calls == [("test", 0, 0), ("test", 1, 0)]  # the stored baselines are reused
    names = [r["name"] for r in result["rows"]]
    assert names[-1] == "ppo (ppo)" and len(names) == 4
    assert "run_ppo_ppo" in json.loads((out / "manifest.json").read_text())["params"]
    played = read_json(out / "points" / "ppo_seed0.json")
    # the mean action on the observation normalised by the run's statistics, replayed by hand
    model = PPO.load(str(ppo / "seed0" / "model.zip"), device="cpu")
    with open(ppo / "seed0" / "vecnormalize.pkl", "rb") as handle:
        normaliser = pickle.load(handle)
    normaliser.training = False
    env = make_env(ENV, {"progress": False})
    for episode in played["episodes"]:
        by_hand = play_episode(
            env,
            lambda obs: model.predict(normaliser.normalize_obs(obs), deterministic=True)[0],
            "test",
            episode["index"],
        )
        assert by_hand["eta_r"] == episode["eta_r"] and by_hand["action"] == episode["action"]
    env.close()
    calls.clear()
    main([*BASELINES, *EPISODES, "--run", str(ppo), "--out", str(out)])  # all rows: nothing to play
    assert calls == []
    err = refused(
        capsys,
        ["--env", ENV, "--run", str(ppo), "--play-env", "dipenv/ViscosityTrackingStressOnly-v0", *EPISODES]
        + ["--out", str(out)],
    )
    assert "--play-env" in err and "observation space" in err


def test_the_paired_gaps_equal_a_hand_computation_on_the_stored_records(made: Path, tmp_path: Path) -> None:
    """Mean over the paired (state, realisation) episodes of a row's metric minus the best constant's, and
    the error reduction 1 - sum e / sum e_constant, from the point files (two realisations: each state's
    gaps are averaged first, which leaves the mean over the episodes unchanged)."""
    out = copy_of(made, tmp_path)
    result = main([*BASELINES, *EPISODES, "--realisations", "2", "--out", str(out)])
    by_name = {r["label"]: r for r in result["rows"]}
    constant = {
        (e["index"], e["realisation"]): e for e in read_json(out / "points" / "constant.json")["episodes"]
    }
    assert len(constant) == 4
    for kind in ("map_feedforward", "angle_pi"):
        mine = {
            (e["index"], e["realisation"]): e for e in read_json(out / "points" / f"{kind}.json")["episodes"]
        }
        paired = by_name[kind]["paired"]["constant"]
        for metric in ("mean_abs_error", "return"):
            gaps = [mine[k][metric] - constant[k][metric] for k in constant]
            assert paired[metric]["gap"] == pytest.approx(float(np.mean(gaps)), rel=1e-12, abs=1e-12)
            assert paired[metric]["episodes"] == 4 and paired[metric]["states"] == 2
        errors = sum(mine[k]["mean_abs_error"] for k in constant)
        reduction = 1 - errors / sum(constant[k]["mean_abs_error"] for k in constant)
        assert paired["error_reduction"]["reduction"] == pytest.approx(reduction, rel=1e-12)
        assert by_name[kind]["mean_abs_error"]["mean"] == pytest.approx(
            float(np.mean([e["mean_abs_error"] for e in mine.values()])), rel=1e-12
        )
    assert "map_feedforward" in by_name["angle_pi"]["paired"] and not by_name["constant"]["paired"].get(
        "constant"
    )


def test_schedules_file_plays_its_own_rate_schedule_with_the_split_target(tmp_path: Path) -> None:
    """A file holding the test split's schedule 0 from start state 0 plays that split's episode 0 bit for bit
    (the target is the start state's); the file's digest joins the identity."""
    from dipenv.schedules import schedule_to_dict

    env = make_env(ENV, {"progress": False})
    schedule = schedule_to_dict(env.unwrapped.fixed_schedule("test", 0))
    file = tmp_path / "schedules.json"
    file.write_text(json.dumps([{**schedule, "start_index": 0}]))
    out = tmp_path / "mine"
    grid = ["--grid", "mason_ref=1", "direction=z"]
    main(
        [
            "--env",
            ENV,
            "--controller",
            "constant",
            *grid,
            "--tune-episodes",
            "1",
            "--no-progress",
            "--schedules",
            str(file),
            "--out",
            str(out),
        ]
    )
    stored = read_json(out / "points" / "constant.json")["episodes"]
    assert len(stored) == 1 and stored[0]["start_index"] == 0 and stored[0]["schedule_digest"]
    fixed = play_episodes(env, ConstantFieldController(1.0, (0.0, 0.0, 1.0)), "test", 1)[0]
    env.close()
    assert stored[0]["eta_r"] == fixed["eta_r"] and stored[0]["target_eta_r"] == fixed["target_eta_r"]
    assert json.loads((out / "manifest.json").read_text())["params"]["schedules"]
