"""Schedules of your own (issue 43): ``--schedules FILE`` on agents.open_loop, agents.controllers and
agents.evaluate. Episode j follows schedule j from its start state; reruns reuse; the file's digest is
part of every identity; a malformed file exits 2 naming the entry; a fixed split's own schedule played
from a file is that split's episode bit for bit."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import dipenv  # noqa: F401  (registers the ids)
from agents import controllers, evaluate, open_loop, train
from agents import schedules as own
from dipenv.schedules import schedule_to_dict, validate_schedule
from sim.runs import read_manifest

TINY = "dipenv/ThickeningControlTiny-v0"
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32"]

ENTRIES: list[dict[str, Any]] = [
    # a jump from 0.5 to 2 at time 0.05 (mid-episode: the tiny episode lasts 0.2); start state 0 mod 2
    {"times": [0.0, 0.05, 0.05], "rates": [0.5, 0.5, 2.0]},
    # a drop from 3 to 1 at time 0.13, on the same start state as entry 0: the rows pair by entry, not by
    # state (jumps, not ramps: the simulator follows a ramp as a staircase, whose interval means are the
    # schedule's within about 1%, a jump's exactly)
    {"schedule": {"times": [0.0, 0.13, 0.13], "rates": [3.0, 3.0, 1.0]}, "start_index": 0, "name": "down"},
]


def write(path: Path, entries: Any) -> Path:
    path.write_text(json.dumps(entries))
    return path


def schedule_of(entry: dict[str, Any]) -> Any:
    return validate_schedule(entry.get("schedule", {k: entry.get(k) for k in ("times", "rates")}))


def count_episodes(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, int]]:
    """Record ``(split, start state)`` of every episode played on a schedules file from now on."""
    calls: list[tuple[str, int]] = []
    real = own.run_episode

    def counted(env: Any, policy: Any, split: str, index: int, **kwargs: Any) -> Any:
        calls.append((split, index))
        return real(env, policy, split, index, **kwargs)

    monkeypatch.setattr(own, "run_episode", counted)
    return calls


def check_follows_the_file(episodes: list[dict[str, Any]], entries: list[dict[str, Any]]) -> None:
    """Episode j: entry j's start state and schedule digest, and the interval rates of ``info`` are
    schedule j's: its rate wherever the schedule holds one rate over the interval (0.005 time units of
    margin: the simulator's last step of an interval may overshoot its end), within its range elsewhere."""
    assert sorted(e["index"] for e in episodes) == list(range(len(entries)))
    for episode in episodes:
        j = episode["index"]
        schedule = schedule_of(entries[j])
        assert episode["entry"] == j and episode["trace"]["index"] == j
        assert episode["start_index"] == entries[j].get("start_index", j % 2)  # 2 test states
        assert episode["schedule_digest"] == own.schedule_digest(schedule)
        trace = episode["trace"]
        held = 0
        for start, end, rate in zip(
            [0.0, *trace["time"][:-1]], trace["time"], trace["shear_rate"], strict=True
        ):
            a, b = max(0.0, start - 0.005), end + 0.005
            if not any(a < t < b for t in schedule.times[1:]):
                assert rate == pytest.approx(schedule(end), rel=1e-12)
                held += 1
            else:
                assert min(schedule.values) - 1e-12 <= rate <= max(schedule.values) + 1e-12
        assert held >= 5
        first, last = trace["shear_rate"][0], trace["shear_rate"][-1]
        assert (first, last) == pytest.approx((schedule.values[0], schedule.values[-1]), rel=1e-12)


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The three commands on a file of two schedules: constant fields (off, Mn 1), the feed-forward
    controller (tuned on one validation schedule), one PPO run (64 steps), and the evaluation."""
    root = tmp_path_factory.mktemp("schedules")
    file = write(root / "mine.json", ENTRIES)
    folders = {name: root / name for name in ("open_loop", "ff", "ppo", "evaluation")}
    open_loop.main(
        ["--env", TINY, "--mason", "off,1", "--schedules", str(file), "--out", str(folders["open_loop"])]
    )
    controllers.main(
        ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1"]
        + ["--schedules", str(file), "--out", str(folders["ff"])]
    )
    train.main(
        [
            "--env",
            TINY,
            "--timesteps",
            "64",
            "--n-envs",
            "1",
            "--no-progress",
            "--algo",
            "ppo",
            "--seeds",
            "0",
        ]
        + ["--out", str(folders["ppo"]), "--hyperparams", *SHORT]
    )
    evaluate.main(
        [str(folders["ppo"]), "--baseline", str(folders["open_loop"]), "--controllers", str(folders["ff"])]
        + ["--schedules", str(file), "--out", str(folders["evaluation"])]
    )
    return {"file": file, **folders}


def evaluate_argv(made: dict[str, Path], file: Path | None = None) -> list[str]:
    argv = [str(made["ppo"]), "--baseline", str(made["open_loop"]), "--controllers", str(made["ff"])]
    return argv + ["--schedules", str(file or made["file"]), "--out", str(made["evaluation"])]


def test_each_command_plays_episode_j_on_schedule_j(made: dict[str, Path]) -> None:
    """Every row holds one episode per entry, numbered by the entry, from the entry's start state and on
    its schedule; the summaries record the file's digest, and OUT/schedules.json (the file resolved) has
    the same digest."""
    digest = own.resolve(made["file"], own.read_entries(made["file"]), "test", 2).digest
    for label in ("off", "Mn1"):
        point = json.loads((made["open_loop"] / "points" / f"{label}.json").read_text())
        assert point["identity"]["schedules"] == digest
        check_follows_the_file(point["episodes"], ENTRIES)
    assert json.loads((made["open_loop"] / "pareto.json").read_text())["schedules"]["digest"] == digest
    (played,) = (made["ff"] / "points").glob("*.json")
    check_follows_the_file(json.loads(played.read_text())["episodes"], ENTRIES)
    (tuning,) = json.loads(next((made["ff"] / "tuning").glob("*.json")).read_text())["episodes"]
    assert tuning["split"] == "validation" and "schedule_digest" not in tuning  # tuned on the split's own
    summary = json.loads((made["ff"] / "controller.json").read_text())
    assert summary["schedules"]["digest"] == digest and "tune_schedules" not in summary
    (run,) = (made["evaluation"] / "runs").glob("*.json")
    check_follows_the_file(json.loads(run.read_text())["episodes"], ENTRIES)
    results = json.loads((made["evaluation"] / "results.json").read_text())
    assert results["schedules"]["digest"] == digest and results["indices"] == [0, 1]
    assert [e["name"] for e in results["schedules"]["entries"]] == [None, "down"]
    assert [row["samples"] for row in results["rows"]] == ["2 start states"] * 3 + ["1 training seeds"]
    for folder in ("open_loop", "ff", "evaluation"):
        manifest = read_manifest(made[folder])
        assert manifest is not None and manifest.params["schedules"] == digest
        copy = made[folder] / "schedules.json"
        assert own.resolve(copy, own.read_entries(copy), "test", 2).digest == digest


def test_a_rerun_reuses_every_episode(made: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    calls = count_episodes(monkeypatch)
    file = str(made["file"])
    open_loop.main(["--env", TINY, "--mason", "off,1", "--schedules", file, "--out", str(made["open_loop"])])
    controllers.main(
        ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1"]
        + ["--schedules", file, "--out", str(made["ff"])]
    )
    evaluate.main(evaluate_argv(made))
    assert calls == []


def refused(capsys: pytest.CaptureFixture[str], command: Any, argv: list[str]) -> str:
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:
        command(argv)
    assert exit_info.value.code == 2
    return capsys.readouterr().err


def test_a_changed_file_is_refused_in_the_same_folder_and_plays_afresh_elsewhere(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    changed = write(tmp_path / "changed.json", [ENTRIES[0], {**ENTRIES[1], "start_index": 1}])
    argv = ["--env", TINY, "--mason", "1", "--schedules", str(changed), "--out"]
    err = refused(capsys, open_loop.main, [*argv, str(made["open_loop"])])
    assert "schedules" in err and str(made["open_loop"]) in err
    err = refused(
        capsys,
        controllers.main,
        ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1"]
        + ["--schedules", str(changed), "--out", str(made["ff"])],
    )
    assert "schedules" in err
    # the evaluation names the file it was given and the one its baseline was made with
    err = refused(capsys, evaluate.main, evaluate_argv(made, changed))
    assert str(changed) in err and str(made["file"]) in err and "--baseline" in err
    # without --schedules, a baseline made with a file is refused, naming the file
    argv_fixed = evaluate_argv(made)[:-4] + ["--out", str(tmp_path / "evaluation")]
    err = refused(capsys, evaluate.main, argv_fixed)
    assert str(made["file"]) in err and "give --schedules" in err
    # a controller made with another file: refused naming both
    other_ff = tmp_path / "ff"
    shutil.copytree(made["ff"], other_ff)
    summary = json.loads((other_ff / "controller.json").read_text())
    summary["schedules"] = {**summary["schedules"], "file": "theirs.json", "digest": "0" * 16}
    (other_ff / "controller.json").write_text(json.dumps(summary))
    argv_ff = evaluate_argv(made)
    argv_ff[argv_ff.index(str(made["ff"]))] = str(other_ff)
    err = refused(capsys, evaluate.main, argv_ff[:-1] + [str(tmp_path / "evaluation_ff")])
    assert "--controllers" in err and "theirs.json" in err and str(made["file"]) in err

    calls = count_episodes(monkeypatch)
    elsewhere = tmp_path / "open_loop"
    open_loop.main([*argv, str(elsewhere), "--episodes", "2"])
    assert calls == [("test", 0), ("test", 1)]  # entry 1 now from state 1
    point = json.loads((elsewhere / "points" / "Mn1.json").read_text())
    assert [e["start_index"] for e in point["episodes"]] == [0, 1]
    stored = json.loads((made["open_loop"] / "points" / "Mn1.json").read_text())
    assert point["episodes"][0]["trace"] == stored["episodes"][0]["trace"]  # entry 0 unchanged


def test_a_fixed_split_schedule_from_a_file_is_that_split_episode_bit_for_bit(tmp_path: Path) -> None:
    """The validation schedules written to a file and played from their own start states (the default
    ``j mod 2``) give the episodes of ``--split validation``, realisations included, bit for bit."""
    env = gym.make(TINY, progress=False)
    fixed = [schedule_to_dict(env.unwrapped.fixed_schedule("validation", k)) for k in range(2)]  # type: ignore[attr-defined]
    env.close()
    file = write(tmp_path / "validation.json", fixed)
    common = ["--env", TINY, "--mason", "1", "--split", "validation", "--repeats", "2", "--out"]
    open_loop.main([*common, str(tmp_path / "file"), "--schedules", str(file)])
    open_loop.main([*common, str(tmp_path / "split")])
    mine = json.loads((tmp_path / "file" / "points" / "Mn1.json").read_text())["episodes"]
    theirs = json.loads((tmp_path / "split" / "points" / "Mn1.json").read_text())["episodes"]
    assert [(e["index"], e["realisation"]) for e in mine] == [(e["index"], e["realisation"]) for e in theirs]
    assert len(mine) == 4
    for a, b in zip(mine, theirs, strict=True):
        assert a["start_index"] == a["index"]
        tagged = ("entry", "start_index", "schedule_digest")
        assert {k: v for k, v in a["trace"].items() if k not in tagged} == b["trace"]
        assert {k: v for k, v in a.items() if k not in (*tagged, "trace")} == {
            k: v for k, v in b.items() if k != "trace"
        }


def test_tune_schedules_tunes_on_the_file(tmp_path: Path) -> None:
    file = write(tmp_path / "tune.json", ENTRIES[:1])
    out = tmp_path / "ff"
    summary = controllers.main(
        ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1", "--episodes", "1"]
        + ["--tune-schedules", str(file), "--out", str(out)]
    )
    (tuning,) = json.loads(next((out / "tuning").glob("*.json")).read_text())["episodes"]
    assert tuning["split"] == "validation" and tuning["start_index"] == 0
    assert tuning["schedule_digest"] == own.schedule_digest(schedule_of(ENTRIES[0]))
    assert summary["tune_schedules"]["digest"] == read_manifest(out).params["tune_schedules"]  # type: ignore[union-attr]
    (played,) = json.loads(next((out / "points").glob("*.json")).read_text())["episodes"]
    assert played["split"] == "test" and "schedule_digest" not in played  # the split's own schedule
    assert (out / "tune_schedules.json").exists() and not (out / "schedules.json").exists()


GOOD = {"times": [0.0], "rates": [1.0]}


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("[{", "is not JSON"),
        (json.dumps(GOOD), "must be a JSON list of schedules"),
        ("[]", "holds no schedule"),
        (json.dumps([GOOD] * (own.MAX_ENTRIES + 1)), f"cap of {own.MAX_ENTRIES}"),
        (json.dumps([3]), "entry 0 must be"),
        (json.dumps([GOOD, {**GOOD, "seed": 3}]), 'entry 1 must be {"times"'),
        (json.dumps([GOOD, {"times": [0.0]}]), "entry 1 must be"),
        (
            json.dumps([GOOD, {"times": [0.0, 1.0], "rates": [1.0, 0.0]}]),
            "entry 1: rates[1] must be a finite",
        ),
        (json.dumps([{"times": [1.0, 2.0], "rates": [1.0, 1.0]}]), "entry 0: times must start at 0"),
        (json.dumps([{"schedule": {"times": [0.0], "rates": ["1"]}}]), "entry 0: rates[0] must be a real"),
        (json.dumps([GOOD, {"schedule": GOOD, "start_index": 2}]), "entry 1: start_index 2 is outside the 2"),
        (json.dumps([{**GOOD, "start_index": True}]), "entry 0: start_index must be an integer"),
        (json.dumps([{**GOOD, "start_index": 1.0}]), "entry 0: start_index must be an integer"),
        (json.dumps([{**GOOD, "name": 5}]), "entry 0: name must be a non-empty string"),
    ],
)
def test_a_malformed_file_exits_2_naming_the_entry(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, match: str
) -> None:
    file = tmp_path / "bad.json"
    file.write_text(content)
    out = tmp_path / "out"
    err = refused(capsys, open_loop.main, ["--env", TINY, "--schedules", str(file), "--out", str(out)])
    assert f"--schedules {file}: " in err and match in err
    assert not out.exists()  # checked before the folder is claimed


def test_every_command_checks_its_files(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = write(tmp_path / "bad.json", [GOOD, {"times": [0.0, -1.0], "rates": [1.0, 1.0]}])
    out = tmp_path / "out"
    base = ["--env", TINY, "--controller", "feedforward", "--out", str(out)]
    err = refused(capsys, controllers.main, [*base, "--schedules", str(bad)])
    assert f"--schedules {bad}: entry 1: times must increase" in err
    err = refused(capsys, controllers.main, [*base, "--tune-schedules", str(bad)])
    assert f"--tune-schedules {bad}: entry 1" in err
    err = refused(capsys, controllers.main, [*base, "--schedules", str(tmp_path / "absent.json")])
    assert "cannot be read" in err
    err = refused(
        capsys,
        open_loop.main,
        ["--env", TINY, "--schedules", str(made["file"]), "--episodes", "3"] + ["--out", str(out)],
    )
    assert "--episodes must be in [1, 2]" in err
    argv = evaluate_argv(made, bad)
    err = refused(capsys, evaluate.main, argv[:-1] + [str(out)])
    assert f"--schedules {bad}: entry 1" in err
    assert not out.exists()


def test_only_the_thickening_envs_take_schedules(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = write(tmp_path / "mine.json", ENTRIES)
    out = tmp_path / "out"
    err = refused(
        capsys,
        open_loop.main,
        ["--env", "dipenv/FieldMagnitudeTiny-v0", "--schedules", str(file), "--out", str(out)],
    )
    assert "--schedules is for the thickening-control envs" in err and "FieldMagnitudeTiny-v0" in err


def test_default_start_states_cycle_through_the_split(tmp_path: Path) -> None:
    file = write(tmp_path / "three.json", [GOOD, GOOD, {**GOOD, "start_index": 1}, GOOD])
    resolved = own.resolve(file, own.read_entries(file), "test", 2)
    assert [e.start_index for e in resolved.episodes] == [0, 1, 1, 1]
    # the digest covers the schedules and the start states, not the names or the layout
    named = write(
        tmp_path / "named.json", [{"schedule": GOOD, "name": "a"}, GOOD, {**GOOD, "start_index": 1}, GOOD]
    )
    spaced = tmp_path / "spaced.json"
    spaced.write_text(json.dumps(json.loads(file.read_text()), indent=4))
    for other in (named, spaced):
        assert own.resolve(other, own.read_entries(other), "test", 2).digest == resolved.digest
    assert own.resolve(file, own.read_entries(file), "test", 3).digest != resolved.digest  # entry 2 -> 2
