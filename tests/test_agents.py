"""agents: task runner (local pool, Dask LocalCluster if installed), hyperparameters, and open_loop ->
train (PPO, SAC; resume) -> evaluate end to end on the tiny environment."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import dipenv
from agents import evaluate, open_loop, train
from agents.rollout import make_env
from agents.tasks import parse_seeds, run_tasks

ENV = "dipenv/FieldMagnitudeTiny-v0"
SHORT = ["n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32"]


@pytest.fixture(scope="module", autouse=True)
def state_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("dipenv_cache_agents")
    patcher = pytest.MonkeyPatch()
    patcher.setenv("DIPENV_CACHE_DIR", str(root))
    yield root
    patcher.undo()


def _square(x: int) -> int:
    return x * x


def test_parse_seeds() -> None:
    assert parse_seeds("0-4") == [0, 1, 2, 3, 4]
    assert parse_seeds("3, 0,7-8") == [0, 3, 7, 8]
    for bad in ("4-2", "-1", "a", ""):
        with pytest.raises(ValueError, match="seeds"):
            parse_seeds(bad)


def test_run_tasks_local_pool_keeps_order() -> None:
    assert run_tasks(_square, [3, 1, 2], workers=1) == [9, 1, 4]
    assert run_tasks(_square, [3, 1, 2], workers=2) == [9, 1, 4]


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="dask.distributed not installed")
def test_run_tasks_on_dask_local_cluster() -> None:
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        assert run_tasks(_square, [3, 1, 2], scheduler=cluster.scheduler_address) == [9, 1, 4]


def test_hyperparameters_for_every_id() -> None:
    for algo in train.ALGOS:
        for env_id in dipenv.ENV_IDS:
            params = train.load_hyperparams(algo, env_id, {"gamma": 0.5})
            assert params["gamma"] == 0.5 and params["n_envs"] >= 1 and params["n_timesteps"] > 0
    with pytest.raises(ValueError, match="no ppo hyperparameters"):
        train.load_hyperparams("ppo", "CartPole-v1")
    assert train.parse_overrides(["policy_kwargs={net_arch: [8]}"]) == {"policy_kwargs": {"net_arch": [8]}}


def test_training_returns_round_trip_through_csv(tmp_path: Path) -> None:
    """A resumed run's TensorBoard logs (two, overlapping at one step, with another tag beside SB3's
    rollout/ep_rew_mean) -> training_returns.csv -> the same arrays once the logs are gone."""
    from torch.utils.tensorboard import SummaryWriter

    run = tmp_path / "seed0"
    parts = {"run_1": {512: -348.5259, 1024: -330.51, 1536: -1.0}, "run_2": {1536: -320.66, 2048: -299.125}}
    for name, points in parts.items():
        writer = SummaryWriter(log_dir=str(run / "tb" / name))
        for step, value in points.items():
            writer.add_scalar("rollout/ep_rew_mean", value, step)
            writer.add_scalar("train/loss", 7.0, step)
        writer.close()
    steps, returns = evaluate.training_returns(run)  # from the logs
    assert steps.tolist() == [512, 1024, 1536, 2048]  # the later log wins at 1536
    assert returns == pytest.approx([-348.5259, -330.51, -320.66, -299.125], rel=1e-6)  # float32 in the logs
    path = evaluate.write_training_returns(run)
    assert path == run / "training_returns.csv"
    assert path.read_text().splitlines()[:2] == ["steps,ep_rew_mean", f"512,{float(returns[0])!r}"]
    shutil.rmtree(run / "tb")
    steps_csv, returns_csv = evaluate.training_returns(run)  # from the CSV alone
    assert np.array_equal(steps_csv, steps) and np.array_equal(returns_csv, returns)
    assert steps_csv.dtype == steps.dtype and returns_csv.dtype == returns.dtype
    with pytest.raises(FileNotFoundError, match="no TensorBoard logs"):
        evaluate.write_training_returns(run)


@pytest.mark.parametrize(
    ("module", "arguments", "named"),
    [
        (train, ["--seeds", "a-b"], "argument --seeds: seeds must look like 0-4"),
        (train, ["--hyperparams", "gamma"], "--hyperparams"),
        (train, ["--env-kwargs", "{bad"], "--env-kwargs"),
        (train, ["--env-kwargs", "[1]"], "--env-kwargs"),
        (train, ["--out", ""], "argument --out: must name a directory"),
        (train, ["--algo", "ppo", "--env", "dipenv/Unknown-v0"], "--env/--algo"),
        (open_loop, ["--env-kwargs", "{bad"], "--env-kwargs"),
        (open_loop, ["--mason", "1,abc"], "--mason"),
        (open_loop, ["--mason", "1000"], "--mason"),
        (open_loop, ["--episodes", "0"], "--episodes"),
    ],
)
def test_bad_command_line_input_exits_2_naming_the_argument(
    module: object, arguments: list[str], named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["--env", ENV, "--out", str(tmp_path / "out")]
    with pytest.raises(SystemExit) as error:
        module.main([*base, *arguments])  # type: ignore[attr-defined]
    assert error.value.code == 2
    message = capsys.readouterr().err
    assert f"python -m agents.{module.__name__.split('.')[-1]}: error: {named}" in message  # type: ignore[attr-defined]
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def _recomputed_verdict(out: Path, baseline: Path, runs: list[str]) -> dict[str, Any]:
    """A policy's verdict numbers recomputed from the raw data, as agents/comparison.py defines them: the
    policy's episodes as played (``out/runs/<run>.json``), the baseline's Pareto points (``pareto.json``)
    and its per-interval traces (``points/*.json``, scored here by hand for the env's default reward:
    their stored returns may be for another). The front's eta_r at the policy's energy: its Pareto points
    joined linearly, flat beyond the ends. The return gap: over seeds, the mean of (the seed's mean return
    minus the best constant's mean return on the same states)."""
    reward = make_env(ENV).unwrapped.reward_function

    def score(trace: dict[str, Any]) -> float:
        return sum(
            -abs(eta - reward.target_viscosity) - reward.energy_weight * energy
            for eta, energy in zip(trace["eta_r"], trace["field_energy"], strict=True)
        )

    played = [json.loads((out / "runs" / f"{run}.json").read_text())["episodes"] for run in runs]
    states = sorted(e["index"] for e in played[0])
    assert all(sorted(e["index"] for e in episodes) == states for episodes in played)
    assert not any(e["failed"] for episodes in played for e in episodes)
    for e in (e for episodes in played for e in episodes):
        assert e["return"] == pytest.approx(score(e["trace"]), rel=1e-12)  # score() is the env's reward
    eta = float(np.mean([e["eta_second_half"] for episodes in played for e in episodes]))
    energy = float(np.mean([e["energy_second_half"] for episodes in played for e in episodes]))
    front = sorted(
        (p["energy"], p["eta_second_half"])
        for p in json.loads((baseline / "pareto.json").read_text())["points"]
        if p["pareto"]
    )
    if energy <= front[0][0]:
        front_eta = front[0][1]
    elif energy >= front[-1][0]:
        front_eta = front[-1][1]
    else:
        pairs = zip(front[:-1], front[1:], strict=True)
        (e0, y0), (e1, y1) = next((a, b) for a, b in pairs if a[0] <= energy <= b[0])
        front_eta = y0 + (y1 - y0) * (energy - e0) / (e1 - e0)
    constants = {}  # label -> mean return over the policy's states
    for path in sorted((baseline / "points").glob("*.json")):
        point = json.loads(path.read_text())
        episodes = [e for e in point["episodes"] if e["index"] in states]
        assert sorted(e["index"] for e in episodes) == states and not any(e["failed"] for e in episodes)
        constants[point["label"]] = float(np.mean([score(e["trace"]) for e in episodes]))
    best = max(constants, key=lambda label: constants[label])
    gaps = [float(np.mean([e["return"] for e in episodes])) - constants[best] for episodes in played]
    return {
        "eta": eta,
        "energy": energy,
        "front_eta": front_eta,
        "eta_minus_front": eta - front_eta,
        "best_label": best,
        "return_gap": float(np.mean(gaps)),
        "seeds_above": sum(g > 0 for g in gaps),
    }


def test_open_loop_train_evaluate_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    baseline = tmp_path / "open_loop"
    rows = open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1,0.2", "--episodes", "1"])
    assert {r["label"] for r in rows} == {"off", "Mn1", "Mn0.2"}
    for name in ("pareto.csv", "pareto.json", "pareto.png", "best_constant.json", "command.txt"):
        assert (baseline / name).exists(), name
    stamp = (baseline / "points" / "Mn1.json").stat().st_mtime_ns
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1,0.2", "--episodes", "1"])
    assert (baseline / "points" / "Mn1.json").stat().st_mtime_ns == stamp  # resumed, not recomputed
    # Another reward rescores the stored intervals (no new simulation): r = -|eta - 3| - 0.5 <1/Mn> per
    # interval, recomputed here by hand from the stored traces (exact up to summation order).
    kwargs = ["--env-kwargs", '{"target_viscosity": 3.0, "energy_weight": 0.5}']
    rescored = open_loop.main(
        ["--env", ENV, "--out", str(baseline), "--mason", "off,1,0.2", "--episodes", "1", *kwargs]
    )
    stored = json.loads((baseline / "points" / "Mn1.json").read_text())
    assert stored["identity"] == json.loads(json.dumps(stored["identity"]))  # same point, rewritten:
    trace = stored["episodes"][0]["trace"]  # its stored rewards are now those of the new reward
    by_hand = sum(
        -abs(eta - 3.0) - 0.5 * e for eta, e in zip(trace["eta_r"], trace["field_energy"], strict=True)
    )
    assert next(r for r in rescored if r["label"] == "Mn1")["return"] == pytest.approx(by_hand, rel=1e-12)
    assert by_hand != pytest.approx(next(r for r in rows if r["label"] == "Mn1")["return"], rel=1e-3)
    assert stored["episodes"][0]["return"] == pytest.approx(by_hand, rel=1e-12)

    ppo = tmp_path / "ppo"
    common = ["--env", ENV, "--timesteps", "64", "--n-envs", "1", "--no-progress"]
    train.main([*common, "--algo", "ppo", "--seeds", "0-1", "--out", str(ppo), "--hyperparams", *SHORT])
    run = ppo / "seed0"
    for name in ("config.yml", "command.txt", "model.zip", "vecnormalize.pkl", "result.json"):
        assert (run / name).exists(), name
    assert any((run / "checkpoints").glob("ckpt_*_steps.zip"))
    assert (run / "eval" / "evaluations.npz").exists() and any((run / "tb").iterdir())
    assert any((run / "monitor").glob("*.monitor.csv"))
    config = yaml.safe_load((run / "config.yml").read_text())
    assert config["seed"] == 0 and config["algo"] == "ppo" and "sim_source" in config["versions"]
    assert "agents.train" in (run / "command.txt").read_text()

    # Finished: a rerun returns at once. Longer: it resumes from the last checkpoint.
    train.main([*common, "--algo", "ppo", "--seed", "0", "--out", str(run), "--hyperparams", *SHORT])
    (run / "result.json").unlink()
    monitor = next((run / "monitor").glob("*.monitor.csv"))
    episodes_before = monitor.read_text().splitlines()
    train.main(
        [
            "--env",
            ENV,
            "--timesteps",
            "128",
            "--n-envs",
            "1",
            "--no-progress",
            "--algo",
            "ppo",
            "--seed",
            "0",
            "--out",
            str(run),
            "--hyperparams",
            *SHORT,
        ]
    )
    result = json.loads((run / "result.json").read_text())
    assert result["resumed_from"] == 64 and result["timesteps"] >= 128
    # the validation log keeps the evaluation made before the interruption (SB3 alone would restart it)
    with np.load(run / "eval" / "evaluations.npz") as log:
        assert [int(t) for t in log["timesteps"]] == [64, 128]
    episodes_after = monitor.read_text().splitlines()  # appended to, not restarted
    assert episodes_after[: len(episodes_before)] == episodes_before
    assert len(episodes_after) > len(episodes_before)

    sac = tmp_path / "sac"
    train.main(
        [
            *common,
            "--algo",
            "sac",
            "--seeds",
            "0-1",
            "--out",
            str(sac),
            "--hyperparams",
            "learning_starts=16",
            "batch_size=16",
            "eval_freq=64",
            "checkpoint_freq=32",
        ]
    )
    # checkpoints at 32 and 64 steps; only the newest replay buffer is kept (agents.callbacks)
    assert (sac / "seed0" / "model.zip").exists()
    assert sorted(p.name for p in (sac / "seed0" / "checkpoints").glob("ckpt_*_steps.zip")) == [
        "ckpt_32_steps.zip",
        "ckpt_64_steps.zip",
    ]
    assert [p.name for p in (sac / "seed0" / "checkpoints").glob("ckpt_replay_buffer_*")] == [
        "ckpt_replay_buffer_64_steps.pkl"
    ]
    # Both seeds record the same hyperparameters: SAC writes use_sde into the policy_kwargs it is given,
    # which leaked into the second seed's config.yml while the seeds shared one dict (then its rerun was
    # refused as "a different run").
    configs = [yaml.safe_load((sac / f"seed{s}" / "config.yml").read_text()) for s in (0, 1)]
    assert configs[0]["hyperparams"] == configs[1]["hyperparams"]
    assert "use_sde" not in configs[1]["hyperparams"]["policy_kwargs"]

    out = tmp_path / "evaluation"
    validation = tmp_path / "open_loop_validation"
    open_loop.main(
        [
            "--env",
            ENV,
            "--out",
            str(validation),
            "--mason",
            "off,1",
            "--split",
            "validation",
            "--episodes",
            "1",
        ]
    )
    capsys.readouterr()
    evaluate.main(
        [
            str(ppo),
            str(sac),
            "--baseline",
            str(baseline),
            "--out",
            str(out),
            "--validation-baseline",
            str(validation),
        ]
    )
    printed = capsys.readouterr().out
    assert "no field" in printed and "best constant" in printed and "ppo (ppo)" in printed
    # The baseline was last scored with target 3.0; the table rescores it with the policies' (default) reward.
    # (Other arguments, another folder: the first one belongs to the evaluation of both policies.)
    default_target = make_env(ENV).unwrapped.reward_function.target_viscosity
    off = json.loads((baseline / "points" / "off.json").read_text())["episodes"][0]["trace"]
    off_return = sum(-abs(eta - default_target) for eta in off["eta_r"])
    both = out
    out = tmp_path / "evaluation_ppo"
    no_field = next(
        r
        for r in evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out)])["rows"]
        if r["name"] == "no field"
    )
    assert default_target != 3.0 and no_field["return"]["mean"] == pytest.approx(off_return, rel=1e-12)
    for name in ("table.md", "results.json", "traces.png", "pareto.png", "verdict.md", "learning.png"):
        assert (out / name).exists(), name
    results = json.loads((out / "results.json").read_text())
    ppo_row = next(r for r in results["rows"] if r["name"] == "ppo (ppo)")
    assert ppo_row["samples"] == "2 training seeds" and len(ppo_row["per_seed"]["eta"]) == 2
    verdict = next(v for v in results["verdicts"] if v["name"] == "ppo (ppo)")
    assert verdict["seeds"] == 2 and 0.0 <= verdict["off_share"] <= 1.0 and verdict["action_std"] >= 0.0
    expected = _recomputed_verdict(out, baseline, ["ppo_seed0", "ppo_seed1"])
    assert any(r["name"] == f"best constant ({expected['best_label']})" for r in results["rows"])
    for key in ("eta", "energy", "front_eta", "eta_minus_front", "return_gap"):
        assert verdict[key] == pytest.approx(expected[key]), key
    assert verdict["seeds_above"] == expected["seeds_above"]
    assert "front" in verdict["verdict"] and "ppo (ppo)" in (out / "verdict.md").read_text()
    # Played runs are known by their model's contents, not its modification time: a fresh checkout of the
    # committed results (new times, same files) replays nothing
    stamp = (out / "runs" / "ppo_seed0.json").stat().st_mtime_ns
    later = (run / "model.zip").stat().st_mtime_ns + 10**9
    os.utime(run / "model.zip", ns=(later, later))
    evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out)])
    assert (out / "runs" / "ppo_seed0.json").stat().st_mtime_ns == stamp

    # --policy-repeats: the trained runs play each state twice (realisations 0, 1), the baseline once; the
    # row averages each seed's realisations first
    out_r2 = tmp_path / "evaluation_r2"
    result = evaluate.main(
        [str(ppo), "--baseline", str(baseline), "--out", str(out_r2), "--policy-repeats", "2"]
    )
    played = [json.loads((out_r2 / "runs" / f"ppo_seed{k}.json").read_text())["episodes"] for k in (0, 1)]
    assert [sorted((e["index"], e["realisation"]) for e in eps) for eps in played] == [[(0, 0), (0, 1)]] * 2
    per_seed = [np.mean([e["return"] for e in eps]) for eps in played]
    row = next(r for r in result["rows"] if r["name"] == "ppo (ppo)")
    assert row["per_seed"]["return"] == pytest.approx(per_seed, rel=1e-12)
    assert "(2 per state and training seed for the policies)" in (out_r2 / "table.md").read_text()
    # An evaluation stopped part way through a run resumes at the next episode: the finished ones come
    # from the partial file (marked here, so a replay would show), the rest are played as before
    stored_file = out_r2 / "runs" / "ppo_seed0.json"
    stored = json.loads(stored_file.read_text())
    first, second = stored["episodes"]
    partial_file = out_r2 / "runs" / "ppo_seed0.partial.json"
    partial_file.write_text(json.dumps({"identity": stored["identity"], "episodes": [{**first, "mark": 1}]}))
    stored_file.unlink()
    evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out_r2), "--policy-repeats", "2"])
    resumed = json.loads(stored_file.read_text())["episodes"]
    assert resumed[0] == {**first, "mark": 1} and resumed[1] == second and not partial_file.exists()
    # a partial file of another identity (e.g. another model) is not used
    other = {**stored["identity"], "model_sha256": "0"}
    partial_file.write_text(json.dumps({"identity": other, "episodes": [{**first, "mark": 1}]}))
    stored_file.unlink()
    evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out_r2), "--policy-repeats", "2"])
    assert json.loads(stored_file.read_text())["episodes"] == [first, second]

    # Bad inputs exit 2 naming the argument: no run in the folder, a baseline of another env
    with pytest.raises(SystemExit) as missing:
        evaluate.main([str(tmp_path / "nowhere"), "--baseline", str(baseline), "--out", str(out)])
    assert missing.value.code == 2 and "RUN_DIRS" in capsys.readouterr().err
    other = tmp_path / "other_baseline"
    shutil.copytree(baseline, other)
    pareto = json.loads((other / "pareto.json").read_text())
    (other / "pareto.json").write_text(json.dumps({**pareto, "env_id": "dipenv/FieldVectorTiny-v0"}))
    with pytest.raises(SystemExit) as mismatch:
        evaluate.main([str(ppo), "--baseline", str(other), "--out", str(out)])
    assert mismatch.value.code == 2 and "FieldVectorTiny-v0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as no_states:
        evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), "--episodes", "0"])
    assert no_states.value.code == 2 and "--episodes" in capsys.readouterr().err

    # The best-validation checkpoint of each seed (with the normalisation saved alongside it), in a folder
    # of its own (other arguments: the protocol refuses them in another evaluation's folder)
    with pytest.raises(SystemExit) as other_arguments:
        evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), "--model", "best"])
    assert other_arguments.value.code == 2 and "model='final' there" in capsys.readouterr().err
    out = tmp_path / "evaluation_best"
    best = evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), "--model", "best"])
    assert any(r["name"] == "ppo (ppo), best validation" for r in best["rows"])
    assert sorted(p.name for p in (out / "runs").glob("*_best.json")) == [
        "ppo_seed0_best.json",
        "ppo_seed1_best.json",
    ]
    with np.load(run / "eval" / "evaluations.npz") as log:
        steps = int(log["timesteps"][np.argmax(log["results"].mean(axis=1))])
    assert evaluate.model_files(run, "best")[0].name == f"ckpt_{steps}_steps.zip"
    # a run still training (no model.zip yet) is played at its best validation checkpoint
    training = tmp_path / "training" / "seed0"
    shutil.copytree(run, training)
    (training / "model.zip").unlink()
    best_early = evaluate.main(
        [str(training.parent), "--baseline", str(baseline), "--out", str(tmp_path / "e2"), "--model", "best"]
    )
    played_best = json.loads((out / "runs" / "ppo_seed0_best.json").read_text())["episodes"]
    assert best_early["rows"][-1]["return"]["mean"] == pytest.approx(
        np.mean([e["return"] for e in played_best]), rel=1e-12
    )
    with pytest.raises(SystemExit) as unfinished:
        evaluate.main([str(training.parent), "--baseline", str(baseline), "--out", str(tmp_path / "e3")])
    assert unfinished.value.code == 2 and "no model.zip" in capsys.readouterr().err

    # Sampled actions: reproducible (torch seeded per start state), different from the mean's
    sampled = [tmp_path / "s1", tmp_path / "s2"]
    for folder, actions in zip(sampled, ("sampled", "both"), strict=True):
        result = evaluate.main(
            [str(run), "--baseline", str(baseline), "--out", str(folder), "--actions", actions]
        )
    assert [r["name"] for r in result["rows"][-2:]] == ["ppo (ppo)", "ppo (ppo), sampled"]
    traces = [json.loads((f / "runs" / "ppo_seed0_stochastic.json").read_text()) for f in sampled]
    assert traces[0]["episodes"][0]["trace"]["action"] == traces[1]["episodes"][0]["trace"]["action"]
    mean = json.loads((both / "runs" / "ppo_seed0.json").read_text())["episodes"][0]["trace"]["action"]
    assert traces[0]["episodes"][0]["trace"]["action"] != mean


def test_train_with_subprocess_envs(tmp_path: Path) -> None:
    """Two environments in a SubprocVecEnv (the default for n_envs = 2)."""
    out = tmp_path / "ppo2"
    shutil.rmtree(out, ignore_errors=True)
    results = train.main(
        [
            "--env",
            ENV,
            "--algo",
            "ppo",
            "--seed",
            "3",
            "--out",
            str(out),
            "--timesteps",
            "64",
            "--no-progress",
            "--hyperparams",
            *SHORT,
        ]
    )
    assert results[0]["timesteps"] >= 64
    assert len(list((out / "monitor").glob("*.monitor.csv"))) == 2


def test_evaluate_plays_runs_trained_with_a_coarser_step_in_the_baselines_physics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--play-kwargs: a run trained with other simulation settings (here a tighter displacement bound, so
    that the step count surely changes) is refused beside a baseline of the reference physics, naming the
    setting and the option; played with ``{"simulation_overrides": {}}`` its episodes are those of its
    policy in the reference env, replayed here by hand (bit for bit), and not those of its training env."""
    import pickle

    from stable_baselines3 import PPO

    from agents.rollout import run_episode

    overrides = {"simulation_overrides": {"max_displacement": 0.001}}
    baseline = tmp_path / "open_loop"
    open_loop.main(["--env", ENV, "--out", str(baseline), "--mason", "off,1", "--episodes", "1"])
    ppo = tmp_path / "ppo"
    train.main(
        ["--env", ENV, "--timesteps", "64", "--n-envs", "1", "--no-progress", "--algo", "ppo", "--seeds", "0"]
        + ["--env-kwargs", json.dumps(overrides), "--out", str(ppo), "--hyperparams", *SHORT]
    )
    out = tmp_path / "evaluation"
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out)])
    message = capsys.readouterr().err
    assert refused.value.code == 2 and "simulation_overrides" in message and "--play-kwargs" in message

    play = ["--play-kwargs", '{"simulation_overrides": {}}']
    evaluate.main([str(ppo), "--baseline", str(baseline), "--out", str(out), *play])
    played = json.loads((out / "runs" / "ppo_seed0.json").read_text())["episodes"][0]["trace"]["eta_r"]
    assert '{"simulation_overrides": {}}' in (out / "table.md").read_text()

    model = PPO.load(str(ppo / "seed0" / "model.zip"), device="cpu")
    with open(ppo / "seed0" / "vecnormalize.pkl", "rb") as handle:
        normaliser = pickle.load(handle)
    normaliser.training = False

    def policy(obs: np.ndarray) -> np.ndarray:
        return np.asarray(model.predict(normaliser.normalize_obs(obs), deterministic=True)[0])

    def replay(kwargs: dict[str, Any]) -> list[float]:
        env = make_env(ENV, {**kwargs, "progress": False})
        trace = run_episode(env, policy, "test", 0).to_dict()
        env.close()
        return list(trace["eta_r"])

    assert played == replay({})
    assert played != replay(overrides)


def test_sigterm_stops_training_with_a_checkpoint_and_the_rerun_resumes_there(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """SIGTERM during agents.train: the run stops at the next step with a checkpoint (model and
    normalisation) at that step, between the periodic ones, exits 143 and writes no result; the same
    command resumes from that step and finishes."""
    import os
    import signal

    from agents import callbacks

    sent = []
    original = callbacks.PhysicsLoggerCallback._on_step

    def signalling(self: callbacks.PhysicsLoggerCallback) -> bool:
        if self.num_timesteps == 40 and not sent:  # between the checkpoints at 32 and 64
            sent.append(True)
            os.kill(os.getpid(), signal.SIGTERM)
        return original(self)

    monkeypatch.setattr(callbacks.PhysicsLoggerCallback, "_on_step", signalling)
    caught = []  # outside training a SIGTERM lands here, not in pytest's default (which would end it)

    def outer(signum: int, frame: object) -> None:
        caught.append(signum)

    previous = signal.signal(signal.SIGTERM, outer)
    run = tmp_path / "ppo"
    argv = ["--env", ENV, "--timesteps", "64", "--n-envs", "1", "--no-progress", "--algo", "ppo"]
    argv += ["--seed", "0", "--out", str(run), "--hyperparams", *SHORT]
    try:
        with pytest.raises(SystemExit) as stopped:
            train.main(argv)
    finally:
        assert signal.getsignal(signal.SIGTERM) is outer  # agents.train put the outer handler back
        signal.signal(signal.SIGTERM, previous)
    assert stopped.value.code == 128 + signal.SIGTERM and caught == []
    assert "stopped by SIGTERM at step 40" in capsys.readouterr().err
    assert (run / "checkpoints" / "ckpt_40_steps.zip").exists()
    assert (run / "checkpoints" / "ckpt_vecnormalize_40_steps.pkl").exists()
    assert not (run / "result.json").exists() and not (run / "model.zip").exists()

    monkeypatch.setattr(callbacks.PhysicsLoggerCallback, "_on_step", original)
    result = train.main(argv)[0]
    assert result["resumed_from"] == 40 and result["timesteps"] >= 64
    # validation and checkpoints stay on the run's own step grid (eval_freq 64, checkpoint_freq 32), not
    # shifted by the resume step (SB3 alone would validate at 40 + 64, after the run's end)
    with np.load(run / "eval" / "evaluations.npz") as log:
        assert [int(t) for t in log["timesteps"]] == [64]
    assert (run / "checkpoints" / "ckpt_64_steps.zip").exists()


def _inner_archive(steps: int) -> bytes:
    """A zip archive as SB3 stores one (uncompressed) inside a model: ``torch.save``'s ``.pth`` format."""
    import io
    import zipfile

    stream = io.BytesIO()
    with zipfile.ZipFile(stream, "w") as archive:
        archive.writestr("policy/data.pkl", bytes(range(256)) * (steps // 256))
    return stream.getvalue()


def _checkpoint_set(folder: Path, steps: int) -> None:
    """A whole checkpoint set at ``steps``: the model a zip archive laid out as SB3's (``data``, then a stored
    ``.pth`` that is a zip archive itself, then more entries), the statistics and the replay buffer pickles
    of the protocols SB3 writes (``VecNormalize.save``: 4; ``save_to_pkl``: the highest)."""
    import pickle
    import zipfile

    folder.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(folder / f"ckpt_{steps}_steps.zip", "w") as archive:
        archive.writestr("data", json.dumps({"steps": steps}) * 100)
        archive.writestr("policy.pth", _inner_archive(steps))
        archive.writestr("system_info.txt", "- OS: test\n" * 20)
    (folder / f"ckpt_vecnormalize_{steps}_steps.pkl").write_bytes(pickle.dumps({"steps": steps}, protocol=4))
    buffer = pickle.dumps(np.arange(steps, dtype=float), protocol=pickle.HIGHEST_PROTOCOL)
    (folder / f"ckpt_replay_buffer_{steps}_steps.pkl").write_bytes(buffer)


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _cut_after_inner_archive(folder: Path) -> None:
    """The model at step 1024 cut where the archive stored inside it ends: ``zipfile`` opens it as that
    archive."""
    model = folder / "ckpt_1024_steps.zip"
    raw, inner = model.read_bytes(), _inner_archive(1024)
    model.write_bytes(raw[: raw.index(inner) + len(inner)])


_DAMAGE = {
    "model missing": lambda folder: (folder / "ckpt_1024_steps.zip").unlink(),
    "truncated model": lambda folder: _truncate(folder / "ckpt_1024_steps.zip"),
    "model cut after an inner archive": _cut_after_inner_archive,
    "empty model": lambda folder: (folder / "ckpt_1024_steps.zip").write_bytes(b""),
    "model without statistics": lambda folder: (folder / "ckpt_vecnormalize_1024_steps.pkl").unlink(),
    "truncated statistics": lambda folder: _truncate(folder / "ckpt_vecnormalize_1024_steps.pkl"),
    "truncated replay buffer": lambda folder: _truncate(folder / "ckpt_replay_buffer_1024_steps.pkl"),
}


@pytest.mark.parametrize("damage", _DAMAGE)
def test_resume_passes_over_an_incomplete_checkpoint_set(tmp_path: Path, damage: str) -> None:
    """Was: a run resumed from its newest ``ckpt_<N>_steps.zip`` whatever the state of its set, so a process
    killed while writing a checkpoint left a truncated model, statistics or replay buffer (the rerun failed
    loading it) or a model without its statistics (the rerun was refused), though the checkpoint before
    it was whole. Now the newest whole set is resumed from; temporary files (here whole ones of a later
    step) never count."""
    run = tmp_path / "run"
    folder = run / "checkpoints"
    _checkpoint_set(folder, 512)
    _checkpoint_set(folder, 1024)
    hyperparams = {"normalize": True, "n_timesteps": 4096}
    assert train._latest_checkpoint(folder) == (1024, folder / "ckpt_1024_steps.zip")  # whole: the newest
    _DAMAGE[damage](folder)
    shutil.copy(folder / "ckpt_512_steps.zip", folder / ".ckpt_2048_steps.tmp.zip")
    shutil.copy(folder / "ckpt_vecnormalize_512_steps.pkl", folder / ".ckpt_vecnormalize_2048_steps.tmp.pkl")
    assert train._latest_checkpoint(folder) == (512, folder / "ckpt_512_steps.zip")
    assert train.missing_normalisation(run, hyperparams) is None and train.has_progress(run)
    # nothing whole: no checkpoint to resume from
    for path in folder.glob("ckpt_*_steps.zip"):
        _truncate(path)
    assert train._latest_checkpoint(folder) is None


@pytest.mark.parametrize("failing", [1, 2, 3], ids=["statistics", "replay buffer", "model"])
def test_checkpoints_are_written_as_a_set_model_last(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, failing: int
) -> None:
    """Was: the checkpoint callback wrote the model in place first, then the replay buffer and the
    statistics, so a process killed in between left a truncated file, or a model without its statistics,
    under the names a rerun resumes from. Now each file of a set is written to a temporary name and
    renamed into place (``os.replace``), statistics and replay buffer first, the model last: a failure at
    any rename leaves no model at the new step, the previous set whole (its replay buffer kept) and no
    temporary file; the temporaries a killed process left are removed when training starts again."""
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.callbacks import NewestBufferCheckpointCallback

    torch.set_num_threads(1)
    folder = tmp_path / "checkpoints"
    env = VecNormalize(make_vec_env(lambda: make_env(ENV, {"progress": False}), n_envs=1, seed=0))
    model = SAC("MlpPolicy", env, buffer_size=64, policy_kwargs={"net_arch": [8]}, device="cpu", seed=0)

    def checkpointer() -> NewestBufferCheckpointCallback:
        callback = NewestBufferCheckpointCallback(
            1, str(folder), name_prefix="ckpt", save_vecnormalize=True, save_replay_buffer=True
        )
        callback.init_callback(model)
        return callback

    callback = checkpointer()
    callback.num_timesteps = 512
    callback.save_now()
    first = sorted(p.name for p in folder.iterdir())
    assert first == [
        "ckpt_512_steps.zip",
        "ckpt_replay_buffer_512_steps.pkl",
        "ckpt_vecnormalize_512_steps.pkl",
    ]

    replace, calls = os.replace, []

    def failing_replace(source: Any, target: Any) -> None:
        calls.append(Path(target).name)
        if len(calls) == failing:
            raise OSError(f"no space left writing {target}")
        replace(source, target)

    monkeypatch.setattr(os, "replace", failing_replace)
    callback.num_timesteps = 1024
    with pytest.raises(OSError, match="no space left"):
        callback.save_now()
    monkeypatch.undo()
    order = ["ckpt_vecnormalize_1024_steps.pkl", "ckpt_replay_buffer_1024_steps.pkl", "ckpt_1024_steps.zip"]
    assert calls == order[:failing]
    assert sorted(p.name for p in folder.iterdir()) == sorted([*first, *order[: failing - 1]])
    assert train._latest_checkpoint(folder) == (512, folder / "ckpt_512_steps.zip")

    # a killed process leaves its temporaries: ignored by resume, removed when training starts again
    for name in order:
        (folder / f".{Path(name).stem}.tmp{Path(name).suffix}").write_bytes(b"partial")
    assert train._latest_checkpoint(folder) == (512, folder / "ckpt_512_steps.zip")
    callback = checkpointer()
    assert not list(folder.glob(".*"))
    callback.num_timesteps = 1024
    callback.save_now()
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["ckpt_512_steps.zip", "ckpt_vecnormalize_512_steps.pkl", *order]
    )
    assert train._latest_checkpoint(folder) == (1024, folder / "ckpt_1024_steps.zip")
    loaded = SAC.load(
        str(folder / "ckpt_1024_steps.zip"),
        env=VecNormalize.load(str(folder / "ckpt_vecnormalize_1024_steps.pkl"), env.venv),
        device="cpu",
    )
    loaded.load_replay_buffer(str(folder / "ckpt_replay_buffer_1024_steps.pkl"))


def _killed_before_the_model(checkpoints: Path) -> None:
    """Step 64 as a process killed while writing its model leaves it: statistics in place, the model a
    partial temporary file."""
    model = checkpoints / "ckpt_64_steps.zip"
    (checkpoints / ".ckpt_64_steps.tmp.zip").write_bytes(model.read_bytes()[:1000])
    model.unlink()


@pytest.mark.parametrize(
    "kill",
    [
        _killed_before_the_model,
        lambda checkpoints: _truncate(checkpoints / "ckpt_64_steps.zip"),
    ],
    ids=["killed before the model's rename", "model truncated in place"],
)
def test_a_rerun_resumes_from_the_last_whole_checkpoint(tmp_path: Path, kill: Any) -> None:
    """End to end: a run killed while writing its step-64 checkpoint (before its model was renamed into
    place; or, as the old in-place writes left it, with its model truncated) resumes from step 32 and
    rewrites step 64 whole; the temporaries left are removed. Was: the truncated model was resumed from
    and failed to load (the half of an SB3 model opens as the ``.pth`` archive stored in it: "No data found
    in the saved file")."""
    run = tmp_path / "ppo"
    argv = ["--env", ENV, "--timesteps", "64", "--n-envs", "1", "--no-progress", "--algo", "ppo"]
    argv += ["--seed", "0", "--out", str(run), "--hyperparams", *SHORT]
    train.main(argv)
    for name in ("result.json", "model.zip", "vecnormalize.pkl"):
        (run / name).unlink()  # killed before the end
    checkpoints = run / "checkpoints"
    kill(checkpoints)
    (checkpoints / ".ckpt_vecnormalize_96_steps.tmp.pkl").write_bytes(b"partial")
    assert train._latest_checkpoint(checkpoints) == (32, checkpoints / "ckpt_32_steps.zip")
    result = train.main(argv)[0]
    assert result["resumed_from"] == 32 and result["timesteps"] >= 64
    assert train._latest_checkpoint(checkpoints) == (64, checkpoints / "ckpt_64_steps.zip")
    assert not list(checkpoints.glob(".*")) and not list(run.glob(".*.tmp.*"))
    assert (run / "model.zip").exists() and (run / "vecnormalize.pkl").exists()


def test_validation_baseline_lines_are_its_no_field_and_best_constant_returns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """evaluate.validation_lines: the no-field and best-constant returns of an open-loop folder on the
    validation states (the mean of its stored episode returns, for the reward given), for learning.png;
    a folder on other states than validation, or of other physics, is refused (exit 2)."""
    test = tmp_path / "open_loop"
    validation = tmp_path / "open_loop_validation"
    open_loop.main(["--env", ENV, "--out", str(test), "--mason", "off,1", "--episodes", "1"])
    open_loop.main(
        [
            "--env",
            ENV,
            "--out",
            str(validation),
            "--mason",
            "off,1",
            "--split",
            "validation",
            "--episodes",
            "2",
        ]
    )
    pareto = json.loads((test / "pareto.json").read_text())
    reward = make_env(ENV).unwrapped.reward_function
    returns = {
        label: float(
            np.mean(
                [
                    e["return"]
                    for e in json.loads((validation / "points" / f"{label}.json").read_text())["episodes"]
                ]
            )
        )
        for label in ("off", "Mn1")
    }
    best = max(returns, key=returns.__getitem__)
    lines = evaluate.validation_lines(validation, pareto, reward)
    expected = [(f"best constant ({best}), validation states", returns[best])]
    if best != "off":
        expected.insert(0, ("no field, validation states", returns["off"]))
    assert [name for name, _ in lines] == [name for name, _ in expected]
    assert [value for _, value in lines] == pytest.approx([value for _, value in expected], rel=1e-12)

    with pytest.raises(SystemExit) as wrong_split:
        evaluate.validation_lines(test, pareto, reward)
    assert wrong_split.value.code == 2 and "not validation" in capsys.readouterr().err
    other = tmp_path / "other"
    shutil.copytree(validation, other)
    moved = json.loads((other / "pareto.json").read_text())
    (other / "pareto.json").write_text(json.dumps({**moved, "env_id": "dipenv/FieldVectorTiny-v0"}))
    with pytest.raises(SystemExit) as wrong_env:
        evaluate.validation_lines(other, pareto, reward)
    assert wrong_env.value.code == 2 and "differs from --baseline" in capsys.readouterr().err


def test_training_without_a_progress_bar_prints_a_line_per_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--no-progress: one line per checkpoint_freq steps on stderr (steps against the total, rate, time
    left, recent training return), so that a study's log shows where it is."""
    argv = ["--env", ENV, "--timesteps", "64", "--n-envs", "1", "--no-progress", "--algo", "ppo"]
    train.main([*argv, "--seed", "0", "--out", str(tmp_path / "ppo"), "--hyperparams", *SHORT])
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("ppo seed 0: ")]
    assert [line.split(",")[0] for line in lines] == ["ppo seed 0: 32/64 steps", "ppo seed 0: 64/64 steps"]
    assert all("steps/s" in line and "min left" in line for line in lines)


def test_validation_files_are_replaced_atomically(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Was: SB3's EvalCallback wrote ``eval/evaluations.npz`` and ``eval/best_model.zip`` in place, so a
    process killed while writing left truncated files under the names ``agents.evaluate --model best``
    and a resumed run read. Now both are written to hidden temporaries and renamed into place: a write
    that fails part-way leaves the previous files whole and loadable, and the temporaries a killed process
    left are removed when training starts again."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure

    from agents.callbacks import AtomicEvalCallback

    torch.set_num_threads(1)
    folder = tmp_path / "eval"
    env = make_vec_env(lambda: make_env(ENV, {"progress": False}), n_envs=1, seed=0)
    eval_env = make_vec_env(lambda: make_env(ENV, {"progress": False}), n_envs=1, seed=1)
    model = PPO(
        "MlpPolicy", env, n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]}, device="cpu", seed=0
    )

    def callback() -> AtomicEvalCallback:
        cb = AtomicEvalCallback(
            eval_env, folder, n_eval_episodes=1, eval_freq=1, deterministic=True, verbose=0
        )
        cb.init_callback(model)
        return cb

    model.set_logger(configure(None, []))
    cb = callback()
    model.num_timesteps = 16
    cb.on_step()
    assert sorted(p.name for p in folder.iterdir()) == [
        ".best_model.tmp",
        "best_model.zip",
        "evaluations.npz",
    ]
    assert list((folder / ".best_model.tmp").iterdir()) == []
    log, best = (folder / "evaluations.npz").read_bytes(), (folder / "best_model.zip").read_bytes()
    assert list(np.load(folder / "evaluations.npz")["timesteps"]) == [16]

    # a write that dies part-way (a full disk, a kill): the old files stay whole
    cb.best_mean_reward = -math.inf  # so that this evaluation saves a best model again
    save = model.save

    def dying_save(path: Any, *args: Any, **kwargs: Any) -> None:
        Path(str(path) + ".zip").write_bytes(b"partial")
        raise OSError("no space left on device")

    monkeypatch.setattr(model, "save", dying_save)
    model.num_timesteps = 32
    with pytest.raises(OSError, match="no space left"):
        cb.on_step()
    monkeypatch.setattr(model, "save", save)
    assert (folder / "best_model.zip").read_bytes() == best
    assert (folder / "evaluations.npz").read_bytes() == log  # renamed only after the step, so not yet
    PPO.load(str(folder / "best_model.zip"), device="cpu")

    # the next start removes the leftovers; training writes the files again
    assert (folder / ".best_model.tmp" / "best_model.zip").exists() and (
        folder / ".evaluations.tmp.npz"
    ).exists()
    cb = callback()
    assert sorted(p.name for p in folder.iterdir()) == [
        ".best_model.tmp",
        "best_model.zip",
        "evaluations.npz",
    ]
    assert list((folder / ".best_model.tmp").iterdir()) == []
    model.num_timesteps = 48
    cb.on_step()
    assert list(np.load(folder / "evaluations.npz")["timesteps"]) == [48]
