"""Slow validation of pure-shear rheology against Maron–Pierce (marked ``slow``).

Run with ``python -m pytest -m slow`` (about 3 minutes on 2 cores). Settings: N = 200, strain 30,
dt = 2e-3, averages over strain 10-30 with 10 blocks, seed 1, default lubrication (cut-off 0.5 a,
regularisation 1e-3 a). The table is written to ``runs/validation/table.md`` (reproduced in the
docs/validation.md) and plotted in ``runs/validation/viscosity.png``.

Independent numbers: Maron–Pierce ``eta_r = (1 - phi/0.63)^-2`` (the correlation the paper validates
against, its Fig. 2a); within 20% for phi <= 0.45 (phi = 0.50 is reported, not asserted). The band
covers what separates this model from the experiments behind the correlation: no far-field many-body
hydrodynamics (which raises eta_r at moderate phi), frictionless spheres whose viscosity diverges at
frictionless random close packing rather than 0.63, finite N, and the lubrication regularisation
(delta = 1e-3 a, as in Mari et al. 2014, gives 10.26 at phi = 0.45, -16%; delta = 1e-4 gave 11.11, -9%;
docs/validation.md). A sign error or a missing contribution moves eta_r(0.45) by far more than 20%.
N1 < 0 and N2 < 0 (Sierou & Brady 2002; paper Fig. 4 insets) at phi >= 0.30 where they exceed their
standard errors.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.config import SimulationConfig
from sim.plots.figures import plot_viscosity_curve
from sim.runs.sweep import run_sweep

VOLUME_FRACTIONS = (0.15, 0.30, 0.40, 0.45, 0.50)
OUT = Path(__file__).resolve().parents[1] / "runs" / "validation"


def maron_pierce(phi: float, phi_max: float = 0.63) -> float:
    return (1.0 - phi / phi_max) ** -2


@pytest.mark.slow
def test_pure_shear_viscosity_against_maron_pierce() -> None:
    configs = [
        SimulationConfig(n_particles=200, volume_fraction=phi, strain=30.0, seed=1)
        for phi in VOLUME_FRACTIONS
    ]
    results = run_sweep(configs, OUT, processes=2)
    lines = [
        "| phi | eta_r | Maron–Pierce | deviation | N1 | N2 | repulsion share of eta_r |",
        "|---|---|---|---|---|---|---|",
    ]
    for phi, r in zip(VOLUME_FRACTIONS, results, strict=True):
        mp_value = maron_pierce(phi)
        dev = r["relative_viscosity"] / mp_value - 1
        rep = r["contributions"]["repulsion"]["relative_viscosity"] / r["relative_viscosity"]
        lines.append(
            f"| {phi:.2f} | {r['relative_viscosity']:.3f} ± {r['relative_viscosity_stderr']:.3f} "
            f"| {mp_value:.2f} | {100 * dev:+.0f}% | {r['n1']:.2f} ± {r['n1_stderr']:.2f} "
            f"| {r['n2']:.2f} ± {r['n2_stderr']:.2f} "
            f"| {100 * rep:.0f}% |"
        )
    (OUT / "table.md").write_text("\n".join(lines) + "\n")
    plot_viscosity_curve(list(VOLUME_FRACTIONS), results, OUT / "viscosity.png")
    print("\n".join(lines))
    for phi, r in zip(VOLUME_FRACTIONS, results, strict=True):
        if phi <= 0.45:
            assert abs(r["relative_viscosity"] / maron_pierce(phi) - 1) <= 0.20, (
                phi,
                r["relative_viscosity"],
            )
        if phi >= 0.30:
            assert r["n1"] < 0 and r["n2"] < 0, (phi, r["n1"], r["n2"])


@pytest.mark.slow
def test_repulsion_stress_in_sierou_brady_decomposition() -> None:
    """phi = 0.45, N = 200, seed 1: sample 60 configurations over strain 5-11 and split the repulsion's
    stress (sim.observables.interparticle_stress). The paper calls the interparticle-force stress
    negligible; here the direct virial alone is about a third of eta_r, and the hydrodynamic stresslet
    it induces cancels it to within a few per cent (measured 5.7% at the default delta = 1e-3, 1% at
    1e-4: a regularised pair is not quite rigid, residual 2.5 gap + 2 delta for an isolated pair, see
    tests/test_interparticle_stress.py; asserted: |total_xy| < 10% of |virial_xy|, i.e. the total stays
    a few per cent of eta_r)."""
    import numpy as np

    from sim import Simulation
    from sim.observables.interparticle_stress import interparticle_stress

    config = SimulationConfig(n_particles=200, volume_fraction=0.45, strain=11.0, seed=1)
    sim = Simulation(config)
    sim.advance_to(5.0)
    virial, induced = [], []
    for k in range(60):
        sim.advance_to(5.0 + 0.1 * (k + 1))
        split = interparticle_stress(sim.state.positions, sim.state.strain, config)
        virial.append(split.virial)
        induced.append(split.induced)
    v = np.mean(virial, axis=0)
    i = np.mean(induced, axis=0)
    rheology = sim.rheology()
    eta = rheology.relative_viscosity

    def row(name: str, s: np.ndarray) -> str:
        return f"| {name} | {s[0, 1]:.3f} | {s[0, 0] - s[1, 1]:.3f} | {s[1, 1] - s[2, 2]:.3f} |"

    lines = [
        f"phi = 0.45, N = 200, strain 5-11 (60 samples); eta_r of the run from strain "
        f"{rheology.averaged_from_strain:g}: {eta:.3f}",
        "",
        "| repulsion stress | eta_r part | N1 part | N2 part |",
        "|---|---|---|---|",
        row("direct virial -n<x F>", v),
        row("induced stresslet -n<R_SU R_FU^-1 F>", i),
        row("total (Sierou & Brady)", v + i),
    ]
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "interparticle.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    assert v[0, 1] > 0.2 * eta  # the virial alone is not negligible ...
    assert abs(v[0, 1] + i[0, 1]) < 0.10 * abs(v[0, 1])  # ... but the total is
