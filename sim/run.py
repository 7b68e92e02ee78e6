"""One run = a pure function of its ``SimulationConfig`` (seed included) that writes one directory."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

from sim import io
from sim.config import SimulationConfig
from sim.figures import plot_rheology
from sim.simulation import Simulation


def run_simulation(
    config: SimulationConfig,
    out_dir: str | Path,
    progress: bool | None = None,
    resume: bool = False,
    command: list[str] | None = None,
) -> dict[str, Any]:
    """Run (or resume) a simulation, writing its files to ``out_dir``; return the result dictionary.

    Args:
        config: the run's parameters.
        out_dir: output directory (created). With ``resume=True`` it must hold a ``checkpoint.npz`` written
            with the same parameters; the run then continues bit-identically to an uninterrupted one.
        progress: show a progress bar; ``None`` means only when stderr is a terminal.
        resume: continue from ``out_dir/checkpoint.npz``.
        command: the command line, recorded in ``params.json``.

    Returns:
        The contents of ``result.json``: ``relative_viscosity``, ``relative_viscosity_stderr``, ``n1``,
        ``n1_stderr``, ``n2``, ``n2_stderr``, ``strain``, ``steps``, ``n_particles``, ``volume_fraction``,
        ``min_gap``, ``wall_seconds`` and per-contribution means.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    checkpoint = out / "checkpoint.npz"
    wall_before = 0.0
    if resume:
        if not checkpoint.exists():
            raise FileNotFoundError(f"--resume: no checkpoint at {checkpoint}")
        saved_config, state, records, wall_before = io.load_checkpoint(checkpoint)
        if saved_config != config:
            raise ValueError(
                f"--resume: the checkpoint in {out} was written with different parameters "
                f"({saved_config.to_dict()}) than requested ({config.to_dict()})"
            )
        sim = Simulation(config, state)
        sim.records = records
    else:
        sim = Simulation(config)
    io.write_params(out, config, command)

    start = time.perf_counter()
    show = sys.stderr.isatty() if progress is None else progress
    bar = None
    if show:
        from tqdm import tqdm

        bar = tqdm(
            total=round(config.strain, 6),
            initial=round(sim.state.strain, 6),
            unit="strain",
            desc=f"phi={config.volume_fraction} N={config.n_particles}",
            file=sys.stderr,
            bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} strain [{elapsed}<{remaining}]",
        )
    next_checkpoint = (
        math.floor(sim.state.strain / config.checkpoint_every + 1e-9) + 1
    ) * config.checkpoint_every

    def on_chunk(s: Simulation) -> None:
        nonlocal next_checkpoint
        if bar is not None:
            bar.n = round(min(s.state.strain, config.strain), 6)
            bar.refresh()
        if s.state.strain >= next_checkpoint - 1e-9:
            io.save_checkpoint(
                checkpoint, config, s.state, s.records, wall_before + time.perf_counter() - start
            )
            next_checkpoint += config.checkpoint_every

    try:
        sim.advance_to(config.strain, chunk_steps=100, on_chunk=on_chunk)
    finally:
        if bar is not None:
            bar.close()
    wall = wall_before + time.perf_counter() - start
    io.save_checkpoint(checkpoint, config, sim.state, sim.records, wall)
    io.save_final_state(out / "final_state.npz", config, sim.state)
    io.write_timeseries(out / "timeseries.csv", sim.records)
    rheo = sim.rheology()
    records = sim.records
    result: dict[str, Any] = {
        "relative_viscosity": rheo.relative_viscosity,
        "relative_viscosity_stderr": rheo.relative_viscosity_stderr,
        "n1": rheo.n1,
        "n1_stderr": rheo.n1_stderr,
        "n2": rheo.n2,
        "n2_stderr": rheo.n2_stderr,
        "strain": sim.state.strain,
        "steps": sim.state.step,
        "n_particles": config.n_particles,
        "volume_fraction": config.volume_fraction,
        "mason_number": config.mason_number,
        "seed": config.seed,
        "min_gap": float(records.min_gap.min()) if records.min_gap.size else math.nan,
        "wall_seconds": wall,
        "averaged_from_strain": rheo.averaged_from_strain,
        "averaged_samples": rheo.samples,
        "mean_solver_iterations": float(records.solver_iterations.mean()) if records.strain.size else 0.0,
        "max_solver_iterations": int(records.solver_iterations.max()) if records.strain.size else 0,
        "steps_with_overlap_removal": int((records.overlap_sweeps > 0).sum()),
        "contributions": {
            name: {"relative_viscosity": v[0], "n1": v[1], "n2": v[2]}
            for name, v in rheo.contributions.items()
        },
    }
    io.write_json(out / "result.json", result)
    plot_rheology(
        records,
        out / "stress.png",
        rheo.averaged_from_strain,
        title=f"phi = {config.volume_fraction}, N = {config.n_particles}, Mn = {config.mason_number}",
    )
    return result
