"""Two spheres in a quiescent fluid under a field (far-field kernels, large periodic box).

Independent expectations (Saintillan 2008; Park & Saintillan 2010; paper §2.1, docs/model.md#dipolophoresis):
under dipolophoresis (ICEP dominant) a pair inclined to the field first approaches, then rotates
towards the plane normal to the field and separates ("transient pairing"); under DEP alone the pair
rotates into the field direction and stays in contact (a chain).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulation, SimulationConfig, SimulationState


def _pair_history(
    mechanism: str, duration: float, near_field: str = "exact", r0: float = 2.6, angle_deg: float = 35.0
) -> tuple[np.ndarray, np.ndarray]:
    """Separation and angle to the field (degrees) every 20 steps of a quiescent pair (time in a/U0)."""
    config = SimulationConfig(
        n_particles=2,
        volume_fraction=0.001,
        mason_number=1.0,
        shear_rate=0,
        mechanism=mechanism,
        time_step=0.01,
        near_field=near_field,
    )
    centre = np.full(3, config.box_length / 2)
    th = math.radians(angle_deg)
    d = np.array([math.sin(th), math.cos(th), 0.0])  # field along y
    pos = np.array([centre - 0.5 * r0 * d, centre + 0.5 * r0 * d])
    sim = Simulation(config, SimulationState.initial(pos, 1.0))
    separations, angles = [], []
    while sim.state.time < duration:
        sim.advance(20)
        sep = sim.state.positions[1] - sim.state.positions[0]
        r = np.linalg.norm(sep)
        separations.append(r)
        angles.append(math.degrees(math.acos(abs(sep[1]) / r)))
    return np.array(separations), np.array(angles)


def test_dip_pair_approaches_rotates_and_separates() -> None:
    """Exact near field. Starting at r = 2.6, 35 degrees from the field: the pair first approaches (closest
    r < 2.4; measured 2.26), the line of centres turns to > 60 degrees from the field (measured 67) and the
    pair ends well apart (r > 3.5 after 60 a/U0; measured 5.6)."""
    r, angle = _pair_history("dip", duration=60.0)
    assert r.min() < 2.4
    assert angle[-1] > 60.0
    assert r[-1] > 3.5


def test_dip_pair_with_far_field_kernels_only() -> None:
    """Far field only (near_field='none'): the truncated ICEP kernel still attracts at contact, so the
    spheres touch (gap < 0.01), then turn to > 70 degrees and separate (r > 3.5 after 60 a/U0). The
    rotation (F_x ~ r^-4) freezes as the pair separates (F_perp ~ r^-2): the angle settles near 78
    degrees (measured), not at 90."""
    r, angle = _pair_history("dip", duration=60.0, near_field="none")
    assert r.min() - 2.0 < 0.01
    assert angle[-1] > 70.0
    assert r[-1] > 3.5


@pytest.mark.parametrize("near_field", ["exact", "none"])
def test_dep_pair_chains_along_the_field(near_field: str) -> None:
    """DEP alone: the pair ends in contact (gap < 0.01) aligned with the field (< 5 degrees)."""
    r, angle = _pair_history("dep", duration=150.0, near_field=near_field)
    assert r[-1] - 2.0 < 0.01
    assert angle[-1] < 5.0
