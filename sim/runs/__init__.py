"""The application side of ``sim`` (the engine is the rest of ``sim``; figures are :mod:`sim.plots`): the
command line (:mod:`sim.runs.cli`, ``python -m sim``), single runs (:mod:`sim.runs.run`) and the
observables they sample (:mod:`sim.runs.observables`), sweeps (:mod:`sim.runs.sweep`), flow curves
(:mod:`sim.runs.flow_curve`), the task engine (:mod:`sim.runs.tasks`), run files (:mod:`sim.runs.io`),
run folders and their protocol (:mod:`sim.runs.folder`, :mod:`sim.runs.legacy`), the configuration a run
starts from (:mod:`sim.runs.initial_state`), and what it keeps on the way: snapshots
(:mod:`sim.runs.snapshots`) and GSD trajectories (:mod:`sim.runs.trajectory`) at multiples of its strain
(:mod:`sim.runs.schedule`).

This ``__init__`` imports only the folder protocol (and :mod:`sim.runs.io`, which it writes with), never
the command line: keep it so (``sim/__init__.py`` imports it, and the modules above import it back)."""

from sim.runs.folder import (
    MANIFEST,
    Claim,
    Manifest,
    RunFolderError,
    check_writable_parent,
    claim,
    differing,
    normalise,
    preview,
    read_manifest,
)

__all__ = [
    "MANIFEST",
    "Claim",
    "Manifest",
    "RunFolderError",
    "check_writable_parent",
    "claim",
    "differing",
    "normalise",
    "preview",
    "read_manifest",
]
