"""Reference outputs of the shipped surrogate models on fixed inputs, for the bit-identity test of
``tests/test_tracking_surrogate.py`` (issue 44: adding the direction block must not change a model fitted
without it by one bit).

Uses only the API that existed before the block (``load_model``, ``begin``, ``step``, ``one_step``,
``rollout``, the registered ``ThickeningControlSurrogate-v0``), so that the same function runs on the code
before the change. ``tests/reference_data/surrogate_bit_identity.json`` was written by it on ``main``'s code
at commit dcac016 (before the block; run from outside the worktree, so that ``main``'s ``dipenv`` is the
one imported)::

    cd /tmp && PYTHONPATH=/work/main python WORKTREE/tests/surrogate_reference.py OUT.json

Floats are stored as ``float.hex`` strings, so the comparison is exact.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

MODELS = ("surrogate_v0.npz", "surrogate_v1.npz")
"""The shipped models (``dipenv/data/``)."""

MASONS = np.array([np.inf, 0.5, 0.5, 2.0, np.inf, 0.1, 20.0, 1.0])
"""The fields of the fixed episode (``Mn_ref``, ``inf``: off)."""

SCHEDULE = {"times": [0.0, 0.5, 1.0, 1.5, 2.0], "rates": [1.0, 1.0, 3.0, 3.0, 0.4]}
"""The rate schedule of the fixed episode (holds and ramps, 8 intervals of 0.25)."""


def _hex(values: Any) -> list[str]:
    return [float(v).hex() for v in np.asarray(values, dtype=np.float64).ravel()]


def reference_values(data_dir: Path) -> dict[str, Any]:
    """Outputs of every shipped model on the fixed episode, and one seeded episode of the registered
    ``ThickeningControlSurrogate-v0`` per model (flattened, as ``float.hex``)."""
    import gymnasium as gym

    import dipenv  # noqa: F401  (registers the ids)
    from dipenv.schedules import schedule_from_dict
    from dipenv.surrogate.features import interval_table
    from dipenv.surrogate.models import load_model

    table = interval_table(schedule_from_dict(SCHEDULE), len(MASONS), 0.25, 0.05)
    out: dict[str, Any] = {}
    for name in MODELS:
        model = load_model(data_dir / name)
        rng = np.random.default_rng(7)
        model.begin(model.start_frames[3], rng)
        steps, previous = [], np.inf
        for k, mason in enumerate(MASONS):
            steps.append(model.step(previous, float(mason), table, k, rng).copy())
            previous = float(mason)
        frames = np.stack([model.start_frames[:2]] * (len(MASONS) + 1), axis=1)  # (2, T + 1, 12)
        frames = frames + 0.01 * np.arange(len(MASONS) + 1)[None, :, None]
        masons = np.stack([MASONS, MASONS[::-1]])
        one_step = model.one_step(frames, masons, [table, table])
        rollout = model.rollout(model.start_frames[:2], masons, [table, table], np.random.default_rng(11), 3)
        env = gym.make("dipenv/ThickeningControlSurrogate-v0", model=str(data_dir / name))
        obs, _ = env.reset(seed=5)
        observations, rewards = [obs], []
        for u in np.linspace(-1.0, 1.0, 48):
            obs, reward, *_ = env.step(np.array([u], dtype=np.float32))
            observations.append(obs)
            rewards.append(reward)
        env.close()
        out[name] = {
            "step": _hex(steps),
            "one_step": _hex(one_step),
            "rollout": _hex(rollout),
            "env_observations": _hex(observations),
            "env_rewards": _hex(rewards),
        }
    return out


def main(argv: list[str]) -> None:
    import dipenv

    data_dir = Path(dipenv.__file__).resolve().parent / "data"
    payload = reference_values(data_dir)
    Path(argv[0]).write_text(json.dumps(payload, indent=0) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
