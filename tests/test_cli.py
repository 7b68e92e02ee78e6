"""Command-line contract: bad input exits 2 naming the flag (in ``run``'s style); --json prints one object
whose numbers are those of a direct ``Simulation`` run of the same configuration."""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import run_cli

import sim.runs.run
from sim import Simulation, SimulationConfig
from sim.runs.cli import _summary, main, with_flags
from sim.runs.io import from_json_ready

CONFIG = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=1)
"""The finished run shared by the tests below: 10 steps of N = 40 (well under a second once compiled)."""

RUN_ARGS = ["--phi", "0.4", "--n-particles", "40", "--mason", "inf", "--strain", "0.02", "--seed", "1"]

PREFIX = "python -m sim run: error: "
# Config field names the command line sets: none may reach a message unmapped.
FIELD_NAMES = re.compile(
    r"\b(n_particles|volume_fraction|mason_number|field_direction|shear_rate|transient_strain|time_step)\b"
)


def assert_refused(status: int, err: str, needle: str) -> None:
    """Exit 2, ``run``'s usage, one error line with the prefix, the flag named, no field name leaked."""
    assert status == 2, err
    assert err.startswith("usage: python -m sim run "), err
    assert PREFIX + needle in err, err
    assert not FIELD_NAMES.search(err), err
    assert "_--" not in err, err  # a flag spliced into a longer word ("transient_--strain")


RATE_RANGE = "argument --shear-rate: must be 0 (quiescent) or in [0.001, 1000]"

BAD_INPUTS = [
    (["--phi", "0.7"], "--phi must be in [0.001, 0.6], got 0.7"),
    (["--phi", "1e-9"], "--phi must be in [0.001, 0.6], got 1e-09"),  # was a MemoryError
    (["--phi", "0"], "--phi must be in [0.001, 0.6]"),
    (["--phi", "abc"], "argument --phi: invalid float value: 'abc'"),
    (["--n-particles", "1"], "--n-particles must be an integer in [2, 50000]"),
    (["--n-particles", "60000"], "--n-particles must be an integer in [2, 50000]"),
    (["--n-particles", "2.5"], "argument --n-particles: invalid int value: '2.5'"),
    (["--n-particles", "5", "--phi", "0.5"], "--n-particles=5 is too small for --phi=0.5"),
    (["--near-field-cutoff", "20"], "--near-field-cutoff must be in (2.5, 10.0], got 20.0"),
    (
        ["--near-field-cutoff", "5", "--n-particles", "64", "--phi", "0.45", "--mason", "1"],
        "--near-field-cutoff=5.0 needs a box side above 10.0 a",
    ),
    (["--near-field", "approx"], "argument --near-field: invalid choice: 'approx'"),
    (["--max-displacement", "0"], "--max-displacement must be in (0.0, 0.05], got 0.0"),
    (["--ewald-accuracy", "1"], "--ewald-accuracy must be in [1e-12, 0.01], got 1.0"),
    (["--strain", "-1"], "--strain must be > 0 for a run, got -1.0"),
    (["--strain", "0"], "--strain must be > 0 for a run, got 0.0"),  # was exit 0 with eta_r = nan
    (["--strain", "nan"], "--strain must be > 0 for a run, got nan"),
    (["--strain", "inf"], "--strain must be in [0.0, inf), got inf"),
    (["--strain", "0.002"], "no samples after the transient"),  # one step: nothing after the transient
    (["--strain", "0.05", "--transient", "0.049"], "no samples after the transient"),
    (["--dt", "0.5"], "--dt must be in (0.0, 0.05], got 0.5"),
    (["--dt", "0"], "--dt must be in (0.0, 0.05], got 0.0"),
    (["--dt", "1e-12"], "--dt=1e-12 is too small for --strain=30.0"),  # was a 3e13-step hang
    (  # was an effective hang: the adaptive step went to ~1e-11
        ["--mason", "1e-9"],
        "--mason=1e-09 is too strong a field for --strain=30: its velocity scale U0 = 1/--mason = 1e+09",
    ),
    (["--transient", "5", "--strain", "0.05"], "--transient must be below --strain (0.05), got 5.0"),
    (["--transient", "-1"], "--transient must be in [0.0, 30.0), got -1.0"),
    (["--seed", "-1"], "--seed must be a non-negative integer, got -1"),
    (["--field-direction", "1,2"], "argument --field-direction: must be three comma-separated"),
    (["--field-direction", "0,0,0"], "argument --field-direction: must be three comma-separated"),
    (["--mason", "-3"], "argument --mason: must be in (0, inf], got '-3'"),
    (["--mason", "nan"], "argument --mason: must be in (0, inf], got 'nan'"),
    (["--mason", "big"], "argument --mason: must be a number in (0, inf] or 'inf', got 'big'"),
    (["--mason", "inf", "--shear-rate", "0"], "--mason must be finite when --shear-rate = 0"),
    (["--shear-rate", "-2"], RATE_RANGE + " (units of the reference rate gammadot_ref), got '-2'"),
    (["--shear-rate", "nan"], RATE_RANGE),
    (["--shear-rate", "1e-300"], RATE_RANGE + " (units of the reference rate gammadot_ref), got '1e-300'"),
    (["--shear-rate", "1e-4"], RATE_RANGE),  # issue 45: eta_r = Sigma_xy / rate blows up below the floor
    (["--shear-rate", "2000"], RATE_RANGE),
    (["--over"], "unrecognized arguments: --over"),  # issue 45: no prefix matching (was --overwrite)
    (["--resum"], "unrecognized arguments: --resum"),
    (["--mechanism", "both"], "argument --mechanism: invalid choice: 'both'"),
    (["--bogus"], "unrecognized arguments: --bogus"),  # with run's usage, not the top-level one
]


@pytest.mark.parametrize(("args", "needle"), BAD_INPUTS, ids=[" ".join(a) for a, _ in BAD_INPUTS])
def test_bad_input_exits_2_naming_the_flag(args: list[str], needle: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    status, _, err = run_cli(["--out", str(out), *args], capsys)
    assert_refused(status, err, needle)
    assert not out.exists()  # refused before anything is written


def test_too_strong_a_field_names_the_range(tmp_path: Path, capsys) -> None:
    status, _, err = run_cli(["--out", str(tmp_path / "o"), "--mason", "1e-9", "--strain", "1"], capsys)
    assert_refused(status, err, "--mason=1e-09 is too strong a field for --strain=1")
    assert "--mason must be in [1.14e-06, inf] for this run (or shorten --strain)" in err, err


def test_no_samples_message_names_both_flags(tmp_path: Path, capsys) -> None:
    status, _, err = run_cli(["--out", str(tmp_path / "o"), "--strain", "0.002"], capsys)
    assert_refused(status, err, "no samples after the transient")
    assert "--strain=0.002" in err and "shorten --transient" in err and "--dt=0.002" in err


def test_missing_out(capsys) -> None:
    status, _, err = run_cli(["--phi", "0.3"], capsys)
    assert_refused(status, err, "the following arguments are required: --out")


def test_out_is_an_existing_file(tmp_path: Path, capsys) -> None:
    """Was a FileExistsError traceback with exit status 1."""
    existing = tmp_path / "notes.txt"
    existing.write_text("keep me\n")
    status, _, err = run_cli(["--out", str(existing), *RUN_ARGS], capsys)
    assert_refused(status, err, f"--out {existing} exists and is not a directory")
    assert existing.read_text() == "keep me\n"


def test_resume_without_checkpoint_leaves_no_folder(tmp_path: Path, capsys) -> None:
    out = tmp_path / "never-run"
    status, _, err = run_cli(["--out", str(out), *RUN_ARGS, "--resume"], capsys)
    assert_refused(status, err, f"--resume: --out {out} holds no run to continue")
    assert not out.exists()


def test_not_implemented_configuration_exits_2(tmp_path: Path, capsys, monkeypatch) -> None:
    """A configuration the simulator refuses with NotImplementedError (as finite Mason numbers were) exits
    2 with the simulator's message in flag names; nothing is written."""

    def refuse(config: SimulationConfig, state: object = None) -> None:
        raise NotImplementedError(
            f"mason_number={config.mason_number}: dipolophoresis (finite Mason number) is not implemented "
            "yet; only mason_number=inf (pure shear) is supported"
        )

    monkeypatch.setattr(sim.runs.run, "Simulation", refuse)
    out = tmp_path / "o"
    args = ["--out", str(out), "--phi", "0.4", "--n-particles", "100", "--mason", "2", "--strain", "0.02"]
    status, _, err = run_cli(args, capsys)
    assert_refused(status, err, "--mason=2.0: dipolophoresis (finite Mason number) is not implemented")
    assert "only --mason=inf (pure shear)" in err
    assert not out.exists()


def test_with_flags_maps_whole_names_only() -> None:
    """Field names become flags; the same words in prose, and longer names containing them, do not."""
    assert with_flags("transient_strain must be in [0.0, 0.05), got 5.0") == (
        "--transient must be in [0.0, 0.05), got 5.0"
    )
    assert with_flags("strain must be in [0.0, inf)") == "--strain must be in [0.0, inf)"
    assert with_flags("time_step=1e-12 is too small for strain=30.0: the strain already run") == (
        "--dt=1e-12 is too small for --strain=30.0: the strain already run"
    )
    prose = "seed must be >= 0; the seed of the packing"
    assert with_flags(prose) == "--" + prose
    untouched = "lubrication_cutoff and max_time_step stay"
    assert with_flags(untouched) == untouched
    assert with_flags("--strain must be > 0") == "--strain must be > 0"  # idempotent


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``python -m sim run ... --json`` of CONFIG, in this process: (output folder, stdout)."""
    out = tmp_path_factory.mktemp("cli") / "o"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        assert main(["run", *RUN_ARGS, "--out", str(out), "--json", "--quiet"]) == 0
    return out, stdout.getvalue()


def test_json_contract_matches_a_direct_simulation(finished_run: tuple[Path, str]) -> None:
    """The last stdout line is strict JSON; its numbers equal those of ``Simulation`` run directly with the
    same config and seed (bit for bit: a run is a pure function of its config)."""
    out, stdout = finished_run

    def reject(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token} in the --json line")

    result = from_json_ready(json.loads(stdout.strip().splitlines()[-1], parse_constant=reject))
    direct = Simulation(CONFIG)
    direct.advance_to(CONFIG.strain)
    rheology = direct.rheology()
    expected = {
        "relative_viscosity": rheology.relative_viscosity,
        "relative_viscosity_stderr": rheology.relative_viscosity_stderr,
        "n1": rheology.n1,
        "n1_stderr": rheology.n1_stderr,
        "n2": rheology.n2,
        "n2_stderr": rheology.n2_stderr,
        "strain": direct.state.strain,
        "steps": direct.state.step,
        "n_particles": 40,
        "volume_fraction": 0.4,
        "min_gap": float(direct.records.min_gap.min()),
        "averaged_from_strain": CONFIG.transient,
        "averaged_samples": rheology.samples,
    }
    for key, value in expected.items():
        got = result[key]
        assert got == value or (math.isnan(got) and math.isnan(value)), (key, got, value)
    assert result["steps"] >= CONFIG.n_steps and result["strain"] >= CONFIG.strain
    assert math.isnan(result["relative_viscosity_stderr"])  # 5 samples after the transient < 10 blocks
    for name, (eta, n1, n2) in rheology.contributions.items():
        assert result["contributions"][name] == {
            "relative_viscosity": eta,
            "n1": n1,
            "n2": n2,
            "particle_pressure": rheology.pressure_contributions[name],
        }
    assert result["particle_pressure"] == rheology.particle_pressure
    assert result["wall_seconds"] > 0.0
    params = json.loads((out / "params.json").read_text())
    assert params["config"] == CONFIG.to_dict()
    assert params["command"][:4] == ["python", "-m", "sim", "run"]


def test_summary_says_when_there_is_no_error_estimate(finished_run: tuple[Path, str]) -> None:
    out, _ = finished_run
    result = from_json_ready(json.loads((out / "result.json").read_text()))
    text = _summary(CONFIG, result, str(out))
    assert "nan" not in text
    assert "+/- n/a" in text and "need at least 10 samples after the transient" in text


def test_resume_with_other_parameters_names_them(finished_run, tmp_path: Path, capsys) -> None:
    """Was one ~1 KB line with both parameter dictionaries."""
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    args = [*RUN_ARGS, "--out", str(out), "--resume", "--seed", "2", "--dt", "0.001"]
    status, _, err = run_cli(args, capsys)
    assert_refused(status, err, f"--resume: --out {out} holds a run with different parameters")
    message = err.splitlines()[-1]
    listed = "--seed (1 there, 2 requested), --dt (0.002 there, 0.001 requested); "
    assert "different parameters: " + listed in message
    assert "only --strain may differ" in message
    assert len(message) < 300 + len(str(out))


def test_resume_to_a_shorter_strain_is_refused(finished_run, tmp_path: Path, capsys) -> None:
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    args = [*RUN_ARGS[:-4], "--strain", "0.01", "--seed", "1", "--out", str(out), "--resume"]
    status, _, err = run_cli(args, capsys)
    assert_refused(status, err, "--resume: the checkpoint in")
    assert "has already run past --strain=0.01" in err


def test_resume_extends_the_strain(finished_run, tmp_path: Path, capsys) -> None:
    """``--resume --strain 0.04`` on the 0.02 run continues it (tests/test_run.py checks the numbers)."""
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    args = [*RUN_ARGS[:-4], "--strain", "0.04", "--seed", "1", "--out", str(out), "--resume", "--json"]
    status, stdout, _ = run_cli(args, capsys)
    assert status == 0
    result = json.loads(stdout.strip().splitlines()[-1])
    assert result["strain"] >= 0.04 and result["averaged_from_strain"] == 0.02


def test_a_folder_holding_another_run_is_refused(finished_run, tmp_path: Path, capsys) -> None:
    """Was: ``--seed 2 --out DIR`` over another run's folder overwrote it with exit 0. Refused (exit 2,
    the folder and the differing flags named, files untouched); the same command again continues the run
    (the run-folder protocol, issue 45: here nothing is left to step, the results are rewritten
    unchanged); ``--overwrite`` replaces the run; ``--resume --overwrite`` is refused by argparse."""
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    before = json.loads((out / "result.json").read_text())
    status, _, err = run_cli([*RUN_ARGS[:-2], "--seed", "2", "--out", str(out)], capsys)
    assert_refused(status, err, f"--out {out} holds a run with different parameters: --seed (1 there, 2 ")
    assert "give --overwrite to delete its files" in err
    assert json.loads((out / "result.json").read_text()) == before
    status, stdout, _ = run_cli([*RUN_ARGS, "--out", str(out), "--json"], capsys)
    assert status == 0
    again = json.loads(stdout.strip().splitlines()[-1])
    assert {k: v for k, v in again.items() if k != "wall_seconds"} == {
        k: v for k, v in before.items() if k != "wall_seconds"
    }
    status, _, err = run_cli([*RUN_ARGS, "--out", str(out), "--resume", "--overwrite"], capsys)
    assert status == 2 and "--overwrite: not allowed with argument --resume" in err
    args = [*RUN_ARGS[:-2], "--seed", "2", "--out", str(out), "--overwrite", "--json"]
    status, stdout, _ = run_cli(args, capsys)
    assert status == 0 and json.loads(stdout.strip().splitlines()[-1])["seed"] == 2
    assert json.loads((out / "params.json").read_text())["config"]["seed"] == 2
    assert json.loads((out / "manifest.json").read_text())["params"]["seed"] == 2


def test_help_lists_overwrite(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "--overwrite" in capsys.readouterr().out


def _truncated(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _foreign(path: Path) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, x=np.zeros(3))


def _pickled(path: Path) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, config=np.array([{"a": 1}], dtype=object))


def _single_array(path: Path) -> None:
    with open(path, "wb") as handle:
        np.save(handle, np.zeros(3))


def _directory(path: Path) -> None:
    path.unlink()
    path.mkdir()


BAD_CHECKPOINTS = [
    (lambda p: p.write_bytes(b""), "is empty"),
    (_truncated, "is not an .npz archive (or is truncated)"),
    (lambda p: p.write_text("not a checkpoint\n"), "is not an .npz archive (or is truncated)"),
    (_foreign, "is not a checkpoint of a run: it lacks 'config' (it holds x)"),
    (_pickled, "cannot be read: its contents are not those of a checkpoint"),
    (_single_array, "is a single .npy array, not a checkpoint archive"),
    (_directory, "is a directory, not a checkpoint file"),
]


@pytest.mark.parametrize("resume", [True, False], ids=["--resume", "a plain rerun"])
@pytest.mark.parametrize(("spoil", "what"), BAD_CHECKPOINTS)
def test_resume_from_a_bad_checkpoint_exits_2_naming_it(
    spoil: Callable[[Path], None], what: str, resume: bool, finished_run, tmp_path: Path, capsys
) -> None:
    """Was: a traceback (numpy's allow_pickle message, BadZipFile, IsADirectoryError, KeyError). A plain
    rerun continues the run too (issue 45), so it validates the checkpoint the same way."""
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    checkpoint = out / "checkpoint.npz"
    spoil(checkpoint)
    status, _, err = run_cli([*RUN_ARGS, "--out", str(out), *(["--resume"] if resume else [])], capsys)
    how = "--resume" if resume else f"--out {out} holds this run (to continue)"
    assert_refused(status, err, f"{how}: {checkpoint} {what}")
    assert "; give --overwrite to delete that run and start afresh" in err
    assert "Traceback" not in err and "allow_pickle" not in err


def test_empty_out_is_refused(tmp_path: Path, capsys) -> None:
    """Was: ``--out ""`` wrote the run into the current folder."""
    status, _, err = run_cli([*RUN_ARGS, "--out", ""], capsys)
    assert_refused(status, err, "argument --out: must name a directory, got ''")
    for command in (["figures", str(tmp_path), "--out", ""], ["sweep", "--out", " ", *RUN_ARGS[:-2]]):
        with pytest.raises(SystemExit) as refused:
            main(command)
        assert refused.value.code == 2
        assert "error: argument --out: must name a directory" in capsys.readouterr().err


def test_interrupted_run_exits_130_keeping_its_checkpoint(
    finished_run, tmp_path: Path, capsys, monkeypatch
) -> None:
    """Was: Ctrl-C ended ``sim run`` with a traceback."""
    out = tmp_path / "copy"
    shutil.copytree(finished_run[0], out)
    before = (out / "checkpoint.npz").read_bytes()

    def interrupted(*args: object, **kwargs: object) -> float:
        raise KeyboardInterrupt

    monkeypatch.setattr(sim.runs.run, "_advance_with_checkpoints", interrupted)
    args = [*RUN_ARGS[:-4], "--strain", "0.04", "--seed", "1", "--out", str(out), "--resume"]
    status, _, err = run_cli(args, capsys)
    assert status == 130 and "Traceback" not in err
    assert f"interrupted; the last checkpoint, {out / 'checkpoint.npz'}, is kept: rerun with --resume" in err
    assert (out / "checkpoint.npz").read_bytes() == before


def test_ctrl_c_in_a_real_process_exits_130(tmp_path: Path) -> None:
    """SIGINT to ``python -m sim run`` once it is stepping: exit 130, a one-line note, no traceback."""
    out = tmp_path / "o"
    args = [*RUN_ARGS[:-4], "--strain", "30", "--seed", "1", "--out", str(out), "--quiet"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim", "run", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 120
        while not (out / "params.json").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "python -m sim run: interrupted;" in err and "Traceback" not in err


def test_process_exit_status() -> None:
    """The real entry point (``python -m sim``) exits 2 on bad input; everything else runs in-process."""
    proc = subprocess.run(
        [sys.executable, "-m", "sim", "run", "--out", "unused", "--phi", "0.7"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert PREFIX + "--phi must be in [0.001, 0.6], got 0.7" in proc.stderr
