"""The cases the input probe (scripts/probe_inputs.py, results/input_probe) found not clean, as unit tests:
each refused now with a message naming the input, or answered without a NaN."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from agents_helpers import TINY, load_script, refused

from agents import controllers, open_loop
from agents.rollout import record_episodes
from sim.runs import cli


def test_sweep_refuses_a_seed_listed_twice(capsys: pytest.CaptureFixture[str]) -> None:
    # the other lists of a sweep (--phi, --mason) refuse repeats; --seeds 1,1 ran one point silently
    for seeds, twice in (("1,1", "1"), ("0-3,2", "2"), ("1,2,1,2", "1, 2")):
        err = refused(capsys, cli.main, ["sweep", "--seeds", seeds, "--out", "/tmp/never_made"])
        assert f"lists seed {twice} twice" in err
    assert cli._seed_list("0-2,5") == [0, 1, 2, 5]


def test_paired_rows_says_n_a_when_the_reference_spends_no_energy() -> None:
    paired_rows = load_script("paired_rows")
    row = {"return": -1.0, "excess_viscosity": 0.1, "energy_mean": 0.0}
    a = {0: dict(row), 1: {**row, "return": -2.0}}
    b = {0: {**row, "return": -3.0}, 1: {**row, "return": -1.5}}
    text = paired_rows.table(paired_rows.compare(a, b), ("A", "B"))
    assert "nan" not in text.lower()
    assert "Field energy saved by A against B: n/a" in text


def test_controllers_name_the_count_flag(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    base = ["--env", TINY, "--controller", "feedforward", "--out", str(tmp_path / "c")]
    err = refused(capsys, controllers.main, [*base, "--tune-episodes", "0"])
    assert "--tune-episodes must be in [1, 2]" in err
    err = refused(capsys, controllers.main, [*base, "--episodes", "9"])
    assert "--episodes must be in [1, 2]" in err


def test_open_loop_rerun_over_a_damaged_point_is_refused_naming_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "ol"
    argv = ["--env", "dipenv/FieldMagnitudeTiny-v0", "--mason", "off", "--episodes", "1", "--out", str(out)]
    open_loop.main(argv)
    point = out / "points" / "off.json"
    point.write_text("{not json")
    capsys.readouterr()
    err = refused(capsys, open_loop.main, argv)
    assert str(point) in err and "--overwrite" in err
    assert point.read_text() == "{not json"  # nothing touched


def test_record_episodes_names_a_bad_file(tmp_path: Path) -> None:
    for text in ("{not json", "[]", '{"episodes": [1]}'):
        path = tmp_path / "bad.json"
        path.write_text(text)
        with pytest.raises(ValueError, match="bad.json"):
            record_episodes(path)
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"episodes": [{"trace": {"eta_r": [1.0]}}]}))
    assert record_episodes(good) == [{"trace": {"eta_r": [1.0]}}]


@pytest.mark.parametrize("name", ["interval_noise", "field_pulsing"])
def test_scripts_reading_points_refuse_garbage(name: str, tmp_path: Path, capsys) -> None:
    script = load_script(name)
    bad = tmp_path / "garbage.json"
    bad.write_text("[]")
    err = refused(capsys, script.main, [str(bad)])
    assert "garbage.json" in err


def test_pulse_train_refuses_a_rate_outside_the_simulators_range(tmp_path: Path, capsys) -> None:
    script = load_script("pulse_train")
    err = refused(capsys, script.main, ["--out", str(tmp_path / "p"), "--rate", "1e-9"])
    assert "--rate must be in [0.001, 1000]" in err
