"""Where a run starts when given a configuration (``--initial-state FILE``, ``run_simulation(state=...)``).

A run from a configuration starts the whole run machinery (records, observables, checkpoints, snapshots,
trajectory, results) from the file's positions, clock and strain (so the Lees–Edwards offset goes on from
the file's); ``--strain`` is the strain this run adds (its end is the file's strain plus ``--strain``) and
its transient is counted from its start. The rest of a dynamical state (the last step's velocity for AB2,
the solver's warm start, the step count, the accumulated displacement) is not taken: the run starts as a
run does, with an explicit Euler step, its own step count from 0 and its displacement from 0, whichever
file the configuration came from, so that a checkpoint, a snapshot and a trajectory frame of the same
configuration start the same run. The field (Mason number and direction) and the shear rate are the
run's (``--mason``, ``--field-direction``, ``--shear-rate``) unless ``--field-from-state`` takes the
file's.

Files read (:func:`read_initial_state`), told apart by their contents, not their names:

* ``.npz`` files our runs write: ``checkpoint.npz`` (its configuration gives the box), ``final_state.npz``
  and ``snapshots/*.npz`` (they hold ``box_length``).
* GSD files (HOOMD schema): the last frame, or frame ``K`` of ``FILE.gsd:K`` (negative ``K`` counts from
  the end), read by :func:`sim.runs.trajectory.read_frame` (a trajectory of ours restarts exactly; a
  foreign file gives its single-precision positions, its clock 0 and its box tilt as the strain).

Checks against the run's configuration (:func:`check_initial_state`): the file's particle count must be
the run's ``--n-particles`` (the flags stay what the run is: a file of another N is refused, naming both,
rather than silently changing N, ``--phi`` and every N-dependent default), and its box side must be the
side that ``--phi`` and ``--n-particles`` give, to a relative ``1e-6`` (GSD stores the box in single
precision), else the message names the file's side and the ``--phi`` it corresponds to.

The identity. :attr:`InitialState.digest` hashes what the run takes from the file (positions, clock and
strain; the field and rate it runs at are the run's configuration, in its identity already); it enters
the run folder's identity (``manifest.json``), so a rerun into the same folder from another configuration
is refused by the run-folder protocol (:mod:`sim.runs.folder`), while the same configuration from another
file (a copy, or a snapshot and the checkpoint written at the same step) continues it.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sim.config import SimulationConfig
from sim.geometry.configurations import box_length_for
from sim.runs.trajectory import TrajectoryError, read_frame
from sim.state import SimulationState

GSD_MAGIC = bytes.fromhex("df65df65df65df65")
"""The first eight bytes of a GSD file (its magic number, little-endian ``0x65DF65DF65DF65DF``)."""

ZIP_MAGIC = b"PK\x03\x04"
"""The first four bytes of an ``.npz`` archive (a zip file)."""

BOX_TOLERANCE = 1e-6
"""Largest relative difference between the file's box side and the run's (GSD: single precision)."""


class InitialStateError(ValueError):
    """An initial state that cannot be used (the message names the parameter, the file and why)."""


@dataclass(frozen=True)
class InitialState:
    """A configuration a run starts from.

    Attributes:
        positions: (N, 3) float64 positions (units a; anywhere: the simulation wraps them into its box).
        time: the clock of the configuration (units ``1/gammadot_ref``).
        strain: its accumulated strain (sets the Lees–Edwards offset).
        box_length: the side of the box it was made in (units a); None when not known (a
            ``SimulationState`` given in Python).
        source: where it came from (a file, ``FILE.gsd:K``, or ``"state"``).
        mason_number: the field the file was at (``Mn_ref``; inf: off), NaN when the file does not say.
        field_direction: (3,) its direction, None when the file does not say.
        shear_rate: its shear rate (units ``gammadot_ref``), NaN when the file does not say.
    """

    positions: np.ndarray
    time: float
    strain: float
    box_length: float | None
    source: str
    mason_number: float = math.nan
    field_direction: np.ndarray | None = None
    shear_rate: float = math.nan

    @property
    def n_particles(self) -> int:
        return int(self.positions.shape[0])

    @property
    def has_field(self) -> bool:
        """Whether the file says which field and shear rate it was at (``--field-from-state``)."""
        return (
            self.field_direction is not None
            and not math.isnan(self.mason_number)
            and not math.isnan(self.shear_rate)
        )

    @classmethod
    def from_state(cls, state: SimulationState, source: str = "state") -> InitialState:
        """The configuration of ``state`` (its field and rate kept for :func:`with_field_of`)."""
        return cls(
            positions=np.array(state.positions, dtype=np.float64),
            time=float(state.time),
            strain=float(state.strain),
            box_length=None,
            source=source,
            mason_number=float(state.mason_number),
            field_direction=np.array(state.field_direction, dtype=np.float64),
            shear_rate=float(state.shear_rate),
        )

    @property
    def digest(self) -> str:
        """SHA-256 (16 hex digits) of what a run takes from this configuration: positions, clock and strain
        (the field and shear rate it runs at are in the run's identity already, as its configuration)."""
        digest = hashlib.sha256()
        digest.update(np.ascontiguousarray(self.positions, dtype=np.float64).tobytes())
        digest.update(np.array([self.time, self.strain], dtype=np.float64).tobytes())
        return digest.hexdigest()[:16]

    def starting_state(self, config: SimulationConfig) -> SimulationState:
        """The state a run of ``config`` starts from: these positions, clock and strain, the run's field
        and shear rate, no history (the first step is Euler), step 0, displacement 0."""
        state = SimulationState.initial(
            self.positions, config.mason_number, config.field_direction, config.shear_rate
        )
        state.time = float(self.time)
        state.strain = float(self.strain)
        return state


def _name(parameter: str, names: Mapping[str, str] | None) -> str:
    return (names or {}).get(parameter, parameter)


def split_frame(spec: str) -> tuple[Path, int | None]:
    """``FILE`` or ``FILE:K`` (a GSD frame): the path and the frame (None: the last). ``FILE:K`` is read as
    a frame only when ``FILE`` exists and ``FILE:K`` does not (a file name may hold a colon)."""
    match = re.fullmatch(r"(.+):(-?\d+)", spec)
    if match and not Path(spec).exists() and Path(match.group(1)).exists():
        return Path(match.group(1)), int(match.group(2))
    return Path(spec), None


def read_initial_state(spec: str | Path, names: Mapping[str, str] | None = None) -> InitialState:
    """The configuration in ``spec`` (module docstring: our ``.npz`` state files, or a GSD file's last
    frame or ``FILE.gsd:K``).

    Raises:
        InitialStateError: (a ``ValueError``) naming the parameter (``state``; the command line passes
            ``--initial-state``) and the file: missing, a folder, empty, neither an ``.npz`` state of a run
            nor a GSD file, damaged, a frame out of range, no particles, non-finite positions.
    """
    flag = _name("state", names)
    path, frame = split_frame(str(spec))
    where = f"{flag} {spec}"
    if path.is_dir():
        raise InitialStateError(f"{where} is a folder; give a file: a run's checkpoint.npz, final_state.npz, "
                                "snapshots/*.npz or trajectory.gsd")
    if not path.exists():
        raise InitialStateError(f"{where}: no such file")
    try:
        with open(path, "rb") as handle:
            head = handle.read(8)
    except OSError as exc:
        raise InitialStateError(f"{where} cannot be read: {exc.strerror or exc}") from None
    if not head:
        raise InitialStateError(f"{where} is empty")
    if head.startswith(GSD_MAGIC):
        try:
            gsd = read_frame(path, -1 if frame is None else frame)
        except TrajectoryError as exc:
            raise InitialStateError(f"{flag}: {exc}") from None
        return InitialState(
            positions=gsd.positions,
            time=gsd.time,
            strain=gsd.strain,
            box_length=gsd.box_length,
            source=f"{path}:{gsd.index}",
            mason_number=gsd.mason_number,
            field_direction=gsd.field_direction,
            shear_rate=gsd.shear_rate,
        )
    if frame is not None:
        raise InitialStateError(f"{where}: a frame (FILE:K) can only be chosen in a GSD file")
    if head.startswith(ZIP_MAGIC):
        return _read_npz(path, where)
    raise InitialStateError(
        f"{where} is neither a state file of a run (.npz: checkpoint.npz, final_state.npz, snapshots/*.npz) "
        "nor a GSD file"
    )


def _scalar(data: np.lib.npyio.NpzFile, name: str, default: float) -> float:
    return float(np.asarray(data[name]).reshape(-1)[0]) if name in data.files else default


def _read_npz(path: Path, where: str) -> InitialState:
    """The configuration of an ``.npz`` state file: ``positions`` (N, 3) and the box (``box_length``, or
    the ``config`` of a checkpoint) are needed; ``time`` and ``strain`` (default 0), ``mason_number``,
    ``field_direction`` and ``shear_rate`` are taken when present (our runs write them all; a
    configuration made by hand, ``np.savez(f, positions=P, box_length=L, strain=s)``, works too)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if not isinstance(data, np.lib.npyio.NpzFile):
                raise InitialStateError(f"{where} is a single .npy array, not a state file")
            files = set(data.files)
            if "positions" not in files:
                raise InitialStateError(
                    f"{where} is not a state file: it holds no positions "
                    f"({', '.join(sorted(files)[:5]) or 'nothing'})"
                )
            if "box_length" in files:
                box_length = _scalar(data, "box_length", math.nan)
                run_rate = math.nan
            elif "config" in files:
                saved = json.loads(str(data["config"]))
                box_length = box_length_for(int(saved["n_particles"]), float(saved["volume_fraction"]))
                run_rate = float(saved.get("shear_rate", 1.0))
            else:
                raise InitialStateError(
                    f"{where} does not say its box (no box_length, no config): a run's checkpoint.npz, "
                    "final_state.npz and snapshots/*.npz do"
                )
            positions = np.array(data["positions"], dtype=np.float64)
            strain = _scalar(data, "strain", 0.0)
            if "time" in files or "previous_velocity" not in files:  # ours, or made by hand: clock 0
                time = _scalar(data, "time", 0.0)
                shear_rate = _scalar(data, "shear_rate", math.nan)
            else:  # ours, from before the clock and the strain were apart: "strain" held the clock
                time = strain
                shear_rate = run_rate
                strain = (1.0 if math.isnan(run_rate) else run_rate) * time
            mason_number = _scalar(data, "mason_number", math.nan)
            direction = (
                np.array(data["field_direction"], dtype=np.float64).reshape(-1)
                if "field_direction" in files
                else None
            )
    except InitialStateError:
        raise
    except (OSError, EOFError, ValueError, KeyError, TypeError, IndexError, zipfile.BadZipFile) as exc:
        raise InitialStateError(
            f"{where} cannot be read: truncated or damaged ({type(exc).__name__})"
        ) from None
    if positions.ndim != 2 or positions.shape[1] != 3 or positions.shape[0] == 0:
        raise InitialStateError(f"{where}: positions must have shape (N, 3), got {positions.shape}")
    if not math.isfinite(box_length) or box_length <= 0.0:
        raise InitialStateError(f"{where}: box_length must be finite and > 0, got {box_length!r}")
    return InitialState(
        positions=positions,
        time=time,
        strain=strain,
        box_length=box_length,
        source=str(path),
        mason_number=mason_number,
        field_direction=direction if direction is not None and direction.size == 3 else None,
        shear_rate=shear_rate,
    )


def check_initial_state(
    initial: InitialState, config: SimulationConfig, names: Mapping[str, str] | None = None
) -> None:
    """Refuse (``InitialStateError``, naming the parameters and both values) a configuration that a run of
    ``config`` cannot start from: another particle count, another box side (beyond a relative
    :data:`BOX_TOLERANCE`), non-finite positions, clock or strain."""
    flag, n_flag, phi_flag = (_name(k, names) for k in ("state", "n_particles", "volume_fraction"))
    where = f"{flag} {initial.source}"
    if initial.n_particles != config.n_particles:
        raise InitialStateError(
            f"{where} holds {initial.n_particles} particles, but {n_flag}={config.n_particles}; the particle "
            f"count is the run's: give {n_flag} {initial.n_particles}"
        )
    if not np.all(np.isfinite(initial.positions)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(initial.positions), axis=1)))
        raise InitialStateError(f"{where}: positions must be finite ({bad} particles have NaN or inf)")
    if not (math.isfinite(initial.time) and math.isfinite(initial.strain)):
        raise InitialStateError(
            f"{where}: time and strain must be finite, got time {initial.time!r}, strain {initial.strain!r}"
        )
    length = initial.box_length
    if length is not None and abs(length - config.box_length) > BOX_TOLERANCE * config.box_length:
        phi = initial.n_particles * (4.0 / 3.0) * math.pi / length**3
        raise InitialStateError(
            f"{where} has a box of side L = {length:.7g}, but {phi_flag}={config.volume_fraction:g} and "
            f"{n_flag}={config.n_particles} give L = {config.box_length:.7g} (they must agree to a relative "
            f"{BOX_TOLERANCE:g}); the file's box is {phi_flag} {phi:.6g} at {n_flag} {initial.n_particles}"
        )


def with_field_of(
    config: SimulationConfig, initial: InitialState, names: Mapping[str, str] | None = None
) -> SimulationConfig:
    """``config`` with the field (Mason number, direction) and shear rate of ``initial``
    (``--field-from-state``); ``InitialStateError`` when the file does not say them, ``ValueError`` when
    the configuration refuses them."""
    if not initial.has_field:
        raise InitialStateError(
            f"{_name('field_from_state', names)}: {initial.source} does not say which field and shear rate "
            f"it was at (a file written by another program); give {_name('mason_number', names)}, "
            f"{_name('field_direction', names)} and {_name('shear_rate', names)} instead"
        )
    assert initial.field_direction is not None
    return replace(
        config,
        mason_number=float(initial.mason_number),
        field_direction=tuple(float(c) for c in initial.field_direction),  # type: ignore[arg-type]
        shear_rate=float(initial.shear_rate),
    )
