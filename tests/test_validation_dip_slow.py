"""Slow validation of sheared dipolophoresis with far-field pair interactions (marked ``slow``).

Run with ``python -m pytest -m slow tests/test_validation_dip_slow.py`` (about 15 minutes on 2 cores).
Settings: N = 100, strain 20 (averages over strain 5-20, 10 blocks), seed 1, field along y, mechanism
``dip``, adaptive step (displacement bound 0.4% of the spacing, dt <= 2e-3), far-field Ewald sums at
relative accuracy 1e-6, no near-field correction (the exact near field is a later issue). The table goes
to ``runs/validation_dip/table.md`` (reproduced in the README).

What is asserted are the trends that follow from the model itself and from the paper (physics.md §8)
without depending on the near field: Mn = 10 within 15% of the pure-shear viscosity (the paper's
``Mn >= 5`` collapse); ``U_rms^DIP / U_rms^shear`` falling monotonically with Mn and crossing 1 between
Mn = 0.1 and 10 (paper Fig. 7: at 0.7-1). The paper's other trends (low-Mn viscosity drop, thickening
across Mn = 1, normal-stress signs) are reported in the table and discussed in the README, not asserted:
with far-field kernels only they are a measurement, not a check.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from sim.config import SimulationConfig
from sim.sweep import run_sweep

VOLUME_FRACTIONS = (0.30, 0.45)
MASON_NUMBERS = (0.1, 1.0, 10.0, math.inf)
OUT = Path(__file__).resolve().parents[1] / "runs" / "validation_dip"
SHEAR_PARTS = ("solvent", "stokes_drag", "lubrication", "repulsion")
DIP_PARTS = ("icep_isolated", "icep_pair", "dep_virial")


def _part(result: dict, names: tuple[str, ...], key: str) -> float:
    return sum(result["contributions"][name][key] for name in names)


@pytest.mark.slow
def test_sheared_dipolophoresis_far_field() -> None:
    configs = [
        SimulationConfig(
            n_particles=100,
            volume_fraction=phi,
            mason_number=mn,
            strain=20.0,
            transient_strain=5.0,
            seed=1,
            near_field="none",
        )
        for phi in VOLUME_FRACTIONS
        for mn in MASON_NUMBERS
    ]
    results = run_sweep(configs, OUT, processes=2)
    lines = [
        "| phi | Mn | eta_r | N1 | N2 | eta_r shear / DIP parts | N1 shear / DIP | N2 shear / DIP "
        "| U_rms^DIP / U_rms^shear | steps per strain |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    by_point = {}
    for config, r in zip(configs, results, strict=True):
        by_point[(config.volume_fraction, config.mason_number)] = r
        ratio = r["u_rms_dip"] / r["u_rms_shear"]
        lines.append(
            f"| {config.volume_fraction:.2f} | {config.mason_number:g} "
            f"| {r['relative_viscosity']:.2f} ± {r['relative_viscosity_stderr']:.2f} "
            f"| {r['n1']:.2f} ± {r['n1_stderr']:.2f} | {r['n2']:.2f} ± {r['n2_stderr']:.2f} "
            f"| {_part(r, SHEAR_PARTS, 'relative_viscosity'):.2f} "
            f"/ {_part(r, DIP_PARTS, 'relative_viscosity'):.2f} "
            f"| {_part(r, SHEAR_PARTS, 'n1'):.2f} / {_part(r, DIP_PARTS, 'n1'):.2f} "
            f"| {_part(r, SHEAR_PARTS, 'n2'):.2f} / {_part(r, DIP_PARTS, 'n2'):.2f} "
            f"| {ratio:.3g} | {r['steps'] / r['strain']:.0f} |"
        )
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    for phi in VOLUME_FRACTIONS:
        pure = by_point[(phi, math.inf)]["relative_viscosity"]
        assert abs(by_point[(phi, 10.0)]["relative_viscosity"] / pure - 1) <= 0.15
        ratios = [
            by_point[(phi, mn)]["u_rms_dip"] / by_point[(phi, mn)]["u_rms_shear"] for mn in MASON_NUMBERS
        ]
        assert ratios[0] > ratios[1] > ratios[2] > ratios[3] == 0.0
        assert ratios[0] > 1.0 > ratios[2]
