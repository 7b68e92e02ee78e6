"""Callbacks: log the physics of each step (from the env's ``info``) to the SB3 logger / TensorBoard,
checkpoints that keep only the newest replay buffer, validation that writes its files atomically, and a
stop on request (SIGTERM) that saves one."""

from __future__ import annotations

import math
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback

from agents.folders import save_atomic


class NewestBufferCheckpointCallback(CheckpointCallback):
    """SB3's ``CheckpointCallback`` that writes each checkpoint atomically as a set, and deletes the older
    replay buffers once a new one is saved.

    A run resumes from its newest checkpoint only, and a replay buffer is the largest file of a run (its
    arrays are allocated for ``buffer_size`` transitions and pickled whole: about 1.2 MB per 10^4
    transitions of a 15-number observation), so ten of them per seed would make a committed SAC study
    ~10x larger than it needs to be. Models and normalisation statistics are kept at every checkpoint
    (for ``agents.evaluate --model best`` and learning curves).

    A set (``ckpt_vecnormalize_<N>_steps.pkl``, ``ckpt_replay_buffer_<N>_steps.pkl``, ``ckpt_<N>_steps.zip``)
    is written file by file to hidden temporary names beside them, each renamed into place once whole
    (:func:`agents.folders.save_atomic`), the model last: a model file means that the rest of its set is in
    place, so that a process killed while writing a checkpoint (SIGKILL, a node lost) leaves the previous
    checkpoint the newest whole one (``agents.train._latest_checkpoint``), not a truncated file, nor a
    model without its statistics. The older replay buffers go only once the new model is in place. The
    temporaries such a process leaves (``.ckpt_*.tmp.*``) are removed when training starts here again."""

    def _init_callback(self) -> None:
        super()._init_callback()
        if self.save_path is not None:  # leftovers of a process killed while writing a checkpoint
            for leftover in Path(self.save_path).glob(f".{self.name_prefix}_*.tmp.*"):
                leftover.unlink(missing_ok=True)

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq == 0:
            self.save_now()
        return True

    def save_now(self) -> None:
        """Save the normalisation statistics, (SAC) the replay buffer and then the model at the current
        step, each atomically, then delete the older replay buffers."""
        normaliser = self.model.get_vec_normalize_env()
        if self.save_vecnormalize and normaliser is not None:
            save_atomic(normaliser.save, Path(self._checkpoint_path("vecnormalize_", extension="pkl")))
        newest = None
        if self.save_replay_buffer and getattr(self.model, "replay_buffer", None) is not None:
            newest = Path(self._checkpoint_path("replay_buffer_", extension="pkl"))
            save_atomic(self.model.save_replay_buffer, newest)  # type: ignore[attr-defined]
        save_atomic(self.model.save, Path(self._checkpoint_path(extension="zip")))
        if newest is not None:  # the new set is whole: the old buffers can go
            for old in newest.parent.glob(f"{self.name_prefix}_replay_buffer_*_steps.pkl"):
                if old != newest:
                    old.unlink()


class AtomicEvalCallback(EvalCallback):
    """SB3's ``EvalCallback`` whose two files, ``FOLDER/evaluations.npz`` and ``FOLDER/best_model.zip``,
    are replaced atomically: SB3 writes them in place, so a process killed while writing left a truncated
    file under the name that ``agents.evaluate --model best`` loads and a resumed run reads its validation
    history from. Here SB3 writes each to a hidden temporary beside it (``FOLDER/.evaluations.tmp.npz``,
    ``FOLDER/.best_model.tmp/best_model.zip``), and once the write has returned it is renamed over the old
    file (``os.replace``). The temporaries a killed process leaves are removed when training starts here
    again. ``folder`` stands for SB3's ``log_path`` and ``best_model_save_path`` (one folder for both, as
    ``agents.train`` uses them).

    ``seed``: every validation pass starts by seeding the validation envs with it (``VecEnv.seed``), so a
    run repeats its validation log and its best model. Without it (SB3's behaviour) the validation env is
    seeded from the OS's entropy at its first reset, so a stochastic env (the surrogates) gave another log
    at every run of the same command. (The passes do not meet identical draws: a ``start_state="cycle"``
    env's cycle moves on at the vector env's automatic reset after a pass, so the next pass plays the
    states in a rotated order against the same draws.)
    """

    def __init__(self, eval_env: Any, folder: str | Path, seed: int | None = None, **kwargs: Any) -> None:
        self.folder = Path(folder)
        self.seed = seed
        self._log_tmp = self.folder / ".evaluations.tmp.npz"
        self._best_tmp = self.folder / ".best_model.tmp"
        super().__init__(
            eval_env, best_model_save_path=str(self._best_tmp), log_path=str(self.folder), **kwargs
        )
        self.log_path = str(self._log_tmp)  # np.savez keeps the .npz suffix

    def _init_callback(self) -> None:
        self._log_tmp.unlink(missing_ok=True)  # leftovers of a process killed while writing
        shutil.rmtree(self._best_tmp, ignore_errors=True)
        super()._init_callback()

    def _on_step(self) -> bool:
        if self.seed is not None and self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
            self.eval_env.seed(self.seed)  # this pass's first reset (SB3's evaluate_policy resets first)
        go_on = super()._on_step()
        if self._log_tmp.exists():
            os.replace(self._log_tmp, self.folder / "evaluations.npz")
        best = self._best_tmp / "best_model.zip"
        if best.exists():
            os.replace(best, self.folder / "best_model.zip")
        return go_on


class StopOnSignalCallback(BaseCallback):
    """Stop training at the next environment step once :meth:`request` has been called (``agents.train``
    installs it as the SIGTERM handler), saving a checkpoint at that step first, so that an interrupted
    run resumes from where it stopped instead of from its last periodic checkpoint. ``stopped_at`` is then
    the step count. A validation pass under way finishes first (it runs inside its own callback)."""

    def __init__(self, checkpoint: NewestBufferCheckpointCallback, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.checkpoint = checkpoint
        self.requested = False
        self.stopped_at: int | None = None

    def request(self, *_: object) -> None:
        """Ask for a stop (signal-handler signature: ``request(signum, frame)``)."""
        self.requested = True

    def _on_step(self) -> bool:
        if not self.requested:
            return True
        self.checkpoint.save_now()
        self.stopped_at = int(self.num_timesteps)
        return False


class PhysicsLoggerCallback(BaseCallback):
    """Record means of ``eta_r``, ``log10 Mn`` (field on), the field-on fraction, the field energy, the
    reward terms and the count of simulator failures under ``physics/`` at every logger dump."""

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.failures = 0

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", []):
            if info.get("simulation_failed"):
                self.failures += 1
                self.logger.record("physics/simulation_failures", self.failures)
                continue
            if "eta_r" not in info or "field_energy" not in info:
                continue
            self.logger.record_mean("physics/eta_r", float(info["eta_r"]))
            self.logger.record_mean("physics/field_energy", float(info["field_energy"]))
            mn = float(info["mason_number"])
            self.logger.record_mean("physics/field_on", 0.0 if math.isinf(mn) else 1.0)
            if math.isfinite(mn):
                self.logger.record_mean("physics/log10_mason", math.log10(mn))
            for key in ("reward_viscosity", "reward_energy", "sim_steps"):
                if key in info:
                    self.logger.record_mean(f"physics/{key}", float(info[key]))
        return True


class ProgressLineCallback(BaseCallback):
    """A line on ``stream`` every ``every`` environment steps: the run, its steps against the total, the
    rate in environment steps per second since this process started it, the time left at that rate, and
    the mean return of the last 10 finished training episodes. For runs without a progress bar (several
    seeds, ``--no-progress``, a log file), so that a long unattended study shows where it is."""

    def __init__(self, name: str, total: int, every: int, stream: TextIO | None = None) -> None:
        super().__init__(0)
        if every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.name, self.total, self.every = name, total, every
        self.stream = stream
        self._start_time = 0.0
        self._start_steps = 0
        self._next = 0

    def _on_training_start(self) -> None:
        self._start_time = time.perf_counter()
        self._start_steps = int(self.model.num_timesteps)
        self._next = (self._start_steps // self.every + 1) * self.every

    def _on_step(self) -> bool:
        steps = int(self.model.num_timesteps)
        if steps < self._next:
            return True
        self._next = (steps // self.every + 1) * self.every
        elapsed = time.perf_counter() - self._start_time
        rate = (steps - self._start_steps) / elapsed if elapsed > 0 else math.nan
        left = (self.total - steps) / rate / 60 if rate > 0 else math.nan
        episodes = [float(e["r"]) for e in list(getattr(self.model, "ep_info_buffer", []))[-10:]]
        recent = f"{sum(episodes) / len(episodes):.1f}" if episodes else "none yet"
        print(
            f"{self.name}: {steps}/{self.total} steps, {rate:.2f} steps/s, {left:.0f} min left; "
            f"mean return of the last {len(episodes)} training episodes: {recent}",
            file=self.stream or sys.stderr,
            flush=True,
        )
        return True
