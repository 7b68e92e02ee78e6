"""Helpers shared by the tests of the agents' commands and of ``scripts/``: the tiny env ids, a script of
``scripts/`` loaded as a module, and a command's refusal (exit 2)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV = "dipenv/FieldMagnitudeTiny-v0"
TINY = "dipenv/ThickeningControlTiny-v0"


def load_script(name: str, cached: bool = False) -> Any:
    """``scripts/<name>.py`` as a module (the scripts are not a package), registered in ``sys.modules``
    under ``name`` (dataclasses and pickling look their module up there). A fresh module each call, unless
    ``cached``: then the one loaded before, if any."""
    if cached and name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def refused(capsys: pytest.CaptureFixture[str], main: Any, arguments: list[str]) -> str:
    """``main(arguments)`` exits 2 (a refusal); its stderr."""
    with pytest.raises(SystemExit) as exit_:
        main(arguments)
    err = capsys.readouterr().err
    assert exit_.value.code == 2, err
    return err
