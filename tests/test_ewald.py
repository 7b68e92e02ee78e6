"""Periodic far-field DIP sums by Ewald summation (sim/dipolophoresis/ewald.py, periodic.py).

Independent numbers: the reference rows of docs/model.md#dipolophoresis (cubic L = 10 and sheared L = 9
boxes),
direct lattice sums (the absolutely convergent T sum; the conditionally convergent stress sums over a
large sphere with the analytic surface term), invariances (splitting parameter, whole-lattice
translation, Lees–Edwards offset +L/2 == -L/2, zero total velocity), and tight Ewald references for the
accuracy promised by ``ewald_plan``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.dipolophoresis.ewald import (
    _MECHANISM_COEFFICIENTS,
    METHOD_EWALD,
    EwaldPlan,
    _erfcx_chebyshev,
    _fourier_error,
    _radial_functions,
    _real_error,
    _real_space_block,
    dip_far_field,
    ewald_plan,
)
from sim.dipolophoresis.far_field import dep_pair_virial, icep_pair_stresslet, pair_velocity
from sim.dipolophoresis.periodic import periodic_pair_velocity
from sim.geometry.box import lees_edwards_offset, wrap_positions

MECHANISMS = {"dip": (1.0, 1.0), "icep": (1.0, 0.0), "dep": (0.0, 1.0)}


def hard_sphere_configuration(
    n: int, phi: float, seed: int, min_gap: float = 0.01
) -> tuple[np.ndarray, float]:
    """Random non-overlapping spheres (gaps >= min_gap) in a cubic box, by iterated overlap removal.

    Uniform random centres; every overlapping pair is pushed apart along its line of centres by half
    the overlap (plus 1e-3) until no gap is below ``min_gap`` (converges in < 100 sweeps up to
    phi = 0.45). Returns positions in ``[0, L)^3`` and ``L``.
    """
    box = (n * 4.0 / 3.0 * math.pi / phi) ** (1.0 / 3.0)
    rng = np.random.default_rng(seed)
    positions = rng.uniform(0.0, box, size=(n, 3))
    diameter = 2.0 + min_gap
    for _ in range(20000):
        d = positions[:, None, :] - positions[None, :, :]
        d -= box * np.round(d / box)
        r = np.sqrt((d * d).sum(-1))
        np.fill_diagonal(r, np.inf)
        overlap = diameter - r
        if overlap.max() <= 0.0:
            return positions, box
        push = np.where(overlap > 0.0, 0.5 * overlap + 1e-3, 0.0) / r
        positions = (positions + (push[:, :, None] * d).sum(1)) % box
    raise RuntimeError("overlap removal did not converge")


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(v * v, axis=1))))


# --------------------------------------------------------------------------------------------------
# Reference values (docs/model.md#dipolophoresis)
# --------------------------------------------------------------------------------------------------


def test_reference_cubic_box() -> None:
    """L = 10, e = y, target (1.5, 2.5, -0.7): docs/model.md#ewald-reference-values values to their 8
    decimals (atol 6e-9)."""
    target = (1.5, 2.5, -0.7)
    icep = periodic_pair_velocity(target, 10.0, mechanism="icep")
    dep = periodic_pair_velocity(target, 10.0, mechanism="dep")
    np.testing.assert_allclose(icep, [-0.03513607, -0.06960498, 0.01640690], atol=6e-9)
    np.testing.assert_allclose(dep, [-0.00778002, -0.00215478, 0.00363097], atol=6e-9)
    np.testing.assert_allclose(periodic_pair_velocity(target, 10.0), icep + dep, rtol=1e-13, atol=1e-16)


@pytest.mark.parametrize("strain", [1.3, 0.3, -0.7])
def test_reference_sheared_box(strain: float) -> None:
    """L = 9, e = z, offset 2.7 (strains 1.3, 0.3, -0.7: one lattice): docs/model.md#ewald-reference-values
    to 10 decimals (6e-11)."""
    target = (0.4, -2.6, 1.7)
    icep = periodic_pair_velocity(target, 9.0, (0, 0, 1), "icep", strain)
    dep = periodic_pair_velocity(target, 9.0, (0, 0, 1), "dep", strain)
    np.testing.assert_allclose(icep, [0.0010414794, -0.0036362244, 0.0073368381], atol=6e-11)
    np.testing.assert_allclose(dep, [-0.0003391998, 0.0022709306, 0.0046002667], atol=6e-11)


def _direct_dep_lattice_sum(
    target: np.ndarray, box: float, offset: float, e: np.ndarray, images: int
) -> np.ndarray:
    """Sum of the DEP kernel (1/12) T:ee over the sheared-lattice images within radius images*L."""
    r = np.arange(-images, images + 1)
    n1, n2, n3 = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    lattice = np.stack([box * n1 + offset * n2, box * n2, box * n3], axis=1)
    x = target - lattice
    dist = np.linalg.norm(x, axis=1)
    x = x[dist < images * box]
    dist = dist[dist < images * box]
    xh = x / dist[:, None]
    c = xh @ e
    w = (5 * c * c - 1)[:, None] * xh - 2 * c[:, None] * e
    return (-w / (2 * dist[:, None] ** 4)).sum(0)


@pytest.mark.parametrize(
    ("box", "strain", "e"), [(10.0, 0.0, (0.0, 1.0, 0.0)), (9.0, 0.3, (0.36, 0.0, 0.48))]
)
def test_t_lattice_sum_direct(box: float, strain: float, e: tuple[float, float, float]) -> None:
    """The T (DEP) lattice sum converges absolutely: Ewald == direct sum over images within 20 L.

    Truncation at radius R: the spherical-shell tail measured 6e-8, 1.2e-9, 2.5e-10 for R = 10, 20, 40 L
    (|U| ~ 8e-3); tolerance 1e-8.
    """
    direction = np.array(e) / np.linalg.norm(e)
    target = np.array([1.5, 2.5, -0.7])
    offset = float(lees_edwards_offset(strain, box))
    ewald = periodic_pair_velocity(target, box, direction, "dep", strain)
    direct = _direct_dep_lattice_sum(target, box, offset, direction, 20)
    np.testing.assert_allclose(ewald, direct, atol=1e-8)


# --------------------------------------------------------------------------------------------------
# Invariances
# --------------------------------------------------------------------------------------------------


def _tight_plan(box: float, n: int, splitting: float | None = None) -> EwaldPlan:
    return ewald_plan(box, n, 1e-13, "ewald", mechanism="all", splitting=splitting)


def test_splitting_independence() -> None:
    """Velocities and both stress sums do not depend on xi: 1e-10 relative (sheared lattice, generic e).

    Each plan is converged to 1e-13; the remaining differences are rounding (measured ~1e-14).
    """
    positions, box = hard_sphere_configuration(40, 0.1, 3)
    offset = float(lees_edwards_offset(0.37, box))
    e = np.array([0.3, 0.8, -0.2]) / np.linalg.norm([0.3, 0.8, -0.2])
    results = []
    for xi in (1.15, 1.4, 1.8):
        plan = _tight_plan(box, 40, xi)
        assert plan.splitting == xi
        results.append(dip_far_field(positions, box, offset, e, 1.0, 1.0, plan))
    v0, s0, d0 = results[0]
    for v, s, d in results[1:]:
        assert np.abs(v - v0).max() <= 1e-10 * _rms(v0)
        assert np.abs(s - s0).max() <= 1e-10 * np.abs(s0).max()
        assert np.abs(d - d0).max() <= 1e-10 * np.abs(d0).max()


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
def test_total_velocity_zero(mechanism: str) -> None:
    """Sum of all periodic pair velocities is zero (odd kernels; Im|rho|^2 = 0): 1e-12 * N * rms."""
    positions, box = hard_sphere_configuration(50, 0.3, 4)
    plan = ewald_plan(box, 50, 1e-8, "ewald", mechanism=mechanism)
    icep, dep = MECHANISMS[mechanism]
    v, _, _ = dip_far_field(positions, box, 0.21 * box, np.array([0.0, 0.6, 0.8]), icep, dep, plan)
    assert np.abs(v.sum(0)).max() <= 1e-12 * 50 * _rms(v)


def test_whole_lattice_translation() -> None:
    """Shifting every sphere by the same vector (then Lees–Edwards wrapping) changes nothing: 1e-11."""
    positions, box = hard_sphere_configuration(60, 0.3, 5)
    offset = float(lees_edwards_offset(0.43, box))
    plan = ewald_plan(box, 60, 1e-10, "ewald", mechanism="all")
    e = np.array([0.0, 1.0, 0.0])
    v0, s0, d0 = dip_far_field(positions, box, offset, e, 1.0, 1.0, plan)
    shifted = positions + np.array([3.7, -11.2, 5.3])
    wrap_positions(shifted, box, offset)
    v1, s1, d1 = dip_far_field(shifted, box, offset, e, 1.0, 1.0, plan)
    assert np.abs(v1 - v0).max() <= 1e-11 * _rms(v0)
    assert np.abs(s1 - s0).max() <= 1e-11 * np.abs(s0).max()
    assert np.abs(d1 - d0).max() <= 1e-11 * np.abs(d0).max()


def test_offset_periodicity() -> None:
    """Offsets +L/2 and -L/2 are one lattice (strain 1/2 vs -1/2): results agree to 1e-11.

    Also strain s and s + 1 give the same offset, hence the same sums.
    """
    positions, box = hard_sphere_configuration(60, 0.3, 6)
    plan = ewald_plan(box, 60, 1e-10, "ewald", mechanism="all")
    e = np.array([0.5, 0.5, math.sqrt(0.5)])
    v0, s0, d0 = dip_far_field(positions, box, 0.5 * box, e, 1.0, 1.0, plan)
    v1, s1, d1 = dip_far_field(positions, box, -0.5 * box, e, 1.0, 1.0, plan)
    assert np.abs(v1 - v0).max() <= 1e-11 * _rms(v0)
    assert np.abs(s1 - s0).max() <= 1e-11 * np.abs(s0).max()
    assert np.abs(d1 - d0).max() <= 1e-11 * np.abs(d0).max()
    a = dip_far_field(positions, box, float(lees_edwards_offset(0.2, box)), e, 1.0, 1.0, plan)[0]
    b = dip_far_field(positions, box, float(lees_edwards_offset(1.2, box)), e, 1.0, 1.0, plan)[0]
    assert np.abs(a - b).max() <= 1e-11 * _rms(a)


# --------------------------------------------------------------------------------------------------
# Stress sums
# --------------------------------------------------------------------------------------------------


def test_stress_symmetric_and_traceless() -> None:
    """Both stress sums are symmetric (exactly); the ICEP stresslet sum is traceless (1e-13 of its size)."""
    positions, box = hard_sphere_configuration(60, 0.35, 7)
    plan = ewald_plan(box, 60, 1e-8, "ewald", mechanism="all")
    for e in (np.array([0.0, 1.0, 0.0]), np.array([0.6, 0.0, 0.8])):
        _, icep, dep = dip_far_field(positions, box, 0.3 * box, e, 1.0, 1.0, plan)
        np.testing.assert_array_equal(icep, icep.T)
        np.testing.assert_array_equal(dep, dep.T)
        assert abs(np.trace(icep)) <= 1e-13 * np.abs(icep).max()


def test_stress_sums_direct_spherical_summation() -> None:
    """Ewald stress sums == direct sums of the free-space pair kernels over a large sphere of images.

    The kernels decay as r^-3, so the lattice sums are conditionally convergent; a spherical summation
    equals the k = 0-dropped Ewald sum plus ``(N^2/V) <lim_{k->0} K^(k)>`` averaged over directions.
    For the ICEP stresslet correction that average vanishes (the free-space formula of docs/model.md,
    summed spherically, equals the Ewald sum, whose ``tr(H) I`` Lorentz term cancels the average of
    the ``-4 pi I`` contact part); for the DEP virial ``<K^> = (8 pi/5) Q`` gives the surface term
    ``-(4 pi^2 N^2/(5 V^2)) Q`` (here 40% of the stress, so the check is sharp). Spherical truncation
    at 16 L leaves a shell-discreteness error (measured 5e-4 and 7e-4 relative, decaying ~1/R);
    tolerance 3e-3 relative to the largest component.
    """
    box = 8.0
    volume = box**3
    positions = np.array([[1.0, 2.0, 3.0], [5.0, 1.5, 6.5], [3.3, 6.2, 0.4]])
    n = positions.shape[0]
    e = np.array([0.3, 0.8, -0.2]) / np.linalg.norm([0.3, 0.8, -0.2])
    q = np.outer(e, e) - np.eye(3) / 3.0
    plan = _tight_plan(box, n)
    _, icep, dep = dip_far_field(positions, box, 0.0, e, 1.0, 1.0, plan)
    images = 16
    r = np.arange(-images, images + 1)
    lattice = box * np.stack([a.ravel() for a in np.meshgrid(r, r, r, indexing="ij")], axis=1)
    direct_icep = np.zeros((3, 3))
    direct_dep = np.zeros((3, 3))
    for a in range(n):
        for b in range(n):
            x = positions[a] - positions[b] + lattice
            dist = np.linalg.norm(x, axis=1)
            keep = (dist < images * box) & (dist > 1e-9)
            for xv in x[keep]:
                direct_icep += icep_pair_stresslet(xv, e)
                direct_dep += 0.5 * dep_pair_virial(xv, e)  # each pair appears twice
    direct_icep /= volume
    direct_dep /= volume
    surface = -4.0 * math.pi**2 * n * n / (5.0 * volume**2) * q
    assert np.abs(direct_icep - icep).max() <= 3e-3 * np.abs(icep).max()
    assert np.abs(direct_dep - (dep + surface)).max() <= 3e-3 * np.abs(dep).max()
    assert np.abs(direct_dep - dep).max() > 0.1 * np.abs(dep).max()  # the surface term matters


def test_single_sphere_stress_from_its_images() -> None:
    """N = 1: no velocity, but the images contribute stress (a cubic lattice with e along an axis)."""
    box = 10.0
    plan = _tight_plan(box, 1)
    e = np.array([0.0, 0.0, 1.0])
    v, icep, dep = dip_far_field(np.array([[1.0, 2.0, 3.0]]), box, 0.0, e, 1.0, 1.0, plan)
    assert np.abs(v).max() <= 1e-15  # rounding of Im[exp(ikx) conj(exp(ikx))]
    # Cubic symmetry with e = z: stresses are diagonal with xx = yy.
    for s in (icep, dep):
        assert abs(s[0, 0] - s[1, 1]) <= 1e-12 * abs(s[2, 2])
        assert np.abs(s - np.diag(np.diag(s))).max() <= 1e-12 * abs(s[2, 2])


# --------------------------------------------------------------------------------------------------
# Kernels and the plan's accuracy
# --------------------------------------------------------------------------------------------------


def test_radial_functions_and_vectorised_block() -> None:
    """f_{n+1} = f_n'/r by 5-point differences (1e-7), and the vectorised pair block equals the scalar
    reference (erfc from its Chebyshev erfcx series, relative error < 2e-14, checked against scipy)."""
    from scipy.special import erfcx

    xi = 0.8
    for r in (0.7, 2.1, 3.5, 6.0):
        h = 1e-3 * r
        g = [np.array(_radial_functions(r + k * h, xi)) for k in (-2, -1, 1, 2)]
        f = np.array(_radial_functions(r, xi))
        # phi_2 = phi_1'/r, phi_3 = phi_2'/r, rho_3 = rho_2'/r, rho_4 = rho_3'/r (5-point differences)
        for lower, upper in ((0, 1), (1, 2), (3, 4), (4, 5)):
            derivative = (g[0][lower] - 8 * g[1][lower] + 8 * g[2][lower] - g[3][lower]) / (12 * h) / r
            assert abs(derivative - f[upper]) <= 1e-7 * (abs(f[upper]) + abs(f[lower]) / r**2) + 1e-15
    coefficients = _erfcx_chebyshev(21)
    x = np.linspace(0.0, 10.0, 2001)
    t_lo = 2.0 / 12.0
    u = (2.0 * (2.0 / (2.0 + x)) - 1.0 - t_lo) / (1.0 - t_lo)
    assert np.abs(np.polynomial.chebyshev.chebval(u, coefficients) / erfcx(x) - 1.0).max() < 2e-14
    rng = np.random.default_rng(8)
    sep = rng.normal(size=(40, 3)) * 2.5
    r2 = (sep * sep).sum(1)
    q = np.outer([0.6, 0.0, 0.8], [0.6, 0.0, 0.8]) - np.eye(3) / 3
    qt = (q[0, 0], q[0, 1], q[0, 2], q[1, 1], q[1, 2], q[2, 2])
    ux, uy, uz = np.empty(40), np.empty(40), np.empty(40)
    sums = _real_space_block(
        40,
        sep[:, 0].copy(),
        sep[:, 1].copy(),
        sep[:, 2].copy(),
        r2,
        np.exp(-xi * xi * r2),
        xi,
        qt,
        -1.125,
        -0.375,
        ux,
        uy,
        uz,
        np.empty(40),
    )
    for i in range(40):
        phi1, phi2, phi3, rho2, rho3, rho4 = _radial_functions(math.sqrt(r2[i]), xi)
        qx = q @ sep[i]
        qq = sep[i] @ qx
        a = -1.125 * 2 * (rho2 - phi1) + 4 * -0.375 * phi2
        b = (-1.125 * rho3 + 2 * -0.375 * phi3) * qq
        np.testing.assert_allclose([ux[i], uy[i], uz[i]], a * qx + b * sep[i], rtol=1e-12, atol=1e-14)
    assert np.all(np.isfinite(sums))


def test_error_estimates_against_measured_errors() -> None:
    """The rms truncation-error estimates (module docstring) match measured errors within a factor 1.6.

    Measured against a converged sum with the same xi, truncating only the real or only the Fourier
    part, for a hard-sphere suspension at phi = 0.3 (N = 150).
    """
    positions, box = hard_sphere_configuration(150, 0.3, 9)
    density = 150 / box**3
    xi = 0.6
    e = np.array([0.0, 1.0, 0.0])
    offset = 0.3 * box
    tight = EwaldPlan(xi, 0.5 * box, 12.0, METHOD_EWALD, (0, 0, 0), 0, box)
    for name, (icep, dep) in MECHANISMS.items():
        a_s, a_t = _MECHANISM_COEFFICIENTS[name]
        ref = dip_far_field(positions, box, offset, e, icep, dep, tight)[0]
        for cutoff in (3.5, 4.5):
            plan = EwaldPlan(xi, cutoff, 12.0, METHOD_EWALD, (0, 0, 0), 0, box)
            err = _rms(dip_far_field(positions, box, offset, e, icep, dep, plan)[0] - ref)
            assert 1 / 1.6 < err / _real_error(xi, cutoff, density, a_s, a_t) < 1.6
        for k_cutoff in (3.0, 4.0):
            plan = EwaldPlan(xi, 0.5 * box, k_cutoff, METHOD_EWALD, (0, 0, 0), 0, box)
            err = _rms(dip_far_field(positions, box, offset, e, icep, dep, plan)[0] - ref)
            assert 1 / 1.6 < err / _fourier_error(xi, k_cutoff, density, a_s, a_t) < 1.6


@pytest.mark.parametrize("phi", [0.1, 0.45])
@pytest.mark.parametrize("n", [30, 200])
def test_plan_accuracy(phi: float, n: int) -> None:
    """ewald_plan(accuracy=1e-6): rms velocity error / rms velocity < 1e-6 against a 1e-11 reference,
    for DIP (default plan) and DEP (plan for DEP), at offsets 0, 0.37 L and -L/2."""
    positions, box = hard_sphere_configuration(n, phi, 10 + n)
    reference_plan = ewald_plan(box, n, 1e-11, "ewald", mechanism="all")
    e = np.array([0.0, 1.0, 0.0])
    for mechanism, (icep, dep) in (("dip", (1.0, 1.0)), ("dep", (0.0, 1.0))):
        plan = ewald_plan(box, n, 1e-6, "ewald", mechanism=mechanism)
        for offset in (0.0, 0.37 * box, -0.5 * box):
            ref = dip_far_field(positions, box, offset, e, icep, dep, reference_plan)[0]
            v = dip_far_field(positions, box, offset, e, icep, dep, plan)[0]
            assert _rms(v - ref) < 1e-6 * _rms(ref)


def test_free_space_limit_of_a_large_box() -> None:
    """Two spheres 3a apart in a box of 200a: the periodic velocity tends to the free-space pair value.

    Image corrections are O(r^3/L^3) relative for S (2e-6 here after the k = 0 convention's uniform
    strain, which is O(phi)); tolerance 1e-4 relative.
    """
    x = np.array([1.2, 2.4, -1.0])
    e = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(
        periodic_pair_velocity(x, 200.0, e, "dip"), pair_velocity(x, e, 1.0, 1.0), rtol=1e-4, atol=0
    )


# --------------------------------------------------------------------------------------------------
# Input validation
# --------------------------------------------------------------------------------------------------


def test_validation() -> None:
    with pytest.raises(ValueError, match="box_length"):
        ewald_plan(3.0, 10)
    with pytest.raises(ValueError, match="n_particles"):
        ewald_plan(10.0, 0)
    with pytest.raises(ValueError, match="accuracy"):
        ewald_plan(10.0, 10, accuracy=0.5)
    with pytest.raises(ValueError, match="method"):
        ewald_plan(10.0, 10, method="pme")
    with pytest.raises(ValueError, match="mechanism"):
        ewald_plan(10.0, 10, mechanism="both")
    with pytest.raises(ValueError, match="splitting"):
        ewald_plan(10.0, 10, splitting=-1.0)
    plan = ewald_plan(10.0, 4, 1e-6)
    positions = np.array([[1.0, 1.0, 1.0], [4.0, 4.0, 4.0]])
    e = np.array([0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="box_length"):
        dip_far_field(positions, 11.0, 0.0, e, 1.0, 1.0, plan)
    with pytest.raises(ValueError, match="offset"):
        dip_far_field(positions, 10.0, 6.0, e, 1.0, 1.0, plan)
    with pytest.raises(ValueError, match="direction"):
        dip_far_field(positions, 10.0, 0.0, 2.0 * e, 1.0, 1.0, plan)
    with pytest.raises(ValueError, match="mechanism"):
        periodic_pair_velocity((1, 2, 3), 10.0, mechanism="ICEP")
    with pytest.raises(ValueError, match="target"):
        periodic_pair_velocity((1, 2), 10.0)
    with pytest.raises(ValueError, match="target"):
        periodic_pair_velocity((10.0, 0.0, -10.0), 10.0)
    with pytest.raises(ValueError, match="field_direction"):
        periodic_pair_velocity((1, 2, 3), 10.0, (0, 0, 0))
    with pytest.raises(ValueError, match="box_length"):
        periodic_pair_velocity((1, 2, 3), float("nan"))
    with pytest.raises(ValueError, match="strain"):
        periodic_pair_velocity((1, 2, 3), 10.0, strain=float("inf"))
