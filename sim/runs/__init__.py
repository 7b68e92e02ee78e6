"""The application side of ``sim``: run folders and their protocol (the engine is the rest of ``sim``)."""

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
