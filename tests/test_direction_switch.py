"""scripts/direction_switch.py: the switching-strain fit recovers a known exponential, and the command
turns the field of a finished run and writes its files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from agents_helpers import load_script


def _binned_exponential(centres: np.ndarray, width: float, before: float, after: float, scale: float):
    """Bin means of ``after + (before - after) exp(-g / scale)`` by the midpoint rule on 20000 points per bin
    (independent of the script's closed form; its error, ~(h / scale)^2 / 24, is below 1e-7 here)."""
    out = []
    for c in centres:
        low, high = max(c - width / 2, 0.0), c + width / 2
        g = low + (np.arange(20000) + 0.5) * (high - low) / 20000
        out.append(np.mean(after + (before - after) * np.exp(-g / scale)))
    return np.array(out)


def test_bin_mean_decay_matches_brute_force_averaging() -> None:
    """The closed-form bin mean of exp(-g/s) against midpoint-rule averaging, first bin (from 0) included:
    to 1e-6 (the midpoint rule's error is below 1e-7 here)."""
    module = load_script("direction_switch")
    centres = np.array([0.25, 0.75, 3.25])
    for scale in (0.05, 0.7, 4.0):
        expected = _binned_exponential(centres, 0.5, 1.0, 0.0, scale)
        np.testing.assert_allclose(module.bin_mean_decay(centres, 0.5, scale), expected, atol=1e-6)


def test_fit_recovers_a_known_switch() -> None:
    """Bin means of eta = 26 + (8.5 - 26) exp(-g / 1.7) in 0.25-strain bins with 1% noise, anchored at
    eta_before 8.5: gamma_s within 5% (the noise's effect on a 60-point fit is ~1%), the plateau within 0.2;
    the half-way strain ln 2 x 1.7 = 1.18 lies below the reported bound, within a bin or two of it."""
    module = load_script("direction_switch")
    rng = np.random.default_rng(1)
    gamma = np.arange(0.125, 15.0, 0.25)
    eta = _binned_exponential(gamma, 0.25, 8.5, 26.0, 1.7) + rng.normal(0.0, 0.26, gamma.size)
    fit = module.fit_switch(gamma, eta, 0.25, 8.5)
    assert fit["gamma_s"] == pytest.approx(1.7, rel=0.05)
    assert fit["eta_inf"] == pytest.approx(26.0, abs=0.2) and fit["eta_before"] == 8.5
    assert fit["gamma_90"] == pytest.approx(fit["gamma_s"] * math.log(10.0))
    assert 1.18 <= fit["gamma_half_by"] <= 1.18 + 0.5


def test_fit_resolves_a_switch_faster_than_one_bin() -> None:
    """A switch from 32 to 8 with gamma_s = 0.1, seen in 0.5-strain bins (the first bin already holds
    nearly all of the change, as z -> y at Mn 0.2 does): the anchored bin-averaged fit recovers gamma_s
    within 10% (noise 0.1 on 24 bins), and the half-way bound is the first bin's upper edge, 0.5."""
    module = load_script("direction_switch")
    rng = np.random.default_rng(2)
    gamma = np.arange(0.25, 12.0, 0.5)
    eta = _binned_exponential(gamma, 0.5, 32.0, 8.0, 0.1) + rng.normal(0.0, 0.1, gamma.size)
    fit = module.fit_switch(gamma, eta, 0.5, 32.0)
    assert fit["gamma_s"] == pytest.approx(0.1, rel=0.1)
    assert fit["eta_inf"] == pytest.approx(8.0, abs=0.1)
    assert fit["gamma_half_by"] == 0.5


def test_binned_means_are_step_weighted() -> None:
    module = load_script("direction_switch")
    strain = np.array([0.0, 0.1, 0.4, 0.6, 0.9])
    dt = np.array([0.1, 0.3, 0.2, 0.3, 0.1])
    values = np.array([[1.0], [2.0], [3.0], [4.0], [5.0]])
    centres, means = module.binned(strain, dt, values, 0.5)
    np.testing.assert_allclose(centres, [0.25, 0.75])
    np.testing.assert_allclose(means[:, 0], [(0.1 * 1 + 0.3 * 2 + 0.2 * 3) / 0.6, (0.3 * 4 + 0.1 * 5) / 0.4])


def test_switch_command_turns_the_field(tmp_path) -> None:
    from sim import SimulationConfig, run_simulation

    config = SimulationConfig(
        n_particles=32, volume_fraction=0.3, strain=0.04, mason_number=1.0, seed=3, near_field_cutoff=3.0
    )
    run_simulation(config, tmp_path / "steady", progress=False)
    module = load_script("direction_switch")
    out = tmp_path / "switch"
    argv = ["--from", str(tmp_path / "steady"), "--direction", "0,0,2", "--strain", "0.04", "--bin", "0.01"]
    result = module.main([*argv, "--out", str(out)])
    assert result["from_direction"] == [0.0, 1.0, 0.0] and result["to_direction"] == [0.0, 0.0, 1.0]
    rows = (out / "switch.csv").read_text().splitlines()
    assert rows[0] == "strain_since_switch,eta_r,n1,n2" and len(rows) >= 4
    fit = json.loads((out / "fit.json").read_text())
    assert fit["mason_number"] == 1.0
    steady = json.loads((tmp_path / "steady" / "result.json").read_text())["relative_viscosity"]
    assert fit["eta_before"] == steady  # the fit starts from the source's steady eta_r
    # a rerun with switch.csv present refits only: the table is not rewritten, the fit is the same
    stamp = (out / "switch.csv").stat().st_mtime_ns
    (out / "fit.json").unlink()
    again = module.main([*argv, "--out", str(out)])
    assert (out / "switch.csv").stat().st_mtime_ns == stamp
    # switch.csv keeps 6 significant digits: the refit's values agree to 1e-3 (the fit's standard errors,
    # from a 4-bin covariance, move more and are not compared)
    for key, value in result.items():
        if not key.endswith("_error"):
            assert again[key] == (pytest.approx(value, rel=1e-3) if isinstance(value, float) else value)
    with pytest.raises(SystemExit) as exit_info:
        module.main(
            ["--from", str(tmp_path / "nothing"), "--direction", "0,0,1", "--out", str(tmp_path / "x")]
        )
    assert exit_info.value.code == 2
