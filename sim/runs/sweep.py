"""Sweeps: independent runs, one folder each, on a local process pool or a Dask cluster; resumable.

Each run is a pure function of its ``SimulationConfig`` (seed included), so a sweep is an embarrassingly
parallel map (:func:`sim.runs.tasks.run_tasks`) of :func:`run_point` over points. A point runs into
``OUT/<run_name>``; what a rerun of the same sweep does with a folder that is already there:

* ``result.json`` of the same configuration made by the same ``sim`` sources (``params.json``: config and
  source digest, see :func:`_same_run`): the point is finished and is not run again (``reused``);
* ``checkpoint.npz`` of the same configuration and sources, possibly with a smaller ``strain`` (a run
  that was interrupted, or a sweep extended to a longer strain): the run continues from the checkpoint
  (``resumed``), bit-identically to an uninterrupted run;
* anything else (other parameters, other sources): stale; its ``result.json`` and checkpoint are removed
  and the point is run from the start, never silently reused.

A point that fails is recorded (``error.json`` in its folder: exception, message, traceback) and the
others go on. ``OUT/sweep.json`` lists the command and every point with its status and files; it is
rewritten as each point finishes.

Folders follow the run-folder protocol (:mod:`sim.runs.folder`). The sweep claims ``OUT`` as
``sim sweep``; its identity (:func:`sweep_identity`) is what every point shares: the options that do not
name a point (time step, transient, near field, ...) and the longest ``strain``. A rerun may add points
(more ``--phi``, ``--mason``, ``--seeds``, ...) and a longer strain (the points are extended); other
shared options, or a shorter strain (which would redo and so delete the longer runs), are refused unless
``overwrite`` deletes the whole sweep. Each point's folder is a ``sim run`` folder, claimed by its run
(:func:`sim.runs.run.run_simulation`); before any work, every point folder that exists must be one (or a
pre-manifest run, or hold only a failed point's ``error.json``), so that a sweep never writes into, or
deletes, a folder it did not make.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.config import SimulationConfig
from sim.runs.folder import RunFolderError, claim, differing, normalise, preview, read_manifest
from sim.runs.io import read_json, versions, write_json
from sim.runs.legacy import legacy_command, legacy_markers
from sim.runs.tasks import TaskFailure, run_tasks

MANIFEST = "sweep.json"
"""The sweep's manifest in its output folder."""

ERROR_FILE = "error.json"
"""A failed point's record in its folder."""

PLANS = ("new", "stale", "resumable", "finished")
"""What a sweep finds in a point's folder before it starts (see the module docstring)."""

STATUSES = ("pending", "reused", "finished", "resumed", "failed")
"""A point's status in ``sweep.json``: not done yet, finished earlier and reused, run now from the start,
continued from its checkpoint, failed (see ``error.json``)."""


class SweepError(RuntimeError):
    """Some points of a sweep failed; the others finished. ``points`` holds every point's outcome."""

    def __init__(self, message: str, points: list[SweepPoint]) -> None:
        super().__init__(message)
        self.points = points


def run_name(config: SimulationConfig) -> str:
    """Directory name of a run: ``phi0.450_N200_Mninf_seed1``; a mechanism other than ``dip``, a
    quiescent run and a field direction other than y are added (``..._Mn1_dep_quiescent_e1,0,0_seed1``).

    Unique over the options a sweep varies (``--phi`` to 3 decimals, ``--mason`` to 6 significant
    digits, ``--n-particles``, ``--mechanism``, ``--seeds``); :func:`run_points` refuses points that share
    a name."""
    parts = [f"phi{config.volume_fraction:.3f}", f"N{config.n_particles}", f"Mn{config.mason_number:g}"]
    if config.mechanism != "dip":
        parts.append(config.mechanism)
    if config.quiescent:
        parts.append("quiescent")
    if tuple(config.field_direction) != (0.0, 1.0, 0.0):
        parts.append("e" + ",".join(f"{c:.3g}" for c in config.field_direction))
    parts.append(f"seed{config.seed}")
    return "_".join(parts)


def _source_digest() -> str:
    return versions()["sim_source"]


def _saved_params(out: Path) -> tuple[SimulationConfig, str] | None:
    """The configuration and source digest recorded in ``out/params.json``, or None if unreadable."""
    try:
        params = read_json(out / "params.json")
        return SimulationConfig.from_dict(params["config"]), str(params["versions"]["sim_source"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _same_run(out: Path, config: SimulationConfig, digest: str | None = None) -> bool:
    """True if ``out`` holds a run of ``config`` made by the same ``sim`` sources (digest in params.json)."""
    saved = _saved_params(out)
    return saved is not None and saved == (config, digest or _source_digest())


def _same_but_strain(a: SimulationConfig, b: SimulationConfig) -> bool:
    """True if two configurations differ at most in ``strain``."""
    first, second = a.to_dict(), b.to_dict()
    first.pop("strain")
    second.pop("strain")
    return first == second


def plan_point(out: Path, config: SimulationConfig, digest: str | None = None) -> str:
    """What a sweep will do with the folder ``out`` of ``config`` (one of :data:`PLANS`).

    ``finished``: ``result.json`` of this config and these sources; ``resumable``: a checkpoint of a run
    of this config and sources, except possibly a smaller strain (:func:`run_point` checks the
    checkpoint itself and runs from the start if it cannot continue it); ``stale``: files of a run with
    other parameters or other sources; ``new``: nothing there, or a run of this config that stopped
    before its first checkpoint (nothing to continue).
    """
    digest = digest or _source_digest()
    saved = _saved_params(out)
    if saved is not None and saved[1] == digest and _same_but_strain(saved[0], config):
        if saved[0] == config and saved_result(out) is not None:
            return "finished"
        return "resumable" if (out / "checkpoint.npz").exists() else "new"
    if out.is_dir() and any(out.iterdir()):
        return "stale"
    return "new"


def saved_result(out: Path) -> dict[str, Any] | None:
    """The contents of ``out/result.json``, or None when it is missing or unreadable (a truncated or
    binary file, or not a JSON object): such a point is redone, not reused."""
    try:
        result = read_json(out / "result.json")
    except (OSError, ValueError):  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        return None
    return result if isinstance(result, dict) else None


def _remove(out: Path, names: Sequence[str]) -> None:
    for name in names:
        (out / name).unlink(missing_ok=True)


def _can_resume(out: Path, config: SimulationConfig) -> bool:
    """True if ``run_simulation(config, out, resume=True)`` would continue the checkpoint in ``out``."""
    from sim.runs.run import _load_resumable

    if plan_point(out, config) not in ("resumable", "finished"):
        return False
    try:
        _load_resumable(out / "checkpoint.npz", config, None)
    except Exception:  # other parameters, already past the strain, or an unreadable file
        return False
    return True


def run_point(payload: dict[str, Any]) -> dict[str, Any]:
    """Run one sweep point; the task of :func:`run_points` (module-level, so workers can import it).

    Args:
        payload: ``config`` (``SimulationConfig.to_dict()``), ``out`` (the point's folder) and optionally
            ``command`` (recorded in ``params.json``).

    Returns:
        ``{"status": "resumed" | "finished", "result": <result.json>}``: continued from the folder's
        checkpoint when :func:`plan_point` and the checkpoint allow it, else run from the start (after
        removing a stale ``result.json``, ``error.json`` and checkpoint).
    """
    from sim.runs.run import run_simulation

    config = SimulationConfig.from_dict(payload["config"])
    out = Path(payload["out"])
    command = payload.get("command")
    # a result.json left from other parameters must not outlive an interrupted rerun
    _remove(out, ("result.json", ERROR_FILE))
    if _can_resume(out, config):
        result = run_simulation(config, out, progress=False, resume=True, command=command)
        return {"status": "resumed", "result": result}
    # the sweep has decided the folder's files are stale (or absent): the run replaces them
    result = run_simulation(config, out, progress=False, command=command, overwrite=True)
    return {"status": "finished", "result": result}


@dataclass
class SweepPoint:
    """One point of a sweep and what became of it.

    Attributes:
        name: its folder name (:func:`run_name`) under the sweep's folder.
        config: its parameters.
        plan: what the sweep found in the folder before it started (:data:`PLANS`).
        status: :data:`STATUSES`.
        result: the contents of its ``result.json`` once finished (or reused).
        failure: the exception that stopped it, if it failed.
    """

    name: str
    config: SimulationConfig
    plan: str
    status: str = "pending"
    result: dict[str, Any] | None = None
    failure: TaskFailure | None = None

    def entry(self) -> dict[str, Any]:
        """The point's entry in ``sweep.json`` (file paths relative to the sweep's folder)."""
        return {
            "name": self.name,
            "status": self.status,
            "plan": self.plan,
            "result": f"{self.name}/result.json" if self.result is not None else None,
            "error": None
            if self.failure is None
            else {
                "file": f"{self.name}/{ERROR_FILE}",
                "type": self.failure.error,
                "message": self.failure.message,
            },
            "config": self.config.to_dict(),
        }


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


COMMAND = "sim sweep"
"""How a sweep's folder names its owner in ``manifest.json`` (:mod:`sim.runs.folder`)."""

POINT_FIELDS = ("volume_fraction", "n_particles", "mason_number", "mechanism", "seed", "field_direction")
"""The configuration fields that name a point (:func:`run_name`): a sweep may add points that differ in
them."""


def sweep_identity(configs: Sequence[SimulationConfig]) -> dict[str, Any]:
    """The identity of a sweep's folder: every configuration field but :data:`POINT_FIELDS` and
    ``strain``, with its value (or the sorted list of its values where the points differ), and the
    longest ``strain``."""
    values: dict[str, list[Any]] = {}
    for config in configs:
        for key, value in config.to_dict().items():
            if key in POINT_FIELDS or key == "strain":
                continue
            seen = values.setdefault(key, [])
            if value not in seen:
                seen.append(value)
    identity: dict[str, Any] = {
        key: seen[0] if len(seen) == 1 else sorted(seen, key=repr) for key, seen in values.items()
    }
    identity["strain"] = max((config.strain for config in configs), default=0.0)
    return identity


def _sweep_differences(saved: Any, requested: Any) -> list[str]:
    """``compare`` of :func:`sim.runs.folder.claim` for a sweep: the differing keys, ``strain`` only when
    the requested one is shorter (a longer strain extends the points)."""
    keys = [key for key in differing(saved, requested) if key != "strain"]
    old, new = normalise(saved).get("strain"), normalise(requested).get("strain")
    if isinstance(old, int | float) and isinstance(new, int | float) and new < old:
        keys.append("strain")
    return keys


def _check_point_folder(folder: Path, flag: str) -> None:
    """Refuse (:class:`RunFolderError`) a point folder that the sweep may not use: anything but a missing
    folder, a ``sim run`` folder (with its manifest, or written before manifests), or one that holds only
    a failed point's ``error.json``."""
    if not folder.exists():
        return
    if not folder.is_dir():
        raise RunFolderError(f"{flag}: the point {folder} exists and is not a folder")
    manifest = read_manifest(folder)
    if manifest is not None:
        if manifest.command != "sim run":
            raise RunFolderError(
                f"{flag}: the point folder {folder} belongs to another command ({manifest.command!r}); "
                f"choose another {flag}, or give --overwrite to delete the whole sweep and start afresh"
            )
        return
    entries = sorted(entry.name for entry in folder.iterdir() if entry.name != ERROR_FILE)
    if entries and legacy_command(folder) != "sim run":
        shown = ", ".join(entries[:5]) + (", ..." if len(entries) > 5 else "")
        raise RunFolderError(
            f"{flag}: the point folder {folder} is not empty ({shown}) and holds no run of a sweep; move "
            f"it away, or choose another {flag}"
        )


NAME_PRECISION = {
    "volume_fraction": "volume_fraction has 3 decimals there",
    "mason_number": "mason_number has 6 significant digits there",
    "field_direction": "field_direction has 3 significant digits per component there",
}
"""How :func:`run_name` rounds the parameters it writes with fewer digits than they hold."""


def check_unique_names(configs: Sequence[SimulationConfig]) -> None:
    """Raise ``ValueError`` naming the differing parameters if two configurations share a folder name."""
    seen: dict[str, SimulationConfig] = {}
    for config in configs:
        name = run_name(config)
        other = seen.get(name)
        if other is None:
            seen[name] = config
            continue
        first, second = other.to_dict(), config.to_dict()
        differing = [f for f in first if first[f] != second[f]]
        rounded = [NAME_PRECISION[f] for f in differing if f in NAME_PRECISION]
        what = (
            "the same point is listed twice"
            if not differing
            else "they differ in "
            + ", ".join(f"{f} ({first[f]!r} and {second[f]!r})" for f in differing)
            + ", which the folder name does not tell apart"
            + (f" ({'; '.join(rounded)})" if rounded else "")
        )
        raise ValueError(f"two points of the sweep would share the folder {name}: {what}")


def run_points(
    configs: Sequence[SimulationConfig],
    out_dir: str | Path,
    workers: int = 2,
    scheduler: str | None = None,
    *,
    progress: bool = False,
    command: list[str] | None = None,
    arguments: dict[str, Any] | None = None,
    log: Callable[[str], None] | None = None,
    resume: bool = False,
    overwrite: bool = False,
) -> list[SweepPoint]:
    """Run every configuration into ``out_dir/<run_name>``; failures are recorded and the rest go on.

    Finished points are reused and interrupted ones resumed (module docstring). ``out_dir`` is claimed
    first (``manifest.json``, :mod:`sim.runs.folder`); then ``out_dir/sweep.json`` (command, arguments,
    source digest, every point's status, result and error files, counts) is written before the first
    point starts and rewritten as each point finishes.

    Args:
        configs: the points (distinct folder names: see :func:`check_unique_names`).
        out_dir: the sweep's folder (created).
        workers: local worker processes, >= 1 (1: in this process); ignored with ``scheduler``.
        scheduler: address of a Dask scheduler (``tcp://host:8786``), or None for the local pool.
        progress: a tqdm bar over the points on stderr.
        command: the command line, recorded in ``sweep.json`` and in every run's ``params.json``.
        arguments: the parsed arguments, recorded in ``sweep.json``.
        log: called with one line per point as it finishes (and one for the reused ones).
        resume: insist on continuing a sweep already in ``out_dir`` (refused when there is none).
        overwrite: delete the sweep in ``out_dir`` (everything in it) and start afresh.

    Returns:
        The points in input order; ``status`` is ``reused``, ``finished``, ``resumed`` or ``failed``.

    Raises:
        ValueError: two points share a folder name, or ``workers < 1``; :class:`RunFolderError` (a
        ``ValueError``, before anything is written): a folder the sweep may not use (module docstring).
    """
    check_unique_names(configs)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    out = Path(out_dir)
    identity = sweep_identity(configs)
    legacy = legacy_markers(out, COMMAND, overwrite)
    options: dict[str, Any] = dict(
        resume=resume, overwrite=overwrite, legacy=legacy, compare=_sweep_differences
    )
    found = preview(out, COMMAND, identity, **options)
    if found in ("same", "adopted"):
        for config in configs:
            _check_point_folder(out / run_name(config), "--out")
    claim(out, COMMAND, identity, argv=command, **options)
    digest = _source_digest()
    points = []
    for config in configs:
        name = run_name(config)
        point = SweepPoint(name=name, config=config, plan=plan_point(out / name, config, digest))
        if point.plan == "finished":
            point.status = "reused"
            point.result = saved_result(out / name)
        points.append(point)
    manifest: dict[str, Any] = {
        "command": command,
        "arguments": arguments,
        "sim_source": digest,
        "workers": workers if scheduler is None else None,
        "scheduler": scheduler,
        "started": _now(),
        "updated": _now(),
        "finished": None,
    }

    def write_manifest() -> None:
        counts = {status: sum(p.status == status for p in points) for status in STATUSES}
        manifest.update(updated=_now(), counts=counts, points=[p.entry() for p in points])
        write_json(out / MANIFEST, manifest)

    write_manifest()
    reused = [p for p in points if p.status == "reused"]
    if reused and log is not None:
        names = ", ".join(p.name for p in reused)
        log(f"{len(reused)} of {len(points)} points finished earlier (same parameters and sources): {names}")
    todo = [p for p in points if p.status == "pending"]
    payloads = [{"config": p.config.to_dict(), "out": str(out / p.name), "command": command} for p in todo]
    done = len(reused)

    def finished(index: int, outcome: dict[str, Any] | TaskFailure) -> None:
        nonlocal done
        point = todo[index]
        done += 1
        if isinstance(outcome, TaskFailure):
            point.status, point.failure = "failed", outcome
            (out / point.name).mkdir(parents=True, exist_ok=True)
            write_json(
                out / point.name / ERROR_FILE,
                {
                    **outcome.to_dict(),
                    "run": point.name,
                    "config": point.config.to_dict(),
                    "sim_source": digest,
                    "time": _now(),
                },
            )
            line = f"[{done}/{len(points)}] {point.name} FAILED: {outcome.error}: {outcome.message}"
        else:
            point.status, point.result = outcome["status"], outcome["result"]
            _remove(out / point.name, (ERROR_FILE,))
            line = (
                f"[{done}/{len(points)}] {point.name} {point.status}: eta_r = "
                f"{outcome['result']['relative_viscosity']:.4g}, {outcome['result']['wall_seconds']:.0f} s"
            )
        write_manifest()
        if log is not None:
            log(line)

    run_tasks(
        run_point,
        payloads,
        workers=workers,
        scheduler=scheduler,
        on_error="record",
        progress=progress,
        description="sweep points",
        on_result=finished,
    )
    manifest["finished"] = _now()
    write_manifest()
    return points


def run_sweep(
    configs: Sequence[SimulationConfig],
    out_dir: str | Path,
    processes: int = 2,
    scheduler: str | None = None,
    progress: bool = False,
    resume: bool = False,
    overwrite: bool = False,
) -> list[dict[str, Any]]:
    """Run ``configs`` with ``processes`` worker processes (or on a Dask cluster); results in input order.

    :func:`run_points` with the results only; if any point failed, the others still finish and then
    :class:`SweepError` lists the failures (``error.json`` in each failed point's folder).
    """
    points = run_points(
        configs,
        out_dir,
        workers=processes,
        scheduler=scheduler,
        progress=progress,
        resume=resume,
        overwrite=overwrite,
    )
    failed = [p for p in points if p.failure is not None]
    if failed:
        listed = "; ".join(f"{p.name}: {p.failure.error}: {p.failure.message}" for p in failed if p.failure)
        raise SweepError(f"{len(failed)} of {len(points)} sweep points failed: {listed}", points)
    return [p.result for p in points if p.result is not None]


def manifest_text(points: Sequence[SweepPoint]) -> str:
    """One line of counts: ``12 points: 3 reused, 8 finished, 1 failed``."""
    counts = {status: sum(p.status == status for p in points) for status in STATUSES}
    listed = ", ".join(f"{n} {status}" for status, n in counts.items() if n)
    return f"{len(points)} points: {listed}"
