"""The hand-made thickening controllers (agents.controllers): feed-forward holds the instantaneous Mn, PI
feedback with anti-windup, and the tune-then-test command."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import dipenv  # noqa: F401  (registers the ids)
import sim
from agents import controllers
from agents.controllers import FeedForwardController, PIController, parse_grid
from dipenv.actions import FieldStrengthMapping

TINY = "dipenv/ThickeningControlTiny-v0"


def test_feedforward_holds_the_instantaneous_mason_number() -> None:
    """Wherever the rate of an interval is the rate the controller read (the rate in force at the end of
    the previous interval), ``info``'s instantaneous Mn = rate x Mn_ref equals ``mason_star``. Tolerance
    1e-6 relative: the action is float32 (7 digits) and maps log-linearly onto Mn_ref over 2.6 decades.
    Across the jump the controller lags by one interval (documented), and Mn is 2 / 0.5 = 4 times off."""
    env = gym.make(TINY, progress=False)
    controller = FeedForwardController(0.5).bind(env)
    schedule = {"times": [0.0, 0.1, 0.1, 0.2], "rates": [2.0, 2.0, 0.5, 0.5]}
    obs, info = env.reset(seed=0, options={"split": "test", "index": 0, "schedule": schedule})
    read = info["shear_rate"]
    held, lagged = [], []
    for _ in range(10):
        obs, _, terminated, truncated, info = env.step(controller(obs))
        same = math.isclose(info["shear_rate"], read, rel_tol=1e-9)
        (held if same else lagged).append(info["instantaneous_mason_number"])
        read = info["shear_rate_end"]
        if terminated or truncated:
            break
    assert len(held) == 9 and len(lagged) == 1
    np.testing.assert_allclose(held, 0.5, rtol=1e-6)
    np.testing.assert_allclose(lagged, 0.5 / 4, rtol=1e-6)
    env.close()


def test_feedforward_saturates_at_the_field_range_and_needs_the_rate() -> None:
    mapping = FieldStrengthMapping(mason_min=0.05, mason_max=20.0)
    controller = FeedForwardController(1.0)
    controller._mapping = mapping  # as bind() sets it
    assert controller.mason_for_rate(2.0) == 0.5
    assert controller.mason_for_rate(100.0) == 0.05  # strongest field
    assert controller.mason_for_rate(0.01) == 20.0  # weakest field
    env = gym.make("dipenv/ThickeningControlStressOnly-v0", **dipenv.THICKENING_TINY_KWARGS, progress=False)
    with pytest.raises(ValueError, match="log10_shear_rate"):
        FeedForwardController(1.0).bind(env)
    env.close()
    with pytest.raises(ValueError, match="mason_star"):
        FeedForwardController(0.0)


def _pi(labels: list[str], **kwargs: float) -> PIController:
    controller = PIController(**kwargs)  # type: ignore[arg-type]
    return controller.bind(SimpleNamespace(unwrapped=SimpleNamespace(observation_labels=labels)))


def _slog(x: float) -> float:
    return math.copysign(math.log10(1.0 + abs(x)), x)


def test_pi_law_and_anti_windup() -> None:
    """u_k = u0 + Kp e_k + Ki sum e_j with e = log10(y / y*); the integral freezes while u is saturated in
    the direction of the error, so the controller leaves saturation as soon as the error changes sign."""
    pi = _pi(["slog_eta_r", "slog_n1"], setpoint=5.0, kp=0.4, ki=0.2)
    assert pi.measured == "slog_eta_r"
    obs = np.array([_slog(50.0), 0.0])  # one decade too viscous: e = 1
    # u = 0.4 + 0.2 k for k = 1, 2, 3 (float32 actions: 1e-6), then saturated at 1 with the sum held at 3
    for k, expected in enumerate([0.6, 0.8, 1.0], start=1):
        assert float(pi(obs)[0]) == pytest.approx(expected, rel=1e-6), k
    for _ in range(20):
        assert float(pi(obs)[0]) == 1.0
    assert pi.integral == pytest.approx(3.0, rel=1e-12)
    below = np.array([_slog(0.5), 0.0])  # one decade below: e = -1, u = -0.4 + 0.2 (3 - 1) = 0
    assert float(pi(below)[0]) == pytest.approx(0.0, abs=1e-6)
    pi.reset()
    assert pi.integral == 0.0
    at_setpoint = np.array([_slog(5.0), 0.0])
    assert float(pi(at_setpoint)[0]) == pytest.approx(0.0, abs=1e-6)


def test_pi_measures_stress_on_the_stress_only_env_and_checks_gains() -> None:
    pi = _pi(["slog_shear_stress", "slog_n1"], setpoint=5.0, kp=1.0, ki=0.0)
    assert pi.measured == "slog_shear_stress"
    for bad in ({"setpoint": 0.0}, {"kp": -1.0}, {"ki": math.nan}, {"u0": 2.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            PIController(**{"setpoint": 5.0, "kp": 1.0, "ki": 1.0, **bad})


def test_parse_grid() -> None:
    assert parse_grid("feedforward", [], eta_cap=6.5) == {"mason_star": [0.25, 0.5, 1.0, 2.0, 4.0]}
    grid = parse_grid("pi", ["kp=1,2"], eta_cap=6.5)
    assert grid["kp"] == [1.0, 2.0] and grid["ki"] == [0.5, 2.0]
    assert grid["setpoint"] == [4.55, 5.52, 6.5]  # 0.7, 0.85, 1 of the cap: the box sets the cap
    assert parse_grid("pi", [], eta_cap=8.0)["setpoint"] == [5.6, 6.8, 8.0]
    assert parse_grid("pi", ["setpoint=3"], eta_cap=8.0)["setpoint"] == [3.0]
    for bad, match in (("kp", "name=v1"), ("gain=1", "gain"), ("kp=a", "numbers")):
        with pytest.raises(ValueError, match=match):
            parse_grid("pi", [bad], eta_cap=6.5)


def test_command_tunes_on_validation_and_plays_the_best_on_test(tmp_path: Path) -> None:
    """Two feed-forward points on one validation schedule; the better return is played on one test
    schedule; a rerun reuses every stored point (same files, same numbers)."""
    out = tmp_path / "ff"
    argv = [
        "--env",
        TINY,
        "--controller",
        "feedforward",
        "--grid",
        "mason_star=0.5,4",
        "--tune-episodes",
        "1",
        "--episodes",
        "1",
        "--out",
        str(out),
    ]
    summary = controllers.main(argv)
    tuning = sorted((out / "tuning").glob("*.json"))
    assert len(tuning) == 2
    returns = {json.loads(p.read_text())["params"]["mason_star"]: json.loads(p.read_text()) for p in tuning}
    best = max(returns, key=lambda m: np.mean([e["return"] for e in returns[m]["episodes"]]))
    assert summary["tuned_params"] == {"mason_star": best}
    (point,) = (out / "points").glob("*.json")
    record = json.loads(point.read_text())
    assert record["episodes"][0]["split"] == "test"
    assert {"time_above_cap", "excess_viscosity", "eta_mean"} <= set(record["episodes"][0])
    before = point.read_bytes()
    assert controllers.main(argv) == summary
    assert point.read_bytes() == before


def count_episodes(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Record the split of every episode that ``agents.controllers`` simulates from now on (through
    ``agents.open_loop.play_missing``)."""
    from agents import open_loop

    calls: list[str] = []
    real = open_loop.run_episode

    def counted(env: gym.Env, policy: object, split: str, index: int, realisation: int = 0) -> object:
        calls.append(split)
        return real(env, policy, split, index, realisation=realisation)  # type: ignore[arg-type]

    monkeypatch.setattr(open_loop, "run_episode", counted)
    return calls


def test_another_energy_weight_rescores_the_stored_points(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rerun with another ``energy_weight`` simulates no tuning point again: their stored returns are
    recomputed from the stored per-interval eta_r and field energy (exactly, the same float sums as the
    env's rewards), the tuning is re-picked, and only a newly picked point is played on test. At
    ``w_E = 100`` the weaker field (Mn* = 4, an eighth of Mn* = 0.5's energy at every rate) must win: its
    energy saving is 100 x 7/8 x the Mn* = 4 energy, far above any eta_r difference on the tiny box."""
    out = tmp_path / "ff"
    argv = ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=0.5,4"]
    argv += ["--tune-episodes", "1", "--episodes", "1", "--out", str(out)]
    controllers.main(argv)
    calls = count_episodes(monkeypatch)
    summary = controllers.main([*argv, "--env-kwargs", '{"energy_weight": 100}'])
    assert "validation" not in calls and len(calls) <= 1
    assert summary["tuned_params"] == {"mason_star": 4.0}
    cap = 7.0  # THICKENING_TINY_KWARGS' eta_cap
    for path in sorted((out / "tuning").glob("*.json")):
        (episode,) = json.loads(path.read_text())["episodes"]
        trace = episode["trace"]
        expected = [
            min(0.0, cap - eta) - 100.0 * energy
            for eta, energy in zip(trace["eta_r"], trace["field_energy"], strict=True)
        ]
        assert trace["reward"] == pytest.approx(expected, rel=1e-12)
        assert episode["return"] == pytest.approx(sum(expected), rel=1e-12)
    (point,) = (out / "points").glob("*.json")
    assert json.loads(point.read_text())["params"] == {"mason_star": 4.0}


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--grid", "mason_star=0"], "mason_star"),
        (["--split", "bogus"], "--split"),
        (["--episodes", "9"], "--split"),
        (["--workers", "0"], "--workers"),
        (["--env", "dipenv/FieldMagnitudeTiny-v0"], "thickening-control"),
        (["--env", "CartPole-v1"], "--env must be one of dipenv/"),
        (["--env-kwargs", '{"bogus": 1}'], '--env-kwargs {"bogus": 1}: '),
        (["--scheduler", "nowhere"], "argument --scheduler: must be a Dask scheduler address"),
        (["--workers", "x"], "argument --workers: must be an integer >= 1, got 'x'"),
    ],
)
def test_bad_arguments_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], match: str
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        controllers.main(["--env", TINY, "--controller", "feedforward", "--out", str(tmp_path), *extra])
    assert exit_info.value.code == 2
    assert match in capsys.readouterr().err


def test_feedforward_is_refused_on_the_stress_only_env(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kwargs = json.dumps({k: v for k, v in dipenv.THICKENING_TINY_KWARGS.items()})
    with pytest.raises(SystemExit) as exit_info:
        controllers.main(
            [
                "--env",
                "dipenv/ThickeningControlStressOnly-v0",
                "--env-kwargs",
                kwargs,
                "--controller",
                "feedforward",
                "--out",
                str(tmp_path),
            ]
        )
    assert exit_info.value.code == 2
    assert "log10_shear_rate" in capsys.readouterr().err


def test_a_changed_schedule_is_simulated_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The start-state library key does not cover the shear-rate schedules, so a point's identity holds a
    digest of its split's schedules: when the shipped schedules change (as the validation split's did on
    2026-12-03), stored points are not reused."""
    from dipenv.envs.thickening_control import ThickeningControlEnv

    argv = ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1"]
    argv += ["--tune-episodes", "1", "--episodes", "1", "--out", str(tmp_path / "ff")]
    controllers.main(argv)
    calls = count_episodes(monkeypatch)
    controllers.main(argv)
    assert calls == []  # same schedules: every point reused
    faster = sim.PiecewiseLinear((0.0, 1.0), (2.0, 2.0))
    monkeypatch.setattr(ThickeningControlEnv, "fixed_schedule", lambda self, split, index: faster)
    controllers.main(argv)
    assert calls == ["validation", "test"]


def test_evaluate_reports_tuned_controllers_beside_the_constant_fields(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """agents.evaluate --controllers: a tuned controller is a row of the table, with the thickening
    metrics (time above the cap, excess eta_r, whole-episode energy); a controller played on other
    episodes than the baseline's is refused (exit 2)."""
    from agents import evaluate, open_loop

    ff = tmp_path / "ff"
    common = ["--env", TINY, "--out"]
    controllers.main(
        ["--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1", "--episodes", "2"]
        + common
        + [str(ff)]
    )
    baseline = tmp_path / "open_loop"
    open_loop.main([*common, str(baseline), "--mason", "off,1", "--split", "test", "--episodes", "2"])
    out = tmp_path / "eval"
    result = evaluate.main(["--controllers", str(ff), "--baseline", str(baseline), "--out", str(out)])
    names = [r["name"] for r in result["rows"]]
    assert names[-1].startswith("feedforward (mason_star 1; tuned on validation)")
    row = result["rows"][-1]
    record = json.loads(next((ff / "points").glob("*.json")).read_text())
    expected = np.mean([e["excess_viscosity"] for e in record["episodes"]])
    assert row["excess_viscosity"]["mean"] == pytest.approx(expected, rel=1e-12)
    assert "time above cap" in (out / "table.md").read_text()
    # the energy target, paired per state against the best constant (agents.comparison.energy_target)
    item = next(v for v in result["verdicts"] if v["name"] == row["name"])
    best = next(r for r in result["rows"] if r["name"].startswith("best constant"))
    label = best["name"].removeprefix("best constant (").removesuffix(")")
    constant = json.loads((baseline / "points" / f"{label}.json").read_text())["episodes"]
    by_state = {i: np.mean([e["energy_mean"] for e in record["episodes"] if e["index"] == i]) for i in (0, 1)}
    theirs = {i: np.mean([e["energy_mean"] for e in constant if e["index"] == i]) for i in (0, 1)}
    if sum(theirs.values()) > 0:
        saved = 1 - sum(by_state.values()) / sum(theirs.values())
        assert item["energy_saved"] == pytest.approx(saved, rel=1e-12, abs=1e-12)
    else:
        assert item["target_verdict"] == "not paired"
    assert "| target |" in (out / "verdict.md").read_text()
    assert (out / "traces.png").exists()
    front = json.loads((out / "thickening_front.json").read_text())
    assert [p["name"] for p in front["constant_fields"]] == ["Mn1", "off"]  # the baseline's points
    assert [p["name"] for p in front["controllers_and_policies"]] == [row["name"]]
    assert front["controllers_and_policies"][0]["excess"] == pytest.approx(expected, rel=1e-12)
    assert (out / "thickening_front.png").exists()

    other = tmp_path / "ff_validation"
    controllers.main(
        ["--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1"]
        + ["--split", "validation", "--episodes", "1"]
        + common
        + [str(other)]
    )

    def refusal(folder: Path) -> str:
        with pytest.raises(SystemExit) as exit_info:
            evaluate.main(["--controllers", str(folder), "--baseline", str(baseline), "--out", str(out)])
        assert exit_info.value.code == 2
        return capsys.readouterr().err

    assert "split validation" in refusal(other)

    # Tuned for another energy weight (a copy of ff rescored, no simulation): its pick may differ, so the
    # evaluation of the default reward refuses it and names the fix.
    heavy = tmp_path / "ff_heavy"
    shutil.copytree(ff, heavy)
    controllers.main(
        ["--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1", "--episodes", "2"]
        + ["--env-kwargs", '{"energy_weight": 100}']
        + common
        + [str(heavy)]
    )
    assert "tuned for energy_weight 100" in refusal(heavy)


def test_evaluate_shares_a_baseline_between_envs_that_differ_only_in_the_observation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A PI controller on the stress-only env (the tiny arguments) is a row beside the constant fields of
    the tiny ThickeningControl env: a constant field ignores the observation, so those episodes are the
    same. A controller whose env differs in its physics or cap (here the cap) is refused, naming it."""
    from agents import evaluate, open_loop

    tiny = json.dumps(dipenv.THICKENING_TINY_KWARGS)
    baseline = tmp_path / "open_loop"
    open_loop.main(["--env", TINY, "--out", str(baseline), "--mason", "off,1", "--episodes", "2"])
    pi_args = ["--controller", "pi", "--grid", "kp=2", "ki=0.5", "setpoint=7", "--tune-episodes", "1"]
    pi_args += ["--episodes", "2"]
    stress_only = tmp_path / "pi_stress_only"
    controllers.main(
        [*pi_args, "--env", "dipenv/ThickeningControlStressOnly-v0", "--env-kwargs", tiny]
        + ["--out", str(stress_only)]
    )
    out = tmp_path / "eval"
    result = evaluate.main(
        ["--controllers", str(stress_only), "--baseline", str(baseline), "--out", str(out)]
    )
    # the row names the id it was played in, as it is not the baseline's
    assert result["rows"][-1]["name"].startswith(
        "pi on ThickeningControlStressOnly-v0 (ki 0.5, kp 2, setpoint 7;"
    )

    other_cap = tmp_path / "pi_other_cap"
    controllers.main([*pi_args, "--env", TINY, "--env-kwargs", '{"eta_cap": 6.0}', "--out", str(other_cap)])
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main(["--controllers", str(other_cap), "--baseline", str(baseline), "--out", str(out)])
    assert exit_info.value.code == 2
    assert "differ in reward" in capsys.readouterr().err


def test_a_constant_field_makes_the_same_episode_in_either_action_map() -> None:
    """Why ``agents.evaluate.physics_difference`` leaves out the action map: ``ThickeningControl-v2``
    (strongest field 0.1) shares ``-v1``'s constant fields (0.05). The tiny env with either ``mason_min``
    holds ``Mn_ref = 0.5`` through a different action ``u``; the float32 action lands within 1e-8 of 0.5
    in both maps, and the two episodes' interval eta_r agree to 1.1e-5 (measured). The 1e-3 tolerance
    leaves room for the chaotic growth of that difference on other platforms; a genuinely different field
    (``Mn_ref = 0.55``, 10% weaker) moves eta_r by more than that, so the check can fail."""
    from agents.evaluate import physics_difference
    from agents.open_loop import constant_action

    def episode(mason_min: float, mason: float) -> np.ndarray:
        env = gym.make(TINY, progress=False, **{**dipenv.THICKENING_TINY_KWARGS, "mason_min": mason_min})
        env.reset(seed=0)
        action = np.array(constant_action(env.unwrapped, mason, None), dtype=np.float32)
        etas, done = [], False
        while not done:
            _, _, terminated, truncated, info = env.step(action)
            assert info["mason_number"] == pytest.approx(mason, rel=1e-7)
            etas.append(info["eta_r"])
            done = terminated or truncated
        return np.array(etas)

    strong_map, weak_map = episode(0.05, 0.5), episode(0.1, 0.5)
    np.testing.assert_allclose(strong_map, weak_map, rtol=1e-3)
    assert np.max(np.abs(episode(0.1, 0.55) / weak_map - 1.0)) > 1e-3
    assert physics_difference(TINY, {"mason_min": 0.05}, TINY, {}) == []
    v0, v1, v2 = (f"dipenv/ThickeningControl-v{k}" for k in range(3))
    assert physics_difference(v2, {}, v1, {}) == []
    assert physics_difference("dipenv/ThickeningControlStressOnly-v2", {}, v1, {}) == []
    assert "simulation" in physics_difference(v2, {}, v0, {})


def test_pulse_alternates_above_the_rate_and_holds_below() -> None:
    """Over a schedule that is fast (rate 3), then slow (rate 0.5), then fast again: strongest field and off
    alternate while the rate read is >= rate_on (each pulse starting with the strongest field), and the
    steady Mn_ref is held below it. info's Mn_ref must equal the map of each action exactly (off: inf; the
    strongest field: Mn_min; the steady field to float32 precision of the action, 1e-6 relative)."""
    env = gym.make(TINY, progress=False)
    mason_min = env.unwrapped.mapping.mason_min
    controller = controllers.RatePulseController(rate_on=2.0, mason_steady=0.5).bind(env)
    schedule = {"times": [0.0, 0.06, 0.06, 0.12, 0.12, 0.2], "rates": [3.0, 3.0, 0.5, 0.5, 3.0, 3.0]}
    obs, info = env.reset(seed=0, options={"split": "test", "index": 0, "schedule": schedule})
    controller.reset()
    masons, read = [], []  # read: the rate the controller saw (the previous interval's end rate)
    rate_seen = info["shear_rate"]
    for _ in range(10):
        read.append(rate_seen)
        obs, _, terminated, truncated, info = env.step(controller(obs))
        masons.append(info["mason_number"])
        rate_seen = info["shear_rate_end"]
        if terminated or truncated:
            break
    # the rates read: fast x4 (the 4th interval reads the 3rd's end rate), slow x3, fast x3
    assert read == [3.0, 3.0, 3.0, 3.0, 0.5, 0.5, 0.5, 3.0, 3.0, 3.0]
    expected = [mason_min, math.inf, mason_min, math.inf, 0.5, 0.5, 0.5, mason_min, math.inf, mason_min]
    assert len(masons) == 10
    for got, want in zip(masons, expected, strict=True):
        if math.isinf(want):
            assert math.isinf(got)
        else:
            assert got == pytest.approx(want, rel=1e-6)
    env.close()


def test_pulse_checks_its_parameters_and_needs_the_rate() -> None:
    with pytest.raises(ValueError, match="rate_on"):
        controllers.RatePulseController(rate_on=0.0, mason_steady=0.5)
    with pytest.raises(ValueError, match="mason_steady"):
        controllers.RatePulseController(rate_on=2.0, mason_steady=-1.0)
    env = gym.make("dipenv/ThickeningControlStressOnly-v0", **dipenv.THICKENING_TINY_KWARGS, progress=False)
    with pytest.raises(ValueError, match="log10_shear_rate"):
        controllers.RatePulseController(rate_on=2.0, mason_steady=0.5).bind(env)
    env.close()
    assert controllers.make_controller("pulse", {"rate_on": 2.0, "mason_steady": 1.0}).rate_on == 2.0
    assert parse_grid("pulse", ["rate_on=3"], eta_cap=7.7) == {"rate_on": [3.0], "mason_steady": [0.5, 1.0]}
