"""GSD trajectories (``sim.runs.trajectory``, ``sim run --trajectory-every``): the format as any GSD reader
sees it, the frames a run writes, and resuming without duplicate frames.

Independent numbers: ``gsd.hoomd.open`` reads the files (not our reader), and the box is checked against
its definition (``xy = delta / L`` with ``delta`` from ``sim.geometry.box.lees_edwards_offset``; every
stored position inside the tilted cell). Single-precision positions agree with the state to
``L 2^-24`` (4.5e-7 a at L = 7.5; the test holds 2e-6); the double-precision log entry bit for bit.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path

import gsd.hoomd
import numpy as np
import pytest

import sim.runs.run
from sim import Simulation, SimulationConfig, SimulationState, run_simulation
from sim.geometry.box import lees_edwards_offset
from sim.runs.io import load_checkpoint
from sim.runs.trajectory import (
    TRAJECTORY,
    TrajectoryError,
    append_frames,
    from_gsd_positions,
    make_frame,
    read_frame,
    to_gsd_positions,
)

SHORT = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=3)
"""10 steps of N = 40."""


@pytest.fixture(scope="module")
def sheared() -> tuple[SimulationConfig, SimulationState]:
    """A state at strain 0.31 (a Lees–Edwards offset of 0.31 L, beyond L/4)."""
    config = dataclasses.replace(SHORT, strain=1.0)
    simulation = Simulation(config)
    simulation.advance_to(0.31)
    return config, simulation.snapshot()


def test_round_trip_through_a_gsd_reader(
    tmp_path: Path, sheared: tuple[SimulationConfig, SimulationState]
) -> None:
    config, state = sheared
    length = config.box_length
    path = tmp_path / "t.gsd"
    append_frames(path, [make_frame(state, length)])
    with gsd.hoomd.open(str(path), "r") as trajectory:
        assert len(trajectory) == 1
        frame = trajectory[0]
    delta = lees_edwards_offset(state.strain, length)
    assert abs(delta) > 0.25 * length
    np.testing.assert_allclose(
        frame.configuration.box, [length, length, length, delta / length, 0.0, 0.0], rtol=1e-7, atol=1e-7
    )
    assert int(frame.configuration.step) == state.step
    assert frame.particles.N == config.n_particles and list(frame.particles.types) == ["sphere"]
    np.testing.assert_array_equal(frame.particles.diameter, np.full(config.n_particles, 2.0))
    stored = np.asarray(frame.particles.position, dtype=np.float64)
    # centred, inside the tilted cell: fractional coordinates in [-1/2, 1/2)
    xy = float(frame.configuration.box[3])
    fractions = np.column_stack(
        [(stored[:, 0] - xy * stored[:, 1]) / length, stored[:, 1] / length, stored[:, 2] / length]
    )
    assert np.all((fractions >= -0.5 - 1e-6) & (fractions < 0.5 + 1e-6))
    # undoing the centring (+L/2 on every axis, x modulo L) gives the state's positions
    undone = stored + 0.5 * length
    undone[:, 0] %= length
    difference = np.abs(undone - state.positions)
    assert float(np.minimum(difference, length - difference).max()) < 2e-6
    np.testing.assert_array_equal(frame.log["particles/dipsim/position"], state.positions)
    assert float(frame.log["dipsim/strain"][0]) == state.strain
    assert float(frame.log["dipsim/time"][0]) == state.time
    assert float(frame.log["dipsim/shear_rate"][0]) == state.shear_rate
    assert float(frame.log["dipsim/mason_number"][0]) == np.inf
    np.testing.assert_array_equal(frame.log["dipsim/field_direction"], state.field_direction)
    # our reader: the exact positions, the strain and the clock
    read = read_frame(path)
    np.testing.assert_array_equal(read.positions, state.positions)
    assert read.exact and read.strain == state.strain and read.time == state.time and read.has_field


def test_positions_round_trip_in_any_tilt() -> None:
    """``to_gsd_positions`` / ``from_gsd_positions`` are inverse at every offset, the cell's corners too."""
    rng = np.random.default_rng(1)
    length = 9.0
    positions = rng.uniform(0.0, length, size=(500, 3))
    positions[:4] = [
        [0.0, 0.0, 0.0],
        [length * (1 - 1e-15), 0.0, 0.0],
        [0.0, length * (1 - 1e-15), 0.0],
        [4.5] * 3,
    ]
    for strain in (0.0, 0.2, 0.5, -0.49, 3.7):
        xy = lees_edwards_offset(strain, length) / length
        stored = to_gsd_positions(positions, length, xy)
        fraction = (stored[:, 0] - xy * stored[:, 1]) / length
        assert np.all((fraction >= -0.5) & (fraction < 0.5))
        back = from_gsd_positions(stored, length)
        difference = np.abs(back - positions)
        assert float(np.minimum(difference, length - difference).max()) < 1e-13


def test_a_run_writes_frames_at_strain_multiples(tmp_path: Path) -> None:
    result = run_simulation(SHORT, tmp_path / "o", progress=False, trajectory_every=0.005)
    assert result["trajectory_frames"] == 5
    with gsd.hoomd.open(str(tmp_path / "o" / TRAJECTORY), "r") as trajectory:
        strains = [float(frame.log["dipsim/strain"][0]) for frame in trajectory]
        steps = [int(frame.configuration.step) for frame in trajectory]
    multiples = 0.005 * np.arange(5)
    # the first step at or beyond each multiple (steps of 0.002); the last at the run's end exactly
    assert np.all(np.array(strains) >= multiples - 1e-12) and np.all(np.array(strains) < multiples + 0.002)
    assert strains[0] == 0.0 and abs(strains[-1] - 0.02) < 1e-12
    assert steps == sorted(set(steps)) and steps[0] == 0 and steps[-1] == result["steps"]


def _frames(path: Path) -> list[tuple[int, float, np.ndarray]]:
    with gsd.hoomd.open(str(path), "r") as trajectory:
        return [
            (
                int(frame.configuration.step),
                float(frame.log["dipsim/strain"][0]),
                np.array(frame.log["particles/dipsim/position"]),
            )
            for frame in trajectory
        ]


def _assert_same_frames(a: Path, b: Path) -> None:
    first, second = _frames(a), _frames(b)
    assert [f[:2] for f in first] == [f[:2] for f in second]
    for x, y in zip(first, second, strict=True):
        np.testing.assert_array_equal(x[2], y[2])


def _assert_same_snapshots(a: Path, b: Path) -> None:
    names = sorted(p.name for p in (a / "snapshots").iterdir())
    assert names == sorted(p.name for p in (b / "snapshots").iterdir())
    for name in names:
        x, y = SimulationState.load(a / "snapshots" / name), SimulationState.load(b / "snapshots" / name)
        np.testing.assert_array_equal(x.positions, y.positions, err_msg=name)
        assert x.strain == y.strain and x.step == y.step, name


def test_extending_a_run_adds_frames_and_snapshots_without_duplicates(tmp_path: Path) -> None:
    """A finished 0.02 run extended to 0.04 (``resume``) holds the frames and snapshots of a 0.04 run from
    the start: the frame and the snapshot the short run kept at its (shortened) end are replaced by the
    longer run's, none is written twice."""
    keep = {"trajectory_every": 0.005, "snapshot_every": 0.01}
    longer = dataclasses.replace(SHORT, strain=0.04)
    run_simulation(SHORT, tmp_path / "extended", progress=False, **keep)  # type: ignore[arg-type]
    assert len(_frames(tmp_path / "extended" / TRAJECTORY)) == 5
    extended = run_simulation(longer, tmp_path / "extended", progress=False, resume=True, **keep)  # type: ignore[arg-type]
    direct = run_simulation(longer, tmp_path / "direct", progress=False, **keep)  # type: ignore[arg-type]
    assert extended["trajectory_frames"] == direct["trajectory_frames"] == 9
    _assert_same_frames(tmp_path / "extended" / TRAJECTORY, tmp_path / "direct" / TRAJECTORY)
    _assert_same_snapshots(tmp_path / "extended", tmp_path / "direct")
    assert sorted(p.name for p in (tmp_path / "direct" / "snapshots").iterdir()) == [
        "strain_0000.01.npz",
        "strain_0000.02.npz",
        "strain_0000.03.npz",
        "strain_0000.04.npz",
    ]


def test_an_interrupted_run_resumes_without_duplicate_or_lost_frames(tmp_path: Path, monkeypatch) -> None:
    """Ctrl-C at the end of the first chunk (a checkpoint is written), then a frame that a killed run
    wrote after its checkpoint: the resumed run drops it and ends with the uninterrupted run's frames."""
    config = dataclasses.replace(SHORT, strain=0.3, transient_strain=0.1)  # 150 steps, several chunks
    keep = {"trajectory_every": 0.05, "snapshot_every": 0.1}

    @contextlib.contextmanager
    def pressed_at_once() -> Iterator[Callable[[], bool]]:
        yield lambda: True

    cut = tmp_path / "cut"
    with monkeypatch.context() as patch:
        patch.setattr(sim.runs.run, "_deferred_interrupt", pressed_at_once)
        with pytest.raises(KeyboardInterrupt):
            run_simulation(config, cut, progress=False, **keep)  # type: ignore[arg-type]
    written = _frames(cut / TRAJECTORY)
    assert 1 <= len(written) < 7
    _, at_checkpoint, _, _ = load_checkpoint(cut / "checkpoint.npz")
    at_checkpoint.step += 7
    stray = make_frame(at_checkpoint, config.box_length)
    append_frames(cut / TRAJECTORY, [stray])  # a frame past the checkpoint (killed before checkpointing)
    resumed = run_simulation(config, cut, progress=False, resume=True, **keep)  # type: ignore[arg-type]
    direct = run_simulation(config, tmp_path / "direct", progress=False, **keep)  # type: ignore[arg-type]
    assert resumed["trajectory_frames"] == direct["trajectory_frames"] == 7  # strain 0, 0.05, ..., 0.3
    _assert_same_frames(cut / TRAJECTORY, tmp_path / "direct" / TRAJECTORY)
    _assert_same_snapshots(cut, tmp_path / "direct")


def test_a_trajectory_the_checkpoint_outlived_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "o"
    run_simulation(SHORT, out, progress=False, trajectory_every=0.005)
    (out / TRAJECTORY).unlink()
    with pytest.raises(
        TrajectoryError, match=r"trajectory.gsd is missing, but the checkpoint counts 4 frames"
    ):
        run_simulation(SHORT, out, progress=False, trajectory_every=0.005)
    (out / TRAJECTORY).write_bytes(b"not a gsd file")
    with pytest.raises(TrajectoryError, match="not a readable GSD file.*give overwrite"):
        run_simulation(SHORT, out, progress=False, trajectory_every=0.005)
    run_simulation(SHORT, out, progress=False, trajectory_every=0.005, overwrite=True)
    assert len(_frames(out / TRAJECTORY)) == 5


def test_a_run_with_other_spacings_is_another_run(tmp_path: Path) -> None:
    out = tmp_path / "o"
    run_simulation(SHORT, out, progress=False, trajectory_every=0.005)
    with pytest.raises(ValueError, match=r"trajectory_every \(0.005 there, 0.01 requested\)"):
        run_simulation(SHORT, out, progress=False, trajectory_every=0.01)
    with pytest.raises(ValueError, match=r"trajectory_every \(0.005 there, None requested\)"):
        run_simulation(SHORT, out, progress=False)
    with pytest.raises(ValueError, match=r"snapshot_every \(None there, 0.01 requested\)"):
        run_simulation(SHORT, out, progress=False, trajectory_every=0.005, snapshot_every=0.01)


def test_foreign_and_broken_gsd_files(
    tmp_path: Path, sheared: tuple[SimulationConfig, SimulationState]
) -> None:
    """A GSD file without our log entries (as HOOMD or another tool writes it) reads with its
    single-precision positions, clock 0 and the tilt as the strain; broken ones are refused, named."""
    config, state = sheared
    length = config.box_length
    frame = make_frame(state, length)
    frame.log = {}
    path = tmp_path / "foreign.gsd"
    append_frames(path, [frame])
    read = read_frame(path)
    assert not read.exact and not read.has_field and read.time == 0.0
    assert read.strain == pytest.approx(lees_edwards_offset(state.strain, length) / length, abs=1e-7)
    difference = np.abs(read.positions - state.positions)
    assert float(np.minimum(difference, length - difference).max()) < 2e-6
    with pytest.raises(TrajectoryError, match="holds no frames"):
        with gsd.hoomd.open(str(tmp_path / "empty.gsd"), "w"):
            pass
        read_frame(tmp_path / "empty.gsd")
    with pytest.raises(TrajectoryError, match=r"the frame must be in \[0, 0\]"):
        read_frame(path, 3)
    skewed = make_frame(state, length)
    skewed.configuration.box = [length, length, length, 0.0, 0.1, 0.0]
    append_frames(tmp_path / "skewed.gsd", [skewed])
    with pytest.raises(TrajectoryError, match="not a cubic Lees–Edwards box"):
        read_frame(tmp_path / "skewed.gsd")
    wrong = make_frame(state, length)
    wrong.configuration.box = [length, length, length, 0.0, 0.0, 0.0]
    append_frames(tmp_path / "wrong.gsd", [wrong])
    with pytest.raises(TrajectoryError, match="is not the Lees–Edwards offset of log/dipsim/strain"):
        read_frame(tmp_path / "wrong.gsd")
    (tmp_path / "garbage.gsd").write_bytes(b"\x00" * 100)
    with pytest.raises(TrajectoryError, match="not a readable GSD file"):
        read_frame(tmp_path / "garbage.gsd")
    with pytest.raises(FileNotFoundError):
        read_frame(tmp_path / "missing.gsd")
