"""``python -m sim movie`` (``sim.plots.movie``): a GIF of a run's trajectory, and the refusals.

Independent check: the GIF is opened with Pillow and holds one picture per frame drawn."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
from PIL import Image

from sim import SimulationConfig, run_simulation
from sim.plots.movie import MovieError, render_movie
from sim.runs.cli import main

SHORT = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=3)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny run with 5 frames (strain 0, 0.005, ..., 0.02)."""
    out = tmp_path_factory.mktemp("movie") / "run"
    run_simulation(SHORT, out, progress=False, trajectory_every=0.005)
    return out


def _movie(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        status = main(["movie", *args])
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_a_gif_of_the_trajectory_in_a_few_seconds(run: Path, capsys) -> None:
    started = time.perf_counter()
    status, out, err = _movie([str(run), "--fps", "5"], capsys)
    elapsed = time.perf_counter() - started
    assert status == 0, err
    movie = run / "movie.gif"
    assert out.strip() == str(movie)
    with Image.open(movie) as image:
        assert image.n_frames == 5 and image.size[0] > 300
    assert elapsed < 30.0  # about 1 s on an idle core; generous for a shared CI machine
    assert [p.name for p in run.iterdir() if p.name.startswith(".")] == []  # no temporary file left


def test_every_and_a_gsd_file_as_run(run: Path, tmp_path: Path) -> None:
    written = render_movie(run / "trajectory.gsd", tmp_path / "m.gif", fps=20, every=2)
    with Image.open(written) as image:
        assert image.n_frames == 3  # frames 0, 2, 4


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["{tmp}/nowhere"], "RUN {tmp}/nowhere: no such run folder or GSD file"),
        (["{tmp}"], "holds no trajectory.gsd: run python -m sim run ... --trajectory-every S"),
        (["{run}", "--out", "{tmp}/m.avi"], "the movie must be a .gif or .mp4 file, got '.avi'"),
        (["{run}", "--fps", "0"], "--fps must be an integer in [1, 100], got 0"),
        (["{run}", "--every", "0"], "--every must be an integer >= 1 (1: every frame), got 0"),
        (["{run}", "--fps", "x"], "argument --fps: invalid int value: 'x'"),
        (["{run}", "--out", "{tmp}/no/m.gif"], "the folder {tmp}/no does not exist"),
        (["{tmp}/garbage.gsd"], "not a readable GSD file"),
    ],
)
def test_bad_input_exits_2(args: list[str], needle: str, run: Path, tmp_path: Path, capsys) -> None:
    (tmp_path / "garbage.gsd").write_bytes(b"GSD? no")
    status, _, err = _movie([a.format(tmp=tmp_path, run=run) for a in args], capsys)
    assert status == 2, err
    assert err.startswith("usage: python -m sim movie ")
    assert "python -m sim movie: error: " in err and needle.format(tmp=tmp_path, run=run) in err, err


def test_mp4_without_ffmpeg_names_the_gif_alternative(run: Path, tmp_path: Path, monkeypatch) -> None:
    from matplotlib import animation

    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    with pytest.raises(MovieError, match=r"needs ffmpeg, which is not installed .*--out .*m.gif"):
        render_movie(run, tmp_path / "m.mp4")
    if shutil.which("ffmpeg") is None:
        monkeypatch.undo()
        with pytest.raises(MovieError, match="needs ffmpeg"):
            render_movie(run, tmp_path / "m.mp4")
