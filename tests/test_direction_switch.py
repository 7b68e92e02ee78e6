"""scripts/direction_switch.py: the switching-strain fit recovers a known exponential, and the command
turns the field of a finished run and writes its files."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _script():
    spec = importlib.util.spec_from_file_location(
        "direction_switch", ROOT / "scripts" / "direction_switch.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fit_recovers_a_known_switch() -> None:
    """eta = 26 + (8.5 - 26) exp(-g / 1.7) with 1% noise: gamma_s within 5% (the noise's effect on a
    60-point fit is ~1%), the plateaus within 0.2."""
    module = _script()
    rng = np.random.default_rng(1)
    gamma = np.arange(0.25, 15.0, 0.25)
    eta = 26.0 + (8.5 - 26.0) * np.exp(-gamma / 1.7) + rng.normal(0.0, 0.26, gamma.size)
    fit = module.fit_switch(gamma, eta)
    assert fit["gamma_s"] == pytest.approx(1.7, rel=0.05)
    assert fit["eta_inf"] == pytest.approx(26.0, abs=0.2) and fit["eta_0"] == pytest.approx(8.5, abs=0.4)
    assert fit["gamma_90"] == pytest.approx(fit["gamma_s"] * math.log(10.0))
    assert 0.75 <= fit["gamma_half_crossing"] <= 1.5  # ln 2 * 1.7 = 1.18


def test_binned_means_are_step_weighted() -> None:
    module = _script()
    strain = np.array([0.0, 0.1, 0.4, 0.6, 0.9])
    dt = np.array([0.1, 0.3, 0.2, 0.3, 0.1])
    values = np.array([[1.0], [2.0], [3.0], [4.0], [5.0]])
    centres, means = module.binned(strain, dt, values, 0.5)
    np.testing.assert_allclose(centres, [0.25, 0.75])
    np.testing.assert_allclose(means[:, 0], [(0.1 * 1 + 0.3 * 2 + 0.2 * 3) / 0.6, (0.3 * 4 + 0.1 * 5) / 0.4])


def test_switch_command_turns_the_field(tmp_path) -> None:
    from sim import SimulationConfig, run_simulation

    config = SimulationConfig(
        n_particles=32, volume_fraction=0.3, strain=0.04, mason_number=1.0, seed=3, near_field_cutoff=3.0
    )
    run_simulation(config, tmp_path / "steady", progress=False)
    module = _script()
    out = tmp_path / "switch"
    result = module.main(
        [
            "--from",
            str(tmp_path / "steady"),
            "--direction",
            "0,0,2",
            "--strain",
            "0.04",
            "--bin",
            "0.01",
            "--out",
            str(out),
        ]
    )
    assert result["from_direction"] == [0.0, 1.0, 0.0] and result["to_direction"] == [0.0, 0.0, 1.0]
    rows = (out / "switch.csv").read_text().splitlines()
    assert rows[0] == "strain_since_switch,eta_r,n1,n2" and len(rows) >= 4
    assert json.loads((out / "fit.json").read_text())["mason_number"] == 1.0
    with pytest.raises(SystemExit) as exit_info:
        module.main(
            ["--from", str(tmp_path / "nothing"), "--direction", "0,0,1", "--out", str(tmp_path / "x")]
        )
    assert exit_info.value.code == 2
