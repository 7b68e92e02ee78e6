"""The facade: determinism, snapshot/restore and checkpoint/resume continue bit-identically."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from sim import SimulationConfig, SimulationState, run_simulation
from sim.runs.io import load_checkpoint, save_checkpoint
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
    """Interrupt after a checkpoint, resume from files: final state, time series and observables identical.

    The checkpoint is written by hand before the transient (0.06) and holds no observable accumulators:
    they start at the transient as in the full run (displacement every 0.01, g every 0.04). Resuming from
    a checkpoint that holds them: tests/test_run.py.
    """
    full = run_simulation(CONFIG, tmp_path / "full", progress=False, sample_interval=0.01)
    assert full["msd_samples"] == 7 and full["pair_distribution_samples"] == 2  # strain 0.06 and 0.1
    with np.load(tmp_path / "full" / "checkpoint.npz") as data:
        assert "observable_msd_buffer" in data.files and "displacement" in data.files
    interrupted = Simulation(CONFIG)
    interrupted.advance_to(0.05)
    (tmp_path / "cut").mkdir()
    save_checkpoint(tmp_path / "cut" / "checkpoint.npz", CONFIG, interrupted.state, interrupted.records, 1.0)
    resumed = run_simulation(CONFIG, tmp_path / "cut", progress=False, resume=True, sample_interval=0.01)
    a = SimulationState.load(tmp_path / "full" / "final_state.npz")
    b = SimulationState.load(tmp_path / "cut" / "final_state.npz")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.previous_velocity, b.previous_velocity)
    np.testing.assert_array_equal(a.displacement, b.displacement)
    for name in ("timeseries.csv", "msd.csv"):
        assert (tmp_path / "full" / name).read_text() == (tmp_path / "cut" / name).read_text(), name
    with (
        np.load(tmp_path / "full" / "pair_distribution.npz") as x,
        np.load(tmp_path / "cut" / "pair_distribution.npz") as y,
    ):
        for name in x.files:
            np.testing.assert_array_equal(x[name], y[name], err_msg=name)
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "msd_samples", "observables_note"):
        assert full[key] == resumed[key]
    _, _, records, _ = load_checkpoint(tmp_path / "cut" / "checkpoint.npz")
    assert records.strain.size == full["steps"] - 1  # it holds the state before the last step (sim.runs.run)
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


@pytest.mark.parametrize("rate", [1e-300, 1e-9, 9e-4, 1001.0, 1e20])
def test_a_shear_rate_outside_the_range_is_refused(rate: float) -> None:
    """Issue 45: ``set_shear_rate(1e-300)`` gave eta_r = -9.7e288 (eta_r = Sigma_xy / rate). Rates are 0
    or in [MIN_SHEAR_RATE, MAX_SHEAR_RATE] (sim.config.check_shear_rate), in the configuration and in
    ``set_shear_rate``; nothing changes when one is refused."""
    simulation = Simulation(CONFIG)
    before = simulation.snapshot()
    with pytest.raises(ValueError, match=r"shear_rate must be 0 \(quiescent\) or in \[0.001, 1000\]"):
        simulation.set_shear_rate(rate)
    assert simulation.shear_rate == before.shear_rate == 1.0
    with pytest.raises(ValueError, match=r"shear_rate must be 0 \(quiescent\) or in \[0.001, 1000\]"):
        dataclasses.replace(CONFIG, shear_rate=rate)
    for edge in (1e-3, 1e3):
        simulation.set_shear_rate(edge)
        assert simulation.shear_rate == edge
