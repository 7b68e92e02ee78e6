"""Issue 45: a run ended at the first step past its strain (up to one step, 0.002, too far). Its last step
is now shortened to land on the requested strain (``sim.runs.run._step_at_most_to``), with the variable-step
AB2 update ``x + h[(1 + r/2) u_n - (r/2) u_{n-1}]``, ``r = h / h_prev``, so that the step stays second
order, and every earlier step is the unshortened run's, bit for bit.

Independent numbers: the uncapped ``Simulation.advance`` steps (the reference for "unchanged"), and, for
the order of the last step, a reference integration of the same interval with 64 times smaller steps
from the same state. Measured here (N = 40, phi = 0.3, pure shear, last step 0.4 of the one before):
local errors 7.1e-8, 8.8e-9, 1.1e-9, 1.4e-10 for previous steps 4e-3 .. 5e-4 (orders 3.01, 3.01, 3.00:
a third-order local error, second order globally), against 3.9e-6 .. 6.1e-8 (orders 2.00) when the last
step is an explicit Euler step; the test holds orders in [2.7, 3.3] and below 2.3 for Euler.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim import Simulation, SimulationConfig, SimulationState, run_simulation
from sim.runs.io import load_checkpoint
from sim.runs.run import _step_at_most_to
from sim.stepper import stop_time

UNEVEN = SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.0205, seed=3)
"""Ten steps of 0.002 and a last one of 0.0005."""


def _land(config: SimulationConfig, state: SimulationState, end: float) -> Simulation:
    """A simulation of ``config`` from ``state`` stepped to the clock ``end`` exactly."""
    simulation = Simulation(config, state)
    while simulation.state.time < stop_time(end, config.time_step):
        _step_at_most_to(simulation, end)
    return simulation


def test_a_run_ends_at_its_strain_and_keeps_every_earlier_step(tmp_path: Path) -> None:
    result = run_simulation(UNEVEN, tmp_path / "o", progress=False)
    assert result["steps"] == 11
    assert abs(result["strain"] - UNEVEN.strain) < 1e-12 and abs(result["time"] - UNEVEN.duration) < 1e-12
    final = SimulationState.load(tmp_path / "o" / "final_state.npz")
    assert abs(final.strain - UNEVEN.strain) < 1e-12
    # the uncapped run: the same ten steps, then a full step past the end
    reference = Simulation(UNEVEN)
    reference.advance(10)
    _, before_last, records, _ = load_checkpoint(tmp_path / "o" / "checkpoint.npz")
    np.testing.assert_array_equal(before_last.positions, reference.state.positions)
    np.testing.assert_array_equal(before_last.previous_velocity, reference.state.previous_velocity)
    assert before_last.time == reference.state.time and before_last.step == 10
    for name in ("time", "strain", "time_step", "stress", "min_gap", "solver_iterations"):
        np.testing.assert_array_equal(getattr(records, name), getattr(reference.records, name), err_msg=name)
    reference.advance(1)
    assert reference.state.time > UNEVEN.duration + 1e-3  # where the run used to end
    ours = Simulation(UNEVEN, before_last)
    ours.advance(1)  # the step the run shortened, taken whole: the reference's eleventh, bit for bit
    np.testing.assert_array_equal(ours.state.positions, reference.state.positions)
    shortened = np.loadtxt(tmp_path / "o" / "timeseries.csv", delimiter=",", skiprows=1)
    assert shortened.shape[0] == 11
    assert shortened[-1, 3] == pytest.approx(UNEVEN.duration - before_last.time, rel=1e-9)  # dt column


def test_a_run_of_whole_steps_is_unchanged_to_its_last_step(tmp_path: Path) -> None:
    """Where the strain is a whole number of steps (its remainder is the last step less the clock's
    round-off, 2e-18 here), the last step is not capped: the run is the uncapped one bit for bit."""
    config = dataclasses.replace(UNEVEN, strain=0.02)
    reference = Simulation(config)
    reference.advance_to(config.duration)
    assert reference.state.time != config.duration  # the clock's round-off: 10 x 0.002 is not 0.02
    run_simulation(config, tmp_path / "o", progress=False)
    final = SimulationState.load(tmp_path / "o" / "final_state.npz")
    assert final.step == reference.state.step == 10 and final.time == reference.state.time
    np.testing.assert_array_equal(final.positions, reference.state.positions)
    landed = _land(config, SimulationState.initial(Simulation(config).state.positions), config.duration)
    np.testing.assert_array_equal(landed.state.positions, reference.state.positions)
    np.testing.assert_array_equal(landed.records.time_step, reference.records.time_step)


def _periodic_difference(a: np.ndarray, b: np.ndarray, box_length: float) -> float:
    d = np.abs(a - b)
    return float(np.minimum(d, box_length - d).max())


def test_the_shortened_last_step_is_second_order() -> None:
    """The local error of a last step of 0.4 times the previous one falls as its cube (AB2 with the step
    ratio's coefficients), where an Euler last step's falls as its square (module docstring)."""
    base = SimulationConfig(
        n_particles=40,
        volume_fraction=0.3,
        seed=5,
        strain=1.0,
        max_displacement=0.05,  # steps of exactly time_step
        solver_tolerance=1e-13,  # the solver's residual far below the errors measured
    )
    fraction = 0.4
    errors, euler_errors = [], []
    for previous in (4e-3, 2e-3, 1e-3, 5e-4):
        config = dataclasses.replace(base, time_step=previous)
        simulation = Simulation(config)
        simulation.advance(int(round(0.02 / previous)))
        assert np.all(simulation.records.time_step == previous)
        state = simulation.snapshot()
        end = state.time + fraction * previous
        landed = _land(config, state, end)
        assert landed.records.time.size == 1 and landed.state.time == pytest.approx(end, abs=1e-15)
        assert landed.records.time_step[0] == pytest.approx(fraction * previous, rel=1e-12)
        reference = _land(dataclasses.replace(base, time_step=previous / 64), state, end)
        euler_state = state.copy()
        euler_state.has_previous = False
        euler = _land(config, euler_state, end)
        box_length = config.box_length
        errors.append(_periodic_difference(landed.state.positions, reference.state.positions, box_length))
        euler_errors.append(
            _periodic_difference(euler.state.positions, reference.state.positions, box_length)
        )
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    euler_orders = np.log2(np.array(euler_errors[:-1]) / np.array(euler_errors[1:]))
    assert np.all((orders > 2.7) & (orders < 3.3)), (errors, orders)
    assert np.all(euler_orders < 2.3), (euler_errors, euler_orders)
    assert errors[-1] < 1e-9


def test_extending_a_run_that_ended_on_a_shortened_step_equals_the_longer_run(tmp_path: Path) -> None:
    """The checkpoint a finished run leaves holds the state before its shortened last step: ``resume``
    with a longer strain continues from there, so it gives the longer run's numbers bit for bit."""
    run_simulation(UNEVEN, tmp_path / "extended", progress=False)
    longer = dataclasses.replace(UNEVEN, strain=0.031)
    extended = run_simulation(longer, tmp_path / "extended", progress=False, resume=True)
    direct = run_simulation(longer, tmp_path / "direct", progress=False)
    for key in ("relative_viscosity", "n1", "n2", "steps", "strain", "time", "min_gap"):
        assert extended[key] == direct[key], key
    for name in ("timeseries.csv", "layering.csv", "msd.csv"):
        assert (tmp_path / "extended" / name).read_text() == (tmp_path / "direct" / name).read_text(), name
    # a rerun of a finished run rewrites its results unchanged
    again = run_simulation(longer, tmp_path / "direct", progress=False)
    assert again["relative_viscosity"] == direct["relative_viscosity"] and again["steps"] == direct["steps"]
