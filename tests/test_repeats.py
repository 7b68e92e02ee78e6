"""Realisations of one episode (dipenv.realisations, agents.repeats) and their use by the open-loop
baseline, the controllers and agents.evaluate (--repeats)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dipenv  # noqa: F401  (registers the ids)
from agents import controllers, evaluate, open_loop, rollout
from agents.repeats import missing, per_state, select, within_state_sd
from dipenv.realisations import REALISATION_AMPLITUDE, perturbed_state

TINY = "dipenv/ThickeningControlTiny-v0"


def _positions(env: gym.Env, **options: object) -> np.ndarray:
    env.reset(seed=0, options={"split": "test", "index": 0, **options})
    return env.unwrapped._simulation.state.positions.copy()  # type: ignore[attr-defined]


def test_realisation_zero_is_the_stored_state_and_others_move_it_by_about_1e9() -> None:
    """Realisation 0 is the stored start state bit for bit; realisation k >= 1 moves every coordinate by
    a normal displacement of sd 1e-9 a, the same on every call, another for another k or state. Tolerance:
    the sample sd of 96 coordinates is within 40% of 1e-9 (its relative sd is about 7%) and no move
    exceeds 6 sd."""
    env = gym.make(TINY)
    stored = _positions(env)
    assert np.array_equal(_positions(env, realisation=0), stored)
    first = _positions(env, realisation=1)
    delta = first - stored
    assert 0.6 * REALISATION_AMPLITUDE < np.std(delta) < 1.4 * REALISATION_AMPLITUDE
    assert np.max(np.abs(delta)) < 6 * REALISATION_AMPLITUDE
    assert np.array_equal(_positions(env, realisation=1), first)  # reproducible
    assert not np.array_equal(_positions(env, realisation=2), first)
    box = env.unwrapped._simulation.config.box_length  # type: ignore[attr-defined]
    assert np.all((first >= 0) & (first < box))
    for bad in (-1, 1.5, True, "1"):
        with pytest.raises(ValueError, match="realisation"):
            env.reset(options={"split": "test", "index": 0, "realisation": bad})
    env.close()


def test_a_move_that_would_leave_the_box_is_reflected() -> None:
    """A coordinate within 1e-9 of a face moves inwards instead of leaving [0, L)."""
    env = gym.make(TINY)
    env.reset(seed=0, options={"split": "test", "index": 0})
    state = env.unwrapped._simulation.snapshot()  # type: ignore[attr-defined]
    env.close()
    box = 10.0
    state.positions = np.full_like(state.positions, 0.0)
    state.positions[1::2] = np.nextafter(box, 0.0)
    moved = perturbed_state(state, box, "test", 0, 3).positions
    assert np.all((moved >= 0.0) & (moved < box))
    assert np.count_nonzero(moved != state.positions) == moved.size


def test_repeat_statistics_average_realisations_per_state() -> None:
    """per_state averages a state's realisations; within_state_sd pools the sd between them (numbers by
    hand); select and missing work on (index, realisation) keys, old records without the key being
    realisation 0."""
    episodes = [
        {"index": 0, "return": 1.0},
        {"index": 0, "realisation": 1, "return": 3.0},
        {"index": 1, "realisation": 0, "return": 10.0},
        {"index": 1, "realisation": 1, "return": 14.0},
    ]
    states, means = per_state(episodes, "return")
    assert states == [0, 1] and means.tolist() == [2.0, 12.0]
    # squares: (1-2)^2 + (3-2)^2 + (10-12)^2 + (14-12)^2 = 10 over 2 degrees of freedom
    assert within_state_sd(episodes, "return") == pytest.approx(math.sqrt(5.0), rel=1e-15)
    assert math.isnan(within_state_sd(episodes[::2], "return"))
    assert [e["return"] for e in select(episodes, [1, 0], 1)] == [1.0, 10.0]
    assert missing(episodes, [0, 1, 2], 3) == [(0, 2), (1, 2), (2, 0), (2, 1), (2, 2)]
    # records without an index (hand-made, or written before indices): each is a state of its own
    states, means = per_state([{"return": 5.0}, {"return": 7.0}], "return")
    assert states == [0, 1] and means.tolist() == [5.0, 7.0]


def test_repeats_add_realisations_to_stored_points_and_evaluate_averages_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """open_loop --repeats 2 after --repeats 1 plays only realisation 1 (realisation 0 reused); the pareto
    row is the mean of the per-state means; evaluate --repeats 2 refuses a controller folder that has one
    realisation (exit 2, naming --repeats), accepts it after its rerun, and its row's return is the mean
    over states of the per-state mean of the two realisations."""
    calls: list[tuple[int, int]] = []
    real = rollout.run_episode

    def counting(env: gym.Env, policy: object, split: str, index: int, seed: int = 0, realisation: int = 0):  # type: ignore[no-untyped-def]
        calls.append((index, realisation))
        return real(env, policy, split, index, seed=seed, realisation=realisation)  # type: ignore[arg-type]

    monkeypatch.setattr(open_loop, "run_episode", counting)
    baseline = tmp_path / "open_loop"
    common = ["--env", TINY, "--mason", "off,1", "--episodes", "2", "--out", str(baseline)]
    open_loop.main(common)
    assert sorted(calls) == [(0, 0), (0, 0), (1, 0), (1, 0)]
    calls.clear()
    rows = open_loop.main([*common, "--repeats", "2"])
    assert sorted(calls) == [(0, 1), (0, 1), (1, 1), (1, 1)]
    record = json.loads((baseline / "points" / "Mn1.json").read_text())
    assert len(record["episodes"]) == 4
    row = next(r for r in rows if r["label"] == "Mn1")
    assert row["episodes"] == 2 and row["repeats"] == 2
    assert row["return"] == pytest.approx(np.mean([e["return"] for e in record["episodes"]]), rel=1e-12)
    # The two realisations are two different episodes (the move grows; the Tiny env's 10 steps suffice
    # for the interval averages to differ in their trailing digits at least).
    by_state = {(e["index"], e.get("realisation", 0)): e for e in record["episodes"]}
    assert by_state[0, 0]["trace"]["eta_r"] != by_state[0, 1]["trace"]["eta_r"]
    calls.clear()
    open_loop.main(common)  # fewer repeats than stored: nothing simulated
    assert calls == []
    # A command that names one point still summarises every point of the folder's study.
    one = ["--env", TINY, "--mason", "1", "--episodes", "2", "--out", str(baseline)]
    assert {r["label"] for r in open_loop.main(one)} == {"off", "Mn1"}
    assert calls == []

    ff = tmp_path / "ff"
    ff_args = ["--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1", "--tune-episodes", "1"]
    ff_args += ["--episodes", "2", "--out", str(ff)]
    controllers.main(ff_args)
    out = tmp_path / "eval"
    argv = ["--controllers", str(ff), "--baseline", str(baseline), "--out", str(out), "--repeats", "2"]
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main(argv)
    assert exit_info.value.code == 2
    assert "--repeats 2" in capsys.readouterr().err
    controllers.main([*ff_args, "--repeats", "2"])
    result = evaluate.main(argv)
    ff_row = result["rows"][-1]
    stored = json.loads(next((ff / "points").glob("*.json")).read_text())["episodes"]
    assert len(stored) == 4
    per_state_means = [np.mean([e["return"] for e in stored if e["index"] == i]) for i in (0, 1)]
    assert ff_row["return"]["mean"] == pytest.approx(np.mean(per_state_means), rel=1e-12)
    assert ff_row["samples"] == "2 start states x 2 realisations"
    assert math.isfinite(ff_row["episode_noise"])
    assert "2 realisations each" in (out / "table.md").read_text()
    # the controller is a verdict row, paired state by state against the best constant field
    verdict = next(v for v in result["verdicts"] if v["name"] == ff_row["name"])
    best_row = next(r for r in result["rows"] if r["name"].startswith("best constant"))
    gaps = np.asarray(per_state_means) - np.asarray(best_row["returns"][0])
    assert verdict["state_gap"] == pytest.approx(gaps.mean(), rel=1e-12, abs=1e-12)
    assert (verdict["states"], verdict["states_above"]) == (2, int(np.sum(gaps > 0)))
    assert "paired per state" in (out / "verdict.md").read_text()

    # its eta_r against the front, paired per state: the front rebuilt from the Pareto points' own eta_r on
    # each state, at the controller's mean energy
    def read(path: Path) -> dict:
        return json.loads(path.read_text())

    summary = read(baseline / "pareto.json")["points"]
    members = sorted((r for r in summary if r["pareto"]), key=lambda r: r["energy"])
    points = {m["label"]: read(baseline / "points" / f"{m['label']}.json") for m in members}

    def state_mean(episodes: list, i: int, key: str) -> float:
        return float(np.mean([e[key] for e in episodes if e["index"] == i]))

    by_hand = [
        state_mean(stored, i, "eta_second_half")
        - np.interp(
            ff_row["energy"]["mean"],
            [m["energy"] for m in members],
            [state_mean(points[m["label"]]["episodes"], i, "eta_second_half") for m in members],
        )
        for i in (0, 1)
    ]
    assert verdict["front_gap"] == pytest.approx(np.mean(by_hand), rel=1e-12, abs=1e-12)
    assert verdict["front_states"] == 2
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main([*argv[:-1], "3"])
    assert exit_info.value.code == 2
    assert "--repeats 3" in capsys.readouterr().err


def test_state_gap_pairs_each_state_after_averaging_seeds() -> None:
    """Two seeds x three states against one constant (numbers by hand): per-state means 2, 3, 4 against
    0, 5, 1 give gaps 2, -2, 3 (mean 1, two states above); a failed episode (NaN) gives NaN."""
    row = {"returns": [[1.0, 2.0, 3.0], [3.0, 4.0, 5.0]]}
    best = {"returns": [[0.0, 5.0, 1.0]]}
    gap = evaluate.state_gap(row, best)
    assert gap["state_gap"] == pytest.approx(1.0, rel=1e-15)
    assert (gap["states"], gap["states_above"]) == (3, 2)
    assert gap["state_gap_low"] < 1.0 < gap["state_gap_high"]
    assert math.isnan(evaluate.state_gap({"returns": [[1.0, math.nan, 3.0]]}, best)["state_gap"])
