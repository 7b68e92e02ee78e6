"""Make tests/ importable (dense_reference) and keep numba's cache warm between runs."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
