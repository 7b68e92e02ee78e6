"""scripts/field_pulsing.py: the switch and strongest-field shares on traces whose answers are known."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location(
    "field_pulsing", Path(__file__).parents[1] / "scripts" / "field_pulsing.py"
)
field_pulsing = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(field_pulsing)


def _fractions(mason: list, rate: list) -> tuple[float, float, float]:
    return field_pulsing.episode_fractions(
        {"mason_number": mason, "shear_rate": rate}, strongest=0.1, weak=5.0, high_rate=2.0, low_rate=1.0
    )


def test_constant_field_never_switches() -> None:
    strong_high, strong_low, switches = _fractions([0.1] * 6, [3.0] * 6)
    assert (strong_high, switches) == (1.0, 0.0)
    assert math.isnan(strong_low)  # no interval below rate 1


def test_alternating_field_switches_every_interval() -> None:
    # strongest, off, strongest, weak (Mn_ref 10), strongest at rate 3: every consecutive pair switches
    strong_high, _, switches = _fractions([0.1, "inf", 0.1, 10.0, 0.1], [3.0] * 5)
    assert switches == 1.0
    assert strong_high == pytest.approx(3 / 5)


def test_rates_split_the_shares() -> None:
    # two slow intervals (one strongest), then two fast ones (both weak): only the fast pairs count
    strong_high, strong_low, switches = _fractions([0.1, 1.0, 5.0, "inf"], [0.5, 0.5, 3.0, 3.0])
    assert strong_low == 0.5
    assert strong_high == 0.0
    assert switches == 0.0  # pairs ending above rate 2: (1.0 -> 5.0) and (5.0 -> off), neither strongest


def test_rate_bins_average_within_each_bin() -> None:
    # two episodes: rates 0.5 (energy 2, eta_r 8 -> excess 0.3) and 3 (energy 0 and 10, eta_r 7 -> 0)
    first = {
        "shear_rate": [0.5, 3.0],
        "field_energy": [2.0, 0.0],
        "eta_r": [8.0, 7.0],
        "eta_cap": 7.7,
        "reward": [-0.9, 0.0],
    }
    second = {
        "shear_rate": [3.0, 9.0],
        "field_energy": [10.0, 1.0],
        "eta_r": [7.0, 9.0],
        "eta_cap": 7.7,
        "reward": [-3.0, -1.0],
    }
    table = field_pulsing.rate_bin_means([first, second], np.array([0.2, 1.0, 5.0, 6.0]))
    assert table[:, 0] == pytest.approx([0.25, 0.5, 0.0])  # the rate-9 interval is outside the edges
    assert table[0, 1:] == pytest.approx([2.0, 0.3, -0.9])
    assert table[1, 1:] == pytest.approx([5.0, 0.0, -1.5])
    assert np.isnan(table[2, 1:]).all()


def _episode_file(path: Path, rates: list[float], energies: list[float]) -> Path:
    trace = {
        "mason_number": [1.0 / e if e > 0 else "inf" for e in energies],
        "shear_rate": rates,
        "field_energy": energies,
        "eta_r": [8.0] * len(rates),
        "eta_cap": 7.7,
        "reward": [-1.0] * len(rates),
    }
    path.write_text(json.dumps({"episodes": [{"trace": trace}]}))
    return path


def test_plot_pools_equal_labels(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two files under one label are one line whose bin means pool both files' intervals; a third file
    under its own label is a second line."""
    a = _episode_file(tmp_path / "a.json", [0.5, 3.0], [1.0, 4.0])
    b = _episode_file(tmp_path / "b.json", [0.5, 3.0], [3.0, 0.0])
    c = _episode_file(tmp_path / "c.json", [0.5, 3.0], [2.0, 2.0])
    drawn = {}
    monkeypatch.setattr(field_pulsing, "plot_rate_bins", lambda tables, edges, path: drawn.update(tables))
    field_pulsing.main(
        [str(a), str(b), str(c), "--rate-bins", "0.2,1,5", "--plot", "x.png", "--labels", "P,P,C"]
    )
    assert list(drawn) == ["P", "C"]
    assert drawn["P"][:, 1] == pytest.approx([2.0, 2.0])  # (1 + 3)/2 below rate 1, (4 + 0)/2 above
    assert drawn["C"][:, 1] == pytest.approx([2.0, 2.0])


def test_plot_writes_a_png(tmp_path: Path) -> None:
    a = _episode_file(tmp_path / "a.json", [0.5, 3.0], [1.0, 4.0])
    field_pulsing.main([str(a), "--rate-bins", "0.2,1,5", "--plot", str(tmp_path / "bins.png")])
    assert (tmp_path / "bins.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "extra", [["--plot", "x.png", "--labels", "A,B"], ["--labels", "A"]], ids=["count", "no-plot"]
)
def test_bad_labels_exit_2(tmp_path: Path, extra: list[str]) -> None:
    a = _episode_file(tmp_path / "a.json", [0.5], [1.0])
    with pytest.raises(SystemExit) as stop:
        field_pulsing.main([str(a), *extra])
    assert stop.value.code == 2
