"""The facade: determinism, snapshot/restore and checkpoint/resume continue bit-identically."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sim import SimulationConfig, SimulationState, run_simulation
from sim.io import load_checkpoint, save_checkpoint
from sim.simulation import Simulation

CONFIG = SimulationConfig(n_particles=40, volume_fraction=0.35, strain=0.12, seed=5, checkpoint_every=0.05)


def _records_equal(a, b) -> None:
    np.testing.assert_array_equal(a.strain, b.strain)
    np.testing.assert_array_equal(a.stress, b.stress)
    np.testing.assert_array_equal(a.min_gap, b.min_gap)
    np.testing.assert_array_equal(a.solver_iterations, b.solver_iterations)


def test_same_seed_same_numbers_and_restore_is_bit_identical() -> None:
    one = Simulation(CONFIG)
    one.advance(30)
    two = Simulation(CONFIG)
    two.advance(12)
    snap = two.snapshot()
    two.advance(18)
    _records_equal(one.records, two.records)
    np.testing.assert_array_equal(one.state.positions, two.state.positions)
    three = Simulation(CONFIG, snap)
    three.advance(18)
    np.testing.assert_array_equal(three.state.positions, one.state.positions)
    np.testing.assert_array_equal(three.records.stress, one.records.stress[12:])


def test_checkpoint_resume_matches_uninterrupted_run(tmp_path) -> None:
    """Interrupt after a checkpoint, resume from files: final state and time series identical."""
    full = run_simulation(CONFIG, tmp_path / "full", progress=False)
    interrupted = Simulation(CONFIG)
    interrupted.advance_to(0.05)
    (tmp_path / "cut").mkdir()
    save_checkpoint(tmp_path / "cut" / "checkpoint.npz", CONFIG, interrupted.state, interrupted.records, 1.0)
    resumed = run_simulation(CONFIG, tmp_path / "cut", progress=False, resume=True)
    a = SimulationState.load(tmp_path / "full" / "final_state.npz")
    b = SimulationState.load(tmp_path / "cut" / "final_state.npz")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.previous_velocity, b.previous_velocity)
    assert (tmp_path / "full" / "timeseries.csv").read_text() == (
        tmp_path / "cut" / "timeseries.csv"
    ).read_text()
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain"):
        assert full[key] == resumed[key]
    _, _, records, _ = load_checkpoint(tmp_path / "cut" / "checkpoint.npz")
    assert records.strain.size == full["steps"]
    params = json.loads((tmp_path / "full" / "params.json").read_text())
    assert params["config"]["seed"] == CONFIG.seed
    for name in ("timeseries.csv", "result.json", "stress.png", "final_state.npz"):
        assert (tmp_path / "full" / name).exists()


def test_resume_with_other_parameters_is_refused(tmp_path) -> None:
    run_simulation(CONFIG, tmp_path, progress=False)
    other = SimulationConfig(
        **{**CONFIG.to_dict(), "seed": 9, "mason_number": float("inf"), "field_direction": (0.0, 1.0, 0.0)}
    )
    with pytest.raises(ValueError, match="different parameters"):
        run_simulation(other, tmp_path, progress=False, resume=True)
