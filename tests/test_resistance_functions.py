"""Tests of the equal-sphere resistance scalars, the model's lubrication functions and the dense reference.

Independent numbers: the exact two-sphere table ``reference_data/two_sphere_resistance_equal.txt``
(Townsend 2023; Lamb's-method rows from Wilson 2013; provenance in ``reference_data/README.md``),
the isolated-sphere Stokes drag (6 pi, 8 pi, 20/3 pi) and the leading-order squeeze/strain force of
``/work/shared/resistance_functions.md`` section 1. The tolerances against the table are bounds that
do not come from this code: the table's printing precision, the order of the first term the
near-contact forms leave out, and the neglected tail of the far-field series.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dense_reference import (
    REFERENCE_TABLE_PATH,
    SYMMETRIC_TRACELESS_IDENTITY,
    dense_grand_resistance,
    dense_pair_list,
    load_reference_table,
    pair_blocks,
    tensor_a,
    tensor_m,
)

from sim.hydrodynamics import resistance_functions as rf
from sim.hydrodynamics.resistance_functions import (
    DEFAULT_LUBRICATION_CUTOFF,
    DEFAULT_LUBRICATION_REGULARISATION,
    SCALAR_NAMES,
    far_field_scalars,
    lubrication_scalars,
    lubrication_taper,
    near_field_scalars,
    scalars_as_dict,
)

TABLE = load_reference_table()
# Functions that contain the isolated-sphere value (tend to 1 at large s).
SELF_FUNCTIONS = ("XA11", "YA11", "XC11", "YC11", "XM11", "YM11", "ZM11")
ISOLATED_VALUES = np.array([1.0 if name in SELF_FUNCTIONS else 0.0 for name in SCALAR_NAMES])
# Functions with a 1/xi or log(1/xi) term (all but X^C and Z^M).
SINGULAR_FUNCTIONS = tuple(name for name in SCALAR_NAMES if name[:2] not in ("XC", "ZM"))
DRAG_DIAGONAL_TWO_SPHERES = np.diag(np.tile([6.0 * np.pi] * 3 + [8.0 * np.pi] * 3, 2))


def table_row(s: float) -> np.ndarray:
    """Exact scalars at tabulated distance ``s`` in SCALAR_NAMES order."""
    index = int(np.flatnonzero(np.isclose(TABLE["s"], s, rtol=0.0, atol=1e-12))[0])
    return np.array([TABLE[name][index] for name in SCALAR_NAMES])


def random_unit_vector(rng: np.random.Generator) -> np.ndarray:
    vector = rng.normal(size=3)
    return vector / np.linalg.norm(vector)


def random_strain(rng: np.random.Generator) -> np.ndarray:
    """Random symmetric traceless 3x3 tensor."""
    matrix = rng.normal(size=(3, 3))
    matrix = 0.5 * (matrix + matrix.T)
    return matrix - np.trace(matrix) / 3.0 * np.eye(3)


def two_sphere_lubrication_matrix(separation: np.ndarray, scalar_fn) -> np.ndarray:
    """12x12 pair part of R_FU (drag diagonal removed) for one pair 0 -> 1."""
    r_fu, _, _, _ = dense_grand_resistance(
        np.zeros((2, 3)), np.array([[0, 1]]), separation[None, :], scalar_fn
    )
    return r_fu - DRAG_DIAGONAL_TWO_SPHERES


# --------------------------------------------------------------------------------------------------
# Names, indices, helpers
# --------------------------------------------------------------------------------------------------


def test_scalar_names_and_index_constants() -> None:
    """SCALAR_NAMES has the 22 names once each; every I_<name> constant is its position."""
    assert len(SCALAR_NAMES) == 22 == len(set(SCALAR_NAMES))
    for index, name in enumerate(SCALAR_NAMES):
        assert getattr(rf, f"I_{name}") == index
    values = np.arange(22, dtype=np.float64)
    labelled = scalars_as_dict(values)
    assert list(labelled) == list(SCALAR_NAMES)
    assert labelled["ZM12"] == 21.0
    with pytest.raises(ValueError, match="22"):
        scalars_as_dict(np.zeros(21))


def test_reference_table_loaded() -> None:
    """Table has 38 distances from 2.00001 to 4.5 and the spot values printed in section 3 at s = 4.5."""
    assert TABLE["s"].shape == (38,)
    assert TABLE["s"][0] == pytest.approx(2.00001) and TABLE["s"][-1] == pytest.approx(4.5)
    row = scalars_as_dict(table_row(4.5))
    assert row["XA11"] == 1.12811192 and row["ZM12"] == -0.00108382797


# --------------------------------------------------------------------------------------------------
# Near-field forms against the exact table
# --------------------------------------------------------------------------------------------------

NEAR_CONTACT_ROWS = [float(s) for s in TABLE["s"] if s <= 2.02 + 1e-12]


def printed_half_unit(values: np.ndarray) -> np.ndarray:
    """Half a unit in the 9th significant digit of each value: the rounding of the table's printout."""
    return 0.5 * 10.0 ** (np.floor(np.log10(np.abs(values))) - 8.0)


@pytest.mark.parametrize("s", NEAR_CONTACT_ROWS)
def test_near_field_matches_table_near_contact(s: float) -> None:
    """Rows 2.00001 <= s <= 2.02 were generated with the same corrected formulas (Townsend 2023), so this
    is a transcription check. Independent bound: the table prints 9 significant digits (half a unit of
    the 9th digit) and each form's O(1) constant is rounded to 8 decimals (5e-9); 1e-13 relative covers
    floating-point round-off. A wrong digit in a constant or a wrong rational coefficient exceeds it."""
    exact = table_row(s)
    bound = printed_half_unit(exact) + 5e-9 + 1e-13 * np.abs(exact)
    assert np.all(np.abs(near_field_scalars(s - 2.0) - exact) <= bound)


LAMB_ROWS_NEAR_CONTACT = [float(s) for s in TABLE["s"] if 2.02 + 1e-12 < s <= 2.1 + 1e-12]


@pytest.mark.parametrize("s", LAMB_ROWS_NEAR_CONTACT)
def test_near_field_remainder_is_order_xi(s: float) -> None:
    """Independent Lamb's-method values (Wilson 2013) just beyond the near-contact range (s = 2.025,
    2.05, 2.1). Independent bound: the forms keep Jeffrey & Onishi's expansion through the
    xi log(1/xi) term, so what they miss is the next term, c xi (+ O(xi^2 log xi)), whose coefficient
    they do not give. Like every coefficient of these expansions it is of order one; the bound assumes
    |c| <= 1/2 (the kept xi log(1/xi) coefficients are <= 0.21), i.e. |near - exact| <= xi / 2 for all
    22 functions. A wrong log coefficient would add about that coefficient error times log(1/xi) ~ 3,
    a wrong constant its error, independently of xi."""
    xi = s - 2.0
    error = np.abs(near_field_scalars(xi) - table_row(s))
    assert np.all(error <= 0.5 * xi), dict(zip(SCALAR_NAMES, error / xi, strict=True))


# --------------------------------------------------------------------------------------------------
# Far-field series against the exact table
# --------------------------------------------------------------------------------------------------

# The last two kept terms (coefficient, power of 1/s) of each truncated series of section 3; None where
# the series keeps only one term (X^C: leading terms only; ZM12 = -2 s^-5).
SERIES_LAST_TERMS: dict[str, tuple[tuple[float, int] | None, tuple[float, int]]] = {
    "XA11": ((320173 / 1024, 10), (4918189 / 4096, 12)),
    "XA12": ((76115 / 512, 9), (1178451 / 2048, 11)),
    "YA11": ((570017 / 65536, 8), (33678825 / 1048576, 10)),
    "YA12": ((4451395 / 262144, 9), (266862875 / 4194304, 11)),
    "YB11": ((1017825 / 32768, 9), (47478057 / 524288, 11)),
    "YB12": ((7087107 / 131072, 10), (336619227 / 2097152, 12)),
    "XC11": (None, (1.0, 6)),
    "XC12": (None, (1.0, 3)),
    "YC11": ((511755 / 16384, 10), (28793891 / 262144, 12)),
    "YC12": ((5945 / 4096, 9), (448833 / 65536, 11)),
    "XG11": ((101205 / 512, 9), (1886037 / 2048, 11)),
    "XG12": ((458859 / 1024, 10), (6614187 / 4096, 12)),
    "YG11": ((2475 / 2048, 9), (936387 / 32768, 11)),
    "YG12": ((81697 / 8192, 10), (10661481 / 131072, 12)),
    "YH11": ((14969 / 1024, 10), (467073 / 16384, 12)),
    "YH12": ((3539 / 256, 9), (196299 / 4096, 11)),
    "XM11": ((117183 / 1280, 10), (3045631 / 5120, 12)),
    "XM12": ((82001 / 640, 9), (1092033 / 2560, 11)),
    "YM11": ((2631 / 80, 10), (4435 / 256, 12)),
    "YM12": ((241 / 10, 9), (20021 / 320, 11)),
    "ZM11": ((3.0, 10), (21 / 4, 12)),
    "ZM12": (None, (2.0, 5)),
}


def neglected_tail(name: str, s: float) -> float:
    """Size of the terms a truncated far-field series leaves out, estimated from the series itself.

    The series in 1/s converge down to contact, s = 2 (where they become singular), so consecutive
    coefficients of the same parity grow by about 2^2 = 4: the first neglected term is about
    ``r = (2/s)^2`` times the last kept one (or ``r^2`` times the one before, when the last is
    unusually small, as for YM11), and the neglected terms add up to that over ``1 - r``.
    """
    previous, last = SERIES_LAST_TERMS[name]
    r = (2.0 / s) ** 2
    first_neglected = abs(last[0]) * s ** -last[1] * r
    if previous is not None:
        first_neglected = max(first_neglected, abs(previous[0]) * s ** -previous[1] * r * r)
    return first_neglected / (1.0 - r)


FAR_ROWS = [float(s) for s in TABLE["s"] if s >= 2.6 - 1e-12]


@pytest.mark.parametrize("s", FAR_ROWS)
def test_far_field_error_is_the_neglected_tail(s: float) -> None:
    """Independent bound: the truncation error of each series is its neglected tail
    (:func:`neglected_tail`), an estimate from the series' own last terms and radius of convergence,
    not from the table. At these low orders the coefficient growth is irregular (a ratio of 1 to 8
    between orders where 4 is the average), so the bound is 3 times the estimate, plus the table's
    printing precision (9 significant digits). This covers s = 2.6 to 4.5, where the series is 1e-2
    to 1e-6 off the exact values; a wrong sign or a lost digit in a term below the last exceeds it."""
    exact = table_row(s)
    error = np.abs(far_field_scalars(s) - exact)
    bound = np.array([3.0 * neglected_tail(name, s) for name in SCALAR_NAMES]) + printed_half_unit(exact)
    assert np.all(error <= bound), dict(zip(SCALAR_NAMES, error / bound, strict=True))


def test_near_and_far_forms_each_win_on_their_side() -> None:
    """Which asymptotic form is closer to the exact table: the near forms for all 22 functions at
    s <= 2.05, the far series for all 22 at s >= 2.6 (in between the winner depends on the function,
    which is why neither is used there in full; section 4)."""
    for s in TABLE["s"]:
        exact = table_row(float(s))
        near_error = np.abs(near_field_scalars(float(s) - 2.0) - exact)
        far_error = np.abs(far_field_scalars(float(s)) - exact)
        if s <= 2.05 + 1e-12:
            assert np.all(near_error < far_error), s
        if s >= 2.6 - 1e-12:
            assert np.all(far_error < near_error), s


# --------------------------------------------------------------------------------------------------
# The model's lubrication functions
# --------------------------------------------------------------------------------------------------


def test_lubrication_vanishes_at_and_beyond_cutoff() -> None:
    """f(xi) = 0 exactly for xi >= xi_cut; continuous there: |f(xi_cut (1 - 1e-9))| < 1e-6
    (largest slope 3/8 / (xi_cut + delta)^2 ~ 1.5 times a step of 5e-10 is ~1e-9)."""
    cut, delta = DEFAULT_LUBRICATION_CUTOFF, DEFAULT_LUBRICATION_REGULARISATION
    for xi in (cut, cut + 1e-12, 0.7, 2.5, 10.0):
        assert np.all(lubrication_scalars(xi, cut, delta) == 0.0)
    for delta_value in (0.0, delta):
        just_inside = lubrication_scalars(cut * (1.0 - 1e-9), cut, delta_value)
        assert np.max(np.abs(just_inside)) < 1e-6
    # Every function keeps the sign of its singular coefficient inside the cut-off.
    inside = lubrication_scalars(0.1, cut, delta)
    near = near_field_scalars(1e-8)
    for k, name in enumerate(SCALAR_NAMES):
        if name in SINGULAR_FUNCTIONS:
            assert np.sign(inside[k]) == np.sign(near[k]), name
        else:
            assert inside[k] == 0.0, name


def test_lubrication_leading_squeeze_behaviour() -> None:
    """(XA11 - XA12) xi -> 1/2 as xi -> 0 (squeeze film, Jeffrey & Onishi 1984), delta = 0.
    At xi = 1e-8 the log and shift terms contribute ~xi (0.45 ln(0.5/xi) + 1) ~ 2e-7: tolerance 1e-6."""
    xi = 1e-8
    values = scalars_as_dict(lubrication_scalars(xi, DEFAULT_LUBRICATION_CUTOFF, 0.0))
    assert (values["XA11"] - values["XA12"]) * xi == pytest.approx(0.5, abs=1e-6)
    assert (values["XG11"] - values["XG12"]) * xi == pytest.approx(0.75, abs=1e-6)
    assert (values["XM11"] + values["XM12"]) * xi == pytest.approx(0.3, abs=1e-6)


def test_lubrication_singular_parts_match_near_forms() -> None:
    """lubrication - near_field tends to a constant as xi -> 0 for every function (delta = 0): the
    1/xi and log(1/xi) coefficients coincide. The difference at xi = 1e-6 and 1e-7 must agree to
    1e-4; the known xi log(1/xi) terms (coefficients <= 0.21) change it by < 3e-6 between the two,
    and rounding of 1/xi ~ 1e7 gives ~1e-9."""
    cut = DEFAULT_LUBRICATION_CUTOFF
    first = lubrication_scalars(1e-6, cut, 0.0) - near_field_scalars(1e-6)
    second = lubrication_scalars(1e-7, cut, 0.0) - near_field_scalars(1e-7)
    np.testing.assert_allclose(first, second, rtol=0.0, atol=1e-4)
    # Without the singular terms the difference would grow like 1/xi or log(1/xi) (sanity of the test):
    assert abs(near_field_scalars(1e-6)[rf.I_XA11] - near_field_scalars(1e-7)[rf.I_XA11]) > 1e6


def test_lubrication_regularisation_and_taper() -> None:
    """Below xi_cut/2: f(xi; delta) equals the unshifted singular terms at xi + delta (1e-13); the taper
    is 1 there, 0 at the cut-off, 1/2 half way through the switch, and C1 (zero slope at both ends)."""
    cut, delta = DEFAULT_LUBRICATION_CUTOFF, DEFAULT_LUBRICATION_REGULARISATION
    for xi in (0.0, 1e-4, 0.03, 0.2):
        regularised = lubrication_scalars(xi, cut, delta)
        unregularised = lubrication_scalars(xi + delta, cut, 0.0)
        np.testing.assert_allclose(regularised, unregularised, rtol=1e-13)
    at_contact = scalars_as_dict(lubrication_scalars(0.0, cut, delta))
    expected = 0.25 / delta + 9.0 / 40.0 * np.log(1.0 / delta)
    assert at_contact["XA11"] == pytest.approx(expected, rel=1e-14)
    assert lubrication_taper(0.5 * cut, cut) == 1.0 and lubrication_taper(cut, cut) == 0.0
    assert lubrication_taper(0.75 * cut, cut) == pytest.approx(0.5, abs=1e-15)
    h = 1e-7
    assert abs(lubrication_taper(0.5 * cut + h, cut) - 1.0) < 1e-10
    assert abs(lubrication_taper(cut - h, cut)) < 1e-10


# --------------------------------------------------------------------------------------------------
# Positivity of the pair matrices
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("delta", [0.0, DEFAULT_LUBRICATION_REGULARISATION])
def test_lubrication_pair_matrix_positive_semidefinite(delta: float) -> None:
    """The singular-only pair matrix (12x12 R_FU minus drag) is PSD for all gaps and orientations.
    Tolerance: min eigenvalue >= -1e-9 max eigenvalue (round-off of eigh is ~1e-15 relative)."""
    rng = np.random.default_rng(20240611)
    cut = DEFAULT_LUBRICATION_CUTOFF
    for xi in np.logspace(-6.0, np.log10(0.49), 25):
        for _ in range(4):
            separation = (2.0 + xi) * random_unit_vector(rng)
            matrix = two_sphere_lubrication_matrix(
                separation, lambda s: lubrication_scalars(s - 2.0, cut, delta)
            )
            np.testing.assert_allclose(matrix, matrix.T, rtol=0.0, atol=1e-12 * np.abs(matrix).max())
            eigenvalues = np.linalg.eigvalsh(matrix)
            assert eigenvalues[0] >= -1e-9 * eigenvalues[-1], (xi, eigenvalues[0], eigenvalues[-1])


def test_two_sphere_resistance_with_drag_is_symmetric_positive_definite() -> None:
    """Drag + lubrication R_FU of two spheres: symmetric to 1e-12 relative and positive definite
    (smallest eigenvalue at least of order the drag, > 1 here since drag is 6 pi)."""
    rng = np.random.default_rng(7)
    for xi in (1e-5, 1e-3, 0.1, 0.45):
        separation = (2.0 + xi) * random_unit_vector(rng)
        r_fu, _, _, _ = dense_grand_resistance(
            np.zeros((2, 3)),
            np.array([[0, 1]]),
            separation[None, :],
            lambda s: lubrication_scalars(
                s - 2.0, DEFAULT_LUBRICATION_CUTOFF, DEFAULT_LUBRICATION_REGULARISATION
            ),
        )
        np.testing.assert_allclose(r_fu, r_fu.T, rtol=0.0, atol=1e-12 * np.abs(r_fu).max())
        assert np.linalg.eigvalsh(r_fu)[0] > 1.0


def test_near_field_constants_make_pair_matrix_indefinite() -> None:
    """Why the constants are dropped (module docstring): with the full near-contact forms minus the
    isolated values, the pair matrix at xi = 0.01 has the eigenvalue 6 pi (XA11 - 1 + XA12) =
    6 pi (0.99541917 - 1 - 0.35015349) = -0.3547 * 6 pi (collective translation along the line of
    centres). Check -0.36 < lambda_min / (6 pi) < -0.34."""
    rng = np.random.default_rng(3)
    separation = 2.01 * random_unit_vector(rng)
    matrix = two_sphere_lubrication_matrix(
        separation, lambda s: near_field_scalars(s - 2.0) - ISOLATED_VALUES
    )
    lowest = np.linalg.eigvalsh(matrix)[0] / (6.0 * np.pi)
    assert -0.36 < lowest < -0.34
    # The mode is the collective translation along d (both spheres, no rotation).
    d = separation / np.linalg.norm(separation)
    mode = np.concatenate([d, np.zeros(3), d, np.zeros(3)]) / np.sqrt(2.0)
    assert mode @ matrix @ mode / (6.0 * np.pi) == pytest.approx(lowest, rel=1e-9)


# --------------------------------------------------------------------------------------------------
# Dense reference sanity
# --------------------------------------------------------------------------------------------------


def test_tensor_forms_reduce_to_identities() -> None:
    """With all scalars 1 the A/C form is the identity and the M form is the identity on symmetric
    traceless tensors, for any d (checks the transcription of the tensor forms; exact to 1e-14)."""
    rng = np.random.default_rng(11)
    d = random_unit_vector(rng)
    np.testing.assert_allclose(tensor_a(1.0, 1.0, d), np.eye(3), atol=1e-14)
    np.testing.assert_allclose(tensor_m(1.0, 1.0, 1.0, d), SYMMETRIC_TRACELESS_IDENTITY, atol=1e-14)


def test_single_sphere_stokes_drag() -> None:
    """Isolated sphere: F = -6 pi U, T = -8 pi Omega, S = (20/3) pi E (Stokes; Batchelor 1970), 1e-13."""
    rng = np.random.default_rng(5)
    r_fu, r_fe, r_su, r_se = dense_grand_resistance(
        np.zeros((1, 3)), np.zeros((0, 2), dtype=np.int64), np.zeros((0, 3)), far_field_scalars
    )
    velocity = rng.normal(size=6)
    strain = random_strain(rng)
    force_torque = -r_fu @ velocity + np.einsum("mij,ij->m", r_fe, strain)
    stresslet = -np.einsum("aijm,m->aij", r_su, velocity) + np.einsum("aijkl,kl->aij", r_se, strain)
    np.testing.assert_allclose(force_torque[:3], -6.0 * np.pi * velocity[:3], rtol=1e-13)
    np.testing.assert_allclose(force_torque[3:], -8.0 * np.pi * velocity[3:], rtol=1e-13)
    np.testing.assert_allclose(stresslet[0], 20.0 / 3.0 * np.pi * strain, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("case", ["squeeze", "strain"])
def test_pair_force_matches_leading_order_formula(case: str) -> None:
    """Section 1: F1 = (6 pi/(4 xi)) [-n n.U1' + n n.U2' + 2 n (n.E.n)] at leading order.
    xi = 1e-4, delta = 0, lubrication scalars: the neglected log and shift terms are
    ~(9/40 ln(5e3) + 0.5)/(1/(4 xi)) ~ 1e-3 of the result, tolerance 1e-2 relative."""
    rng = np.random.default_rng(13)
    xi = 1e-4
    n = np.array([1.0, 0.0, 0.0])
    velocity = np.zeros(12)
    strain = np.zeros((3, 3))
    if case == "squeeze":
        velocity[0:3] = [0.5, 0.0, 0.0]  # relative squeeze only: U1 = -U2 along n
        velocity[6:9] = [-0.5, 0.0, 0.0]
    else:
        strain = random_strain(rng)
    r_fu, r_fe, _, _ = dense_grand_resistance(
        np.zeros((2, 3)),
        np.array([[0, 1]]),
        ((2.0 + xi) * n)[None, :],
        lambda s: lubrication_scalars(s - 2.0, DEFAULT_LUBRICATION_CUTOFF, 0.0),
    )
    force_torque = -r_fu @ velocity + np.einsum("mij,ij->m", r_fe, strain)
    u1, u2 = velocity[0:3], velocity[6:9]
    leading = 6.0 * np.pi / (4.0 * xi) * (-n * (n @ u1) + n * (n @ u2) + 2.0 * n * (n @ strain @ n))
    np.testing.assert_allclose(force_torque[0:3], leading, rtol=1e-2, atol=1e-2 * np.abs(leading).max())
    # Antisymmetric motion/strain of equal spheres: F2 = -F1 (exact up to round-off).
    np.testing.assert_allclose(force_torque[6:9], -force_torque[0:3], rtol=1e-12, atol=1e-9)


def random_cluster(rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Loose random cluster in free space with all pairs closer than 4.4 listed."""
    positions = np.zeros((count, 3))
    placed = 1
    while placed < count:
        candidate = positions[rng.integers(placed)] + rng.uniform(2.02, 2.8) * random_unit_vector(rng)
        if np.all(np.linalg.norm(positions[:placed] - candidate, axis=1) > 2.01):
            positions[placed] = candidate
            placed += 1
    pairs = [(i, j) for i in range(count) for j in range(i + 1, count)]
    pairs = [(i, j) for i, j in pairs if np.linalg.norm(positions[j] - positions[i]) < 4.4]
    pair_array = np.array(pairs, dtype=np.int64)
    return positions, pair_array, positions[pair_array[:, 1]] - positions[pair_array[:, 0]]


def far_field_pair_part(s: float) -> np.ndarray:
    """Far-field scalars minus the isolated sphere: nonzero in all 22 entries (exercises every tensor)."""
    return far_field_scalars(s) - ISOLATED_VALUES


def test_grand_resistance_symmetry_and_reciprocity() -> None:
    """R_FU = R_FU^T; reciprocity sum_a R_SU[a, i, j, m] = R_FE[m, i, j] (the same E acts on every
    particle, so R_FE is summed over the partner); sum_a R_SE[a] symmetric under (ij) <-> (kl).
    Relative 1e-12 (pure round-off)."""
    rng = np.random.default_rng(17)
    positions, pairs, separations = random_cluster(rng, 5)
    for scalar_fn in (far_field_pair_part, lambda s: lubrication_scalars(s - 2.0, 0.5, 1e-3)):
        r_fu, r_fe, r_su, r_se = dense_grand_resistance(positions, pairs, separations, scalar_fn)
        np.testing.assert_allclose(r_fu, r_fu.T, rtol=0.0, atol=1e-12 * np.abs(r_fu).max())
        transposed = np.einsum("aijm->mij", r_su)
        np.testing.assert_allclose(transposed, r_fe, rtol=0.0, atol=1e-12 * np.abs(r_fe).max())
        total_se = r_se.sum(axis=0)
        np.testing.assert_allclose(
            total_se, np.einsum("ijkl->klij", total_se), atol=1e-12 * np.abs(total_se).max()
        )


def test_label_swap_invariance() -> None:
    """Listing a pair as (j, i) with d -> -d must give the same tensors (the 'robust alternative' of
    section 1); checks the equal-sphere label rules B22 = -B11, G21 = -G12, H22 = H11, etc.
    Exact up to round-off, 1e-12 relative."""
    rng = np.random.default_rng(19)
    separation = 2.3 * random_unit_vector(rng)
    blocks = pair_blocks(far_field_pair_part(2.3), separation / 2.3)
    swapped = pair_blocks(far_field_pair_part(2.3), -separation / 2.3)
    for family in ("A", "B", "C", "G", "H", "M"):
        for alpha in range(2):
            for beta in range(2):
                np.testing.assert_allclose(
                    blocks[family][alpha][beta], swapped[family][1 - alpha][1 - beta], rtol=0.0, atol=1e-12
                )
    forward = dense_grand_resistance(
        np.zeros((2, 3)), np.array([[0, 1]]), separation[None, :], far_field_pair_part
    )
    backward = dense_grand_resistance(
        np.zeros((2, 3)), np.array([[1, 0]]), -separation[None, :], far_field_pair_part
    )
    for first, second in zip(forward, backward, strict=True):
        np.testing.assert_allclose(first, second, rtol=0.0, atol=1e-12 * np.abs(first).max())


# --------------------------------------------------------------------------------------------------
# Brute-force Lees-Edwards pair list
# --------------------------------------------------------------------------------------------------

# L = 10, offset 3: (0, 1) are close only through the sheared y boundary (without the offset their
# distance is |(-3, 0.8, 0)| = 3.1 > 2.5); (2, 3) across x; (4, 5) across z; (6, 7) across the
# y-x-z corner (image of 7 at (7.9 + 3 - 10, 0.2 + 10, 9.8 - 10)).
HAND_POSITIONS = np.array(
    [
        [7.0, 9.5, 5.0],
        [4.0, 0.3, 5.0],
        [9.8, 5.0, 5.0],
        [0.4, 5.5, 5.0],
        [5.0, 5.0, 9.9],
        [5.5, 5.0, 0.2],
        [1.0, 9.7, 0.1],
        [7.9, 0.2, 9.8],
    ]
)
HAND_PAIRS = np.array([[0, 1], [2, 3], [4, 5], [6, 7]])
HAND_SEPARATIONS = np.array([[0.0, 0.8, 0.0], [0.6, 0.5, 0.0], [0.5, 0.0, 0.3], [-0.1, 0.5, -0.3]])


def test_dense_pair_list_hand_configurations() -> None:
    """Hand-computed pairs and separations (x_j - x_i, nearest image), to 1e-12."""
    pairs, separations = dense_pair_list(HAND_POSITIONS, 10.0, 3.0, 2.5)
    np.testing.assert_array_equal(pairs, HAND_PAIRS)
    np.testing.assert_allclose(separations, HAND_SEPARATIONS, atol=1e-12)
    # The same configuration with the offset given modulo L and particle 1 unwrapped above the box
    # (at y + L it sits at x + offset).
    unwrapped = HAND_POSITIONS.copy()
    unwrapped[1] = [4.0 + 3.0, 10.3, 5.0]
    pairs, separations = dense_pair_list(unwrapped, 10.0, 13.0, 2.5)
    np.testing.assert_array_equal(pairs, HAND_PAIRS)
    np.testing.assert_allclose(separations, HAND_SEPARATIONS, atol=1e-12)
    # Without the offset pair (0, 1) is not listed; with offset -3 the partner of 0 sits at x = 0.
    pairs, _ = dense_pair_list(HAND_POSITIONS, 10.0, 0.0, 2.5)
    assert [0, 1] not in pairs.tolist()
    shifted = HAND_POSITIONS.copy()
    shifted[1] = [0.0, 0.3, 5.0]
    pairs, separations = dense_pair_list(shifted, 10.0, -3.0, 2.5)
    assert pairs.tolist()[0] == [0, 1]
    np.testing.assert_allclose(separations[0], [0.0, 0.8, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match="cutoff"):
        dense_pair_list(HAND_POSITIONS, 10.0, 3.0, 5.0)


def test_dense_pair_list_matches_wide_lattice_search() -> None:
    """Random configuration: same pairs and separations as a search over 5^3 sheared-lattice images
    (a different enumeration); separations to 1e-12."""
    rng = np.random.default_rng(23)
    length, offset, cutoff = 8.0, 2.7, 3.0
    positions = rng.uniform(0.0, length, size=(30, 3))
    pairs, separations = dense_pair_list(positions, length, offset, cutoff)
    lattice = np.array(
        [
            [nx * length + ny * offset, ny * length, nz * length]
            for nx in range(-2, 3)
            for ny in range(-2, 3)
            for nz in range(-2, 3)
        ]
    )
    expected_pairs, expected_separations = [], []
    for i in range(len(positions)):
        for j in range(i + 1, len(positions)):
            candidates = positions[j] + lattice - positions[i]
            norms = np.linalg.norm(candidates, axis=1)
            if norms.min() < cutoff:
                expected_pairs.append([i, j])
                expected_separations.append(candidates[np.argmin(norms)])
    assert len(expected_pairs) > 10
    np.testing.assert_array_equal(pairs, np.array(expected_pairs))
    np.testing.assert_allclose(separations, np.array(expected_separations), atol=1e-12)


SHARED_TABLE = Path(__file__).resolve().parents[2] / "shared" / "reference" / REFERENCE_TABLE_PATH.name


@pytest.mark.skipif(not SHARED_TABLE.is_file(), reason="no shared reference folder beside this checkout")
def test_reference_table_is_the_shared_copy() -> None:
    """tests/reference_data/README.md says the table is a byte-identical copy of the project's shared one
    (header included: it states the rows' accuracy, which the tolerances above follow)."""
    assert REFERENCE_TABLE_PATH.read_bytes() == SHARED_TABLE.read_bytes()
