"""Microstructure statistics of one configuration in the Lees–Edwards box (paper §3.3;
docs/model.md#observables).

Three compiled statistics of the pair geometry, each built on the Lees–Edwards cell list
(:func:`sim.geometry.neighbors.build_pair_list`, minimum image with the offset
``delta = strain L mod L`` of :func:`sim.geometry.box.lees_edwards_offset`):

* :func:`fabric_tensor` — the second-moment fabric ``A = <n n>`` of the unit vectors between near
  neighbours (dimensionless, trace 1; ``I/3`` when isotropic);
* :func:`contact_number` — the mean number of neighbours ``Z`` per particle within a surface gap
  (dimensionless);
* :func:`angular_pair_distribution` — the pair distribution ``g`` in a thin shell near contact, resolved
  in ``|cos theta|`` about a direction (the field), normalised by the ideal-gas count, so that poles
  (along the field) and equators (normal to it) can be compared (paper Fig. 5).

All lengths are in units of the sphere radius ``a``; positions must be wrapped into ``[0, L)^3`` (as
``Simulation.state.positions`` are). Cut-offs must not exceed ``L/2`` (minimum image); a ``ValueError``
says so otherwise.

References:
    Mirfendereski & Park (2024), J. Fluid Mech., §3.3 (pair distribution, fabric); Sierou & Brady (2002),
    J. Fluid Mech. 453, 193 (fabric and contact statistics of sheared suspensions); Allen & Tildesley
    (2017), Computer Simulation of Liquids, ch. 2 (pair distribution normalisation).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.box import lees_edwards_offset
from sim.geometry.neighbors import build_pair_list

__all__ = [
    "DEFAULT_CONTACT_GAP",
    "DEFAULT_FABRIC_CUTOFF",
    "angular_pair_distribution",
    "contact_number",
    "fabric_tensor",
]

DEFAULT_FABRIC_CUTOFF = 2.2
"""Centre distance (units a) below which two spheres count as near neighbours for the fabric: a surface
gap below 0.2 a, inside the lubrication range (gap < 0.5 a) where the pair stresslet is large."""

DEFAULT_CONTACT_GAP = 0.01
"""Surface gap (units a) below which a pair counts as a contact: ten repulsion lengths (sigma = 1e-3 a);
in sheared dense suspensions most load-bearing pairs sit far below it (near the 1e-5 a overlap floor)."""


@njit(cache=True)
def check_configuration(positions: np.ndarray, box_length: float, strain: float) -> None:
    """``ValueError`` unless positions are ``(N, 3)``, ``box_length`` finite and > 0, ``strain`` finite."""
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError("positions must have shape (N, 3)")
    if not (box_length > 0.0) or not math.isfinite(box_length):
        raise ValueError("box_length must be finite and > 0")
    if not math.isfinite(strain):
        raise ValueError("strain must be finite")


@njit(cache=True)
def _checked_pairs(
    positions: np.ndarray, box_length: float, strain: float, cutoff: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pair list within ``cutoff`` at the Lees–Edwards offset of ``strain`` (cut-off checked)."""
    check_configuration(positions, box_length, strain)
    if not (cutoff > 0.0) or cutoff > 0.5 * box_length:
        raise ValueError("the cut-off must be in (0, L/2] (minimum image)")
    offset = lees_edwards_offset(strain, box_length)
    return build_pair_list(positions, box_length, offset, cutoff)


@njit(cache=True)
def fabric_tensor(positions: np.ndarray, box_length: float, strain: float, cutoff: float) -> np.ndarray:
    """Fabric tensor ``A = <n n>`` over all pairs with centre distance ``r < cutoff``.

    ``A_kl = (1/M) sum_{pairs, r < r_c} n_k n_l`` with ``n = r_vec / r`` the unit vector between the
    centres (minimum image under Lees–Edwards) and ``M`` the number of such pairs. ``A`` is symmetric,
    positive semi-definite, with trace 1; an isotropic structure gives ``I/3``, pairs all along ``y`` give
    ``diag(0, 1, 0)``. Its deviatoric part ``A - I/3`` measures the shear- and field-induced anisotropy.

    Args:
        positions: (N, 3) float64 wrapped centres in ``[0, L)^3`` (units a).
        box_length: box side ``L`` (units a).
        strain: accumulated strain (sets the Lees–Edwards offset ``strain L mod L``).
        cutoff: centre-distance cut-off ``r_c`` (units a), in ``(0, L/2]``; e.g.
            :data:`DEFAULT_FABRIC_CUTOFF`.

    Returns:
        (3, 3) float64 ``A`` (dimensionless); all zeros when no pair is closer than ``cutoff``.

    References:
        Sierou & Brady (2002), J. Fluid Mech. 453, §5 (fabric of sheared suspensions); paper §3.3.
    """
    _, separations = _checked_pairs(positions, box_length, strain, cutoff)
    out = np.zeros((3, 3))
    m = separations.shape[0]
    for k in range(m):
        dx = separations[k, 0]
        dy = separations[k, 1]
        dz = separations[k, 2]
        r_sq = dx * dx + dy * dy + dz * dz
        if r_sq == 0.0:
            continue
        inv = 1.0 / r_sq
        out[0, 0] += dx * dx * inv
        out[1, 1] += dy * dy * inv
        out[2, 2] += dz * dz * inv
        out[0, 1] += dx * dy * inv
        out[0, 2] += dx * dz * inv
        out[1, 2] += dy * dz * inv
    if m > 0:
        out /= m
    out[1, 0] = out[0, 1]
    out[2, 0] = out[0, 2]
    out[2, 1] = out[1, 2]
    return out


@njit(cache=True)
def contact_number(positions: np.ndarray, box_length: float, strain: float, contact_gap: float) -> float:
    """Mean contact number ``Z = 2 M_c / N``: neighbours per particle with surface gap below ``contact_gap``.

    ``M_c`` counts the pairs with ``r - 2a < h_c`` (centre distance ``r``, minimum image under
    Lees–Edwards). For an ideal gas of number density ``n``, ``Z = (N - 1)/V (4/3) pi (2 + h_c)^3``; for a
    simple cubic lattice of spacing ``d < 2 + h_c < sqrt(2) d``, ``Z = 6``.

    Args:
        positions: (N, 3) float64 wrapped centres in ``[0, L)^3`` (units a).
        box_length: box side ``L`` (units a).
        strain: accumulated strain (sets the Lees–Edwards offset).
        contact_gap: ``h_c`` (units a), with ``0 < 2 + h_c <= L/2``; e.g. :data:`DEFAULT_CONTACT_GAP`.

    Returns:
        ``Z`` (dimensionless, float).

    References:
        Sierou & Brady (2002), J. Fluid Mech. 453, §5; Mari et al. (2014), J. Rheol. 58, 1693.
    """
    pairs, _ = _checked_pairs(positions, box_length, strain, 2.0 + contact_gap)
    return 2.0 * pairs.shape[0] / positions.shape[0]


@njit(cache=True)
def angular_pair_distribution(
    positions: np.ndarray,
    box_length: float,
    strain: float,
    direction: np.ndarray,
    r_inner: float,
    r_outer: float,
    n_bins: int,
) -> np.ndarray:
    """Pair distribution in the shell ``r_inner <= r < r_outer``, in bins of ``mu = |cos theta|``.

    ``theta`` is the angle between a pair's separation and ``direction`` (``e``, normalised here; ``e``
    and ``-e`` are equivalent). Bin ``k`` holds ``k/K <= mu < (k+1)/K`` (``mu = 1`` in the last), which
    is the same solid angle ``4 pi / K`` (both hemispheres) for every bin, and

        ``g_k = C_k / [ (N (N - 1) / 2) (4/3) pi (r_outer^3 - r_inner^3) / (V K) ]``,

    the pair count ``C_k`` over its ideal-gas expectation (``V = L^3``). An ideal gas gives ``g_k = 1``;
    the last bin is the pole (along the field), the first the equator.

    Args:
        positions: (N, 3) float64 wrapped centres in ``[0, L)^3`` (units a), N >= 2.
        box_length: box side ``L`` (units a).
        strain: accumulated strain (sets the Lees–Edwards offset).
        direction: (3,) float64 reference direction (the field), not zero.
        r_inner: inner radius of the shell (units a), >= 0.
        r_outer: outer radius (units a), in ``(r_inner, L/2]``.
        n_bins: number ``K >= 1`` of ``mu`` bins.

    Returns:
        (K,) float64 ``g_k`` (dimensionless).

    References:
        Paper §3.3 and Fig. 5 (g near contact, poles vs equators); Allen & Tildesley (2017), §2.6.
    """
    if n_bins < 1:
        raise ValueError("n_bins must be >= 1")
    if positions.shape[0] < 2:
        raise ValueError("at least two particles are needed")
    if not (r_inner >= 0.0) or not (r_outer > r_inner):
        raise ValueError("the shell needs 0 <= r_inner < r_outer")
    norm = math.sqrt(direction[0] ** 2 + direction[1] ** 2 + direction[2] ** 2)
    if not (norm > 0.0) or not math.isfinite(norm):
        raise ValueError("direction must be finite and not zero")
    ex = direction[0] / norm
    ey = direction[1] / norm
    ez = direction[2] / norm
    _, separations = _checked_pairs(positions, box_length, strain, r_outer)
    counts = np.zeros(n_bins)
    inner_sq = r_inner * r_inner
    for k in range(separations.shape[0]):
        dx = separations[k, 0]
        dy = separations[k, 1]
        dz = separations[k, 2]
        r_sq = dx * dx + dy * dy + dz * dz
        if r_sq < inner_sq or r_sq == 0.0:
            continue
        mu = abs(dx * ex + dy * ey + dz * ez) / math.sqrt(r_sq)
        b = int(mu * n_bins)
        if b >= n_bins:
            b = n_bins - 1
        counts[b] += 1.0
    n = positions.shape[0]
    volume = box_length**3
    shell = (4.0 / 3.0) * math.pi * (r_outer**3 - r_inner**3)
    expected = 0.5 * n * (n - 1) * shell / volume / n_bins
    return counts / expected
