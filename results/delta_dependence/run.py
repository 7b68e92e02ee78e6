"""delta (lubrication regularisation) dependence of the high-Mn rise of eta_r (issue 11).

phi = 0.45, N = 100, strain 20 (averaged 5-20), seed 1, exact near field; delta = 1e-4 (default) and
1e-3; Mn = 5, 20 and no field. Usage: ``python results/delta_dependence/run.py OUT`` (resumable).
"""

import math
import sys

from sim import SimulationConfig
from sim.sweep import run_sweep


def main(out: str) -> None:
    for delta in (1e-4, 1e-3):
        configs = [
            SimulationConfig(
                n_particles=100,
                volume_fraction=0.45,
                mason_number=mn,
                strain=20.0,
                transient_strain=5.0,
                seed=1,
                lubrication_regularisation=delta,
            )
            for mn in (5.0, 20.0, math.inf)
        ]
        for config, r in zip(configs, run_sweep(configs, f"{out}/delta{delta:g}", processes=2), strict=True):
            print(
                f"delta={delta:g} Mn={config.mason_number:g}: eta_r={r['relative_viscosity']:.2f} "
                f"+- {r['relative_viscosity_stderr']:.2f}, N1={r['n1']:.2f}, N2={r['n2']:.2f}, "
                f"min_gap={r['min_gap']:.2e}",
                flush=True,
            )


if __name__ == "__main__":
    main(sys.argv[1])
