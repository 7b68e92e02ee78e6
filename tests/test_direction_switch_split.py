"""scripts/direction_switch_split.py: the stress split over the first strains of a direction switch."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from agents_helpers import load_script


def test_split_bins_are_step_weighted() -> None:
    """Two contributions over steps of unequal strain, by hand; an empty bin is NaN."""
    module = load_script("direction_switch_split")
    strain = np.array([0.0, 0.1, 0.3, 0.6])
    steps = np.array([0.1, 0.2, 0.3, 0.1])
    parts = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])
    means = module.split_bins(strain, steps, parts, np.array([0.0, 0.2, 0.5, 0.6, 0.7]))
    np.testing.assert_allclose(means[0], [(0.1 * 1 + 0.2 * 2) / 0.3, (0.1 * 10 + 0.2 * 20) / 0.3])
    np.testing.assert_allclose(means[1], [3.0, 30.0])
    assert np.isnan(means[2]).all()
    np.testing.assert_allclose(means[3], [4.0, 40.0])


@pytest.fixture(scope="module")
def steady(tmp_path_factory) -> Path:
    from sim import SimulationConfig, run_simulation

    folder = tmp_path_factory.mktemp("steady") / "run"
    config = SimulationConfig(
        n_particles=32, volume_fraction=0.3, strain=0.04, mason_number=1.0, seed=3, near_field_cutoff=3.0
    )
    run_simulation(config, folder, progress=False)
    return folder


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def test_split_adds_up_to_eta_r_and_keeping_the_field_repeats_the_run(steady: Path, tmp_path) -> None:
    """The parts of each bin add up to the total, which is the step-weighted eta_r that
    ``StepRecords.rheology`` gives for the same run (an independent path: the total stress's xy over the
    rate), to 1e-9; a "switch" to the field the run already has is the "keep" run, bin for bin (the
    simulator is deterministic)."""
    from sim import SimulationConfig, SimulationState
    from sim.runs.io import read_json

    module = load_script("direction_switch_split")
    argv = ["--from", str(steady), "--direction", "0,1,0", "--strain", "0.03"]
    out = module.main([*argv, "--edges", "0", "0.01", "0.03", "--out", str(tmp_path / "same")])
    rows = _rows(out)
    assert [r["run"] for r in rows] == ["keep", "keep", "switch", "switch"]
    names = module.STRESS_CONTRIBUTIONS
    for row in rows:
        assert float(row["total"]) == pytest.approx(sum(float(row[n]) for n in names), rel=1e-5)
    for keep, switch in zip(rows[:2], rows[2:], strict=True):
        assert {k: v for k, v in keep.items() if k != "run"} == {
            k: v for k, v in switch.items() if k != "run"
        }
    config = SimulationConfig.from_dict(read_json(steady / "params.json")["config"])
    state = SimulationState.load(steady / "final_state.npz")
    strain, steps, _ = module.shear_parts(config, state, (0.0, 1.0, 0.0), 0.03)
    import sim

    simulation = sim.Simulation(config, state, keep_records=True)
    simulation.advance_to(simulation.state.time + 0.03 / simulation.shear_rate)
    eta, _, _ = simulation.records.rheology()
    first = strain < 0.01
    expected = np.sum(eta[first] * steps[first]) / steps[first].sum()
    assert float(rows[0]["total"]) == pytest.approx(expected, rel=1e-5)  # csv keeps 6 digits


def test_a_turned_field_changes_the_split_and_bad_edges_are_refused(steady: Path, tmp_path) -> None:
    """Turning the field to z changes the field's own parts from the first bin on (a different field on the
    same structure); edges that do not start at 0 or pass --strain exit with code 2."""
    module = load_script("direction_switch_split")
    turn = ["--from", str(steady), "--direction", "0,0,1", "--strain", "0.02"]
    out = module.main([*turn, "--edges", "0", "0.02", "--out", str(tmp_path / "turn")])
    keep, switch = _rows(out)
    field_parts = [n for n in module.STRESS_CONTRIBUTIONS if n.startswith(("icep", "dep"))]
    assert any(float(keep[n]) != float(switch[n]) for n in field_parts)
    for edges in (["0.01", "0.02"], ["0", "0.05"]):
        with pytest.raises(SystemExit) as exit_info:
            module.main([*turn, "--edges", *edges, "--out", str(tmp_path / "bad")])
        assert exit_info.value.code == 2
