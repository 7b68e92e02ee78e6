"""Bulk stress: isolated-sphere limits, dilute limit, reflection symmetries, block averages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.config import SimulationConfig
from sim.contacts.repulsion import repulsion_scale
from sim.geometry.box import lees_edwards_offset
from sim.geometry.configurations import random_packing
from sim.hydrodynamics.resistance_solver import solve_resistance
from sim.observables.stress import (
    LUBRICATION,
    REPULSION,
    SOLVENT,
    STOKES_DRAG,
    STRESS_CONTRIBUTIONS,
    block_average,
    rheology,
)
from sim.step_parameters import field_parameters, run_ewald_plan, step_parameters
from sim.stepper import evaluate


def _evaluate(positions: np.ndarray, config: SimulationConfig, strain: float = 0.0):
    """(velocity, disturbance, stress, min_gap, iterations) at one configuration, field off."""
    n = positions.shape[0]
    params = step_parameters(config)._replace(solver_tolerance=1e-12)
    field = field_parameters(config, math.inf, np.array([0.0, 1.0, 0.0]), run_ewald_plan(config))
    velocity, disturbance, dip, stress, min_gap, iterations = evaluate(
        np.ascontiguousarray(positions), strain, np.zeros((n, 6)), params, field
    )
    assert np.all(dip == 0.0) and np.all(stress[4:] == 0.0)  # no field: no dipolophoresis at all
    return velocity, disturbance, stress, min_gap, iterations


def test_single_sphere_resistance() -> None:
    """Isolated sphere: F = 6 pi U and T = 8 pi Omega (Stokes), via the solver with no pairs (1e-14)."""
    diag = np.zeros((1, 6, 6))
    diag[0, :3, :3] = 6 * math.pi * np.eye(3)
    diag[0, 3:, 3:] = 8 * math.pi * np.eye(3)
    rhs = np.array([[1.0, -2.0, 0.5, 0.3, 0.0, -1.0]])
    sol, _, _ = solve_resistance(
        diag, np.zeros((0, 6, 6)), np.zeros((0, 2), dtype=np.int64), rhs, np.zeros((1, 6)), 1e-14, 10
    )
    np.testing.assert_allclose(sol[0, :3], rhs[0, :3] / (6 * math.pi), rtol=1e-14)
    np.testing.assert_allclose(sol[0, 3:], rhs[0, 3:] / (8 * math.pi), rtol=1e-14)


def test_isolated_spheres_follow_the_flow_and_give_einstein_stresslet() -> None:
    """Two far-apart spheres: U = u_inf exactly, S = (20/3) pi E, so eta_r = 1 + 2.5 phi (1e-12)."""
    config = SimulationConfig(n_particles=2, volume_fraction=0.001, strain=0.0)
    length = config.box_length
    pos = np.array([[0.25, 0.25, 0.25], [0.75, 0.75, 0.75]]) * length
    velocity, disturbance, stress, min_gap, iterations = _evaluate(pos, config)
    assert math.isinf(min_gap) and iterations == 0
    np.testing.assert_allclose(velocity[:, 0], pos[:, 1], rtol=1e-14)
    assert np.abs(disturbance).max() == 0.0
    eta, n1, n2 = rheology(stress.sum(axis=0))
    assert eta == pytest.approx(1 + 2.5 * config.volume_fraction, rel=1e-12)
    assert n1 == 0 and n2 == 0
    assert stress[SOLVENT, 0, 1] == 1.0
    assert stress[LUBRICATION].sum() == 0 and stress[REPULSION].sum() == 0


def test_dilute_limit() -> None:
    """eta_r -> 1 + 2.5 phi (Einstein): at phi = 0.01 the remainder is O(phi^2).

    Bound: |eta_r - 1 - 2.5 phi| <= 10 phi^2 = 0.001, i.e. 4% of the Einstein term 2.5 phi = 0.025, so an
    error of 4% in the Einstein coefficient fails. The pair coefficient of this model for a random (g = 1)
    configuration is about 6 (5.7 measured at phi = 0.02), of the order of Batchelor & Green's (1972) 5-7.6.
    """
    phi = 0.01
    config = SimulationConfig(n_particles=400, volume_fraction=phi, strain=0.0)
    pos = random_packing(400, phi, seed=3, min_gap=0.01)
    _, _, stress, _, _ = _evaluate(pos, config)
    eta, _, _ = rheology(stress.sum(axis=0))
    assert abs(eta - (1 + 2.5 * phi)) <= 10 * phi**2


@pytest.fixture(scope="module")
def dense_configuration():
    config = SimulationConfig(n_particles=60, volume_fraction=0.45, strain=0.0, initial_min_gap=1e-3)
    return config, random_packing(60, 0.45, seed=11, min_gap=1e-3)


def test_reflection_z_symmetry(dense_configuration) -> None:
    """Mirror z -> -z: simple shear is invariant, so eta_r, N1, N2 are unchanged (1e-9 relative, the
    solver tolerance 1e-12 times the condition number) and the xz, yz components change sign."""
    config, pos = dense_configuration
    _, _, s1, _, _ = _evaluate(pos, config, strain=0.0)
    mirrored = pos.copy()
    mirrored[:, 2] = (config.box_length - mirrored[:, 2]) % config.box_length
    _, _, s2, _, _ = _evaluate(mirrored, config, strain=0.0)
    t1, t2 = s1.sum(axis=0), s2.sum(axis=0)
    for a, b in zip(rheology(t1), rheology(t2), strict=True):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-9)
    assert t1[0, 2] == pytest.approx(-t2[0, 2], abs=1e-9)
    assert t1[1, 2] == pytest.approx(-t2[1, 2], abs=1e-9)


def test_rotation_about_vorticity_axis(dense_configuration) -> None:
    """(x, y) -> (-x, -y) maps simple shear and the sheared lattice onto themselves, so the stress obeys
    Sigma' = R Sigma R^T with R = diag(-1, -1, 1): xx, yy, zz, xy unchanged, xz and yz flip (1e-9)."""
    config, pos = dense_configuration
    rotated = pos.copy()
    rotated[:, :2] = (config.box_length - rotated[:, :2]) % config.box_length
    _, _, s1, _, _ = _evaluate(pos, config, strain=0.0)
    _, _, s2, _, _ = _evaluate(rotated, config, strain=0.0)
    rot = np.diag([-1.0, -1.0, 1.0])
    np.testing.assert_allclose(s1.sum(axis=0), rot @ s2.sum(axis=0) @ rot.T, rtol=1e-9, atol=1e-9)


def test_contributions_against_direct_sums(dense_configuration) -> None:
    """Drag part equals n (20/3) pi E = 2.5 phi (Einstein) exactly; the repulsion contribution equals a
    brute-force sum over all minimum-image pairs of eq. 2.7's force, ``-(1/V) sum |F| r d d``, written
    here in numpy independently of the kernel's cell list (1e-12 relative, rounding only)."""
    config, pos = dense_configuration
    strain = 1.0  # the packing was made at zero offset; strain 1 gives the same lattice
    _, _, stress, _, _ = _evaluate(pos, config, strain=strain)
    assert stress[STOKES_DRAG, 0, 1] == pytest.approx(2.5 * config.volume_fraction, rel=1e-12)
    length = config.box_length
    offset = lees_edwards_offset(strain, length)
    f0, sigma = repulsion_scale(config.repulsion_shear_rate_ratio), config.repulsion_range
    expected = np.zeros((3, 3))
    for i in range(len(pos)):
        for j in range(i + 1, len(pos)):
            d = pos[j] - pos[i]
            ny = np.round(d[1] / length)
            d[1] -= ny * length
            d[0] -= ny * offset
            d[0] -= np.round(d[0] / length) * length
            d[2] -= np.round(d[2] / length) * length
            r = np.linalg.norm(d)
            if r - 2.0 < config.lubrication_cutoff:
                force = f0 / sigma * np.exp(-(r - 2) / sigma) / (1 - np.exp(-(r - 2) / sigma))
                expected -= force * np.outer(d, d) / r / length**3
    assert np.abs(expected).max() > 1e-6  # the configuration has pairs within a few sigma
    np.testing.assert_allclose(stress[REPULSION], expected, rtol=1e-12, atol=1e-14)
    assert stress.shape[0] == len(STRESS_CONTRIBUTIONS)


def test_block_average() -> None:
    """Independent samples: E[stderr] = c4(10) sigma/sqrt(n) with c4(10) = 0.9727 (bias of the sample
    standard deviation); the mean over 100 seeds has a 2.3% spread, so 8% is a 3.5-sigma tolerance."""
    ratios = []
    for seed in range(100):
        x = np.random.default_rng(seed).normal(2.0, 1.0, 20000)
        b = block_average(x, 10)
        assert b.mean == pytest.approx(2.0, abs=0.05)
        ratios.append(b.stderr * math.sqrt(x.size))
    assert np.mean(ratios) == pytest.approx(0.9727, rel=0.08)
    assert block_average(np.ones(50), 5).stderr == 0.0
    assert math.isnan(block_average(np.ones(3), 5).stderr)
    with pytest.raises(ValueError, match="n_blocks"):
        block_average(x, 1)
