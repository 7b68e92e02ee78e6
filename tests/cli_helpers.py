"""Helpers shared by the tests of ``python -m sim``'s subcommands."""

from __future__ import annotations

import pytest

from sim.runs.cli import main


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``main(["run", *args])`` in this process: (exit status, stdout, stderr)."""
    try:
        status = main(["run", *args])
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return status, captured.out, captured.err
