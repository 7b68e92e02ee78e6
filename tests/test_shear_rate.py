"""A shear rate that changes between ``advance`` calls: units, the clock/strain split, restarts.

Independent numbers:

* the exact rate scaling of the dimensionless problem (``docs/units.md``): doubling the rate, ``1/Mn_ref``
  and the repulsion ``F0`` doubles every velocity and stress, so with half the time step a run covers the
  same strains in half the time. Every scaling is by 2, which binary floating point does exactly (no
  rounding, no underflow here), and every step (the solve's stopping rule, the adaptive step, AB2, the
  Lees–Edwards wrap) is homogeneous in the velocity scale, so the two runs agree to rounding; the issue asks
  1e-12, and we hold positions and eta_r to that;
* the strain bookkeeping: over a schedule of rates the accumulated strain is the sum of ``rate * dt`` over
  the steps, and the Lees–Edwards offset follows it;
* restarts: a snapshot (or checkpoint) taken between rate changes continues bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulation, SimulationConfig
from sim.geometry.box import lees_edwards_offset
from sim.runs.io import load_checkpoint, save_checkpoint
from sim.state import SimulationState

BASE = dict(n_particles=64, volume_fraction=0.45, seed=3, strain=1.0)
"""A dense box (phi = 0.45: lubrication, repulsion and the near field all act) with the field on."""


def _run(rate: float, mason_number: float, gammadot_star: float, time_step: float, end: float) -> Simulation:
    config = SimulationConfig(
        **BASE,
        mason_number=mason_number,
        shear_rate=rate,
        repulsion_shear_rate_ratio=gammadot_star,
        time_step=time_step,
    )
    sim = Simulation(config)
    sim.advance_to(end)
    return sim


def test_doubling_the_rate_and_the_field_halves_the_time_exactly() -> None:
    """Rate 2, Mn_ref/2, gammadot* (so F0 x 2 relative to the reference run), dt/2, to T/2 equals rate 1,
    Mn_ref, 2 gammadot*, dt, to T: same positions after the same steps, eta_r equal, stress doubled."""
    reference = _run(1.0, 1.0, 10000.0, 2e-3, 0.06)
    scaled = _run(2.0, 0.5, 5000.0, 1e-3, 0.03)
    assert scaled.state.step == reference.state.step > 10
    np.testing.assert_allclose(scaled.state.positions, reference.state.positions, rtol=0, atol=1e-12)
    assert scaled.state.strain == pytest.approx(reference.state.strain, abs=1e-12)
    assert scaled.state.time == pytest.approx(0.5 * reference.state.time, abs=1e-12)
    eta_scaled, n1_scaled, _ = scaled.records.rheology()
    eta_reference, n1_reference, _ = reference.records.rheology()
    np.testing.assert_allclose(eta_scaled, eta_reference, rtol=1e-12)
    np.testing.assert_allclose(n1_scaled, 2.0 * n1_reference, rtol=1e-12)  # N1 in eta gammadot_ref
    np.testing.assert_allclose(scaled.records.instantaneous_mason_number, 1.0)  # 2 x 0.5
    np.testing.assert_allclose(reference.records.instantaneous_mason_number, 1.0)


SCHEDULE = ((0.0, 1.0), (0.02, 0.5), (0.05, 3.0), (0.07, 0.0), (0.09, 2.0))
"""(time, rate from then on): a ramp down, a jump up, a stop (the field drives alone) and a restart."""


def _scheduled(sim: Simulation, schedule=SCHEDULE, end: float = 0.11) -> None:
    """Drive ``sim`` through ``schedule`` up to the clock ``end``, from wherever its clock stands."""
    for (start, rate), (stop, _) in zip(schedule, (*schedule[1:], (0.11, None)), strict=True):
        stop = min(stop, end)
        if start >= end or sim.state.time >= stop:
            continue  # a hold that is over (or not reached before the end)
        sim.set_shear_rate(rate)
        sim.advance_to(stop)


def _field_on() -> Simulation:
    return Simulation(SimulationConfig(**BASE, mason_number=1.0))


def test_strain_is_the_integral_of_the_rate_over_a_schedule() -> None:
    sim = _field_on()
    _scheduled(sim)
    records = sim.records
    # every step adds rate * dt to the strain and dt to the clock (exact sums of the steps taken)
    increments = (records.shear_rate * records.time_step)[:-1]
    np.testing.assert_allclose(np.diff(records.strain), increments, atol=1e-15)
    np.testing.assert_allclose(np.diff(records.time), records.time_step[:-1], atol=1e-15)
    expected = float(np.sum(records.shear_rate * records.time_step))
    assert sim.state.strain == pytest.approx(expected, abs=1e-13)
    # the rates of the schedule are in the records where they were in force, and the strain stood still at 0
    np.testing.assert_array_equal(np.unique(records.shear_rate), [0.0, 0.5, 1.0, 2.0, 3.0])
    stopped = records.shear_rate == 0.0
    assert np.ptp(records.strain[stopped]) == 0.0 and np.ptp(records.time[stopped]) > 0.0
    # instantaneous Mason number = rate x Mn_ref (Mn_ref = 1 here)
    np.testing.assert_array_equal(records.instantaneous_mason_number, records.shear_rate)
    # the final strain sits between what the nominal switch times give and one step more at each switch
    nominal = sum(r * (b - a) for (a, r), (b, _) in zip(SCHEDULE, (*SCHEDULE[1:], (0.11, None)), strict=True))
    assert nominal - 1e-12 <= sim.state.strain <= nominal + 3.0 * 5 * 2e-3
    # the Lees–Edwards images follow the strain, not the clock: every wrapped position is in the box
    offset = lees_edwards_offset(sim.state.strain, sim.config.box_length)
    assert -sim.config.box_length / 2 <= offset < sim.config.box_length / 2
    assert np.all((sim.state.positions >= 0) & (sim.state.positions < sim.config.box_length))


def test_rate_one_records_keep_time_equal_to_strain() -> None:
    """At the reference rate the clock and the strain are the same numbers, bit for bit."""
    sim = _field_on()
    sim.advance_to(0.02)
    np.testing.assert_array_equal(sim.records.time, sim.records.strain)
    assert sim.state.time == sim.state.strain


def test_restart_across_rate_changes_is_bit_identical(tmp_path) -> None:
    straight = _field_on()
    _scheduled(straight)

    first = _field_on()
    _scheduled(first, end=0.06)  # stops inside the rate-3 hold
    snapshot = first.snapshot()
    save_checkpoint(tmp_path / "checkpoint.npz", first.config, first.state, first.records, 0.0)
    config, state, records, _ = load_checkpoint(tmp_path / "checkpoint.npz")
    assert state.shear_rate == 3.0 and state.time == snapshot.time and state.strain == snapshot.strain

    for start in (snapshot, state):
        resumed = Simulation(config, start)
        assert resumed.shear_rate == 3.0
        _scheduled(resumed)
        np.testing.assert_array_equal(resumed.state.positions, straight.state.positions)
        assert resumed.state.strain == straight.state.strain and resumed.state.time == straight.state.time
    np.testing.assert_array_equal(records.shear_rate, first.records.shear_rate)

    restored = _field_on()
    restored.set_shear_rate(0.25)
    restored.restore(snapshot)  # restore brings the snapshot's rate back
    assert restored.shear_rate == 3.0


def test_a_state_without_a_rate_takes_the_configuration_s() -> None:
    config = SimulationConfig(**BASE, mason_number=1.0, shear_rate=0.5)
    positions = Simulation(config).state.positions
    sim = Simulation(config, SimulationState.initial(positions, 1.0))
    assert sim.shear_rate == 0.5


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, -math.inf, "1", True])
def test_bad_shear_rates_are_refused_by_name(bad) -> None:
    with pytest.raises(ValueError, match="shear_rate"):
        SimulationConfig(**BASE, shear_rate=bad)
    sim = _field_on()
    before = sim.snapshot()
    with pytest.raises(ValueError, match="shear_rate"):
        sim.set_shear_rate(bad)
    assert sim.shear_rate == 1.0 and sim.state.shear_rate == before.shear_rate


def test_stopping_the_flow_needs_a_field() -> None:
    sim = Simulation(SimulationConfig(**BASE))  # no field
    with pytest.raises(ValueError, match="shear_rate = 0 needs a field"):
        sim.set_shear_rate(0.0)
    assert sim.shear_rate == 1.0
    sim.set_field(1.0)
    sim.set_shear_rate(0.0)
    with pytest.raises(ValueError, match="mason_number must be finite"):
        sim.set_field(math.inf)


def test_any_finite_rate_is_a_configuration() -> None:
    config = SimulationConfig(**BASE, mason_number=2.0, shear_rate=2.5)
    assert config.duration == pytest.approx(1.0 / 2.5)
    assert config.transient_time == pytest.approx(0.5 / 2.5)  # half of a run shorter than 20, in time
    assert SimulationConfig(**BASE, shear_rate=0.0, mason_number=1.0).duration == 1.0
