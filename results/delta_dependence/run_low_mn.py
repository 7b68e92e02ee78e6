"""Does delta = 1e-3 keep the low-Mn physics? phi = 0.45, N = 100, strain 20 (averaged 5-20), seed 1,
exact near field, Mn = 0.1 and 1, delta = 1e-3 (the delta = 1e-4 values are in results/validation_dip/exact).

Usage: ``python results/delta_dependence/run_low_mn.py OUT`` (resumable).
"""

import sys

from sim import SimulationConfig
from sim.sweep import run_sweep


def main(out: str) -> None:
    configs = [
        SimulationConfig(
            n_particles=100,
            volume_fraction=0.45,
            mason_number=mn,
            strain=20.0,
            transient_strain=5.0,
            seed=1,
            lubrication_regularisation=1e-3,
        )
        for mn in (1.0, 0.1)
    ]
    for config, r in zip(configs, run_sweep(configs, f"{out}/delta0.001", processes=2), strict=True):
        print(
            f"delta=0.001 Mn={config.mason_number:g}: eta_r={r['relative_viscosity']:.2f} "
            f"+- {r['relative_viscosity_stderr']:.2f}, N1={r['n1']:.2f}, N2={r['n2']:.2f}, "
            f"u_rms ratio={r['u_rms_dip'] / r['u_rms_shear']:.3g}",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1])
