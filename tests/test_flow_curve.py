"""``sim.runs.flow_curve`` and ``python -m sim flow-curve``: holds, averages, resume, refusals."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import sim
import sim.runs.run
from sim import Simulation, SimulationConfig, run_simulation, summarise
from sim.runs.cli import build_parser, main
from sim.runs.flow_curve import MIN_HOLD_STEPS, FlowCurveSpec, read_rows, run_flow_curve

CONFIG = SimulationConfig(n_particles=64, volume_fraction=0.3, mason_number=2.0, seed=4)
SPEC = FlowCurveSpec(CONFIG, (0.5, 2.0), strain_per_rate=0.02, down=True)
"""Two rates up and the way back: holds at 0.5, 2, 0.5 (strain 0.02 each: 0.04, 0.01, 0.04 in time)."""


def _numbers(rows: list[dict]) -> list[dict]:
    """Rows without the wall time, NaN (no error estimate from two samples) as a string, floats as
    printed in the csv (10 significant digits), so that rows compare with ``==``."""
    return [
        {k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items() if k != "wall_seconds"}
        for row in rows
    ]


def test_holds_in_order_with_the_instantaneous_mason_number(tmp_path) -> None:
    rows = run_flow_curve(SPEC, tmp_path / "curve", progress=False)
    assert [(r["direction"], r["shear_rate"]) for r in rows] == [("up", 0.5), ("up", 2.0), ("down", 0.5)]
    assert [r["mason_number"] for r in rows] == [1.0, 4.0, 1.0]  # rate x Mn_ref
    for row in rows:
        assert row["averaged_to_strain"] - row["averaged_from_strain"] == pytest.approx(0.01, abs=0.004)
        # the shear stress is eta_r times the rate (eta_r = Sigma_xy / gammadot; same samples and weights)
        assert row["shear_stress"] == pytest.approx(row["relative_viscosity"] * row["shear_rate"], rel=1e-12)
        assert all(math.isfinite(row[k]) for k in ("relative_viscosity", "n1", "n2"))
    assert _numbers(read_rows(tmp_path / "curve" / "flow_curve.csv")) == _numbers(rows)
    assert (tmp_path / "curve" / "flow_curve.png").stat().st_size > 0


def test_the_first_hold_is_a_plain_run_at_that_rate(tmp_path) -> None:
    """The hold's average is the time average of a plain Simulation at rate 0.5 over the second half."""
    spec = FlowCurveSpec(CONFIG, (0.5,), strain_per_rate=0.02)
    rows = run_flow_curve(spec, tmp_path / "one", progress=False)
    plain = Simulation(SimulationConfig(**{**CONFIG.to_dict(), "mason_number": 2.0, "shear_rate": 0.5}))
    records = plain.advance_to(0.04)
    half = 0.5 * float(records.time[-1] + records.time_step[-1])
    expected = summarise(records, half)
    assert rows[0]["relative_viscosity"] == expected.relative_viscosity
    assert rows[0]["n1"] == expected.n1


def test_an_interrupted_curve_continues_bit_for_bit(tmp_path, monkeypatch) -> None:
    straight = run_flow_curve(SPEC, tmp_path / "straight", progress=False)
    calls = {"n": 0}
    original = Simulation.advance_to

    def interrupt_second_hold(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Simulation, "advance_to", interrupt_second_hold)
    with pytest.raises(KeyboardInterrupt):
        run_flow_curve(SPEC, tmp_path / "cut", progress=False)
    assert len(read_rows(tmp_path / "cut" / "flow_curve.csv")) == 1
    monkeypatch.setattr(Simulation, "advance_to", original)
    resumed = run_flow_curve(SPEC, tmp_path / "cut", progress=False)
    assert _numbers(resumed) == _numbers(straight)


def test_a_folder_with_another_curve_is_refused(tmp_path) -> None:
    run_flow_curve(FlowCurveSpec(CONFIG, (1.0,), strain_per_rate=0.01), tmp_path / "c", progress=False)
    other = r"holds a run of sim flow-curve with other parameters: rates=\[1.0\]"
    with pytest.raises(ValueError, match=other):
        run_flow_curve(FlowCurveSpec(CONFIG, (0.5,), strain_per_rate=0.01), tmp_path / "c", progress=False)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("{}")
    with pytest.raises(ValueError, match=r"is not empty \(notes.txt\) and holds no manifest.json"):
        run_flow_curve(SPEC, tmp_path / "other", progress=False)
    run_simulation(
        SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02), tmp_path / "run", progress=False
    )
    with pytest.raises(ValueError, match="belongs to another command .'sim run'"):
        run_flow_curve(SPEC, tmp_path / "run", progress=False)
    (tmp_path / "run" / "manifest.json").unlink()  # a run written before manifests
    with pytest.raises(ValueError, match=r"holds a run of sim run written before manifests \(params.json"):
        run_flow_curve(SPEC, tmp_path / "run", progress=False)


@pytest.mark.parametrize(
    "rates, strain, message",
    [
        ((), 1.0, "rates must list"),
        ((1.0, 0.5), 1.0, "rates must increase"),
        ((0.0, 1.0), 1.0, "rates must be finite numbers > 0"),
        ((1.0, math.inf), 1.0, "rates must be finite numbers > 0"),
        ((1.0,), 0.0, "strain_per_rate must be finite and > 0"),
        ((1.0,), math.nan, "strain_per_rate must be finite and > 0"),
        ((1.0, 1e20), 1.0, r"rates must be in \[0.001, 1000\] \(units gammadot_ref\), got 1e\+20"),
        ((1e-4, 1.0), 1.0, r"rates must be in \[0.001, 1000\]"),
        ((1.0,), 1e-9, "strain_per_rate=1e-09 is too short a hold: at the highest rate, 1, it lasts 1e-09"),
        ((1.0, 1000.0), 1.0, "strain_per_rate must be at least 8 for these rates"),
        ((0.001,), 1e6, "strain_per_rate=1e[+]06 is too long a hold"),
    ],
)
def test_bad_specs_name_the_parameter(rates, strain, message) -> None:
    with pytest.raises(ValueError, match=message):
        FlowCurveSpec(CONFIG, rates, strain)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--rates", "1,0.5"], "--rates must increase"),
        (
            ["--rates", "0,1"],
            "argument --rates: must be in [0.001, 1000] (units of the reference rate "
            "gammadot_ref; a flow curve has no rate-0 point), got '0'",
        ),
        (["--rates", "1,-1"], "argument --rates: must be in [0.001, 1000]"),
        (["--rates", "1,1e20"], "argument --rates: must be in [0.001, 1000]"),  # issue 45: was an IndexError
        (["--rates", "1,1e300"], "argument --rates: must be in [0.001, 1000]"),
        (["--strain-per-rate", "1e-9"], "--strain-per-rate=1e-09 is too short a hold"),  # was NaN rows
        (["--strain", "5"], "unrecognized arguments: --strain 5"),  # was taken as --strain-per-rate 5
        (["--ove"], "unrecognized arguments: --ove"),
        (["--resume", "--overwrite"], "argument --overwrite: not allowed with argument --resume"),
        (["--strain-per-rate", "0"], "--strain-per-rate must be finite and > 0"),
        (["--mason", "0"], "argument --mason: must be in (0, inf]"),
        (["--phi", "0.9"], "--phi must be in"),
    ],
)
def test_cli_bad_input_exits_2_naming_the_flag(tmp_path, capsys, arguments, message) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["flow-curve", "--n-particles", "64", "--phi", "0.3", "--out", str(tmp_path / "o"), *arguments])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_one_curve_per_field(tmp_path, capsys) -> None:
    out = tmp_path / "curves"
    code = main(
        [
            "flow-curve",
            "--n-particles",
            "64",
            "--phi",
            "0.3",
            "--mason",
            "2,inf",
            "--rates",
            "1,2",
            "--strain-per-rate",
            "0.016",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    for folder in ("Mn2", "Mninf"):
        assert len(read_rows(out / folder / "flow_curve.csv")) == 2
    combined = np.genfromtxt(out / "flow_curve.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert sorted(set(combined["mason_number_ref"].tolist())) == [2.0, math.inf]
    assert (out / "flow_curve.png").exists()


CLI = ["flow-curve", "--n-particles", "64", "--phi", "0.3", "--rates", "1,2", "--strain-per-rate", "0.016",
       "--quiet"]  # fmt: skip
"""Two holds of 8 and 4 steps of N = 64."""


def _cli(arguments: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        status = main([*CLI, *arguments])
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("masons", ["2,inf", "2,1"])
@pytest.mark.parametrize("legacy", [False, True], ids=["with manifest", "written before manifests"])
def test_several_fields_into_a_single_curve_folder_are_refused(tmp_path, capsys, masons, legacy) -> None:
    """Issue 45 (data loss): ``--mason 1,inf`` into a folder holding a single curve exited 0, overwrote its
    flow_curve.csv and left its params.json and checkpoint beside the new sub-curves. Refused (exit 2,
    the folder and --mason named), nothing touched; --overwrite replaces the whole folder."""
    out = tmp_path / "curve"
    assert _cli(["--mason", "2", "--out", str(out)], capsys)[0] == 0
    if legacy:
        (out / "manifest.json").unlink()
    before = _files(out)
    status, _, err = _cli(["--mason", masons, "--out", str(out)], capsys)
    assert status == 2, err
    assert f"--out {out} holds " in err and "--mason=[2.0] there" in err and "--overwrite" in err, err
    assert _files(out) == before
    assert _cli(["--mason", masons, "--out", str(out), "--overwrite"], capsys)[0] == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["manifest.json", "flow_curve.csv", "flow_curve.png", *(f"Mn{m}" for m in masons.split(","))]
    )
    status, _, err = _cli(["--mason", "2", "--out", str(out)], capsys)  # and back: refused as well
    assert status == 2 and ("--mason=[1.0, 2.0] there" in err or "--mason=[2.0, 'inf'] there" in err), err


def test_sim_run_overwrite_deletes_a_flow_curve(tmp_path, capsys) -> None:
    """Issue 45 (data loss): ``sim run --overwrite`` on a flow-curve folder left flow_curve.csv/.png beside
    the new run. Without --overwrite it is refused as another command's folder."""
    for legacy in (False, True):
        out = tmp_path / f"curve{legacy}"
        assert _cli(["--mason", "2", "--out", str(out)], capsys)[0] == 0
        if legacy:
            (out / "manifest.json").unlink()
        run = ["run", "--n-particles", "40", "--phi", "0.4", "--strain", "0.02", "--out", str(out), "--quiet"]
        with pytest.raises(SystemExit) as refused:
            main(run)
        err = capsys.readouterr().err
        assert refused.value.code == 2 and "sim flow-curve" in err, err
        assert main([*run, "--overwrite"]) == 0
        left = {p.name for p in out.iterdir()}
        assert not left & {"flow_curve.csv", "flow_curve.png"} and "result.json" in left
        assert json.loads((out / "params.json").read_text())["config"]["n_particles"] == 40


def test_a_no_field_curve_continues(tmp_path, capsys) -> None:
    """Issue 45: ``params.json`` held ``"inf"`` as a string, which never compared equal to the float, so a
    no-field curve could never be resumed (refused as another curve). Its identity round-trips."""
    no_field = dataclasses.replace(CONFIG, mason_number=math.inf)
    spec = FlowCurveSpec(no_field, (1.0, 2.0), strain_per_rate=0.016)
    first = run_flow_curve(spec, tmp_path / "c", progress=False)
    again = run_flow_curve(spec, tmp_path / "c", progress=False, resume=True)
    assert _numbers(again) == _numbers(first)
    assert _cli(["--mason", "inf", "--out", str(tmp_path / "cli")], capsys)[0] == 0
    status, _, err = _cli(["--mason", "inf", "--out", str(tmp_path / "cli"), "--resume"], capsys)
    assert status == 0, err
    (tmp_path / "c" / "manifest.json").unlink()  # a curve written before manifests: params.json compares
    assert _numbers(run_flow_curve(spec, tmp_path / "c", progress=False)) == _numbers(first)


def test_the_shortest_hold_allowed_gives_finite_rows(tmp_path) -> None:
    """The floor (MIN_HOLD_STEPS = 4 steps of --dt at the highest rate): every mean is finite (issue 45:
    ``--strain-per-rate 1e-9`` wrote NaN rows, then crashed in the log-scale plot)."""
    rates = (0.5, 2.0)
    shortest = MIN_HOLD_STEPS * CONFIG.time_step * rates[-1]
    with pytest.raises(ValueError, match="too short a hold"):
        FlowCurveSpec(CONFIG, rates, strain_per_rate=0.99 * shortest)
    spec = FlowCurveSpec(CONFIG, rates, strain_per_rate=shortest)
    rows = run_flow_curve(spec, tmp_path / "c", progress=False)
    for row in rows:
        assert row["samples"] >= 2 and row["steps"] >= MIN_HOLD_STEPS
        for key in ("relative_viscosity", "shear_stress", "n1", "n2", "averaged_from_strain"):
            assert math.isfinite(row[key]), (row["hold"], key)


def test_help_names_only_flags_that_exist(capsys) -> None:
    """Issue 45: ``flow-curve --help`` mentioned a ``--strain`` it does not have (in --dt's help)."""
    with pytest.raises(SystemExit):
        main(["flow-curve", "--help"])
    text = re.sub(r"-\n\s*", "-", capsys.readouterr().out)  # argparse wraps lines after a hyphen
    assert not re.search(r"--strain(?!-per-rate)", text), text
    assert "--resume" in text and "--overwrite" in text and "[0.001, 1000]" in text


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _into_directory(path: Path) -> None:
    path.unlink()
    path.mkdir()


def _foreign(path: Path) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, x=np.zeros(2))


def _pickled(path: Path) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, holds_done=np.array([{"a": 1}], dtype=object))


BAD_FILES = [
    ("checkpoint.npz", _truncate, "is not an .npz archive (or is truncated)"),
    ("checkpoint.npz", _into_directory, "is a directory (or not a regular file), not the curve's checkpoint"),
    ("checkpoint.npz", lambda p: p.write_bytes(b""), "is empty"),
    ("checkpoint.npz", _pickled, "cannot be read: its contents are not those of a checkpoint"),
    ("checkpoint.npz", _foreign, "is not a checkpoint of a run: it lacks 'holds_done'"),
    ("flow_curve.csv", _into_directory, "is a directory (or not a regular file), not the curve's"),
    ("flow_curve.csv", lambda p: p.write_text("a,b\n1,2\n"), "is not a flow curve's csv (its columns: a, b)"),
    ("flow_curve.csv", lambda p: p.write_bytes(b"\x89PNG\x00\xff"), "cannot be read as a flow curve"),
    ("flow_curve.csv", lambda p: p.write_text(p.read_text().replace("up", "down", 1)), "row 0 is the hold"),
    ("flow_curve.png", _into_directory, "is a directory (or not a regular file)"),
]


@pytest.mark.parametrize(("name", "spoil", "what"), BAD_FILES, ids=[f"{n}: {w}" for n, _, w in BAD_FILES])
def test_a_damaged_resume_file_exits_2_naming_it(tmp_path, capsys, name, spoil, what) -> None:
    """Issue 45: a truncated checkpoint, a directory in its place or in place of flow_curve.csv, a garbage
    checkpoint (numpy's allow_pickle advice) gave tracebacks on a rerun. Exit 2 naming the file and what is
    wrong, before any work, nothing changed."""
    out = tmp_path / "curve"
    assert _cli(["--mason", "2", "--out", str(out)], capsys)[0] == 0  # a finished curve: a rerun continues
    spoil(out / name)
    before = _files(out)
    for resume in ([], ["--resume"]):
        status, _, err = _cli(["--mason", "2", "--out", str(out), *resume], capsys)
        assert status == 2, err
        assert f"--out {out}: {out / name} {what}" in err, err
        assert "--overwrite" in err and "Traceback" not in err and "allow_pickle" not in err
        assert _files(out) == before
    assert _cli(["--mason", "2", "--out", str(out), "--overwrite"], capsys)[0] == 0
    assert len(read_rows(out / "flow_curve.csv")) == 2


def test_rows_after_the_last_checkpoint_are_redone(tmp_path) -> None:
    """Killed between writing the csv and the checkpoint, a curve has one row more than its checkpoint:
    the rerun drops it and runs that hold again, bit for bit."""
    straight = run_flow_curve(SPEC, tmp_path / "c", progress=False)
    cut = tmp_path / "cut"
    calls = {"n": 0}
    original = Simulation.advance_to

    def killed_before_the_third_checkpoint(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Simulation, "advance_to", killed_before_the_third_checkpoint)
        with pytest.raises(KeyboardInterrupt):
            run_flow_curve(SPEC, cut, progress=False)
    rows = (cut / "flow_curve.csv").read_text().splitlines()
    (cut / "flow_curve.csv").write_text("\n".join([*rows, rows[-1].replace(",up,", ",down,")]) + "\n")
    assert len(read_rows(cut / "flow_curve.csv")) == 3  # one row more than the checkpoint's 2 holds
    assert _numbers(run_flow_curve(SPEC, cut, progress=False)) == _numbers(straight)


def test_ctrl_c_exits_130_printing_only_what_was_written(tmp_path, capsys, monkeypatch) -> None:
    """Issue 45: Ctrl-C during one ``sim flow-curve`` gave exit 1 (``SystemError: CPUDispatcher(...)
    returned a result with an exception set``: the interrupt inside a compiled kernel) and printed the
    paths of files it had not written. Ctrl-C is deferred to the end of a chunk of steps (as in ``sim
    run``): exit 130, the finished holds kept and named, no other path printed; a rerun continues."""
    presses = {"after": 2}  # checks before Ctrl-C (one per hold and per chunk): after the first hold

    @contextlib.contextmanager
    def pressed_during_the_second_hold():
        def interrupted() -> bool:
            presses["after"] -= 1
            return presses["after"] < 0

        yield interrupted

    monkeypatch.setattr(sim.runs.run, "_deferred_interrupt", pressed_during_the_second_hold)
    out = tmp_path / "curve"
    status, stdout, err = _cli(["--mason", "2", "--out", str(out)], capsys)
    assert status == 130, err
    csv_path = out / "flow_curve.csv"
    assert f"interrupted; the finished holds are kept in {csv_path} (1 of 2 holds)" in err
    assert "Traceback" not in err and "SystemError" not in err and "flow_curve.png" not in stdout + err
    assert not (out / "flow_curve.png").exists()
    presses["after"] = 0  # at once: nothing finished
    status, _, err = _cli(["--mason", "2", "--out", str(tmp_path / "none")], capsys)
    assert status == 130 and "interrupted; no hold had finished; rerun the same command to continue" in err
    monkeypatch.undo()
    status, stdout, _ = _cli(["--mason", "2", "--out", str(out)], capsys)
    assert status == 0 and len(read_rows(csv_path)) == 2 and (out / "flow_curve.png").exists()


def test_ctrl_c_in_a_real_process_exits_130(tmp_path: Path) -> None:
    """SIGINT to ``python -m sim flow-curve`` while it steps: exit 130, a one-line note, no traceback (was
    exit 1 with numba's SystemError)."""
    out = tmp_path / "o"
    args = [*CLI[1:], "--rates", "1", "--strain-per-rate", "30", "--mason", "2", "--out", str(out)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim", "flow-curve", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not (out / "params.json").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        stdout, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "python -m sim flow-curve: interrupted; no hold had finished" in err
    assert "Traceback" not in err and "SystemError" not in err and stdout == ""


def test_every_parser_of_sim_refuses_prefixes() -> None:
    """Issue 45: argparse's prefix matching took ``flow-curve --strain 5`` as ``--strain-per-rate 5``.
    Every parser in sim/ has ``allow_abbrev=False`` (the command line's, and any other)."""
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert parser.allow_abbrev is False
    assert {name: sub.allow_abbrev for name, sub in commands.choices.items()} == dict.fromkeys(
        ("run", "sweep", "figures", "flow-curve", "movie"), False
    )
    root = Path(sim.__file__).parent
    for path in root.rglob("*.py"):
        text = path.read_text()
        for match in re.finditer(r"ArgumentParser\(", text):
            call = text[match.start() : text.find("\n)", match.start()) + 2]
            assert (
                "allow_abbrev=False" in call
                or "class _Parser(argparse.ArgumentParser)" in text[match.start() - 20 : match.end() + 5]
            ), f"{path.relative_to(root)}: an ArgumentParser without allow_abbrev=False"
