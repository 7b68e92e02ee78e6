"""Isolated-sphere (Stokes) resistance: the diagonal of the grand resistance tensor.

For a sphere of radius ``a`` in a fluid of viscosity ``eta`` (Kim & Karrila 1991, ch. 2):

    F = -6 pi eta a (U - u_inf),   T = -8 pi eta a^3 (Omega - omega_inf),   S = (20/3) pi eta a^3 E_inf.

In simulation units ``a = eta = 1`` these are the constants below. The stresslet coefficient gives the
Einstein viscosity ``eta_r = 1 + 2.5 phi`` (``n (20/3) pi a^3 E_xy / (eta gammadot) = 2.5 phi``).

References:
    Kim, S. & Karrila, S. J. (1991) Microhydrodynamics, Butterworth-Heinemann, §2.
"""

from __future__ import annotations

import math

FORCE_DRAG = 6.0 * math.pi
"""Translational resistance ``6 pi eta a`` (units eta a)."""

TORQUE_DRAG = 8.0 * math.pi
"""Rotational resistance ``8 pi eta a^3`` (units eta a^3)."""

STRESSLET_DRAG = 20.0 * math.pi / 3.0
"""Stresslet resistance ``(20/3) pi eta a^3`` (units eta a^3)."""
