"""Observations: interval-averaged rheology, microstructure of the end state, and the field in force.

Every component is labelled with its units and bounds (:func:`observation_features`); the vector is
clipped into those bounds (the bounds are wide enough that clipping only catches outliers). Stresses
span decades and change sign, so they enter through the signed logarithm
``slog(x) = sign(x) log10(1 + |x|)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import sim

FABRIC_CUTOFF = 2.2
"""Centre distance (units a) of the near neighbours in the fabric tensor (surface gap < 0.2 a)."""

CONTACT_GAP = 0.01
"""Surface gap (units a) below which a pair counts as a contact (ten repulsion lengths)."""

SHELL = (2.0, 2.2)
"""Shell ``r`` in ``[2, 2.2)`` a (near contact) of the angular pair distribution."""

ANGULAR_BINS = 3
"""Bins of ``|cos theta|`` (theta from the field): equator ``[0, 1/3)``, middle, pole ``[2/3, 1]``."""

MICROSTRUCTURE_DOC_ROWS = """| 3 | fabric_xx | A_xx - 1/3, A = <n n> over pairs with r < 2.2 a | 1 | [-1, 1] |
    | 4 | fabric_yy | A_yy - 1/3 | 1 | [-1, 1] |
    | 5 | fabric_xy | A_xy | 1 | [-1, 1] |
    | 6 | fabric_xz | A_xz | 1 | [-1, 1] |
    | 7 | fabric_yz | A_yz | 1 | [-1, 1] |
    | 8 | contact_number | neighbours per particle with surface gap < 0.01 a | 1 | [0, 13] |
    | 9 | g_equator | g at r in [2, 2.2) a, abs(cos theta) in [0, 1/3) | 1 | [0, 100] |
    | 10 | g_middle | g at r in [2, 2.2) a, abs(cos theta) in [1/3, 2/3) | 1 | [0, 100] |
    | 11 | g_pole | g at r in [2, 2.2) a, abs(cos theta) in [2/3, 1] | 1 | [0, 100] |"""
"""Rows 3-11 (fabric, contact number, angular g) of the observation tables in the env classes' docstrings
(each class's "## Observation Space"; one text for all of them, spliced in where ``{microstructure_rows}``
stands, indented by 4 spaces after the first line)."""


@dataclass(frozen=True)
class ObservationFeature:
    """One observation component: name, units, bounds and meaning."""

    name: str
    units: str
    low: float
    high: float
    description: str


def signed_log(x: float) -> float:
    """``sign(x) log10(1 + |x|)``: a log scale that keeps the sign and is linear near 0."""
    return math.copysign(math.log10(1.0 + abs(x)), x)


def observation_features(vector_field: bool) -> list[ObservationFeature]:
    """The labelled layout of one observation frame (the vector env adds the field direction)."""
    features = [
        ObservationFeature(
            "slog_eta_r", "slog(eta gammadot)", -6.0, 6.0, "interval-averaged relative viscosity"
        ),
        ObservationFeature("slog_n1", "slog(eta gammadot)", -6.0, 6.0, "interval-averaged N1 = S_xx - S_yy"),
        ObservationFeature("slog_n2", "slog(eta gammadot)", -6.0, 6.0, "interval-averaged N2 = S_yy - S_zz"),
        ObservationFeature("fabric_xx", "1", -1.0, 1.0, "A_xx - 1/3, A = <n n> over r < 2.2 a (end state)"),
        ObservationFeature("fabric_yy", "1", -1.0, 1.0, "A_yy - 1/3"),
        ObservationFeature("fabric_xy", "1", -1.0, 1.0, "A_xy"),
        ObservationFeature("fabric_xz", "1", -1.0, 1.0, "A_xz"),
        ObservationFeature("fabric_yz", "1", -1.0, 1.0, "A_yz"),
        ObservationFeature("contact_number", "1", 0.0, 13.0, "neighbours per particle with gap < 0.01 a"),
        ObservationFeature(
            "g_equator", "1", 0.0, 100.0, "g in r in [2, 2.2) a, |cos theta| < 1/3 (theta: field)"
        ),
        ObservationFeature("g_middle", "1", 0.0, 100.0, "g in r in [2, 2.2) a, 1/3 <= |cos theta| < 2/3"),
        ObservationFeature("g_pole", "1", 0.0, 100.0, "g in r in [2, 2.2) a, |cos theta| >= 2/3"),
        ObservationFeature(
            "field_energy_fraction", "1", 0.0, 1.0, "(E0/E0_max)^2 = Mn_min/Mn at the end (0: off)"
        ),
        ObservationFeature("field_coordinate", "1", -1.0, 1.0, "strength-action coordinate of Mn (-1: off)"),
    ]
    if vector_field:
        features += [
            ObservationFeature("field_ex", "1", -1.0, 1.0, "field direction x component (e_y >= 0)"),
            ObservationFeature("field_ey", "1", 0.0, 1.0, "field direction y component"),
            ObservationFeature("field_ez", "1", -1.0, 1.0, "field direction z component"),
        ]
    return features


def observation_bounds(
    features: list[ObservationFeature], history_length: int
) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) float32 arrays of the full observation: the frame of ``features`` repeated
    ``history_length + 1`` times."""
    low = np.array([f.low for f in features], dtype=np.float32)
    high = np.array([f.high for f in features], dtype=np.float32)
    return np.tile(low, history_length + 1), np.tile(high, history_length + 1)


def microstructure_features(
    positions: np.ndarray, box_length: float, strain: float, direction: np.ndarray
) -> np.ndarray:
    """Fabric deviator (5), contact number and the angular g near contact (3) of one configuration.

    Args:
        positions: (N, 3) wrapped centres (units a).
        box_length: box side L (units a).
        strain: the clock (sets the Lees–Edwards offset).
        direction: (3,) field direction (reference axis of the angular bins).

    Returns:
        (9,) float64 in the order of :func:`observation_features` (indices 3 to 11).
    """
    fabric = sim.fabric_tensor(positions, box_length, strain, FABRIC_CUTOFF)
    z = sim.contact_number(positions, box_length, strain, CONTACT_GAP)
    g = sim.angular_pair_distribution(
        positions,
        box_length,
        strain,
        np.asarray(direction, dtype=np.float64),
        SHELL[0],
        SHELL[1],
        ANGULAR_BINS,
    )
    third = 1.0 / 3.0
    return np.array(
        [
            fabric[0, 0] - third,
            fabric[1, 1] - third,
            fabric[0, 1],
            fabric[0, 2],
            fabric[1, 2],
            z,
            g[0],
            g[1],
            g[2],
        ]
    )


def observation_frame(
    eta_r: float,
    n1: float,
    n2: float,
    microstructure: np.ndarray,
    energy_fraction: float,
    coordinate: float,
    direction: np.ndarray | None,
) -> np.ndarray:
    """One observation frame (float64, unclipped) in the order of :func:`observation_features`.

    Args:
        eta_r, n1, n2: interval-averaged stresses (units eta gammadot).
        microstructure: (9,) from :func:`microstructure_features`.
        energy_fraction: ``(E0/E0_max)^2`` of the field in force at the end of the interval.
        coordinate: strength-action coordinate of that field.
        direction: (3,) its direction with ``e_y >= 0`` (vector env), or None.
    """
    parts = [
        np.array([signed_log(eta_r), signed_log(n1), signed_log(n2)]),
        np.asarray(microstructure, dtype=np.float64),
        np.array([energy_fraction, coordinate]),
    ]
    if direction is not None:
        parts.append(np.asarray(direction, dtype=np.float64))
    return np.concatenate(parts)
