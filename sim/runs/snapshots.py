"""A run's snapshots: its state at every ``--snapshot-every`` strain, kept in ``snapshots/``.

``python -m sim run ... --snapshot-every S`` keeps the state at the strains ``S, 2S, ...`` after the run's
start (:class:`sim.runs.schedule.StrainMultiples`: the state at the first step at or beyond each) as
``snapshots/strain_XXXX.npz``, named after the multiple (``strain_0005.npz``; with the decimals ``S``
needs, ``strain_0002.5.npz`` for ``S = 0.5``; ``time_XXXX.npz`` in a quiescent run, whose length is a
time). Each file is written atomically and holds what ``final_state.npz`` holds (the state's arrays and
``box_length``, :func:`sim.runs.io.save_final_state`), so ``--initial-state`` reads it. The state inside
carries its exact clock and strain (the file's name is the nominal multiple); the run's last step is
shortened to end at the requested strain, so a multiple at the end is kept at exactly that strain.

Resuming: the schedule restarts from the checkpoint's clock, so a snapshot is written once for every
multiple, before or after an interruption; one written after the last checkpoint by an interrupted run is
written again, with the same contents, when the resumed run reaches it.
"""

from __future__ import annotations

from pathlib import Path

from sim.config import SimulationConfig
from sim.runs import io
from sim.runs.schedule import StrainMultiples, multiples_decimals
from sim.state import SimulationState

SNAPSHOT_FOLDER = "snapshots"
"""The folder of a run's snapshots, inside the run's folder."""


def snapshot_name(length: float, every: float, quiescent: bool = False) -> str:
    """``strain_XXXX.npz`` for the multiple ``length`` of ``every`` (``time_XXXX.npz`` when quiescent):
    four digits before the point and the decimals ``every`` needs (:func:`multiples_decimals`)."""
    decimals = multiples_decimals(every)
    width = 4 + (decimals + 1 if decimals else 0)
    prefix = "time" if quiescent else "strain"
    return f"{prefix}_{length:0{width}.{decimals}f}.npz"


class SnapshotWriter:
    """Writes the state of a run into ``folder`` at the multiples of ``schedule``.

    Args:
        folder: ``<run>/snapshots`` (created when the first snapshot is written).
        config: the run's parameters (the box side written beside the state).
        schedule: the multiples (``include_start=False``: the starting state is the run's input).
    """

    def __init__(self, folder: Path, config: SimulationConfig, schedule: StrainMultiples) -> None:
        self.folder = Path(folder)
        self.config = config
        self.schedule = schedule

    @property
    def next_clock(self) -> float:
        """The clock of the next snapshot."""
        return self.schedule.next_clock

    def write_if_due(self, state: SimulationState) -> Path | None:
        """Write ``state`` if it has reached the next multiple; return the file written (None if none)."""
        index = self.schedule.due(state.time)
        if index is None:
            return None
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / snapshot_name(
            self.schedule.length_at(index), self.schedule.every, self.config.quiescent
        )
        io.save_final_state(path, self.config, state)
        return path
