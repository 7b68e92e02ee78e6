"""Flow curves as a rheometer measures them: a staircase of shear rates at a fixed field.

One curve is a pure function of its :class:`FlowCurveSpec` (seed included). It starts from a random
packing, holds each rate of ``rates`` for ``strain_per_rate`` (the time ``strain_per_rate / rate``; each
rate starts from the state the previous one left, as in a stepped rate sweep) and averages the stress
over the second half of each hold. ``down`` adds the way back (the rates in reverse order, without
repeating the top one), for hysteresis.

The field is given by its Mason number at the reference rate ``Mn_ref = eta gammadot_ref / (eps E0^2)``,
so at a rate ``gammadot`` the instantaneous Mason number is ``(gammadot / gammadot_ref) Mn_ref``: a
curve at fixed field crosses the thickening transition (paper Fig. 3b, eta_r against Mn) as the rate
rises. Stresses are in ``eta gammadot_ref`` and ``eta_r = Sigma_xy / (eta gammadot)`` (``docs/units.md``).

A curve writes ``flow_curve.csv`` (one row per hold: direction, rate, instantaneous Mn, eta_r, shear
stress, N1, N2 with block standard errors, the strain interval averaged, steps, wall time),
``flow_curve.png``, ``params.json`` and ``checkpoint.npz`` (the state after the last finished hold). A
rerun of the same curve continues after the last finished hold (bit for bit as an uninterrupted curve:
a hold depends only on the state it starts from); a folder holding another curve is refused.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import SimulationConfig
from sim.io import read_json, versions, write_json
from sim.observables.stress import block_average
from sim.simulation import Simulation, StepRecords, summarise
from sim.state import SimulationState

CSV_NAME = "flow_curve.csv"
PLOT_NAME = "flow_curve.png"
PARAMS_NAME = "params.json"
CHECKPOINT_NAME = "checkpoint.npz"

COLUMNS = (
    "hold",
    "direction",
    "shear_rate",
    "mason_number",
    "relative_viscosity",
    "relative_viscosity_stderr",
    "shear_stress",
    "shear_stress_stderr",
    "n1",
    "n1_stderr",
    "n2",
    "n2_stderr",
    "averaged_from_strain",
    "averaged_to_strain",
    "samples",
    "steps",
    "wall_seconds",
)
"""Columns of ``flow_curve.csv``: ``mason_number`` is the instantaneous one (rate x Mn_ref); stresses in
``eta gammadot_ref``; the strains are the run's accumulated strain over which the hold was averaged."""


def _positive_number(value: Any) -> bool:
    """True for a finite int or float > 0 (not a bool)."""
    return (
        isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and value > 0
    )


@dataclass(frozen=True)
class FlowCurveSpec:
    """One flow curve.

    Attributes:
        config: the suspension and numerics (``n_particles``, ``volume_fraction``, ``mason_number`` =
            ``Mn_ref``, ``seed``, ...); its ``shear_rate`` and ``strain`` are ignored (set per hold).
        rates: shear rates ``gammadot / gammadot_ref`` of the upward sweep, finite, > 0, increasing.
        strain_per_rate: strain each rate is held for, > 0; the second half is averaged.
        down: add the downward sweep (rates reversed, top rate not repeated).
    """

    config: SimulationConfig
    rates: tuple[float, ...]
    strain_per_rate: float
    down: bool = False

    def __post_init__(self) -> None:
        rates = tuple(self.rates)
        if not rates:
            raise ValueError("rates must list at least one shear rate")
        for rate in rates:
            if not _positive_number(rate):
                raise ValueError(f"rates must be finite numbers > 0 (units gammadot_ref), got {rate!r}")
        if any(b <= a for a, b in zip(rates, rates[1:], strict=False)):
            raise ValueError(
                f"rates must increase (the sweep goes up; down=True adds the way back), got {list(rates)}"
            )
        object.__setattr__(self, "rates", tuple(float(r) for r in rates))
        if not _positive_number(self.strain_per_rate):
            raise ValueError(f"strain_per_rate must be finite and > 0, got {self.strain_per_rate!r}")
        # the config of the first hold (validates the run length at the lowest rate against MAX_STEPS)
        replace(self.config, shear_rate=rates[0], strain=float(self.strain_per_rate), transient_strain=None)

    @property
    def holds(self) -> list[tuple[str, float]]:
        """``(direction, rate)`` of every hold in order."""
        up = [("up", r) for r in self.rates]
        down = [("down", r) for r in reversed(self.rates[:-1])] if self.down else []
        return up + down

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters."""
        out = asdict(self)
        out["config"] = self.config.to_dict()
        out["rates"] = list(self.rates)
        return out


def _hold_row(
    index: int, direction: str, rate: float, mason_ref: float, records: StepRecords, n_blocks: int,
    wall: float,
) -> dict[str, Any]:
    """The averages of one hold over the second half of its strain."""
    start = float(records.time[0])
    end = start + 0.5 * (float(records.time[-1] + records.time_step[-1]) - start)
    averaged = summarise(records, end, n_blocks)
    selected = records.select(records.time >= end - 1e-12)
    shear = block_average(selected.total_stress[:, 0, 1], n_blocks, selected.time_step)
    return {
        "hold": index,
        "direction": direction,
        "shear_rate": rate,
        "mason_number": rate * mason_ref if math.isfinite(mason_ref) else math.inf,
        "relative_viscosity": averaged.relative_viscosity,
        "relative_viscosity_stderr": averaged.relative_viscosity_stderr,
        "shear_stress": shear.mean,
        "shear_stress_stderr": shear.stderr,
        "n1": averaged.n1,
        "n1_stderr": averaged.n1_stderr,
        "n2": averaged.n2,
        "n2_stderr": averaged.n2_stderr,
        "averaged_from_strain": float(selected.strain[0]) if selected.strain.size else math.nan,
        "averaged_to_strain": float(records.strain[-1] + rate * records.time_step[-1]),
        "samples": averaged.samples,
        "steps": int(records.time.size),
        "wall_seconds": wall,
    }


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Rows of a ``flow_curve.csv`` (numbers as floats, ``hold``/``samples``/``steps`` as ints)."""
    rows = []
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            parsed: dict[str, Any] = {}
            for key, value in row.items():
                if key == "direction":
                    parsed[key] = value
                elif key in ("hold", "samples", "steps"):
                    parsed[key] = int(value)
                else:
                    parsed[key] = float(value)
            rows.append(parsed)
    return rows


def _write_rows(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()})
    tmp.replace(path)


def resume_point(out: Path, spec: FlowCurveSpec) -> tuple[list[dict[str, Any]], SimulationState | None]:
    """Finished rows and the state after them, or ``([], None)`` for a new curve; ``ValueError`` when
    ``out`` holds another curve (or a run that is not a flow curve)."""
    params_path = out / PARAMS_NAME
    if not params_path.exists():
        if out.exists() and any(out.iterdir()):
            raise ValueError(f"out_dir {out} is not empty and holds no flow curve; choose another folder")
        return [], None
    try:
        saved = read_json(params_path)
    except (OSError, ValueError) as exc:
        raise ValueError(f"out_dir {out}: {params_path.name} cannot be read ({exc})") from exc
    if saved.get("flow_curve") != spec.to_dict():
        raise ValueError(
            f"out_dir {out} holds another flow curve (see its {PARAMS_NAME}); choose another folder"
        )
    csv_path, checkpoint = out / CSV_NAME, out / CHECKPOINT_NAME
    if not (csv_path.exists() and checkpoint.exists()):
        return [], None
    rows = read_rows(csv_path)
    with np.load(checkpoint) as data:
        holds_done = int(data["holds_done"])
        state = SimulationState.from_arrays(data)
    if holds_done != len(rows):
        raise ValueError(f"out_dir {out}: {CSV_NAME} and {CHECKPOINT_NAME} disagree; remove the folder")
    return rows, state


def run_flow_curve(spec: FlowCurveSpec, out_dir: str | Path, progress: bool | None = None) -> list[dict]:
    """Run (or continue) one flow curve into ``out_dir``; return its rows (see :data:`COLUMNS`)."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {out} exists and is not a directory")
    rows, state = resume_point(out, spec)
    holds = spec.holds
    out.mkdir(parents=True, exist_ok=True)
    write_json(
        out / PARAMS_NAME,
        {
            "flow_curve": spec.to_dict(),
            "units": "a = eta = gammadot_ref = 1; time in 1/gammadot_ref; stress in eta*gammadot_ref; "
            "mason_number in the csv = shear_rate * Mn_ref",
            "versions": versions(),
        },
    )
    first = replace(spec.config, shear_rate=spec.rates[0], strain=spec.strain_per_rate, transient_strain=None)
    sim = Simulation(first, state, keep_records=False)
    show = sys.stderr.isatty() if progress is None else progress
    bar = None
    if show:
        from tqdm import tqdm

        bar = tqdm(
            total=len(holds), initial=len(rows), desc=f"flow curve Mn_ref={spec.config.mason_number:g}",
            unit="rate", file=sys.stderr,
        )
    try:
        for index in range(len(rows), len(holds)):
            direction, rate = holds[index]
            sim.set_shear_rate(rate)
            start = time.perf_counter()
            records = sim.advance_to(sim.state.time + spec.strain_per_rate / rate, chunk_steps=500)
            rows.append(
                _hold_row(index, direction, rate, spec.config.mason_number, records, spec.config.n_blocks,
                          time.perf_counter() - start)
            )
            _write_rows(out / CSV_NAME, rows)
            tmp = out / (CHECKPOINT_NAME + ".tmp.npz")
            np.savez(tmp, holds_done=np.array(len(rows)), **sim.state.arrays())
            tmp.replace(out / CHECKPOINT_NAME)
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(f"rate {rate:g}: eta_r {rows[-1]['relative_viscosity']:.3g}")
    finally:
        if bar is not None:
            bar.close()
    plot_flow_curves({spec.config.mason_number: rows}, out / PLOT_NAME)
    return rows


def run_flow_curve_task(payload: dict[str, Any]) -> list[dict]:
    """Task form of :func:`run_flow_curve` for :func:`sim.tasks.run_tasks` (a picklable payload)."""
    spec = FlowCurveSpec(
        SimulationConfig.from_dict(payload["config"]),
        tuple(payload["rates"]),
        payload["strain_per_rate"],
        payload["down"],
    )
    return run_flow_curve(spec, payload["out"], progress=payload.get("progress", False))


def curve_folder(mason_number: float) -> str:
    """Sub-folder of one field's curve in a multi-field run: ``Mn1``, ``Mn0.5``, ``Mninf``."""
    return f"Mn{mason_number:g}"


def plot_flow_curves(curves: dict[float, list[dict[str, Any]]], path: Path) -> None:
    """eta_r and the shear stress against the shear rate, one line per field; the upper axis gives the
    instantaneous Mason number of the first field, ``rate x Mn_ref`` (log axes; error bars one standard
    error; the downward sweep dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(6.4, 7.2), sharex=True, layout="constrained")
    for k, (mason, rows) in enumerate(sorted(curves.items())):
        colour = f"C{k}"
        label = "no field" if math.isinf(mason) else rf"$Mn_\mathrm{{ref}}$ = {mason:g}"
        for direction, style in (("up", "-o"), ("down", "--s")):
            part = [r for r in rows if r["direction"] == direction]
            if not part:
                continue
            rate = np.array([r["shear_rate"] for r in part])
            for ax, key in zip(axes, ("relative_viscosity", "shear_stress"), strict=True):
                ax.errorbar(
                    rate, [r[key] for r in part], yerr=[r[key + "_stderr"] for r in part], fmt=style,
                    color=colour, ms=4, capsize=2, label=label + ("" if direction == "up" else " (down)"),
                )
    axes[0].set_ylabel(r"$\eta_r = \Sigma_{xy}/\eta\dot\gamma$")
    axes[1].set_ylabel(r"$\Sigma_{xy}/\eta\dot\gamma_\mathrm{ref}$")
    axes[1].set_xlabel(r"shear rate $\dot\gamma/\dot\gamma_\mathrm{ref}$")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
    finite = [m for m in curves if math.isfinite(m)]
    if finite:
        first = min(finite)
        top = axes[0].secondary_xaxis("top", functions=(lambda r: r * first, lambda m: m / first))
        top.set_xlabel(rf"instantaneous $Mn$ for $Mn_\mathrm{{ref}}$ = {first:g}")
    axes[0].legend(fontsize="small", frameon=False)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_combined(out: Path, curves: dict[float, list[dict[str, Any]]]) -> None:
    """``flow_curve.csv`` (with a ``mason_number_ref`` column) and ``flow_curve.png`` of several fields."""
    tmp = out / (CSV_NAME + ".tmp")
    with open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=("mason_number_ref", *COLUMNS))
        writer.writeheader()
        for mason, rows in sorted(curves.items()):
            for row in rows:
                values = {k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()}
                writer.writerow({"mason_number_ref": f"{mason:g}", **values})
    tmp.replace(out / CSV_NAME)
    plot_flow_curves(curves, out / PLOT_NAME)
