"""scripts/field_pulsing.py: the switch and strongest-field shares on traces whose answers are known."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location(
    "field_pulsing", Path(__file__).parents[1] / "scripts" / "field_pulsing.py"
)
field_pulsing = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(field_pulsing)


def _fractions(mason: list, rate: list) -> tuple[float, float, float]:
    return field_pulsing.episode_fractions(
        {"mason_number": mason, "shear_rate": rate}, strongest=0.1, weak=5.0, high_rate=2.0, low_rate=1.0
    )


def test_constant_field_never_switches() -> None:
    strong_high, strong_low, switches = _fractions([0.1] * 6, [3.0] * 6)
    assert (strong_high, switches) == (1.0, 0.0)
    assert math.isnan(strong_low)  # no interval below rate 1


def test_alternating_field_switches_every_interval() -> None:
    # strongest, off, strongest, weak (Mn_ref 10), strongest at rate 3: every consecutive pair switches
    strong_high, _, switches = _fractions([0.1, "inf", 0.1, 10.0, 0.1], [3.0] * 5)
    assert switches == 1.0
    assert strong_high == pytest.approx(3 / 5)


def test_rates_split_the_shares() -> None:
    # two slow intervals (one strongest), then two fast ones (both weak): only the fast pairs count
    strong_high, strong_low, switches = _fractions([0.1, 1.0, 5.0, "inf"], [0.5, 0.5, 3.0, 3.0])
    assert strong_low == 0.5
    assert strong_high == 0.0
    assert switches == 0.0  # pairs ending above rate 2: (1.0 -> 5.0) and (5.0 -> off), neither strongest


def test_rate_bins_average_within_each_bin() -> None:
    # two episodes: rates 0.5 (energy 2, eta_r 8 -> excess 0.3) and 3 (energy 0 and 10, eta_r 7 -> 0)
    first = {
        "shear_rate": [0.5, 3.0],
        "field_energy": [2.0, 0.0],
        "eta_r": [8.0, 7.0],
        "eta_cap": 7.7,
        "reward": [-0.9, 0.0],
    }
    second = {
        "shear_rate": [3.0, 9.0],
        "field_energy": [10.0, 1.0],
        "eta_r": [7.0, 9.0],
        "eta_cap": 7.7,
        "reward": [-3.0, -1.0],
    }
    table = field_pulsing.rate_bin_means([first, second], np.array([0.2, 1.0, 5.0, 6.0]))
    assert table[:, 0] == pytest.approx([0.25, 0.5, 0.0])  # the rate-9 interval is outside the edges
    assert table[0, 1:] == pytest.approx([2.0, 0.3, -0.9])
    assert table[1, 1:] == pytest.approx([5.0, 0.0, -1.5])
    assert np.isnan(table[2, 1:]).all()
