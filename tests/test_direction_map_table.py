"""scripts/direction_map_table.py: seed averages, the stress split and the collected files."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _script():
    spec = importlib.util.spec_from_file_location(
        "direction_map_table", ROOT / "scripts" / "direction_map_table.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _result(eta: float, seed: int, mason: float) -> dict:
    parts = {
        name: {"relative_viscosity": 0.0}
        for name in (
            "solvent",
            "stokes_drag",
            "lubrication",
            "repulsion",
            "icep_isolated",
            "icep_pair",
            "dep_virial",
            "dep_stresslet",
        )
    }
    parts["lubrication"]["relative_viscosity"] = eta - 2.0
    parts["icep_pair"]["relative_viscosity"] = 1.0
    return {
        "relative_viscosity": eta,
        "relative_viscosity_stderr": 0.1,
        "n1": -1.0,
        "n1_stderr": 0.1,
        "n2": 1.0,
        "n2_stderr": 0.1,
        "layer_order": 0.05,
        "layer_order_stderr": 0.01,
        "seed": seed,
        "mason_number": mason,
        "contributions": parts,
    }


def test_table_averages_seeds_and_splits_the_stress(tmp_path) -> None:
    module = _script()
    for seed, eta in ((1, 25.0), (2, 27.0)):
        point = tmp_path / "phi0.45_z" / f"phi0.450_N500_Mn1_seed{seed}"
        point.mkdir(parents=True)
        (point / "result.json").write_text(json.dumps(_result(eta, seed, 1.0)))
        (point / "params.json").write_text("{}")
    points = module.read_points(tmp_path)
    summary = module.summarise(points[(0.45, "z", 1.0)])
    assert summary["relative_viscosity"] == pytest.approx(26.0)
    assert summary["relative_viscosity_stderr"] == pytest.approx(1.0)  # sd 1.414 / sqrt 2
    assert summary["eta_hydrodynamic"] == pytest.approx(24.0) and summary["eta_dip"] == pytest.approx(1.0)
    text = module.table(points)
    assert "| z (vorticity) | 26.00 ± 1.00 [2] |" in text
    assert module.collect(tmp_path, tmp_path / "out") == 2
    copied = tmp_path / "out" / "phi0.45_z" / "phi0.450_N500_Mn1_seed1"
    assert (copied / "result.json").exists() and (copied / "params.json").exists()
    assert math.isnan(module._mean([1.0], [math.nan])[1])
