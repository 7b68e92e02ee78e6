"""Folders that ``sim``'s commands wrote before manifests existed (:mod:`sim.runs.folder`).

Such a folder holds no ``manifest.json``; what it holds tells which command made it:

=================== ===================================================================================
``sim sweep``       ``sweep.json``
``sim flow-curve``  ``flow_curve.csv``, a ``params.json`` with a ``flow_curve`` entry, or only ``Mn<value>``
                    sub-folders that are such curves (several fields, stopped before the combined csv)
``sim run``         ``params.json`` (with a ``config`` entry), ``checkpoint.npz`` or ``result.json``
=================== ===================================================================================

A command adopts a folder of its own (after its own checks of the old files); another command's folder
is refused, naming the command, unless ``--overwrite`` deletes it (it is a ``sim`` run, not an unknown
folder: the protocol's rule that ``--overwrite`` never deletes a folder it did not make does not apply).
"""

from __future__ import annotations

import json
from pathlib import Path

from sim.runs.folder import MANIFEST, RunFolderError

MARKERS = {
    "sim sweep": ("sweep.json",),
    "sim flow-curve": ("flow_curve.csv", "params.json", "checkpoint.npz"),
    "sim run": ("params.json", "checkpoint.npz", "result.json"),
}
"""The files by which each command's pre-manifest folder is recognised (the ``legacy`` of
:func:`sim.runs.folder.claim`)."""


def _params_entry(folder: Path) -> str | None:
    """The top-level entry of ``folder/params.json`` that tells its maker (``flow_curve``, ``config``)."""
    try:
        data = json.loads((folder / "params.json").read_text())
    except (OSError, ValueError):
        return None
    if isinstance(data, dict):
        for key in ("flow_curve", "config"):
            if key in data:
                return key
    return None


def legacy_command(folder: str | Path) -> str | None:
    """The ``sim`` command that wrote ``folder`` before manifests existed, or None (a folder with a
    manifest, a missing or empty folder, or one that no ``sim`` command made)."""
    folder = Path(folder)
    if not folder.is_dir() or (folder / MANIFEST).exists():
        return None
    if (folder / "sweep.json").exists():
        return "sim sweep"
    entry = _params_entry(folder) if (folder / "params.json").is_file() else None
    if (folder / "flow_curve.csv").exists() or entry == "flow_curve":
        return "sim flow-curve"
    if any((folder / name).exists() for name in MARKERS["sim run"]):
        return "sim run"
    if _curve_folders(folder):
        return "sim flow-curve"
    return None


def _curve_folders(folder: Path) -> tuple[str, ...]:
    """The ``Mn<value>`` sub-folders of ``folder`` if it holds nothing else and each is a pre-manifest
    flow curve (a several-field curve stopped before its combined csv), else ()."""
    entries = list(folder.iterdir())
    if entries and all(
        entry.is_dir() and entry.name.startswith("Mn") and legacy_command(entry) == "sim flow-curve"
        for entry in entries
    ):
        return tuple(sorted(entry.name for entry in entries))
    return ()


def legacy_markers(
    folder: str | Path,
    command: str,
    overwrite: bool,
    flag: str = "--out",
    overwrite_flag: str = "--overwrite",
) -> tuple[str, ...]:
    """The ``legacy`` argument of :func:`sim.runs.folder.claim` for ``command`` claiming ``folder``.

    A pre-manifest folder of ``command`` gives its marker files (it is adopted); one of another ``sim``
    command gives them only with ``overwrite`` (it is deleted) and is refused otherwise, naming the
    command; anything else gives none (the protocol's own rules apply)."""
    folder = Path(folder)
    maker = legacy_command(folder)
    if maker is None:
        return ()
    present = tuple(name for name in MARKERS[maker] if (folder / name).exists()) or _curve_folders(folder)
    if maker == command or overwrite:
        return present
    raise RunFolderError(
        f"{flag} {folder} holds a run of {maker} written before manifests ({', '.join(present)}); choose "
        f"another {flag}, or give {overwrite_flag} to delete that run and start afresh"
    )
