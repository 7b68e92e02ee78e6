"""The ``fresh`` split (issue 43): 128 schedules drawn from the generator with a recorded seed no other split
reaches, each paired with its own start state (packing seeds from 300,000), generated only when asked for.

These tests check the mechanics on the tiny id (a state is produced, schedule k pairs with state k, the
seeds are recorded) and never play an episode on the split: nothing may be tuned or selected on it.
"""

from __future__ import annotations

import hashlib
import json
from importlib import resources
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dipenv
import sim
from dipenv.realisations import perturbed_state
from dipenv.schedules import (
    DATA_FILE,
    FIXED_SPLITS,
    FRESH_SCHEDULES,
    FRESH_SPLIT,
    HOLD_RANGE,
    RAMP_RANGE,
    RATE_RANGE,
    STRATIFIED_POOLS,
    draw_schedule,
    fixed_schedules,
    schedule_to_dict,
    split_seeds,
)
from dipenv.state_library import (
    DEFAULT_FRESH_SIZE,
    MAX_SPLIT_SIZE,
    SPLIT_SEED_OFFSET,
    SPLITS,
    StateLibrary,
    check_split_sizes,
)

SHIPPED_DIGESTS = {
    "validation": "5c1e60abbae6914e0d904b5f7278166b7367870f2471a90d216824a1b66636e3",
    "test": "913f8eb3b6e7b6e5d9b638395cafb78cc1d8e2ee5b2e0bccff082a662a7c9d92",
}
"""SHA-256 of ``json.dumps`` of the shipped validation and test entries before the fresh split was added
(commit 3b75af9): they stay bit-identical."""


def _shipped() -> dict[str, object]:
    return json.loads((resources.files("dipenv") / "data" / DATA_FILE).read_text())


def test_validation_and_test_schedules_are_unchanged() -> None:
    data = _shipped()
    for split, digest in SHIPPED_DIGESTS.items():
        assert hashlib.sha256(json.dumps(data[split]).encode()).hexdigest() == digest, split


def test_fresh_schedules_are_the_recorded_seed_s_plain_draws() -> None:
    count, seed = FRESH_SCHEDULES
    assert FIXED_SPLITS[FRESH_SPLIT] == (count, seed) == (128, 3_000_000)
    assert split_seeds(FRESH_SPLIT) == [seed + k for k in range(count)]
    data = _shipped()
    assert data["splits"][FRESH_SPLIT] == {"count": count, "first_seed": seed, "pool": None}  # type: ignore[index]
    assert (data["duration"], data["rate_range"], data["hold_range"], data["ramp_range"]) == (
        12.0,
        list(RATE_RANGE),
        list(HOLD_RANGE),
        list(RAMP_RANGE),
    )
    entries = data[FRESH_SPLIT]
    assert [e["seed"] for e in entries] == [seed + k for k in range(count)]  # type: ignore[union-attr, index]
    shipped = fixed_schedules(FRESH_SPLIT)
    assert len(shipped) == count
    for k in (0, 1, 63, count - 1):
        assert shipped[k] == draw_schedule(np.random.default_rng(seed + k), 12.0)


def test_no_other_split_reaches_the_fresh_seeds() -> None:
    """Schedules: a split enlarged past its shipped schedules draws ``seed + pool + index`` with index below
    MAX_SPLIT_SIZE. Start states: ``offset + index``."""
    fresh_count, fresh_seed = FRESH_SCHEDULES
    fresh = range(fresh_seed, fresh_seed + MAX_SPLIT_SIZE + STRATIFIED_POOLS.get(FRESH_SPLIT, 0))
    for split, (_, seed) in FIXED_SPLITS.items():
        if split != FRESH_SPLIT:
            reach = range(seed, seed + STRATIFIED_POOLS.get(split, 0) + MAX_SPLIT_SIZE)
            assert reach.stop <= fresh.start or fresh.stop <= reach.start, split
    assert SPLITS == ("train", "validation", "test", "fresh") and SPLIT_SEED_OFFSET["fresh"] == 300_000
    ranges = sorted((SPLIT_SEED_OFFSET[s], SPLIT_SEED_OFFSET[s] + MAX_SPLIT_SIZE) for s in SPLITS)
    assert all(a[1] <= b[0] for a, b in zip(ranges, ranges[1:], strict=False))
    assert DEFAULT_FRESH_SIZE == fresh_count


def test_split_sizes_take_fresh_as_optional() -> None:
    sizes = {"train": 4, "validation": 2, "test": 2}
    assert check_split_sizes(sizes) == {**sizes, "fresh": DEFAULT_FRESH_SIZE}
    assert check_split_sizes({**sizes, "fresh": 64})["fresh"] == 64
    for bad in (0, 1.5, True, MAX_SPLIT_SIZE + 1):
        with pytest.raises(ValueError, match=r"split_sizes\['fresh'\] must be an integer"):
            check_split_sizes({**sizes, "fresh": bad})
    env = gym.make("dipenv/ThickeningControlTiny-v0", progress=False).unwrapped
    assert env.split_sizes == {**dipenv.TINY_KWARGS["split_sizes"], "fresh": DEFAULT_FRESH_SIZE}


def test_the_fresh_states_are_generated_only_when_asked_for(tmp_path: Path) -> None:
    config = sim.SimulationConfig(n_particles=32, volume_fraction=0.45, near_field_cutoff=3.0)
    sizes = {"train": 1, "validation": 1, "test": 1}
    library = StateLibrary(config, preshear_strain=0.2, tail_strain=0.1, root=tmp_path, split_sizes=sizes)
    assert library.split_sizes["fresh"] == DEFAULT_FRESH_SIZE
    assert all(split != "fresh" for split, _ in library.missing())
    library.ensure(progress=False)  # the development splits only
    generated = sorted(p.name.split("_")[0] for p in library.directory.glob("*.npz"))
    assert generated == ["test", "train", "validation"]
    start = library.load("fresh", 2, progress=False)  # that one state, not the split's 128
    assert (start.seed, start.split, start.index) == (300_002, "fresh", 2)
    assert [p.name for p in library.directory.glob("fresh_*.npz")] == ["fresh_00002_seed300002.npz"]
    assert len(library.missing(["fresh"])) == DEFAULT_FRESH_SIZE - 1
    # an evaluation on the first n episodes makes only those states (not the split's 128)
    assert library.missing(["fresh"], count=3) == [("fresh", 0), ("fresh", 1)]
    library.ensure(["fresh"], progress=False, count=2)
    assert sorted(p.name[:11] for p in library.directory.glob("fresh_*.npz")) == [
        "fresh_00000",
        "fresh_00001",
        "fresh_00002",
    ]
    assert library.missing(["fresh"], count=3) == [] and library.missing(["test"], count=10**6) == []
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="count must be an integer >= 1"):
            library.ensure(["fresh"], progress=False, count=bad)  # type: ignore[arg-type]
    moved = perturbed_state(start.state, config.box_length, "fresh", 2, 1)  # realisations know the split
    assert 0 < np.max(np.abs(moved.positions - start.state.positions)) < 1e-7


def test_the_tiny_env_pairs_fresh_state_k_with_fresh_schedule_k(tmp_path: Path) -> None:
    """A reset only (no step): the state is produced, its packing seed and schedule are the recorded ones."""
    env = gym.make("dipenv/ThickeningControlTiny-v0", library_root=tmp_path, progress=False)
    unwrapped = env.unwrapped
    count, seed = FRESH_SCHEDULES
    _, info = env.reset(seed=0, options={"split": "fresh", "index": 1})
    assert (info["split"], info["index"], info["packing_seed"]) == ("fresh", 1, 300_001)
    expected = draw_schedule(
        np.random.default_rng(seed + 1),
        unwrapped.episode_duration,
        unwrapped.rate_range,
        unwrapped.hold_range,
        unwrapped.ramp_range,
    )
    assert info["schedule"] == schedule_to_dict(expected)
    assert info["schedule"] == schedule_to_dict(unwrapped.fixed_schedule("fresh", 1))
    fresh_files = [p.name for p in unwrapped.library().directory.glob("fresh_*.npz")]
    assert fresh_files == ["fresh_00001_seed300001.npz"]
    _, again = env.reset(seed=7, options={"split": "fresh", "index": 1, "realisation": 2})
    assert again["schedule"] == info["schedule"] and again["realisation"] == 2
    # the shipped schedules are the ones of an env with the default parameters (the standard ids)
    standard = gym.make("dipenv/ThickeningControl-v2", progress=False).unwrapped
    assert standard.fixed_schedule("fresh", count - 1) == fixed_schedules("fresh")[count - 1]
    env.close()


def test_an_evaluation_on_the_first_n_fresh_episodes_makes_only_their_states(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``agents.open_loop --split fresh --episodes 1`` pre-shears fresh state 0 alone, not the split's 128
    (the final evaluation takes the first 64: half the split's cost of states)."""
    from agents import open_loop

    monkeypatch.setenv("DIPENV_CACHE_DIR", str(tmp_path / "cache"))
    open_loop.main(
        ["--env", "dipenv/ThickeningControlTiny-v0", "--split", "fresh", "--episodes", "1", "--mason", "off"]
        + ["--out", str(tmp_path / "out")]
    )
    made = sorted(p.name[:11] for p in (tmp_path / "cache").rglob("*.npz"))
    assert made == ["fresh_00000"]
