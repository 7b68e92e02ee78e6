"""``run_simulation``: input refused before anything is written, runs extended on resume, a compile notice
and a progress bar whose clock starts after compilation."""

from __future__ import annotations

import contextlib
import dataclasses
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import sim
import sim.runs.run
from sim import SimulationConfig, SimulationState, run_simulation
from sim.runs.folder import MANIFEST, RunFolderError, claim, normalise, read_manifest
from sim.runs.io import OBSERVABLE_PREFIX
from sim.runs.run import COMPILE_NOTICE, check_run_length, compiled_kernels_cached

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


def test_run_length_is_bounded_by_the_field_as_well(tmp_path: Path) -> None:
    """A strong field makes the adaptive step tiny: ``--mason 1e-9`` was an effective hang."""
    strong = dataclasses.replace(SHORT, mason_number=1e-9, strain=30.0, near_field="none")
    assert sim.runs.run.field_step_estimate(strong) > 1e12
    with pytest.raises(ValueError, match=r"mason_number=1e-09 is too strong a field for strain=30"):
        run_simulation(strong, tmp_path / "o", progress=False)
    assert not (tmp_path / "o").exists()
    # the paper's range
    check_run_length(dataclasses.replace(SHORT, mason_number=0.01, strain=30.0, near_field="none"))
    assert sim.runs.run.field_step_estimate(SHORT) == 0.0  # no field


def test_refused_runs_write_nothing(tmp_path: Path) -> None:
    existing = tmp_path / "file"
    existing.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a directory"):
        run_simulation(SHORT, existing, progress=False)
    with pytest.raises(ValueError, match="out_dir must name a directory, got ''"):
        run_simulation(SHORT, "", progress=False)
    with pytest.raises(RunFolderError, match=r"resume: out_dir .*none holds no run to continue"):
        run_simulation(SHORT, tmp_path / "none", progress=False, resume=True)
    assert not (tmp_path / "none").exists()


OBSERVABLE_KEYS = (
    "diffusivity_xx",
    "diffusivity_yy",
    "diffusivity_zz",
    "diffusivity_fit_window",
    "diffusivity_note",
    "msd_samples",
    "pair_distribution_samples",
    "observables_from_strain",
    "observables_note",
    "fabric_tensor",
    "contact_number",
    "structure_samples",
    "layer_order",
    "layer_order_stderr",
    "layer_spacing",
    "layer_onset_time",
    "layer_onset_strain",
    "layer_axis",
    "layer_samples",
    "layer_note",
)


def _assert_same_observables(a: Path, b: Path) -> None:
    """pair_distribution.npz arrays, msd.csv and layering.csv identical (bit for bit; NaN where both are
    NaN)."""
    with np.load(a / "pair_distribution.npz") as x, np.load(b / "pair_distribution.npz") as y:
        assert set(x.files) == set(y.files)
        for name in x.files:
            np.testing.assert_array_equal(x[name], y[name], err_msg=name)
    assert (a / "msd.csv").read_text() == (b / "msd.csv").read_text()
    assert (a / "layering.csv").read_text() == (b / "layering.csv").read_text()


@pytest.mark.parametrize("transient", [None, 0.01])
def test_extending_a_run_on_resume_equals_the_longer_run(tmp_path: Path, transient: float | None) -> None:
    """Resume a finished 0.02-strain run with strain 0.04: files and numbers identical to a 0.04 run,
    observables included (sampled every 0.004). With the default transient (half the run: 0.01, then 0.02)
    the accumulators restart at the new transient, which the checkpoint has just reached; with a fixed one
    they continue from the checkpoint."""
    short = dataclasses.replace(SHORT, transient_strain=transient)
    long = dataclasses.replace(LONG, transient_strain=transient)
    run_simulation(short, tmp_path / "extended", progress=False, sample_interval=0.004)
    extended = run_simulation(long, tmp_path / "extended", progress=False, resume=True, sample_interval=0.004)
    direct = run_simulation(long, tmp_path / "direct", progress=False, sample_interval=0.004)
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "min_gap", "averaged_samples"):
        assert extended[key] == direct[key], key
    for key in OBSERVABLE_KEYS:
        assert extended[key] == direct[key] or (extended[key] != extended[key] and direct[key] != direct[key])
    assert direct["observables_note"] == ""
    assert direct["msd_samples"] == (6 if transient is None else 8)  # every 0.004 from 0.02 or 0.012
    assert direct["pair_distribution_samples"] == 2  # every fourth
    assert direct["layer_samples"] == 11 and extended["layer_samples"] == 11  # every 0.004 from 0 to 0.04
    _assert_same_observables(tmp_path / "extended", tmp_path / "direct")
    for name in ("timeseries.csv", "params.json"):
        assert (tmp_path / "extended" / name).read_text() == (tmp_path / "direct" / name).read_text(), name
    a = SimulationState.load(tmp_path / "extended" / "final_state.npz")
    b = SimulationState.load(tmp_path / "direct" / "final_state.npz")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.displacement, b.displacement)
    if transient is not None:
        return
    with pytest.raises(ValueError, match="has already run past strain=0.02"):
        run_simulation(SHORT, tmp_path / "extended", progress=False, resume=True)
    other = dataclasses.replace(LONG, seed=4, time_step=0.001)
    with pytest.raises(ValueError) as refused:
        run_simulation(other, tmp_path / "extended", progress=False, resume=True)
    message = str(refused.value)
    listed = "seed (3 there, 4 requested), time_step (0.002 there, 0.001 requested)"
    assert f"different parameters: {listed}; only strain may differ" in message
    assert "n_particles" not in message  # only the differing parameters are named


def test_checkpoint_without_layer_order_still_resumes(tmp_path: Path) -> None:
    """A checkpoint written before the layer order was sampled (its ``layer_*`` arrays removed) resumes:
    the layer order starts at the first sample time the state has not passed (0.02: the last step
    started at 0.018), says so in ``layer_note``, and the other observables are as before."""
    run_simulation(SHORT, tmp_path / "o", progress=False, sample_interval=0.004)
    checkpoint = tmp_path / "o" / "checkpoint.npz"
    with np.load(checkpoint) as data:
        kept = {name: data[name] for name in data.files if not name.startswith(f"{OBSERVABLE_PREFIX}layer_")}
        assert len(kept) == len(data.files) - 6  # box_length, axis, n_particles, rows, next_index, note
    np.savez(checkpoint, **kept)
    resumed = run_simulation(LONG, tmp_path / "o", progress=False, resume=True, sample_interval=0.004)
    direct = run_simulation(LONG, tmp_path / "direct", progress=False, sample_interval=0.004)
    assert resumed["layer_note"] == "layer order from time 0.02: the checkpoint holds none before"
    assert resumed["layer_samples"] == 6  # 0.02, 0.024, ..., 0.04
    layering = np.loadtxt(tmp_path / "o" / "layering.csv", delimiter=",", skiprows=1)
    full = np.loadtxt(tmp_path / "direct" / "layering.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(layering, full[5:])  # the same configurations as the direct run's
    assert resumed["relative_viscosity"] == direct["relative_viscosity"]
    assert resumed["msd_samples"] == direct["msd_samples"]


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


def test_observables_contract_and_short_runs(tmp_path: Path) -> None:
    """result.json, pair_distribution.npz and msd.csv as other tools read them; a run too short for the
    diffusivity window gives NaN and says why; a resume with another sample_interval, or past a moved
    transient, is refused or noted."""
    result = run_simulation(SHORT, tmp_path / "o", progress=False, sample_interval=0.004)
    assert np.isnan(result["diffusivity_yy"]) and np.isnan(result["diffusivity_zz"])
    assert "too short for the fit window" in result["diffusivity_note"]
    assert result["diffusivity_fit_window"][0] == 1.0
    assert result["observables_from_strain"] == pytest.approx(0.012)  # first t_k >= transient 0.01
    saved = sim.runs.io.read_json(tmp_path / "o" / "result.json")
    assert np.isnan(saved["diffusivity_yy"]) and saved["msd_samples"] == 3
    assert saved["pair_distribution_samples"] == 1
    # fabric and contact number of the configurations g is sampled at: <n n> has trace 1 and is symmetric
    fabric = np.array(saved["fabric_tensor"])
    assert saved["structure_samples"] == 1 and np.trace(fabric) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_array_equal(fabric, fabric.T)
    assert saved["contact_number"] >= 0.0
    # layer order from t = 0 (the transient included) at every sample time; N = 40 random: not layered
    layering = np.loadtxt(tmp_path / "o" / "layering.csv", delimiter=",", skiprows=1)
    assert (tmp_path / "o" / "layering.csv").read_text().startswith("time,strain,psi,s_peak,k_peak,spacing\n")
    np.testing.assert_allclose(layering[:, 0], np.arange(6) * 0.004, atol=1e-12)
    np.testing.assert_allclose(layering[:, 1], layering[:, 0], atol=1e-12)  # strain = time at rate 1
    assert np.all((layering[:, 2] > 0.0) & (layering[:, 2] <= 1.0))
    np.testing.assert_allclose(layering[:, 2] * 40, layering[:, 3], rtol=1e-9)  # psi = S_peak / N
    np.testing.assert_allclose(layering[:, 5] * layering[:, 4], 2 * np.pi, rtol=1e-9)
    assert saved["layer_samples"] == 6 and saved["layer_axis"] == "y" and saved["layer_note"] == ""
    assert saved["layer_order"] == pytest.approx(layering[3:, 2].mean(), rel=1e-9)  # t >= 0.01
    assert np.isnan(saved["layer_order_stderr"])  # 3 samples < 10 blocks
    assert np.isnan(saved["layer_onset_time"]) and np.isnan(saved["layer_onset_strain"])
    assert (tmp_path / "o" / "layering.png").stat().st_size > 0
    with np.load(tmp_path / "o" / "pair_distribution.npz") as data:
        assert data["g_xy"].shape == (data["x_edges"].size - 1, data["y_edges"].size - 1)
        assert data["g_r"].shape == (data["r_edges"].size - 1,) and int(data["samples"]) == 1
    lines = (tmp_path / "o" / "msd.csv").read_text().splitlines()
    assert lines[0] == "lag_strain,msd_xx,msd_yy,msd_zz" and len(lines) == 3  # lags 0.004, 0.008
    np.testing.assert_allclose(np.loadtxt(lines[1:], delimiter=",")[:, 0], [0.004, 0.008], rtol=1e-6)
    with pytest.raises(ValueError, match="sample_interval=0.01 was requested"):
        run_simulation(LONG, tmp_path / "o", progress=False, resume=True, sample_interval=0.01)
    with pytest.raises(ValueError, match="sample_interval must be finite and > 0"):
        run_simulation(LONG, tmp_path / "o", progress=False, sample_interval=0.0)
    longer = dataclasses.replace(SHORT, strain=0.03)  # transient 0.015: already passed at 0.02
    moved = run_simulation(longer, tmp_path / "o", progress=False, resume=True, sample_interval=0.004)
    assert "transient 0.015 had been passed" in moved["observables_note"]
    assert moved["observables_from_strain"] == pytest.approx(0.012)


def test_compile_notice_and_progress_bar_after_the_first_chunk(tmp_path: Path, monkeypatch, capsys) -> None:
    """With an empty kernel cache a note is printed before the run; the bar is created after the first
    chunk of steps (which includes compilation), so its clock and estimate exclude compiling."""
    bars: list[_Bar] = []

    def make_bar(config: SimulationConfig, strain: float) -> Any:
        bars.append(_Bar(strain))
        return bars[-1]

    monkeypatch.setattr(sim.runs.run, "_progress_bar", make_bar)
    monkeypatch.setattr(sim.runs.run, "compiled_kernels_cached", lambda: False)
    config = dataclasses.replace(SHORT, strain=0.3)  # at least 150 steps: two chunks of <= 100
    run_simulation(config, tmp_path / "o", progress=True)
    assert COMPILE_NOTICE in capsys.readouterr().err
    assert len(bars) == 1 and bars[0].closed
    assert 0.0 < bars[0].start < 0.3  # created at the end of the first chunk, not before the run
    assert bars[0].updates >= 1 and bars[0].n == pytest.approx(0.3, abs=config.time_step)
    run_simulation(config, tmp_path / "quiet", progress=False)
    assert COMPILE_NOTICE not in capsys.readouterr().err
    monkeypatch.setattr(sim.runs.run, "compiled_kernels_cached", lambda: True)
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


def test_a_folder_holding_another_run_is_refused_unless_overwritten(tmp_path: Path) -> None:
    """The run-folder protocol (issue 45). Was: a run with another seed overwrote the folder's run with
    no complaint (issue 16), then the same parameters were refused too. Now the manifest names the owner:
    a run of other parameters is refused (naming them) and left untouched, a longer strain needs
    ``resume``, a rerun of the same parameters continues (a finished run's results rewritten, unchanged),
    ``overwrite`` deletes the previous run, ``resume`` and ``overwrite`` exclude each other."""
    out = tmp_path / "o"
    first = run_simulation(SHORT, out, progress=False)
    manifest = read_manifest(out)
    assert manifest is not None and manifest.command == "sim run"
    assert manifest.params == normalise(sim.runs.run.run_identity(SHORT))
    before = {name: (out / name).read_bytes() for name in ("params.json", "result.json", "checkpoint.npz")}
    other = dataclasses.replace(SHORT, seed=4)
    with pytest.raises(ValueError) as refused:
        run_simulation(other, out, progress=False)
    message = str(refused.value)
    assert f"out_dir {out} holds a run with different parameters: seed (3 there, 4 requested)" in message
    assert "n_particles" not in message and "overwrite" in message
    with pytest.raises(ValueError, match="resume continues it to the new strain"):
        run_simulation(LONG, out, progress=False)
    with pytest.raises(ValueError, match="resume and overwrite exclude each other"):
        run_simulation(SHORT, out, progress=False, resume=True, overwrite=True)
    assert {name: (out / name).read_bytes() for name in before} == before
    again = run_simulation(SHORT, out, progress=False)  # the same run: continued, nothing left to step
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "min_gap"):
        assert again[key] == first[key], key
    result = run_simulation(other, out, progress=False, overwrite=True)
    assert result["seed"] == 4 and sim.runs.io.read_json(out / "result.json")["seed"] == 4
    assert sim.runs.io.read_json(out / "params.json")["config"]["seed"] == 4
    assert read_manifest(out).params["seed"] == 4  # type: ignore[union-attr]


def test_a_run_folder_written_before_manifests_is_adopted(tmp_path: Path) -> None:
    """A folder of ``params.json``/``checkpoint.npz``/``result.json`` without a manifest is a run of an
    older ``sim``: compared through its params.json (else its checkpoint), continued when it is this run
    (the manifest is added), refused when it is another one or cannot be read."""
    out = tmp_path / "o"
    run_simulation(SHORT, out, progress=False)
    (out / MANIFEST).unlink()
    other = dataclasses.replace(SHORT, seed=4)
    differing = r"holds a run with different parameters: seed \(3 there, 4 requested\)"
    with pytest.raises(ValueError, match=differing):
        run_simulation(other, out, progress=False)
    (out / "params.json").write_text("{")  # unreadable: the checkpoint tells the parameters
    with pytest.raises(ValueError, match=r"seed \(3 there, 4 requested\)"):
        run_simulation(other, out, progress=False)
    run_simulation(SHORT, out, progress=False)  # adopted and continued
    assert read_manifest(out).command == "sim run"  # type: ignore[union-attr]
    (out / MANIFEST).unlink()
    (out / "checkpoint.npz").unlink()
    (out / "params.json").write_text("{")
    with pytest.raises(ValueError, match=r"holds files of another run \(params.json.*cannot be read"):
        run_simulation(other, out, progress=False)
    assert run_simulation(other, out, progress=False, overwrite=True)["seed"] == 4


def test_unknown_and_foreign_folders(tmp_path: Path) -> None:
    """A non-empty folder without a manifest is refused, even with ``overwrite`` (it may hold anything);
    another command's folder is refused, and ``overwrite`` deletes all of it (issue 45: ``sim run
    --overwrite`` on a flow-curve folder left flow_curve.csv/.png beside the new run)."""
    unrelated = tmp_path / "unrelated"
    unrelated.mkdir()
    (unrelated / "notes.txt").write_text("x")
    for overwrite in (False, True):
        with pytest.raises(RunFolderError, match=r"is not empty \(notes.txt\) and holds no manifest.json"):
            run_simulation(SHORT, unrelated, progress=False, overwrite=overwrite)
    assert [p.name for p in unrelated.iterdir()] == ["notes.txt"]
    curve = tmp_path / "curve"
    claim(curve, "sim flow-curve", {"rates": [1.0]})
    for name in ("flow_curve.csv", "flow_curve.png", "params.json", "checkpoint.npz"):
        (curve / name).write_text("x")
    with pytest.raises(RunFolderError, match="belongs to another command .'sim flow-curve'"):
        run_simulation(SHORT, curve, progress=False)
    run_simulation(SHORT, curve, progress=False, overwrite=True)
    left = {p.name for p in curve.iterdir()}
    assert "flow_curve.csv" not in left and "flow_curve.png" not in left and "result.json" in left
    assert read_manifest(curve).command == "sim run"  # type: ignore[union-attr]


@pytest.mark.parametrize("resume", [False, True])
def test_an_interrupted_rerun_leaves_no_old_result_beside_its_parameters(
    tmp_path: Path, monkeypatch, resume: bool
) -> None:
    """Was: killed mid-run, a new run left its params.json beside the old run's result.json. The earlier
    run's results are deleted before the new parameters are written (a resume keeps the checkpoint)."""
    out = tmp_path / "o"
    run_simulation(SHORT, out, progress=False)

    def killed(*args: Any, **kwargs: Any) -> float:
        raise KeyboardInterrupt

    monkeypatch.setattr(sim.runs.run, "_advance_with_checkpoints", killed)
    new = LONG if resume else dataclasses.replace(SHORT, seed=4)
    with pytest.raises(KeyboardInterrupt):
        run_simulation(new, out, progress=False, resume=resume, overwrite=not resume)
    assert SimulationConfig.from_dict(sim.runs.io.read_json(out / "params.json")["config"]) == new
    left = sorted(p.name for p in out.iterdir())
    assert left == (["checkpoint.npz", MANIFEST, "params.json"] if resume else [MANIFEST, "params.json"])


def _partial_then_fail(file: Any, *args: Any, **kwargs: Any) -> None:
    """Stands in for np.savez / np.savetxt on a full disk: half a file, then an error."""
    handle = open(file, "wb") if isinstance(file, str | Path) else file  # noqa: SIM115
    handle.write(b"half a file")
    raise OSError("No space left on device")


_STATE = SimulationState.initial(np.zeros((2, 3)))
_RECORDS = sim.StepRecords.empty()
_WRITERS = {
    "checkpoint.npz": lambda p: sim.runs.io.save_checkpoint(p, SHORT, _STATE, _RECORDS, 0.0),
    "final_state.npz": lambda p: sim.runs.io.save_final_state(p, SHORT, _STATE),
    "pair_distribution.npz": lambda p: sim.runs.io.write_pair_distribution(p, {"g_r": np.ones(3)}),
    "timeseries.csv": lambda p: sim.runs.io.write_timeseries(p, _RECORDS),
    "msd.csv": lambda p: sim.runs.io.write_msd(p, np.ones(2), np.ones((2, 3))),
}


@pytest.mark.parametrize("name", sorted(_WRITERS))
def test_result_files_are_written_atomically(tmp_path: Path, monkeypatch, name: str) -> None:
    """Was: np.savez / np.savetxt straight into the file, so a failure (full disk, a kill) half-way left
    a truncated file. A write that fails half-way keeps the previous file whole, with no temporary file
    left; a write that succeeds replaces it."""
    path = tmp_path / name
    _WRITERS[name](path)
    written = path.read_bytes()
    path.write_bytes(b"previous")
    with monkeypatch.context() as patch:
        patch.setattr(sim.runs.io.np, "savez" if name.endswith(".npz") else "savetxt", _partial_then_fail)
        with pytest.raises(OSError, match="No space left"):
            _WRITERS[name](path)
    assert path.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    _WRITERS[name](path)
    assert path.read_bytes() == written or name.endswith(".npz")  # npz: zip timestamps may differ


def test_json_goes_through_atomic_file(tmp_path: Path) -> None:
    """``result.json`` and ``params.json`` are written by :func:`sim.runs.io.write_json`, atomically."""
    path = tmp_path / "result.json"
    path.write_text("previous")
    with pytest.raises(RuntimeError), sim.runs.io.atomic_file(path) as handle:
        handle.write(b"{half")
        raise RuntimeError("killed")
    assert path.read_text() == "previous" and [p.name for p in tmp_path.iterdir()] == ["result.json"]
    sim.runs.io.write_json(path, {"a": float("nan")})
    assert sim.runs.io.read_json(path)["a"] != sim.runs.io.read_json(path)["a"]
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


def test_ctrl_c_stops_at_the_end_of_a_chunk_with_a_checkpoint(tmp_path: Path, monkeypatch) -> None:
    """Ctrl-C inside a compiled kernel came out as a SystemError (a failed simulation). It is deferred to
    the end of the chunk of steps, where a checkpoint is written; resuming from it gives the
    uninterrupted run's numbers bit for bit."""
    config = dataclasses.replace(SHORT, strain=0.3, transient_strain=0.1)  # 150 steps, several chunks

    @contextlib.contextmanager
    def pressed_at_once() -> Iterator[Callable[[], bool]]:
        yield lambda: True

    with monkeypatch.context() as patch:
        patch.setattr(sim.runs.run, "_deferred_interrupt", pressed_at_once)
        with pytest.raises(KeyboardInterrupt):
            run_simulation(config, tmp_path / "cut", progress=False)
    _, state, _, _ = sim.runs.io.load_checkpoint(tmp_path / "cut" / "checkpoint.npz")
    assert 0.0 < state.strain < 0.3 and not (tmp_path / "cut" / "result.json").exists()
    resumed = run_simulation(config, tmp_path / "cut", progress=False, resume=True)
    direct = run_simulation(config, tmp_path / "direct", progress=False)
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "min_gap", "msd_samples"):
        assert resumed[key] == direct[key], key
    _assert_same_observables(tmp_path / "cut", tmp_path / "direct")
    assert (tmp_path / "cut" / "timeseries.csv").read_text() == (
        tmp_path / "direct" / "timeseries.csv"
    ).read_text()


def test_deferred_interrupt_sets_a_flag_then_restores_the_handler() -> None:
    previous = signal.getsignal(signal.SIGINT)
    with sim.runs.run._deferred_interrupt() as interrupted:
        assert not interrupted()
        signal.raise_signal(signal.SIGINT)  # no KeyboardInterrupt here
        assert interrupted()
    assert signal.getsignal(signal.SIGINT) is previous


def test_figures_are_written_atomically(tmp_path: Path, monkeypatch) -> None:
    """Issue 45: the plots (stress.png, layering.png, flow_curve.png, the sweep figures) were saved
    straight into their files. Every figure goes through :func:`sim.runs.io.save_figure` (a failure half-way
    keeps the previous file, and no temporary file is left)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = tmp_path / "stress.png"
    path.write_bytes(b"previous")
    figure = plt.figure()

    def half_then_full_disk(self: Any, handle: Any, **kwargs: Any) -> None:
        handle.write(b"half a png")
        raise OSError("No space left on device")

    with monkeypatch.context() as patch:
        patch.setattr(type(figure), "savefig", half_then_full_disk)
        with pytest.raises(OSError, match="No space left"):
            sim.runs.io.save_figure(figure, path)
    assert path.read_bytes() == b"previous" and [p.name for p in tmp_path.iterdir()] == ["stress.png"]
    sim.runs.io.save_figure(figure, path, dpi=40)
    assert path.read_bytes().startswith(b"\x89PNG")
    plt.close(figure)
    root = Path(sim.__file__).parent
    direct = [p.name for p in root.rglob("*.py") if ".savefig(" in p.read_text() and p.name != "io.py"]
    assert direct == [], f"figures saved without sim.runs.io.save_figure in {direct}"
