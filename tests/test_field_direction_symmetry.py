"""Exact symmetries of the model under axis permutations, reflections and field reversal (issue 44).

Each test runs the full compiled step (resistance solve with lubrication and repulsion, Ewald sums of the
dipolophoretic far field, the exact near field, adaptive AB2, the Lees–Edwards wrap, Melrose–Ball overlap
removal) twice: run A from positions ``P`` with field direction ``e``, run B from the transformed positions
``T P`` (wrapped into ``[0, L)^3`` by the simulator's own Lees–Edwards rule, as its states are) with the
transformed field ``T e``. If ``T`` is a symmetry of the equations, B is the image of A step for step:

* **At rest** (``shear_rate = 0``, field on) the only other vector is ``e`` and the box is cubic with no
  offset, so every permutation of the axes, applied to positions and field together, is a symmetry. Odd
  permutations (swaps) are improper: angular velocities (pseudovectors) change sign as well.
* **Under shear** ``u_inf = gammadot y x_hat`` singles out the axes. Two maps keep it (and
  ``E_inf = (gammadot/2)(xy + yx)``, ``omega_inf = -(gammadot/2) z_hat``) unchanged:
  the mirror ``z -> -z`` (``M = diag(1, 1, -1)``) and the rotation by pi about the vorticity axis
  ``(x, y) -> (-x, -y)`` (``R = diag(-1, -1, 1)``). Both also map the sheared lattice ``a1 = L x``,
  ``a2 = delta x + L y``, ``a3 = L z`` onto itself at every strain (``M a3 = -a3``; ``R a1 = -a1``,
  ``R a2 = -a2``), so the Lees–Edwards offset ``delta`` keeps its value and sign; under ``R`` the image at
  ``y + L``, moving with ``+gammadot L x_hat``, maps onto the image at ``y' - L``, moving with
  ``-gammadot L x_hat``.
  (A reflection of ``x`` or of ``y`` alone flips ``u_inf`` and maps the lattice of offset ``delta`` onto
  that of ``-delta``: not a symmetry.) ``R`` rotates about the axis ``x = y = 0``, in the plane where
  ``u_inf`` vanishes. We apply ``R`` and let the simulator's Lees–Edwards wrap pick the representative
  images, so the periodic configuration is exactly ``R P``. Rotating about the box centre instead,
  ``(L - x, L - y)``, gives ``R P + a1 + a2 - delta x_hat``: the rotated configuration translated by
  ``-delta`` along the flow, which is a symmetry too, so that run stays at ``-delta x_hat`` from the
  rotated one (tested below). The sheared runs start at strain 0.25 (offset ``delta = L/4``, reached by a
  short sheared run), so the offset is far from 0 and from ``L/2``.
* **Field reversal** ``e -> -e``: dipolophoresis is quadratic in the field, so A and B are the same run.

Stresses transform as tensors, ``Sigma_B = T Sigma_A T^T`` (each contribution and every step; under
``M`` and ``R`` the ``xz`` and ``yz`` components flip, the rest are equal); the disturbance velocities
``V' = (U - u_inf, Omega - omega_inf)`` of the last solve transform as a vector and a pseudovector
(``Omega_B = det(T) T Omega_A``).

Why not bit for bit (except ``e -> -e``): B computes the same numbers in another order (separations
``L - z`` rounded, minimum images and ``|x|^2`` summed over permuted components, pair and Ewald sums in
another cell order), so the runs part by round-off, and near contact the model amplifies it. Overlap
removal holds gaps at ``overlap_min_gap = 1e-5 a`` (here it acts on 14 of the 20 steps at rest and on every
sheared step; asserted that it acts), where the repulsion ``~ F0 sigma / h`` changes by a relative ``dh/h``:
a rounding ``dh ~ 1e-16 * 2a`` of the centre distance becomes ``~2e-11`` of the force, of the repulsion and
lubrication stresses and of the velocities, and it compounds over the steps. Measured over 20 steps
(N = 64, phi = 0.4): positions agree to <= 3e-13 L (3.4e-13 L for the rotation about the box centre), each
stress contribution to <= 3.5e-10 of its largest value (lubrication and repulsion; the dipolophoretic
ones <= 2e-11), ``V'`` to <= 1.1e-10 of its largest value, the adaptive time steps to <= 4.5e-11 relative.
We hold positions to 2e-12 L (about 2e-11 a), stresses to 1e-8 of each contribution's scale, ``V'`` and the
steps to 1e-9: room for the compounding, and far below what a broken symmetry leaves. Controls that are
not symmetries (run once, not kept as tests): transforming the positions but not the field parts the
runs by 1.3e-2 to 1.6e-2 L after 20 steps and every field-dependent stress by O(1); ``y -> -y`` alone (at
strain ``-0.25``, where it maps the lattice) by 0.5 L and O(1) in the shear stresses; leaving out the
pseudovector sign of a swap misses ``V'`` by 0.49 of its scale; rotating about the box centre and
comparing without the ``-delta`` shift, by 0.25 L. Field reversal involves no reordering: ``e`` enters only
through products of two of its components (``e_a e_b``, ``c e`` with ``c = e . xh``), IEEE negation is exact
and rounding is symmetric, so every intermediate value is identical and the runs are bit-identical
(asserted exactly).

The default field direction and the validation of directions are checked at the end.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from sim import LeesEdwardsBox, Simulation, SimulationConfig, SimulationState, random_packing
from sim.observables.stress import STRESS_CONTRIBUTIONS

N_PARTICLES = 64
VOLUME_FRACTION = 0.4
"""Dense enough for lubrication, repulsion, the exact near field and overlap removal to act on every step;
L = 8.75 a > 2 r_c = 8 a (the exact near field needs the box wider than twice its cut-off)."""
SEED = 1
STEPS = 20
QUIESCENT_MASON = 0.25
"""At rest: U0 = 4 a gammadot_ref, fast enough that the adaptive step binds (dt down to ~5e-4)."""
SHEAR_MASON = 1.0
START_STRAIN = 0.25
"""Strain at which the sheared runs start (Lees–Edwards offset L/4)."""

POSITION_TOLERANCE = 2e-12
"""Largest minimum-image distance between mapped B and A after STEPS steps, in units of L."""
STRESS_TOLERANCE = 1e-8
"""Largest difference per stress contribution, relative to that contribution's largest component."""
VELOCITY_TOLERANCE = 1e-9
"""Largest difference of the last disturbance velocities V', relative to the largest component of V'."""
TIME_STEP_TOLERANCE = 1e-9
"""Largest relative difference of the adaptive time steps."""

GENERIC = (0.3, 0.8, -0.5)
"""A field direction with no zero component and no special angle (normalised by SimulationConfig)."""
PERMUTATIONS = {
    "swap y<->z": (0, 2, 1),
    "swap x<->y": (1, 0, 2),
    "swap x<->z": (2, 1, 0),
    "cyclic x<-y<-z": (1, 2, 0),
    "cyclic x<-z<-y": (2, 0, 1),
}
"""``perm`` maps the coordinates as ``x'_i = x_perm[i]`` (positions ``P[:, perm]``, field ``e[perm]``)."""

MIRROR_Z = np.diag([1.0, 1.0, -1.0])
ROTATION_Z = np.diag([-1.0, -1.0, 1.0])


def _config(direction, shear_rate: float, mason_number: float) -> SimulationConfig:
    return SimulationConfig(
        n_particles=N_PARTICLES,
        volume_fraction=VOLUME_FRACTION,
        mason_number=mason_number,
        field_direction=tuple(float(c) for c in direction),
        shear_rate=shear_rate,
        strain=1.0,
        seed=SEED,
    )


BOX_LENGTH = _config((0.0, 1.0, 0.0), 1.0, 1.0).box_length


@functools.cache
def _packing() -> np.ndarray:
    return random_packing(N_PARTICLES, VOLUME_FRACTION, SEED)


@functools.cache
def _sheared_start() -> tuple[np.ndarray, float]:
    """Positions after shearing the packing to START_STRAIN (field along y): a configuration in which the
    strained lattice's images are consistent (no pair across y = 0 or L overlaps at this offset)."""
    config = _config((0.0, 1.0, 0.0), 1.0, SHEAR_MASON)
    sim = Simulation(config, SimulationState.initial(_packing(), SHEAR_MASON, config.field_direction, 1.0))
    sim.advance_to(START_STRAIN)
    return sim.state.positions.copy(), sim.state.strain


def _run(positions: np.ndarray, direction, shear_rate: float, mason_number: float, strain: float = 0.0):
    """STEPS steps from rest (first step Euler) at ``strain``; returns the Simulation."""
    config = _config(direction, shear_rate, mason_number)
    state = SimulationState.initial(positions, mason_number, config.field_direction, shear_rate)
    state.strain = strain
    state.time = strain
    sim = Simulation(config, state)
    sim.advance(STEPS)
    return sim


@functools.cache
def _quiescent_reference(direction: tuple[float, float, float]) -> Simulation:
    return _run(_packing(), direction, 0.0, QUIESCENT_MASON)


@functools.cache
def _sheared_reference(direction: tuple[float, float, float]) -> Simulation:
    positions, strain = _sheared_start()
    return _run(positions, direction, 1.0, SHEAR_MASON, strain)


def _transform(positions: np.ndarray, matrix: np.ndarray, strain: float) -> np.ndarray:
    """``matrix`` applied to every centre, wrapped into [0, L)^3 by the simulator's Lees–Edwards rule."""
    wrapped, _ = LeesEdwardsBox(BOX_LENGTH, strain).wrap(positions @ matrix.T)
    return wrapped


def _deviations(a: Simulation, b: Simulation, matrix: np.ndarray) -> dict[str, float]:
    """How far run B is from the image of run A under the orthogonal ``matrix`` (see module docstring).

    Returns the largest minimum-image distance of the final positions (units L), per stress contribution
    the largest difference over all steps relative to the contribution's largest component (contributions
    that vanish in A must vanish exactly in B: reported as 0 or inf), the largest difference of the last
    disturbance velocities relative to their largest component, and of the time steps (relative).
    """
    box = LeesEdwardsBox(BOX_LENGTH, a.state.strain)
    mapped = a.state.positions @ matrix.T
    out = {"positions": float(np.abs(box.minimum_image(b.state.positions - mapped)).max() / BOX_LENGTH)}
    stress_a = np.einsum("ij,sqjk,lk->sqil", matrix, a.records.stress, matrix)
    stress_b = b.records.stress
    for k, name in enumerate(STRESS_CONTRIBUTIONS):
        scale = np.abs(stress_a[:, k]).max()
        difference = np.abs(stress_b[:, k] - stress_a[:, k]).max()
        out[name] = float(difference / scale) if scale > 0.0 else (0.0 if difference == 0.0 else math.inf)
    sign = np.linalg.det(matrix)
    velocity_a = np.hstack(
        [a.state.warm_start[:, :3] @ matrix.T, sign * a.state.warm_start[:, 3:] @ matrix.T]
    )
    out["disturbance"] = float(np.abs(b.state.warm_start - velocity_a).max() / np.abs(velocity_a).max())
    out["time_step"] = float(np.abs(b.records.time_step / a.records.time_step - 1.0).max())
    return out


def _assert_symmetric(
    a: Simulation, b: Simulation, matrix: np.ndarray, start: np.ndarray
) -> dict[str, float]:
    """Assert the tolerances of the module docstring for B against the image of A; return the deviations."""
    assert a.state.step == b.state.step == STEPS
    # the runs exercise what they are meant to: spheres moved relative to each other and overlap removal acted
    moved = LeesEdwardsBox(BOX_LENGTH, a.state.strain).minimum_image(a.state.positions - start)
    assert np.ptp(moved, axis=0).max() > 0.05
    assert a.records.overlap_sweeps.sum() > 0
    deviation = _deviations(a, b, matrix)
    assert deviation["positions"] <= POSITION_TOLERANCE, deviation
    for name in STRESS_CONTRIBUTIONS:
        assert deviation[name] <= STRESS_TOLERANCE, (name, deviation)
    assert deviation["disturbance"] <= VELOCITY_TOLERANCE, deviation
    assert deviation["time_step"] <= TIME_STEP_TOLERANCE, deviation
    assert abs(a.state.strain - b.state.strain) <= TIME_STEP_TOLERANCE * max(a.state.strain, 1.0)
    return deviation


def _permutation_matrix(perm: tuple[int, int, int]) -> np.ndarray:
    """``T`` with ``T x = x[perm]``."""
    return np.eye(3)[list(perm)]


@pytest.mark.parametrize("direction", [(0.0, 0.0, 1.0), GENERIC], ids=["e=z", "e=generic"])
@pytest.mark.parametrize("perm", list(PERMUTATIONS.values()), ids=list(PERMUTATIONS))
def test_axis_permutation_at_rest(perm, direction) -> None:
    """Quiescent, field on: permuting the axes of positions and field permutes the run (positions after
    20 adaptive steps, every stress contribution at every step, V' with Omega as a pseudovector)."""
    a = _quiescent_reference(direction)
    matrix = _permutation_matrix(perm)
    b = _run(_packing()[:, list(perm)], np.asarray(direction)[list(perm)], 0.0, QUIESCENT_MASON)
    assert np.ptp(a.records.time_step) > 0.0  # the adaptive step bound acted
    _assert_symmetric(a, b, matrix, _packing())


@pytest.mark.parametrize(
    "direction",
    [(0.0, 1.0, 1.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), GENERIC],
    ids=["e=(0,1,1)/sqrt2", "e=z", "e=y", "e=generic"],
)
def test_vorticity_mirror_under_shear(direction) -> None:
    """Shear on, z -> -z on positions and field: the trajectories mirror; Sigma_xz and Sigma_yz flip."""
    a = _sheared_reference(direction)
    positions, strain = _sheared_start()
    e = MIRROR_Z @ np.asarray(direction)
    b = _run(_transform(positions, MIRROR_Z, strain), e, 1.0, SHEAR_MASON, strain)
    _assert_symmetric(a, b, MIRROR_Z, positions)


@pytest.mark.parametrize(
    "direction", [(0.0, 1.0, 0.0), (0.0, 1.0, 1.0), GENERIC], ids=["e=y", "e=(0,1,1)/sqrt2", "e=generic"]
)
def test_rotation_about_vorticity_under_shear(direction) -> None:
    """Shear on, (x, y) -> (-x, -y) on positions and field, in the Lees–Edwards box at offset L/4: the
    trajectories rotate; Sigma_xz and Sigma_yz flip, Sigma_xy, N1 and N2 are unchanged."""
    a = _sheared_reference(direction)
    positions, strain = _sheared_start()
    assert abs(LeesEdwardsBox(BOX_LENGTH, strain).offset - 0.25 * BOX_LENGTH) < 1e-9
    e = ROTATION_Z @ np.asarray(direction)
    b = _run(_transform(positions, ROTATION_Z, strain), e, 1.0, SHEAR_MASON, strain)
    _assert_symmetric(a, b, ROTATION_Z, positions)


@pytest.mark.parametrize("direction", [(0.0, 1.0, 0.0), GENERIC], ids=["e=y", "e=generic"])
def test_field_reversal_is_bit_identical_under_shear(direction) -> None:
    """E -> -E (dipolophoresis is quadratic in the field): the same run, bit for bit."""
    a = _sheared_reference(direction)
    positions, strain = _sheared_start()
    b = _run(positions, -np.asarray(direction), 1.0, SHEAR_MASON, strain)
    # the configuration's normalisation negates exactly: B's e is -e to the last bit
    np.testing.assert_array_equal(b.config.field_direction, -np.asarray(a.config.field_direction))
    np.testing.assert_array_equal(b.state.positions, a.state.positions)
    np.testing.assert_array_equal(b.records.stress, a.records.stress)
    np.testing.assert_array_equal(b.records.time_step, a.records.time_step)
    np.testing.assert_array_equal(b.state.warm_start, a.state.warm_start)
    assert a.records.u_rms_dip.min() > 0.0


def test_rotation_about_the_box_centre_is_the_rotation_shifted_by_minus_the_offset() -> None:
    """(x, y) -> (L - x, L - y), the rotation about the box centre, is the rotation about the origin
    followed by the lattice translation a1 + a2 = (L + delta, L, 0) less delta x_hat: a translation by
    ``-delta`` along the flow (an exact symmetry) relative to the rotated run. The run from it stays at
    ``-delta x_hat`` from the rotated reference (delta = L/4 here, so a wrong sign of the offset in the wrap
    or the minimum image shows as L/2) and agrees with it, shifted back, to round-off."""
    direction = (0.0, 1.0, 1.0)
    a = _sheared_reference(direction)
    positions, strain = _sheared_start()
    offset = LeesEdwardsBox(BOX_LENGTH, strain).offset
    centred = positions.copy()
    centred[:, :2] = BOX_LENGTH - centred[:, :2]
    centred, _ = LeesEdwardsBox(BOX_LENGTH, strain).wrap(centred)
    b = _run(centred, ROTATION_Z @ np.asarray(direction), 1.0, SHEAR_MASON, strain)
    box = LeesEdwardsBox(BOX_LENGTH, a.state.strain)
    rotated = a.state.positions @ ROTATION_Z.T
    np.testing.assert_allclose(
        box.minimum_image(b.state.positions - rotated),
        np.tile([-offset, 0.0, 0.0], (N_PARTICLES, 1)),
        rtol=0,
        atol=POSITION_TOLERANCE * BOX_LENGTH,
    )
    b.state.positions[:, 0] += offset
    _assert_symmetric(a, b, ROTATION_Z, positions)


def test_default_field_direction_is_the_gradient_axis() -> None:
    """The paper's field, e = y (the velocity-gradient axis), is the default everywhere a direction may be
    left out: the configuration, a fresh state and ``Simulation.set_field(mn)`` on a pure-shear run."""
    config = SimulationConfig(n_particles=N_PARTICLES, volume_fraction=VOLUME_FRACTION)
    assert config.field_direction == (0.0, 1.0, 0.0)
    assert np.array_equal(SimulationState.initial(np.zeros((2, 3))).field_direction, [0.0, 1.0, 0.0])
    sim = Simulation(config, SimulationState.initial(_packing()))
    assert math.isinf(sim.field[0]) and np.array_equal(sim.field[1], [0.0, 1.0, 0.0])
    sim.set_field(2.0)
    assert sim.field[0] == 2.0 and np.array_equal(sim.field[1], [0.0, 1.0, 0.0])


def test_field_direction_is_normalised_and_validated() -> None:
    """Directions are normalised on construction (and by ``set_field``, through the same check): exactly
    for round cases, with exact negation (the field-reversal test relies on it), and without overflow or
    underflow for extreme magnitudes (before the fix, (1e200, 1e200, 0) became (0, 0, 0) and the run failed
    at its first step; (1e-160, 0, 0) became a vector of length 1.0000056; (1e-170, 0, 0) was refused as
    zero). Anything but three finite numbers, not all zero, is refused naming ``field_direction``; a state
    whose direction is not a unit vector is refused by the dipolophoresis kernel at the first step."""

    def unit(direction) -> tuple[float, float, float]:
        config = SimulationConfig(
            n_particles=N_PARTICLES,
            volume_fraction=VOLUME_FRACTION,
            mason_number=1.0,
            field_direction=direction,
        )
        return config.field_direction

    assert unit((0, 3, 4)) == (0.0, 0.6, 0.8)
    assert unit((0.0, 0.0, -2.5)) == (0.0, 0.0, -1.0)
    assert unit(np.array([1.0, 0.0, 0.0])) == (1.0, 0.0, 0.0)
    assert unit(tuple(-c for c in GENERIC)) == tuple(-c for c in unit(GENERIC))
    assert unit((1e200, 1e200, 0.0)) == unit((1.0, 1.0, 0.0))
    assert unit((-1e300, 0.0, 1e300)) == unit((-1.0, 0.0, 1.0))
    assert unit((1e-160, 0.0, 0.0)) == unit((1e-320, 0.0, 0.0)) == (1.0, 0.0, 0.0)
    assert unit((3e-170, 0.0, 4e-170)) == pytest.approx((0.6, 0.0, 0.8), rel=1e-15)
    for bad in (
        (0, 0, 0),
        (0.0, -0.0, 0.0),
        (1, 2),
        (1, 2, 3, 4),
        (math.nan, 0, 1),
        (0, math.inf, 0),
        1.0,
        "123",
        ("a", 0, 0),
        None,
    ):
        with pytest.raises(ValueError, match="field_direction must be three finite numbers"):
            unit(bad)

    sim = Simulation(
        SimulationConfig(n_particles=N_PARTICLES, volume_fraction=VOLUME_FRACTION, mason_number=1.0),
        SimulationState.initial(_packing(), 1.0),
    )
    sim.set_field(1.0, (0.0, 1e200, 1e200))
    assert np.array_equal(sim.field[1], unit((0.0, 1.0, 1.0)))
    with pytest.raises(ValueError, match="field_direction"):
        sim.set_field(0.5, (0.0, 0.0, 0.0))
    assert sim.field[0] == 1.0 and np.array_equal(sim.field[1], unit((0.0, 1.0, 1.0)))  # nothing changed

    config = SimulationConfig(n_particles=N_PARTICLES, volume_fraction=VOLUME_FRACTION, mason_number=1.0)
    stretched = Simulation(config, SimulationState.initial(_packing(), 1.0, (0.0, 0.0, 2.0)))
    with pytest.raises(ValueError, match="unit vector"):
        stretched.advance(1)


@pytest.mark.parametrize(("direction", "sign"), [((1, 1, 0), 1.0), ((1, -1, 0), -1.0), ((0, 1, 1), 0.0)])
def test_isolated_stresslet_gives_a_diagonal_field_a_shear_stress(
    direction: tuple[int, ...], sign: float
) -> None:
    """docs/direction.md#the-bulk-map: each sphere's isolated ICEP stresslet is
    ``(27/4) phi / Mn (e e - I/3)`` (units ``eta gammadot``; physics.md §4: ``n . S0 = (27/4) phi``), so a
    field along the extensional (compressional) diagonal adds ``+(-)(27/8) phi / Mn`` to the shear stress
    whatever the particles do, and one in the y-z plane adds nothing. Closed form; tolerance 1e-12
    (round-off)."""
    phi, mason = 0.3, 0.2
    config = SimulationConfig(
        n_particles=100, volume_fraction=phi, mason_number=mason, field_direction=direction, seed=1
    )
    records = Simulation(config).advance(1)
    isolated = records.stress[0, list(STRESS_CONTRIBUTIONS).index("icep_isolated")]
    e = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    expected = 27 / 4 * phi / mason * (np.outer(e, e) - np.eye(3) / 3)
    np.testing.assert_allclose(isolated, expected, rtol=1e-12, atol=1e-12)
    assert isolated[0, 1] == pytest.approx(sign * 27 / 8 * phi / mason, abs=1e-12)
