"""The compiled step end to end through ``Simulation``: config names reach the right kernel parameters,
the adaptive step obeys its bound, and the field API (set_field, snapshot/restore, checkpoints)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from dense_reference import dense_grand_resistance, dense_pair_list

from sim import Simulation, SimulationConfig, SimulationState
from sim.contacts.repulsion import repulsion_scale
from sim.hydrodynamics.resistance_functions import lubrication_scalars
from sim.hydrodynamics.stokes_drag import STRESSLET_DRAG
from sim.observables.stress import DIPOLOPHORESIS_CONTRIBUTIONS, LUBRICATION, REPULSION, STRESS_CONTRIBUTIONS
from sim.runs.io import load_checkpoint, save_checkpoint
from sim.step_parameters import step_parameters
from sim.stepper import choose_time_step

SHEAR = np.array([[0.0, 0.5, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])


def _lattice_config(**overrides) -> tuple[SimulationConfig, np.ndarray]:
    """27 spheres on a jittered cubic lattice (spacing 2.6, jitter 0.29): many pairs in lubrication
    range, no overlaps; the config's box is exactly the lattice's."""
    n_side, spacing = 3, 2.6
    length = n_side * spacing
    phi = 27 * (4.0 / 3.0) * math.pi / length**3
    config = SimulationConfig(n_particles=27, volume_fraction=phi, **overrides)
    grid = (np.arange(n_side) + 0.5) * config.box_length / n_side
    pos = np.array([[a, b, c] for a in grid for b in grid for c in grid])
    pos += np.random.default_rng(0).uniform(-0.29, 0.29, pos.shape)
    return config, pos


def test_config_reaches_the_kernel_end_to_end() -> None:
    """One Euler step through Simulation equals a dense numpy solve built from the config by hand.

    The reference assembles R_FU, R_FE, R_SU, R_SE densely (tests/dense_reference.py, an independent
    einsum implementation) with the config's cut-off and regularisation passed by name, adds eq. 2.7's
    repulsion with the config's F0 and sigma, solves, and forms the lubrication stresslets and the
    repulsion virial. Non-default, well-separated values make any swap of two parameters (cut-off with
    regularisation, force scale with range) change the velocity by O(1): tolerance 1e-9 relative (the
    solver runs to 1e-12; the velocity is recovered from positions, ~1e-13).
    """
    config, pos = _lattice_config(
        lubrication_cutoff=0.4,
        lubrication_regularisation=1e-3,
        repulsion_range=0.05,
        repulsion_shear_rate_ratio=20.0,
        time_step=1e-4,
        solver_tolerance=1e-12,
    )
    length = config.box_length
    sim = Simulation(config, SimulationState.initial(pos))
    record = sim.advance(1)
    dt = record.time_step[0]
    assert dt == config.time_step

    cut, delta = config.lubrication_cutoff, config.lubrication_regularisation
    pairs, seps = dense_pair_list(pos, length, 0.0, 2.0 + cut)
    r_fu, r_fe, r_su, r_se = dense_grand_resistance(
        pos, pairs, seps, lambda s: lubrication_scalars(s - 2.0, cut, delta)
    )
    n = len(pos)
    f0, sigma = repulsion_scale(config.repulsion_shear_rate_ratio), config.repulsion_range
    forces = np.zeros((n, 6))
    virial = np.zeros((3, 3))
    for (i, j), sep in zip(pairs, seps, strict=True):
        r = np.linalg.norm(sep)
        magnitude = f0 / sigma / np.expm1((r - 2.0) / sigma)
        forces[i, :3] -= magnitude * sep / r
        forces[j, :3] += magnitude * sep / r
        virial += magnitude * np.outer(sep, sep) / r
    disturbance = np.linalg.solve(r_fu, np.einsum("aij,ij->a", r_fe, SHEAR) + forces.ravel()).reshape(n, 6)
    velocity = disturbance[:, :3].copy()
    velocity[:, 0] += pos[:, 1]

    moved = (sim.state.positions - pos) / dt  # no particle crosses the box in one tiny step
    np.testing.assert_allclose(moved, velocity, rtol=1e-9, atol=1e-9 * np.abs(velocity).max())
    stresslets = -np.einsum("aijb,b->aij", r_su, disturbance.ravel()) + np.einsum(
        "aijkl,kl->aij", r_se, SHEAR
    )
    lubrication = (stresslets.sum(axis=0) - n * STRESSLET_DRAG * SHEAR) / length**3
    stress = record.stress[0]
    np.testing.assert_allclose(
        stress[LUBRICATION], lubrication, rtol=1e-9, atol=1e-9 * np.abs(lubrication).max()
    )
    np.testing.assert_allclose(stress[REPULSION], -virial / length**3, rtol=1e-12)
    assert abs(stress[REPULSION]).max() > 1e-3 * abs(stress[LUBRICATION]).max()  # repulsion really acts


def test_time_step_control() -> None:
    """choose_time_step: the displacement bound, the growth cap and the floor (exact arithmetic)."""
    config = SimulationConfig(n_particles=64, volume_fraction=0.3, time_step=0.002, max_displacement=0.004)
    params = step_parameters(config)
    bound = 0.004 * config.mean_spacing
    assert params.max_displacement == pytest.approx(bound, rel=1e-15)
    assert choose_time_step(1.0, 0.002, True, params) == 0.002  # slow: the cap
    assert choose_time_step(10.0, 0.002, True, params) == pytest.approx(bound / 10.0, rel=1e-15)
    assert choose_time_step(0.0, 1e-4, True, params) == 2e-4  # growth at most x2 per step
    assert choose_time_step(0.0, 1e-4, False, params) == 0.002  # first step: no history
    assert choose_time_step(1e12, 0.002, True, params) == params.min_time_step


def test_pure_shear_keeps_the_validated_fixed_step() -> None:
    """phi = 0.45 pure shear: the displacement bound (0.4% of the spacing) never binds, so every step is
    the fixed dt = 0.002 of the validated runs (docs/validation.md), and the rheology is that of the
    fixed-step code."""
    sim = Simulation(SimulationConfig(n_particles=64, volume_fraction=0.45, seed=2))
    records = sim.advance_to(1.0)
    assert np.all(records.time_step == 0.002)


def test_field_api_validation() -> None:
    sim = Simulation(SimulationConfig(n_particles=40, volume_fraction=0.2))
    for bad in (0.0, -1.0, float("nan"), "1", True):
        with pytest.raises(ValueError, match="mason_number"):
            sim.set_field(bad)  # type: ignore[arg-type]
    for bad_direction in ((0, 0, 0), (1, 2), (np.nan, 1, 0)):
        with pytest.raises(ValueError, match="direction"):
            sim.set_field(1.0, bad_direction)
    sim.set_field(2.0, (0, 0, 3))
    mn, e = sim.field
    assert mn == 2.0 and np.array_equal(e, [0.0, 0.0, 1.0])
    small = Simulation(SimulationConfig(n_particles=20, volume_fraction=0.2))  # fine without a field ...
    with pytest.raises(ValueError, match="near_field_cutoff"):
        small.set_field(1.0)  # ... but too small a box for the exact near field
    assert np.isinf(small.field[0]) and np.array_equal(small.field[1], [0.0, 1.0, 0.0])  # nothing changed
    quiescent = Simulation(
        SimulationConfig(n_particles=40, volume_fraction=0.2, mason_number=1.0, shear_rate=0)
    )
    with pytest.raises(ValueError, match="quiescent"):
        quiescent.set_field(math.inf)


def test_field_off_gives_no_dipolophoresis() -> None:
    """Mn = inf: U^d and the three DIP stress contributions are exactly zero."""
    sim = Simulation(SimulationConfig(n_particles=30, volume_fraction=0.3, seed=3))
    records = sim.advance(5)
    dip = list(DIPOLOPHORESIS_CONTRIBUTIONS)
    assert [STRESS_CONTRIBUTIONS[k] for k in dip] == [
        "icep_isolated",
        "icep_pair",
        "dep_virial",
        "dep_stresslet",
    ]
    assert np.all(records.stress[:, dip] == 0.0) and np.all(records.u_rms_dip == 0.0)


def test_isolated_icep_stresslet() -> None:
    """n S0 with S0 = 9 pi eps a^3 E0^2 (ee - I/3) (docs/model.md#dipolophoresis): (27/4) phi (ee - I/3) /
    Mn, exact."""
    config = SimulationConfig(
        n_particles=64, volume_fraction=0.3, mason_number=0.5, field_direction=(1, 1, 0)
    )
    record = Simulation(config).advance(1)
    e = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    expected = 27.0 / 4.0 * config.volume_fraction * (np.outer(e, e) - np.eye(3) / 3.0) / 0.5
    k = STRESS_CONTRIBUTIONS.index("icep_isolated")
    np.testing.assert_allclose(record.stress[0, k], expected, rtol=1e-12, atol=1e-15)
    dep_only = SimulationConfig(**{**config.to_dict(), "mechanism": "dep", "field_direction": (1, 1, 0)})
    assert np.all(Simulation(dep_only).advance(1).stress[0, k] == 0.0)


def test_field_switching_restarts_bit_identically(tmp_path) -> None:
    """Field on, off and rotated mid-run; a checkpoint taken between the switches reproduces the
    uninterrupted run bit for bit (state, field and records)."""
    config = SimulationConfig(n_particles=64, volume_fraction=0.35, seed=4, mason_number=1.0)

    def protocol(sim: Simulation, start: int) -> None:
        schedule = [(1.0, (0, 1, 0)), (math.inf, None), (0.5, (1, 0, 1))]
        for index in range(start, len(schedule)):
            mn, e = schedule[index]
            sim.set_field(mn, e)
            sim.advance(7)

    full = Simulation(config)
    protocol(full, 0)

    first = Simulation(config)
    first.set_field(1.0, (0, 1, 0))
    first.advance(7)
    save_checkpoint(tmp_path / "c.npz", config, first.state, first.records, 0.0)
    _, state, records, _ = load_checkpoint(tmp_path / "c.npz")
    resumed = Simulation(config, state)
    resumed.records = records
    protocol(resumed, 1)
    np.testing.assert_array_equal(resumed.state.positions, full.state.positions)
    np.testing.assert_array_equal(resumed.records.stress, full.records.stress)
    np.testing.assert_array_equal(resumed.records.mason_number, full.records.mason_number)
    assert resumed.field[0] == 0.5
    assert np.isinf(full.records.mason_number[7:14]).all()

    # snapshot/restore carries the field
    snap = full.snapshot()
    full.set_field(3.0, (1, 0, 0))
    full.restore(snap)
    assert full.field[0] == 0.5 and np.allclose(full.field[1], np.array([1, 0, 1]) / math.sqrt(2))


def test_records_can_be_dropped_for_flat_memory() -> None:
    sim = Simulation(SimulationConfig(n_particles=20, volume_fraction=0.2), keep_records=False)
    chunk = sim.advance(4)
    assert chunk.strain.size == 4 and sim.records.strain.size == 0
