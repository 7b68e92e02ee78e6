"""Switching time of the field's direction (issue 44): from a steady state, turn the field and time eta_r.

Takes the end state of a steady run (a ``sim run``/``sim sweep`` point folder of the direction map: its
``final_state.npz`` and ``params.json``), turns the field to ``--direction`` at the same Mason number
(strain 0 of the switch), shears on for ``--strain`` and records eta_r, N1 and N2 per step. The switching
strain is fitted to the binned eta_r as a single exponential that starts from the steady eta_r before the
switch (``eta_before``, the source run's ``relative_viscosity``, averaged over its steady strains),

    eta_r(gamma) = eta_inf + (eta_before - eta_inf) exp(-gamma / gamma_s),

averaged over each bin as the data are (the mean of ``exp(-g / s)`` over ``[a, b]`` is
``s (exp(-a / s) - exp(-b / s)) / (b - a)``), so that a switch faster than one bin still gives its
``gamma_s`` instead of a fit that has nothing to bend (``scipy.optimize.curve_fit``; ``eta_inf`` and
``gamma_s`` free). It is reported with ``gamma_90 = gamma_s ln 10``, the strain to cover 90% of the change,
and, model free, ``gamma_half_by``: the upper edge of the first bin whose mean lies past half-way from
``eta_before`` to the tail's mean (the last third of the bins): the half-way strain is at most that, to
the bin's resolution.

Writes ``OUT/switch.csv`` (strain since the switch, eta_r, N1, N2 per bin of ``--bin`` strain),
``OUT/fit.json`` and ``OUT/manifest.json``. A pure function of its inputs. A rerun into a folder that holds
``switch.csv`` does not simulate again: it redoes only the fit. Usage::

    python scripts/direction_switch.py --from runs/direction_map/phi0.45_y/phi0.450_N500_Mn1_seed1 \\
        --direction 0,0,1 --strain 15 --out runs/direction_switch/y_to_z_Mn1_seed1
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

import sim
from sim.runs import RunFolderError, claim
from sim.runs.io import read_json, write_json, write_text_atomically


def binned(
    strain: np.ndarray, dt: np.ndarray, values: np.ndarray, width: float
) -> tuple[np.ndarray, np.ndarray]:
    """Step-weighted means of ``values`` (steps x k) in bins of ``width`` strain (``dt``: each step's strain):
    (bin centres, means)."""
    edges = np.arange(0.0, strain[-1] + dt[-1] + 1e-12, width)
    index = np.clip(np.searchsorted(edges, strain, side="right") - 1, 0, len(edges) - 2)
    weights = np.bincount(index, dt, minlength=len(edges) - 1)
    means = np.stack(
        [np.bincount(index, dt * values[:, k], minlength=len(edges) - 1) for k in range(values.shape[1])],
        axis=1,
    )
    keep = weights > 0
    return 0.5 * (edges[:-1] + edges[1:])[keep], means[keep] / weights[keep, None]


def bin_mean_decay(gamma: np.ndarray, width: float, scale: float) -> np.ndarray:
    """The mean of ``exp(-g / scale)`` over each bin ``[gamma - width/2, gamma + width/2]`` (``gamma``: bin
    centres; a first bin that starts at 0 included)."""
    low, high = np.maximum(gamma - 0.5 * width, 0.0), gamma + 0.5 * width
    return scale * (np.exp(-low / scale) - np.exp(-high / scale)) / (high - low)


def fit_switch(gamma: np.ndarray, eta: np.ndarray, width: float, eta_before: float) -> dict[str, float]:
    """The anchored, bin-averaged single-exponential fit (module docstring) of bin means ``eta`` at bin
    centres ``gamma`` of ``width`` strain, from the steady ``eta_before``, and the model-free half-way strain
    ``gamma_half_by``."""
    from scipy.optimize import curve_fit

    def model(g: np.ndarray, eta_inf: float, scale: float) -> np.ndarray:
        return eta_inf + (eta_before - eta_inf) * bin_mean_decay(g, width, scale)

    tail = float(eta[len(eta) * 2 // 3 :].mean())
    try:
        bounds = ([-np.inf, 1e-3], [np.inf, 1e3])
        params, cov = curve_fit(model, gamma, eta, p0=(tail, 1.0), bounds=bounds)
        errors = np.sqrt(np.diag(cov))
    except RuntimeError:
        params, errors = np.full(2, math.nan), np.full(2, math.nan)
    halfway = 0.5 * (eta_before + tail)
    rising = tail > eta_before
    crossed = np.nonzero(eta >= halfway if rising else eta <= halfway)[0]
    return {
        "eta_before": float(eta_before),
        "eta_inf": float(params[0]),
        "eta_inf_error": float(errors[0]),
        "gamma_s": float(params[1]),
        "gamma_s_error": float(errors[1]),
        "gamma_90": float(params[1] * math.log(10.0)),
        "gamma_half_by": float(gamma[crossed[0]] + 0.5 * width) if crossed.size else math.nan,
        "eta_tail_mean": tail,
    }


def read_switch(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``switch.csv``'s bin centres and its (bins x 3) eta_r, N1, N2."""
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return table[:, 0], table[:, 1:]


def _direction(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be three comma-separated numbers, got {text!r}") from None
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
        raise argparse.ArgumentTypeError(f"must be three finite numbers, not all zero, got {text!r}")
    return values  # type: ignore[return-value]


def _positive(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], allow_abbrev=False)
    parser.add_argument("--from", dest="source", required=True, type=Path, help="steady run folder")
    parser.add_argument("--direction", required=True, type=_direction, help="new field direction x,y,z")
    parser.add_argument("--strain", type=_positive, default=15.0, help="strain after the switch (default 15)")
    parser.add_argument("--bin", type=_positive, default=0.5, help="bin width of switch.csv in strain (0.5)")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="delete the folder's previous run first")
    return parser


def load_steady(source: Path) -> tuple[sim.SimulationConfig, sim.SimulationState, float]:
    """A finished steady run's config, end state and steady eta_r (its ``relative_viscosity``);
    ``ValueError`` saying why where ``source`` is not a finished, sheared run with a field."""
    try:
        config = sim.SimulationConfig.from_dict(read_json(source / "params.json")["config"])
        state = sim.SimulationState.load(source / "final_state.npz")
        eta_before = float(read_json(source / "result.json")["relative_viscosity"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"not a finished run ({exc})") from None
    if math.isinf(config.mason_number) or config.shear_rate == 0.0:
        raise ValueError("needs a sheared run with a field")
    return config, state, eta_before


def turned(
    config: sim.SimulationConfig,
    state: sim.SimulationState,
    direction: tuple[float, float, float],
    strain: float,
) -> tuple[sim.StepRecords, np.ndarray]:
    """From ``state``, the field turned to ``direction`` at the run's Mason number and ``strain`` of shear:
    the step records and each step's strain since the turn."""
    simulation = sim.Simulation(config, state, keep_records=True)
    simulation.set_field(config.mason_number, direction)
    start = simulation.state.strain
    simulation.advance_to(simulation.state.time + strain / simulation.shear_rate)
    records = simulation.records
    return records, records.strain - start


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        config, state, eta_before = load_steady(args.source)
    except ValueError as exc:
        parser.exit(2, f"direction_switch.py: error: --from {args.source}: {exc}\n")
    identity = {
        "source": str(args.source.resolve()),
        "source_config": config.to_dict(),
        "direction": list(args.direction),
        "strain": args.strain,
        "bin": args.bin,
    }
    try:
        claim(args.out, "scripts/direction_switch.py", identity, overwrite=args.overwrite, argv=sys.argv)
    except RunFolderError as exc:
        parser.exit(2, f"direction_switch.py: error: {exc}\n")
    csv = args.out / "switch.csv"
    if csv.exists():
        # simulated before: only the fit is redone (it is cheap, and its method may have changed)
        gamma, means = read_switch(csv)
    else:
        records, since = turned(config, state, args.direction, args.strain)
        eta, n1, n2 = records.rheology()
        strain_steps = records.time_step * records.shear_rate
        gamma, means = binned(since, strain_steps, np.stack([eta, n1, n2], axis=1), args.bin)
        lines = ["strain_since_switch,eta_r,n1,n2"] + [
            f"{g:.6g},{m[0]:.6g},{m[1]:.6g},{m[2]:.6g}" for g, m in zip(gamma, means, strict=True)
        ]
        write_text_atomically(csv, "\n".join(lines) + "\n")
    to = np.asarray(args.direction, dtype=float)
    result = {
        "from_direction": [float(v) for v in config.field_direction],
        "to_direction": [float(v) for v in to / np.linalg.norm(to)],
        "mason_number": config.mason_number,
        "volume_fraction": config.volume_fraction,
        "n_particles": config.n_particles,
        "seed": config.seed,
        **fit_switch(gamma, means[:, 0], args.bin, eta_before),
    }
    write_json(args.out / "fit.json", result)
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
