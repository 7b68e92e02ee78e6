"""agents.comparison: a policy against the constant-field front, on a front worked by hand."""

from __future__ import annotations

import math

import pytest

from agents.comparison import (
    action_variation,
    energy_target,
    front_energy,
    front_eta,
    front_points,
    paired_front_gap,
    position,
    return_gap,
)
from agents.open_loop import summarise_points

# A front (energy, eta_r): off 10, Mn 2 at 8, Mn 1 at 6, Mn 0.5 at 5.5 (energy = 1/Mn).
FRONT = [(0.0, 10.0), (0.5, 8.0), (1.0, 6.0), (2.0, 5.5)]


def test_front_eta_interpolates_linearly_and_holds_flat() -> None:
    assert front_eta(FRONT, 0.0) == 10.0
    assert front_eta(FRONT, 0.75) == pytest.approx(7.0, abs=1e-14)  # halfway between 8 and 6
    assert front_eta(FRONT, 1.5) == pytest.approx(5.75, abs=1e-14)
    assert front_eta(FRONT, 20.0) == 5.5  # beyond the strongest front field: flat
    with pytest.raises(ValueError, match="energy"):
        front_eta(FRONT, -0.1)
    with pytest.raises(ValueError, match="energy"):
        front_eta(FRONT, math.nan)


def test_front_energy_is_the_inverse_on_the_front() -> None:
    assert front_energy(FRONT, 11.0) == 0.0  # no field already reaches it
    assert front_energy(FRONT, 7.0) == pytest.approx(0.75, abs=1e-14)
    assert front_energy(FRONT, 5.75) == pytest.approx(1.5, abs=1e-14)
    assert front_energy(FRONT, 5.0) == math.inf  # below every constant field
    for energy in (0.1, 0.6, 1.9):
        assert front_energy(FRONT, front_eta(FRONT, energy)) == pytest.approx(energy, abs=1e-12)


def test_position_uses_the_interval() -> None:
    below = position(FRONT, 0.5, 6.5, 6.2, 6.8)  # front at 8 there
    assert below["verdict"].startswith("below") and below["eta_minus_front"] == pytest.approx(-1.5)
    assert below["front_energy"] == pytest.approx(0.875)  # 8 -> 6 over 0.5 -> 1: 6.5 at 0.875
    assert position(FRONT, 0.5, 7.5, 6.9, 8.1)["verdict"].startswith("on")
    assert position(FRONT, 1.0, 7.0, 6.5, 7.5)["verdict"].startswith("above")
    one_seed = position(FRONT, 1.0, 5.9, math.nan, math.nan)["verdict"]
    assert one_seed.startswith("below") and one_seed.endswith("no interval")


def test_paired_front_gap_by_hand() -> None:
    """Two front points (energies 0 and 1) on three states, numbers by hand: at energy 0.5 the front is
    the midpoint of each state's own values (8, 9.5, 6.5); gaps -1, -0.5, +1. The mean gap is the
    unpaired one: the policy's mean 47/6 against the front of the state means (10, 6) at 0.5, 8."""
    energies, front = [0.0, 1.0], [[10.0, 12.0, 8.0], [6.0, 7.0, 5.0]]
    gap = paired_front_gap(energies, front, [7.0, 9.0, 7.5], 0.5)
    assert gap["front_gap"] == pytest.approx((-1.0 - 0.5 + 1.0) / 3, rel=1e-14)
    assert gap["front_gap"] == pytest.approx(47 / 6 - front_eta([(0.0, 10.0), (1.0, 6.0)], 0.5), rel=1e-14)
    assert (gap["states_below_front"], gap["front_states"]) == (2, 3)
    assert gap["front_gap_low"] < gap["front_gap"] < gap["front_gap_high"]
    assert gap["paired_verdict"].startswith("on the front")
    # What a state shares between the policy and the front drops out: shifting state 1 by +3 in both
    # changes nothing.
    shifted = paired_front_gap(energies, [[10.0, 15.0, 8.0], [6.0, 10.0, 5.0]], [7.0, 12.0, 7.5], 0.5)
    assert shifted["front_gap"] == pytest.approx(gap["front_gap"], rel=1e-14)


def test_paired_front_gap_verdicts_and_refusals() -> None:
    energies, front = [0.0, 1.0], [[10.0, 11.0, 9.0, 10.0], [6.0, 7.0, 5.0, 6.0]]
    at_half = 0.5  # the front lies at 8, 9, 7, 8
    below = paired_front_gap(energies, front, [7.0, 7.9, 6.1, 7.0], at_half)
    assert below["paired_verdict"] == "below the front, paired per state"
    assert below["front_gap_high"] < 0 and below["states_below_front"] == 4
    above = paired_front_gap(energies, front, [9.0, 10.1, 7.9, 9.0], at_half)
    assert above["paired_verdict"] == "above the front, paired per state" and above["front_gap_low"] > 0
    # A state a point lacks (shapes differ) or a failed episode (NaN): not paired.
    assert (
        paired_front_gap(energies, [f[:3] for f in front], [7.0] * 4, at_half)["paired_verdict"]
        == "not paired"
    )
    nan_gap = paired_front_gap(energies, front, [7.0, math.nan, 6.0, 7.0], at_half)
    assert math.isnan(nan_gap["front_gap"]) and nan_gap["front_states"] == 0
    assert paired_front_gap(energies, front, [7.0] * 4, math.inf)["paired_verdict"] == "not paired"
    with pytest.raises(ValueError, match="front_energies"):
        paired_front_gap([1.0, 0.0], front, [7.0] * 4, at_half)


def test_front_points_are_the_pareto_rows_of_summarise_points() -> None:
    def record(label: str, eta: float, energy: float) -> dict:
        episode = {"eta_second_half": eta, "energy_second_half": energy, "return": -1.0, "failed": False}
        return {
            "label": label,
            "mason_number": 1.0,
            "direction": None,
            "action": [0.0],
            "episodes": [episode],
        }

    rows = summarise_points(
        [record("off", 10, 0), record("Mn20", 12, 0.05), record("Mn1", 6, 1), record("Mn0.1", 7, 10)]
    )
    assert front_points(rows) == [(0.0, 10.0), (1.0, 6.0)]  # Mn20 and Mn0.1 are dominated


def test_action_variation_by_hand() -> None:
    trace = {"action": [[0.0], [0.0], [1.0], [-1.0]], "mason_number": ["inf", 1.0, "inf", 2.0]}
    stats = action_variation([{"trace": trace}])
    # second half: actions 1, -1 (population std 1); field off in one of two intervals; Mn used: 2 only
    assert stats["action_std"] == pytest.approx(1.0)
    assert stats["off_share"] == pytest.approx(0.5)
    assert stats["mason_p10"] == stats["mason_p90"] == 2.0
    constant = {"action": [[0.3]] * 6, "mason_number": [1.0] * 6}
    assert action_variation([{"trace": constant}])["action_std"] == 0.0


def test_return_gap_is_paired_per_seed() -> None:
    # Seeds' returns -130, -128, -132 against a constant's -133: gaps 3, 5, 1, mean 3. The percentile
    # bootstrap of the mean of 3 values resamples them with replacement: each extreme mean (all three
    # draws the smallest, 1, or the largest, 5) has probability 1/27 = 3.7% > 2.5%, so the 95% interval is
    # exactly [1, 5] (a bootstrap cannot reach beyond the observed gaps; a t-interval would give
    # [-1.97, 7.97]: with 3 seeds the bootstrap is the narrower, docs/agents.md says so).
    gap = return_gap([-130.0, -128.0, -132.0], -133.0)
    assert gap["return_gap"] == pytest.approx(3.0)
    assert gap["return_gap_low"] == pytest.approx(1.0, abs=1e-12)
    assert gap["return_gap_high"] == pytest.approx(5.0, abs=1e-12)
    assert gap["seeds_above"] == 3 and gap["return_verdict"] == "higher return"
    same = return_gap([-135.0, -130.0, -129.0], -133.0)  # gaps -2, 3, 4: the interval reaches -2
    assert same["return_gap_low"] == pytest.approx(-2.0, abs=1e-12)
    assert same["return_verdict"].startswith("same") and same["seeds_above"] == 2
    assert return_gap([-120.0, -121.0, -119.0], -133.0)["return_verdict"] == "higher return"
    assert return_gap([-150.0, -151.0, -149.0], -133.0)["return_verdict"] == "lower return"
    one = return_gap([-140.0, math.nan], -133.0)  # a failed seed is left out
    assert one["return_verdict"] == "lower return; one sample, no interval" and one["seeds_above"] == 0
    with pytest.raises(ValueError, match="reference"):
        return_gap([-130.0], math.inf)


def test_energy_target_by_hand() -> None:
    """The energy saving is 1 - (sum of the row's energies) / (sum of the constant's), paired per state.
    With three states the paired bootstrap's 2.5% and 97.5% percentiles are, exactly, the smallest and the
    largest single-state saving: a ratio of sums lies between its terms' ratios (the mediant inequality),
    and each state drawn three times has probability 1/27 = 3.7% > 2.5% (~370 of 10^4 draws, far above
    the 250 that the percentile's rank needs)."""
    best_energy, best_excess = [2.0, 2.0, 2.0], [0.8, 0.8, 0.8]
    energy = [0.8, 1.2, 1.0]  # savings 60%, 40%, 50% per state; 50% of the sums
    result = energy_target(energy, [0.7, 0.9, 0.8], best_energy, best_excess)
    assert result["energy_saved"] == pytest.approx(0.5, abs=1e-15)
    assert result["energy_saved_low"] == pytest.approx(0.4, abs=1e-15)
    assert result["energy_saved_high"] == pytest.approx(0.6, abs=1e-15)
    assert result["excess_gap"] == pytest.approx(0.0, abs=1e-15)
    assert result["states_less_excess"] == 1 and result["target_states"] == 3
    assert result["energy_verdict"] == "saves at least 30%"
    assert result["excess_verdict"] == "same thickening within the 95% interval"
    assert result["target_verdict"] == "met"


def test_energy_target_verdicts_and_refusals() -> None:
    best_energy, best_excess = [2.0] * 4, [0.8, 0.6, 1.0, 0.7]
    # half the energy, but more thickening on every state: not met
    more = energy_target([1.0] * 4, [x + 0.3 for x in best_excess], best_energy, best_excess)
    assert more["excess_verdict"] == "thickens more" and more["target_verdict"] == "not met"
    assert more["excess_gap"] == pytest.approx(0.3, abs=1e-12)
    # 10% saved on every state: resolved below the target
    little = energy_target([1.8] * 4, best_excess, best_energy, best_excess)
    assert little["energy_verdict"] == "saves less than 30%" and little["target_verdict"] == "not met"
    # savings of 0% to 60% by state (30% of the sums): the interval spans the target
    spread = energy_target([2.0, 0.8, 1.4, 1.4], best_excess, best_energy, best_excess)
    assert spread["energy_saved"] == pytest.approx(0.3, abs=1e-12)
    assert spread["target_verdict"] == "not resolved"
    # less thickening and more than 30% saved: met
    less = energy_target([1.0] * 4, [x - 0.2 for x in best_excess], best_energy, best_excess)
    assert less["excess_verdict"] == "thickens less" and less["target_verdict"] == "met"
    # not pairable: other lengths, a failed episode, a constant without energy
    for args in (
        ([1.0] * 3, [0.8] * 3, best_energy, best_excess),
        ([1.0, math.nan, 1.0, 1.0], best_excess, best_energy, best_excess),
        ([1.0] * 4, best_excess, [0.0] * 4, best_excess),
    ):
        refused = energy_target(*args)
        assert refused["target_verdict"] == "not paired" and math.isnan(refused["energy_saved"])
