"""Independent realisations of one episode: the same start state and schedule, moved by 1e-9 a.

A dense sheared suspension is chaotic: two runs whose start states differ by far less than anything
physical part within a few strains, and their interval-averaged ``eta_r`` then differ by the full size of
its fluctuations. On the thickening-control test split (N = 300, 12 time units per episode) one episode's
return carries a noise of about 23 (standard deviation) that no pairing of controllers on the same start
state removes (``results/thickening_control/v2/README.md``). Playing each held-out episode ``K`` times from
start states moved by a tiny random displacement and averaging gives that noise's size and divides its
variance by ``K``.

Realisation ``k`` of start state ``(split, index)``: ``k = 0`` is the stored state itself, bit for bit;
``k >= 1`` adds to every coordinate an independent normal displacement of standard deviation
:data:`REALISATION_AMPLITUDE` (units of the sphere radius ``a``), drawn from
``numpy.random.default_rng((REALISATION_SEED, split number, index, k))``, so every controller meets the
same perturbed states. A displacement that would leave the box ``[0, L)`` is applied with the opposite
sign (a 1e-9 move then stays inside without a Lees–Edwards wrap). Velocities, the AB2 history and the
PCG warm start are kept: they are those of the unperturbed state, a difference of the same 1e-9 order.
The amplitude is 4e6 times smaller than the displacement bound of one step (0.4% of ``a``) and 1e4 times
smaller than the smallest gap that overlap removal keeps (``overlap_min_gap`` = 1e-5 a); it changes no
observable at t = 0 beyond the ninth digit.
"""

from __future__ import annotations

import numpy as np

import sim

REALISATION_AMPLITUDE = 1e-9
"""Standard deviation of the displacement per coordinate, in units of ``a``."""

REALISATION_SEED = 20261204
"""First entry of the seed sequence of every realisation's displacement."""

_SPLIT_NUMBERS = {"train": 0, "validation": 1, "test": 2, "fresh": 3}


def perturbed_state(
    state: sim.SimulationState, box_length: float, split: str, index: int, realisation: int
) -> sim.SimulationState:
    """Realisation ``realisation`` of the start state ``state`` (``(split, index)`` in its library, box
    side ``box_length`` in units of ``a``): a copy, moved as the module docstring says (``state`` itself,
    copied, for realisation 0)."""
    if isinstance(realisation, bool) or not isinstance(realisation, int | np.integer) or realisation < 0:
        raise ValueError(f"realisation must be an integer >= 0, got {realisation!r}")
    if split not in _SPLIT_NUMBERS:
        raise ValueError(f"split must be one of {', '.join(_SPLIT_NUMBERS)}, got {split!r}")
    out = state.copy()
    if realisation == 0:
        return out
    rng = np.random.default_rng((REALISATION_SEED, _SPLIT_NUMBERS[split], int(index), int(realisation)))
    delta = REALISATION_AMPLITUDE * rng.standard_normal(out.positions.shape)
    moved = out.positions + delta
    outside = (moved < 0.0) | (moved >= box_length)
    moved[outside] = out.positions[outside] - delta[outside]
    out.positions = moved
    return out
