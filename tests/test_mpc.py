"""agents.mpc (issue 43): model-predictive control through the surrogate. The vectorised rollout it uses is
the env's own step path (from an episode's start, and mid-episode after a field); on the surrogate env it
beats the best constant field; the same seed gives the same actions; envs it cannot control are refused;
it binds to the simulator env; ``agents.controllers --controller mpc`` tunes and plays it, with the env's
model or one named by ``--model``."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import dipenv
from agents import controllers
from agents.mpc import MPCController
from agents.rollout import constant_policy, make_env, run_episode
from dipenv.surrogate import load_model
from dipenv.surrogate.features import interval_table

SURROGATE = dipenv.SURROGATE_IDS[0]
CHEAP: dict[str, Any] = {"horizon": 4, "candidates": 32, "samples": 2, "seed": 0}


def test_the_vectorised_rollout_is_the_envs_step_path() -> None:
    model = load_model()
    env = make_env(SURROGATE)
    unwrapped: Any = env.unwrapped
    table = interval_table(unwrapped.fixed_schedule("validation", 2), 48, 0.25, 0.05)
    masons = np.array([math.inf, 0.5, 0.1, math.inf, 2.0, 0.3])
    frame = model.start_frames[3]

    def stepped(start: int, previous: float, seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        model.begin(frame, rng)
        out = []
        for k in range(start, len(masons)):
            out.append(model.step(previous, masons[k], table, k, rng).copy())
            previous = masons[k]
        return np.array(out)

    whole = model.rollout(frame[None], masons[None], [table], np.random.default_rng(7), 1)[0, 0]
    np.testing.assert_allclose(whole, stepped(0, math.inf, 7), rtol=0, atol=1e-12)
    # mid-episode: intervals 3.. after the field of interval 2
    rng = np.random.default_rng(8)
    tail = model.rollout(frame[None], masons[None, 3:], [table.window(3, 48)], rng, 1, previous=masons[2:3])
    tail = tail[0, 0]
    np.testing.assert_allclose(tail, stepped(3, masons[2], 8), rtol=0, atol=1e-12)
    assert table.window(3, 5).rate_initial == table.rate_end[2]


def returns(env: gym.Env, policy: object, episodes: int) -> np.ndarray:
    return np.array(
        [sum(run_episode(env, policy, "validation", i, seed=i).reward) for i in range(episodes)]  # type: ignore[arg-type]
    )


def test_mpc_beats_the_best_constant_field_on_the_surrogate() -> None:
    """4 validation episodes (env seeds 0-3): MPC against the best of five constant fields on the same
    episodes (Mn_ref 0.25-2 or off). Measured: MPC -38.3 against the best constant (0.5) -76.6, a margin of
    38; over 10 seeds of both the margin against Mn_ref 0.5 was 24-47."""
    env = make_env(SURROGATE)
    mapping = env.unwrapped.mapping  # type: ignore[attr-defined]
    constants = {
        mason: returns(env, constant_policy([mapping.action_for(mason)]), 4).mean()
        for mason in (0.25, 0.5, 1.0, 2.0, math.inf)
    }
    best = max(constants.values())
    tic = time.perf_counter()
    mpc = returns(env, MPCController(**CHEAP).bind(env), 4)
    per_decision = (time.perf_counter() - tic) / (4 * 48)
    assert mpc.mean() > best + 10.0, (mpc, constants)
    assert per_decision < 0.2  # about 5 ms here; a simulator step takes about 1 s


def test_same_seed_same_actions() -> None:
    env = make_env(SURROGATE)

    def actions(seed: int) -> list[list[float]]:
        controller = MPCController(**{**CHEAP, "seed": seed}).bind(env)
        return run_episode(env, controller, "validation", 1, seed=5).action

    first = actions(0)
    assert actions(0) == first
    assert actions(1) != first


def test_envs_it_cannot_control_are_refused() -> None:
    with pytest.raises(ValueError, match="lacks slog_eta_r.*stress-only"):
        MPCController().bind(make_env(dipenv.SURROGATE_IDS[1]))
    with pytest.raises(ValueError, match="fitted at n_particles=300"):
        MPCController().bind(make_env("dipenv/ThickeningControlTiny-v0"))
    with pytest.raises(ValueError, match="needs a thickening-control env"):
        MPCController().bind(make_env("dipenv/FieldMagnitudeTiny-v0"))
    for bad in ({"horizon": 0}, {"candidates": 2.5}, {"elites": 9, "candidates": 8}, {"seed": -1}):
        with pytest.raises(ValueError):
            MPCController(**bad)  # type: ignore[arg-type]
    with pytest.raises(RuntimeError, match="bind"):
        MPCController()(np.zeros(15))


def test_it_binds_to_the_simulator_env() -> None:
    """On ThickeningControl-v2 the shipped surrogate is the internal model and the simulator the plant;
    the schedule comes from the env (set here as a reset would set it, without simulating)."""
    env = gym.make("dipenv/ThickeningControl-v2")
    unwrapped = env.unwrapped
    controller = MPCController(**CHEAP).bind(env)
    assert controller._surrogate.kind == "ensemble"
    unwrapped._schedule = unwrapped.fixed_schedule("validation", 0)  # type: ignore[attr-defined]
    controller.reset()
    obs = np.zeros(15, dtype=np.float32)
    obs[:12] = load_model().start_frames[0]
    obs[14] = math.log10(unwrapped._schedule(0.0))  # type: ignore[attr-defined]
    first = controller(obs)
    assert first.shape == (1,) and -1.0 <= float(first[0]) <= 1.0
    controller.reset()
    assert controller(obs) == first


def test_the_controllers_command_tunes_and_plays_mpc(tmp_path: Path) -> None:
    out = tmp_path / "mpc"
    summary = controllers.main(
        ["--env", SURROGATE, "--controller", "mpc", "--grid", "horizon=2,3", "candidates=8", "samples=1"]
        + ["--tune-episodes", "2", "--episodes", "2", "--out", str(out)]
    )
    assert summary["tuned_params"]["horizon"] in (2.0, 3.0) and summary["library_key"] is None
    assert len(list((out / "tuning").glob("*.json"))) == 2
    played = json.loads((out / "points" / f"{summary['label']}.json").read_text())
    assert len(played["episodes"]) == 2


def test_the_controllers_command_plans_with_a_named_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--model FILE`` is the planner's model: its digest joins the identity (another file is refused in
    the same folder), the planner loads it (the actions differ from the env's own model's), and only MPC
    takes it; a missing file is named."""
    v1 = Path(dipenv.__file__).parent / "data" / "surrogate_v1.npz"
    base = ["--env", SURROGATE, "--controller", "mpc", "--grid", "horizon=2", "candidates=8", "samples=1"]
    base += ["--tune-episodes", "1", "--split", "validation", "--episodes", "1"]
    own = controllers.main([*base, "--out", str(tmp_path / "own")])
    named = controllers.main([*base, "--model", str(v1), "--out", str(tmp_path / "v1")])
    assert "model_sha256" not in own and len(named["model_sha256"]) == 16
    manifest = json.loads((tmp_path / "v1" / "manifest.json").read_text())
    assert manifest["params"]["model_sha256"] == named["model_sha256"]
    actions = [
        json.loads((tmp_path / d / "points" / f"{s['label']}.json").read_text())["episodes"][0]["trace"][
            "action"
        ]
        for d, s in (("own", own), ("v1", named))
    ]
    assert not np.allclose(np.asarray(actions[0], float), np.asarray(actions[1], float))
    with pytest.raises(SystemExit) as refused:  # another model in the v1 folder: another identity
        controllers.main([*base, "--out", str(tmp_path / "v1")])
    assert refused.value.code == 2
    pulse = ["--env", SURROGATE, "--controller", "pulse", "--tune-episodes", "1", "--split", "validation"]
    for argv, message in (
        ([*base, "--model", str(tmp_path / "none.npz")], "no such file"),
        ([*pulse, "--model", str(v1)], "mpc only"),
    ):
        with pytest.raises(SystemExit) as error:
            controllers.main([*argv, "--out", str(tmp_path / "bad")])
        assert error.value.code == 2 and message in capsys.readouterr().err
