"""Command-line contract: bad input exits non-zero naming the parameter; --json prints one object."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from sim.cli import main


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--phi", "0.7"], "--phi must be in (0.0, 0.6]"),
        (["--phi", "0"], "--phi must be in (0.0, 0.6]"),
        (["--n-particles", "1"], "--n-particles must be an integer >= 2"),
        (["--n-particles", "5", "--phi", "0.5"], "--n-particles=5 is too small"),
        (["--strain", "-1"], "--strain must be in [0.0, inf)"),
        (["--field-direction", "1,2"], "--field-direction must be three"),
        (["--field-direction", "0,0,0"], "--field-direction must be three"),
        (["--mason", "-3"], "--mason must be in (0, inf]"),
        (["--mason", "2"], "dipolophoresis"),
        (["--dt", "0.5"], "--dt must be in (0.0, 0.05]"),
        (["--bogus"], "unrecognized arguments: --bogus"),
    ],
)
def test_bad_input_exits_nonzero_with_message(args, needle, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", "--out", str(tmp_path), *args])
    assert exc.value.code != 0
    assert needle in capsys.readouterr().err


def test_json_contract(tmp_path) -> None:
    """The exact command of the issue (short strain) prints one JSON object as its last line."""
    cmd = [
        sys.executable,
        "-m",
        "sim",
        "run",
        "--phi",
        "0.40",
        "--n-particles",
        "40",
        "--mason",
        "inf",
        "--strain",
        "0.02",
        "--seed",
        "1",
        "--out",
        str(tmp_path / "o"),
        "--json",
        "--field-direction",
        "0,1,0",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    last = proc.stdout.strip().splitlines()[-1]

    def reject(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token} in the --json line")

    result = json.loads(last, parse_constant=reject)  # strict JSON: no NaN / Infinity tokens
    for key in (
        "relative_viscosity",
        "relative_viscosity_stderr",
        "n1",
        "n1_stderr",
        "n2",
        "n2_stderr",
        "strain",
        "steps",
        "n_particles",
        "volume_fraction",
        "min_gap",
        "wall_seconds",
    ):
        assert key in result
    assert result["n_particles"] == 40 and result["steps"] == 10
    assert (tmp_path / "o" / "params.json").exists()
