"""scripts/pulse_train.py: protocol parsing, bad arguments, and a short run whose field energies are known."""

import importlib.util
import json
import math
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "pulse_train", Path(__file__).parents[1] / "scripts" / "pulse_train.py"
)
pulse_train = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(pulse_train)


def test_protocols_parse() -> None:
    assert pulse_train.parse_protocol("steady:0.2") == [0.2]
    assert pulse_train.parse_protocol("steady:off") == [math.inf]
    assert pulse_train.parse_protocol("pulse:0.1:off") == [0.1, math.inf]
    assert pulse_train.parse_protocol("pulse:0.1:0.1:off:off") == [0.1, 0.1, math.inf, math.inf]
    for bad in ("steady:0.1:0.2", "pulse:0.1", "ramp:1", "steady:-1", "steady:0", "pulse:0.1:strong"):
        with pytest.raises(ValueError, match="steady:MN or pulse:MN1:MN2"):
            pulse_train.parse_protocol(bad)


@pytest.mark.parametrize(
    "flags", [["--rate", "0"], ["--rate", "nan"], ["--states", "1"], ["--skip", "4", "--intervals", "4"]]
)
def test_bad_arguments_exit_2(tmp_path: Path, flags: list[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        pulse_train.main(["--out", str(tmp_path), *flags])
    assert stop.value.code == 2


def test_pulse_alternates_and_energy_is_the_field_energy(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = [
        "--out",
        str(tmp_path),
        "--env",
        "dipenv/ThickeningControlTiny-v0",
        "--rate",
        "2",
        "--states",
        "2",
    ]
    argv += ["--intervals", "3", "--skip", "0", "--protocols", "steady:off,pulse:0.1:off,pulse:0.1:off:off"]
    pulse_train.main(argv)
    episodes = json.loads((tmp_path / "episodes.json").read_text())
    # eps E0^2 = 1/Mn_ref in eta gammadot_ref: 10 with Mn_ref = 0.1, 0 with the field off
    assert episodes["pulse:0.1:off/0"]["energy"] == pytest.approx([10.0, 0.0, 10.0], rel=1e-9)
    assert episodes["pulse:0.1:off:off/0"]["energy"] == pytest.approx([10.0, 0.0, 0.0], rel=1e-9)
    assert episodes["pulse:0.1:off/1"]["mason_number"][1] == "inf"
    assert episodes["steady:off/0"]["energy"] == [0.0, 0.0, 0.0]
    out = capsys.readouterr().out
    assert "| pulse:0.1:off |" in out
    # the phase table: the field's stress is there in the field-on phase only, and the groups sum to eta_r;
    # a pattern longer than two names each place
    assert "| pulse:0.1:off | off |" in out and "| pulse:0.1:off | 0.1 |" in out
    assert "| pulse:0.1:off:off | 2 of 3: off |" in out and "| pulse:0.1:off:off | 3 of 3: off |" in out
    on, off = pulse_train.phase_rows(episodes["pulse:0.1:off/0"], period=2, skip=0)
    assert off["field"] == 0.0 and on["field"] != 0.0
    for row in (on, off):
        assert row["hydrodynamic"] + row["repulsion"] + row["field"] == pytest.approx(row["eta_r"], rel=1e-12)
        assert 0.0 <= row["contact_number"] <= 13.0
    pulse_train.main(argv)  # a rerun reuses every stored episode
    assert json.loads((tmp_path / "episodes.json").read_text()) == episodes


def test_phase_rows_split_a_pulse_by_phase() -> None:
    parts = {name: 0.0 for name in ("solvent", "stokes_drag", "repulsion", "icep_pair", "dep_virial")}
    episode = {
        "eta_r": [9.0, 8.0, 7.0, 6.0, 5.0],
        "contributions": [
            {**parts, "solvent": 1.0, "lubrication": eta - 1.0 - f, "icep_isolated": f, "dep_stresslet": 0.0}
            for eta, f in ((9.0, 1.0), (8.0, 0.0), (7.0, 3.0), (6.0, 0.0), (5.0, 5.0))
        ],
        **{name: [1.0, 2.0, 3.0, 4.0, 5.0] for name in pulse_train.MICROSTRUCTURE},
    }
    first, second = pulse_train.phase_rows(episode, period=2, skip=1)  # intervals 1..4
    assert first["eta_r"] == 6.0 and second["eta_r"] == 7.0  # phase 0: intervals 2, 4; phase 1: 1, 3
    assert first["field"] == 4.0 and second["field"] == 0.0
    assert first["hydrodynamic"] == 2.0 and second["hydrodynamic"] == 7.0
    assert first["contact_number"] == 4.0 and second["contact_number"] == 3.0
    (steady,) = pulse_train.phase_rows(episode, period=1, skip=0)
    assert steady["eta_r"] == 7.0 and steady["field"] == 1.8
