"""Sweeps: each run is a pure function of its config; a pool gives the same numbers as a direct run."""

from __future__ import annotations

import json

from sim import SimulationConfig, run_simulation
from sim.sweep import run_name, run_sweep

CONFIGS = [
    SimulationConfig(n_particles=40, volume_fraction=0.3, strain=0.02, seed=1),
    SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=2),
]


def test_pool_sweep_matches_direct_runs_and_reuses_results(tmp_path) -> None:
    results = run_sweep(CONFIGS, tmp_path / "sweep", processes=2)
    for config, result in zip(CONFIGS, results, strict=True):
        direct = run_simulation(config, tmp_path / "direct" / run_name(config), progress=False)
        for key in ("relative_viscosity", "n1", "n2", "steps", "min_gap"):
            assert result[key] == direct[key]  # same config and seed -> same numbers, bit for bit
        saved = json.loads((tmp_path / "sweep" / run_name(config) / "params.json").read_text())
        assert saved["config"] == config.to_dict()
    (tmp_path / "sweep" / run_name(CONFIGS[0]) / "timeseries.csv").unlink()  # finished runs are not redone
    again = run_sweep(CONFIGS, tmp_path / "sweep", processes=1)
    for cached, fresh in zip(again, results, strict=True):  # same values and types (nan compares unequal)
        assert json.dumps(cached, sort_keys=True) == json.dumps(fresh, sort_keys=True)
    assert not (tmp_path / "sweep" / run_name(CONFIGS[0]) / "timeseries.csv").exists()


def test_results_from_other_sources_or_parameters_are_recomputed(tmp_path) -> None:
    """A result is reused only if params.json names the same config and the same ``sim`` source digest."""
    config = CONFIGS[0]
    run_dir = tmp_path / "sweep" / run_name(config)
    run_sweep([config], tmp_path / "sweep", processes=1)
    params_file = run_dir / "params.json"
    params = json.loads(params_file.read_text())
    params["versions"]["sim_source"] = "0" * 16  # as if written by an older version of the simulator
    params_file.write_text(json.dumps(params))
    (run_dir / "timeseries.csv").unlink()
    run_sweep([config], tmp_path / "sweep", processes=1)
    assert (run_dir / "timeseries.csv").exists()  # recomputed
    assert json.loads(params_file.read_text())["versions"]["sim_source"] != "0" * 16
    params = json.loads(params_file.read_text())
    params["config"]["seed"] = 99  # a different run left in this directory
    params_file.write_text(json.dumps(params))
    (run_dir / "timeseries.csv").unlink()
    run_sweep([config], tmp_path / "sweep", processes=1)
    assert (run_dir / "timeseries.csv").exists()
