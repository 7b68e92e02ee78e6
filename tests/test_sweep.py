"""Sweeps: each run is a pure function of its config, so a local pool, a Dask cluster and a direct run give
the same numbers bit for bit; reruns reuse finished points, resume interrupted ones and rerun stale ones;
a failed point is recorded and the others finish. Also the task engine (sim.runs.tasks) they run on."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
from pathlib import Path
from typing import Any

import pytest

import sim.runs.run
from sim import SimulationConfig, SimulationError, run_simulation
from sim.runs.sweep import ERROR_FILE, MANIFEST, SweepError, plan_point, run_name, run_points, run_sweep
from sim.runs.tasks import TaskFailure, run_tasks

CONFIGS = [
    SimulationConfig(n_particles=40, volume_fraction=0.3, strain=0.02, seed=1),
    SimulationConfig(n_particles=40, volume_fraction=0.4, strain=0.02, seed=2),
]
"""Two tiny runs (10 steps of N = 40 each, well under a second once compiled)."""

VOLATILE = {"wall_seconds"}
"""result.json keys that may differ between identical runs."""


def _comparable(result: dict[str, Any]) -> str:
    """A result's deterministic values as canonical JSON (NaN compares equal to itself as text)."""
    return json.dumps({k: v for k, v in result.items() if k not in VOLATILE}, sort_keys=True, default=str)


def _result_file(out: Path, config: SimulationConfig) -> Path:
    return out / run_name(config) / "result.json"


def test_pool_sweep_matches_direct_runs_and_reuses_results(tmp_path) -> None:
    results = run_sweep(CONFIGS, tmp_path / "sweep", processes=2)
    for config, result in zip(CONFIGS, results, strict=True):
        direct = run_simulation(config, tmp_path / "direct" / run_name(config), progress=False)
        for key in ("relative_viscosity", "n1", "n2", "steps", "min_gap"):
            assert result[key] == direct[key]  # same config and seed -> same numbers, bit for bit
        saved = json.loads((tmp_path / "sweep" / run_name(config) / "params.json").read_text())
        assert saved["config"] == config.to_dict()
    (tmp_path / "sweep" / run_name(CONFIGS[0]) / "timeseries.csv").unlink()  # finished runs are not redone
    again = run_sweep(CONFIGS, tmp_path / "sweep", processes=1)
    for cached, fresh in zip(again, results, strict=True):  # same values and types (nan compares unequal)
        assert json.dumps(cached, sort_keys=True) == json.dumps(fresh, sort_keys=True)
    assert not (tmp_path / "sweep" / run_name(CONFIGS[0]) / "timeseries.csv").exists()
    manifest = json.loads((tmp_path / "sweep" / MANIFEST).read_text())
    assert [p["status"] for p in manifest["points"]] == ["reused", "reused"]
    assert manifest["points"][0]["result"] == f"{run_name(CONFIGS[0])}/result.json"


def test_results_from_other_sources_or_parameters_are_recomputed(tmp_path) -> None:
    """A result is reused only if params.json names the same config and the same ``sim`` source digest."""
    config = CONFIGS[0]
    run_dir = tmp_path / "sweep" / run_name(config)
    run_sweep([config], tmp_path / "sweep", processes=1)
    params_file = run_dir / "params.json"
    params = json.loads(params_file.read_text())
    params["versions"]["sim_source"] = "0" * 16  # as if written by an older version of the simulator
    params_file.write_text(json.dumps(params))
    (run_dir / "timeseries.csv").unlink()
    assert plan_point(run_dir, config) == "stale"
    run_sweep([config], tmp_path / "sweep", processes=1)
    assert (run_dir / "timeseries.csv").exists()  # recomputed
    assert json.loads(params_file.read_text())["versions"]["sim_source"] != "0" * 16
    params = json.loads(params_file.read_text())
    params["config"]["seed"] = 99  # a different run left in this directory
    params_file.write_text(json.dumps(params))
    (run_dir / "timeseries.csv").unlink()
    points = run_points([config], tmp_path / "sweep", workers=1)
    assert points[0].plan == "stale" and points[0].status == "finished"  # from the start, not resumed
    assert (run_dir / "timeseries.csv").exists()


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="dask.distributed not installed")
def test_dask_cluster_sweep_equals_the_local_pool_bit_for_bit(tmp_path) -> None:
    """The same points on an in-process Dask LocalCluster and on the spawned local pool: every result.json
    value equal (the wall time aside)."""
    from distributed import LocalCluster

    run_sweep(CONFIGS, tmp_path / "pool", processes=2)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        points = run_points(CONFIGS, tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert [p.status for p in points] == ["finished", "finished"]
    manifest = json.loads((tmp_path / "dask" / MANIFEST).read_text())
    assert manifest["scheduler"] == cluster.scheduler_address and manifest["workers"] is None
    for config in CONFIGS:
        pool = json.loads(_result_file(tmp_path / "pool", config).read_text())
        dask = json.loads(_result_file(tmp_path / "dask", config).read_text())
        assert _comparable(pool) == _comparable(dask)


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, bool]]:
    """Record every ``run_simulation`` call of an in-process sweep as (folder name, resume)."""
    calls: list[tuple[str, bool]] = []
    original = sim.runs.run.run_simulation

    def counted(config: SimulationConfig, out_dir: Any, *args: Any, **kwargs: Any) -> dict[str, Any]:
        calls.append((Path(out_dir).name, bool(kwargs.get("resume", False))))
        return original(config, out_dir, *args, **kwargs)

    monkeypatch.setattr(sim.runs.run, "run_simulation", counted)
    return calls


def test_interrupted_sweep_resumes_only_unfinished_points(tmp_path, monkeypatch) -> None:
    """Run three points; remove one point's result (killed after its last checkpoint), make another look
    interrupted half-way (a checkpoint at strain 0.02 of a 0.04 run) and a third stale (other sources):
    the rerun resumes the first two from their checkpoints, reruns the stale one from the start, and
    leaves nothing else untouched; the resumed results equal uninterrupted runs bit for bit."""
    out = tmp_path / "sweep"
    base = dict(n_particles=40, strain=0.04, transient_strain=0.01, checkpoint_every=0.02)
    configs = [SimulationConfig(volume_fraction=phi, seed=1, **base) for phi in (0.2, 0.3, 0.4, 0.45)]
    finished_early, killed, half_way, stale = (out / run_name(c) for c in configs)
    run_points([configs[0], configs[1], configs[3]], out, workers=1)
    # the half-way point: a run to strain 0.02 whose params.json names the 0.04 run (as a kill leaves it)
    first_half = dataclasses.replace(configs[2], strain=0.02)
    run_simulation(first_half, half_way, progress=False)
    (half_way / "result.json").unlink()
    params = json.loads((half_way / "params.json").read_text())
    params["config"]["strain"] = 0.04
    (half_way / "params.json").write_text(json.dumps(params))
    (killed / "result.json").unlink()
    params = json.loads((stale / "params.json").read_text())
    params["versions"]["sim_source"] = "0" * 16
    (stale / "params.json").write_text(json.dumps(params))
    before = (finished_early / "result.json").stat().st_mtime_ns
    assert [
        plan_point(d, c) for d, c in zip((finished_early, killed, half_way, stale), configs, strict=True)
    ] == [
        "finished",
        "resumable",
        "resumable",
        "stale",
    ]

    calls = _counting(monkeypatch)
    points = run_points(configs, out, workers=1)
    assert [p.status for p in points] == ["reused", "resumed", "resumed", "finished"]
    assert sorted(calls) == sorted([(killed.name, True), (half_way.name, True), (stale.name, False)])
    assert (finished_early / "result.json").stat().st_mtime_ns == before
    for config in configs[1:]:
        run_simulation(config, tmp_path / "direct" / run_name(config), progress=False)
        direct = json.loads(_result_file(tmp_path / "direct", config).read_text())
        assert _comparable(json.loads(_result_file(out, config).read_text())) == _comparable(direct)
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["counts"] == {"pending": 0, "reused": 1, "finished": 1, "resumed": 2, "failed": 0}
    assert manifest["finished"] is not None

    calls.clear()
    assert [p.status for p in run_points(configs, out, workers=1)] == ["reused"] * 4
    assert calls == []  # nothing runs a second time


def test_a_failed_point_is_recorded_and_the_others_finish(tmp_path, monkeypatch) -> None:
    original = sim.runs.run.run_simulation

    def fails_for_seed_2(config: SimulationConfig, *args: Any, **kwargs: Any) -> dict[str, Any]:
        if config.seed == 2:
            raise SimulationError("overlap removal did not converge (injected)")
        return original(config, *args, **kwargs)

    monkeypatch.setattr(sim.runs.run, "run_simulation", fails_for_seed_2)
    configs = [dataclasses.replace(CONFIGS[0], seed=seed) for seed in (1, 2, 3)]
    out = tmp_path / "sweep"
    with pytest.raises(SweepError, match=r"1 of 3 sweep points failed: .*seed2: SimulationError") as caught:
        run_sweep(configs, out, processes=1)
    points = caught.value.points
    assert [p.status for p in points] == ["finished", "failed", "finished"]
    error = json.loads((out / run_name(configs[1]) / ERROR_FILE).read_text())
    assert error["error"] == "SimulationError" and "injected" in error["message"]
    assert "fails_for_seed_2" in error["traceback"] and error["config"]["seed"] == 2
    manifest = json.loads((out / MANIFEST).read_text())
    entry = manifest["points"][1]
    assert entry["status"] == "failed" and entry["result"] is None
    assert entry["error"]["file"] == f"{run_name(configs[1])}/{ERROR_FILE}"
    for config in (configs[0], configs[2]):
        assert _result_file(out, config).exists()

    monkeypatch.setattr(sim.runs.run, "run_simulation", original)  # fixed: the rerun runs only that point
    points = run_points(configs, out, workers=1)
    assert [p.status for p in points] == ["reused", "finished", "reused"]
    assert not (out / run_name(configs[1]) / ERROR_FILE).exists()


def test_plans_of_folders(tmp_path) -> None:
    """What a rerun finds: nothing, a run stopped before its first checkpoint (params.json only: nothing to
    continue), files of another configuration."""
    from sim.runs.io import write_params

    config = CONFIGS[0]
    folder = tmp_path / run_name(config)
    assert plan_point(folder, config) == "new"
    folder.mkdir()
    write_params(folder, config)
    assert plan_point(folder, config) == "new"
    write_params(folder, dataclasses.replace(config, seed=7))
    assert plan_point(folder, config) == "stale"


def test_a_corrupt_result_is_redone_not_fatal(tmp_path) -> None:
    """A rerun whose points hold a truncated or binary ``result.json`` redoes those points (it used to
    abort the whole sweep with a JSONDecodeError or UnicodeDecodeError)."""
    configs = [dataclasses.replace(CONFIGS[0], seed=seed) for seed in (1, 2, 3)]
    out = tmp_path / "sweep"
    run_points(configs, out, workers=1)
    truncated, binary = _result_file(out, configs[0]), _result_file(out, configs[1])
    truncated.write_text(truncated.read_text()[:40])
    binary.write_bytes(b"\x89PNG\x00\xff\xfe")
    assert plan_point(truncated.parent, configs[0]) == "resumable"
    points = run_points(configs, out, workers=1)
    assert [p.status for p in points] == ["resumed", "resumed", "reused"]
    for config in configs[:2]:
        assert json.loads(_result_file(out, config).read_text())["seed"] == config.seed
    _result_file(out, configs[2]).write_text("[1, 2]")  # valid JSON, not a result
    assert plan_point(out / run_name(configs[2]), configs[2]) == "resumable"


def test_points_differing_in_mason_number_name_it_not_the_volume_fraction(tmp_path) -> None:
    twins = [dataclasses.replace(CONFIGS[0], mason_number=mn, near_field="none") for mn in (1.0, 1.0000001)]
    with pytest.raises(ValueError, match=r"tell apart \(mason_number has 6 significant digits there\)$"):
        run_points(twins, tmp_path / "sweep", workers=1)


def test_points_sharing_a_folder_are_refused(tmp_path) -> None:
    twins = [dataclasses.replace(CONFIGS[0], volume_fraction=phi) for phi in (0.3001, 0.3004)]
    with pytest.raises(
        ValueError, match=r"share the folder phi0\.300_N40_Mninf_seed1: they differ in volume"
    ):
        run_points(twins, tmp_path / "sweep", workers=1)
    assert not (tmp_path / "sweep").exists()


# --- the task engine ------------------------------------------------------------------------------------


def _square_or_fail(x: int) -> int:
    if x < 0:
        raise ValueError(f"negative input {x}")
    return x * x


def _die(x: int) -> int:
    if x == 0:
        os._exit(3)  # a worker that crashes (no exception to report)
    return x


def test_run_tasks_records_failures_and_reports_progress(capsys) -> None:
    seen: list[int] = []
    for workers in (1, 2):
        seen.clear()
        results = run_tasks(
            _square_or_fail,
            [3, -1, 2],
            workers=workers,
            on_error="record",
            progress=True,
            description="squares",
            on_result=lambda index, result: seen.append(index),
        )
        assert results[0] == 9 and results[2] == 4
        failure = results[1]
        assert isinstance(failure, TaskFailure)
        assert (failure.index, failure.error, failure.message) == (1, "ValueError", "negative input -1")
        assert "_square_or_fail" in failure.traceback  # formatted where the task ran
        assert sorted(seen) == [0, 1, 2]
        assert "squares" in capsys.readouterr().err  # the bar, on stderr
    with pytest.raises(ValueError, match="negative input"):
        run_tasks(_square_or_fail, [3, -1], workers=1)
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        run_tasks(_square_or_fail, [3], workers=0)


def test_a_crashed_worker_process_is_a_recorded_failure() -> None:
    """A worker process that dies fails its task (and the pool's unfinished ones) instead of hanging."""
    results = run_tasks(_die, [0, 5], workers=2, on_error="record")
    assert isinstance(results[0], TaskFailure) and results[0].error == "BrokenProcessPool"
    assert results[1] == 5 or isinstance(results[1], TaskFailure)


@pytest.mark.xfail(
    strict=True,
    reason="known bug, fix after the fresh evaluations (sim/ is frozen until then): SimulationConfig's "
    "normalisation of field_direction is not idempotent at the last bit (1,1,0 -> 0.7071067811865475, whose "
    "round trip through params.json gives ...476), so a rerun calls a finished diagonal point stale and "
    "deletes and redoes it. scripts/direction_map.sh works around it by passing ...476.",
)
def test_a_finished_point_with_a_diagonal_field_is_reused(tmp_path) -> None:
    config = dataclasses.replace(CONFIGS[0], field_direction=(1.0, 1.0, 0.0))
    assert SimulationConfig.from_dict(config.to_dict()) == config  # the round trip of params.json
    run_sweep([config], tmp_path / "sweep", processes=1)
    run_sweep([config], tmp_path / "sweep", processes=1)
    manifest = json.loads((tmp_path / "sweep" / MANIFEST).read_text())
    assert [p["status"] for p in manifest["points"]] == ["reused"]
