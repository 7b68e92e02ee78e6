"""scripts/contact_angles.py: poles against equators on the contact ring of g(x, y).

Known structures through the simulator's own pair-distribution accumulator: touching chains along the field
(y) put every contact in the slab at a pole, touching rows along the flow (x) every contact at an equator,
so the measure must read 0 and 90 degrees and leave the other sector empty. This also pins the index
convention ``g_xy[x bin, y bin]`` that the script relies on (swapping it would swap poles and equators).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.observables.pair_distribution import PairDistributionAccumulator
from tests.agents_helpers import load_script

GAP = 2.1  # centre spacing, a: on the contact ring 2 <= r_xy < 2.3 of the script's default


def lattice_run(folder: Path, axis: int, mason: float = 0.1) -> Path:
    """A run folder whose g(x, y) is that of periodic rows of touching spheres along ``axis`` (0: x, 1: y),
    the rows 4.2 a apart in the two other directions (beyond the ring, and outside each other's slab)."""
    per_row, rows = 6, 3
    box = per_row * GAP
    points = []
    for i in range(per_row):
        for j in range(rows):
            for k in range(rows):
                p = [0.0, 0.0, 0.0]
                p[axis] = i * GAP
                others = [d for d in range(3) if d != axis]
                p[others[0]], p[others[1]] = j * box / rows, k * box / rows
                points.append(p)
    accumulator = PairDistributionAccumulator.for_box(len(points), box)
    accumulator.add(np.asarray(points, dtype=float), 0.0)
    folder.mkdir(parents=True)
    np.savez(folder / "pair_distribution.npz", **accumulator.result_arrays())
    config = {
        "volume_fraction": 0.1,
        "mason_number": mason,
        "mechanism": "dep",
        "n_particles": len(points),
        "seed": 1,
        "field_direction": [0.0, 1.0, 0.0],
    }
    (folder / "params.json").write_text(json.dumps({"config": config}))
    return folder


def test_chains_along_the_field_sit_at_the_poles_and_rows_along_the_flow_at_the_equators(
    tmp_path: Path,
) -> None:
    script = load_script("contact_angles")
    chains = script.measure(lattice_run(tmp_path / "chains", axis=1), (2.0, 2.3), 10.0)
    rows = script.measure(lattice_run(tmp_path / "rows", axis=0), (2.0, 2.3), 10.0)
    # the lattice is exact: its only pairs on the ring lie on the axis, so the other sector is empty (0
    # exactly) and the maximum's angle is that of the axis to within the half-width of one bin (0.05 a at
    # r = 2.1 a: atan(0.05/2.1) = 1.4 degrees)
    assert chains["poles"] > 0.0 and chains["equators"] == 0.0 and chains["peak_angle"] < 1.5
    assert rows["equators"] > 0.0 and rows["poles"] == 0.0 and rows["peak_angle"] > 88.5
    assert chains["poles"] == pytest.approx(rows["equators"], rel=1e-12)  # the same structure, turned by 90


def test_a_field_off_the_y_axis_and_bad_sectors_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = load_script("contact_angles")
    folder = lattice_run(tmp_path / "run", axis=1)
    params = json.loads((folder / "params.json").read_text())
    params["config"]["field_direction"] = [0.0, 0.0, 1.0]
    (folder / "params.json").write_text(json.dumps(params))
    with pytest.raises(ValueError, match="not y"):
        script.measure(folder, (2.0, 2.3), 10.0)
    keyless = lattice_run(tmp_path / "keyless", axis=1)
    params = json.loads((keyless / "params.json").read_text())
    del params["config"]["seed"]
    (keyless / "params.json").write_text(json.dumps(params))
    # every bad input exits 2 (argparse's usage error) naming what is wrong, without a traceback
    for argv, named in (
        ([str(keyless)], "keyless: no readable params.json"),
        ([str(folder)], "not y"),
        ([str(folder), "--half-angle", "50"], "--half-angle"),
        ([str(tmp_path / "nothing")], "neither a run folder"),
        ([str(lattice_run(tmp_path / "ok", axis=1)), "--ring", "2.0", "2.01", "--half-angle", "1"], "sector"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            script.main(argv)
        assert exit_info.value.code == 2 and named in capsys.readouterr().err
