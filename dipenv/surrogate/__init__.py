"""The thickening-control surrogate (issue 43's second fidelity): a fitted model of the simulator's
trajectories behind the spaces, schedules and reward of ``ThickeningControl`` (``docs/surrogate.md``).

* :mod:`dipenv.surrogate.features`: what a model sees (the frame's dynamic part, the field, the rates);
* :mod:`dipenv.surrogate.models`: numpy inference of the two model kinds (ensemble of MLPs, lambda model);
* :mod:`dipenv.surrogate.data`: the simulator episodes of ``scripts/surrogate_data.py``;
* :mod:`dipenv.surrogate.env`: the environments ``dipenv/ThickeningControlSurrogate-v0`` and
  ``dipenv/ThickeningControlSurrogateStressOnly-v0``.

Fitting (torch, scipy) lives in ``scripts/fit_surrogate.py``.
"""

from dipenv.surrogate.env import (
    ThickeningControlSurrogateEnv,
    ThickeningControlSurrogateStressOnlyEnv,
    surrogate_kwargs,
)
from dipenv.surrogate.models import EnsembleModel, LambdaModel, SurrogateModel, default_model_path, load_model

__all__ = [
    "EnsembleModel",
    "LambdaModel",
    "SurrogateModel",
    "ThickeningControlSurrogateEnv",
    "ThickeningControlSurrogateStressOnlyEnv",
    "default_model_path",
    "load_model",
    "surrogate_kwargs",
]
