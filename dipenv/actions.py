"""Actions: from ``Box(-1, 1)`` to the electric field (Mason number, direction) and the actuator filter.

Units as in ``sim``: ``Mn = eta gammadot / (eps E0^2)``, so the field energy density is
``eps E0^2 = 1/Mn`` (units ``eta gammadot``). The field *amplitude* used below is
``E = E0 / E0_max = sqrt(Mn_min / Mn)`` in ``[0, 1]`` (``0``: field off), the quantity a first-order
actuator filter acts on (a voltage amplifier's lag).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEFAULT_MASON_MIN = 0.05
"""Strongest field (smallest Mason number) the strength action reaches; the paper's lowest Mn."""

DEFAULT_MASON_MAX = 20.0
"""Weakest field above the off band; at Mn >= 5 the rheology is that of pure shear (paper Fig. 3)."""

DEFAULT_OFF_BAND = 0.1
"""Width of the strength-action band ``[-1, -1 + off_band)`` that switches the field off."""

OFF_SNAP_AMPLITUDE = 0.01
"""A lagging amplitude decaying towards "off" is switched off once below this (``E0/E0_max``; at the
default Mn_min = 0.05 that is Mn > 500, where dipolophoresis is negligible but a field still costs
simulator time)."""


def validate_action(action: object, shape: tuple[int, ...]) -> tuple[np.ndarray, bool]:
    """Check an action and clip it into ``[-1, 1]``.

    Args:
        action: array-like of floats with exactly ``shape`` (a Python float is accepted for shape (1,)
            only if wrapped: scalars are rejected).
        shape: the action space's shape.

    Returns:
        ``(clipped float64 copy, whether anything was clipped)``.

    Raises:
        ValueError: for a wrong shape, a non-numeric dtype, or NaN/inf entries (naming them).
    """
    array = np.asarray(action)
    if array.dtype.kind not in "fiu":
        raise ValueError(f"action must be an array of floats with shape {shape}, got dtype {array.dtype}")
    if array.shape != shape:
        raise ValueError(f"action must have shape {shape}, got shape {array.shape}: {action!r}")
    array = array.astype(np.float64)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"action must be finite (no NaN or inf), got {action!r}")
    clipped = np.clip(array, -1.0, 1.0)
    return clipped, bool(np.any(clipped != array))


@dataclass(frozen=True)
class FieldStrengthMapping:
    """Strength action ``u`` in ``[-1, 1]`` to the Mason number, log-linear, with an off band.

    ``u < u_off = -1 + off_band``: field off (``Mn = inf``). Otherwise
    ``log Mn = log Mn_max + s (log Mn_min - log Mn_max)`` with ``s = (u - u_off) / (1 - u_off)`` in
    ``[0, 1]``: ``u = u_off`` is the weakest field ``Mn_max``, ``u = 1`` the strongest ``Mn_min``.

    Attributes:
        mason_min: smallest Mason number (strongest field), > 0.
        mason_max: largest finite Mason number (weakest field), > mason_min.
        off_band: width of the off band, in [0, 1).
    """

    mason_min: float = DEFAULT_MASON_MIN
    mason_max: float = DEFAULT_MASON_MAX
    off_band: float = DEFAULT_OFF_BAND

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mason_min) and self.mason_min > 0.0):
            raise ValueError(f"mason_min must be finite and > 0, got {self.mason_min!r}")
        if not (math.isfinite(self.mason_max) and self.mason_max > self.mason_min):
            raise ValueError(
                f"mason_max must be finite and > mason_min={self.mason_min}, got {self.mason_max!r}"
            )
        if not 0.0 <= self.off_band < 1.0:
            raise ValueError(f"off_band must be in [0, 1), got {self.off_band!r}")

    @property
    def off_threshold(self) -> float:
        """``u_off = -1 + off_band``: actions below it switch the field off."""
        return -1.0 + self.off_band

    def mason_number(self, u: float) -> float:
        """Mason number for the strength action ``u`` in ``[-1, 1]`` (``inf``: off)."""
        if u < self.off_threshold:
            return math.inf
        s = (u - self.off_threshold) / (1.0 - self.off_threshold)
        log_mn = math.log(self.mason_max) + s * (math.log(self.mason_min) - math.log(self.mason_max))
        return math.exp(log_mn)

    def action_for(self, mason_number: float) -> float:
        """Inverse of :meth:`mason_number`: the action that gives ``mason_number`` (``inf`` -> -1).

        Raises:
            ValueError: if a finite ``mason_number`` lies outside ``[mason_min, mason_max]``.
        """
        if math.isinf(mason_number):
            return -1.0
        if not self.mason_min * (1 - 1e-12) <= mason_number <= self.mason_max * (1 + 1e-12):
            raise ValueError(
                f"mason_number must be inf or in [{self.mason_min}, {self.mason_max}], got {mason_number!r}"
            )
        s = (math.log(self.mason_max) - math.log(mason_number)) / (
            math.log(self.mason_max) - math.log(self.mason_min)
        )
        return min(1.0, max(self.off_threshold, self.off_threshold + s * (1.0 - self.off_threshold)))

    def amplitude(self, mason_number: float) -> float:
        """Field amplitude ``E0 / E0_max = sqrt(Mn_min / Mn)`` (0 when off; above 1 only if Mn < Mn_min)."""
        return 0.0 if math.isinf(mason_number) else math.sqrt(self.mason_min / mason_number)

    def mason_for_amplitude(self, amplitude: float) -> float:
        """Inverse of :meth:`amplitude`: ``Mn = Mn_min / E^2`` (``inf`` for ``E = 0``)."""
        return math.inf if amplitude <= 0.0 else self.mason_min / (amplitude * amplitude)

    def coordinate(self, mason_number: float) -> float:
        """Action coordinate of any Mason number, clipped into ``[-1, 1]`` (for observations; off -> -1)."""
        if math.isinf(mason_number):
            return -1.0
        mn = min(max(mason_number, self.mason_min), self.mason_max)
        return self.action_for(mn)


def field_energy(mason_number: float) -> float:
    """Field energy density ``eps E0^2 = 1/Mn`` (units ``eta gammadot``; 0 when off)."""
    return 0.0 if math.isinf(mason_number) else 1.0 / mason_number


def direction_from_action(polar: float, azimuth: float) -> np.ndarray:
    """Unit field direction from two actions in ``[-1, 1]``.

    ``theta = (polar + 1) pi / 4`` in ``[0, pi/2]`` is the angle from the velocity-gradient axis ``y``
    and ``psi = azimuth pi`` in ``[-pi, pi]`` the azimuth in the flow–vorticity (``x``–``z``) plane:
    ``e = (sin theta cos psi, cos theta, sin theta sin psi)``. Since the dipolophoretic forces are
    quadratic in the field, ``e`` and ``-e`` are the same field, so the hemisphere ``e_y >= 0`` covers
    every direction. ``polar = -1`` is the paper's field along ``y``.
    """
    theta = (polar + 1.0) * math.pi / 4.0
    psi = azimuth * math.pi
    return np.array([math.sin(theta) * math.cos(psi), math.cos(theta), math.sin(theta) * math.sin(psi)])


def action_from_direction(direction: np.ndarray | tuple[float, float, float]) -> tuple[float, float]:
    """Inverse of :func:`direction_from_action` (``e`` is flipped to ``e_y >= 0`` first).

    Raises:
        ValueError: if ``direction`` is not three finite numbers, not all zero.
    """
    e = np.asarray(direction, dtype=np.float64).reshape(-1)
    norm = float(np.linalg.norm(e)) if e.size == 3 and np.all(np.isfinite(e)) else 0.0
    if norm == 0.0:
        raise ValueError(f"direction must be three finite numbers, not all zero, got {direction!r}")
    e = e / norm
    if e[1] < 0.0:
        e = -e
    theta = math.acos(min(1.0, max(-1.0, float(e[1]))))
    psi = math.atan2(float(e[2]), float(e[0])) if theta > 0.0 else 0.0
    return 4.0 * theta / math.pi - 1.0, psi / math.pi


def canonical_direction(direction: np.ndarray) -> np.ndarray:
    """``direction`` normalised and flipped so that ``e_y >= 0`` (``e`` and ``-e`` are one field)."""
    e = np.asarray(direction, dtype=np.float64) / float(np.linalg.norm(direction))
    return -e if e[1] < 0.0 else e


@dataclass(frozen=True)
class ActuatorFilter:
    """First-order lag of the field amplitude: ``dE/dt = (E_cmd - E) / tau`` (t in strain units).

    Over one control interval of length ``T`` the amplitude is held piecewise constant on ``substeps``
    equal sub-intervals, at its exact value at each sub-interval's midpoint,
    ``E(t) = E_cmd + (E_start - E_cmd) exp(-t / tau)``. ``tau = 0`` is an ideal actuator (one
    sub-interval at ``E_cmd``). Only the amplitude lags; the direction switches at once. When the
    command is "off", amplitudes below :data:`OFF_SNAP_AMPLITUDE` are set to 0.

    Attributes:
        time_constant: ``tau`` (strain), >= 0.
        substeps: sub-intervals per control interval when ``tau > 0`` (>= 1).
    """

    time_constant: float = 0.0
    substeps: int = 4

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time_constant) and self.time_constant >= 0.0):
            raise ValueError(f"actuator_time_constant must be finite and >= 0, got {self.time_constant!r}")
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, int) or self.substeps < 1:
            raise ValueError(f"actuator_substeps must be an integer >= 1, got {self.substeps!r}")

    def schedule(self, start: float, command: float, interval: float) -> tuple[list[float], float]:
        """Amplitudes held on each sub-interval and the amplitude at the end of the interval.

        Args:
            start: amplitude at the start of the interval (dimensionless, >= 0).
            command: commanded amplitude (>= 0).
            interval: control interval ``T`` (strain).
        """
        if self.time_constant == 0.0:
            return [command], command
        n = self.substeps
        held = [
            command + (start - command) * math.exp(-(k + 0.5) * interval / n / self.time_constant)
            for k in range(n)
        ]
        end = command + (start - command) * math.exp(-interval / self.time_constant)
        snap = [0.0 if (command == 0.0 and a < OFF_SNAP_AMPLITUDE) else a for a in held]
        return snap, (0.0 if (command == 0.0 and end < OFF_SNAP_AMPLITUDE) else end)
