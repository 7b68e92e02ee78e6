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
