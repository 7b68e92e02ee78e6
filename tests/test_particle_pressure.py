"""Particle pressure ``Pi = -tr(Sigma^p)/3``: definition, averaging, and which contributions carry it."""

from __future__ import annotations

import math

import numpy as np

from sim import Simulation, SimulationConfig
from sim.contacts.repulsion import repulsion_scale
from sim.observables.stress import (
    DEP_VIRIAL,
    N_CONTRIBUTIONS,
    REPULSION,
    STRESS_CONTRIBUTIONS,
    particle_pressure,
)
from sim.simulation import StepRecords, summarise
from sim.state import SimulationState


def test_particle_pressure_of_an_isotropic_stress_is_its_pressure() -> None:
    """``Sigma = -p I + deviator`` gives ``Pi = p`` exactly (the deviator has no trace)."""
    deviator = np.array([[0.3, 1.2, -0.4], [1.2, -0.1, 0.7], [-0.4, 0.7, -0.2]])
    stress = np.stack([-2.5 * np.eye(3) + deviator, 4.0 * np.eye(3)])
    np.testing.assert_allclose(particle_pressure(stress), [2.5, -4.0], rtol=0, atol=1e-15)


def test_summarised_pressure_is_the_time_weighted_mean_per_contribution() -> None:
    """Hand-made records with unequal steps: the mean is weighted by each sample's step (1e-14)."""
    samples = 20
    steps = np.linspace(0.5, 1.5, samples) * 1e-3
    pressures = np.linspace(1.0, 3.0, samples)
    stress = np.zeros((samples, N_CONTRIBUTIONS, 3, 3))
    stress[:, REPULSION] = -pressures[:, None, None] * np.eye(3)
    stress[:, DEP_VIRIAL] = 0.5 * np.eye(3)  # tension: Pi = -0.5
    records = StepRecords(
        np.cumsum(steps) - steps,
        steps,
        stress,
        np.ones(samples),
        np.zeros(samples, dtype=np.int64),
        np.zeros(samples, dtype=np.int64),
        np.zeros(samples),
        np.zeros(samples),
        np.full(samples, math.inf),
    )
    result = summarise(records, 0.0, n_blocks=10)
    expected = float(np.sum(steps * pressures) / steps.sum())
    assert math.isclose(result.pressure_contributions["repulsion"], expected, rel_tol=1e-14)
    assert math.isclose(result.pressure_contributions["dep_virial"], -0.5, rel_tol=1e-14)
    assert math.isclose(result.particle_pressure, expected - 0.5, rel_tol=1e-14)
    assert result.particle_pressure_stderr > 0


def test_repelling_pair_has_the_virial_pressure() -> None:
    """Independent number: two spheres at gap h repel with eq. 2.7's ``|F|``; the virial
    ``-(1/V) |F| r d d`` has ``Pi = |F| r / (3 V)`` > 0. Checked on the first recorded sample of a real
    run (evaluated at the start configuration); 1e-9 relative (the gap recomputed from positions near
    L/2 carries ~1e-15 rounding, amplified by d ln F / dh ~ 1/sigma)."""
    config = SimulationConfig(n_particles=2, volume_fraction=0.001, strain=0.002)
    gap = 2e-3
    centre = np.full(3, config.box_length / 2)
    d = np.array([1.0, 2.0, -0.5]) / np.sqrt(5.25)
    positions = np.array([centre - (1 + gap / 2) * d, centre + (1 + gap / 2) * d])
    sim = Simulation(config, SimulationState.initial(positions))
    records = sim.advance(1)
    sigma = config.repulsion_range
    force = repulsion_scale(config.repulsion_shear_rate_ratio) / sigma / np.expm1(gap / sigma)
    expected = force * (2 + gap) / (3 * config.box_length**3)
    got = particle_pressure(records.stress[0, REPULSION])
    assert expected > 0
    assert math.isclose(got, expected, rel_tol=1e-9), (got, expected)


def test_only_the_virials_carry_a_trace() -> None:
    """Sheared dipolophoresis (phi = 0.45, N = 64, Mn = 1, exact near field, 20 steps): every stresslet
    contribution is traceless to rounding (1e-10 of the largest stress component), so ``Pi`` comes from
    the repulsion and DEP virials only, as the stress module documents; both of those are non-zero."""
    config = SimulationConfig(n_particles=64, volume_fraction=0.45, strain=1.0, mason_number=1.0, seed=3)
    sim = Simulation(config)
    records = sim.advance(20)
    scale = np.abs(records.stress).max()
    traces = np.trace(records.stress, axis1=-2, axis2=-1)  # (S, C)
    for index, name in enumerate(STRESS_CONTRIBUTIONS):
        largest = np.abs(traces[:, index]).max()
        if index in (REPULSION, DEP_VIRIAL):
            assert largest > 1e-6 * scale, name
        else:
            assert largest <= 1e-10 * scale, (name, largest / scale)
