"""Slow validation of sheared dipolophoresis with far-field kernels only (marked ``slow``).

Run with ``python -m pytest -m slow tests/test_validation_dip_slow.py`` (about 20 minutes on 2 cores).
Settings: N = 100, strain 20 (averages over strain 5-20, 10 blocks), seed 1, field along y, mechanism
``dip``, adaptive step (displacement bound 0.4% of the spacing, dt <= 2e-3), far-field Ewald sums at
relative accuracy 1e-6, ``near_field = "none"`` (the far-field kernels of issue 10, no two-sphere
corrections). The table goes to ``runs/validation_dip/none/table.md``. The paper's model (exact near
field) is validated by ``tests/test_validation_paper_grid_slow.py``.

What is asserted: ``U_rms^DIP / U_rms^shear`` falls monotonically with Mn (the DIP velocity scales as
1/Mn). The far-field model's viscosities are reported, not asserted: without the near field the
truncated ICEP kernel still attracts at contact and the field raises eta_r at every Mn (docs/validation.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from sim.config import SimulationConfig
from sim.observables.stress import DIPOLOPHORESIS_CONTRIBUTIONS, SHEAR_CONTRIBUTIONS, STRESS_CONTRIBUTIONS
from sim.runs.sweep import run_sweep

VOLUME_FRACTIONS = {"none": (0.30, 0.45)}
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
@pytest.mark.parametrize("near_field", ["none"])
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
