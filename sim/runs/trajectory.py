"""Trajectories in GSD files (HOOMD schema), written by a run and read as initial states and movies.

``python -m sim run ... --trajectory-every S`` writes ``trajectory.gsd`` in the run's folder: one frame at
every multiple of ``S`` strain from the run's start on (:class:`sim.runs.schedule.StrainMultiples`; the
state at the first step at or beyond each, the starting configuration included when it sits on a
multiple, as a fresh run's strain 0 does). Any GSD reader opens it (``gsd.hoomd.open``, freud, OVITO,
HOOMD-blue itself).

The box. The Lees–Edwards box of side ``L`` is the sheared lattice with basis vectors ``a1 = (L, 0, 0)``,
``a2 = (delta, L, 0)``, ``a3 = (0, 0, L)`` (:mod:`sim.geometry.box`), ``delta`` the Lees–Edwards offset of
the strain, ``strain * L`` reduced into ``[-L/2, L/2)``. HOOMD's triclinic box ``[Lx, Ly, Lz, xy, xz, yz]``
has the basis ``(Lx, 0, 0)``, ``(xy Ly, Ly, 0)``, ``(xz Lz, yz Lz, Lz)``, so the same lattice is
``configuration/box = [L, L, L, xy, 0, 0]`` with the tilt **xy = delta / L** in ``[-1/2, 1/2)``: the box
of a frame is sheared as the images are at that strain (and ``xy`` recovers the strain modulo 1).

The positions. HOOMD stores positions centred on the origin, inside the tilted cell: with
``r = (x, y, z)`` in the simulator's primary box ``[0, L)^3``, a frame holds ``r - (L/2)(1, 1, 1)``, its
``x`` then moved by a whole ``L`` where needed so that the fractional coordinate along ``a1``,
``(x_c - xy y_c) / L``, lies in ``[-1/2, 1/2)`` (a lattice translation: the same configuration). Reading
undoes it: ``r = p + (L/2)(1, 1, 1)``, then ``x`` wrapped into ``[0, L)`` (``y`` and ``z`` are in the box
already). ``particles/position`` is single precision, as HOOMD's schema has it (round-off ``L 2^-24``,
6e-7 a at L = 10); the exact double-precision positions of the primary box ride along as the log entry
``log/particles/dipsim/position``, which :func:`read_frame` prefers, so a restart from a trajectory of
ours is exact.

Per frame: ``configuration/step`` (the run's step count), ``configuration/box``, ``particles/N``,
``particles/types = ["sphere"]``, ``particles/typeid``, ``particles/diameter = 2a = 2``,
``particles/position``, and the log entries ``log/dipsim/time`` (the clock, units ``1/gammadot_ref``),
``log/dipsim/strain`` (the accumulated strain), ``log/dipsim/shear_rate`` (units ``gammadot_ref``),
``log/dipsim/mason_number`` (``Mn_ref``; inf: no field), ``log/dipsim/field_direction`` (3,) and
``log/particles/dipsim/position`` (N, 3).

Writing and resuming. Frames are kept in memory and written when the run writes its checkpoint (and at
its end): the file is copied, the frames appended to the copy, and the copy renamed over the file, so the
file is always whole and never holds frames past a checkpoint it has not reached. A resumed run keeps the
frames its checkpoint counted (:attr:`TrajectoryWriter.frames`, stored in the checkpoint) and drops any
written after it (a run killed between its trajectory and its checkpoint), so no frame is duplicated. The
file is rewritten at each checkpoint: its cost grows with its size (36 bytes a sphere a frame).
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.geometry.box import lees_edwards_offset
from sim.runs import io
from sim.runs.schedule import StrainMultiples
from sim.state import SimulationState

TRAJECTORY = "trajectory.gsd"
"""The trajectory's file name inside a run's folder."""

TYPE_NAME = "sphere"
"""The one particle type of the frames."""

LOG_PREFIX = "dipsim/"
"""Namespace of the scalar log entries (``log/dipsim/strain``, ...)."""

EXACT_POSITIONS = "particles/dipsim/position"
"""Log entry (under ``log/``) of the double-precision positions in the primary box ``[0, L)^3``."""

BOX_TOLERANCE = 1e-6
"""Relative tolerance of the box checks (GSD stores the box in single precision: 6e-8 relative)."""


class TrajectoryError(ValueError):
    """A GSD file that cannot be used (the message names the file and what is wrong)."""


def _hoomd() -> Any:
    """``gsd.hoomd``, or an error that says how to install it."""
    try:
        import gsd.hoomd
    except ImportError:  # pragma: no cover - gsd is a dependency
        raise TrajectoryError("GSD files need the gsd package: pip install 'gsd>=3'") from None
    return gsd.hoomd


def tilt(strain: float, box_length: float) -> float:
    """HOOMD's ``xy`` of the Lees–Edwards box at ``strain``: ``delta / L`` in ``[-1/2, 1/2)``, with
    ``delta`` the offset of :func:`sim.geometry.box.lees_edwards_offset`."""
    return float(lees_edwards_offset(float(strain), float(box_length))) / box_length


def gsd_box(box_length: float, strain: float) -> list[float]:
    """``configuration/box`` of the Lees–Edwards box of side ``box_length`` at ``strain``:
    ``[L, L, L, xy, 0, 0]`` with ``xy = delta / L`` (module docstring)."""
    return [box_length, box_length, box_length, tilt(strain, box_length), 0.0, 0.0]


def to_gsd_positions(positions: np.ndarray, box_length: float, xy: float) -> np.ndarray:
    """Positions of the primary box as GSD stores them: centred, inside the tilted cell.

    Args:
        positions: (N, 3) float64 positions in ``[0, L)^3`` (units a).
        box_length: ``L`` (units a).
        xy: the box's tilt (:func:`tilt`).

    Returns:
        (N, 3) float64 ``r - (L/2)(1, 1, 1)`` with ``x`` shifted by whole periods so that the fractional
        coordinate ``(x - xy y) / L`` lies in ``[-1/2, 1/2)``.
    """
    centred = np.array(positions, dtype=np.float64) - 0.5 * box_length
    fraction = (centred[:, 0] - xy * centred[:, 1]) / box_length
    centred[:, 0] -= box_length * np.floor(fraction + 0.5)
    return centred


def from_gsd_positions(positions: np.ndarray, box_length: float) -> np.ndarray:
    """Inverse of :func:`to_gsd_positions`: ``p + (L/2)(1, 1, 1)``, ``x`` wrapped into ``[0, L)``.

    Args:
        positions: (N, 3) positions as a GSD frame holds them (units a).
        box_length: ``L`` (units a).

    Returns:
        (N, 3) float64 positions; ``y`` and ``z`` of a frame of ours lie in ``[0, L)``, and a
        :class:`sim.Simulation` wraps any others (:meth:`sim.Simulation.enter`).
    """
    shifted = np.array(positions, dtype=np.float64) + 0.5 * box_length
    shifted[:, 0] -= box_length * np.floor(shifted[:, 0] / box_length)
    return shifted


def make_frame(state: SimulationState, box_length: float) -> Any:
    """The ``gsd.hoomd.Frame`` of ``state`` in a box of side ``box_length`` (module docstring)."""
    hoomd = _hoomd()
    n = state.positions.shape[0]
    box = gsd_box(box_length, state.strain)
    frame = hoomd.Frame()
    frame.configuration.step = int(state.step)
    frame.configuration.dimensions = 3
    frame.configuration.box = box
    frame.particles.N = n
    frame.particles.types = [TYPE_NAME]
    frame.particles.typeid = np.zeros(n, dtype=np.uint32)
    frame.particles.diameter = np.full(n, 2.0, dtype=np.float32)
    frame.particles.position = to_gsd_positions(state.positions, box_length, box[3]).astype(np.float32)
    frame.log = {
        f"{LOG_PREFIX}time": np.array([state.time], dtype=np.float64),
        f"{LOG_PREFIX}strain": np.array([state.strain], dtype=np.float64),
        f"{LOG_PREFIX}shear_rate": np.array([state.shear_rate], dtype=np.float64),
        f"{LOG_PREFIX}mason_number": np.array([state.mason_number], dtype=np.float64),
        f"{LOG_PREFIX}field_direction": np.array(state.field_direction, dtype=np.float64),
        EXACT_POSITIONS: np.array(state.positions, dtype=np.float64, order="C"),  # a copy: the state steps on
    }
    return frame


@dataclass(frozen=True)
class GsdFrame:
    """One frame read from a GSD file, in the simulator's conventions.

    Attributes:
        positions: (N, 3) float64 positions with the centring undone (:func:`from_gsd_positions`; the
            exact ones of ``log/particles/dipsim/position`` when the frame has them), units a.
        box_length: ``L`` (units a).
        time: ``log/dipsim/time``, the clock (units ``1/gammadot_ref``); 0 when the frame has none.
        strain: ``log/dipsim/strain``; when the frame has none, the tilt ``xy`` (the strain modulo 1,
            which sets the same Lees–Edwards offset).
        step: ``configuration/step``.
        shear_rate: ``log/dipsim/shear_rate`` (NaN: not in the frame).
        mason_number: ``log/dipsim/mason_number`` (NaN: not in the frame).
        field_direction: ``log/dipsim/field_direction`` (None: not in the frame).
        index: the frame's index in its file.
        exact: whether the positions came from the double-precision log entry.
    """

    positions: np.ndarray
    box_length: float
    time: float
    strain: float
    step: int
    shear_rate: float
    mason_number: float
    field_direction: np.ndarray | None
    index: int
    exact: bool

    @property
    def has_field(self) -> bool:
        """Whether the frame says which field and shear rate it was at."""
        return (
            self.field_direction is not None
            and not math.isnan(self.mason_number)
            and not math.isnan(self.shear_rate)
        )


@contextlib.contextmanager
def open_trajectory(path: Path) -> Any:
    """``gsd.hoomd.open(path, "r")``, or :class:`TrajectoryError` naming the file and what is wrong."""
    hoomd = _hoomd()
    path = Path(path)
    if path.is_dir():
        raise TrajectoryError(f"{path} is a directory, not a GSD file")
    if not path.exists():
        raise FileNotFoundError(f"no such file: {path}")
    try:
        handle = hoomd.open(str(path), "r")
    except (RuntimeError, OSError, ValueError, KeyError) as exc:
        raise TrajectoryError(f"{path} is not a readable GSD file of the HOOMD schema ({exc})") from None
    with handle:
        yield handle


def _log_scalar(log: dict[str, np.ndarray], name: str) -> float:
    value = log.get(f"{LOG_PREFIX}{name}")
    if value is None or np.size(value) != 1:
        return math.nan
    return float(np.asarray(value).reshape(-1)[0])


def frame_count(path: Path) -> int:
    """How many frames the GSD file at ``path`` holds (:class:`TrajectoryError` if it is unreadable)."""
    with open_trajectory(path) as handle:
        return len(handle)


def read_frame(path: Path, index: int = -1) -> GsdFrame:
    """Frame ``index`` of the GSD file at ``path`` (negative: from the end; -1 the last), in the
    simulator's conventions (:class:`GsdFrame`).

    Raises:
        FileNotFoundError: no such file.
        TrajectoryError: (a ``ValueError``) not a GSD file of the HOOMD schema, no frames, ``index`` out of
            range, a box that is not a cubic Lees–Edwards box (``Lx = Ly = Lz``, ``xz = yz = 0``), no
            particles, non-finite positions, or log entries that contradict the box.
    """
    path = Path(path)
    with open_trajectory(path) as handle:
        count = len(handle)
        if count == 0:
            raise TrajectoryError(f"{path} holds no frames")
        if not -count <= index < count:
            raise TrajectoryError(
                f"{path} has {count} frames: the frame must be in [0, {count - 1}] (or [-{count}, -1] "
                f"from the end), got {index}"
            )
        try:
            frame = handle[index]
        except (RuntimeError, OSError, ValueError, KeyError) as exc:
            raise TrajectoryError(f"{path}: frame {index} cannot be read ({exc})") from None
        return _frame(path, frame, index % count)


def _frame(path: Path, frame: Any, index: int) -> GsdFrame:
    """A :class:`GsdFrame` of ``frame`` (frame ``index`` of ``path``), checked."""
    where = f"{path} frame {index}"
    box = np.asarray(frame.configuration.box, dtype=np.float64)
    length = float(box[0])
    if not (
        math.isfinite(length)
        and length > 0.0
        and abs(box[1] - length) <= BOX_TOLERANCE * length
        and abs(box[2] - length) <= BOX_TOLERANCE * length
        and box[4] == 0.0
        and box[5] == 0.0
    ):
        raise TrajectoryError(
            f"{where}: configuration/box {box.tolist()} is not a cubic Lees–Edwards box "
            "(Lx = Ly = Lz > 0, xz = yz = 0)"
        )
    n = int(frame.particles.N)
    if n == 0:
        raise TrajectoryError(f"{where} holds no particles")
    log = dict(frame.log or {})
    exact = log.get(EXACT_POSITIONS)
    if exact is not None and np.shape(exact) == (n, 3):
        positions = np.array(exact, dtype=np.float64)
    else:
        exact = None
        raw = np.asarray(frame.particles.position, dtype=np.float64)
        positions = from_gsd_positions(raw.reshape(n, 3), length)
    if not np.all(np.isfinite(positions)):
        raise TrajectoryError(f"{where}: positions must be finite")
    xy = float(box[3])
    strain = _log_scalar(log, "strain")
    if math.isnan(strain):
        strain = xy
    elif not math.isfinite(strain):
        raise TrajectoryError(f"{where}: log/{LOG_PREFIX}strain must be finite, got {strain}")
    else:
        mismatch = (tilt(strain, length) - xy + 0.5) % 1.0 - 0.5
        if abs(mismatch) > 1e-5:
            raise TrajectoryError(
                f"{where}: the box tilt xy = {xy:.6g} is not the Lees–Edwards offset of "
                f"log/{LOG_PREFIX}strain = {strain:.6g} (xy = offset / L = {tilt(strain, length):.6g})"
            )
    time = _log_scalar(log, "time")
    if math.isnan(time):
        time = 0.0
    direction = log.get(f"{LOG_PREFIX}field_direction")
    return GsdFrame(
        positions=positions,
        box_length=length,
        time=time,
        strain=strain,
        step=int(frame.configuration.step),
        shear_rate=_log_scalar(log, "shear_rate"),
        mason_number=_log_scalar(log, "mason_number"),
        field_direction=None
        if direction is None or np.size(direction) != 3
        else np.array(direction, dtype=np.float64).reshape(3),
        index=index,
        exact=exact is not None,
    )


def read_frames(path: Path, every: int = 1) -> list[GsdFrame]:
    """Every ``every``-th frame of the GSD file at ``path`` (from the first), in the simulator's
    conventions (:class:`GsdFrame`; errors as :func:`read_frame`)."""
    path = Path(path)
    with open_trajectory(path) as handle:
        return [_frame(path, handle[index], index) for index in range(0, len(handle), every)]


def _fsync(path: Path) -> None:
    with open(path, "rb+") as handle:
        os.fsync(handle.fileno())


def _temporary(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}{io.TEMPORARY_SUFFIX}")


def _write_atomically(path: Path, frames: list[Any], append: bool) -> None:
    """Write ``frames`` to a temporary copy of ``path`` (after the file's own frames when ``append``) and
    rename it over ``path``: a kill leaves the old file or the new one, never a broken one."""
    hoomd = _hoomd()
    tmp = _temporary(path)
    try:
        if append and path.exists():
            shutil.copyfile(path, tmp)
        with hoomd.open(str(tmp), "a" if append and path.exists() else "w") as handle:
            for frame in frames:
                handle.append(frame)
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def append_frames(path: Path, frames: list[Any]) -> None:
    """Append ``frames`` to the GSD file at ``path`` (created if missing) atomically: a copy of the file
    gets them and replaces it (a kill leaves the old file or the new one, never a broken one)."""
    if frames:
        _write_atomically(Path(path), frames, append=True)


def keep_first_frames(path: Path, count: int) -> None:
    """Cut the GSD file at ``path`` to its first ``count`` frames (rewritten atomically; nothing happens
    when it holds no more)."""
    path = Path(path)
    with open_trajectory(path) as handle:
        if len(handle) <= count:
            return
        kept = [handle[index] for index in range(count)]
    _write_atomically(path, kept, append=False)


class TrajectoryWriter:
    """The frames of a run at the multiples of ``schedule``, appended to ``path`` at each checkpoint.

    Args:
        path: ``<run>/trajectory.gsd``.
        box_length: the run's box side ``L`` (units a).
        schedule: the multiples (``include_start=True``).
        frames: frames the file held at the checkpoint the run continues from (0 for a new run).
    """

    def __init__(self, path: Path, box_length: float, schedule: StrainMultiples, frames: int = 0) -> None:
        self.path = Path(path)
        self.box_length = float(box_length)
        self.schedule = schedule
        self.written = int(frames)
        self.pending: list[Any] = []

    @staticmethod
    def check_resumable(path: Path, box_length: float, frames: int, n_particles: int) -> None:
        """Refuse (:class:`TrajectoryError`, naming the file) a trajectory that a run continuing from a
        checkpoint counting ``frames`` frames cannot continue: missing, unreadable, holding fewer frames,
        or frames of another box or particle number. Nothing is written."""
        path = Path(path)
        if frames <= 0:
            return
        if not path.exists():
            raise TrajectoryError(
                f"{path} is missing, but the checkpoint counts {frames} frames written into it"
            )
        count = frame_count(path)
        if count < frames:
            raise TrajectoryError(
                f"{path} holds {count} frames, but the checkpoint counts {frames} written into it (the file "
                "was damaged or replaced)"
            )
        last = read_frame(path, frames - 1)
        if last.positions.shape[0] != n_particles or abs(last.box_length - box_length) > (
            BOX_TOLERANCE * box_length
        ):
            raise TrajectoryError(
                f"{path} holds frames of {last.positions.shape[0]} spheres in a box of side "
                f"{last.box_length:.6g}, not of this run ({n_particles} spheres, side {box_length:.6g})"
            )

    @classmethod
    def resume(
        cls, path: Path, box_length: float, schedule: StrainMultiples, frames: int, n_particles: int
    ) -> TrajectoryWriter:
        """The writer of a run continuing from a checkpoint that counted ``frames`` frames (0: a new run,
        whose file is deleted if one is there): the file's frames after those are dropped (frames a run
        killed between its trajectory and its checkpoint had written; the run writes them again). A file
        it cannot continue is refused as :meth:`check_resumable` refuses it."""
        path = Path(path)
        cls.check_resumable(path, box_length, frames, n_particles)
        if frames > 0:
            keep_first_frames(path, frames)
        elif path.exists():
            path.unlink()
        return cls(path, box_length, schedule, frames)

    @property
    def frames(self) -> int:
        """Frames written or pending (what the next checkpoint counts once :meth:`flush` has run)."""
        return self.written + len(self.pending)

    @property
    def next_clock(self) -> float:
        """The clock of the next frame."""
        return self.schedule.next_clock

    def add_if_due(self, state: SimulationState) -> bool:
        """Keep a frame of ``state`` if it has reached the next multiple."""
        if self.schedule.due(state.time) is None:
            return False
        self.pending.append(make_frame(state, self.box_length))
        return True

    def flush(self) -> None:
        """Append the pending frames to the file (:func:`append_frames`)."""
        if self.pending:
            append_frames(self.path, self.pending)
            self.written += len(self.pending)
            self.pending = []
