"""The application side of ``sim`` (the engine is the rest of ``sim``): run folders and their protocol
(:mod:`sim.runs.folder`, :mod:`sim.runs.legacy`), the configuration a run starts from
(:mod:`sim.runs.initial_state`), and what it keeps on the way: snapshots (:mod:`sim.runs.snapshots`) and
GSD trajectories (:mod:`sim.runs.trajectory`) at multiples of its strain (:mod:`sim.runs.schedule`)."""

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
