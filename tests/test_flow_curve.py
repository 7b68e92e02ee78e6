"""``sim.flow_curve`` and ``python -m sim flow-curve``: holds, averages, resume, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulation, SimulationConfig, summarise
from sim.cli import main
from sim.flow_curve import FlowCurveSpec, read_rows, run_flow_curve

CONFIG = SimulationConfig(n_particles=64, volume_fraction=0.3, mason_number=2.0, seed=4)
SPEC = FlowCurveSpec(CONFIG, (0.5, 2.0), strain_per_rate=0.02, down=True)
"""Two rates up and the way back: holds at 0.5, 2, 0.5 (strain 0.02 each: 0.04, 0.01, 0.04 in time)."""


def _numbers(rows: list[dict]) -> list[dict]:
    """Rows without the wall time, NaN (no error estimate from two samples) as a string, floats as
    printed in the csv (10 significant digits), so that rows compare with ``==``."""
    return [
        {k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items() if k != "wall_seconds"}
        for row in rows
    ]


def test_holds_in_order_with_the_instantaneous_mason_number(tmp_path) -> None:
    rows = run_flow_curve(SPEC, tmp_path / "curve", progress=False)
    assert [(r["direction"], r["shear_rate"]) for r in rows] == [("up", 0.5), ("up", 2.0), ("down", 0.5)]
    assert [r["mason_number"] for r in rows] == [1.0, 4.0, 1.0]  # rate x Mn_ref
    for row in rows:
        assert row["averaged_to_strain"] - row["averaged_from_strain"] == pytest.approx(0.01, abs=0.004)
        # the shear stress is eta_r times the rate (eta_r = Sigma_xy / gammadot; same samples and weights)
        assert row["shear_stress"] == pytest.approx(row["relative_viscosity"] * row["shear_rate"], rel=1e-12)
        assert all(math.isfinite(row[k]) for k in ("relative_viscosity", "n1", "n2"))
    assert _numbers(read_rows(tmp_path / "curve" / "flow_curve.csv")) == _numbers(rows)
    assert (tmp_path / "curve" / "flow_curve.png").stat().st_size > 0


def test_the_first_hold_is_a_plain_run_at_that_rate(tmp_path) -> None:
    """The hold's average is the time average of a plain Simulation at rate 0.5 over the second half."""
    spec = FlowCurveSpec(CONFIG, (0.5,), strain_per_rate=0.02)
    rows = run_flow_curve(spec, tmp_path / "one", progress=False)
    plain = Simulation(SimulationConfig(**{**CONFIG.to_dict(), "mason_number": 2.0, "shear_rate": 0.5}))
    records = plain.advance_to(0.04)
    half = 0.5 * float(records.time[-1] + records.time_step[-1])
    expected = summarise(records, half)
    assert rows[0]["relative_viscosity"] == expected.relative_viscosity
    assert rows[0]["n1"] == expected.n1


def test_an_interrupted_curve_continues_bit_for_bit(tmp_path, monkeypatch) -> None:
    straight = run_flow_curve(SPEC, tmp_path / "straight", progress=False)
    calls = {"n": 0}
    original = Simulation.advance_to

    def interrupt_second_hold(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Simulation, "advance_to", interrupt_second_hold)
    with pytest.raises(KeyboardInterrupt):
        run_flow_curve(SPEC, tmp_path / "cut", progress=False)
    assert len(read_rows(tmp_path / "cut" / "flow_curve.csv")) == 1
    monkeypatch.setattr(Simulation, "advance_to", original)
    resumed = run_flow_curve(SPEC, tmp_path / "cut", progress=False)
    assert _numbers(resumed) == _numbers(straight)


def test_a_folder_with_another_curve_is_refused(tmp_path) -> None:
    run_flow_curve(FlowCurveSpec(CONFIG, (1.0,), strain_per_rate=0.01), tmp_path / "c", progress=False)
    with pytest.raises(ValueError, match="holds another flow curve"):
        run_flow_curve(FlowCurveSpec(CONFIG, (2.0,), strain_per_rate=0.01), tmp_path / "c", progress=False)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "result.json").write_text("{}")
    with pytest.raises(ValueError, match="holds no flow curve"):
        run_flow_curve(SPEC, tmp_path / "other", progress=False)


@pytest.mark.parametrize(
    "rates, strain, message",
    [
        ((), 1.0, "rates must list"),
        ((1.0, 0.5), 1.0, "rates must increase"),
        ((0.0, 1.0), 1.0, "rates must be finite numbers > 0"),
        ((1.0, math.inf), 1.0, "rates must be finite numbers > 0"),
        ((1.0,), 0.0, "strain_per_rate must be finite and > 0"),
        ((1.0,), math.nan, "strain_per_rate must be finite and > 0"),
    ],
)
def test_bad_specs_name_the_parameter(rates, strain, message) -> None:
    with pytest.raises(ValueError, match=message):
        FlowCurveSpec(CONFIG, rates, strain)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--rates", "1,0.5"], "--rates must increase"),
        (["--rates", "0,1"], "argument --rates: must be > 0"),
        (["--rates", "1,-1"], "argument --rates: must be a finite number >= 0"),
        (["--strain-per-rate", "0"], "--strain-per-rate must be finite and > 0"),
        (["--mason", "0"], "argument --mason: must be in (0, inf]"),
        (["--phi", "0.9"], "--phi must be in"),
    ],
)
def test_cli_bad_input_exits_2_naming_the_flag(tmp_path, capsys, arguments, message) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["flow-curve", "--n-particles", "64", "--phi", "0.3", "--out", str(tmp_path / "o"), *arguments])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_one_curve_per_field(tmp_path, capsys) -> None:
    out = tmp_path / "curves"
    code = main(
        ["flow-curve", "--n-particles", "64", "--phi", "0.3", "--mason", "2,inf", "--rates", "1,2",
         "--strain-per-rate", "0.01", "--out", str(out), "--quiet"]
    )
    assert code == 0
    for folder in ("Mn2", "Mninf"):
        assert len(read_rows(out / folder / "flow_curve.csv")) == 2
    combined = np.genfromtxt(out / "flow_curve.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert sorted(set(combined["mason_number_ref"].tolist())) == [2.0, math.inf]
    assert (out / "flow_curve.png").exists()
