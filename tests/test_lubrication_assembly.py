"""Block-sparse assembly of R_FU, R_FE, R_SU, R_SE against the dense reference (tests/dense_reference.py).

The dense reference is an independent, deliberately simple einsum implementation of the tensor forms of
resistance_functions.md §1; agreement is required to 1e-12 relative (pure floating-point reordering).
"""

from __future__ import annotations

import numpy as np
import pytest
from dense_reference import dense_grand_resistance, dense_pair_list

from sim.hydrodynamics.lubrication import (
    assemble_resistance,
    pair_scalars,
    pair_stresslet_sum,
    pair_stresslets,
    strain_forcing,
)
from sim.hydrodynamics.resistance_functions import lubrication_scalars
from sim.hydrodynamics.resistance_solver import block_matvec
from sim.hydrodynamics.stokes_drag import FORCE_DRAG, STRESSLET_DRAG, TORQUE_DRAG

XI_CUT = 0.5
DELTA = 1e-3


def _jittered_lattice(seed: int, spacing: float = 2.6, jitter: float = 0.29, n_side: int = 3):
    """A 27-particle configuration with many pairs inside the lubrication range and no overlaps."""
    rng = np.random.default_rng(seed)
    g = (np.arange(n_side) + 0.5) * spacing  # inside (0, L): no wrapping needed
    pos = np.array([[a, b, c] for a in g for b in g for c in g], dtype=float)
    pos += rng.uniform(-jitter, jitter, pos.shape)
    return pos, n_side * spacing


def _setup(seed: int, offset: float):
    """Offsets must be multiples of the lattice spacing so the sheared images do not overlap."""
    pos, length = _jittered_lattice(seed)
    pairs, seps = dense_pair_list(pos, length, offset, 2.0 + XI_CUT)
    pairs = pairs.astype(np.int64)
    scalars, units, gaps = pair_scalars(pairs, seps, XI_CUT, DELTA)
    assert gaps.min() > 0 and len(pairs) > 10
    dense = dense_grand_resistance(pos, pairs, seps, lambda s: lubrication_scalars(s - 2.0, XI_CUT, DELTA))
    return pos.shape[0], pairs, units, scalars, dense


def _shear():
    e = np.zeros((3, 3))
    e[0, 1] = e[1, 0] = 0.5
    return e


@pytest.mark.parametrize("seed,offset", [(0, 0.0), (1, 2.6), (2, -2.6)])
def test_sparse_equals_dense(seed: int, offset: float) -> None:
    n, pairs, units, scalars, (r_fu, r_fe, r_su, r_se) = _setup(seed, offset)
    diag, off = assemble_resistance(n, pairs, units, scalars, FORCE_DRAG, TORQUE_DRAG)
    rng = np.random.default_rng(seed + 10)
    v = rng.normal(size=(n, 6))
    scale = np.abs(r_fu).max()
    assert np.abs(block_matvec(diag, off, pairs, v).ravel() - r_fu @ v.ravel()).max() < 1e-12 * scale * 10

    e = rng.normal(size=(3, 3))
    e = 0.5 * (e + e.T) - np.trace(e) / 3 * np.eye(3)
    fe = strain_forcing(n, pairs, units, scalars, e)
    fe_dense = np.einsum("aij,ij->a", r_fe, e)
    assert np.abs(fe.ravel() - fe_dense).max() < 1e-12 * np.abs(fe_dense).max() * 10

    stresslets = pair_stresslets(n, pairs, units, scalars, v, e)
    dense_s = -np.einsum("aijb,b->aij", r_su, v.ravel()) + np.einsum("aijkl,kl->aij", r_se, e)
    dense_s -= STRESSLET_DRAG * e  # the isolated-sphere part is reported separately
    assert np.abs(stresslets - dense_s).max() < 1e-12 * np.abs(dense_s).max() * 10
    # the bulk sum the step uses, by its own per-pair formula, against the dense reference's sum
    total = pair_stresslet_sum(pairs, units, scalars, v, e)
    assert np.abs(total - dense_s.sum(axis=0)).max() < 1e-12 * np.abs(dense_s).max() * 10


def test_assembled_resistance_is_symmetric_positive_definite() -> None:
    """R_FU symmetric to 1e-13 relative; smallest eigenvalue >= the drag floor minus rounding.

    With singular-only pair terms each pair matrix is PSD, so lambda_min(R_FU) >= min(6pi, 8pi) = 6pi is
    a lower bound set by the Stokes drag diagonal (an independent number).
    """
    n, pairs, units, scalars, (r_fu, *_rest) = _setup(3, 0.4)
    assert np.abs(r_fu - r_fu.T).max() <= 1e-13 * np.abs(r_fu).max()
    assert np.linalg.eigvalsh(r_fu).min() >= FORCE_DRAG * (1 - 1e-10)


def test_pair_force_balance() -> None:
    """Strain forcing conserves momentum: the pair forces sum to zero (1e-12 of the largest)."""
    n, pairs, units, scalars, _ = _setup(4, 0.0)
    fe = strain_forcing(n, pairs, units, scalars, _shear())
    assert np.abs(fe[:, :3].sum(axis=0)).max() < 1e-12 * np.abs(fe).max()
