"""``run_simulation``: input refused before anything is written, runs extended on resume, a compile notice
and a progress bar whose clock starts after compilation."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import sim
import sim.run
from sim import SimulationConfig, SimulationState, run_simulation
from sim.run import COMPILE_NOTICE, check_run_length, compiled_kernels_cached

SHORT = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=3)
"""10 steps of N = 40."""

LONG = dataclasses.replace(SHORT, strain=0.04)


@pytest.mark.parametrize(
    ("strain", "transient", "message"),
    [
        (0.0, None, "strain must be > 0 for a run"),
        (0.002, None, "no samples after the transient: averaging starts at strain 0.001"),
        (0.01, 0.0095, "no samples after the transient: averaging starts at strain 0.0095"),
    ],
)
def test_run_length_checks(strain: float, transient: float | None, message: str, tmp_path: Path) -> None:
    config = dataclasses.replace(SHORT, strain=strain, transient_strain=transient)
    with pytest.raises(ValueError, match=message):
        run_simulation(config, tmp_path / "o", progress=False)
    assert not (tmp_path / "o").exists()


def test_run_length_accepts_one_sample_after_the_transient() -> None:
    """The last step starts at strain - dt at the latest: a transient there leaves one sample."""
    check_run_length(dataclasses.replace(SHORT, strain=0.004))  # default transient 0.002 = strain - dt
    check_run_length(dataclasses.replace(SHORT, transient_strain=0.018))
    flags = {"strain": "--strain", "transient_strain": "--transient", "time_step": "--dt"}
    with pytest.raises(ValueError, match="lengthen --strain or shorten --transient"):
        check_run_length(dataclasses.replace(SHORT, transient_strain=0.0185), flags)


def test_refused_runs_write_nothing(tmp_path: Path) -> None:
    existing = tmp_path / "file"
    existing.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a directory"):
        run_simulation(SHORT, existing, progress=False)
    with pytest.raises(FileNotFoundError, match="resume: no checkpoint at"):
        run_simulation(SHORT, tmp_path / "none", progress=False, resume=True)
    assert not (tmp_path / "none").exists()


def test_extending_a_run_on_resume_equals_the_longer_run(tmp_path: Path) -> None:
    """Resume a finished 0.02-strain run with strain 0.04: files and numbers identical to a 0.04 run."""
    run_simulation(SHORT, tmp_path / "extended", progress=False)
    extended = run_simulation(LONG, tmp_path / "extended", progress=False, resume=True)
    direct = run_simulation(LONG, tmp_path / "direct", progress=False)
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "min_gap", "averaged_samples"):
        assert extended[key] == direct[key], key
    for name in ("timeseries.csv", "params.json"):
        assert (tmp_path / "extended" / name).read_text() == (tmp_path / "direct" / name).read_text(), name
    a = SimulationState.load(tmp_path / "extended" / "final_state.npz")
    b = SimulationState.load(tmp_path / "direct" / "final_state.npz")
    np.testing.assert_array_equal(a.positions, b.positions)
    with pytest.raises(ValueError, match="has already run past strain=0.02"):
        run_simulation(SHORT, tmp_path / "extended", progress=False, resume=True)
    other = dataclasses.replace(LONG, seed=4, time_step=0.001)
    with pytest.raises(ValueError) as refused:
        run_simulation(other, tmp_path / "extended", progress=False, resume=True)
    message = str(refused.value)
    listed = "seed (3 there, 4 requested), time_step (0.002 there, 0.001 requested)"
    assert f"different parameters: {listed}; only strain may differ" in message
    assert "n_particles" not in message  # only the differing parameters are named


class _Bar:
    """Stands in for tqdm: records its starting strain and updates."""

    def __init__(self, strain: float) -> None:
        self.start = strain
        self.n = strain
        self.updates = 0
        self.closed = False

    def refresh(self) -> None:
        self.updates += 1

    def close(self) -> None:
        self.closed = True


def test_compile_notice_and_progress_bar_after_the_first_chunk(tmp_path: Path, monkeypatch, capsys) -> None:
    """With an empty kernel cache a note is printed before the run; the bar is created after the first
    chunk of steps (which includes compilation), so its clock and estimate exclude compiling."""
    bars: list[_Bar] = []

    def make_bar(config: SimulationConfig, strain: float) -> Any:
        bars.append(_Bar(strain))
        return bars[-1]

    monkeypatch.setattr(sim.run, "_progress_bar", make_bar)
    monkeypatch.setattr(sim.run, "compiled_kernels_cached", lambda: False)
    config = dataclasses.replace(SHORT, strain=0.3)  # at least 150 steps: two chunks of <= 100
    run_simulation(config, tmp_path / "o", progress=True)
    assert COMPILE_NOTICE in capsys.readouterr().err
    assert len(bars) == 1 and bars[0].closed
    assert 0.0 < bars[0].start < 0.3  # created at the end of the first chunk, not before the run
    assert bars[0].updates >= 1 and bars[0].n == pytest.approx(0.3, abs=config.time_step)
    run_simulation(config, tmp_path / "quiet", progress=False)
    assert COMPILE_NOTICE not in capsys.readouterr().err
    monkeypatch.setattr(sim.run, "compiled_kernels_cached", lambda: True)
    run_simulation(config, tmp_path / "cached", progress=True)
    assert COMPILE_NOTICE not in capsys.readouterr().err


def test_compiled_kernels_cached_reads_this_checkouts_cache(tmp_path: Path, monkeypatch) -> None:
    """True after a run (the kernels are in numba's cache); False for an empty cache directory."""
    run_simulation(SHORT, tmp_path / "o", progress=False)
    if sim.NUMBA_CACHE_DIR and Path(sim.NUMBA_CACHE_DIR).is_dir():
        assert compiled_kernels_cached()
    monkeypatch.setattr(sim, "NUMBA_CACHE_DIR", str(tmp_path / "empty"))
    (tmp_path / "empty").mkdir()
    assert not compiled_kernels_cached()
    (tmp_path / "empty" / "elsewhere_0123").mkdir()  # another checkout's kernels do not count
    (tmp_path / "empty" / "elsewhere_0123" / "stepper.advance-1.py311.nbi").write_bytes(b"")
    assert not compiled_kernels_cached()
