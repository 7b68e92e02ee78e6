"""Slow validation of sheared dipolophoresis (marked ``slow``): far field only, and exact near field.

Run with ``python -m pytest -m slow tests/test_validation_dip_slow.py`` (about an hour on 2 cores; the
two grids can be run alone with ``-k none`` or ``-k exact``). Settings: N = 100, strain 20 (averages over
strain 5-20, 10 blocks), seed 1, field along y, mechanism ``dip``, adaptive step (displacement bound 0.4%
of the spacing, dt <= 2e-3), far-field Ewald sums at relative accuracy 1e-6; ``near_field = "none"``
(far-field kernels only, issue 10) or ``"exact"`` (two-sphere functions blended in below r = 4 a). The
tables go to ``runs/validation_dip/<near field>/table.md`` (reproduced in the README).

What is asserted: for both grids, ``U_rms^DIP / U_rms^shear`` falls monotonically with Mn (the DIP
velocity scales as 1/Mn); for the exact near field, the paper's trends that this model reproduces
(physics.md §8, paper §3.1): phi = 0.15 nearly Newtonian (every Mn within 10% of pure shear; measured
3%), a lower viscosity at Mn = 0.1 than without field at phi >= 0.3 (measured 2.2x lower at 0.45), and
shear thickening from Mn = 0.1 to 1 to 10 at phi >= 0.3. The trends it does not reproduce (the collapse
of Mn >= 5 onto pure shear: Mn = 10 is 23-48% above it; the velocity-ratio crossing at Mn = 0.7-1: here
1.1-2; N1 > 0, N2 < 0 at phi = 0.15 and low Mn) are in the table and discussed in the README, with the
evidence; they are not asserted (a test that fails for a documented modelling reason would only be
skipped).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from sim.config import SimulationConfig
from sim.observables.stress import DIPOLOPHORESIS_CONTRIBUTIONS, SHEAR_CONTRIBUTIONS, STRESS_CONTRIBUTIONS
from sim.sweep import run_sweep

VOLUME_FRACTIONS = {"none": (0.30, 0.45), "exact": (0.15, 0.30, 0.45)}
MASON_NUMBERS = (0.1, 1.0, 10.0, math.inf)
OUT = Path(__file__).resolve().parents[1] / "runs" / "validation_dip"
SHEAR_PARTS = tuple(STRESS_CONTRIBUTIONS[k] for k in SHEAR_CONTRIBUTIONS)
DIP_PARTS = tuple(STRESS_CONTRIBUTIONS[k] for k in DIPOLOPHORESIS_CONTRIBUTIONS)


def _part(result: dict, names: tuple[str, ...], key: str) -> float:
    return sum(result["contributions"][name][key] for name in names)


def _row(config: SimulationConfig, r: dict) -> str:
    ratio = r["u_rms_dip"] / r["u_rms_shear"]
    return (
        f"| {config.volume_fraction:.2f} | {config.mason_number:g} "
        f"| {r['relative_viscosity']:.2f} ± {r['relative_viscosity_stderr']:.2f} "
        f"| {r['n1']:.2f} ± {r['n1_stderr']:.2f} | {r['n2']:.2f} ± {r['n2_stderr']:.2f} "
        f"| {_part(r, SHEAR_PARTS, 'relative_viscosity'):.2f} "
        f"/ {_part(r, DIP_PARTS, 'relative_viscosity'):.2f} "
        f"| {_part(r, SHEAR_PARTS, 'n1'):.2f} / {_part(r, DIP_PARTS, 'n1'):.2f} "
        f"| {_part(r, SHEAR_PARTS, 'n2'):.2f} / {_part(r, DIP_PARTS, 'n2'):.2f} "
        f"| {ratio:.3g} | {r['steps'] / r['strain']:.0f} | {r['wall_seconds'] / r['strain']:.1f} |"
    )


@pytest.mark.slow
@pytest.mark.parametrize("near_field", ["none", "exact"])
def test_sheared_dipolophoresis(near_field: str) -> None:
    configs = [
        SimulationConfig(
            n_particles=100,
            volume_fraction=phi,
            mason_number=mn,
            strain=20.0,
            transient_strain=5.0,
            seed=1,
            near_field=near_field,
        )
        for phi in VOLUME_FRACTIONS[near_field]
        for mn in MASON_NUMBERS
    ]
    out = OUT / near_field
    results = run_sweep(configs, out, processes=2)
    lines = [
        f"near field: {near_field}; N = 100, strain 20 (averaged 5-20), seed 1, e = y, mechanism dip",
        "",
        "| phi | Mn | eta_r | N1 | N2 | eta_r shear / DIP parts | N1 shear / DIP | N2 shear / DIP "
        "| U_rms^DIP / U_rms^shear | steps per strain | wall s per strain |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    by_point = {}
    for config, r in zip(configs, results, strict=True):
        by_point[(config.volume_fraction, config.mason_number)] = r
        lines.append(_row(config, r))
    (out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    for phi in VOLUME_FRACTIONS[near_field]:
        ratios = [
            by_point[(phi, mn)]["u_rms_dip"] / by_point[(phi, mn)]["u_rms_shear"] for mn in MASON_NUMBERS
        ]
        assert ratios[0] > ratios[1] > ratios[2] > ratios[3] == 0.0, (phi, ratios)
    if near_field != "exact":
        return
    eta = {point: r["relative_viscosity"] for point, r in by_point.items()}
    for mn in MASON_NUMBERS:
        assert abs(eta[(0.15, mn)] / eta[(0.15, math.inf)] - 1) <= 0.10, (mn, eta[(0.15, mn)])
    for phi in (0.30, 0.45):
        assert eta[(phi, 0.1)] < eta[(phi, math.inf)], phi
        assert eta[(phi, 0.1)] < eta[(phi, 1.0)] < eta[(phi, 10.0)], phi
