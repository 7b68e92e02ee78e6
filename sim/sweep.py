"""Sweeps: independent runs in separate processes, each writing its own directory and result file.

Each run is a pure function of its ``SimulationConfig`` (seed included), so a sweep is an embarrassingly
parallel map; here it uses a local process pool (a Dask or cluster backend can call :func:`run_one`).
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sim.config import SimulationConfig
from sim.io import read_json, versions


def run_name(config: SimulationConfig) -> str:
    """Directory name of a run: ``phi0.450_N200_Mninf_seed1``; a mechanism other than ``dip``, a
    quiescent run and a field direction other than y are added (``..._Mn1_dep_quiescent_e1,0,0_seed1``)."""
    parts = [f"phi{config.volume_fraction:.3f}", f"N{config.n_particles}", f"Mn{config.mason_number:g}"]
    if config.mechanism != "dip":
        parts.append(config.mechanism)
    if config.quiescent:
        parts.append("quiescent")
    if tuple(config.field_direction) != (0.0, 1.0, 0.0):
        parts.append("e" + ",".join(f"{c:.3g}" for c in config.field_direction))
    parts.append(f"seed{config.seed}")
    return "_".join(parts)


def run_one(args: tuple[dict[str, Any], str]) -> dict[str, Any]:
    """Run one configuration (given as ``to_dict()``) into ``out_dir/run_name``; return its result."""
    from sim.run import run_simulation

    config = SimulationConfig.from_dict(args[0])
    out = Path(args[1]) / run_name(config)
    result_file = out / "result.json"
    if result_file.exists() and _same_run(out, config):  # finished earlier: re-running fills gaps only
        return read_json(result_file)
    return run_simulation(config, out, progress=False)


def _same_run(out: Path, config: SimulationConfig) -> bool:
    """True if ``out`` holds a run of ``config`` made by the same ``sim`` sources (digest in params.json)."""
    params_file = out / "params.json"
    if not params_file.exists():
        return False
    params = read_json(params_file)
    try:
        same_config = SimulationConfig.from_dict(params["config"]) == config
    except (KeyError, TypeError, ValueError):
        return False
    return same_config and params.get("versions", {}).get("sim_source") == versions()["sim_source"]


def run_sweep(
    configs: Sequence[SimulationConfig], out_dir: str | Path, processes: int = 2
) -> list[dict[str, Any]]:
    """Run ``configs`` with ``processes`` worker processes; results in input order."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(c.to_dict(), str(out)) for c in configs]
    if processes <= 1:
        return [run_one(j) for j in jobs]
    with mp.get_context("spawn").Pool(processes) as pool:
        return pool.map(run_one, jobs, chunksize=1)
