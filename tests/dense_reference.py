"""Slow, obviously-correct dense references for the hydrodynamics tests (pure numpy, no numba).

Nothing here is optimised: every tensor is written out from the formulas of
``/work/shared/resistance_functions.md`` section 1 (Kim & Karrila 1991, section 11.3; Jeffrey 1992)
so that the fast sparse assembly and the neighbour list of the simulator can be compared with it.

Contents:
    * :func:`dense_grand_resistance` -- grand resistance tensor of N equal spheres (Stokes drag +
      any pair scalars), as dense arrays.
    * :func:`dense_pair_list` -- O(N^2) brute-force minimum-image pair search in a Lees-Edwards box.
    * :func:`load_reference_table` -- reader for ``reference_data/two_sphere_resistance_equal.txt``.

Units: radius ``a = 1``, viscosity ``eta = 1``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from sim.hydrodynamics.resistance_functions import SCALAR_NAMES

REFERENCE_TABLE_PATH = Path(__file__).parent / "reference_data" / "two_sphere_resistance_equal.txt"

# Dimensional prefactors of the scalars (Kim & Karrila 11.3 with a = eta = 1).
SCALE_A = 6.0 * np.pi
SCALE_B = 4.0 * np.pi
SCALE_C = 8.0 * np.pi
SCALE_G = 4.0 * np.pi
SCALE_H = 8.0 * np.pi
SCALE_M = 20.0 / 3.0 * np.pi

IDENTITY = np.eye(3)
LEVI_CIVITA = np.zeros((3, 3, 3))
LEVI_CIVITA[0, 1, 2] = LEVI_CIVITA[1, 2, 0] = LEVI_CIVITA[2, 0, 1] = 1.0
LEVI_CIVITA[0, 2, 1] = LEVI_CIVITA[2, 1, 0] = LEVI_CIVITA[1, 0, 2] = -1.0

# Identity on symmetric traceless rank-2 tensors:
# P_ijkl = (1/2)(d_ik d_jl + d_il d_jk) - (1/3) d_ij d_kl.
SYMMETRIC_TRACELESS_IDENTITY = (
    0.5 * (np.einsum("ik,jl->ijkl", IDENTITY, IDENTITY) + np.einsum("il,jk->ijkl", IDENTITY, IDENTITY))
    - np.einsum("ij,kl->ijkl", IDENTITY, IDENTITY) / 3.0
)


def tensor_a(x: float, y: float, d: np.ndarray) -> np.ndarray:
    """A_ij = X d_i d_j + Y (delta_ij - d_i d_j); also used for C. Shape (3, 3)."""
    dd = np.einsum("i,j->ij", d, d)
    return x * dd + y * (IDENTITY - dd)


def tensor_b(y: float, d: np.ndarray) -> np.ndarray:
    """B_ij = Y eps_ijk d_k. Shape (3, 3)."""
    return y * np.einsum("ijk,k->ij", LEVI_CIVITA, d)


def tensor_g(x: float, y: float, d: np.ndarray) -> np.ndarray:
    """G_ijk = X (d_i d_j - delta_ij/3) d_k + Y (d_i delta_jk + d_j delta_ik - 2 d_i d_j d_k); (3,3,3)."""
    ddd = np.einsum("i,j,k->ijk", d, d, d)
    x_part = ddd - np.einsum("ij,k->ijk", IDENTITY, d) / 3.0
    y_part = np.einsum("i,jk->ijk", d, IDENTITY) + np.einsum("j,ik->ijk", d, IDENTITY) - 2.0 * ddd
    return x * x_part + y * y_part


def tensor_h(y: float, d: np.ndarray) -> np.ndarray:
    """H_ijk = Y (eps_ikl d_l d_j + eps_jkl d_l d_i). Shape (3, 3, 3)."""
    return y * (np.einsum("ikl,l,j->ijk", LEVI_CIVITA, d, d) + np.einsum("jkl,l,i->ijk", LEVI_CIVITA, d, d))


def tensor_m(x: float, y: float, z: float, d: np.ndarray) -> np.ndarray:
    """M_ijkl of Kim & Karrila / Jeffrey 1992 (resistance_functions.md section 1). Shape (3,3,3,3)."""
    delta = IDENTITY
    dd = np.einsum("i,j->ij", d, d)
    dddd = np.einsum("i,j,k,l->ijkl", d, d, d, d)
    traceless = dd - delta / 3.0
    x_part = 1.5 * np.einsum("ij,kl->ijkl", traceless, traceless)
    # d_i delta_jl d_k + d_j delta_il d_k + d_i delta_jk d_l + d_j delta_ik d_l
    mixed = (
        np.einsum("i,jl,k->ijkl", d, delta, d)
        + np.einsum("j,il,k->ijkl", d, delta, d)
        + np.einsum("i,jk,l->ijkl", d, delta, d)
        + np.einsum("j,ik,l->ijkl", d, delta, d)
    )
    y_part = 0.5 * (mixed - 4.0 * dddd)
    z_part = 0.5 * (
        np.einsum("ik,jl->ijkl", delta, delta)
        + np.einsum("jk,il->ijkl", delta, delta)
        - np.einsum("ij,kl->ijkl", delta, delta)
        + np.einsum("ij,kl->ijkl", dd, delta)
        + np.einsum("ij,kl->ijkl", delta, dd)
        + dddd
        - mixed
    )
    return x * x_part + y * y_part + z * z_part


def pair_blocks(scalars: np.ndarray, d: np.ndarray) -> dict[str, list[list[np.ndarray]]]:
    """Label blocks [alpha][beta] (alpha, beta in {0, 1} for labels 1, 2) of one equal-sphere pair.

    Equal-sphere rules (resistance_functions.md section 1), all with the same ``d`` from 1 to 2:
    A22 = A11, A21 = A12 (also C, H, M); B22 = -B11, B21 = -B12 (also G).

    Args:
        scalars: float64 (22,), the scalars in ``SCALAR_NAMES`` order.
        d: float64 (3,), unit vector from sphere 1 to sphere 2.

    Returns:
        Dict with keys "A", "B", "C", "G", "H", "M", each a 2x2 nested list of dimensionless blocks.
    """
    v = dict(zip(SCALAR_NAMES, (float(value) for value in scalars), strict=True))
    a11 = tensor_a(v["XA11"], v["YA11"], d)
    a12 = tensor_a(v["XA12"], v["YA12"], d)
    b11 = tensor_b(v["YB11"], d)
    b12 = tensor_b(v["YB12"], d)
    c11 = tensor_a(v["XC11"], v["YC11"], d)
    c12 = tensor_a(v["XC12"], v["YC12"], d)
    g11 = tensor_g(v["XG11"], v["YG11"], d)
    g12 = tensor_g(v["XG12"], v["YG12"], d)
    h11 = tensor_h(v["YH11"], d)
    h12 = tensor_h(v["YH12"], d)
    m11 = tensor_m(v["XM11"], v["YM11"], v["ZM11"], d)
    m12 = tensor_m(v["XM12"], v["YM12"], v["ZM12"], d)
    return {
        "A": [[a11, a12], [a12, a11]],
        "B": [[b11, b12], [-b12, -b11]],
        "C": [[c11, c12], [c12, c11]],
        "G": [[g11, g12], [-g12, -g11]],
        "H": [[h11, h12], [h12, h11]],
        "M": [[m11, m12], [m12, m11]],
    }


def dense_grand_resistance(
    positions: np.ndarray,
    pairs: np.ndarray,
    separations: np.ndarray,
    scalar_fn: Callable[[float], np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Dense grand resistance tensor of N equal spheres: Stokes drag plus pairwise terms.

    Relation (Jeffrey 1992; resistance_functions.md section 1), with ``V = [U_1, Omega_1, U_2,
    Omega_2, ...]`` (6 per particle, particle-major) and ``V_inf`` the imposed flow at the
    particles::

        [F; T] = -R_FU . (V - V_inf) + R_FE : E_inf
        S      = -R_SU . (V - V_inf) + R_SE : E_inf

    F, T, S are the hydrodynamic force, torque and stresslet on each particle. Per pair (i, j) with
    ``d = (x_j - x_i)/|x_j - x_i|`` (i labelled 1, j labelled 2), blocks from :func:`pair_blocks`
    and ``U' = U - U_inf``, ``Omega' = Omega - Omega_inf``::

        F_a = -sum_b [6pi A^ab U'_b + 4pi Bt^ab Omega'_b] + sum_b 4pi Gt^ab : E
        T_a = -sum_b [4pi B^ab U'_b + 8pi C^ab Omega'_b] + sum_b 8pi Ht^ab : E
        S_a = -sum_b [4pi G^ab U'_b + 8pi H^ab Omega'_b] + sum_b (20/3)pi M^ab : E

    with ``Bt^ab_ij = B^ba_ji``, ``Gt^ab_ijk = G^ba_jki``, ``Ht^ab_ijk = H^ba_jki``. The isolated
    sphere adds ``6 pi I`` (force), ``8 pi I`` (torque) and ``(20/3) pi P`` (stresslet, ``P`` the
    identity on symmetric traceless tensors) on the diagonal. Since the same ``E_inf`` acts on
    every particle, ``R_FE`` and ``R_SE`` are summed over the partner label b; reciprocity then
    reads ``sum_a R_SU[a, i, j, m] = R_FE[m, i, j]``.

    Args:
        positions: float64 (N, 3); only N is used.
        pairs: int (M, 2), particle index pairs (i, j), i != j.
        separations: float64 (M, 3), ``x_j - x_i`` (minimum image) for each pair.
        scalar_fn: ``scalar_fn(s) -> float64 (22,)``, the pair scalars at ``s = r/a`` in
            ``SCALAR_NAMES`` order, WITHOUT the isolated-sphere part (nothing is subtracted here),
            e.g. ``lambda s: lubrication_scalars(s - 2.0, 0.5, 1e-3)``.

    Returns:
        ``(R_FU, R_FE, R_SU, R_SE)`` with shapes (6N, 6N), (6N, 3, 3), (N, 3, 3, 6N) and
        (N, 3, 3, 3, 3), float64. ``R_FE : E`` contracts the last two indices,
        ``R_SU . V`` the last index, ``R_SE[a] : E`` the last two.

    References:
        Jeffrey (1992) Phys. Fluids A 4, 16 (grand resistance relation);
        Kim & Karrila (1991) Microhydrodynamics, section 11.3 (tensor forms).
    """
    n = np.asarray(positions).shape[0]
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    separations = np.asarray(separations, dtype=np.float64).reshape(-1, 3)
    r_fu = np.zeros((6 * n, 6 * n))
    r_fe = np.zeros((6 * n, 3, 3))
    r_su = np.zeros((n, 3, 3, 6 * n))
    r_se = np.zeros((n, 3, 3, 3, 3))

    for a in range(n):
        r_fu[6 * a : 6 * a + 3, 6 * a : 6 * a + 3] += SCALE_A * IDENTITY
        r_fu[6 * a + 3 : 6 * a + 6, 6 * a + 3 : 6 * a + 6] += SCALE_C * IDENTITY
        r_se[a] += SCALE_M * SYMMETRIC_TRACELESS_IDENTITY

    for (i, j), sep in zip(pairs, separations, strict=True):
        r = float(np.linalg.norm(sep))
        d = sep / r
        blocks = pair_blocks(np.asarray(scalar_fn(r), dtype=np.float64), d)
        labels = (int(i), int(j))
        for alpha in range(2):
            a = labels[alpha]
            for beta in range(2):
                b = labels[beta]
                bt = blocks["B"][beta][alpha].T  # Bt^ab_ij = B^ba_ji
                gt = np.einsum("jki->ijk", blocks["G"][beta][alpha])  # Gt^ab_ijk = G^ba_jki
                ht = np.einsum("jki->ijk", blocks["H"][beta][alpha])  # Ht^ab_ijk = H^ba_jki
                r_fu[6 * a : 6 * a + 3, 6 * b : 6 * b + 3] += SCALE_A * blocks["A"][alpha][beta]
                r_fu[6 * a : 6 * a + 3, 6 * b + 3 : 6 * b + 6] += SCALE_B * bt
                r_fu[6 * a + 3 : 6 * a + 6, 6 * b : 6 * b + 3] += SCALE_B * blocks["B"][alpha][beta]
                r_fu[6 * a + 3 : 6 * a + 6, 6 * b + 3 : 6 * b + 6] += SCALE_C * blocks["C"][alpha][beta]
                r_fe[6 * a : 6 * a + 3] += SCALE_G * gt
                r_fe[6 * a + 3 : 6 * a + 6] += SCALE_H * ht
                r_su[a, :, :, 6 * b : 6 * b + 3] += SCALE_G * blocks["G"][alpha][beta]
                r_su[a, :, :, 6 * b + 3 : 6 * b + 6] += SCALE_H * blocks["H"][alpha][beta]
                r_se[a] += SCALE_M * blocks["M"][alpha][beta]
    return r_fu, r_fe, r_su, r_se


def dense_pair_list(
    positions: np.ndarray, box_length: float, shear_offset: float, cutoff: float
) -> tuple[np.ndarray, np.ndarray]:
    """Brute-force O(N^2) minimum-image pair search in a cubic Lees-Edwards box.

    Periodic images at ``y +/- L`` are shifted by ``+/- shear_offset`` in x (lattice vectors
    ``L x``, ``L y + shear_offset x``, ``L z``). Positions are first wrapped into the primary box
    ``[0, L)^3`` (a particle leaving through ``y = L`` re-enters at ``y = 0`` shifted by
    ``-shear_offset`` in x) and the offset is reduced to ``[-L/2, L/2)``; then the 27 images
    ``x_j + nx L + ny (shear_offset, L, 0) + nz L``, ``nx, ny, nz in {-1, 0, 1}``, of every j
    are checked, which contain the nearest one. For ``cutoff < L/2`` at most one image of j lies
    within the cut-off (every lattice vector is at least L long).

    Args:
        positions: float64 (N, 3).
        box_length: Side L of the cubic box.
        shear_offset: Current x shift of the image above the box (strain * L).
        cutoff: Centre-centre distance below which a pair is listed; must be < L/2.

    Returns:
        ``(pairs, separations)``: int64 (M, 2) with i < j, sorted lexicographically, and float64
        (M, 3) with ``separations[k] = x_j - x_i`` for the nearest image of j.

    Raises:
        ValueError: If ``cutoff`` is not in (0, L/2).
    """
    length = float(box_length)
    if not 0.0 < cutoff < 0.5 * length:
        raise ValueError(f"cutoff must be in (0, box_length/2) = (0, {0.5 * length}), got {cutoff}")
    offset = float(shear_offset) - length * np.floor(float(shear_offset) / length + 0.5)
    wrapped = np.array(positions, dtype=np.float64).reshape(-1, 3)
    crossings = np.floor(wrapped[:, 1] / length)
    wrapped[:, 1] -= crossings * length
    wrapped[:, 0] -= crossings * offset
    wrapped[:, 0] -= length * np.floor(wrapped[:, 0] / length)
    wrapped[:, 2] -= length * np.floor(wrapped[:, 2] / length)

    shifts = np.array(
        [
            [nx * length + ny * offset, ny * length, nz * length]
            for nx in (-1, 0, 1)
            for ny in (-1, 0, 1)
            for nz in (-1, 0, 1)
        ]
    )
    pair_rows: list[tuple[int, int]] = []
    separation_rows: list[np.ndarray] = []
    n = wrapped.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            candidates = wrapped[j] + shifts - wrapped[i]
            distances = np.linalg.norm(candidates, axis=1)
            nearest = int(np.argmin(distances))
            if distances[nearest] < cutoff:
                pair_rows.append((i, j))
                separation_rows.append(candidates[nearest])
    pairs = np.array(pair_rows, dtype=np.int64).reshape(-1, 2)
    separations = np.array(separation_rows, dtype=np.float64).reshape(-1, 3)
    return pairs, separations


def load_reference_table(path: str | Path = REFERENCE_TABLE_PATH) -> dict[str, np.ndarray]:
    """Read the exact equal-sphere resistance table (Townsend 2023; see reference_data/README.md).

    File columns: ``s_dash gamma XA YA YB XC YC XG YG YH XM YM ZM``, gamma 0 = self ("11"),
    gamma 1 = pair ("12").

    Args:
        path: Table file.

    Returns:
        Dict with key ``"s"`` (float64 (K,), increasing) and one float64 (K,) array per name in
        ``SCALAR_NAMES``.
    """
    lines = [line.split() for line in Path(path).read_text().splitlines()]
    lines = [fields for fields in lines if fields and not fields[0].startswith("#")]
    header = lines[0]
    if header[:2] != ["s_dash", "gamma"]:
        raise ValueError(f"{path}: unexpected header {header}")
    rows = np.array(lines[1:], dtype=np.float64)
    columns = header[2:]
    table: dict[str, np.ndarray] = {}
    self_rows = rows[rows[:, 1] == 0.0]
    pair_rows = rows[rows[:, 1] == 1.0]
    self_rows = self_rows[np.argsort(self_rows[:, 0])]
    pair_rows = pair_rows[np.argsort(pair_rows[:, 0])]
    if not np.array_equal(self_rows[:, 0], pair_rows[:, 0]):
        raise ValueError(f"{path}: self and pair rows are not given at the same distances")
    table["s"] = self_rows[:, 0]
    for column_index, family in enumerate(columns):
        table[f"{family[0]}{family[1]}11"] = self_rows[:, 2 + column_index]
        table[f"{family[0]}{family[1]}12"] = pair_rows[:, 2 + column_index]
    missing = set(SCALAR_NAMES) - set(table)
    if missing:
        raise ValueError(f"{path}: columns missing for {sorted(missing)}")
    return table
