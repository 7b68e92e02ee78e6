"""Residual policies: a learnt correction added to a hand-built controller's action (issue 44).

A policy that must discover a whole control law from a random start can stall where a simple feedback
law already works: on the tracking surrogate's validation episodes PPO ties the best constant field while
the angle PI cuts its error by 60% (``docs/direction.md``). Residual policy learning (Silver et al. 2018,
arXiv:1812.06298; Johannink et al. 2019, ICRA, arXiv:1812.03201) starts the agent from the controller and
lets it learn only what the controller gets wrong:

    a_env = clip(a_controller(obs) + scale * a_agent, -1, 1)

:class:`ResidualControllerWrapper` does this inside the environment, so that an SB3 agent trained on the
wrapped env learns ``a_agent`` and any agent command that plays the env plays the sum. A run asks for it
with the env argument ``residual`` (``--env-kwargs '{"residual": {"controller": "angle_pi", "params":
{"kp": 3, "ki": 1}, "scale": 0.5}}'``), which :func:`agents.rollout.make_env` takes out of the env's own
arguments; it is stored in the run's ``config.yml`` with the rest, so that the run is played with the same
controller wherever it is played (``--play-env`` carries it over).

The controller sees the env's raw observation (before any ``VecNormalize``), is reset with each episode
and keeps its state (the PI's integral) across the episode's steps, exactly as when it acts alone. With
``a_agent = 0`` the wrapped env is the controller's episode, action for action (tested).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

RESIDUAL_KEY = "residual"
"""The env argument that asks :func:`agents.rollout.make_env` for a residual env."""


def check_residual(spec: Any) -> dict[str, Any]:
    """``spec`` as ``{"controller": KIND, "params": {...}, "scale": s}`` (``scale`` in ``(0, 2]``, default
    0.5; ``params`` default ``{}``); ``ValueError`` naming ``residual`` and the valid values otherwise."""
    from agents.tracking_controllers import TRACKING_CONTROLLERS

    if (
        not isinstance(spec, dict)
        or set(spec) - {"controller", "params", "scale"}
        or "controller" not in spec
    ):
        raise ValueError(
            f"{RESIDUAL_KEY} must be a mapping with controller and optionally params and scale, got {spec!r}"
        )
    kind = spec["controller"]
    if kind not in TRACKING_CONTROLLERS:
        raise ValueError(
            f"{RESIDUAL_KEY}.controller must be one of {', '.join(TRACKING_CONTROLLERS)}, got {kind!r}"
        )
    params = spec.get("params", {})
    if not isinstance(params, dict):
        raise ValueError(
            f"{RESIDUAL_KEY}.params must be a mapping of the controller's parameters, got {params!r}"
        )
    scale = spec.get("scale", 0.5)
    if isinstance(scale, bool) or not isinstance(scale, int | float) or not (0.0 < scale <= 2.0):
        raise ValueError(f"{RESIDUAL_KEY}.scale must be a number in (0, 2], got {scale!r}")
    return {"controller": kind, "params": dict(params), "scale": float(scale)}


class ResidualControllerWrapper(gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """``env`` acting on ``clip(controller(obs) + scale * action, -1, 1)`` (module docstring).

    The action space is the env's (``Box(-1, 1, (n,))``): the agent's action is the correction in units of
    ``scale``. ``info["controller_action"]`` holds the controller's action and ``info["env_action"]`` the
    one the env was given."""

    def __init__(self, env: gym.Env, controller: str, params: dict[str, Any], scale: float = 0.5) -> None:
        from agents.tracking_controllers import make_tracking_controller

        super().__init__(env)
        box = env.action_space
        if not isinstance(box, gym.spaces.Box) or not (np.all(box.low == -1.0) and np.all(box.high == 1.0)):
            raise ValueError(f"{RESIDUAL_KEY} needs an env whose actions are Box(-1, 1), got {box}")
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"{RESIDUAL_KEY}.scale must be finite and > 0, got {scale!r}")
        try:
            made = make_tracking_controller(controller, params)
        except TypeError as error:  # an argument the controller does not take
            raise ValueError(f"{RESIDUAL_KEY}.params: {error}") from None
        self.controller = made.bind(env)
        self.scale = float(scale)
        self._obs: np.ndarray | None = None

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        reset = getattr(self.controller, "reset", None)
        if reset is not None:
            reset()
        self._obs = obs
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._obs is None:
            raise RuntimeError("reset() the env before step()")
        correction = np.asarray(action, dtype=np.float32).reshape(self.action_space.shape)
        if not np.all(np.isfinite(correction)):
            raise ValueError(f"the residual action must be finite, got {correction!r}")
        base = np.asarray(self.controller(self._obs), dtype=np.float32)
        total = np.clip(base + np.float32(self.scale) * correction, -1.0, 1.0).astype(np.float32)
        obs, reward, terminated, truncated, info = self.env.step(total)
        self._obs = obs
        info = {**info, "controller_action": base, "env_action": total}
        return obs, float(reward), terminated, truncated, info


def residual_env(env: gym.Env, spec: Any) -> ResidualControllerWrapper:
    """``env`` wrapped as the checked ``spec`` asks (:func:`check_residual`)."""
    checked = check_residual(spec)
    return ResidualControllerWrapper(env, checked["controller"], checked["params"], checked["scale"])
