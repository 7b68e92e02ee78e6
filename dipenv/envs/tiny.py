"""Arguments of the tiny ids (``dipenv/FieldMagnitudeTiny-v0``, ``dipenv/FieldVectorTiny-v0``,
``dipenv/ThickeningControlTiny-v0``, ``dipenv/ViscosityTrackingTiny-v0``), in one place.

The tiny ids are cheap stand-ins for tests, CI and the demo: a box of N = 32, episodes of 10 short
intervals and a 4/2/2-state start-state library, so that an episode, a training of a few dozen steps or
an evaluation runs in seconds to minutes. They are not physics: the box is far below the size whose
viscosity matches the bulk's (docs/environments.md#box-size), and no result is drawn from them.

The dicts live here, not in :mod:`dipenv` (which re-exports them), so that the env modules can use them
without importing the package's ``__init__`` (an import cycle): each is built from the one before it,
plus what differs.
"""

from __future__ import annotations

from typing import Any

TINY_KWARGS: dict[str, Any] = {
    "n_particles": 32,
    "volume_fraction": 0.45,
    "near_field_cutoff": 3.0,
    "control_interval": 0.02,
    "episode_steps": 10,
    "mason_min": 0.1,
    "preshear_strain": 1.0,
    "split_sizes": {"train": 4, "validation": 2, "test": 2},
    "target_viscosity": 7.0,
}
"""Arguments of the tiny variants: the smallest box the exact near field allows at phi = 0.45 with a
3 a cut-off, short intervals and episodes, a narrower Mn range (Mn = 0.05 costs 4x the steps of 0.2)."""

THICKENING_TINY_KWARGS: dict[str, Any] = {
    **{k: v for k, v in TINY_KWARGS.items() if k != "target_viscosity"},
    "eta_cap": 7.0,
    "hold_range": (0.04, 0.08),
    "ramp_range": (0.02, 0.05),
    "max_piece": 0.01,
}
"""The tiny thickening-control variant: the tiny box and intervals, with holds and ramps scaled to its
0.2-time episodes."""

TRACKING_TINY_KWARGS: dict[str, Any] = {
    **{k: v for k, v in THICKENING_TINY_KWARGS.items() if k != "eta_cap"},
    "target_hold_range": (0.04, 0.08),
    "target_ramp_range": (0.02, 0.05),
    "target_preview": 0.04,
}
"""The tiny tracking id: the box, intervals and rate schedules of ``ThickeningControlTiny-v0`` (so it shares
that id's start states; its reward has a target schedule, not a cap), with the target's holds, ramps and
preview scaled to its 0.2-time episodes."""
