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

A curve writes ``manifest.json`` first (the run-folder protocol, :mod:`sim.runs.folder`: command
``sim flow-curve``, identity :func:`curve_identity`), then ``params.json``, ``flow_curve.csv`` (one row
per hold: direction, rate, instantaneous Mn, eta_r, shear stress, N1, N2 with block standard errors, the
strain interval averaged, steps, wall time), ``checkpoint.npz`` (the state after the last finished hold)
and ``flow_curve.png``, every file atomically. A rerun of the same curve continues after the last
finished hold (bit for bit as an uninterrupted curve: a hold depends only on the state it starts from);
its files are validated first (a damaged one is named with what is wrong). A folder holding another curve,
another command's run or unknown files is refused; ``overwrite`` deletes the previous run. Ctrl-C stops a
curve at the end of the current chunk of steps (the finished holds are kept) with ``KeyboardInterrupt``.

Each hold must take at least :data:`MIN_HOLD_STEPS` steps of the largest step ``time_step`` at the
highest rate, so that its averaged second half holds samples (a hold of ``1e-9`` gave NaN rows).
"""

from __future__ import annotations

import csv
import io
import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import MAX_SHEAR_RATE, MAX_STEPS, MIN_SHEAR_RATE, SimulationConfig
from sim.observables.stress import block_average
from sim.runs.folder import RunFolderError, claim, differing, normalise, preview
from sim.runs.io import (
    CheckpointError,
    atomic_file,
    open_checkpoint,
    read_json,
    save_figure,
    versions,
    write_json,
    write_text_atomically,
)
from sim.runs.legacy import legacy_markers
from sim.simulation import Simulation, StepRecords, summarise
from sim.state import SimulationState

CSV_NAME = "flow_curve.csv"
PLOT_NAME = "flow_curve.png"
PARAMS_NAME = "params.json"
CHECKPOINT_NAME = "checkpoint.npz"
COMMAND = "sim flow-curve"
"""How a flow curve's folder names its owner in ``manifest.json`` (:mod:`sim.runs.folder`)."""

MIN_HOLD_STEPS = 4
"""Fewest steps of the largest step (``time_step``) a hold may take: the second half is averaged, so it
then holds at least two samples."""

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
            if not MIN_SHEAR_RATE <= rate <= MAX_SHEAR_RATE:
                raise ValueError(
                    f"rates must be in [{MIN_SHEAR_RATE:g}, {MAX_SHEAR_RATE:g}] (units gammadot_ref), "
                    f"got {rate!r}"
                )
        if any(b <= a for a, b in zip(rates, rates[1:], strict=False)):
            raise ValueError(
                f"rates must increase (the sweep goes up; down=True adds the way back), got {list(rates)}"
            )
        object.__setattr__(self, "rates", tuple(float(r) for r in rates))
        if not _positive_number(self.strain_per_rate):
            raise ValueError(f"strain_per_rate must be finite and > 0, got {self.strain_per_rate!r}")
        strain, dt = float(self.strain_per_rate), self.config.time_step
        shortest, longest = strain / rates[-1], strain / rates[0]  # hold times, units 1/gammadot_ref
        if shortest < MIN_HOLD_STEPS * dt * (1.0 - 1e-9):
            raise ValueError(
                f"strain_per_rate={strain:g} is too short a hold: at the highest rate, {rates[-1]:g}, it "
                f"lasts {shortest:.3g} (units 1/gammadot_ref), fewer than {MIN_HOLD_STEPS} steps of "
                f"time_step={dt:g}, and its second half is averaged; strain_per_rate must be at least "
                f"{MIN_HOLD_STEPS * dt * rates[-1]:.3g} for these rates (or lower the highest rate)"
            )
        if longest / dt > MAX_STEPS:
            raise ValueError(
                f"strain_per_rate={strain:g} is too long a hold: at the lowest rate, {rates[0]:g}, it "
                f"takes {longest / dt:.3g} steps of time_step={dt:g} (more than {MAX_STEPS:.0e}); "
                f"strain_per_rate must be at most {MAX_STEPS * dt * rates[0]:.3g} for these rates"
            )
        # the config of the first hold (the configuration's own checks at the lowest rate)
        replace(self.config, shear_rate=rates[0], strain=strain, transient_strain=None)

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


def _csv_text(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> str:
    handle = io.StringIO(newline="")
    writer = csv.DictWriter(handle, fieldnames=columns)
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()})
    return handle.getvalue()


def _write_rows(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    write_text_atomically(path, _csv_text(rows, COLUMNS))


def _identity(
    config: Mapping[str, Any],
    masons: Sequence[Any],
    rates: Sequence[float],
    strain_per_rate: float,
    down: bool,
) -> dict[str, Any]:
    shared = {k: v for k, v in config.items() if k not in ("mason_number", "shear_rate", "strain",
                                                           "transient_strain")}
    return {
        **shared,
        "mason_number": sorted(float(m) for m in masons),
        "rates": [float(r) for r in rates],
        "strain_per_rate": float(strain_per_rate),
        "down": bool(down),
    }


def curve_identity(specs: Sequence[FlowCurveSpec]) -> dict[str, Any]:
    """The identity of a flow-curve folder (:mod:`sim.runs.folder`) holding the curves of ``specs`` (one
    per field, alike but for ``mason_number``): the suspension and numerics (the configuration without
    the ``shear_rate``, ``strain`` and ``transient_strain`` that each hold sets), the sorted Mason
    numbers, the rates, the strain per rate and ``down``. A folder of one curve and a ``Mn<value>``
    sub-folder of several have the identity of that one field."""
    first = specs[0]
    masons = [spec.config.mason_number for spec in specs]
    return _identity(first.config.to_dict(), masons, first.rates, first.strain_per_rate, first.down)


def _legacy_identity(out: Path) -> dict[str, Any] | None:
    """The identity of a curve folder written before manifests (from its ``params.json``, or for several
    fields from its ``Mn<value>/params.json``), None when it cannot be read."""

    def single(folder: Path) -> dict[str, Any] | None:
        try:
            saved = read_json(folder / PARAMS_NAME)["flow_curve"]
            config = saved["config"]
            return _identity(config, [config["mason_number"]], saved["rates"], saved["strain_per_rate"],
                             saved["down"])
        except (OSError, ValueError, KeyError, TypeError):
            return None

    if (out / PARAMS_NAME).exists():
        return single(out)
    parts = [single(sub) for sub in sorted(out.glob("Mn*")) if sub.is_dir()]
    if not parts or any(part is None for part in parts):
        return None
    identity = dict(parts[0])  # type: ignore[arg-type]
    identity["mason_number"] = sorted(m for part in parts for m in part["mason_number"])  # type: ignore[index]
    return identity


def check_curve_folder(
    out: Path,
    specs: Sequence[FlowCurveSpec],
    resume: bool = False,
    overwrite: bool = False,
    flag: str = "out_dir",
) -> tuple[str, tuple[str, ...]]:
    """What a flow curve of ``specs`` (one field, or several in ``Mn<value>`` sub-folders) finds in
    ``out``: the ``state`` of :func:`sim.runs.folder.claim` and the pre-manifest files by which it adopts
    the folder; :class:`RunFolderError` (naming ``flag`` and the folder) when it may not use it. Nothing
    is written. A pre-manifest curve folder is compared through its ``params.json``."""
    legacy = legacy_markers(out, COMMAND, overwrite, flag)
    identity = curve_identity(specs)
    if legacy and not overwrite:
        saved = _legacy_identity(out)
        if saved is None:
            raise RunFolderError(
                f"{flag} {out} holds a flow curve whose parameters cannot be read ({PARAMS_NAME}); choose "
                f"another {flag}, or give --overwrite to delete it and start afresh"
            )
        keys = [key for key in differing(saved, identity) if key in saved]  # not keys added since
        if keys:
            there = ", ".join(f"{k}={normalise(saved).get(k)!r}" for k in keys)
            asked = ", ".join(f"{k}={normalise(identity).get(k)!r}" for k in keys)
            raise RunFolderError(
                f"{flag} {out} holds a flow curve of other parameters: {there} there, {asked} requested; "
                f"choose another {flag}, or give --overwrite to delete it and start afresh"
            )
    found = preview(out, COMMAND, identity, resume=resume, overwrite=overwrite, legacy=legacy, flag=flag)
    return found, legacy


def resume_point(out: Path, spec: FlowCurveSpec) -> tuple[list[dict[str, Any]], SimulationState | None]:
    """Finished rows and the state after them in the curve folder ``out`` (of ``spec``: see
    :func:`check_curve_folder`), or ``([], None)`` when no hold has finished.

    Every file a rerun reads or replaces is validated first: ``ValueError`` names the file and what is
    wrong (a directory in its place, an unreadable or truncated csv or checkpoint, rows of other holds,
    a checkpoint that does not match the rows). Rows written after the last checkpoint (a curve killed
    between the two writes) are dropped: their hold is run again, bit for bit."""
    csv_path, checkpoint = out / CSV_NAME, out / CHECKPOINT_NAME
    for path in (csv_path, checkpoint, out / PLOT_NAME, out / PARAMS_NAME):
        if path.exists() and not path.is_file():
            raise ValueError(f"{path} is a directory (or not a regular file), not the curve's {path.name}")
    if not checkpoint.exists():
        return [], None
    try:
        with open_checkpoint(checkpoint) as data:
            holds_done = int(data["holds_done"])
            state = SimulationState.from_arrays(data)
    except CheckpointError as exc:
        raise ValueError(str(exc)) from None
    except FileNotFoundError:  # removed meanwhile
        return [], None
    holds = spec.holds
    n = spec.config.n_particles
    if not 0 <= holds_done <= len(holds):
        raise ValueError(f"{checkpoint} is after {holds_done} holds, but the curve has {len(holds)}")
    if state.positions.shape != (n, 3) or not np.all(np.isfinite(state.positions)):
        raise ValueError(
            f"{checkpoint} holds {state.positions.shape[0]} positions (finite: "
            f"{bool(np.all(np.isfinite(state.positions)))}), not {n} finite ones"
        )
    if not csv_path.exists():
        if holds_done:
            raise ValueError(f"{checkpoint} is after {holds_done} holds, but no {CSV_NAME} is beside it")
        return [], state
    try:
        with open(csv_path, newline="") as handle:
            header = next(csv.reader(handle), [])
        rows = read_rows(csv_path)
    except (OSError, ValueError, TypeError, csv.Error) as exc:
        raise ValueError(f"{csv_path} cannot be read as a flow curve ({type(exc).__name__}: {exc})") from None
    if tuple(header) != COLUMNS:
        raise ValueError(f"{csv_path} is not a flow curve's csv (its columns: {', '.join(header) or 'none'})")
    if len(rows) < holds_done:
        raise ValueError(
            f"{csv_path} has {len(rows)} rows but {checkpoint} is after {holds_done} holds: they disagree"
        )
    rows = rows[:holds_done]
    for index, (row, (direction, rate)) in enumerate(zip(rows, holds, strict=False)):
        if row["hold"] != index or row["direction"] != direction or row["shear_rate"] != rate:
            raise ValueError(
                f"{csv_path} row {index} is the hold ({row['hold']}, {row['direction']}, rate "
                f"{row['shear_rate']:g}), not ({index}, {direction}, rate {rate:g}) of this curve"
            )
    return rows, state


def _remove_curve_files(out: Path) -> None:
    """Delete a curve's results (not its manifest): before a curve starts from its first hold."""
    for name in (CSV_NAME, PLOT_NAME, CHECKPOINT_NAME):
        (out / name).unlink(missing_ok=True)


def run_flow_curve(
    spec: FlowCurveSpec,
    out_dir: str | Path,
    progress: bool | None = None,
    *,
    resume: bool = False,
    overwrite: bool = False,
    command: Sequence[str] | None = None,
    flag: str = "out_dir",
) -> list[dict]:
    """Run (or continue) one flow curve into ``out_dir``; return its rows (see :data:`COLUMNS`).

    The folder follows the run-folder protocol (:mod:`sim.runs.folder`): a rerun of the same curve
    continues after its last finished hold, ``resume`` insists on a curve to continue, ``overwrite``
    deletes the folder's previous run; anything else there is refused (:class:`RunFolderError`, a
    ``ValueError``, naming ``flag``). Ctrl-C stops the curve at the end of the current chunk of steps
    with ``KeyboardInterrupt``; the finished holds are kept.
    """
    from sim.runs.run import _deferred_interrupt

    out = Path(out_dir)
    found, legacy = check_curve_folder(out, [spec], resume, overwrite, flag)
    try:
        rows, state = resume_point(out, spec) if found in ("same", "adopted") else ([], None)
    except ValueError as exc:
        raise RunFolderError(
            f"{flag} {out}: {exc}; give --overwrite to delete that curve and start afresh"
        ) from None
    claim(out, COMMAND, curve_identity([spec]), resume=resume, overwrite=overwrite, argv=command,
          legacy=legacy, flag=flag)
    holds = spec.holds
    if state is None:
        _remove_curve_files(out)
    elif rows:  # drops rows written after the last checkpoint (their holds are run again)
        _write_rows(out / CSV_NAME, rows)
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
    show = sys.stderr.isatty() if progress is None else progress
    bar = None
    try:
        with _deferred_interrupt() as interrupted:

            def stop_if_interrupted(_: Simulation | None = None) -> None:
                if interrupted():  # Ctrl-C: stop at the end of this chunk; the finished holds are kept
                    raise KeyboardInterrupt

            sim = Simulation(first, state, keep_records=False)
            if show:
                from tqdm import tqdm

                bar = tqdm(
                    total=len(holds), initial=len(rows), unit="rate", file=sys.stderr,
                    desc=f"flow curve Mn_ref={spec.config.mason_number:g}",
                )
            for index in range(len(rows), len(holds)):
                stop_if_interrupted()
                direction, rate = holds[index]
                sim.set_shear_rate(rate)
                start = time.perf_counter()
                end = sim.state.time + spec.strain_per_rate / rate
                records = sim.advance_to(end, chunk_steps=100, on_chunk=stop_if_interrupted)
                rows.append(
                    _hold_row(index, direction, rate, spec.config.mason_number, records, spec.config.n_blocks,
                              time.perf_counter() - start)
                )
                _write_rows(out / CSV_NAME, rows)
                with atomic_file(out / CHECKPOINT_NAME) as handle:
                    np.savez(handle, holds_done=np.array(len(rows)), **sim.state.arrays())
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix_str(f"rate {rate:g}: eta_r {rows[-1]['relative_viscosity']:.3g}")
            plot_flow_curves({spec.config.mason_number: rows}, out / PLOT_NAME)
    finally:
        if bar is not None:
            bar.close()
    return rows


def run_flow_curve_task(payload: dict[str, Any]) -> list[dict]:
    """Task form of :func:`run_flow_curve` for :func:`sim.runs.tasks.run_tasks` (a picklable payload)."""
    spec = FlowCurveSpec(
        SimulationConfig.from_dict(payload["config"]),
        tuple(payload["rates"]),
        payload["strain_per_rate"],
        payload["down"],
    )
    return run_flow_curve(
        spec,
        payload["out"],
        progress=payload.get("progress", False),
        resume=payload.get("resume", False),
        overwrite=payload.get("overwrite", False),
        command=payload.get("command"),
        flag=payload.get("flag", "out_dir"),
    )


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
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def write_combined(out: Path, curves: dict[float, list[dict[str, Any]]]) -> None:
    """``flow_curve.csv`` (with a ``mason_number_ref`` column) and ``flow_curve.png`` of several fields,
    atomically."""
    rows = [
        {"mason_number_ref": f"{mason:g}", **row} for mason, part in sorted(curves.items()) for row in part
    ]
    write_text_atomically(out / CSV_NAME, _csv_text(rows, ("mason_number_ref", *COLUMNS)))
    plot_flow_curves(curves, out / PLOT_NAME)
