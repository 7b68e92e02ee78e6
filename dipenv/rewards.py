"""Reward: hold the interval-averaged viscosity at a low target with as little field energy as possible.

``r = -|eta_r - eta_target| - w_E <eps E0^2>``, both terms in stress units ``eta gammadot``:
``eta_r`` is the time average of the relative viscosity over the control interval and
``<eps E0^2> = <1/Mn>`` the time-averaged field energy density over it, which is the field energy per
unit volume spent per unit strain (``gammadot = 1``; in the paper's scaling the dipolophoretic stress
is ``eps E0^2 = eta gammadot / Mn``). A simulator failure ends the episode with
``-failure_penalty`` for the failing step and each step the episode had left, so that failing never
pays (the per-step reward at the defaults stays above about -30).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

DEFAULT_ENERGY_WEIGHT = 1.0
"""``w_E``: one unit of viscosity (eta gammadot) is worth one unit of field energy density per strain."""

DEFAULT_FAILURE_PENALTY = 50.0
"""Reward of a failed step and of each step an episode loses by failing (units eta gammadot)."""

DEFAULT_TARGET_VISCOSITY = {(0.45, 64): 6.1, (0.45, 300): 7.4}
"""Default targets by (volume fraction, N): the lowest time-averaged ``eta_r`` that a constant field
reaches over an episode of ``dipenv/FieldMagnitude`` (mean and standard error over the test start states,
second half of each episode), rounded:

* N = 64 (``-v0``): 6.15 +- 0.28 at Mn = 0.5 and 6.23 +- 0.34 at Mn = 1 (16 states; no field: 10.16,
  Mn = 0.2: 6.87), from ``results/open_loop/FieldMagnitude-v0``;
* N = 300 (``-v1``): 7.41 +- 0.26 at Mn = 0.5, 7.83 +- 0.43 at 0.8, 8.04 +- 0.25 at 1 (8 states each;
  Mn = 0.2: 8.62 +- 0.16, Mn = 2: 9.22 +- 0.19), from ``results/box_size/env_episodes``.

The plateau depends on the box (docs/environments.md#box-size), so another N or volume fraction needs
``target_viscosity`` explicitly."""


def default_target_viscosity(volume_fraction: float, n_particles: int = 64) -> float:
    """The tabulated default target for ``volume_fraction`` (within 1e-6) and ``n_particles``.

    Raises:
        ValueError: if no default is tabulated for it (name the ones that are).
    """
    return _tabulated(DEFAULT_TARGET_VISCOSITY, "target_viscosity", volume_fraction, n_particles)


def _tabulated(table: dict[tuple[float, int], float], name: str, volume_fraction: float, n: int) -> float:
    """``table[(phi, N)]`` for ``phi`` within 1e-6 of ``volume_fraction``; ``ValueError`` naming ``name``
    and the tabulated pairs otherwise (the plateau depends on the box: docs/environments.md#box-size)."""
    for (phi, size), value in table.items():
        if abs(phi - volume_fraction) < 1e-6 and size == n:
            return value
    raise ValueError(
        f"no default {name} for volume_fraction={volume_fraction}, n_particles={n}; tabulated (phi, N): "
        f"{sorted(table)}; pass {name} explicitly"
    )


@dataclass(frozen=True)
class ViscosityTargetReward:
    """``r = -|eta_r - eta_target| - w_E <eps E0^2>`` (see the module docstring).

    Attributes:
        target_viscosity: ``eta_target`` (units eta gammadot), finite.
        energy_weight: ``w_E`` (dimensionless), >= 0.
        failure_penalty: penalty per failed or lost step (units eta gammadot), >= 0.
    """

    target_viscosity: float
    energy_weight: float = DEFAULT_ENERGY_WEIGHT
    failure_penalty: float = DEFAULT_FAILURE_PENALTY

    def __post_init__(self) -> None:
        if not math.isfinite(self.target_viscosity):
            raise ValueError(f"target_viscosity must be finite, got {self.target_viscosity!r}")
        if not (math.isfinite(self.energy_weight) and self.energy_weight >= 0.0):
            raise ValueError(f"energy_weight must be finite and >= 0, got {self.energy_weight!r}")
        if not (math.isfinite(self.failure_penalty) and self.failure_penalty >= 0.0):
            raise ValueError(f"failure_penalty must be finite and >= 0, got {self.failure_penalty!r}")

    def __call__(self, relative_viscosity: float, field_energy: float) -> tuple[float, dict[str, float]]:
        """Reward of one interval and its terms (``reward_viscosity``, ``reward_energy``).

        Args:
            relative_viscosity: interval-averaged ``eta_r``.
            field_energy: interval-averaged ``<eps E0^2> = <1/Mn>`` (units eta gammadot).
        """
        viscosity_term = -abs(relative_viscosity - self.target_viscosity)
        energy_term = -self.energy_weight * field_energy
        return float(viscosity_term + energy_term), {
            "reward_viscosity": float(viscosity_term),
            "reward_energy": float(energy_term),
            "reward_failure": 0.0,
        }

    def failure(self, steps_lost: int) -> tuple[float, dict[str, float]]:
        """Reward of a failed step when ``steps_lost`` further steps of the episode are lost."""
        penalty = -self.failure_penalty * (1 + max(0, steps_lost))
        return float(penalty), {
            "reward_viscosity": 0.0,
            "reward_energy": 0.0,
            "reward_failure": float(penalty),
        }


DEFAULT_VISCOSITY_CAP = {(0.45, 64): 6.5, (0.45, 300): 7.7}
"""Default ``eta_cap`` of the thickening-control reward by (volume fraction, N): the low-viscosity plateau
that constant fields reach in ``dipenv/FieldMagnitude`` at phi = 0.45 (the values of
:data:`DEFAULT_TARGET_VISCOSITY`; N = 64 also 6.03 at Mn 0.8), plus about one standard error, so that a
suspension held on the plateau pays no thickening penalty: 6.5 at N = 64 (``-v0``), 7.7 at N = 300
(``-v1``)."""


def default_viscosity_cap(volume_fraction: float, n_particles: int = 64) -> float:
    """The tabulated default ``eta_cap`` for ``volume_fraction`` (within 1e-6) and ``n_particles``;
    ``ValueError`` otherwise."""
    return _tabulated(DEFAULT_VISCOSITY_CAP, "eta_cap", volume_fraction, n_particles)


@dataclass(frozen=True)
class ThickeningPenaltyReward(ViscosityTargetReward):
    """``r = -(max(0, eta_r - eta_cap) + w_E <eps E0^2>)``: pay for thickening above a cap, and for field.

    ``eta_r = Sigma_xy / (eta gammadot)`` averaged over the control interval at the rates in force,
    ``<eps E0^2> = <1/Mn_ref>`` the field energy density in ``eta gammadot_ref`` (``docs/units.md``). The
    control intervals are equal in time, so the episode return is the time integral of the penalty rate
    divided by the interval. ``target_viscosity`` holds ``eta_cap`` (the shared environment code reports it
    under that name and as ``eta_cap``).
    """

    def __call__(self, relative_viscosity: float, field_energy: float) -> tuple[float, dict[str, float]]:
        """Reward of one interval and its terms (``reward_viscosity`` is the thickening term)."""
        viscosity_term = min(0.0, self.target_viscosity - relative_viscosity)
        energy_term = -self.energy_weight * field_energy
        return float(viscosity_term + energy_term), {
            "reward_viscosity": float(viscosity_term),
            "reward_energy": float(energy_term),
            "reward_failure": 0.0,
        }
