"""scripts/direction_mechanism.py: the fabric of sheets normal to the field (issue 44's mechanism)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import direction_mechanism  # noqa: E402


def _sheets(spacing: float, gap: float, sites: int, planes: int, normal: int) -> tuple[np.ndarray, float]:
    """Square lattices of ``spacing`` in the planes normal to axis ``normal``, ``gap`` apart."""
    length = spacing * sites
    assert np.isclose(gap * planes, length)
    a, b, c = np.meshgrid(np.arange(sites) * spacing, np.arange(sites) * spacing, np.arange(planes) * gap)
    in_plane = [axis for axis in range(3) if axis != normal]
    positions = np.zeros((a.size, 3))
    positions[:, in_plane[0]] = a.ravel()
    positions[:, in_plane[1]] = b.ravel()
    positions[:, normal] = c.ravel()
    return positions + 0.3, length


def _point(root: Path, key: str, mason: float, positions: np.ndarray, length: float) -> None:
    folder = root / f"phi0.45_{key}" / f"point_Mn{mason:g}"
    folder.mkdir(parents=True)
    np.savez(folder / "final_state.npz", positions=positions, box_length=length, strain=0.0)
    config = {"seed": 1, "mason_number": mason}
    (folder / "params.json").write_text(json.dumps({"config": config}))
    (folder / "result.json").write_text(json.dumps({"relative_viscosity": 7.5}))


def test_sheets_normal_to_the_field_have_no_neighbours_along_it(tmp_path, capsys):
    # Sheets normal to y (field y) and normal to z (field z): nearest in-plane neighbours at 2.05 a, the
    # next at 2.9 a and the next plane at 3.075 a, all beyond the 2.2 a cut-off, so exactly half the near
    # pairs lie along each in-plane axis and none along the field: A_ff = 0, in-plane 0.5 (exact counts;
    # tolerance round-off).
    for key, normal in (("y", 1), ("z", 2)):
        positions, length = _sheets(2.05, 3.075, 6, 4, normal)
        _point(tmp_path, key, 1.0, positions, length)
    figure = tmp_path / "mechanism.png"
    assert direction_mechanism.main([str(tmp_path), "--figure", str(figure)]) == 0
    rows = [
        line
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| y (") or line.startswith("| z (")
    ]
    assert len(rows) == 2
    for row, diag in zip(rows, ((0.5, 0.0, 0.5), (0.5, 0.5, 0.0)), strict=True):
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        assert cells[2] == "7.50"
        assert float(cells[3]) == pytest.approx(0.0, abs=1e-12)
        assert [float(v) for v in cells[4:7]] == pytest.approx(list(diag), abs=1e-12)
    assert figure.is_file() and figure.stat().st_size > 10_000


def test_planar_maps_are_normalised_to_the_ideal_gas():
    # Uniform random points: the pair density on every plane averages 1 (ideal gas). 2,000 points in a box
    # of 20 a give 4.0 M ordered pairs, of which a share (2 a / 20 a) x (10 a / 20 a)^2 = 2.5%, ~100 k
    # (~50 k independent), fall in each map: the mean's Poisson sd is ~0.45%, so 2% is > 4 sd.
    rng = np.random.default_rng(0)
    length = 20.0
    positions = rng.uniform(0.0, length, size=(2000, 3))
    maps = direction_mechanism.planar_maps(positions, length, 0.37)
    for grid in maps.values():
        assert grid.mean() == pytest.approx(1.0, rel=0.02)


def test_missing_root_is_refused(tmp_path):
    with pytest.raises(SystemExit) as exc:
        direction_mechanism.main([str(tmp_path / "nothing")])
    assert exc.value.code == 2
