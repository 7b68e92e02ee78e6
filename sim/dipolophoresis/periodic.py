"""Periodic far-field pair velocity: one source sphere and all its Lees–Edwards images.

The public contract used by other tools (the reference values of ``docs/model.md#ewald-reference-values``
are computed with it).

References:
    Hasimoto (1959) J. Fluid Mech. 5, 317; Beenakker (1986) J. Chem. Phys. 85, 1581;
    Saintillan (2008) Phys. Fluids 20, 067104; Mirfendereski & Park (2024) J. Fluid Mech. §2.1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from sim.dipolophoresis.ewald import EwaldPlan, dip_far_field, ewald_plan
from sim.dipolophoresis.far_field import mechanism_weights
from sim.geometry.box import lees_edwards_offset, minimum_image, wrap_positions

__all__ = ["periodic_pair_velocity"]

# Tight plans are cached per box length (they cost tens of ms to make).
_PLANS: dict[float, EwaldPlan] = {}


def _vector3(value: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return arr


def periodic_pair_velocity(
    target: Sequence[float] | np.ndarray,
    box_length: float,
    field_direction: Sequence[float] | np.ndarray = (0.0, 1.0, 0.0),
    mechanism: str = "dip",
    strain: float = 0.0,
) -> np.ndarray:
    """Far-field velocity of a sphere at ``target`` due to a sphere at the origin and all its images.

    ``U(target) = sum_n M(target - n):ee`` over the sheared lattice ``n = n1 a1 + n2 a2 + n3 a3``
    (``a1 = (L,0,0)``, ``a2 = (delta,L,0)``, ``a3 = (0,0,L)``, ``delta`` the Lees–Edwards offset of
    ``strain``) with the far-field kernels ``M = -(9/8) S - (11/24) T`` (ICEP) and ``(1/12) T`` (DEP),
    summed by Ewald with the ``k = 0`` term dropped (:mod:`sim.dipolophoresis.ewald`). The target's own
    images contribute nothing (they cancel by inversion symmetry). Accuracy about ``1e-12`` relative.

    Args:
        target: Position of the target sphere, 3 numbers (units ``a``); any lattice image of it gives
            the same result; it must not coincide with a lattice point.
        box_length: Box side ``L`` (units ``a``), finite and ``> 4``.
        field_direction: Field direction ``e``, 3 numbers, non-zero (normalised here).
        mechanism: ``"dip"`` (ICEP + DEP), ``"icep"`` or ``"dep"``.
        strain: Accumulated shear strain (sets ``delta = strain L`` mod ``L``), finite.

    Returns:
        Velocity, shape ``(3,)``, float64, in units ``U0 = eps a E0^2/eta``.

    Raises:
        ValueError: A parameter is out of range (the message names it).
    """
    icep_weight, dep_weight = mechanism_weights(mechanism)
    point = _vector3(target, "target")
    direction = _vector3(field_direction, "field_direction")
    norm = float(np.linalg.norm(direction))
    if norm == 0.0:
        raise ValueError("field_direction must be a non-zero vector")
    direction = direction / norm
    if isinstance(box_length, bool) or not math.isfinite(float(box_length)) or float(box_length) <= 4.0:
        raise ValueError(f"box_length must be a finite number > 4 (units a), got {box_length!r}")
    box_length = float(box_length)
    if isinstance(strain, bool) or not math.isfinite(float(strain)):
        raise ValueError(f"strain must be a finite number, got {strain!r}")
    offset = float(lees_edwards_offset(float(strain), box_length))
    positions = np.zeros((2, 3))
    positions[1] = point
    wrap_positions(positions, box_length, offset)
    # Distance from the target to the nearest source image (exact below L/2, which is all that matters).
    dx, dy, dz = minimum_image(positions[1, 0], positions[1, 1], positions[1, 2], box_length, offset)
    if math.sqrt(dx * dx + dy * dy + dz * dz) < 1e-8:
        raise ValueError("target must not coincide with a lattice image of the source (the origin)")
    plan = _PLANS.get(box_length)
    if plan is None:
        plan = ewald_plan(box_length, 2, accuracy=1e-13, method="ewald", mechanism="all")
        _PLANS[box_length] = plan
    velocity, _, _ = dip_far_field(positions, box_length, offset, direction, icep_weight, dep_weight, plan)
    return np.array(velocity[1], dtype=np.float64)
