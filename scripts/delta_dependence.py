"""delta (lubrication regularisation) dependence of eta_r at phi = 0.45 (issue 11).

N = 100, strain 20 (averaged 5-20), seed 1, exact near field, field along y. Usage (resumable):

    python scripts/delta_dependence.py OUT            # delta 1e-4 and 1e-3 at Mn = 5, 20, no field
    python scripts/delta_dependence.py OUT --low-mn   # delta 1e-3 at Mn = 1, 0.1

(delta = 1e-4 at low Mn is in results/validation_dip/exact.)
"""

import argparse
import math

from sim import SimulationConfig
from sim.sweep import run_sweep

HIGH_MN = {1e-4: (5.0, 20.0, math.inf), 1e-3: (5.0, 20.0, math.inf)}
LOW_MN = {1e-3: (1.0, 0.1)}


def main(out: str, grid: dict[float, tuple[float, ...]]) -> None:
    for delta, masons in grid.items():
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
            for mn in masons
        ]
        for config, r in zip(configs, run_sweep(configs, f"{out}/delta{delta:g}", processes=2), strict=True):
            print(
                f"delta={delta:g} Mn={config.mason_number:g}: eta_r={r['relative_viscosity']:.2f} "
                f"+- {r['relative_viscosity_stderr']:.2f}, N1={r['n1']:.2f}, N2={r['n2']:.2f}, "
                f"min_gap={r['min_gap']:.2e}, u_rms ratio={r['u_rms_dip'] / r['u_rms_shear']:.3g}",
                flush=True,
            )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="output folder (one sweep folder per delta under it; resumable)")
    parser.add_argument("--low-mn", action="store_true", help="delta 1e-3 at Mn = 1, 0.1 instead")
    args = parser.parse_args()
    main(args.out, LOW_MN if args.low_mn else HIGH_MN)
