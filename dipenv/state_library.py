"""Library of pre-sheared start states, generated on first use and cached on disk.

A start state is a random packing (seed ``s``) sheared without field for ``preshear_strain`` strains
(the contact network and the fabric reach their steady state after about 2–3 strains: see
docs/environments.md's
relaxation measurement). The library keeps, per state, the full :class:`sim.SimulationState` (so that a
run continues it bit for bit) and the per-step ``eta_r``, ``N1``, ``N2`` and step sizes of the last
``tail_strain`` strains, from which the first observation's interval averages are taken.

Splits are disjoint ranges of packing seeds: ``train`` uses seeds ``0, 1, ...``, ``validation``
``100000, ...``, ``test`` ``200000, ...`` and ``fresh`` ``300000, ...`` (each split holds at most
:data:`MAX_SPLIT_SIZE` = 100,000 states, so the ranges never meet), and enlarging a split keeps its
existing states. ``fresh`` is the held-out split of the final evaluation (issue 43,
``docs/thickening_control.md#the-fresh-split``): :meth:`StateLibrary.missing` and
:meth:`StateLibrary.ensure` leave it out unless it is named, and :meth:`StateLibrary.load` generates only
the state it is asked for, so no fresh state exists until an evaluation asks for it.

Cache: ``$DIPENV_CACHE_DIR`` or ``$XDG_CACHE_HOME/dipenv`` (default ``~/.cache/dipenv``), then
``states/<key>/``, where ``key`` hashes everything that shapes the states: the simulation config (all
fields but the seed and the run length), the pre-shear and tail strains, the library format version and
a digest of the simulator sources the pre-shear runs (:func:`physics_source_digest`: every ``.py`` file
of ``sim/`` but those listed in :data:`PHYSICS_EXCLUDED`: the field's kernels, which a field-free
pre-shear never runs, and the command line, run files, figures, sweeps and tasks, which do not touch a
trajectory). States made by other physics therefore live under another key and are never
reused: an edit of the dynamics regenerates the states (and the open-loop results keyed on them), an
edit of ``sim/runs/cli.py`` does not. ``library.json`` records these parameters; a directory whose record
differs from the library's (states copied from elsewhere, or a damaged record) is stale: its states are
deleted and generated again, with a warning. Files are written atomically (temporary name, then rename),
so concurrent workers at worst repeat work.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import json
import math
import multiprocessing
import os
import tempfile
import warnings
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

import sim

LIBRARY_VERSION = 2
"""Bump when the file layout or the generation protocol changes (2: keyed on the physics sources instead
of the hand-bumped ``sim.__version__``)."""

PHYSICS_EXCLUDED = frozenset(
    {
        "dipolophoresis/",
        "observables/diffusion.py",
        "observables/layering.py",
        "observables/microstructure.py",
        "observables/pair_distribution.py",
        "variants.py",
        "__main__.py",
        "runs/",
        "plots/",
    }
)
"""Files of ``sim/`` (paths relative to it; a trailing ``/`` names a whole subpackage) that do not shape a
start state: the pre-shear runs without a field, so the dipolophoresis kernels and their tables never run;
sampled observables (g(r), MSD, fabric, layering), rate schedules and the application do not touch its
trajectory: ``runs/`` (the command line, a run's files and sampled observables, run folders, snapshots,
GSD trajectories, initial states, sweeps, flow curves and the task engine) and ``plots/`` (figures and
movies). Everything else (the stepper, geometry, hydrodynamics, contacts, the stress, config, state, the
numba settings) is part of :func:`physics_source_digest`. So a speed-up of the field's kernels keeps the
start states and every result keyed on them."""

DIGESTED_UNDER_FORMER_NAME = {
    "sim.runs.cli": "sim.cli",
    "sim.runs.run": "sim.run",
    "sim.runs.observables": "sim.run_observables",
    "sim.runs.sweep": "sim.sweep",
    "sim.runs.flow_curve": "sim.flow_curve",
    "sim.runs.tasks": "sim.tasks",
    "sim.runs.io": "sim.io",
    "sim.plots.figures": "sim.figures",
    "sim.plots.sweep": "sim.sweep_figures",
}
"""Application modules that moved into ``runs/`` and ``plots/`` (issue 45), each with its former name.
:func:`_normalised_source` digests an import of one under its former name, so that move alone (which
rewrote the imports of ``sim/__init__.py``, a digested file) kept the library key and every state and
result keyed on it. New imports change the key as any code edit does."""

SPLITS = ("train", "validation", "test", "fresh")
"""Every split of the start states; ``fresh`` is held out for the final evaluation."""
DEVELOPMENT_SPLITS = ("train", "validation", "test")
"""The splits :meth:`StateLibrary.missing` and :meth:`StateLibrary.ensure` cover unless told otherwise:
all but ``fresh``, which is generated only when named."""
SPLIT_SEED_OFFSET = {"train": 0, "validation": 100_000, "test": 200_000, "fresh": 300_000}
"""First packing seed of each split; seeds of a split are ``offset + index``."""

DEFAULT_FRESH_SIZE = 128
"""States of the fresh split unless ``split_sizes`` says otherwise: as many as its shipped schedules
(:data:`dipenv.schedules.FRESH_SCHEDULES`), state ``k`` paired with schedule ``k``. A size only bounds the
indices: nothing is generated before a state is asked for."""

DEFAULT_SPLIT_SIZES = {"train": 64, "validation": 8, "test": 16, "fresh": DEFAULT_FRESH_SIZE}


def cache_root() -> Path:
    """``$DIPENV_CACHE_DIR``, else ``$XDG_CACHE_HOME/dipenv``, else ``~/.cache/dipenv``."""
    if os.environ.get("DIPENV_CACHE_DIR"):
        return Path(os.environ["DIPENV_CACHE_DIR"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "dipenv"


def _normalised_source(path: Path) -> bytes:
    """What of a source file can shape a trajectory: for Python, its syntax tree without docstrings and
    other bare string statements (comments and layout never reach the tree); for a data table, its lines
    that are not ``#`` comments. So rewording a docstring or a table's header keeps the digest. (The tree's
    printed form belongs to the Python version: another minor version may give another key, and then the
    states are generated again, never wrongly reused.) An import of a moved application module is
    digested under its former name (:data:`DIGESTED_UNDER_FORMER_NAME`)."""
    text = path.read_text()
    if path.suffix != ".py":
        return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#")).encode()
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module in DIGESTED_UNDER_FORMER_NAME:
            node.module = DIGESTED_UNDER_FORMER_NAME[node.module]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                alias.name = DIGESTED_UNDER_FORMER_NAME.get(alias.name, alias.name)
        body = getattr(node, "body", None)
        if isinstance(body, list):
            kept = [
                statement
                for statement in body
                if not (
                    isinstance(statement, ast.Expr)
                    and isinstance(statement.value, ast.Constant)
                    and isinstance(statement.value.value, str)
                )
            ]
            node.body = kept or [ast.Pass()]  # type: ignore[attr-defined]
    return ast.dump(tree, include_attributes=False).encode()


def pick_start_index(
    options: dict[str, Any], size: int, start_state: str, cycle: int, rng: np.random.Generator
) -> tuple[Any, int]:
    """The start-state index of a reset, and the cycle counter after it: ``options["index"]`` when given
    (unchecked here), else the next of the cycle (``start_state == "cycle"``), else a draw from ``rng``. The
    simulator envs and the surrogate envs share it, so one seed picks one index in both."""
    if "index" in options:
        return options["index"], cycle
    if start_state == "cycle":
        return cycle % size, cycle + 1
    return int(rng.integers(size)), cycle


def source_digest(root: Path, exclude: frozenset[str] = frozenset()) -> str:
    """SHA-256 (16 hex digits) of the relative paths and normalised contents (:func:`_normalised_source`:
    code without docstrings, tables without comments) of the ``.py`` files and data tables
    (``*/tables/*.txt``) under ``root``, less the relative paths in ``exclude`` (an entry ending in ``/``
excludes everything under that folder)."""
    digest = hashlib.sha256()
    for path in sorted(list(root.rglob("*.py")) + list(root.glob("*/tables/*.txt"))):
        relative = path.relative_to(root).as_posix()
        if "__pycache__" in path.parts or any(
            relative == item or (item.endswith("/") and relative.startswith(item)) for item in exclude
        ):
            continue
        digest.update(relative.encode())
        digest.update(_normalised_source(path))
    return digest.hexdigest()[:16]


def _simulator_root() -> Path | None:
    spec = importlib.util.find_spec("sim")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


@functools.lru_cache(maxsize=1)
def simulator_source_digest() -> str:
    """SHA-256 (16 hex digits) of the simulator package's ``.py`` files and data tables."""
    root = _simulator_root()
    return "unknown" if root is None else source_digest(root)


@functools.lru_cache(maxsize=1)
def physics_source_digest() -> str:
    """:func:`source_digest` of the simulator sources that shape a trajectory (all but
    :data:`PHYSICS_EXCLUDED`): part of the library key."""
    root = _simulator_root()
    if root is None:
        raise RuntimeError("the simulator package 'sim' is not importable: its sources cannot be digested")
    return source_digest(root, PHYSICS_EXCLUDED)


@dataclass(frozen=True)
class StartState:
    """One library entry: the state and the per-step rheology of the pre-shear's last strains.

    Attributes:
        state: the simulator state at the end of the pre-shear (field off).
        seed: packing seed.
        split: ``train``, ``validation``, ``test`` or ``fresh``.
        index: index within the split.
        tail_strain: (S,) clock of each tail sample.
        tail_time_step: (S,) step after each sample (time-average weights).
        tail_rheology: (S, 3) ``eta_r``, ``N1``, ``N2`` per sample (units eta gammadot).
    """

    state: sim.SimulationState
    seed: int
    split: str
    index: int
    tail_strain: np.ndarray
    tail_time_step: np.ndarray
    tail_rheology: np.ndarray

    def tail_average(self, window: float) -> np.ndarray:
        """Time average of ``(eta_r, N1, N2)`` over the last ``window`` strains of the pre-shear tail."""
        end = self.tail_strain[-1] + self.tail_time_step[-1]
        mask = self.tail_strain >= end - window - 1e-12
        if not np.any(mask):
            mask[-1] = True
        w = self.tail_time_step[mask]
        return (w[:, None] * self.tail_rheology[mask]).sum(axis=0) / w.sum()


MAX_SPLIT_SIZE = 100_000
"""The most start states one split may hold."""


def check_split_sizes(split_sizes: Any) -> dict[str, int]:
    """Raise ``ValueError`` unless ``split_sizes`` maps each of :data:`DEVELOPMENT_SPLITS`, and optionally
    ``fresh`` (default :data:`DEFAULT_FRESH_SIZE`), and nothing else, to an integer in
    [1, :data:`MAX_SPLIT_SIZE`]; return the sizes of every split in :data:`SPLITS`. The one check, made by
    the envs at construction and by :class:`StateLibrary`."""
    if not isinstance(split_sizes, dict):
        raise ValueError(
            f"split_sizes must be a dict of {', '.join(DEVELOPMENT_SPLITS)} to sizes (fresh optional), got "
            f"{split_sizes!r}"
        )
    unknown = [key for key in split_sizes if key not in SPLITS]
    if unknown:
        raise ValueError(
            f"split_sizes has unknown split {unknown[0]!r} (the splits are {', '.join(SPLITS)}), got "
            f"{split_sizes!r}"
        )
    resolved = {"fresh": DEFAULT_FRESH_SIZE, **split_sizes}
    for split in SPLITS:
        size = resolved.get(split, 0)
        if isinstance(size, bool) or not isinstance(size, int) or not 1 <= size <= MAX_SPLIT_SIZE:
            raise ValueError(
                f"split_sizes[{split!r}] must be an integer in [1, {MAX_SPLIT_SIZE}], got {size!r}"
            )
    return {split: int(resolved[split]) for split in SPLITS}


@dataclass(frozen=True)
class StateLibrary:
    """Pre-sheared start states for one simulation setup.

    Attributes:
        config: the simulation config of the episodes (its seed and strain are ignored; its field must be
            off).
        preshear_strain: strain sheared without field from the random packing (> tail_strain).
        tail_strain: strain at the end of the pre-shear whose per-step rheology is kept (> 0).
        split_sizes: number of states per split (``fresh`` optional: :data:`DEFAULT_FRESH_SIZE`); stored
            with every split filled in.
        root: cache root (default :func:`cache_root`).
    """

    config: sim.SimulationConfig
    preshear_strain: float = 5.0
    tail_strain: float = 1.0
    split_sizes: dict[str, int] = field(default_factory=lambda: dict(DEFAULT_SPLIT_SIZES))
    root: Path | None = None

    def __post_init__(self) -> None:
        if not math.isinf(self.config.mason_number):
            raise ValueError(
                "the start states are pre-sheared without field: config.mason_number must be inf"
            )
        if not (0.0 < self.tail_strain < self.preshear_strain and math.isfinite(self.preshear_strain)):
            raise ValueError(
                "need 0 < tail_strain < preshear_strain (finite), got "
                f"{self.tail_strain}, {self.preshear_strain}"
            )
        object.__setattr__(self, "split_sizes", check_split_sizes(self.split_sizes))

    # -- identity ----------------------------------------------------------------------------------------
    def parameters(self) -> dict[str, Any]:
        """Everything that shapes the states (the cache key is its hash)."""
        config = self.config.to_dict()
        for name in ("seed", "strain", "transient_strain", "checkpoint_every", "n_blocks"):
            config.pop(name, None)
        return {
            "library_version": LIBRARY_VERSION,
            "physics_source": physics_source_digest(),
            "preshear_strain": self.preshear_strain,
            "tail_strain": self.tail_strain,
            "config": config,
        }

    @property
    def key(self) -> str:
        text = json.dumps(self.parameters(), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def directory(self) -> Path:
        return (self.root or cache_root()) / "states" / self.key

    def seed(self, split: str, index: int) -> int:
        """Packing seed of state ``index`` of ``split``."""
        self._check(split, index)
        return SPLIT_SEED_OFFSET[split] + index

    def path(self, split: str, index: int) -> Path:
        return self.directory / f"{split}_{index:05d}_seed{self.seed(split, index)}.npz"

    def _check(self, split: str, index: int) -> None:
        if split not in SPLITS:
            raise ValueError(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
        size = self.split_sizes[split]
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < size:
            raise ValueError(f"index must be an integer in [0, {size}) for split {split!r}, got {index!r}")

    # -- generation ----------------------------------------------------------------------------------------
    def missing(
        self, splits: Iterable[str] = DEVELOPMENT_SPLITS, count: int | None = None
    ) -> list[tuple[str, int]]:
        """``(split, index)`` of the states of ``splits`` (default: all but ``fresh``) not on disk yet;
        ``count``: only among the first ``count`` states of each split (default: all of them)."""
        splits = list(splits)
        for split in splits:
            if split not in SPLITS:
                raise ValueError(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
        if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
            raise ValueError(f"count must be an integer >= 1 (the first states of each split), got {count!r}")
        return [
            (s, i)
            for s in splits
            for i in range(self.split_sizes[s] if count is None else min(count, self.split_sizes[s]))
            if not self.path(s, i).exists()
        ]

    def ensure(
        self,
        splits: Iterable[str] = DEVELOPMENT_SPLITS,
        progress: bool = True,
        workers: int = 1,
        count: int | None = None,
    ) -> None:
        """Generate the missing states of ``splits`` (default: all but ``fresh``, which is generated only
        when named; progress bar on stderr unless ``progress=False``); ``count``: only the first ``count``
        states of each split (an evaluation on its first ``n`` episodes needs no more).

        ``workers > 1`` pre-shears that many states at once in separate processes (each state is
        independent, so the files are the same as with one worker). A state that another process wrote
        meanwhile is not generated again."""
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        splits = list(splits)
        for split in splits:
            if split not in SPLITS:
                raise ValueError(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
        self.missing(splits, count)  # the arguments, checked before anything is discarded
        self._generate_missing(lambda: self.missing(splits, count), progress, workers)

    def _generate_missing(
        self, missing: Callable[[], list[tuple[str, int]]], progress: bool, workers: int
    ) -> None:
        """Generate the states ``missing()`` lists once stale states are discarded."""
        self._discard_if_stale()
        todo = missing()
        if not todo:
            return
        self.directory.mkdir(parents=True, exist_ok=True)
        params = self.directory / "library.json"
        if not params.exists():
            provenance = {**self.parameters(), "sim_source_at_generation": simulator_source_digest()}
            _atomic_write_text(params, json.dumps(provenance, indent=1, sort_keys=True))
        description = (
            f"pre-shearing start states (N={self.config.n_particles}, phi={self.config.volume_fraction}, "
            f"{self.preshear_strain:g} strains)"
        )
        bar = tqdm(total=len(todo), desc=description, unit="state", disable=not progress, leave=False)
        with bar:
            if workers == 1 or len(todo) == 1:
                for split, index in todo:
                    self._generate_if_missing(split, index)
                    bar.update()
                return
            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(min(workers, len(todo)), mp_context=context) as pool:
                jobs = [pool.submit(self._generate_if_missing, split, index) for split, index in todo]
                for job in as_completed(jobs):
                    job.result()
                    bar.update()

    def _generate_if_missing(self, split: str, index: int) -> None:
        if not self.path(split, index).exists():
            self._generate(split, index)

    def stale_reason(self) -> str | None:
        """Why the states in :attr:`directory` are not this library's, or None (none there, or they are).

        They are stale when ``library.json`` records other parameters than :meth:`parameters` (states
        made elsewhere, e.g. copied from a cache of other simulator sources) or is missing or unreadable
        while states are there."""
        if not self.directory.is_dir():
            return None
        params = self.directory / "library.json"
        try:
            recorded = json.loads(params.read_text())
        except (OSError, ValueError):
            if any(self.directory.glob("*.npz")):
                return f"{params} is missing or unreadable"
            return None
        expected = json.loads(json.dumps(self.parameters()))
        differing = sorted(k for k in expected if recorded.get(k) != expected[k])
        if not differing:
            return None
        listed = ", ".join(f"{k} ({recorded.get(k)!r} there, {expected[k]!r} now)" for k in differing)
        return f"{params} records other parameters: {listed}"

    def _discard_if_stale(self) -> None:
        """Delete stale states (:meth:`stale_reason`) and their record, with a warning, so that they are
        generated again."""
        reason = self.stale_reason()
        if reason is None:
            return
        warnings.warn(
            f"start states in {self.directory} are stale ({reason}); generating them again", stacklevel=3
        )
        for path in self.directory.glob("*.npz"):
            path.unlink(missing_ok=True)
        (self.directory / "library.json").unlink(missing_ok=True)

    def _generate(self, split: str, index: int) -> None:
        seed = self.seed(split, index)
        config = replace(self.config, seed=seed, strain=self.preshear_strain)
        simulation = sim.Simulation(config, keep_records=False)
        try:
            simulation.advance_to(self.preshear_strain - self.tail_strain)
            records = simulation.advance_to(self.preshear_strain)
        except sim.SimulationError as error:
            raise RuntimeError(
                f"pre-shearing start state {split}[{index}] (packing seed {seed}) failed: {error}"
            ) from error
        eta, n1, n2 = sim.rheology(records.stress.sum(axis=1))
        arrays = dict(simulation.snapshot().arrays())
        arrays.update(
            tail_strain=records.strain,
            tail_time_step=records.time_step,
            tail_rheology=np.stack([eta, n1, n2], axis=1),
            seed=np.array(seed),
        )
        _atomic_save_npz(self.path(split, index), arrays)

    # -- reading -------------------------------------------------------------------------------------------
    def load(self, split: str, index: int, progress: bool = True) -> StartState:
        """State ``index`` of ``split``, generated first if it is missing (that state only: the rest of its
        split is generated by :meth:`ensure`)."""
        path = self.path(split, index)
        if not path.exists() or self.stale_reason() is not None:
            self._generate_missing(lambda: [] if path.exists() else [(split, index)], progress, 1)
        with np.load(path) as data:
            return StartState(
                state=sim.SimulationState.from_arrays(data),
                seed=int(data["seed"]),
                split=split,
                index=int(index),
                tail_strain=np.array(data["tail_strain"]),
                tail_time_step=np.array(data["tail_time_step"]),
                tail_rheology=np.array(data["tail_rheology"]),
            )


def _atomic_write_text(path: Path, text: str) -> None:
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as handle:
        handle.write(text)
    os.replace(handle.name, path)


def _atomic_save_npz(path: Path, arrays: dict[str, Any]) -> None:
    with tempfile.NamedTemporaryFile(dir=path.parent, delete=False, suffix=".npz") as handle:
        np.savez(handle, **arrays)
    os.replace(handle.name, path)
