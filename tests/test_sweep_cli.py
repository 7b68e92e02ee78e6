"""``python -m sim sweep``: comma lists, --seeds forms, --spec/--preset with command-line overrides, bad input
exiting 2 naming the flag (in ``run``'s style), a tiny sweep end to end, and exit status 1 when a point
fails."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import sim.runs.run
from sim import SimulationConfig, SimulationError
from sim.runs.cli import _sweep_configs, build_parser, main, parse_arguments, preset_names
from sim.runs.sweep import ERROR_FILE, MANIFEST

PREFIX = "python -m sim sweep: error: "
TINY = ["--n-particles", "40", "--strain", "0.02", "--workers", "1", "--quiet"]
"""Tiny points (10 steps of N = 40), run in this process."""


def sweep_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``main(["sweep", *args])`` in this process: (exit status, stdout, stderr)."""
    try:
        status = main(["sweep", *args])
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_comma_lists_and_seed_forms() -> None:
    args = build_parser().parse_args(
        ["sweep", "--phi", "0.15, 0.30", "--mason", "0.1,1,inf", "--n-particles", "40,64", "--mechanism",
         "dip,dep", "--seeds", "3", "--out", "x"]
    )  # fmt: skip
    assert args.phi == [0.15, 0.3] and args.mason == [0.1, 1.0, math.inf]
    assert args.n_particles == [40, 64] and args.mechanism == ["dip", "dep"] and args.seeds == [1, 2, 3]
    defaults = build_parser().parse_args(["sweep", "--out", "x"])
    assert defaults.phi == [0.4] and defaults.mason == [math.inf] and defaults.seeds == [1]
    assert defaults.workers == 2 and defaults.scheduler is None and defaults.strain == 30.0
    for text, seeds in (("1,4", [1, 4]), ("0-4", [0, 1, 2, 3, 4]), ("7-7", [7]), ("0,2,5-6", [0, 2, 5, 6])):
        assert build_parser().parse_args(["sweep", "--seeds", text]).seeds == seeds


def test_the_product_of_the_lists_is_the_sweep() -> None:
    args = parse_arguments(
        ["sweep", "--phi", "0.3,0.4", "--mason", "1,inf", "--seeds", "1,4", "--strain", "0.02", "--out", "x",
         "--n-particles", "64"]
    )  # fmt: skip
    configs = _sweep_configs(args)
    assert len(configs) == 8
    assert {(c.volume_fraction, c.mason_number, c.seed) for c in configs} == {
        (phi, mn, seed) for phi in (0.3, 0.4) for mn in (1.0, math.inf) for seed in (1, 4)
    }
    assert all(c.n_particles == 64 and c.strain == 0.02 for c in configs)


def test_spec_file_with_command_line_overrides(tmp_path: Path) -> None:
    spec = tmp_path / "sweep.yml"
    spec.write_text(
        "phi: [0.3, 0.45]\nmason: [0.5, .inf]\nn_particles: 64\nseeds: [5]\nstrain: 12\ntransient: 4\n"
        "workers: 1\nquiet: true\nout: from_spec\n"
    )
    args = parse_arguments(["sweep", "--spec", str(spec)])
    assert args.phi == [0.3, 0.45] and args.mason == [0.5, math.inf] and args.n_particles == [64]
    assert args.seeds == [5]  # a one-element list is that seed, not a count
    assert (args.strain, args.transient, args.workers, args.quiet, args.out) == (
        12.0,
        4.0,
        1,
        True,
        "from_spec",
    )
    args = parse_arguments(["sweep", "--strain", "20", "--spec", str(spec), "--phi", "0.2", "--out", "cli"])
    assert args.strain == 20.0 and args.phi == [0.2] and args.out == "cli"  # the command line wins
    assert args.mason == [0.5, math.inf]  # the rest from the spec


def test_presets_are_packaged_and_parse() -> None:
    assert {"small", "full"} <= set(preset_names())
    small = _sweep_configs(parse_arguments(["sweep", "--preset", "small", "--out", "x"]))
    assert {c.volume_fraction for c in small} == {0.30, 0.45}
    assert {c.mason_number for c in small} == {0.5, 1.0, 5.0, math.inf}
    full = _sweep_configs(parse_arguments(["sweep", "--preset", "full", "--out", "x"]))
    assert {c.volume_fraction for c in full} == {0.15, 0.30, 0.45, 0.50}
    assert {c.mason_number for c in full} == {0.1, 0.5, 1.0, 2.0, 5.0, 10.0, math.inf}
    assert {c.seed for c in full} == {1, 2, 3} and len(full) == 4 * 7 * 3
    override = parse_arguments(["sweep", "--preset", "small", "--strain", "0.5", "--transient", "0.25"])
    assert override.strain == 0.5 and override.transient == 0.25


BAD_INPUTS = [
    (["--phi", "0.3,0.7"], "--phi must be in [0.001, 0.6], got 0.7"),
    (["--phi", "0.3,abc"], "argument --phi: must be a comma list of numbers, got 'abc' in '0.3,abc'"),
    (["--phi", "0.3,0.3"], "argument --phi: '0.3' is listed twice in '0.3,0.3'"),
    (["--phi", "0.3,"], "argument --phi: must be a comma list of numbers, got ''"),
    (["--phi", "0.3001,0.3004"], "two points of the sweep would share the folder phi0.300_N40_Mninf_seed1"),
    (["--mason", "1,-2"], "argument --mason: must be in (0, inf], got '-2' (in the list '1,-2')"),
    (["--mason", "1,big"], "argument --mason: must be a number in (0, inf] or 'inf', got 'big'"),
    (
        ["--mechanism", "dip,both"],
        "argument --mechanism: invalid choice: 'both' (choose from dip, icep, dep)",
    ),
    (["--n-particles", "40,2.5"], "argument --n-particles: must be a comma list of integers, got '2.5'"),
    (["--n-particles", "40,5", "--phi", "0.5"], "--n-particles=5 is too small for --phi=0.5"),
    (["--seeds", "0"], "argument --seeds: a count of seeds must be in [1, 10000] (3 = seeds 1, 2, 3)"),
    (  # was an OverflowError
        ["--seeds", "99999999999999999999"],
        "argument --seeds: a count of seeds must be in [1, 10000] (3 = seeds 1, 2, 3), got '9999999999999",
    ),
    (  # was killed for memory
        ["--seeds", "0-99999999999"],
        "argument --seeds: at most 10000 seeds are allowed, got 100000000000 in '0-99999999999'",
    ),
    (  # blamed --phi
        ["--mason", "1,1.0000001", "--near-field", "none"],
        "two points of the sweep would share the folder phi0.400_N40_Mn1_seed1: they differ in --mason (1.0 "
        "and 1.0000001), which the folder name does not tell apart (--mason has 6 significant digits there)",
    ),
    (["--seeds", "4-2"], "argument --seeds: must be a count (3 = seeds 1, 2, 3), a list (1,4) or ranges"),
    (["--seeds", "x"], "argument --seeds: must be a count"),
    (["--workers", "0"], "argument --workers: must be an integer >= 1, got '0'"),
    (["--scheduler", "localhost:8786"], "argument --scheduler: must be a Dask scheduler address like tcp://"),
    (["--strain", "0"], "--strain must be > 0 for a run, got 0.0"),
    (["--strain", "0.002"], "no samples after the transient"),
    (["--transient", "5"], "--transient must be below --strain (0.02), got 5.0"),
    (["--dt", "0.5"], "--dt must be in (0.0, 0.05], got 0.5"),
    (["--mason", "inf", "--shear-rate", "0"], "--mason must be finite when --shear-rate = 0"),
    (["--field-direction", "1,2"], "argument --field-direction: must be three comma-separated"),
    (["--preset", "huge"], "--preset: no preset 'huge' (available: "),
    (["--preset", "small", "--spec", "x.yml"], "argument --spec: not allowed with argument --preset"),
    (["--spec", "/nonexistent/sweep.yml"], "--spec /nonexistent/sweep.yml: cannot be read"),
    (["--resume"], "--resume: --out {out} holds no run to continue"),  # issue 45: as in run
    (["--resume", "--overwrite"], "argument --overwrite: not allowed with argument --resume"),
    (["--seed", "3"], "unrecognized arguments: --seed 3"),  # issue 45: was taken as --seeds 3
    (["--shear-rate", "1e-9"], "argument --shear-rate: must be 0 (quiescent) or in [0.001, 1000]"),
]


@pytest.mark.parametrize(("args", "needle"), BAD_INPUTS, ids=[" ".join(a) for a, _ in BAD_INPUTS])
def test_bad_input_exits_2_naming_the_flag(args: list[str], needle: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    status, _, err = sweep_cli(["--out", str(out), *TINY, *args], capsys)
    assert status == 2, err
    assert err.startswith("usage: python -m sim sweep "), err
    assert PREFIX + needle.replace("{out}", str(out)) in err, err
    assert "volume_fraction" not in err and "n_particles" not in err and "mason_number" not in err, err
    assert not out.exists()  # refused before anything is written


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("phi: [0.3\n", "not valid YAML"),
        ("- 0.3\n", "must be a mapping of flags (without '--') to values"),
        (
            "volume_fraction: 0.3\n",
            "unknown key 'volume_fraction' (keys are sweep's flags without '--': phi,",
        ),
        ("quiet: 3\n", "quiet must be true or false, got 3"),
        ("phi: 0.9\n", "--phi must be in [0.001, 0.6], got 0.9"),
    ],
)
def test_bad_spec_exits_2(text: str, needle: str, tmp_path: Path, capsys) -> None:
    spec = tmp_path / "sweep.yml"
    spec.write_text(text)
    status, _, err = sweep_cli(["--spec", str(spec), "--out", str(tmp_path / "o"), *TINY], capsys)
    assert status == 2 and PREFIX in err and needle in err, err


def test_binary_spec_exits_2_naming_it(tmp_path: Path, capsys) -> None:
    spec = tmp_path / "sweep.yml"
    spec.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")  # was a UnicodeDecodeError
    status, _, err = sweep_cli(["--spec", str(spec), "--out", str(tmp_path / "o"), *TINY], capsys)
    assert status == 2 and PREFIX + f"--spec {spec}: not a YAML text file (not UTF-8 at byte 0)" in err, err
    assert not (tmp_path / "o").exists()


def test_missing_out_and_out_a_file(tmp_path: Path, capsys) -> None:
    status, _, err = sweep_cli(TINY, capsys)
    assert status == 2 and PREFIX + "the following arguments are required: --out" in err
    existing = tmp_path / "notes.txt"
    existing.write_text("keep me\n")
    status, _, err = sweep_cli(["--out", str(existing), *TINY], capsys)
    assert status == 2 and PREFIX + f"--out {existing} exists and is not a directory" in err
    assert existing.read_text() == "keep me\n"


def test_tiny_sweep_end_to_end_and_rerun(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sweep"
    args = ["--phi", "0.3,0.4", "--seeds", "1-2", "--out", str(out), *TINY]
    status, stdout, _ = sweep_cli([*args, "--json"], capsys)
    assert status == 0
    manifest = json.loads(stdout.strip().splitlines()[-1])
    assert manifest == json.loads((out / MANIFEST).read_text())
    assert [p["status"] for p in manifest["points"]] == ["finished"] * 4
    assert manifest["command"][:4] == ["python", "-m", "sim", "sweep"]
    assert manifest["arguments"]["phi"] == [0.3, 0.4] and manifest["arguments"]["seeds"] == [1, 2]
    names = [p["name"] for p in manifest["points"]]
    assert names == ["phi0.300_N40_Mninf_seed1", "phi0.300_N40_Mninf_seed2", "phi0.400_N40_Mninf_seed1",
                     "phi0.400_N40_Mninf_seed2"]  # fmt: skip
    params = json.loads((out / names[0] / "params.json").read_text())
    assert params["command"] == manifest["command"]
    status, stdout, _ = sweep_cli(args, capsys)
    assert status == 0 and "4 points: 4 reused" in stdout


def test_a_failed_point_gives_exit_status_1(tmp_path: Path, capsys, monkeypatch) -> None:
    original = sim.runs.run.run_simulation

    def fails_at_phi_04(config: SimulationConfig, *args: Any, **kwargs: Any) -> dict[str, Any]:
        if config.volume_fraction == 0.4:
            raise SimulationError("resistance solve did not converge (injected)")
        return original(config, *args, **kwargs)

    monkeypatch.setattr(sim.runs.run, "run_simulation", fails_at_phi_04)
    out = tmp_path / "sweep"
    status, stdout, err = sweep_cli(["--phi", "0.3,0.4", "--out", str(out), *TINY], capsys)
    assert status == 1
    assert "2 points: 1 finished, 1 failed" in stdout
    failed = out / "phi0.400_N40_Mninf_seed1"
    assert "phi0.400_N40_Mninf_seed1 failed: SimulationError: resistance solve" in err
    assert str(failed / ERROR_FILE) in err
    assert json.loads((failed / ERROR_FILE).read_text())["error"] == "SimulationError"
    assert (out / "phi0.300_N40_Mninf_seed1" / "result.json").exists()


def test_ctrl_c_with_one_worker_exits_130_and_leaves_the_point_pending(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    """Issue 23: Ctrl-C during ``sim sweep --workers 1`` recorded the running point as failed, because
    numba turned the interrupt inside a kernel into a ``SystemError``. A run now defers Ctrl-C to its next
    checkpoint and raises ``KeyboardInterrupt`` there (sim.runs.run; a real SIGINT is tested in test_cli); the
    sweep must pass that up: exit 130, the point still pending (no error.json), the finished one kept.
    (A real SIGINT to ``sim sweep --workers 1`` gave exactly this on 2026-12-03.)"""
    original = sim.runs.run.run_simulation

    def interrupted_at_phi_04(config: SimulationConfig, *args: Any, **kwargs: Any) -> dict[str, Any]:
        if config.volume_fraction == 0.4:
            raise KeyboardInterrupt
        return original(config, *args, **kwargs)

    monkeypatch.setattr(sim.runs.run, "run_simulation", interrupted_at_phi_04)
    out = tmp_path / "sweep"
    status, _, err = sweep_cli(["--phi", "0.3,0.4", "--workers", "1", "--out", str(out), *TINY], capsys)
    assert status == 130
    assert "interrupted; rerun the same command to resume" in err and "Traceback" not in err
    assert not (out / "phi0.400_N40_Mninf_seed1" / ERROR_FILE).exists()
    assert (out / "phi0.300_N40_Mninf_seed1" / "result.json").exists()


def test_process_exit_status() -> None:
    """The real entry point exits 2 on a bad list value, naming the flag."""
    proc = subprocess.run(
        [sys.executable, "-m", "sim", "sweep", "--out", "unused", "--phi", "0.3,0.7", "--n-particles", "40"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert PREFIX + "--phi must be in [0.001, 0.6], got 0.7" in proc.stderr


def test_the_sweep_folder_follows_the_run_folder_protocol(tmp_path: Path, capsys) -> None:
    """Issue 45: the sweep claims OUT (manifest.json, command ``sim sweep``) and every point folder is a
    ``sim run`` folder. A rerun may add points and lengthen --strain; other shared options and a shorter
    --strain (which would redo, and so delete, the longer runs) are refused naming the flag, unless
    --overwrite deletes the whole sweep; another command's folder, or an unknown one, is refused."""
    out = tmp_path / "sweep"
    args = ["--phi", "0.3", "--out", str(out), *TINY]
    assert sweep_cli(args, capsys)[0] == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["command"] == "sim sweep" and manifest["params"]["time_step"] == 0.002
    point = out / "phi0.300_N40_Mninf_seed1"
    assert json.loads((point / "manifest.json").read_text())["command"] == "sim run"
    result = (point / "result.json").read_bytes()
    status, stdout, _ = sweep_cli([*args, "--seeds", "1-2"], capsys)  # one more point
    assert status == 0 and "2 points: 1 reused, 1 finished" in stdout
    status, _, err = sweep_cli([*args, "--dt", "0.001"], capsys)
    assert status == 2 and PREFIX + f"--out {out} holds a run of sim sweep with other parameters: --dt" in err
    status, _, err = sweep_cli([*args, "--strain", "0.01"], capsys)
    assert status == 2 and "--strain=0.02 there, --strain=0.01 requested" in err, err
    assert (point / "result.json").read_bytes() == result  # nothing was touched
    status, stdout, _ = sweep_cli([*args, "--dt", "0.001", "--overwrite"], capsys)
    assert status == 0 and "1 points: 1 finished" in stdout
    assert not (out / "phi0.300_N40_Mninf_seed2").exists()  # the previous sweep is gone
    assert json.loads((out / "manifest.json").read_text())["params"]["time_step"] == 0.001
    status, _, err = sweep_cli(["--phi", "0.3", "--out", str(point), *TINY], capsys)
    assert status == 2 and PREFIX + f"--out {point} belongs to another command ('sim run'" in err
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("x")
    status, _, err = sweep_cli(["--phi", "0.3", "--out", str(mine), "--overwrite", *TINY], capsys)
    assert status == 2 and "is not empty (notes.txt) and holds no manifest.json" in err
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]


def test_a_point_folder_the_sweep_did_not_make_is_refused_before_any_work(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sweep"
    args = ["--phi", "0.3", "--out", str(out), *TINY]
    assert sweep_cli(args, capsys)[0] == 0
    stranger = out / "phi0.400_N40_Mninf_seed1"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("x")
    status, _, err = sweep_cli([*args[:1], "0.3,0.4", *args[2:]], capsys)
    assert status == 2 and f"the point folder {stranger} is not empty (notes.txt)" in err, err
    assert [p.name for p in stranger.iterdir()] == ["notes.txt"]


def test_a_sweep_written_before_manifests_is_adopted(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sweep"
    args = ["--phi", "0.3", "--out", str(out), *TINY]
    assert sweep_cli(args, capsys)[0] == 0
    (out / "manifest.json").unlink()
    (out / "phi0.300_N40_Mninf_seed1" / "manifest.json").unlink()
    status, stdout, _ = sweep_cli(args, capsys)
    assert status == 0 and "1 points: 1 reused" in stdout
    assert json.loads((out / "manifest.json").read_text())["command"] == "sim sweep"
