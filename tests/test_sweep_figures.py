"""``python -m sim figures``: on a synthetic sweep folder with known numbers, every figure is drawn and
summary.csv holds the seed means and standard errors computed here independently; the crossover Mason
number of a power-law velocity ratio is found to 1e-12; older folders (no g(x, y), no diffusivities) get
the other figures and a note."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from sim.plots.sweep import crossover_mason, load_sweep, make_figures, mean_pair_distribution
from sim.runs.cli import main
from sim.runs.io import write_json

PHIS = (0.3, 0.45)
MASONS = (0.5, 1.0, 5.0, math.inf)
CROSSOVER = {0.3: 0.8, 0.45: 1.7}
"""U_rms^DIP / U_rms^shear = (Mn / Mn_c)^-1.3 exactly (seed factors 1 -/+ 0.05 average out)."""
SINGLE_SEED = (0.45, 0.5)
"""The one (phi, Mn) with a single seed: its error bars are the run's own standard errors."""

ALL_FIGURES = {
    "viscosity_vs_phi.png",
    "viscosity_vs_mason.png",
    "normal_stress_vs_mason.png",
    "velocity_ratio_vs_mason.png",
    "pair_distribution.png",
    "diffusivity.png",
    "summary.csv",
}


def fake_result(phi: float, mason: float, seed: int, with_new_keys: bool = True) -> dict:
    """A result.json with made-up but known numbers."""
    field = 0.0 if math.isinf(mason) else 1.0 / mason
    wobble = {1: -0.05, 2: 0.05}[seed]
    result = {
        "relative_viscosity": 2.0 + 10.0 * phi + 0.3 * seed + field,
        "relative_viscosity_stderr": 0.01 * seed,
        "n1": -phi * (1.0 + 0.1 * seed) * (1.0 + field),
        "n1_stderr": 0.02,
        "n2": -2.0 * phi * (1.0 - 0.1 * seed) * (1.0 + 2.0 * field),
        "n2_stderr": 0.03,
        "u_rms_dip": 0.0 if math.isinf(mason) else (mason / CROSSOVER[phi]) ** -1.3 * (1.0 + wobble),
        "u_rms_shear": 1.0,
        "volume_fraction": phi,
        "mason_number": mason,
        "n_particles": 40,
        "mechanism": "dip",
        "near_field": "exact" if not math.isinf(mason) else "none",
        "field_direction": [0.0, 1.0, 0.0],
        "shear_rate": 1.0,
        "seed": seed,
        "strain": 0.02,
    }
    if with_new_keys:
        result["diffusivity_yy"] = 0.01 * (1.0 + phi) * (1.0 + field) * (1.0 + wobble)
        result["diffusivity_zz"] = 0.02 * (1.0 + phi)
        result["layer_order"] = 0.1 * phi + 0.01 * seed
        result["layer_order_stderr"] = 0.005
        result["layer_spacing"] = 2.45
        result["layer_onset_strain"] = 1.0 + seed if seed == 1 else math.nan  # seed 2 never layered
    return result


def write_sweep(root: Path, with_new_keys: bool = True) -> dict[tuple[float, float, int], dict]:
    """A sweep folder of fake points; returns each point's result by (phi, Mn, seed)."""
    results = {}
    for phi in PHIS:
        for mason in MASONS:
            for seed in (1,) if (phi, mason) == SINGLE_SEED else (1, 2):
                folder = root / f"phi{phi:.3f}_N40_Mn{mason:g}_seed{seed}"
                folder.mkdir(parents=True)
                result = fake_result(phi, mason, seed, with_new_keys)
                write_json(folder / "result.json", result)
                results[(phi, mason, seed)] = result
                if with_new_keys:
                    edges = np.linspace(-4.0, 4.0, 9)
                    g_xy = np.full((8, 8), float(seed)) + np.arange(8)[:, None] * 0.1  # varies along x
                    np.savez(
                        folder / "pair_distribution.npz",
                        x_edges=edges,
                        y_edges=edges,
                        g_xy=g_xy,
                        samples=seed,
                    )
    return results


def read_summary(path: Path) -> dict[tuple[float, float], dict[str, float | str]]:
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    return {(float(r["volume_fraction"]), float(r["mason_number"])): r for r in rows}


def mean_and_stderr(values: list[float]) -> tuple[float, float]:
    """Independent of the module: mean and sample standard deviation / sqrt(n)."""
    n = len(values)
    mean = sum(values) / n
    return mean, math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1)) / math.sqrt(n)


def test_every_figure_and_the_summary_numbers(tmp_path: Path) -> None:
    root = tmp_path / "sweep"
    results = write_sweep(root)
    notes: list[str] = []
    written = make_figures(root, log=notes.append)
    assert {p.name for p in written} == ALL_FIGURES
    for path in written:
        assert path.parent == root / "figures" and path.stat().st_size > 0
        if path.suffix == ".png":
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = read_summary(root / "figures" / "summary.csv")
    assert len(rows) == len(PHIS) * len(MASONS)
    for (phi, mason), row in rows.items():
        seeds = [s for s in (1, 2) if (phi, mason, s) in results]
        assert int(row["n_seeds"]) == len(seeds)
        for name, key in (("eta_r", "relative_viscosity"), ("n1", "n1"), ("n2", "n2")):
            values = [results[(phi, mason, s)][key] for s in seeds]
            if len(values) > 1:
                expected = mean_and_stderr(values)
            else:
                expected = (values[0], results[(phi, mason, seeds[0])][f"{key}_stderr"])
            assert float(row[name]) == pytest.approx(expected[0], rel=1e-12)
            assert float(row[f"{name}_stderr"]) == pytest.approx(expected[1], rel=1e-12)
        assert float(row["maron_pierce"]) == pytest.approx((1 - phi / 0.63) ** -2, rel=1e-14)
        assert float(row["mason_crossover"]) == pytest.approx(CROSSOVER[phi], rel=1e-12)
        if math.isinf(mason):
            assert row["u_rms_ratio"] == "nan" and float(row["n1_over_pure_shear"]) == 1.0
            continue
        ratios = [
            results[(phi, mason, s)]["u_rms_dip"] / results[(phi, mason, s)]["u_rms_shear"] for s in seeds
        ]
        assert float(row["u_rms_ratio"]) == pytest.approx(sum(ratios) / len(ratios), rel=1e-12)
        if len(seeds) > 1:  # the seed factors average out: the power law itself
            assert float(row["u_rms_ratio"]) == pytest.approx((mason / CROSSOVER[phi]) ** -1.3, rel=1e-12)
        # N1 over the pure-shear value of the same phi, errors of both (seed stderrs) combined
        pure = mean_and_stderr([results[(phi, math.inf, s)]["n1"] for s in (1, 2)])
        here = (
            mean_and_stderr([results[(phi, mason, s)]["n1"] for s in seeds])
            if len(seeds) > 1
            else (results[(phi, mason, 1)]["n1"], 0.02)
        )
        ratio = here[0] / pure[0]
        error = abs(ratio) * math.hypot(here[1] / here[0], pure[1] / pure[0])
        assert float(row["n1_over_pure_shear"]) == pytest.approx(ratio, rel=1e-12)
        assert float(row["n1_over_pure_shear_stderr"]) == pytest.approx(error, rel=1e-12)
        d_yy = [results[(phi, mason, s)]["diffusivity_yy"] for s in seeds]
        assert float(row["diffusivity_yy"]) == pytest.approx(sum(d_yy) / len(d_yy), rel=1e-12)
        psi = [results[(phi, mason, s)]["layer_order"] for s in seeds]
        expected_psi = mean_and_stderr(psi) if len(psi) > 1 else (psi[0], 0.005)
        assert float(row["layer_order"]) == pytest.approx(expected_psi[0], rel=1e-12)
        assert float(row["layer_order_stderr"]) == pytest.approx(expected_psi[1], rel=1e-12)
        assert float(row["layer_spacing"]) == 2.45
        assert float(row["layer_onset_strain"]) == 2.0  # seed 1's; seed 2 has none
    single = rows[SINGLE_SEED]
    assert single["diffusivity_yy_stderr"] == "nan"  # one seed and no per-run error: no bar
    assert any("Mn_c = 0.8" in note for note in notes) and any("Mn_c = 1.7" in note for note in notes)


def test_seed_average_of_the_pair_distribution_is_weighted_by_samples(tmp_path: Path) -> None:
    write_sweep(tmp_path / "sweep")
    (series,) = load_sweep(tmp_path / "sweep")
    x_edges, y_edges, g = mean_pair_distribution(series.groups[(0.3, 1.0)])
    assert x_edges.shape == (9,) and g.shape == (8, 8)
    # seed 1 (value 1, 1 sample) and seed 2 (value 2, 2 samples): (1 + 4) / 3 on top of the x ramp
    np.testing.assert_allclose(g, 5.0 / 3.0 + np.arange(8)[:, None] * 0.1 * np.ones((1, 8)), rtol=1e-14)


def test_crossover_by_log_linear_interpolation() -> None:
    masons = [0.1, 0.5, 1.0, 2.0, 5.0, 10.0, math.inf]
    for mn_c, power in ((0.8, 1.3), (0.7, 0.5), (3.0, 2.0)):
        ratios = [0.0 if math.isinf(m) else (m / mn_c) ** -power for m in masons]
        assert crossover_mason(masons, ratios) == pytest.approx(mn_c, rel=1e-12)
    # not a power law: the straight log-log segment between Mn = 0.5 (ratio 3) and Mn = 2 (ratio 0.6)
    expected = 0.5 * 4.0 ** (math.log(3.0) / math.log(5.0))
    assert crossover_mason([2.0, 0.5], [0.6, 3.0]) == pytest.approx(expected, rel=1e-12)
    assert crossover_mason([0.5, 1.0, 2.0], [3.0, 1.0, 0.5]) == 1.0  # exactly 1 at a sampled point
    assert math.isnan(crossover_mason([0.5, 1.0], [3.0, 2.0]))  # no crossing in the range
    assert math.isnan(crossover_mason([], []))


def test_older_sweep_folders_skip_the_missing_figures(tmp_path: Path, capsys) -> None:
    root = tmp_path / "sweep"
    write_sweep(root, with_new_keys=False)
    out = tmp_path / "figs"
    assert main(["figures", str(root), "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "pair_distribution.png skipped: no pair_distribution.npz" in stdout
    assert "diffusivity.png skipped: no finite diffusivity_yy" in stdout
    assert {p.name for p in out.iterdir()} == ALL_FIGURES - {"pair_distribution.png", "diffusivity.png"}
    rows = read_summary(out / "summary.csv")
    assert all(r["diffusivity_yy"] == "nan" and r["layer_order"] == "nan" for r in rows.values())


def test_without_pure_shear_the_normal_stress_figure_is_skipped(tmp_path: Path) -> None:
    root = tmp_path / "sweep"
    write_sweep(root)
    for folder in root.glob("*_Mninf_*"):
        (folder / "result.json").unlink()
    notes: list[str] = []
    names = {p.name for p in make_figures(root, log=notes.append)}
    assert "normal_stress_vs_mason.png" not in names and "viscosity_vs_mason.png" in names
    assert any("no pure-shear (Mn = inf) point" in n for n in notes)


def test_series_that_differ_in_n_get_their_own_files(tmp_path: Path) -> None:
    root = tmp_path / "sweep"
    write_sweep(root)
    folder = root / "phi0.300_N64_Mn1_seed1"
    folder.mkdir()
    write_json(folder / "result.json", {**fake_result(0.3, 1.0, 1), "n_particles": 64})
    names = {p.name for p in make_figures(root, log=None)}
    assert {"viscosity_vs_phi_N40.png", "viscosity_vs_phi_N64.png", "summary.csv"} <= names
    rows = list(csv.DictReader((root / "figures" / "summary.csv").open()))
    assert {r["series"] for r in rows} == {"N40", "N64"}


def test_cli_refuses_a_folder_without_results(tmp_path: Path, capsys) -> None:
    for target, needle in ((tmp_path / "nowhere", "is not a folder"), (tmp_path, "no <point>/result.json")):
        with pytest.raises(SystemExit) as exc:
            main(["figures", str(target)])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith("usage: python -m sim figures") and "python -m sim figures: error: DIR" in err
        assert needle in err


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (b'{"relative_viscosity": 2.1, "volume', "not a valid result.json (JSONDecodeError"),  # truncated
        (b"\x89PNG\x00\xff\xfe", "not a valid result.json (UnicodeDecodeError"),  # binary
        (b"[1, 2, 3]", "not a run's result (a JSON object expected, got list)"),  # was a TypeError
        (b'{"relative_viscosity": 2.1}', "volume_fraction must be a number in (0, 1), got None"),  # KeyError
        (
            b'{"volume_fraction": 0.3, "mason_number": "x", "field_direction": 3}',
            "mason_number must be a number > 0 or 'inf', got 'x'; field_direction must be three numbers",
        ),
        (b'{"volume_fraction": 0.3, "mason_number": 1, "near_field": {"a": 1}}', "near_field must be"),
    ],
)
def test_cli_names_a_corrupt_or_foreign_result(content: bytes, needle: str, tmp_path: Path, capsys) -> None:
    root = tmp_path / "sweep"
    write_sweep(root)
    bad = root / "phi0.300_N40_Mn1_seed1" / "result.json"
    bad.write_bytes(content)
    with pytest.raises(SystemExit) as exc:
        main(["figures", str(root), "--out", str(tmp_path / "figs")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"python -m sim figures: error: {bad}: " in err and needle in err, err
    assert "rerun the sweep to redo it" in err
    assert not (tmp_path / "figs").exists()  # refused before anything is written


def test_cli_refuses_an_out_that_is_a_file_or_below_one(tmp_path: Path, capsys) -> None:
    """Both were tracebacks (FileExistsError, NotADirectoryError)."""
    root = tmp_path / "sweep"
    write_sweep(root)
    afile = tmp_path / "notes.txt"
    afile.write_text("keep\n")
    for out, needle in (
        (afile, f"--out {afile} exists and is not a directory"),
        (afile / "sub", f"--out {afile / 'sub'} cannot be created: {afile} is not a directory"),
    ):
        with pytest.raises(SystemExit) as exc:
            main(["figures", str(root), "--out", str(out)])
        assert exc.value.code == 2
        assert f"python -m sim figures: error: {needle}" in capsys.readouterr().err
    assert afile.read_text() == "keep\n"


def test_cli_names_a_file_it_cannot_write(tmp_path: Path, capsys, monkeypatch) -> None:
    """A write that fails after the checks (a read-only folder, a full disk) exits 2 naming the file."""
    import sim.plots.sweep

    root = tmp_path / "sweep"
    write_sweep(root)

    def read_only(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", str(tmp_path / "figs" / "summary.csv"))

    monkeypatch.setattr(sim.plots.sweep, "write_summary", read_only)
    with pytest.raises(SystemExit) as exc:
        main(["figures", str(root), "--out", str(tmp_path / "figs"), "--quiet"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"error: --out: cannot write {tmp_path / 'figs' / 'summary.csv'}: Permission denied" in err
