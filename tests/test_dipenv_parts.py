"""dipenv building blocks: action mapping, direction, actuator filter, reward, observation bounds, library."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import sim
from dipenv import state_library
from dipenv.actions import (
    ActuatorFilter,
    FieldStrengthMapping,
    action_from_direction,
    direction_from_action,
    validate_action,
)
from dipenv.observations import observation_bounds, observation_features, signed_log
from dipenv.rewards import ViscosityTargetReward, default_target_viscosity, default_viscosity_cap
from dipenv.state_library import SPLIT_SEED_OFFSET, StateLibrary


def test_strength_mapping_ends_off_band_and_inverse() -> None:
    m = FieldStrengthMapping(0.05, 20.0, 0.1)
    assert m.mason_number(1.0) == pytest.approx(0.05)
    assert m.mason_number(-0.9) == pytest.approx(20.0)
    assert math.isinf(m.mason_number(-0.95)) and math.isinf(m.mason_number(-1.0))
    for u in np.linspace(-0.9, 1.0, 11):
        assert m.action_for(m.mason_number(float(u))) == pytest.approx(u, abs=1e-12)
    assert m.mason_number(0.0) == pytest.approx(math.exp(math.log(20) + (0.9 / 1.9) * math.log(0.05 / 20)))
    assert m.action_for(math.inf) == -1.0 and m.coordinate(1e6) == pytest.approx(-0.9)
    with pytest.raises(ValueError, match="mason_number"):
        m.action_for(0.01)
    with pytest.raises(ValueError, match="mason_max"):
        FieldStrengthMapping(1.0, 0.5)


def test_direction_mapping_round_trip_and_hemisphere() -> None:
    np.testing.assert_allclose(direction_from_action(-1.0, 0.3), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(direction_from_action(1.0, 0.0), [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(direction_from_action(1.0, 0.5), [0.0, 0.0, 1.0], atol=1e-15)
    rng = np.random.default_rng(0)
    for polar, azimuth in rng.uniform(-1, 1, size=(20, 2)):
        e = direction_from_action(polar, azimuth)
        assert np.linalg.norm(e) == pytest.approx(1.0) and e[1] >= 0
        np.testing.assert_allclose(direction_from_action(*action_from_direction(e)), e, atol=1e-12)
        np.testing.assert_allclose(direction_from_action(*action_from_direction(-e)), e, atol=1e-12)


def test_validate_action() -> None:
    clipped, flag = validate_action(np.array([1.5, -0.2]), (2,))
    assert clipped.tolist() == [1.0, -0.2] and flag
    with pytest.raises(ValueError, match="shape"):
        validate_action([0.1], (2,))
    with pytest.raises(ValueError, match="finite"):
        validate_action(np.array([np.nan]), (1,))


def test_actuator_filter_is_the_exact_exponential() -> None:
    f = ActuatorFilter(time_constant=0.5, substeps=4)
    held, end = f.schedule(0.2, 1.0, 1.0)
    assert held == pytest.approx([1.0 - 0.8 * math.exp(-(k + 0.5) / 4 / 0.5) for k in range(4)])
    assert end == pytest.approx(1.0 - 0.8 * math.exp(-2.0))
    assert ActuatorFilter().schedule(0.2, 0.7, 1.0) == ([0.7], 0.7)
    held, end = ActuatorFilter(0.001, 2).schedule(1.0, 0.0, 0.1)  # decays below the snap: off
    assert held == [0.0, 0.0] and end == 0.0


def test_reward_terms() -> None:
    reward = ViscosityTargetReward(target_viscosity=5.0, energy_weight=2.0, failure_penalty=10.0)
    r, terms = reward(7.0, 0.5)
    assert r == pytest.approx(-3.0) and terms["reward_viscosity"] == -2.0 and terms["reward_energy"] == -1.0
    assert reward.failure(3)[0] == -40.0
    assert default_target_viscosity(0.45) == default_target_viscosity(0.45, 64) == 6.1
    with pytest.raises(ValueError, match="target_viscosity"):
        default_target_viscosity(0.2)
    with pytest.raises(ValueError, match=r"n_particles=100.*\(0.45, 64\)"):
        default_target_viscosity(0.45, 100)
    assert default_viscosity_cap(0.45, 64) == 6.5
    assert default_target_viscosity(0.45, 300) == 7.4 and default_viscosity_cap(0.45, 300) == 7.7
    with pytest.raises(ValueError, match="eta_cap"):
        default_viscosity_cap(0.45, 150)  # the plateau depends on N: no default for another box


def test_observation_bounds_and_signed_log() -> None:
    low, high = observation_bounds(observation_features(True), 1)
    assert low.shape == (2 * len(observation_features(True)),) and np.all(low < high)
    assert signed_log(-9.0) == pytest.approx(-1.0) and signed_log(0.0) == 0.0


def test_library_key_tracks_every_shaping_parameter(tmp_path: Path) -> None:
    config = sim.SimulationConfig(n_particles=32, volume_fraction=0.45, near_field_cutoff=3.0)
    base = StateLibrary(config, root=tmp_path)
    assert base.key == StateLibrary(replace(config, seed=9, strain=3.0), root=tmp_path).key
    for other in (
        StateLibrary(replace(config, volume_fraction=0.4), root=tmp_path),
        StateLibrary(replace(config, solver_tolerance=1e-6), root=tmp_path),
        StateLibrary(config, preshear_strain=4.0, root=tmp_path),
    ):
        assert other.key != base.key
    assert base.seed("test", 3) == SPLIT_SEED_OFFSET["test"] + 3
    with pytest.raises(ValueError, match="split"):
        base.seed("holdout", 0)
    with pytest.raises(ValueError, match="mason_number"):
        StateLibrary(replace(config, mason_number=1.0), root=tmp_path)


def test_library_generates_once_and_reloads(tmp_path: Path) -> None:
    config = sim.SimulationConfig(n_particles=32, volume_fraction=0.45, near_field_cutoff=3.0)
    library = StateLibrary(
        config,
        preshear_strain=0.2,
        tail_strain=0.1,
        root=tmp_path,
        split_sizes={"train": 2, "validation": 1, "test": 1},
    )
    library.ensure(["train"], progress=False)
    assert library.missing(["train"]) == []
    assert len(library.missing()) == 2
    path = library.path("train", 1)
    stamp = path.stat().st_mtime_ns
    library.ensure(["train"], progress=False)
    assert path.stat().st_mtime_ns == stamp
    start = library.load("train", 1)
    assert start.seed == 1 and start.state.strain >= 0.2 and math.isinf(start.state.mason_number)
    mean = start.tail_average(0.05)
    assert mean.shape == (3,) and np.all(np.isfinite(mean))
    assert (library.directory / "library.json").exists()


def test_library_workers_write_the_same_states_as_one_process(tmp_path: Path) -> None:
    """Two worker processes pre-shear the states of one library: the files equal those of a serial run
    bit for bit (each state depends on its packing seed only), and a bad worker count is refused."""
    config = sim.SimulationConfig(n_particles=32, volume_fraction=0.45, near_field_cutoff=3.0)
    sizes = {"train": 2, "validation": 1, "test": 1}
    serial, pooled = (
        StateLibrary(config, preshear_strain=0.2, tail_strain=0.1, root=tmp_path / name, split_sizes=sizes)
        for name in ("a", "b")
    )
    serial.ensure(["train", "test"], progress=False)
    pooled.ensure(["train", "test"], progress=False, workers=2)
    assert pooled.missing(["train", "test"]) == [] and len(pooled.missing()) == 1
    for split, index in (("train", 0), ("train", 1), ("test", 0)):
        with np.load(serial.path(split, index)) as a, np.load(pooled.path(split, index)) as b:
            assert sorted(a.files) == sorted(b.files)
            for name in a.files:
                np.testing.assert_array_equal(a[name], b[name])
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="workers"):
            pooled.ensure(["validation"], progress=False, workers=bad)  # type: ignore[arg-type]


def _tiny_library(root: Path) -> StateLibrary:
    config = sim.SimulationConfig(n_particles=32, volume_fraction=0.45, near_field_cutoff=3.0)
    sizes = {"train": 1, "validation": 1, "test": 1}
    return StateLibrary(config, preshear_strain=0.2, tail_strain=0.1, root=root, split_sizes=sizes)


def test_library_key_tracks_the_physics_sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Was: keyed on the hand-bumped sim.__version__, so states made by older physics were reused. The
    key holds a digest of the simulator sources a pre-shear runs: an edit of the stepper changes it (the
    states are generated again under the new key), an edit of the command line does not."""
    library = _tiny_library(tmp_path / "cache")
    library.ensure(["train"], progress=False)
    assert library.missing(["train"]) == []
    key = library.key
    monkeypatch.setattr(state_library, "physics_source_digest", lambda: "0" * 16)
    assert library.key != key and library.missing(["train"]) == [("train", 0)]
    monkeypatch.undo()

    copy = tmp_path / "sim"
    shutil.copytree(Path(sim.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED)
    for name in state_library.PHYSICS_EXCLUDED:
        assert (copy / name).exists(), name  # the list names files and folders that exist
    cli = copy / "runs" / "cli.py"
    cli.write_text(cli.read_text() + "\nEDITED_COMMAND_LINE = 1\n")  # a change of the application's code
    assert state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED) == before
    stepper = copy / "stepper.py"
    text = stepper.read_text()
    # rewording its docstrings and comments does not touch a trajectory: same digest
    reworded = text.replace('"""', '"""Reworded. ', 1) + "\n# a comment\n"
    stepper.write_text(reworded)
    assert state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED) == before
    stepper.write_text(reworded + "\nEDITED_DYNAMICS = 1.0\n")  # a change of the code
    edited = state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED)
    assert edited != before
    hydro = copy / "hydrodynamics" / "lubrication.py"
    hydro.write_text(hydro.read_text() + "\nEDITED_LUBRICATION = 2.0\n")
    lubricated = state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED)
    assert lubricated != edited
    # the pre-shear has no field: the dipolophoresis kernels and their tables do not shape the states
    table = next(copy.glob("dipolophoresis/tables/*.txt"))
    table.write_text(table.read_text() + "\n")
    ewald = copy / "dipolophoresis" / "ewald.py"
    ewald.write_text(ewald.read_text() + "\n# a faster Ewald sum\n")
    assert state_library.source_digest(copy, state_library.PHYSICS_EXCLUDED) == lubricated


def test_the_moved_application_keeps_the_library_key(tmp_path: Path) -> None:
    """Issue 45 moved the application into ``sim/runs/`` and ``sim/plots/``, which rewrote the imports of
    ``sim/__init__.py`` (a digested file): an import of a moved module is digested under its former name,
    so the move kept the library key and the cached states. Any other import change is a code edit."""
    moved = tmp_path / "moved.py"
    moved.write_text("from sim.runs.io import versions\nimport sim.plots.sweep\n")
    former = tmp_path / "former.py"
    former.write_text("from sim.io import versions\nimport sim.sweep_figures\n")
    assert state_library._normalised_source(moved) == state_library._normalised_source(former)
    (tmp_path / "stayed.py").write_text("from sim.runs.folder import claim\n")  # not moved: not renamed
    (tmp_path / "renamed.py").write_text("from sim.folder import claim\n")
    assert state_library._normalised_source(tmp_path / "stayed.py") != state_library._normalised_source(
        tmp_path / "renamed.py"
    )
    for new, old in state_library.DIGESTED_UNDER_FORMER_NAME.items():
        path = Path(sim.__file__).parent.joinpath(*new.split(".")[1:]).with_suffix(".py")
        assert path.is_file() and old.count(".") == 1, (new, old)  # every entry names a module that moved


def test_stale_states_in_the_library_folder_are_generated_again(tmp_path: Path) -> None:
    """Was: the recorded source digest was never checked. States whose library.json records other
    parameters (here: other physics sources) are deleted and generated again, with a warning."""
    library = _tiny_library(tmp_path)
    path = library.path("train", 0)
    library.directory.mkdir(parents=True)
    record = {**library.parameters(), "physics_source": "0123456789abcdef"}
    (library.directory / "library.json").write_text(json.dumps(record))
    np.savez(path, not_a_state=np.zeros(1))  # states of other physics
    assert "physics_source ('0123456789abcdef' there" in str(library.stale_reason())
    with pytest.warns(UserWarning, match="are stale"):
        start = library.load("train", 0, progress=False)
    assert start.seed == 0 and library.stale_reason() is None
    assert json.loads((library.directory / "library.json").read_text())["physics_source"] == (
        state_library.physics_source_digest()
    )
    stamp = path.stat().st_mtime_ns
    library.load("train", 0, progress=False)  # not stale any more: reused
    assert path.stat().st_mtime_ns == stamp
