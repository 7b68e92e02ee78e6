"""scripts/paired_rows.py: per-state averaging and paired gaps on episodes whose answers are known."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location(
    "paired_rows", Path(__file__).parents[1] / "scripts" / "paired_rows.py"
)
paired_rows = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(paired_rows)


def _episode(index: int, value: float, split: str = "test", failed: bool = False) -> dict:
    return {
        "split": split,
        "index": index,
        "failed": failed,
        "return": -value,
        "excess_viscosity": value / 10,
        "energy_mean": value / 5,
    }


def _write(path: Path, episodes: list[dict]) -> Path:
    path.write_text(json.dumps({"episodes": episodes}))
    return path


def test_states_average_over_files_and_realisations(tmp_path: Path) -> None:
    # state 0: values 10 and 20 in two files (two seeds) -> mean 15; a failed episode and a validation
    # episode are left out
    a = _write(tmp_path / "a.json", [_episode(0, 10.0), _episode(0, 99.0, failed=True)])
    b = _write(tmp_path / "b.json", [_episode(0, 20.0), _episode(0, 99.0, split="validation")])
    states = paired_rows.per_state([a, b], "test")
    assert states == {0: pytest.approx({"return": -15.0, "excess_viscosity": 1.5, "energy_mean": 3.0})}


def test_constant_shift_gives_a_zero_width_interval(tmp_path: Path) -> None:
    # A is B with every value 2 lower on every state: return gap +2 exactly, every bootstrap mean +2,
    # energy saved 1 - sum(v - 2) / sum(v)
    values = np.array([10.0, 14.0, 20.0, 30.0])
    a = paired_rows.per_state(
        [_write(tmp_path / "a.json", [_episode(i, v - 2) for i, v in enumerate(values)])], "test"
    )
    b = paired_rows.per_state(
        [_write(tmp_path / "b.json", [_episode(i, v) for i, v in enumerate(values)])], "test"
    )
    result = paired_rows.compare(a, b)
    assert result["return"]["gap"] == pytest.approx(2.0)
    assert (result["return"]["low"], result["return"]["high"]) == pytest.approx((2.0, 2.0))
    assert result["return"]["states_higher"] == 4
    assert result["energy_mean"]["gap"] == pytest.approx(-0.4)
    assert result["energy_saved"]["energy_saved"] == pytest.approx(1 - (values - 2).sum() / values.sum())
    assert "| return | -16.500 | -18.500 | +2.000 [+2.000, +2.000] | 4/4 |" in paired_rows.table(
        result, ("A", "B")
    )


def test_different_states_are_refused(tmp_path: Path) -> None:
    a = paired_rows.per_state([_write(tmp_path / "a.json", [_episode(0, 1.0)])], "test")
    b = paired_rows.per_state([_write(tmp_path / "b.json", [_episode(1, 1.0)])], "test")
    with pytest.raises(ValueError, match="different states"):
        paired_rows.compare(a, b)


@pytest.mark.parametrize("bad", ["missing", "not_json", "no_episodes", "other_split"])
def test_bad_files_exit_2_naming_the_option(tmp_path: Path, capsys, bad: str) -> None:
    good = _write(tmp_path / "good.json", [_episode(0, 1.0)])
    path = tmp_path / "bad.json"
    if bad == "not_json":
        path.write_text("{")
    elif bad == "no_episodes":
        path.write_text(json.dumps({"label": "x"}))
    elif bad == "other_split":
        _write(path, [_episode(0, 1.0, split="validation")])
    with pytest.raises(SystemExit) as exit_info:
        paired_rows.main(["--a", str(good), "--b", str(path)])
    assert exit_info.value.code == 2
    assert "--b" in capsys.readouterr().err
