"""delta (lubrication regularisation) dependence of eta_r at phi = 0.45 (issue 11).

N = 100, strain 20 (averaged 5-20), seed 1, exact near field, field along y. Usage (resumable):

    python scripts/delta_dependence.py OUT            # delta 1e-4 and 1e-3 at Mn = 5, 20, no field
    python scripts/delta_dependence.py OUT --low-mn   # delta 1e-3 at Mn = 1, 0.1

(delta = 1e-4 at low Mn is in results/validation_dip/exact.)

``OUT`` follows the run-folder protocol (:mod:`agents.folders`): it is claimed for this script (the grids
are fixed, so every run of it is the same study: both commands above share one ``OUT``) before any
simulation, and holds one ``sim`` sweep folder per delta; another command's folder, or a non-empty folder
without a manifest, is refused (exit 2); a folder made before manifests (``delta0.0001/``, ``delta0.001/``)
is adopted; ``--overwrite`` deletes the whole previous run.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from agents.folders import add_folder_options, check_parent, claim_for_script, legacy_markers
from sim import SimulationConfig
from sim.runs.sweep import run_sweep

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


def cli(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("out", type=Path, help="output folder (a sweep folder per delta under it; resumable)")
    parser.add_argument("--low-mn", action="store_true", help="delta 1e-3 at Mn = 1, 0.1 instead")
    add_folder_options(parser, "OUT")
    args = parser.parse_args(argv)
    check_parent(parser, args.out, "OUT")
    claim_for_script(
        parser,
        args.out,
        "delta_dependence.py",
        {"grids": "fixed in the script"},
        argv=argv,
        resume=args.resume,
        overwrite=args.overwrite,
        legacy=legacy_markers(args.out, [f"delta{d:g}" for d in {**HIGH_MN, **LOW_MN}]),
        flag="OUT",
    )
    main(str(args.out), LOW_MN if args.low_mn else HIGH_MN)


if __name__ == "__main__":
    cli()
