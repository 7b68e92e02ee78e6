"""Issue 45: starting the run machinery from a configuration (``sim run --initial-state FILE``,
``run_simulation(state=...)``, :mod:`sim.runs.initial_state`).

Independent numbers: a run's own trajectory frame, snapshot and final state hold the same configuration
(same step), so runs started from them must be identical; the first stress of a run from a state at
strain 0.01 must be the stress the source run recorded there (its warm start differs, so to the solver's
tolerance, 1e-8 relative; the test holds 1e-6), which fails by orders of magnitude if the strain, and so
the Lees–Edwards offset, were not taken.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import gsd.hoomd
import numpy as np
import pytest
from cli_helpers import run_cli

from sim import SimulationConfig, SimulationState, run_simulation
from sim.runs.folder import MANIFEST
from sim.runs.initial_state import (
    InitialState,
    InitialStateError,
    check_initial_state,
    read_initial_state,
    with_field_of,
)
from sim.runs.io import load_checkpoint, read_json
from sim.runs.trajectory import TRAJECTORY, append_frames, make_frame

CONFIG = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=3)
RUN_ARGS = ["--phi", "0.4", "--n-particles", "40", "--strain", "0.02", "--seed", "3", "--quiet"]
PREFIX = "python -m sim run: error: "
FIELD_NAMES = re.compile(
    r"\b(n_particles|volume_fraction|mason_number|field_direction|shear_rate|snapshot_every|"
    r"trajectory_every|field_from_state)\b"
)


def assert_refused(status: int, err: str, needle: str) -> None:
    """Exit 2, ``run``'s usage, one error line naming the flag, no field name leaked."""
    assert status == 2, err
    assert err.startswith("usage: python -m sim run "), err
    assert PREFIX in err and needle in err.split(PREFIX, 1)[1], err
    assert not FIELD_NAMES.search(err), err


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished run with a trajectory (every 0.005) and snapshots (every 0.01)."""
    out = tmp_path_factory.mktemp("source") / "run"
    run_simulation(CONFIG, out, progress=False, trajectory_every=0.005, snapshot_every=0.01)
    return out


def _timeseries(out: Path) -> np.ndarray:
    return np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)


def test_a_frame_and_a_snapshot_of_one_step_start_the_same_run(source: Path, tmp_path: Path, capsys) -> None:
    """Frame 2 of the trajectory and the snapshot at strain 0.01 hold step 5 of the source run: the runs
    from them are identical, start at its clock and strain, and continue its Lees–Edwards offset."""
    from_frame, from_snapshot = tmp_path / "frame", tmp_path / "snapshot"
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(from_frame), "--initial-state", f"{source / TRAJECTORY}:2"], capsys
    )
    assert status == 0, err
    snapshot = source / "snapshots" / "strain_0000.01.npz"
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(from_snapshot), "--initial-state", str(snapshot)], capsys
    )
    assert status == 0, err
    np.testing.assert_array_equal(_timeseries(from_frame), _timeseries(from_snapshot))
    start = SimulationState.load(snapshot)
    series = _timeseries(from_frame)
    assert series[0, 1] == start.time and series[0, 2] == start.strain == pytest.approx(0.01)
    result = read_json(from_frame / "result.json")
    assert abs(result["strain"] - (start.strain + CONFIG.strain)) < 1e-12  # --strain is added to the file's
    assert result["averaged_from_strain"] == pytest.approx(start.strain + CONFIG.transient)
    assert result["initial_state"]["source"] == f"{source / TRAJECTORY}:2"
    assert result["initial_state"]["strain"] == start.strain and result["steps"] == 10
    params = read_json(from_snapshot / "params.json")
    assert params["initial_state"]["digest"] == result["initial_state"]["digest"]
    # the first stress is the one the source run recorded at that state (same offset, same positions)
    source_series = _timeseries(source)
    row = int(np.flatnonzero(source_series[:, 2] == start.strain)[0])
    np.testing.assert_allclose(series[0, 12:], source_series[row, 12:], rtol=1e-6, atol=1e-9)
    # the same configuration from the other file continues the folder (same identity digest)
    status, _, err = run_cli([*RUN_ARGS, "--out", str(from_frame), "--initial-state", str(snapshot)], capsys)
    assert status == 0, err


def test_a_trajectory_restarts_from_its_last_frame_as_from_the_final_state(
    source: Path, tmp_path: Path, capsys
) -> None:
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(tmp_path / "gsd"), "--initial-state", str(source / TRAJECTORY)], capsys
    )
    assert status == 0, err
    final = source / "final_state.npz"
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(tmp_path / "npz"), "--initial-state", str(final)], capsys
    )
    assert status == 0, err
    np.testing.assert_array_equal(_timeseries(tmp_path / "gsd"), _timeseries(tmp_path / "npz"))
    a = SimulationState.load(tmp_path / "gsd" / "final_state.npz")
    assert abs(a.strain - 0.04) < 1e-12 and a.step == 10
    # the checkpoint of a finished run holds the state before its last (shortened) step: a run from it
    # starts one step earlier
    _, before, _, _ = load_checkpoint(source / "checkpoint.npz")
    assert before.step == 9 and before.strain < 0.02


def test_python_api_takes_a_state_a_file_or_an_initial_state(source: Path, tmp_path: Path) -> None:
    state = SimulationState.load(source / "final_state.npz")
    state.positions = state.positions + [0.0, 0.0, 3.0 * CONFIG.box_length]  # an image: wrapped on entry
    by_state = run_simulation(CONFIG, tmp_path / "state", progress=False, state=state)
    by_file = run_simulation(CONFIG, tmp_path / "file", progress=False, state=source / "final_state.npz")
    assert by_state["relative_viscosity"] == pytest.approx(by_file["relative_viscosity"], rel=1e-9)
    assert by_state["initial_state"]["source"] == "state"
    with pytest.raises(InitialStateError, match="state state holds 40 particles, but n_particles=64"):
        run_simulation(
            dataclasses.replace(CONFIG, n_particles=64), tmp_path / "n", progress=False, state=state
        )
    assert not (tmp_path / "n").exists()
    bad = state.copy()
    bad.positions[3, 1] = math.nan
    with pytest.raises(InitialStateError, match="positions must be finite"):
        run_simulation(CONFIG, tmp_path / "nan", progress=False, state=bad)
    with pytest.raises(ValueError, match="state must be a SimulationState, an InitialState or a file"):
        run_simulation(CONFIG, tmp_path / "x", progress=False, state=3)  # type: ignore[arg-type]
    assert not (tmp_path / "nan").exists() and not (tmp_path / "x").exists()


def test_the_field_and_rate_from_the_file(tmp_path: Path) -> None:
    """``--field-from-state`` takes the file's Mason number, direction and shear rate."""
    state = SimulationState.initial(np.zeros((40, 3)) + 1.0, 3.0, (1.0, 0.0, 0.0), 2.0)
    path = tmp_path / "s.npz"
    np.savez(path, box_length=CONFIG.box_length, **state.arrays())
    initial = read_initial_state(path)
    assert initial.has_field
    config = with_field_of(dataclasses.replace(CONFIG, near_field="none"), initial)
    assert (config.mason_number, config.field_direction, config.shear_rate) == (3.0, (1.0, 0.0, 0.0), 2.0)
    hand_made = tmp_path / "hand.npz"  # what a script writes: positions, box, strain
    np.savez(hand_made, positions=state.positions, box_length=CONFIG.box_length, strain=0.25)
    made = read_initial_state(hand_made)
    assert made.strain == 0.25 and made.time == 0.0 and not made.has_field
    with pytest.raises(InitialStateError, match="field_from_state: .* does not say which field"):
        with_field_of(CONFIG, made)


def _write_garbage(tmp_path: Path, source: Path) -> dict[str, Path]:
    files = {}
    files["empty"] = tmp_path / "empty.npz"
    files["empty"].write_bytes(b"")
    files["text"] = tmp_path / "notes.txt"
    files["text"].write_text("positions: none\n")
    files["truncated"] = tmp_path / "truncated.npz"
    files["truncated"].write_bytes((source / "final_state.npz").read_bytes()[:200])
    files["no box"] = tmp_path / "nobox.npz"
    np.savez(files["no box"], positions=np.zeros((40, 3)))
    files["no positions"] = tmp_path / "other.npz"
    np.savez(files["no positions"], g_r=np.ones(3))
    files["non-finite"] = tmp_path / "nan.npz"
    positions = SimulationState.load(source / "final_state.npz").positions.copy()
    positions[0, 0] = math.inf
    np.savez(files["non-finite"], positions=positions, box_length=CONFIG.box_length)
    files["other box"] = tmp_path / "bigger.npz"
    np.savez(files["other box"], positions=np.ones((40, 3)), box_length=CONFIG.box_length * 2 ** (1 / 3))
    return files


REFUSALS = [
    (["--initial-state", "{tmp}/missing.npz"], "--initial-state {tmp}/missing.npz: no such file"),
    (["--initial-state", "{tmp}"], "is a folder; give a file"),
    (["--initial-state", "{tmp}/empty.npz"], "empty.npz is empty"),
    (["--initial-state", "{tmp}/notes.txt"], "is neither a state file of a run (.npz"),
    (["--initial-state", "{tmp}/truncated.npz"], "cannot be read: truncated or damaged"),
    (["--initial-state", "{tmp}/nobox.npz"], "does not say its box"),
    (["--initial-state", "{tmp}/other.npz"], "is not a state file: it holds no positions"),
    (["--initial-state", "{tmp}/nan.npz"], "positions must be finite (1 particles"),
    (
        ["--initial-state", "{tmp}/bigger.npz"],
        "has a box of side L = 9.426986, but --phi=0.4 and --n-particles=40 give L = 7.482204 (they must "
        "agree to a relative 1e-06); the file's box is --phi 0.2 at --n-particles 40",
    ),
    (
        ["--initial-state", "{source}/final_state.npz", "--n-particles", "50"],
        "holds 40 particles, but --n-particles=50; the particle count is the run's: give --n-particles 40",
    ),
    (["--initial-state", "{source}/trajectory.gsd:9"], "has 5 frames: the frame must be in [0, 4]"),
    (["--initial-state", "{source}/final_state.npz:1"], "a frame (FILE:K) can only be chosen in a GSD file"),
    (["--field-from-state"], "--field-from-state needs --initial-state FILE"),
    (["--snapshot-every", "-1"], "--snapshot-every must be a strain > 0 (finite), got -1.0"),
    (["--snapshot-every", "0"], "--snapshot-every must be a strain > 0 (finite), got 0.0"),
    (["--trajectory-every", "nan"], "--trajectory-every must be a strain > 0 (finite), got nan"),
    (
        ["--trajectory-every", "1e-9"],
        "--trajectory-every=1e-09 would keep more than 100000 states over "
        "--strain=0.02: --trajectory-every must be in [2e-07, inf) (strain)",
    ),
    (["--snapshot-every", "x"], "argument --snapshot-every: invalid float value: 'x'"),
]


@pytest.mark.parametrize(("extra", "needle"), REFUSALS, ids=[r[1][:40] for r in REFUSALS])
def test_bad_input_exits_2_naming_the_flag(
    extra: list[str], needle: str, source: Path, tmp_path: Path, capsys
) -> None:
    _write_garbage(tmp_path, source)
    args = [a.format(tmp=tmp_path, source=source) for a in extra]
    out = tmp_path / "out"
    arguments = [*RUN_ARGS, "--out", str(out), *args]
    if "--n-particles" in args:  # the later flag wins
        arguments = [a for a in RUN_ARGS if a not in ("--n-particles", "40")] + ["--out", str(out), *args]
    status, _, err = run_cli(arguments, capsys)
    assert_refused(status, err, needle.format(tmp=tmp_path, source=source))
    assert not out.exists()  # refused before anything was written


def test_a_foreign_gsd_without_a_field_and_field_from_state(source: Path, tmp_path: Path, capsys) -> None:
    frame = make_frame(SimulationState.load(source / "final_state.npz"), CONFIG.box_length)
    frame.log = {}
    foreign = tmp_path / "foreign.gsd"
    append_frames(foreign, [frame])
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(tmp_path / "o"), "--initial-state", str(foreign), "--field-from-state"],
        capsys,
    )
    assert_refused(status, err, "--field-from-state: ")
    assert "give --mason, --field-direction and --shear-rate instead" in err
    # without --field-from-state it runs, from single-precision positions (clock 0, strain = the tilt)
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(tmp_path / "o"), "--initial-state", str(foreign)], capsys
    )
    assert status == 0, err
    with gsd.hoomd.open(str(foreign), "r") as trajectory:
        tilt = float(trajectory[0].configuration.box[3])
    assert read_json(tmp_path / "o" / "result.json")["initial_state"]["strain"] == pytest.approx(tilt)


def test_another_configuration_into_the_same_folder_is_refused(source: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(out), "--initial-state", f"{source / TRAJECTORY}:1"], capsys
    )
    assert status == 0, err
    digest = read_json(out / MANIFEST)["params"]["initial_state"]
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(out), "--initial-state", f"{source / TRAJECTORY}:3"], capsys
    )
    assert_refused(
        status, err, f"--out {out} holds a run with different parameters: --initial-state ('{digest}' there"
    )
    status, _, err = run_cli([*RUN_ARGS, "--out", str(out)], capsys)
    assert_refused(status, err, f"--initial-state ('{digest}' there, None requested)")
    status, _, err = run_cli([*RUN_ARGS, "--out", str(out), "--resume"], capsys)
    assert_refused(status, err, "--initial-state")
    # a plain run's folder refuses a start from a file, and --overwrite replaces it
    plain = tmp_path / "plain"
    assert run_cli([*RUN_ARGS, "--out", str(plain)], capsys)[0] == 0
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(plain), "--initial-state", f"{source / TRAJECTORY}:1"], capsys
    )
    assert_refused(status, err, "--initial-state (None there")
    status, _, err = run_cli(
        [*RUN_ARGS, "--out", str(plain), "--initial-state", f"{source / TRAJECTORY}:1", "--overwrite"], capsys
    )
    assert status == 0, err
    # --resume extends a run from a file, with the same file
    status, _, err = run_cli(
        [
            *RUN_ARGS,
            "--out",
            str(out),
            "--initial-state",
            f"{source / TRAJECTORY}:1",
            "--resume",
            "--strain",
            "0.03",
            "--quiet",
        ],
        capsys,
    )
    assert status == 0, err
    assert read_json(out / "result.json")["steps"] == 15


def test_checks_of_an_initial_state() -> None:
    initial = InitialState(np.zeros((40, 3)), 0.0, 0.0, CONFIG.box_length * (1 + 5e-7), "f")
    check_initial_state(initial, CONFIG)  # single-precision round-off of the box is accepted
    with pytest.raises(InitialStateError, match="has a box of side"):
        check_initial_state(dataclasses.replace(initial, box_length=CONFIG.box_length * 1.01), CONFIG)
    with pytest.raises(InitialStateError, match="time and strain must be finite"):
        check_initial_state(dataclasses.replace(initial, strain=math.inf), CONFIG)
