"""Relaxation strain of the microstructure after a field switch (it sets the envs' control interval).

Protocol: pre-shear N spheres at phi without field for ``--preshear`` strains (the contact network
plateaus after about 2), switch the field on at ``--mason`` for ``--on`` strains, then off for ``--off``
strains. Every ``--window`` strain the window-averaged eta_r, the fabric anisotropy ``A_yy - 1/3``
(r < 2.2 a) and the contact number (gap < 0.01 a) are recorded. The responses are averaged over
``--seeds`` packings and each is fitted by ``y(g) = y_inf + (y_0 - y_inf) exp(-g / g_r)`` (least squares
on a grid of ``g_r``), for the switch-on and the switch-off halves; ``g_r`` is the relaxation strain.

    python benchmarks/relaxation_strain.py --seeds 4 --mason 0.5 --on 3 --off 3 --out runs/relaxation

Writes ``relaxation.json`` (the averaged responses and the fits) and prints a table. Timings on the
shared 2-core machine are indicative only.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import sim


def fit_relaxation(strain: np.ndarray, values: np.ndarray) -> dict[str, float]:
    """Best ``y_inf + (y_0 - y_inf) exp(-g/g_r)`` over a log grid of ``g_r`` (linear least squares inside)."""
    best = {"relaxation_strain": math.nan, "initial": math.nan, "final": math.nan, "rms": math.inf}
    for g_r in np.geomspace(0.01, 20.0, 400):
        basis = np.stack([np.ones_like(strain), np.exp(-strain / g_r)], axis=1)
        coef, *_ = np.linalg.lstsq(basis, values, rcond=None)
        rms = float(np.sqrt(np.mean((basis @ coef - values) ** 2)))
        if rms < best["rms"]:
            best = {
                "relaxation_strain": float(g_r),
                "initial": float(coef[0] + coef[1]),
                "final": float(coef[0]),
                "rms": rms,
            }
    return best


def window_means(records: sim.StepRecords) -> tuple[float, float, int, int]:
    """Time-averaged eta_r, field energy <1/Mn>, steps and PCG iterations of one window."""
    eta, _, _ = sim.rheology(records.stress.sum(axis=1))
    w = records.time_step
    energy = np.where(np.isinf(records.mason_number), 0.0, 1.0 / records.mason_number)
    return (
        float(np.sum(w * eta) / np.sum(w)),
        float(np.sum(w * energy) / np.sum(w)),
        int(w.size),
        int(records.solver_iterations.sum()),
    )


def run_seed(args: argparse.Namespace, seed: int) -> dict[str, list[float]]:
    config = sim.SimulationConfig(
        n_particles=args.n_particles,
        volume_fraction=args.phi,
        seed=seed,
        strain=args.preshear + args.on + args.off,
        solver_tolerance=args.tolerance,
    )
    simulation = sim.Simulation(config, keep_records=False)
    simulation.advance_to(args.preshear)
    out: dict[str, list[float]] = {k: [] for k in ("strain", "eta", "a_yy", "z", "steps", "seconds", "iters")}
    start = simulation.state.strain
    n_windows = round((args.on + args.off) / args.window)
    for k in range(n_windows):
        if k == round(args.on / args.window):
            simulation.set_field(math.inf)
        elif k == 0:
            simulation.set_field(args.mason)
        tic = time.perf_counter()
        records = simulation.advance_to(start + (k + 1) * args.window)
        seconds = time.perf_counter() - tic
        eta, _, steps, iters = window_means(records)
        state = simulation.state
        fabric = sim.fabric_tensor(state.positions, config.box_length, state.strain, 2.2)
        out["strain"].append((k + 1) * args.window)
        out["eta"].append(eta)
        out["a_yy"].append(float(fabric[1, 1] - 1.0 / 3.0))
        out["z"].append(sim.contact_number(state.positions, config.box_length, state.strain, 0.01))
        out["steps"].append(steps)
        out["seconds"].append(seconds)
        out["iters"].append(iters)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n-particles", type=int, default=64)
    parser.add_argument("--phi", type=float, default=0.45)
    parser.add_argument("--mason", type=float, default=0.5)
    parser.add_argument("--preshear", type=float, default=3.0)
    parser.add_argument("--on", type=float, default=3.0)
    parser.add_argument("--off", type=float, default=3.0)
    parser.add_argument("--window", type=float, default=0.1)
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--tolerance", type=float, default=1e-6)
    parser.add_argument("--out", type=Path, default=Path("runs/relaxation"))
    args = parser.parse_args()
    runs = [run_seed(args, seed) for seed in range(args.seeds)]
    mean = {key: np.mean([r[key] for r in runs], axis=0) for key in runs[0]}
    strain = mean["strain"]
    on = strain <= args.on + 1e-9
    fits = {}
    for key in ("eta", "a_yy", "z"):
        fits[key] = {
            "switch_on": fit_relaxation(strain[on] - args.window / 2, mean[key][on]),
            "switch_off": fit_relaxation(strain[~on] - args.on - args.window / 2, mean[key][~on]),
        }
    args.out.mkdir(parents=True, exist_ok=True)
    result = {
        "arguments": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "mean": {k: v.tolist() for k, v in mean.items()},
        "fits": fits,
    }
    (args.out / "relaxation.json").write_text(json.dumps(result, indent=1))
    print(f"N={args.n_particles} phi={args.phi} Mn={args.mason} seeds={args.seeds} window={args.window}")
    print("| quantity | switch | before | after | relaxation strain |")
    print("|---|---|---|---|---|")
    for key, label in (("eta", "eta_r"), ("a_yy", "A_yy - 1/3"), ("z", "Z (gap < 0.01)")):
        for switch in ("switch_on", "switch_off"):
            f = fits[key][switch]
            print(
                f"| {label} | {switch} | {f['initial']:.3f} | {f['final']:.3f} "
                f"| {f['relaxation_strain']:.2f} |"
            )
    for label, mask in (("field on", on), ("field off", ~on)):
        steps = mean["steps"][mask].sum()
        seconds = mean["seconds"][mask].sum()
        strains = mask.sum() * args.window
        print(
            f"{label}: {steps / strains:.0f} steps/strain, {1e3 * seconds / steps:.2f} ms/step, "
            f"{mean['iters'][mask].sum() / steps:.1f} PCG iterations/step, {seconds / strains:.2f} s/strain"
        )


if __name__ == "__main__":
    main()
