"""dipenv and agents talk to the simulator only through names exported by sim/__init__.py, and by its
public application subpackage ``sim.runs`` (the run-folder protocol: :data:`PUBLIC_SUBPACKAGES`).

The checker reads the source (``ast``) of every module of those packages and flags: ``import sim.x``
(any submodule), ``from sim.x import ...`` (but ``from sim.runs import name`` for a name in
``sim.runs.__all__``), ``from sim import name`` for a name not in ``sim.__all__``, and ``sim.name``
attribute access (after ``import sim`` or ``import sim as alias``) for such a name. Imports through
strings (``importlib.import_module("sim.x")``) are out of its scope.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import sim
import sim.runs

PUBLIC_SUBPACKAGES = {"sim.runs": set(sim.runs.__all__)}
"""Subpackages of ``sim`` whose exported names are public too."""

ROOT = Path(__file__).resolve().parents[1]
GUARDED_PACKAGES = ("dipenv", "agents")


def _sim_aliases(tree: ast.AST) -> set[str]:
    """Names bound to the ``sim`` package itself by ``import sim`` / ``import sim as alias``."""
    return {
        alias.asname or alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.Import)
        for alias in node.names
        if alias.name == "sim"
    }


def private_sim_uses(source: str, public: set[str] | None = None) -> list[str]:
    """Every use of ``sim`` beyond its public names in ``source``, as ``line N: what``."""
    public = set(sim.__all__) if public is None else public
    tree = ast.parse(source)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("sim."):
                    found.append(f"line {node.lineno}: import {alias.name}")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module in PUBLIC_SUBPACKAGES:
                for alias in node.names:
                    if alias.name not in PUBLIC_SUBPACKAGES[node.module]:
                        found.append(f"line {node.lineno}: from {node.module} import {alias.name}")
            elif node.module.startswith("sim."):
                found.append(f"line {node.lineno}: from {node.module} import ...")
            elif node.module == "sim":
                for alias in node.names:
                    if alias.name != "*" and alias.name not in public:
                        found.append(f"line {node.lineno}: from sim import {alias.name}")
    aliases = _sim_aliases(tree)
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in aliases
            and node.attr not in public
        ):
            found.append(f"line {node.lineno}: {node.value.id}.{node.attr}")
    return found


def test_only_public_sim_names_are_used() -> None:
    """The guard itself, over every module of dipenv and agents (both packages must exist)."""
    offenders = []
    scanned = 0
    for package in GUARDED_PACKAGES:
        directory = ROOT / package
        assert (directory / "__init__.py").is_file(), f"{package} moved: update GUARDED_PACKAGES"
        for path in sorted(directory.rglob("*.py")):
            scanned += 1
            offenders += [f"{path.relative_to(ROOT)} {use}" for use in private_sim_uses(path.read_text())]
    assert scanned >= len(GUARDED_PACKAGES)
    assert not offenders, offenders


@pytest.mark.parametrize(
    "source",
    [
        "import sim.stepper\n",
        "import sim.hydrodynamics.lubrication as lub\n",
        "import os, sim.config\n",
        "from sim.simulation import Simulation\n",
        "from sim.geometry import box\n",
        "from sim import _private\n",
        "from sim import Simulation, stepper\n",
        "from sim.runs import folder\n",
        "from sim.runs.folder import differing\n",
        "def f():\n    from sim import NUMBA_CACHE_DIR\n",
        "import sim\nsim.stepper.advance\n",
        "import sim as s\nx = s.config.MAX_STEPS\n",
    ],
)
def test_checker_flags_private_uses(source: str, tmp_path: Path) -> None:
    """Each kind of private use is found in a module written to disk, as the guard reads them."""
    module = tmp_path / "module.py"
    module.write_text(source)
    assert private_sim_uses(module.read_text()), source


@pytest.mark.parametrize(
    "source",
    [
        "import sim\n",
        "import sim\nsim.Simulation\n",
        "import sim as s\nconfig = s.SimulationConfig(n_particles=10, volume_fraction=0.1)\n",
        "from sim import Simulation, SimulationConfig, run_simulation\n",
        "from sim import *\n",
        "from sim.runs import MANIFEST, RunFolderError, claim\n",
        "import simulator.stepper\nfrom simple import x\n",  # other packages whose names start with sim
        "from . import sim\n",  # a relative import of a local module named sim
        "import numpy as np\nnp.sim\n",
    ],
)
def test_checker_accepts_public_uses(source: str) -> None:
    assert private_sim_uses(source) == [], source


def test_public_names_exist() -> None:
    for name in sim.__all__:
        assert hasattr(sim, name), name
