"""Associated Legendre functions of order m = 0 and m = 1 and their angular derivatives.

Both the electric (Laplace) and the hydrodynamic (Stokes, Lamb's solution) two-sphere solvers expand
their fields in ``P_n^m(cos theta)`` with ``m = 0`` (axisymmetric) or ``m = 1`` (``cos phi`` /
``sin phi`` dependence). The solvers need, at many points, the three amplitudes

* ``P_n^m(cos theta)``,
* ``dP_n^m/dtheta``,
* ``m P_n^m(cos theta) / sin(theta)`` (the ``1/sin(theta)`` of the azimuthal derivative, regular at
  the poles because ``P_n^1`` carries a factor ``sin(theta)``),

for ``n = 0..order``. They are computed from the three-term recurrences of ``P_n(x)`` and its
derivative ``P_n'(x)`` (Abramowitz & Stegun 8.5.3; ``P'_{n+1} = P'_{n-1} + (2n+1) P_n``), with the
Condon--Shortley phase of :func:`scipy.special.lpmv`:

    P_n^1(x) = -sin(theta) P_n'(x),
    dP_n/dtheta = -sin(theta) P_n'(x),
    dP_n^1/dtheta = x P_n'(x) - n (n+1) P_n(x)      (from Legendre's equation),
    P_n^1/sin(theta) = -P_n'(x).

No division by ``sin(theta)`` occurs, so the values are exact to rounding on the axis too.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class LegendreTable(NamedTuple):
    """Values of ``P_n^m`` and derivatives, each of shape ``(order + 1, n_points)`` (row = degree n)."""

    value: FloatArray
    d_dtheta: FloatArray
    m_over_sin: FloatArray


def legendre_table(order: int, m: int, cos_theta: FloatArray, sin_theta: FloatArray) -> LegendreTable:
    """Tabulate ``P_n^m(cos theta)``, ``dP_n^m/dtheta`` and ``m P_n^m/sin(theta)`` for ``n = 0..order``.

    Args:
        order: highest degree ``n`` (>= 1).
        m: azimuthal order, 0 or 1.
        cos_theta: shape ``(n_points,)``, cosines of the polar angles.
        sin_theta: shape ``(n_points,)``, the matching sines (>= 0); passed separately so that points
            close to the axis keep full relative accuracy.

    Returns:
        :class:`LegendreTable` of arrays of shape ``(order + 1, n_points)``.
    """
    if m not in (0, 1):
        raise ValueError(f"m must be 0 or 1, got {m}")
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    x = np.asarray(cos_theta, dtype=float)
    s = np.asarray(sin_theta, dtype=float)
    n_points = x.shape[0]
    p = np.empty((order + 1, n_points))
    dp = np.empty((order + 1, n_points))
    p[0] = 1.0
    p[1] = x
    dp[0] = 0.0
    dp[1] = 1.0
    for n in range(1, order):
        p[n + 1] = ((2 * n + 1) * x * p[n] - n * p[n - 1]) / (n + 1)
        dp[n + 1] = dp[n - 1] + (2 * n + 1) * p[n]
    if m == 0:
        return LegendreTable(p, -s * dp, np.zeros_like(p))
    degrees = np.arange(order + 1, dtype=float)[:, None]
    return LegendreTable(-s * dp, x * dp - degrees * (degrees + 1.0) * p, -dp)
