"""One run = a pure function of its ``SimulationConfig`` (seed included) that writes one directory.

Besides the step records (rheology), a run samples g(r), its x–y projection and the displacement for the
MSD at fixed clock times (:mod:`sim.runs.observables`); their accumulators travel in the checkpoint, so a
resumed run continues them bit for bit. On request it keeps its state at multiples of its strain
(``snapshots/``, :mod:`sim.runs.snapshots`) and a GSD trajectory (``trajectory.gsd``,
:mod:`sim.runs.trajectory`), and it may start from a given configuration instead of a random packing
(:mod:`sim.runs.initial_state`).

A run ends at its requested strain exactly: the steps adapt (they are at most ``time_step``), and the one
that would pass the end is shortened to land on it (:func:`_advance_with_checkpoints`). The update of that
step is the variable-step AB2 the stepper always uses,
``x_{n+1} = x_n + h [(1 + r/2) u_n - (r/2) u_{n-1}]`` with ``r = h / h_prev`` (:mod:`sim.integrators`), so
it stays second order. Every earlier step is the one an unshortened run takes, bit for bit: the cap on
the step (``end - clock``) only binds for the last one, and not even there in a run of a whole number of
steps (:func:`_step_at_most_to`). The checkpoint a finished run leaves holds the
state before that shortened step, so that extending the run (``--resume`` with a longer ``--strain``)
continues exactly as the longer run from the start does.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import MAX_STEPS, SimulationConfig
from sim.plots.figures import plot_rheology
from sim.runs import io
from sim.runs.folder import RunFolderError, claim, normalise, preview, read_manifest
from sim.runs.initial_state import InitialState, check_initial_state, read_initial_state
from sim.runs.legacy import legacy_markers
from sim.runs.observables import DEFAULT_SAMPLE_INTERVAL, RunObservables
from sim.runs.schedule import StrainMultiples
from sim.runs.snapshots import SNAPSHOT_FOLDER, SnapshotWriter
from sim.runs.trajectory import TRAJECTORY, TrajectoryError, TrajectoryWriter
from sim.simulation import Simulation, StepRecords
from sim.state import SimulationState
from sim.step_parameters import field_strength
from sim.stepper import stop_time

COMPILE_NOTICE = "compiling kernels (first run only, about a minute)..."
"""Printed to stderr before a run whose compiled kernels are not in numba's cache yet."""


def _name(parameter: str, names: Mapping[str, str] | None) -> str:
    """How an error message names ``parameter`` (a config field or an argument of :func:`run_simulation`)."""
    return (names or {}).get(parameter, parameter)


def check_run_length(config: SimulationConfig, names: Mapping[str, str] | None = None) -> None:
    """Raise ``ValueError`` unless the run takes at least one step and leaves a sample after the transient.

    The stress is sampled at the start of every step, and steps are at most ``time_step`` long (they
    may adapt below it), so the last sample of a run to ``strain`` may be as early as
    ``strain - time_step``; the averages need one sample at or after the transient.

    Args:
        config: the run's parameters.
        names: how messages name parameters (the command line passes its flags); field names by default.
    """
    strain, transient = _name("strain", names), _name("transient_strain", names)
    if not config.strain > 0.0:
        raise ValueError(
            f"{strain} must be > 0 for a run (there is nothing to average otherwise), got {config.strain!r}"
        )
    earliest_last_sample = max(config.duration - config.time_step, 0.0)  # a clock time
    if config.transient_time > earliest_last_sample:
        if config.shear_rate > 0.0:
            earliest_last_sample *= config.shear_rate  # as a strain, like the flags
        default = " (the default: half of a run shorter than 20)" if config.transient_strain is None else ""
        raise ValueError(
            f"no samples after the transient: averaging starts at strain {config.transient:g}{default}, "
            f"but the last stress sample of a {strain}={config.strain:g} run may be at strain "
            f"{earliest_last_sample:g} (one per step of at most {_name('time_step', names)}="
            f"{config.time_step:g}, taken at its start); lengthen {strain} or shorten {transient}"
        )
    _check_field_steps(config, names)


def field_step_estimate(config: SimulationConfig) -> float:
    """Steps a run of ``config`` takes at the least with its field on (0 without a field).

    The adaptive step keeps the non-affine displacement per step below ``max_displacement`` times the
    mean spacing; the dipolophoretic velocity has the scale ``U0 = 1/mason_number``, so a step is at most
    about ``max_displacement * spacing / U0`` long once the field moves the spheres, and the run's
    ``duration`` needs ``duration * U0 / (max_displacement * spacing)`` of them (more where pairs move
    faster than ``U0``): the field's share of the planned work, beside ``duration / time_step``.
    """
    u0 = field_strength(config.mason_number)
    if u0 == 0.0:
        return 0.0
    return config.duration * u0 / (config.max_displacement * config.mean_spacing)


def _check_field_steps(config: SimulationConfig, names: Mapping[str, str] | None) -> None:
    """Refuse a field so strong that the adaptive step would need more than ``MAX_STEPS`` steps
    (``--mason 1e-9``: steps of ~1e-11, an effective hang), naming the smallest Mason number allowed."""
    steps = field_step_estimate(config)
    if steps <= MAX_STEPS:
        return
    mason, strain = _name("mason_number", names), _name("strain", names)
    smallest = config.mason_number * steps / MAX_STEPS
    raise ValueError(
        f"{mason}={config.mason_number:g} is too strong a field for {strain}={config.strain:g}: its "
        f"velocity scale U0 = 1/{mason} = {1.0 / config.mason_number:.3g} and the displacement bound "
        f"{_name('max_displacement', names)}={config.max_displacement:g} of the mean spacing make steps of "
        f"about {config.duration / steps:.3g}, some {steps:.3g} steps (more than {MAX_STEPS:.0e}); "
        f"{mason} must be in [{smallest:.3g}, inf] for this run (or shorten {strain})"
    )


def _check_output_directory(out: Path, names: Mapping[str, str] | None) -> None:
    """Refuse an output path that exists but is not a directory."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"{_name('out_dir', names)} {out} exists and is not a directory")


RUN_FILES = (
    "params.json",
    "checkpoint.npz",
    "result.json",
    "final_state.npz",
    "timeseries.csv",
    "pair_distribution.npz",
    "msd.csv",
    "stress.png",
    "layering.csv",
    "layering.png",
    TRAJECTORY,
)
"""The files a run writes into its folder (:mod:`sim.runs.io`); a folder holding any of them holds a run.
(``snapshots/``, :data:`sim.runs.snapshots.SNAPSHOT_FOLDER`, is its folder of snapshots.)"""

MAX_KEPT_STATES = 100_000
"""Most snapshots, and most trajectory frames, a run may plan (``--strain`` over ``--snapshot-every`` or
``--trajectory-every``): more is almost certainly a typo, and fills the disk (a frame of N = 2000 takes
72 kB)."""

OPTIONAL_IDENTITY = ("initial_state", "snapshot_every", "trajectory_every")
"""Identity keys a run has only when they are set (a missing key reads as None, so that a run folder made
before they existed, or without them, keeps its identity)."""


COMMAND = "sim run"
"""How a run's folder names its owner in ``manifest.json`` (:mod:`sim.runs.folder`)."""


def run_identity(
    config: SimulationConfig,
    sample_interval: float = DEFAULT_SAMPLE_INTERVAL,
    initial_state: str | None = None,
    snapshot_every: float | None = None,
    trajectory_every: float | None = None,
) -> dict[str, Any]:
    """The parameters that make a run's results what they are (its folder's identity in the manifest):
    every field of ``config``, the observables' ``sample_interval`` and, when set, the digest of the
    configuration it starts from (:attr:`sim.runs.initial_state.InitialState.digest`) and the spacings of
    its snapshots and trajectory frames (strain)."""
    identity: dict[str, Any] = {**config.to_dict(), "sample_interval": float(sample_interval)}
    optional = {
        "initial_state": initial_state,
        "snapshot_every": None if snapshot_every is None else float(snapshot_every),
        "trajectory_every": None if trajectory_every is None else float(trajectory_every),
    }
    identity.update({key: value for key, value in optional.items() if value is not None})
    return identity


def _saved_config(out: Path) -> SimulationConfig | None:
    """The configuration of the run in ``out`` (its ``params.json``, else its checkpoint), None if neither
    can be read."""
    try:
        return SimulationConfig.from_dict(io.read_json(out / "params.json")["config"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    try:
        return io.load_checkpoint(out / "checkpoint.npz")[0]
    except Exception:  # missing or unreadable: nothing to compare with
        return None


def _run_differences(resume: bool) -> Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]]:
    """``compare`` of :func:`sim.runs.folder.claim` for a run: the identity keys (in order) whose values
    differ between the saved and the requested run, ``strain`` left out with ``resume`` (extending a run),
    keys the saved identity lacks (a folder written before they existed) left out, and
    ``sample_interval`` left out (continuing from a checkpoint checks it, naming it:
    :meth:`RunObservables.for_run`; a run without a checkpoint starts afresh)."""

    def compare(saved: Mapping[str, Any], requested: Mapping[str, Any]) -> list[str]:
        old, new = normalise(saved), normalise(requested)
        keys = [
            key
            for key in new
            if key in old and old[key] != new[key] and key not in ("sample_interval", *OPTIONAL_IDENTITY)
        ]
        keys += [key for key in OPTIONAL_IDENTITY if old.get(key) != new.get(key)]
        return [key for key in keys if not (resume and key == "strain")]

    return compare


def _check_run_folder(
    out: Path, identity: dict[str, Any], resume: bool, overwrite: bool, names: Mapping[str, str] | None
) -> tuple[str, tuple[str, ...]]:
    """What a run finds in ``out`` (the ``state`` of :func:`sim.runs.folder.claim`, and the pre-manifest
    files by which it adopts a folder), or :class:`RunFolderError` (a ``ValueError``); nothing is written.

    The protocol's rules (:mod:`sim.runs.folder`): a folder holding a run of the same parameters is
    continued (from its checkpoint; a finished run's results are rewritten, unchanged), ``resume`` also
    continues one of a smaller ``strain`` (extending it), ``overwrite`` deletes whatever run the folder
    holds; a run of other parameters is refused naming them (``ValueError``), as is another command's
    folder or a non-empty folder that no command owns. A folder written before manifests (``params.json``,
    ``checkpoint.npz``, ``result.json``) is compared through its ``params.json`` (else its checkpoint).
    """
    out_flag, resume_flag, overwrite_flag = (_name(n, names) for n in ("out_dir", "resume", "overwrite"))
    if resume and overwrite:
        raise RunFolderError(f"{resume_flag} and {overwrite_flag} exclude each other")
    legacy = legacy_markers(out, COMMAND, overwrite, out_flag, overwrite_flag)
    if not overwrite and out.is_dir():
        ways = f"choose another {out_flag}, or give {overwrite_flag} to delete its files and start afresh"
        manifest = read_manifest(out)
        saved: dict[str, Any] | None = None
        if manifest is not None and manifest.command == COMMAND:
            saved = io.from_json_ready(manifest.params)
        elif manifest is None and legacy:
            config = _saved_config(out)
            if config is None:
                raise RunFolderError(
                    f"{out_flag} {out} holds files of another run ({', '.join(legacy)}) whose parameters "
                    f"cannot be read; {ways}"
                )
            saved = config.to_dict()
        if saved is not None:
            differing = _run_differences(resume)(saved, identity)
            if differing:
                listed = ", ".join(
                    f"{_name(f, names)} ({saved.get(f)!r} there, {identity.get(f)!r} requested)"
                    for f in differing
                )
                if resume:
                    raise RunFolderError(
                        f"{resume_flag}: {out_flag} {out} holds a run with different parameters: {listed}; "
                        f"only {_name('strain', names)} may differ (to extend a run); {ways}"
                    )
                extend = (
                    f"; {resume_flag} continues it to the new {_name('strain', names)}"
                    if differing == ["strain"] and (out / "checkpoint.npz").exists()
                    else ""
                )
                raise RunFolderError(
                    f"{out_flag} {out} holds a run with different parameters: {listed}{extend}; {ways}"
                )
    state = preview(
        out,
        COMMAND,
        identity,
        resume=resume,
        overwrite=overwrite,
        legacy=legacy,
        compare=_run_differences(resume),
        flag=out_flag,
        resume_flag=resume_flag,
        overwrite_flag=overwrite_flag,
    )
    return state, legacy


def _remove_outputs(out: Path, keep: tuple[str, ...] = ()) -> None:
    """Delete the run files of ``out`` (and temporary files of :func:`sim.runs.io.atomic_file`) but ``keep``
    (the snapshot folder too, unless ``keep`` names it).

    Done before a run writes its ``params.json``, so that a run killed later never leaves the new
    parameters beside the results of an earlier run."""
    if not out.is_dir():
        return
    for name in RUN_FILES:
        if name not in keep:
            (out / name).unlink(missing_ok=True)
    snapshots = out / SNAPSHOT_FOLDER
    if SNAPSHOT_FOLDER not in keep and snapshots.is_dir() and not snapshots.is_symlink():
        shutil.rmtree(snapshots)
    for name in RUN_FILES:
        for tmp in out.glob(f".{name}.*{io.TEMPORARY_SUFFIX}"):
            tmp.unlink(missing_ok=True)


def _differing_parameters(saved: SimulationConfig, requested: SimulationConfig) -> list[str]:
    """Fields (other than ``strain``) in which two configurations differ."""
    old, new = saved.to_dict(), requested.to_dict()
    return [field for field in old if field != "strain" and old[field] != new.get(field)]


def _load_resumable(
    checkpoint: Path,
    config: SimulationConfig,
    names: Mapping[str, str] | None,
    how: str | None = None,
    origin: float = 0.0,
) -> tuple[SimulationState, StepRecords, float]:
    """State, records and wall time of ``checkpoint`` if ``config`` may continue it, else ``ValueError``
    (``FileNotFoundError`` when there is none); messages start with ``how`` (default: the resume flag).

    Only ``strain`` may differ from the checkpoint's parameters (extending a run), and the checkpoint
    may not hold a step that a run to ``config.strain`` would not take (one starting at or after it; the
    run started at the clock ``origin``: 0, or the clock of the configuration it started from).
    """
    resume = how or _name("resume", names)
    if not (checkpoint.exists() or checkpoint.is_symlink()):
        raise FileNotFoundError(f"{resume}: no checkpoint at {checkpoint}")
    try:
        saved_config, state, records, wall_before = io.load_checkpoint(checkpoint)
    except (io.CheckpointError, OSError) as exc:
        raise io.CheckpointError(f"{resume}: {exc}") from None
    differing = _differing_parameters(saved_config, config)
    if differing:
        old, new = saved_config.to_dict(), config.to_dict()
        listed = ", ".join(f"{_name(f, names)} ({old[f]!r} there, {new[f]!r} requested)" for f in differing)
        raise ValueError(
            f"{resume}: the checkpoint in {checkpoint.parent} was written with different parameters: "
            f"{listed}; only {_name('strain', names)} may differ (to extend a run)"
        )
    last_start = float(records.time[-1]) if records.time.size else -math.inf
    if last_start >= stop_time(origin + config.duration, config.time_step):  # a run to config.strain stops
        last_start -= origin
        if config.shear_rate > 0.0:
            last_start *= config.shear_rate  # as a strain, like the flags
        strain = _name("strain", names)
        raise ValueError(
            f"{resume}: the checkpoint in {checkpoint.parent} has already run past {strain}="
            f"{config.strain:g} (its last step started at strain {last_start:g}); give a {strain} above "
            f"{last_start:g}"
        )
    return state, records, wall_before


def compiled_kernels_cached() -> bool:
    """True when numba's cache holds compiled kernels of this checkout of ``sim`` (so no long compile).

    The cache directory (``sim.NUMBA_CACHE_DIR``) is named after a hash of the ``sim/`` sources; inside
    it numba keeps one folder per source directory, named after that directory's absolute path, holding
    an index file (``*.nbi``) per compiled kernel. A checkout at another path, or other sources, find no
    index files and compile. (Numba also checks each file's content, or before numba 0.68 its
    modification time, when it loads a kernel; that finer check is not repeated here.)
    """
    import sim

    cache = Path(sim.NUMBA_CACHE_DIR) if sim.NUMBA_CACHE_DIR else None
    if cache is None or not cache.is_dir():
        return False
    try:
        from numba.core.caching import _CacheLocator
    except ImportError:  # another numba layout: any index at all
        return any(cache.rglob("*.nbi"))
    package = Path(os.path.abspath(sim.__file__)).parent
    directories = {path.parent for path in package.rglob("*.py")}
    return any(
        any((cache / _CacheLocator.get_suitable_cache_subpath(str(d / "x.py"))).glob("*.nbi"))
        for d in directories
    )


def _progress_bar(config: SimulationConfig, strain: float) -> Any:
    """A tqdm bar on stderr from ``strain`` to ``config.strain``; its clock starts now."""
    from tqdm import tqdm

    return tqdm(
        total=round(config.strain, 6),
        initial=round(strain, 6),
        unit="strain",
        desc=f"phi={config.volume_fraction} N={config.n_particles}",
        file=sys.stderr,
        bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} strain [{elapsed}<{remaining}]",
    )


def _check_every(
    value: float | None, parameter: str, config: SimulationConfig, names: Mapping[str, str] | None
) -> None:
    """Refuse a spacing of snapshots or frames that is not a finite number > 0, or that plans more than
    :data:`MAX_KEPT_STATES` of them."""
    if value is None:
        return
    unit = "time (a/U0)" if config.quiescent else "strain"
    flag = _name(parameter, names)
    smallest = config.strain / MAX_KEPT_STATES
    if not (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value > 0.0
    ):
        raise ValueError(f"{flag} must be a {unit} > 0 (finite), got {value!r}")
    if value < smallest:
        raise ValueError(
            f"{flag}={value:g} would keep more than {MAX_KEPT_STATES} states over "
            f"{_name('strain', names)}={config.strain:g}: {flag} must be in [{smallest:.3g}, inf) ({unit})"
        )


def _initial_state(
    state: SimulationState | InitialState | str | Path | None,
    config: SimulationConfig,
    names: Mapping[str, str] | None,
) -> InitialState | None:
    """The configuration a run starts from (:mod:`sim.runs.initial_state`), checked against ``config``."""
    if state is None:
        return None
    if isinstance(state, SimulationState):
        initial = InitialState.from_state(state)
    elif isinstance(state, InitialState):
        initial = state
    elif isinstance(state, str | Path):
        initial = read_initial_state(state, names)
    else:
        raise ValueError(
            f"{_name('state', names)} must be a SimulationState, an InitialState or a file, got "
            f"{type(state).__name__}"
        )
    check_initial_state(initial, config, names)
    return initial


@dataclasses.dataclass
class _Recorders:
    """What a run keeps besides its records and observables: its snapshots and its trajectory frames.

    Attributes:
        snapshots: writes ``snapshots/strain_XXXX.npz`` (None: no ``snapshot_every``).
        trajectory: collects the frames of ``trajectory.gsd`` (None: no ``trajectory_every``).
        final_checkpoint: set once the checkpoint of the state before the run's last (shortened) step
            has been written; the results then leave it as it is.
    """

    snapshots: SnapshotWriter | None = None
    trajectory: TrajectoryWriter | None = None
    final_checkpoint: bool = False

    @property
    def next_clock(self) -> float:
        """The clock of the next snapshot or frame (inf: none)."""
        clocks = [w.next_clock for w in (self.snapshots, self.trajectory) if w is not None]
        return min(clocks, default=math.inf)

    def record(self, state: SimulationState) -> None:
        """Keep ``state`` as a snapshot and as a frame where it has reached their next multiple."""
        if self.snapshots is not None:
            self.snapshots.write_if_due(state)
        if self.trajectory is not None:
            self.trajectory.add_if_due(state)

    def flush(self) -> None:
        """Write the pending frames (before a checkpoint that counts them)."""
        if self.trajectory is not None:
            self.trajectory.flush()

    def arrays(self) -> dict[str, np.ndarray]:
        """What the checkpoint holds of them: the frames written (``trajectory_frames``)."""
        if self.trajectory is None:
            return {}
        return {TRAJECTORY_FRAMES: np.array(self.trajectory.frames, dtype=np.int64)}


TRAJECTORY_FRAMES = "trajectory_frames"
"""The checkpoint's count of the frames ``trajectory.gsd`` held when it was written (with the observables'
arrays, :data:`sim.runs.io.OBSERVABLE_PREFIX`)."""


def run_simulation(
    config: SimulationConfig,
    out_dir: str | Path,
    progress: bool | None = None,
    resume: bool = False,
    command: list[str] | None = None,
    parameter_names: Mapping[str, str] | None = None,
    sample_interval: float = DEFAULT_SAMPLE_INTERVAL,
    overwrite: bool = False,
    state: SimulationState | InitialState | str | Path | None = None,
    snapshot_every: float | None = None,
    trajectory_every: float | None = None,
) -> dict[str, Any]:
    """Run (or continue) a simulation, writing its files to ``out_dir``; return the result dictionary.

    Every check of the input happens before anything is written: a refused run leaves no directory
    behind. The folder follows the run-folder protocol (:mod:`sim.runs.folder`, :func:`_check_run_folder`):
    ``manifest.json`` (command ``sim run``, identity :func:`run_identity`) is written first; a folder
    holding this run (same parameters) is continued from its checkpoint, bit for bit (a finished run's
    results are rewritten unchanged); ``resume`` insists on a run to continue and may extend its
    ``strain``; ``overwrite`` deletes the folder's previous run, whatever made it; a run of other
    parameters, another command's folder and a non-empty folder without a manifest are refused. The
    checkpoint a run continues from is validated first (a damaged one is named with what is wrong).
    Before ``params.json`` is written, the files of the earlier run that the new one will rewrite are
    deleted (when continuing, all but the checkpoint, the snapshots and the trajectory), so an
    interrupted run never leaves stale results beside its parameters.

    The run ends at ``config.strain`` (after its start) exactly: its last step is shortened to land there
    (module docstring). The checkpoint it leaves holds the state before that step, so that a longer
    ``strain`` continues as the longer run does.

    Args:
        config: the run's parameters; ``strain`` must be > 0 and leave a sample after the transient.
        out_dir: output directory (created). With ``resume=True`` it must hold a run of the same parameters
            except possibly a smaller ``strain`` (the run is then extended); the run continues from its
            ``checkpoint.npz`` bit-identically to an uninterrupted run of ``config``.
        progress: show a progress bar; ``None`` means only when stderr is a terminal. Unless ``False``,
            a note goes to stderr before kernels are compiled (the first run of these sources).
        resume: continue the run in ``out_dir`` (from its checkpoint), possibly to a longer ``strain``.
        overwrite: delete the run in ``out_dir`` (every file of the folder, whichever command made it) and
            start afresh.
        command: the command line, recorded in ``params.json``.
        parameter_names: how error messages name parameters (config fields, ``out_dir``, ``resume``,
            ``state``, ``snapshot_every``, ``trajectory_every``); the command line passes its flags. Field
            names by default.
        sample_interval: clock interval between observable samples (g(r), x–y projection, displacement
            for the MSD), > 0; a resumed run must use its checkpoint's.
        state: start from this configuration instead of a random packing (:mod:`sim.runs.initial_state`):
            a file (a run's ``checkpoint.npz``, ``final_state.npz`` or snapshot, a GSD file or
            ``FILE.gsd:K``), an :class:`~sim.runs.initial_state.InitialState` or a
            :class:`~sim.SimulationState`. Its positions (wrapped into the box,
            :meth:`sim.Simulation.enter`), clock and strain are taken; its field and shear rate are
            ``config``'s, its AB2 history, step count and displacement start afresh. Its particle count
            must be ``config.n_particles`` and its box (when a file says it) ``config.box_length``.
            The run lasts ``config.strain`` from there, and its transient is counted from there. Its
            digest is part of the folder's identity, and a rerun (or ``resume``) gives it again.
        snapshot_every: keep the state at every multiple of this strain (time when quiescent) after the
            start in ``snapshots/`` (:mod:`sim.runs.snapshots`); finite, > 0, at most
            :data:`MAX_KEPT_STATES` of them. None: no snapshots.
        trajectory_every: write a frame at every multiple of this strain (time when quiescent) from the
            start into ``trajectory.gsd`` (:mod:`sim.runs.trajectory`); same range. None: no trajectory.

    Returns:
        The contents of ``result.json``: ``relative_viscosity``, ``relative_viscosity_stderr``, ``n1``,
        ``n1_stderr``, ``n2``, ``n2_stderr``, ``particle_pressure`` (``-tr(Sigma^p)/3``),
        ``particle_pressure_stderr``, ``strain``, ``steps``, ``n_particles``, ``volume_fraction``,
        ``min_gap``, ``wall_seconds`` and per-contribution means (eta_r, N1, N2, particle pressure). A
        standard error that needs more samples than the run has after its transient (fewer than
        ``n_blocks``) is NaN. The observables add
        ``diffusivity_xx``, ``diffusivity_yy``, ``diffusivity_zz`` (units gammadot a^2; U0 a when quiescent;
        NaN, with the reason in ``diffusivity_note``, when the run is too short for the fit window),
        ``diffusivity_fit_window`` ``[start, end]`` (lags of the fit), ``diffusivity_note``,
        ``msd_samples``, ``pair_distribution_samples``, ``observables_sample_interval``,
        ``observables_from_strain`` and ``observables_note`` (see :meth:`RunObservables.results`); the
        arrays go to ``pair_distribution.npz`` and ``msd.csv`` (:mod:`sim.runs.io`). A run from a given
        configuration adds ``initial_state`` (``source``, ``digest``, ``time``, ``strain``), a run with a
        trajectory ``trajectory_frames``.

    Raises:
        ValueError: bad input (the message names the parameter); :class:`sim.runs.folder.RunFolderError`
        (a ``ValueError``) for a folder this run may not use, ``resume`` without a run to continue, or
        ``resume`` with ``overwrite``; :class:`sim.runs.io.CheckpointError` (a ``ValueError``) for a damaged
        checkpoint; :class:`sim.runs.initial_state.InitialStateError` (a ``ValueError``) for a
        configuration that cannot be read or does not fit ``config``;
        :class:`sim.runs.trajectory.TrajectoryError` (a ``ValueError``) for a trajectory that cannot be
        continued; NotImplementedError: a configuration the simulator does not support yet;
        SimulationError: a step failed.
    """
    names = parameter_names
    if not str(out_dir).strip():  # Path("") would be the current folder
        raise ValueError(f"{_name('out_dir', names)} must name a directory, got {str(out_dir)!r}")
    out = Path(out_dir)
    check_run_length(config, names)
    if not (
        isinstance(sample_interval, int | float)
        and not isinstance(sample_interval, bool)
        and math.isfinite(sample_interval)
        and sample_interval > 0.0
    ):
        raise ValueError(f"{_name('sample_interval', names)} must be finite and > 0, got {sample_interval!r}")
    _check_every(snapshot_every, "snapshot_every", config, names)
    _check_every(trajectory_every, "trajectory_every", config, names)
    initial = _initial_state(state, config, names)
    _check_output_directory(out, names)
    identity = run_identity(
        config,
        sample_interval,
        None if initial is None else initial.digest,
        snapshot_every,
        trajectory_every,
    )
    found, legacy = _check_run_folder(out, identity, resume, overwrite, names)
    origin_clock = 0.0 if initial is None else float(initial.time)
    origin_length = 0.0 if initial is None else float(initial.time if config.quiescent else initial.strain)
    checkpoint = out / "checkpoint.npz"
    start_state: SimulationState | None = None if initial is None else initial.starting_state(config)
    records: StepRecords | None = None
    wall_before = 0.0
    saved_observables: dict[str, np.ndarray] = {}
    continuing = found in ("same", "adopted") and (checkpoint.exists() or checkpoint.is_symlink())
    out_flag, overwrite_flag = _name("out_dir", names), _name("overwrite", names)
    fix = f"; give {overwrite_flag} to delete that run and start afresh"
    frames = 0
    if continuing:
        how = _name("resume", names) if resume else f"{out_flag} {out} holds this run (to continue)"
        try:
            start_state, records, wall_before = _load_resumable(checkpoint, config, names, how, origin_clock)
            saved_observables = io.load_checkpoint_observables(checkpoint)
        except io.CheckpointError as exc:  # a damaged checkpoint, named with what is wrong
            message = str(exc) if str(exc).startswith(how) else f"{how}: {exc}"
            raise io.CheckpointError(message + fix) from None
        frames = int(saved_observables.pop(TRAJECTORY_FRAMES, 0))
        if trajectory_every is not None:
            try:
                TrajectoryWriter.check_resumable(
                    out / TRAJECTORY, config.box_length, frames, config.n_particles
                )
            except (TrajectoryError, FileNotFoundError) as exc:
                raise TrajectoryError(f"{how}: {exc}{fix}") from None
    observables = RunObservables.for_run(
        config, float(sample_interval), records, saved_observables, names, origin_clock
    )
    if progress is not False and not compiled_kernels_cached():
        print(COMPILE_NOTICE, file=sys.stderr, flush=True)
    sim = Simulation(config, start_state)
    if records is not None:
        sim.records = records
    claim(
        out,
        COMMAND,
        identity,
        resume=resume,
        overwrite=overwrite,
        argv=command,
        legacy=legacy,
        compare=_run_differences(resume),
        flag=out_flag,
        resume_flag=_name("resume", names),
        overwrite_flag=overwrite_flag,
    )
    _remove_outputs(
        out, keep=("checkpoint.npz", TRAJECTORY, SNAPSHOT_FOLDER) if continuing else ()
    )
    extra: dict[str, Any] = {}
    if initial is not None:
        extra["initial_state"] = _initial_state_entry(initial)
    if snapshot_every is not None:
        extra["snapshot_every"] = float(snapshot_every)
    if trajectory_every is not None:
        extra["trajectory_every"] = float(trajectory_every)
    io.write_params(out, config, command, extra)
    resumed_at = sim.state.time if continuing else None
    recorders = _Recorders()
    if snapshot_every is not None:
        recorders.snapshots = SnapshotWriter(
            out / SNAPSHOT_FOLDER,
            config,
            StrainMultiples.for_run(
                snapshot_every, origin_clock, origin_length, config.shear_rate, config.time_step,
                clock=resumed_at, include_start=False,
            ),
        )
    if trajectory_every is not None:
        recorders.trajectory = TrajectoryWriter.resume(
            out / TRAJECTORY,
            config.box_length,
            StrainMultiples.for_run(
                trajectory_every, origin_clock, origin_length, config.shear_rate, config.time_step,
                clock=resumed_at, include_start=True,
            ),
            frames,
            config.n_particles,
        )
    wall = _advance_with_checkpoints(
        sim, checkpoint, wall_before, progress, observables, recorders, origin_clock, origin_length
    )
    return _write_results(
        sim, out, checkpoint, wall, observables, recorders, initial, origin_clock, origin_length
    )


def _initial_state_entry(initial: InitialState) -> dict[str, Any]:
    """What ``params.json`` and ``result.json`` say of the configuration a run started from."""
    return {
        "source": initial.source,
        "digest": initial.digest,
        "time": initial.time,
        "strain": initial.strain,
    }


def _step_at_most_to(sim: Simulation, end_time: float) -> None:
    """One step of ``sim`` that does not pass ``end_time``: the step the simulation would take, or, where
    that one could pass ``end_time``, one capped to land on it.

    The cap goes where the step size is chosen (:func:`sim.stepper.choose_time_step`): the largest step
    ``time_step`` (and the floor ``min_time_step``, for a remainder below it) becomes ``end_time - clock``
    for this one step. The result is ``min`` of the same numbers, so a step that does not reach
    ``end_time`` is the uncapped step bit for bit; the position update is the variable-step AB2 with the
    shortened step's ratio to the one before (:func:`sim.integrators.variable_step_adams_bashforth`). When
    even a whole ``time_step`` ends within the slack of :func:`sim.stepper.stop_time` of ``end_time``
    (``1e-9`` of a step: a run of a whole number of steps, whose remainder is the last step less the
    clock's round-off) no cap is set, so such a run takes its last step unchanged, bit for bit. The
    compiled kernels are untouched (only a run-constant parameter of this one call differs).
    """
    params = sim._params
    remaining = end_time - sim.state.time
    if remaining + 1e-9 * params.max_time_step >= params.max_time_step:
        sim.advance(1)
        return
    sim._params = params._replace(
        max_time_step=min(params.max_time_step, remaining),
        min_time_step=min(params.min_time_step, remaining),
    )
    try:
        sim.advance(1)
    finally:
        sim._params = params


@contextlib.contextmanager
def _deferred_interrupt() -> Iterator[Callable[[], bool]]:
    """While the block runs, Ctrl-C (SIGINT) only sets a flag, which the yielded function reads.

    A ``KeyboardInterrupt`` raised while a compiled kernel runs comes out of numba as a ``SystemError``
    ("returned a result with an exception set") and would end the run as a failed simulation; deferred,
    the step loop stops at the end of the current chunk of steps, with a checkpoint. A second Ctrl-C
    puts the previous handler back, so a third interrupts at once. Outside the main thread (where no
    handler can be set) nothing is deferred."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    pending = False
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum: int, frame: Any) -> None:
        nonlocal pending
        if pending:
            signal.signal(signal.SIGINT, previous)
        pending = True

    signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: pending
    finally:
        signal.signal(signal.SIGINT, previous)


def _advance_with_checkpoints(
    sim: Simulation,
    checkpoint: Path,
    wall_before: float,
    progress: bool | None,
    observables: RunObservables,
    recorders: _Recorders | None = None,
    origin_clock: float = 0.0,
    origin_length: float = 0.0,
) -> float:
    """Step ``sim`` to its configured strain after its start (at the clock ``origin_clock`` and the length
    coordinate ``origin_length``: strain, or time when quiescent), sampling ``observables`` at their
    clock times, keeping snapshots and frames (``recorders``) at their multiples and checkpointing every
    ``checkpoint_every``; return wall time.

    The step loop is stopped at every sample time and every multiple (:meth:`Simulation.advance_to`;
    stopping never changes the trajectory), and what is due at the end of a chunk is taken before that
    chunk's checkpoint, so a checkpoint always holds the accumulators of its state (and counts the
    frames written with it). Up to one largest step before the end the steps are the simulation's own;
    from there one step at a time, each capped at the time left (:func:`_step_at_most_to`), so that the
    last one lands on the end. Before that last step's state is sampled, the checkpoint of the state
    before it is written (and ``recorders.final_checkpoint`` set): extending the run continues from there
    as a longer run would. Ctrl-C is deferred to the end of the current chunk (:func:`_deferred_interrupt`),
    where a checkpoint is written and ``KeyboardInterrupt`` raised. The progress bar appears after the
    first chunk of steps, so that its clock (and its estimate of the time left) does not include compiling
    the kernels.
    """
    config = sim.config
    recorders = _Recorders() if recorders is None else recorders
    start = time.perf_counter()
    show = sys.stderr.isatty() if progress is None else progress
    bar = None
    next_checkpoint = (
        math.floor(sim.state.time / config.checkpoint_every + 1e-9) + 1
    ) * config.checkpoint_every
    end = origin_clock + config.duration
    last_full = end - config.time_step  # steps that start before it cannot pass the end

    def run_length(s: Simulation) -> float:
        """How far the run has come, in the unit of ``config.strain`` (strain; time when quiescent)."""
        length = s.state.strain if config.shear_rate > 0.0 else s.state.time
        return min(length - origin_length, config.strain)

    def save(state: SimulationState, records: StepRecords) -> None:
        recorders.flush()
        io.save_checkpoint(
            checkpoint,
            config,
            state,
            records,
            wall_before + time.perf_counter() - start,
            {**observables.arrays(), **recorders.arrays()},
        )

    def keep(s: Simulation) -> None:
        observables.sample_if_due(s)
        recorders.record(s.state)

    def on_chunk(s: Simulation) -> None:
        nonlocal next_checkpoint, bar
        if show and bar is None:
            bar = _progress_bar(config, run_length(s))
        elif bar is not None:
            bar.n = round(run_length(s), 6)
            bar.refresh()
        keep(s)
        stop = interrupted()
        if s.state.time >= next_checkpoint - 1e-9 or stop:
            save(s.state, s.records)
            if not stop:
                next_checkpoint += config.checkpoint_every
        if stop:  # Ctrl-C: stop here, at the end of a chunk, with the checkpoint just written
            raise KeyboardInterrupt

    try:
        with _deferred_interrupt() as interrupted:
            keep(sim)  # what is due at the starting state (t_0 with no transient, the first frame)
            while sim.state.time < stop_time(last_full, config.time_step):
                target = min(observables.next_sample_time, recorders.next_clock, last_full)
                sim.advance_to(target, chunk_steps=100, on_chunk=on_chunk)
            while sim.state.time < stop_time(end, config.time_step):
                before = sim.snapshot()
                _step_at_most_to(sim, end)
                if sim.state.time < stop_time(end, config.time_step):
                    on_chunk(sim)
                    continue
                records = sim.records
                save(before, records.select(np.arange(records.time.size) < records.time.size - 1))
                recorders.final_checkpoint = True
                keep(sim)
                if bar is not None:
                    bar.n = round(run_length(sim), 6)
                    bar.refresh()
    finally:
        if bar is not None:
            bar.close()
    return wall_before + time.perf_counter() - start


def _write_results(
    sim: Simulation,
    out: Path,
    checkpoint: Path,
    wall: float,
    observables: RunObservables,
    recorders: _Recorders | None = None,
    initial: InitialState | None = None,
    origin_clock: float = 0.0,
    origin_length: float = 0.0,
) -> dict[str, Any]:
    """Write the last frames, the checkpoint (unless the one before the last step is there already),
    final state, time series, observables, ``result.json`` and plot; return the result."""
    config = sim.config
    recorders = _Recorders() if recorders is None else recorders
    recorders.flush()
    if not recorders.final_checkpoint:  # a run that took no step (continued at its end)
        io.save_checkpoint(
            checkpoint,
            config,
            sim.state,
            sim.records,
            wall,
            {**observables.arrays(), **recorders.arrays()},
        )
    io.save_final_state(out / "final_state.npz", config, sim.state)
    io.write_timeseries(out / "timeseries.csv", sim.records)
    observables.write(out)
    rheo = sim.rheology(from_time=origin_clock + config.transient_time)
    records = sim.records
    result: dict[str, Any] = {
        "relative_viscosity": rheo.relative_viscosity,
        "relative_viscosity_stderr": rheo.relative_viscosity_stderr,
        "n1": rheo.n1,
        "n1_stderr": rheo.n1_stderr,
        "n2": rheo.n2,
        "n2_stderr": rheo.n2_stderr,
        "particle_pressure": rheo.particle_pressure,
        "particle_pressure_stderr": rheo.particle_pressure_stderr,
        "strain": sim.state.strain,
        "time": sim.state.time,
        "steps": sim.state.step,
        "n_particles": config.n_particles,
        "volume_fraction": config.volume_fraction,
        "mason_number": config.mason_number,
        "mechanism": config.mechanism,
        "field_direction": list(config.field_direction),
        "shear_rate": config.shear_rate,
        "near_field": config.near_field if not config.pure_shear else "none",
        "u_rms_dip": rheo.u_rms_dip,
        "u_rms_shear": rheo.u_rms_shear,
        "seed": config.seed,
        "min_gap": float(records.min_gap.min()) if records.min_gap.size else math.nan,
        "wall_seconds": wall,
        "averaged_from_strain": origin_length + config.transient,
        "averaged_samples": rheo.samples,
        "mean_solver_iterations": float(records.solver_iterations.mean()) if records.strain.size else 0.0,
        "max_solver_iterations": int(records.solver_iterations.max()) if records.strain.size else 0,
        "steps_with_overlap_removal": int((records.overlap_sweeps > 0).sum()),
        "mean_time_step": float(records.time_step.mean()) if records.strain.size else math.nan,
        "min_time_step": float(records.time_step.min()) if records.strain.size else math.nan,
        "contributions": {
            name: {
                "relative_viscosity": v[0],
                "n1": v[1],
                "n2": v[2],
                "particle_pressure": rheo.pressure_contributions[name],
            }
            for name, v in rheo.contributions.items()
        },
        **observables.results(config),
    }
    if initial is not None:
        result["initial_state"] = _initial_state_entry(initial)
    if recorders.trajectory is not None:
        result["trajectory_frames"] = recorders.trajectory.frames
    io.write_json(out / "result.json", result)
    plot_rheology(
        records,
        out / "stress.png",
        rheo.averaged_from_time,
        title=f"phi = {config.volume_fraction}, N = {config.n_particles}, Mn = {config.mason_number}",
    )
    return result
