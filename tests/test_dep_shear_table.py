"""scripts/dep_shear_table.py: seed means, the excess over pure shear and the local power of Mn."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.agents_helpers import load_script

ETA_INF = 1.5


def point(
    root: Path, mason: float | str, seed: int, eta: float, mechanism: str = "dep", n: int = 100
) -> None:
    folder = root / f"Mn{mason}_{mechanism}_N{n}_seed{seed}"
    folder.mkdir(parents=True)
    result = {
        "relative_viscosity": eta,
        "relative_viscosity_stderr": 0.01,
        "mason_number": mason,
        "volume_fraction": 0.15,
        "mechanism": mechanism,
        "n_particles": n,
        "n1": 0.0,
        "n2": 0.0,
        "fabric_tensor": [[1 / 3, 0, 0], [0, 1 / 3, 0], [0, 0, 1 / 3]],
        "contact_number": 1.0,
    }
    (folder / "result.json").write_text(json.dumps(result))


def test_a_bingham_excess_reads_a_power_of_one_and_seeds_are_averaged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dep, dip = tmp_path / "dep", tmp_path / "dip"
    for mason in (0.1, 0.2, 0.4):
        # excess 0.1 / Mn (eta - eta_inf ~ Mn^-1, a Bingham fluid), split across two seeds by +-0.05
        point(dep, mason, 1, ETA_INF + 0.1 / mason - 0.05)
        point(dep, mason, 2, ETA_INF + 0.1 / mason + 0.05)
    point(dip, "inf", 1, ETA_INF - 0.01, mechanism="dip")
    point(dip, "inf", 2, ETA_INF + 0.01, mechanism="dip")
    point(dip, 0.1, 1, 1.4, mechanism="dip")
    assert load_script("dep_shear_table").main([str(dep), "--dip", str(dip)]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 100 |")]
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in rows]
    assert [c[1] for c in cells] == ["0.1", "0.2", "0.4"]
    assert [c[3] for c in cells] == ["2.50", "2.00", "1.75"]  # seed means: 1.5 + 0.1/Mn
    assert [c[5] for c in cells] == ["1.00", "0.50", "0.25"]  # excess over the no-field mean 1.5
    # -d ln(excess)/d ln Mn of 0.1/Mn is 1; none after the last Mn
    assert [c[12] for c in cells] == ["1.00", "1.00", ""]
    assert cells[0][13] == "1.40" and cells[1][13] == ""  # the DIP value where the DIP sweep has that Mn


def test_no_pure_shear_reference_and_a_corrupt_result_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    point(tmp_path / "dep", 0.1, 1, 2.0)
    point(tmp_path / "dip", 0.1, 1, 1.4, mechanism="dip")
    main = load_script("dep_shear_table").main
    with pytest.raises(SystemExit) as exit_info:
        main([str(tmp_path / "dep"), "--dip", str(tmp_path / "dip")])
    assert exit_info.value.code == 2 and "pure-shear reference" in capsys.readouterr().err
    point(tmp_path / "dip", "inf", 1, 1.5, mechanism="dip")
    (tmp_path / "dep" / "broken").mkdir()
    (tmp_path / "dep" / "broken" / "result.json").write_text("{")  # a truncated file: exit 2 naming it
    with pytest.raises(SystemExit) as exit_info:
        main([str(tmp_path / "dep"), "--dip", str(tmp_path / "dip")])
    assert exit_info.value.code == 2 and "broken/result.json" in capsys.readouterr().err
    (tmp_path / "dep" / "broken" / "result.json").write_text(
        '{"mason_number": 0.1, "volume_fraction": 0.15, "n_particles": 100}'
    )  # complete JSON without the mechanism: exit 2 naming the file
    with pytest.raises(SystemExit) as exit_info:
        main([str(tmp_path / "dep"), "--dip", str(tmp_path / "dip")])
    assert exit_info.value.code == 2 and "broken/result.json" in capsys.readouterr().err
