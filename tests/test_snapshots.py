"""Snapshots at multiples of the strain (``sim.runs.snapshots``) and the schedule of kept states
(``sim.runs.schedule``): names, the multiples a run from a given state keeps, resuming the schedule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim import SimulationConfig, SimulationState, run_simulation
from sim.runs.initial_state import read_initial_state
from sim.runs.schedule import StrainMultiples, multiples_decimals
from sim.runs.snapshots import snapshot_name

SHORT = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=3)


def test_names_carry_the_decimals_the_spacing_needs() -> None:
    assert [multiples_decimals(s) for s in (1.0, 5.0, 0.5, 0.25, 0.1, 0.005, 1 / 3)] == [0, 0, 1, 2, 1, 3, 6]
    assert snapshot_name(5.0, 1.0) == "strain_0005.npz"
    assert snapshot_name(2.5, 0.5) == "strain_0002.5.npz"
    assert snapshot_name(120.0, 0.5) == "strain_0120.0.npz"
    assert snapshot_name(0.015, 0.005) == "strain_0000.015.npz"
    assert snapshot_name(3.0, 1.0, quiescent=True) == "time_0003.npz"
    names = [snapshot_name(k * 0.25, 0.25) for k in range(1, 60)]
    assert names == sorted(names) and len(set(names)) == len(names)  # in order, none twice


def test_the_multiples_of_a_run_from_a_given_state() -> None:
    """A run from strain 37.2 at clock 50 and rate 2 keeps strains 38, 39, ... (snapshots; the
    trajectory would keep 37.2 itself only if it were a multiple), reached at clock 50 + (k - 37.2)/2."""
    snapshots = StrainMultiples.for_run(1.0, 50.0, 37.2, 2.0, 0.002, include_start=False)
    assert snapshots.next_index == 38 and snapshots.next_clock == pytest.approx(50.4)
    frames = StrainMultiples.for_run(0.5, 0.0, 0.0, 1.0, 0.002, include_start=True)
    assert frames.next_index == 0 and frames.due(0.0) == 0 and frames.next_index == 1
    on_a_multiple = StrainMultiples.for_run(1.0, 0.0, 3.0, 1.0, 0.002, include_start=False)
    assert on_a_multiple.next_index == 4
    # a step past several multiples keeps the state once, for the first; the next is the first not passed
    assert frames.due(0.49) is None and frames.due(1.7) == 1 and frames.next_index == 4
    # resuming at a checkpoint's clock: the multiples it reached were kept before it was written
    resumed = StrainMultiples.for_run(0.5, 0.0, 0.0, 1.0, 0.002, clock=1.7, include_start=True)
    assert resumed.next_index == 4
    quiescent = StrainMultiples.for_run(0.5, 2.2, 2.2, 0.0, 0.002, include_start=False)
    assert quiescent.next_index == 5 and quiescent.next_clock == 2.5  # the length is the clock


def test_snapshots_hold_final_states_that_initial_state_reads(tmp_path: Path) -> None:
    result = run_simulation(SHORT, tmp_path / "o", progress=False, snapshot_every=0.005)
    folder = tmp_path / "o" / "snapshots"
    assert sorted(p.name for p in folder.iterdir()) == [
        "strain_0000.005.npz",
        "strain_0000.010.npz",
        "strain_0000.015.npz",
        "strain_0000.020.npz",
    ]
    last = SimulationState.load(folder / "strain_0000.020.npz")
    final = SimulationState.load(tmp_path / "o" / "final_state.npz")
    np.testing.assert_array_equal(last.positions, final.positions)  # the end, at exactly 0.02
    assert last.step == result["steps"] and abs(last.strain - 0.02) < 1e-12
    for path in folder.iterdir():
        state = SimulationState.load(path)
        nominal = float(path.stem.split("_")[1])
        assert nominal - 1e-12 <= state.strain < nominal + SHORT.time_step  # the first step at or after it
        initial = read_initial_state(path)
        assert initial.box_length == SHORT.box_length and initial.strain == state.strain
    # a rerun of another length (--overwrite) starts the folder of snapshots afresh
    run_simulation(
        SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.01, seed=3),
        tmp_path / "o",
        progress=False,
        snapshot_every=0.005,
        overwrite=True,
    )
    assert sorted(p.name for p in folder.iterdir()) == ["strain_0000.005.npz", "strain_0000.010.npz"]
