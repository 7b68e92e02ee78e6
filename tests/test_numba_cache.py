"""The numba cache directory follows the package source, so stale kernels cannot be reused."""

from __future__ import annotations

from pathlib import Path

import sim
from sim.numba_cache import source_digest


def test_digest_changes_with_any_source_file(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    before = source_digest(tmp_path)
    assert source_digest(tmp_path) == before
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert source_digest(tmp_path) != before


def test_digest_changes_with_a_data_table(tmp_path: Path) -> None:
    """Kernels bake tables in as constants (sim/dipolophoresis/near_field.py): a table edit must select a
    fresh cache too."""
    (tmp_path / "pkg" / "tables").mkdir(parents=True)
    (tmp_path / "pkg" / "m.py").write_text("x = 1\n")
    table = tmp_path / "pkg" / "tables" / "t.txt"
    table.write_text("1 2\n")
    before = source_digest(tmp_path)
    table.write_text("1 3\n")
    assert source_digest(tmp_path) != before


def test_package_uses_a_source_keyed_cache() -> None:
    import os

    import numba

    if os.environ.get("NUMBA_CACHE_DIR"):  # the user's choice is respected
        assert sim.NUMBA_CACHE_DIR == os.environ["NUMBA_CACHE_DIR"]
        return
    assert numba.config.CACHE_DIR == sim.NUMBA_CACHE_DIR
    assert sim.NUMBA_CACHE_DIR.endswith(source_digest(Path(sim.__file__).parent))


def test_kernels_use_only_reproducible_fast_math_flags() -> None:
    """``fastmath=True`` (reassociation, contraction, approximate functions) makes freshly compiled and
    cache-loaded kernels give different numbers (measured: 1e-4 in the first step's stress); every
    ``fastmath=`` in ``sim`` must name :data:`sim.numba_cache.REPRODUCIBLE_FASTMATH`, whose flags cannot
    change a finite result."""
    import re

    from sim.numba_cache import REPRODUCIBLE_FASTMATH

    assert REPRODUCIBLE_FASTMATH <= {"nnan", "ninf", "nsz"}
    offending = []
    for path in Path(sim.__file__).parent.rglob("*.py"):
        for match in re.finditer(r"@n?jit\([^)]*fastmath\s*=\s*([^,)\s]+)", path.read_text()):
            if match.group(1) != "REPRODUCIBLE_FASTMATH":
                offending.append(f"{path.name}: fastmath={match.group(1)}")
    assert not offending, offending


_FAR_FIELD_SCRIPT = """
import sys
import numpy as np
from sim.dipolophoresis.ewald import dip_far_field, ewald_plan
rng = np.random.default_rng(3)
n, length = 60, 9.0
positions = rng.uniform(0.0, length, size=(n, 3))
outputs = []
for method in ("ewald", "spme"):
    plan = ewald_plan(length, n, 1e-6, method)
    outputs += dip_far_field(positions, length, 0.3, np.array([0.0, 1.0, 0.0]), 1.0, 1.0, plan)
np.save(sys.argv[1], np.concatenate([np.ravel(o) for o in outputs]))
"""


def test_fresh_and_cached_kernels_give_the_same_numbers(tmp_path: Path) -> None:
    """The Ewald far field compiled in a fresh cache and then loaded from it: bit-identical outputs.

    Compiles the Ewald and SPME kernels once in a fresh cache (about 20 s); with ``fastmath=True`` in
    ``ewald.py`` this test fails (checked).
    """
    import os
    import subprocess
    import sys

    import numpy as np

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    script = tmp_path / "far_field.py"
    script.write_text(_FAR_FIELD_SCRIPT)
    for name in ("fresh", "cached"):
        subprocess.run([sys.executable, str(script), str(tmp_path / f"{name}.npy")], env=env, check=True)
    fresh, cached = np.load(tmp_path / "fresh.npy"), np.load(tmp_path / "cached.npy")
    assert np.array_equal(fresh, cached)


def test_recorded_source_digest_covers_the_whole_package() -> None:
    """Issue 45 moved ``sim/io.py`` to ``sim/runs/io.py``: the digest that run files (``versions()``) and
    run-folder manifests record is still that of all of ``sim/``, not of the folder the writer lives in."""
    from sim.runs.folder import _source_digest

    whole = source_digest(Path(sim.__file__).parent)
    assert sim.versions()["sim_source"] == whole == _source_digest()
