"""scripts/thickening_summary.py: the README's summary table from committed agents.evaluate folders."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "thickening_summary", Path(__file__).parents[1] / "scripts" / "thickening_summary.py"
)
thickening_summary = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(thickening_summary)

V2 = Path(__file__).parents[1] / "results" / "thickening_control" / "v2"


def test_rows_carry_agents_evaluates_numbers(capsys: pytest.CaptureFixture) -> None:
    """The interim evaluation's PPO row and the pulse controller's, as the v2 results README quotes them
    from agents.evaluate's table and verdict; the baselines common to both folders appear once."""
    thickening_summary.main([str(V2 / "evaluation_ppo_interim"), str(V2 / "evaluation_pulse")])
    lines = capsys.readouterr().out.splitlines()
    cells = {row[0]: row for row in ([c.strip() for c in line.strip("|").split("|")] for line in lines[2:])}
    ppo = cells["ppo (ppo)"]
    assert ppo[1:5] == ["52%", "0.44", "1.77", "-45.3 [-48.1, -42.7]"]  # the return as its IQM
    assert ppo[5:] == ["+19.7 [+11.2, +27.6]", "15/16", "0.88 [0.81, 0.94]", "12 [-5, 28]%", "not met"]
    pulse = next(v for k, v in cells.items() if k.startswith("pulse on"))
    assert pulse[5:7] == ["+8.9 [+2.8, +14.6]", "12/16"] and pulse[8] == "-37 [-52, -21]%"
    assert pulse[7] == "0.75"  # no interval for a controller: the value alone
    assert cells["best constant (Mn0.5)"][5:] == [""] * 5
    assert sum(1 for line in lines if line.startswith("| best constant")) == 1
    assert len(lines) == 2 + 7  # no field, best constant, feed-forward, 2 PI, PPO, pulse


def test_an_unpaired_energy_saving_is_a_blank_cell() -> None:
    """A verdict whose saving is NaN (``agents.comparison`` could not pair the states) prints nothing in
    the energy column, not a bare per cent sign; a paired one prints its interval in per cent."""
    assert thickening_summary._percent(float("nan"), float("nan"), float("nan")) == ""
    assert thickening_summary._percent(0.12, -0.05, 0.28) == "12 [-5, 28]%"


def test_a_folder_without_results_exits_2(tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as stop:
        thickening_summary.main([str(tmp_path)])
    assert stop.value.code == 2
