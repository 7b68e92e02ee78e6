"""The surrogates (the second fidelity of issues 43 and 44): a fitted model of the simulator's trajectories
behind the spaces, schedules and reward of ``ThickeningControl`` or ``ViscosityTracking``
(``docs/surrogate.md``).

* :mod:`dipenv.surrogate.features`: what a model sees (the frame's dynamic part, the field, the rates);
* :mod:`dipenv.surrogate.models`: numpy inference of the two model kinds (ensemble of MLPs, lambda model);
* :mod:`dipenv.surrogate.data`: the simulator episodes of ``scripts/surrogate_data.py``;
* :mod:`dipenv.surrogate.env`: the environments ``dipenv/ThickeningControlSurrogate-v0`` and
  ``dipenv/ThickeningControlSurrogateStressOnly-v0``;
* :mod:`dipenv.surrogate.tracking_env`: ``dipenv/ViscosityTrackingSurrogate-v0`` (a direction-aware model).

Fitting (torch, scipy) lives in ``scripts/fit_surrogate.py``.
"""

from dipenv.surrogate.env import (
    ThickeningControlSurrogateEnv,
    ThickeningControlSurrogateStressOnlyEnv,
    surrogate_kwargs,
)
from dipenv.surrogate.models import EnsembleModel, LambdaModel, SurrogateModel, default_model_path, load_model
from dipenv.surrogate.tracking_env import ViscosityTrackingSurrogateEnv

__all__ = [
    "EnsembleModel",
    "LambdaModel",
    "SurrogateModel",
    "ThickeningControlSurrogateEnv",
    "ThickeningControlSurrogateStressOnlyEnv",
    "ViscosityTrackingSurrogateEnv",
    "default_model_path",
    "load_model",
    "surrogate_kwargs",
]
