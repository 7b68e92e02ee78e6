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
from sim.dipolophoresis.far_field import MECHANISM_WEIGHTS
from sim.dipolophoresis.near_field import pair_functions


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


@pytest.mark.parametrize("mechanism", ["dip", "icep", "dep"])
@pytest.mark.parametrize("along", [True, False])
def test_velocity_split_of_a_quiescent_pair(mechanism: str, along: bool) -> None:
    """The records' U_rms split (physics.md §7) on the one case with an independent number: a quiescent,
    force-free pair at r = 3 a, along the field or across it (Mn_ref = 1, so U0 = 1). Both spheres move at
    the exact two-sphere speed |F_par(3)| or |F_perp(3)| (the tabulated solution,
    ``docs/model.md#dip-near-field``), so ``u_rms_dip`` is that speed, and the disturbance velocity of shear
    and repulsion is exactly zero (no flow, no force at a gap of 1 a).

    The periodic images slow the pair by ``c / L^p``: ``p = 3`` where ICEP's ``r^-2`` kernel leads and
    ``p = 5`` for DEP alone (``r^-4``); measured, going from L = 20.3 to 16.1 a (phi = 0.001 to 0.002)
    multiplies the deficit by 1.98 for ICEP along the field (1.26^3 = 2.0) and 3.3 for DEP (1.26^5 = 3.2).
    The two boxes extrapolate it away; what the next term leaves is below 3e-4 of the speed (measured
    6.7e-5 for DEP; a p = 3 fit there would leave 2.6e-3), so the tolerance is 1e-3 relative."""
    r0 = 3.0
    k = 0 if along else 1  # F_par or F_perp
    icep, dep = MECHANISM_WEIGHTS[mechanism]
    exact = abs(icep * pair_functions(r0, "icep")[k] + dep * pair_functions(r0, "dep")[k])
    speeds, lengths = [], []
    for phi in (0.001, 0.002):
        config = SimulationConfig(
            n_particles=2, volume_fraction=phi, mason_number=1.0, shear_rate=0, mechanism=mechanism
        )
        centre = np.full(3, config.box_length / 2)
        d = np.array([0.0, 1.0, 0.0] if along else [1.0, 0.0, 0.0])  # the field is along y
        sim = Simulation(
            config, SimulationState.initial(np.array([centre - r0 / 2 * d, centre + r0 / 2 * d]), 1.0)
        )
        records = sim.advance(1)
        assert records.u_rms_shear[0] == 0.0
        speeds.append(records.u_rms_dip[0])
        lengths.append(config.box_length)
    assert abs(speeds[0] - exact) < abs(speeds[1] - exact)  # closer in the larger box
    p = 5 if mechanism == "dep" else 3
    a, _ = np.linalg.solve(np.c_[np.ones(2), np.asarray(lengths) ** -p], np.asarray(speeds))
    assert a == pytest.approx(exact, rel=1e-3), (a, exact, speeds)
