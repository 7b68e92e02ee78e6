"""Make tests/ importable (dense_reference) and keep numba's cache warm between runs.

BLAS runs on one thread: the dense linear algebra in the tests is small, and on the 2-core CI machine
OpenBLAS threads fighting the numba kernels made the two-sphere tests ten times slower.
"""

import os
import sys
from pathlib import Path

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

sys.path.insert(0, str(Path(__file__).parent))
