"""Gymnasium environments for electric-field control of a sheared dense suspension's viscosity.

``import dipenv`` registers (Gymnasium 1.x has no plugin discovery; ``gym.make("dipenv:dipenv/...")``
imports it too):

* ``dipenv/FieldMagnitude-v1``: field strength, direction along y (N = 300, phi = 0.45, 0.25 strain per
  action, 48 actions per episode);
* ``dipenv/FieldVector-v1``: strength and direction;
* ``dipenv/ThickeningControl-v2``: field strength while the shear rate follows a schedule of holds and
  ramps in [0.2, 5] gammadot_ref (the rate is observed); ``dipenv/ThickeningControlStressOnly-v2``: the
  same with only the measured stresses and the microstructure observed; the ``-v1`` ids are the same
  with the strongest field at ``Mn_ref = 0.05`` instead of 0.1;
* the ``-v0`` ids: the same environments in a box of N = 64, whose low-Mn viscosity plateau lies about one
  unit of eta_r below the bulk's (docs/environments.md#box-size); kept because published results use them;
* ``dipenv/FieldMagnitudeTiny-v0``, ``dipenv/FieldVectorTiny-v0``: N = 32, 0.02 strain per action, 10
  actions per episode, Mn in [0.1, 20], a 4/2/2-state library: for tests, CI and the demo;
  ``dipenv/ThickeningControlTiny-v0`` likewise;
* ``dipenv/ViscosityTracking-v0``: field strength and direction so that eta_r follows a target schedule
  (9-25) while the shear rate follows its own (the box of ``ThickeningControl-v2``);
  ``dipenv/ViscosityTrackingStressOnly-v0`` without the rate (and with Sigma_xy for eta_r);
  ``dipenv/ViscosityTrackingTiny-v0`` in the tiny box, for tests (issue 44). The tiny ids' arguments
  (:data:`TINY_KWARGS`, :data:`THICKENING_TINY_KWARGS`, :data:`TRACKING_TINY_KWARGS`) live in
  :mod:`dipenv.envs.tiny`;
* ``dipenv/ThickeningControlSurrogate-v0`` (and its stress-only id) and
  ``dipenv/ViscosityTrackingSurrogate-v0``: the same tasks over a fitted model instead of the simulator
  (docs/surrogate.md; :data:`SURROGATE_IDS`, :data:`TRACKING_SURROGATE_IDS`).

See :class:`dipenv.envs.field_control.FieldMagnitudeEnv`,
:class:`dipenv.envs.thickening_control.ThickeningControlEnv` and
:class:`dipenv.envs.viscosity_tracking.ViscosityTrackingEnv` for the full descriptions.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import register, registry

from dipenv.envs.field_control import FieldMagnitudeEnv, FieldVectorEnv
from dipenv.envs.thickening_control import ThickeningControlEnv, ThickeningControlStressOnlyEnv
from dipenv.envs.tiny import THICKENING_TINY_KWARGS, TINY_KWARGS, TRACKING_TINY_KWARGS
from dipenv.envs.viscosity_tracking import (
    TRACKING_KWARGS,
    ViscosityTrackingEnv,
    ViscosityTrackingStressOnlyEnv,
)

__all__ = [
    "ENV_IDS",
    "V1_KWARGS",
    "THICKENING_ENERGY_WEIGHT_V1",
    "THICKENING_V1_KWARGS",
    "THICKENING_V2_KWARGS",
    "THICKENING_TINY_KWARGS",
    "TINY_KWARGS",
    "TRACKING_KWARGS",
    "TRACKING_TINY_KWARGS",
    "FieldMagnitudeEnv",
    "FieldVectorEnv",
    "ThickeningControlEnv",
    "ThickeningControlStressOnlyEnv",
    "ViscosityTrackingEnv",
    "ViscosityTrackingStressOnlyEnv",
]

V1_KWARGS: dict[str, Any] = {"n_particles": 300}
"""What the ``-v1`` ids change against ``-v0``: the box. N = 300 (L = 14.1 a at phi = 0.45) is the smallest
box of the box-size study whose episode-averaged eta_r matches N = 500's at Mn 0.5 and 1 (issue 24,
docs/environments.md#box-size). The reward's target and cap follow from the tabulated (phi, N) defaults
(:mod:`dipenv.rewards`)."""

THICKENING_ENERGY_WEIGHT_V1 = 0.3
"""``w_E`` of the ``ThickeningControl*-v1`` ids (``-v0``: 1). In the N = 300 box a field lowers eta_r only
from 10 to about 7.4, so at ``w_E = 1`` no constant field beats no field on the test schedules (return
-113.2 against -127.4 at ``Mn_ref = 1`` and -130.4 at 0.5). At 0.3 the two terms of the penalty weigh about
the same at the best constant field (``Mn_ref = 0.5``: excess eta_r 0.72, energy term 0.3 x 2 = 0.60 per
interval), so a controller gains by spending less field and by thickening less alike
(docs/thickening_control.md#energy-weight, results/thickening_control/v1)."""

THICKENING_V1_KWARGS: dict[str, Any] = {**V1_KWARGS, "energy_weight": THICKENING_ENERGY_WEIGHT_V1}
"""What the thickening-control ``-v1`` ids change against ``-v0``: the box, and the energy weight."""

THICKENING_V2_KWARGS: dict[str, Any] = {**THICKENING_V1_KWARGS, "mason_min": 0.1}
"""What the thickening-control ``-v2`` ids change against ``-v1``: the strongest field, ``Mn_ref = 0.1``
instead of 0.05 (the action ``u = 1``; the rest of the log-linear map moves with it). A field below 0.1
costs ``w_E / Mn_ref > 3`` per interval, about the largest excess eta_r a field-free interval shows
(p99 4.0 on the test schedules), while no constant field below ``Mn_ref = 0.3`` lowered the excess any
further; yet those fields were the most expensive to simulate (the adaptive step: 55 s per time unit at
``Mn_ref = 0.05`` against 13 at 0.2, rate 1) and an untrained policy spends about 16% of its actions at
``u = 1`` (docs/thickening_control.md#action-range-v2)."""

_THICKENING = "dipenv.envs.thickening_control"
_TRACKING = "dipenv.envs.viscosity_tracking"
_SPECS = {
    "dipenv/FieldMagnitude-v0": ("FieldMagnitudeEnv", {}),
    "dipenv/FieldVector-v0": ("FieldVectorEnv", {}),
    "dipenv/FieldMagnitude-v1": ("FieldMagnitudeEnv", V1_KWARGS),
    "dipenv/FieldVector-v1": ("FieldVectorEnv", V1_KWARGS),
    "dipenv/FieldMagnitudeTiny-v0": ("FieldMagnitudeEnv", TINY_KWARGS),
    "dipenv/FieldVectorTiny-v0": ("FieldVectorEnv", TINY_KWARGS),
    "dipenv/ThickeningControl-v0": (f"{_THICKENING}:ThickeningControlEnv", {}),
    "dipenv/ThickeningControlStressOnly-v0": (f"{_THICKENING}:ThickeningControlStressOnlyEnv", {}),
    "dipenv/ThickeningControlTiny-v0": (f"{_THICKENING}:ThickeningControlEnv", THICKENING_TINY_KWARGS),
    "dipenv/ThickeningControl-v1": (f"{_THICKENING}:ThickeningControlEnv", THICKENING_V1_KWARGS),
    "dipenv/ThickeningControlStressOnly-v1": (
        f"{_THICKENING}:ThickeningControlStressOnlyEnv",
        THICKENING_V1_KWARGS,
    ),
    "dipenv/ThickeningControl-v2": (f"{_THICKENING}:ThickeningControlEnv", THICKENING_V2_KWARGS),
    "dipenv/ThickeningControlStressOnly-v2": (
        f"{_THICKENING}:ThickeningControlStressOnlyEnv",
        THICKENING_V2_KWARGS,
    ),
    "dipenv/ViscosityTracking-v0": (f"{_TRACKING}:ViscosityTrackingEnv", TRACKING_KWARGS),
    "dipenv/ViscosityTrackingStressOnly-v0": (f"{_TRACKING}:ViscosityTrackingStressOnlyEnv", TRACKING_KWARGS),
    "dipenv/ViscosityTrackingTiny-v0": (f"{_TRACKING}:ViscosityTrackingEnv", TRACKING_TINY_KWARGS),
}
"""Entry point and keyword arguments of each id. No ``max_episode_steps``: each env truncates itself after
its own ``episode_steps`` (``gym.make(id, episode_steps=20)`` gives 20-action episodes, as ``settings()``
says; a registered time limit would cut them at the registered length instead).

The ids register with ``disable_env_checker=True``: Gymnasium's ``PassiveEnvChecker`` (1.4) marks its
one reset check done before the env's ``reset`` returns, so a refused first reset (bad options) left it
without the data its first-step check unpacks, and the next valid ``step`` failed with ``TypeError:
cannot unpack non-iterable NoneType``, although the env refuses before changing anything. The tests run
Gymnasium's full ``check_env`` and SB3's on every id instead (``tests/test_dipenv.py``)."""

ENV_IDS = tuple(_SPECS)
"""Every registered id."""

for _env_id, (_cls, _kwargs) in _SPECS.items():
    if _env_id not in registry:
        register(
            id=_env_id,
            entry_point=_cls if ":" in _cls else f"dipenv.envs.field_control:{_cls}",
            kwargs=dict(_kwargs),
            disable_env_checker=True,
        )

SURROGATE_IDS = ("dipenv/ThickeningControlSurrogate-v0", "dipenv/ThickeningControlSurrogateStressOnly-v0")
"""The surrogates of ``ThickeningControl-v2`` and ``ThickeningControlStressOnly-v2`` (issue 43): their spaces,
schedules and reward over a fitted model of the N = 300 simulator's trajectories (docs/surrogate.md). Not in
:data:`ENV_IDS`, which lists the simulator's ids."""

for _env_id, _cls in zip(
    SURROGATE_IDS, ("ThickeningControlSurrogateEnv", "ThickeningControlSurrogateStressOnlyEnv"), strict=True
):
    if _env_id not in registry:
        register(id=_env_id, entry_point=f"dipenv.surrogate.env:{_cls}", kwargs=dict(THICKENING_V2_KWARGS))

TRACKING_SURROGATE_IDS = ("dipenv/ViscosityTrackingSurrogate-v0",)
"""The surrogate of ``ViscosityTracking-v0`` (issue 44): its spaces, schedules, targets and reward over a
fitted direction-aware model of the simulator's tracking trajectories
(docs/surrogate.md#the-tracking-surrogate); the shipped model ``dipenv/data/tracking_surrogate_v0.npz`` is the
default (``model=PATH`` runs another). Neither in :data:`ENV_IDS` nor in :data:`SURROGATE_IDS`;
``agents.train`` and the agents' commands accept it."""

for _env_id in TRACKING_SURROGATE_IDS:
    if _env_id not in registry:
        register(
            id=_env_id,
            entry_point="dipenv.surrogate.tracking_env:ViscosityTrackingSurrogateEnv",
            kwargs=dict(TRACKING_KWARGS),
        )
