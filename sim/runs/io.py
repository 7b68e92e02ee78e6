"""Files a run writes: parameters, stress time series, checkpoints, final state, result.

A run directory holds:

================== ==================================================================================
``params.json``    every parameter of the run (``SimulationConfig``), box side, package versions
``timeseries.csv`` per step: time (units 1/gammadot_ref), accumulated strain, step size, Mason number
                   at the reference rate, shear rate, instantaneous Mason number (rate x Mn_ref), min
                   gap, solver iterations, overlap sweeps, RMS of the DIP and shear velocities, eta_r
                   (Sigma_xy / rate), N1, N2 and the six independent stress components of every
                   contribution (stress in eta gammadot_ref)
``checkpoint.npz`` state + records + parameters + observable accumulators (and the count of the
                   trajectory's frames); ``--resume`` continues from it bit for bit; a finished run's
                   holds the state before its last, shortened step
``final_state.npz`` positions and the rest of the state at the end (with the accumulated non-affine
                   displacement), with the box side and strain
``result.json``    averaged rheology with standard errors, diffusivities (the CLI's ``--json`` line)
``pair_distribution.npz`` ``g(r)`` (``r_edges``, ``g_r``) and its x–y projection in the slab ``|dz| < h``
                   (``x_edges``, ``y_edges``, ``g_xy[x bin, y bin]``), averaged over ``samples``
                   configurations after the transient, with the raw counts
                   (:class:`sim.observables.pair_distribution.PairDistributionAccumulator`)
``msd.csv``        per lag: ``lag_strain`` (mean lag; time a/U0 when quiescent), ``msd_xx``, ``msd_yy``,
                   ``msd_zz`` (units a^2; x non-affine) over all origins after the transient
``stress.png``     eta_r, N1, N2 against strain
``manifest.json``  the folder's owner, written first: command (``sim run``), its parameters (the
                   identity a rerun is compared with), command line, version and source digest
                   (:mod:`sim.runs.folder`, the run-folder protocol shared by every command)
``snapshots/``     with ``--snapshot-every S``: the state at every multiple of ``S`` strain,
                   ``strain_XXXX.npz``, as ``final_state.npz`` holds it (:mod:`sim.runs.snapshots`)
``trajectory.gsd`` with ``--trajectory-every S``: a GSD (HOOMD schema) frame at every multiple of ``S``
                   strain (:mod:`sim.runs.trajectory`)
================== ==================================================================================

Every file, the plots included, is written atomically (:func:`atomic_file`: a temporary file in the same
folder, then ``os.replace``; figures through :func:`save_figure`): a run killed while writing leaves the
previous version or the new one, never a truncated file.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import zipfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from sim.config import SimulationConfig
from sim.observables.stress import STRESS_CONTRIBUTIONS
from sim.simulation import StepRecords
from sim.state import SimulationState

_COMPONENTS = (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("xz", 0, 2), ("yz", 1, 2))


def versions() -> dict[str, str]:
    """Versions of the interpreter and the numerical stack (written next to results)."""
    import numba
    import scipy

    from sim import __version__
    from sim.numba_cache import source_digest

    return {
        "sim": __version__,
        "sim_source": source_digest(Path(__file__).resolve().parent.parent),  # all of sim/, not sim/runs/
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
    }


_NON_FINITE = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def json_ready(value: Any) -> Any:
    """Copy of ``value`` with non-finite floats as ``"nan"``, ``"inf"``, ``"-inf"`` (keeps JSON standard)."""
    if isinstance(value, float) and not np.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    return value


def from_json_ready(value: Any) -> Any:
    """Inverse of :func:`json_ready`."""
    if isinstance(value, str) and value in _NON_FINITE:
        return _NON_FINITE[value]
    if isinstance(value, dict):
        return {k: from_json_ready(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_json_ready(v) for v in value]
    return value


TEMPORARY_SUFFIX = ".tmp"
"""Suffix of the temporary files of :func:`atomic_file` (``.<name>.<pid>.tmp`` beside the file)."""


@contextlib.contextmanager
def atomic_file(path: Path) -> Iterator[IO[bytes]]:
    """A binary file handle whose contents replace ``path`` in one step when the block ends.

    The data go to ``.<name>.<pid>.tmp`` in the same folder (so the final ``os.replace`` is a rename on
    one file system), flushed to disk, then renamed over ``path``. If the block raises (or the process
    is killed), ``path`` keeps its previous contents; the temporary file is removed on an exception.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}{TEMPORARY_SUFFIX}")
    try:
        with open(tmp, "wb") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text_atomically(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_file`)."""
    with atomic_file(path) as handle:
        handle.write(text.encode())


def save_figure(figure: Any, path: Path, **options: Any) -> None:
    """``figure.savefig`` into ``path`` atomically (:func:`atomic_file`); the format is the suffix's."""
    path = Path(path)
    with atomic_file(path) as handle:
        figure.savefig(handle, format=path.suffix.lstrip(".") or "png", **options)


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented standard JSON (non-finite numbers as strings, see :func:`json_ready`),
    atomically (:func:`atomic_file`)."""
    write_text_atomically(path, json.dumps(json_ready(data), indent=2) + "\n")


def read_json(path: Path) -> dict[str, Any]:
    """Read a file written by :func:`write_json`, restoring non-finite numbers."""
    return from_json_ready(json.loads(path.read_text()))


def write_params(
    out_dir: Path,
    config: SimulationConfig,
    command: list[str] | None = None,
    extra: Mapping[str, Any] | None = None,
) -> None:
    """``params.json``: the configuration, derived quantities and versions, and ``extra`` entries (a run
    from a given configuration: ``initial_state``; ``snapshot_every``, ``trajectory_every``)."""
    write_json(
        out_dir / "params.json",
        {
            "config": config.to_dict(),
            "box_length": config.box_length,
            "n_steps": config.n_steps,
            "units": (
                "a = eta = 1; quiescent (shear_rate 0): U0 = eps a E0^2/eta = 1, time in a/U0, "
                "stress in eps E0^2"
                if config.quiescent
                else "a = eta = gammadot = 1; time in strain; stress in eta*gammadot; U0 = a gammadot / Mn"
            ),
            "command": command,
            "versions": versions(),
            **(extra or {}),
        },
    )


def write_timeseries(path: Path, records: StepRecords) -> None:
    """``timeseries.csv`` with one row per step (see the module docstring for columns)."""
    total = records.total_stress
    eta, n1, n2 = records.rheology()
    columns = [
        np.arange(records.strain.size),
        records.time,
        records.strain,
        records.time_step,
        records.mason_number,
        records.shear_rate,
        records.instantaneous_mason_number,
        records.min_gap,
        records.solver_iterations,
        records.overlap_sweeps,
        records.u_rms_dip,
        records.u_rms_shear,
        eta,
        n1,
        n2,
    ]
    header = [
        "step",
        "time",
        "strain",
        "dt",
        "mason_number",
        "shear_rate",
        "instantaneous_mason_number",
        "min_gap",
        "solver_iterations",
        "overlap_sweeps",
        "u_rms_dip",
        "u_rms_shear",
        "eta_r",
        "N1",
        "N2",
    ]
    for index, name in enumerate(STRESS_CONTRIBUTIONS):
        for label, a, b in _COMPONENTS:
            columns.append(records.stress[:, index, a, b])
            header.append(f"{name}_{label}")
    for label, a, b in _COMPONENTS:
        columns.append(total[:, a, b])
        header.append(f"total_{label}")
    with atomic_file(path) as handle:
        np.savetxt(
            handle, np.column_stack(columns), delimiter=",", header=",".join(header), comments="", fmt="%.10g"
        )


OBSERVABLE_PREFIX = "observable_"
"""Prefix of the observable accumulators' arrays in ``checkpoint.npz``."""


def save_checkpoint(
    path: Path,
    config: SimulationConfig,
    state: SimulationState,
    records: StepRecords,
    wall_seconds: float,
    observables: Mapping[str, np.ndarray] | None = None,
) -> None:
    """Atomically write state, records, parameters and (optionally) observable accumulators to ``path``.

    ``observables`` are stored under their names prefixed by :data:`OBSERVABLE_PREFIX`; read them back
    with :func:`load_checkpoint_observables`.
    """
    extra: dict[str, Any] = {f"{OBSERVABLE_PREFIX}{name}": v for name, v in (observables or {}).items()}
    with atomic_file(path) as handle:
        np.savez(
            handle,
            config=np.array(json.dumps(config.to_dict())),
            wall_seconds=np.array(wall_seconds),
            **state.arrays(),
            **records.arrays(),
            **extra,
        )


class CheckpointError(ValueError):
    """A checkpoint file that cannot be read: the message names the file and what is wrong with it."""


_UNREADABLE = (OSError, EOFError, ValueError, KeyError, TypeError, IndexError, zipfile.BadZipFile)
"""What reading a damaged or foreign ``.npz`` can raise (numpy, zipfile, json, the config's checks)."""


@contextlib.contextmanager
def open_checkpoint(path: Path) -> Iterator[Any]:
    """The ``.npz`` archive at ``path`` (never unpickling), or :class:`CheckpointError` saying what is
    wrong: a directory in its place, an empty file, a file that is not an ``.npz`` archive, a truncated
    one, or one that lacks what a checkpoint holds. ``FileNotFoundError`` when nothing is there."""
    path = Path(path)
    if path.is_dir():
        raise CheckpointError(f"{path} is a directory, not a checkpoint file")
    if not path.exists():
        raise FileNotFoundError(f"no checkpoint at {path}")
    if path.stat().st_size == 0:
        raise CheckpointError(f"{path} is empty (a run killed while writing it?)")
    try:
        data = np.load(path, allow_pickle=False)
    except _UNREADABLE:
        raise CheckpointError(f"{path} is not an .npz archive (or is truncated)") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise CheckpointError(f"{path} is a single .npy array, not a checkpoint archive")
    with data:
        try:
            yield data
        except KeyError as exc:
            missing = str(exc.args[0] if exc.args else exc).removesuffix(" is not a file in the archive")
            raise CheckpointError(
                f"{path} is not a checkpoint of a run: it lacks {missing!r} (it holds "
                f"{', '.join(data.files[:5]) or 'nothing'}{', ...' if len(data.files) > 5 else ''})"
            ) from None
        except _UNREADABLE as exc:
            damaged = isinstance(exc, zipfile.BadZipFile | EOFError | OSError)
            reason = "truncated or damaged" if damaged else "its contents are not those of a checkpoint"
            raise CheckpointError(f"{path} cannot be read: {reason}") from None


def load_checkpoint_observables(path: Path) -> dict[str, np.ndarray]:
    """The observable accumulators of a checkpoint (prefix removed); empty for a checkpoint without.

    Raises :class:`CheckpointError` for a file that is not a readable checkpoint."""
    with open_checkpoint(path) as data:
        return {
            name[len(OBSERVABLE_PREFIX) :]: np.array(data[name])
            for name in data.files
            if name.startswith(OBSERVABLE_PREFIX)
        }


def load_checkpoint(path: Path) -> tuple[SimulationConfig, SimulationState, StepRecords, float]:
    """Inverse of :func:`save_checkpoint`.

    Raises:
        FileNotFoundError: nothing at ``path``.
        CheckpointError: (a ``ValueError``) anything else that is not a readable checkpoint, named with
            what is wrong (a directory, an empty, truncated, foreign or non-``.npz`` file).
    """
    with open_checkpoint(path) as data:
        config = SimulationConfig.from_dict(json.loads(str(data["config"])))
        return (
            config,
            SimulationState.from_arrays(data, config.shear_rate),
            StepRecords.from_arrays(data, config.shear_rate),
            float(data["wall_seconds"]),
        )


def save_final_state(path: Path, config: SimulationConfig, state: SimulationState) -> None:
    """``final_state.npz``: the state plus the box side."""
    with atomic_file(path) as handle:
        np.savez(handle, box_length=np.array(config.box_length), **state.arrays())


def write_pair_distribution(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """``pair_distribution.npz``: the arrays of
    :meth:`sim.observables.pair_distribution.PairDistributionAccumulator.result_arrays`."""
    data: dict[str, Any] = dict(arrays)
    with atomic_file(path) as handle:
        np.savez(handle, **data)


def write_msd(path: Path, lag_times: np.ndarray, msd: np.ndarray) -> None:
    """``msd.csv``: columns ``lag_strain, msd_xx, msd_yy, msd_zz``, one row per lag with data.

    Args:
        path: file to write.
        lag_times: (M,) mean lag per row (strain; time a/U0 when quiescent); NaN rows (lags without an
            origin) are left out.
        msd: (M, 3) mean-square non-affine displacement per component (units a^2).
    """
    lag_times = np.asarray(lag_times, dtype=np.float64)
    msd = np.asarray(msd, dtype=np.float64)
    keep = np.isfinite(lag_times)
    with atomic_file(path) as handle:
        np.savetxt(
            handle,
            np.column_stack([lag_times[keep], msd[keep]]).reshape(-1, 4),
            delimiter=",",
            header="lag_strain,msd_xx,msd_yy,msd_zz",
            comments="",
            fmt="%.10g",
        )
