"""``python -m sim movie RUN``: the layers forming and melting, drawn from a run's ``trajectory.gsd``.

Each frame of the trajectory (every ``every``-th) becomes one picture of two views of the box, both with
the spheres drawn to scale (diameter ``2a``) and coloured by their coordinate along the layer axis (the
box axis nearest the field, :func:`sim.observables.layering.nearest_layer_axis`; ``y``, the velocity
gradient, when the field is off), so that a layer is one colour:

* **side view** (left): the layer axis upwards, against the flow direction ``x`` (against ``z`` when the
  layer axis is ``x``), every sphere of the box projected: layers normal to the field are horizontal
  rows of one colour each; a disordered suspension is a mix of colours everywhere.
* **along the field** (right): the plane normal to the layer axis, the spheres projected onto it; a
  layered box shows each layer's sheet (hexagonal order within it when it crystallises) and its colour
  steps.

The title gives the strain (time when quiescent), the Mason number at the reference rate and the layer
order ``psi = S_peak / N`` along the layer axis (:func:`sim.observables.layering.layer_order`:
``psi ~ 1/N`` without layers, towards 1 in perfect layers). Positions are those of the simulator's
primary box ``[0, L)^3`` (:func:`sim.runs.trajectory.read_frame` undoes GSD's centring).

GIF files are written with matplotlib's Pillow writer; ``.mp4`` needs ``ffmpeg`` on the ``PATH``
(:class:`MovieError` otherwise, naming the GIF alternative). The file is written atomically (a temporary
file beside it, then a rename). Rendering costs about 0.2 s of CPU a frame at N = 100 (matplotlib, Agg).
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from sim.observables.layering import AXIS_NAMES, layer_order, nearest_layer_axis
from sim.runs.io import TEMPORARY_SUFFIX
from sim.runs.trajectory import TRAJECTORY, GsdFrame, read_frames

MOVIE_SUFFIXES = (".gif", ".mp4")
"""The movie formats: GIF (Pillow, always there) and MP4 (needs ffmpeg)."""

DEFAULT_FPS = 10
"""Frames per second unless told otherwise."""

MAX_FPS = 100
"""Most frames per second a movie may ask for (GIF players round delays below 10 ms anyway)."""


class MovieError(ValueError):
    """A movie that cannot be made (the message names the parameter and why)."""


def trajectory_path(run: str | Path) -> Path:
    """The GSD file of ``run``: ``run`` itself when it is a file, else ``run/trajectory.gsd``
    (:class:`MovieError` when there is none)."""
    path = Path(run)
    if path.is_dir():
        path = path / TRAJECTORY
        if not path.exists():
            raise MovieError(
                f"RUN {run} holds no {TRAJECTORY}: run python -m sim run ... --trajectory-every S "
                "--out RUN first"
            )
        return path
    if not path.exists():
        raise MovieError(f"RUN {run}: no such run folder or GSD file")
    return path


def _writer(out: Path, fps: int) -> Any:
    """The matplotlib movie writer of ``out``'s format."""
    from matplotlib import animation

    if out.suffix.lower() == ".gif":
        return animation.PillowWriter(fps=fps)
    if not animation.writers.is_available("ffmpeg"):
        raise MovieError(
            f"--out {out}: an .mp4 movie needs ffmpeg, which is not installed (not on the PATH); write a "
            f"GIF instead: --out {out.with_suffix('.gif')}"
        )
    return animation.FFMpegWriter(fps=fps)


def check_movie_arguments(out: Path, fps: int, every: int) -> None:
    """Refuse (:class:`MovieError`, naming the flag and its valid range) a movie file of another format,
    a frame rate outside ``[1, MAX_FPS]`` or a frame stride below 1."""
    if out.suffix.lower() not in MOVIE_SUFFIXES:
        raise MovieError(
            f"--out {out}: the movie must be a {' or '.join(MOVIE_SUFFIXES)} file, got "
            f"{out.suffix or 'none'!r}"
        )
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= MAX_FPS:
        raise MovieError(f"--fps must be an integer in [1, {MAX_FPS}], got {fps!r}")
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise MovieError(f"--every must be an integer >= 1 (1: every frame), got {every!r}")
    if out.exists() and out.is_dir():
        raise MovieError(f"--out {out} is a folder; give a file name ending in .gif or .mp4")
    if not out.parent.is_dir():
        raise MovieError(f"--out {out}: the folder {out.parent} does not exist")


def _layer_axis(frame: GsdFrame) -> int:
    """The box axis of the layers: nearest the field, ``y`` without one."""
    if frame.field_direction is None or not (frame.mason_number < math.inf):
        return 1
    return nearest_layer_axis(frame.field_direction)


def _title(frame: GsdFrame, axis: int, n_particles: int) -> str:
    quiescent = frame.shear_rate == 0.0
    clock = f"time {frame.time:.3f}" if quiescent else f"strain {frame.strain:.3f}"
    field = "no field" if not (frame.mason_number < math.inf) else f"Mn_ref = {frame.mason_number:g}"
    psi = layer_order(frame.positions, frame.box_length, axis, frame.strain).psi
    return f"{clock}   {field}   N = {n_particles}   layer order psi_{AXIS_NAMES[axis]} = {psi:.3f}"


def render_movie(
    run: str | Path, out: str | Path | None = None, fps: int = DEFAULT_FPS, every: int = 1
) -> Path:
    """Draw the movie of ``run``'s trajectory (module docstring) into ``out``; return its path.

    Args:
        run: a run folder holding ``trajectory.gsd``, or a GSD file.
        out: the movie file, ``.gif`` or ``.mp4`` (default ``movie.gif`` beside the trajectory).
        fps: frames per second, in ``[1, MAX_FPS]``.
        every: draw every ``every``-th frame of the trajectory (>= 1).

    Raises:
        MovieError: (a ``ValueError``) no trajectory, a bad ``out``, ``fps`` or ``every``, mp4 without
            ffmpeg. :class:`sim.runs.trajectory.TrajectoryError` (a ``ValueError``): a GSD file that
            cannot be read.
    """
    source = trajectory_path(run)
    target = Path(out) if out is not None else source.parent / "movie.gif"
    check_movie_arguments(target, fps, every)
    frames = read_frames(source, every)
    if not frames:
        raise MovieError(f"RUN {run}: {source} holds no frames")
    writer = _writer(target, fps)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection

    first = frames[0]
    length = first.box_length
    n = first.positions.shape[0]
    axis = _layer_axis(first)
    across = 0 if axis != 0 else 2  # the side view's horizontal axis: the flow x (z when layers are in x)
    normal_plane = [a for a in range(3) if a != axis]
    names = AXIS_NAMES
    figure, (side, along) = plt.subplots(1, 2, figsize=(9.6, 5.0), dpi=80, layout="constrained")
    views = ((side, across, axis, "side view"), (along, normal_plane[0], normal_plane[1], "along the field"))
    collections = []
    for ax, horizontal, vertical, label in views:
        circles = EllipseCollection(
            np.full(n, 2.0),
            np.full(n, 2.0),
            np.zeros(n),
            units="xy",
            offsets=first.positions[:, [horizontal, vertical]],
            offset_transform=ax.transData,
            cmap="viridis",
            edgecolors="0.2",
            linewidths=0.3,
        )
        circles.set_array(first.positions[:, axis])
        circles.set_clim(0.0, length)
        ax.add_collection(circles)
        ax.set_xlim(-1.0, length + 1.0)
        ax.set_ylim(-1.0, length + 1.0)
        ax.set_aspect("equal")
        ax.add_patch(plt.Rectangle((0.0, 0.0), length, length, fill=False, lw=0.8, ls="--", color="0.4"))
        ax.set_xlabel(f"{names[horizontal]} / a")
        ax.set_ylabel(f"{names[vertical]} / a")
        ax.set_title(label, fontsize=10)
        collections.append((circles, horizontal, vertical))
    figure.colorbar(collections[0][0], ax=along, label=f"{names[axis]} / a (layer axis)", shrink=0.8)
    title = figure.suptitle(_title(first, axis, n), fontsize=10)
    figure.canvas.draw()  # lay the figure out once (constrained layout), then keep it for every frame:
    figure.set_layout_engine("none")  # re-laying it out per frame was half the rendering time

    def draw(frame: GsdFrame) -> None:
        positions = frame.positions.copy()
        positions -= length * np.floor(positions / length)  # the primary box, for the picture
        for circles, horizontal, vertical in collections:
            circles.set_offsets(positions[:, [horizontal, vertical]])
            circles.set_array(positions[:, axis])
        title.set_text(_title(frame, axis, n))

    tmp = target.with_name(f".{target.stem}.{os.getpid()}{TEMPORARY_SUFFIX}{target.suffix}")
    try:
        with writer.saving(figure, str(tmp), dpi=80):
            for frame in frames:
                draw(frame)
                writer.grab_frame()
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    finally:
        plt.close(figure)
    return target
