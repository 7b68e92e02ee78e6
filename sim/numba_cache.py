"""Numba's on-disk cache, keyed on the package source.

``@njit(cache=True)`` invalidates a cached kernel when *its own* file changes, but not when a kernel it
calls from another module changes: after an edit (or an upgrade) a caller can keep running stale
machine code. To make that impossible, the cache directory is named after a hash of every ``.py`` file in
``sim/``; any source change selects a fresh directory. A user-set ``NUMBA_CACHE_DIR`` is respected.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path


def source_digest(package_dir: Path) -> str:
    """SHA-256 (first 16 hex digits) of the relative paths and contents of all ``.py`` files below and of
    the data tables (``*/tables/*.txt``), which compiled kernels may bake in as constants."""
    digest = hashlib.sha256()
    files = list(package_dir.rglob("*.py")) + list(package_dir.glob("*/tables/*.txt"))
    for path in sorted(files):
        digest.update(path.relative_to(package_dir).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def configure_numba_cache() -> str | None:
    """Point numba's cache at ``$XDG_CACHE_HOME/dipsim/numba-<digest>``; return the directory used."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    import numba

    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "dipsim"
    directory = base / f"numba-{source_digest(Path(__file__).resolve().parent)}"
    numba.config.CACHE_DIR = str(directory)  # type: ignore[attr-defined]
    return str(directory)


REPRODUCIBLE_FASTMATH = {"nnan", "ninf", "nsz"}
"""The only LLVM fast-math flags ``sim``'s kernels may use: they let the compiler assume finite values
(dropping NaN/inf and signed-zero checks) and never change a finite result. The flags that do
(``reassoc``, ``contract``, ``arcp``, ``afn``, i.e. ``fastmath=True``) make freshly compiled and
cache-loaded machine code differ: measured, a run whose Ewald kernels were compiled in the same process
and the same run loading them from numba's cache parted in the fifth digit of the first step's stress
(N = 100, phi = 0.35, Mn = 1), breaking "same seed, same numbers" between a first run and its rerun.
With these flags both agree bit for bit (``tests/test_numba_cache.py``). The cost: the Ewald real-space
and k-space sums no longer vectorise their reductions (DIP far field about 2x slower at N = 500)."""
