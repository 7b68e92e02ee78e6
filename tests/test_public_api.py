"""dipenv and agents talk to the simulator only through names exported by sim/__init__.py."""

from __future__ import annotations

import ast
from pathlib import Path

import sim

ROOT = Path(__file__).resolve().parents[1]


def test_only_public_sim_names_are_used() -> None:
    offenders = []
    for package in ("dipenv", "agents"):
        for path in (ROOT / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("sim"):
                    if node.module != "sim" or any(a.name not in sim.__all__ for a in node.names):
                        offenders.append(f"{path.name}: from {node.module} import ...")
                if isinstance(node, ast.Import) and any(a.name.startswith("sim.") for a in node.names):
                    offenders.append(f"{path.name}: import of a private sim module")
    assert not offenders, offenders


def test_public_names_exist() -> None:
    for name in sim.__all__:
        assert hasattr(sim, name), name
