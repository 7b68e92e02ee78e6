"""The run-folder protocol: one owner per output folder, named in a manifest written first.

Every command that writes a result folder (``sim run``, ``sim sweep``, ``sim flow-curve``,
``agents.train``, ``agents.open_loop``, ``agents.controllers``, ``agents.evaluate``, ``agents.demo`` and
the scripts that write folders) claims it with :func:`claim` before it writes anything else. The claim
writes ``manifest.json``:

=================== ====================================================================================
``command``         who owns the folder (``"sim run"``, ``"agents.train"``, ...)
``params``          the parameters that make the folder's results what they are (the identity; JSON-safe,
                    non-finite numbers as ``"inf"``/``"-inf"``/``"nan"`` so that they round-trip)
``argv``            the command line that claimed it
``version``         the project version
``source_digest``   a digest of the ``sim`` sources (:func:`sim.runs.io.versions`)
``created``         UTC time of the claim
=================== ====================================================================================

The rules, the same for every command:

* A missing or empty folder is created and claimed.
* A folder that holds a manifest of the same command and the same identity is continued (a rerun
  resumes: finished work is reused, interrupted work continues). ``resume=True`` (``--resume``) insists
  on that: it refuses a folder that holds no such run.
* A folder that another command owns, or the same command with other parameters, is refused with
  :class:`RunFolderError` naming the folder and what differs, unless ``overwrite=True``
  (``--overwrite``), which deletes the whole previous run (everything in the folder) and claims it anew.
* A non-empty folder without a manifest is refused, even with ``overwrite`` (it may hold anything: the
  protocol never deletes a folder it did not make), except a folder of the same command written before
  manifests existed: it holds one of the command's ``legacy`` marker files, and is adopted (the manifest
  is added; the command's own checks of its old files still run).
* A path that exists and is not a folder, or a folder that cannot be written, is refused.

Commands map :class:`RunFolderError` to exit status 2 with its message. :func:`preview` tells what
:func:`claim` would do (or raises what it would raise) without writing anything, so that a command can
check its folder, then validate the files it would continue from, before it claims the folder and works.
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.runs.io import json_ready, write_text_atomically

MANIFEST = "manifest.json"
"""The manifest's file name."""

SCHEMA = 1
"""Version of the manifest's layout."""


class RunFolderError(ValueError):
    """A folder that this command may not write into (the message names it and says why)."""


@dataclass(frozen=True)
class Manifest:
    """The parsed ``manifest.json`` of a folder."""

    command: str
    params: dict[str, Any]
    argv: list[str]
    version: str
    source_digest: str
    created: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "command": self.command,
            "params": self.params,
            "argv": self.argv,
            "version": self.version,
            "source_digest": self.source_digest,
            "created": self.created,
        }


def normalise(params: Mapping[str, Any]) -> dict[str, Any]:
    """``params`` as they read back from JSON: non-finite floats as strings, tuples as lists, paths as
    strings, keys as strings. Two identities are equal when their normalised forms are."""
    return json.loads(json.dumps(json_ready(dict(params)), default=str, sort_keys=True))


def differing(saved: Mapping[str, Any], requested: Mapping[str, Any]) -> list[str]:
    """Keys (sorted) whose normalised values differ between two identities (a key missing on one side
    differs)."""
    a, b = normalise(saved), normalise(requested)
    return sorted(key for key in set(a) | set(b) if a.get(key, _MISSING) != b.get(key, _MISSING))


_MISSING = object()


def read_manifest(folder: Path) -> Manifest | None:
    """The manifest of ``folder``, None if it has none; :class:`RunFolderError` if it is unreadable."""
    path = Path(folder) / MANIFEST
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text())
        if not isinstance(data, dict) or not isinstance(data.get("params"), dict):
            raise ValueError("not a manifest object")
        return Manifest(
            command=str(data["command"]),
            params=data["params"],
            argv=[str(a) for a in data.get("argv", [])],
            version=str(data.get("version", "")),
            source_digest=str(data.get("source_digest", "")),
            created=str(data.get("created", "")),
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RunFolderError(
            f"{path} is not a readable manifest ({type(exc).__name__}: {exc}); the folder's owner is "
            "unknown: "
            "choose another output folder, or delete that folder yourself"
        ) from None


def _source_digest() -> str:
    from sim.numba_cache import source_digest

    return source_digest(Path(__file__).resolve().parent.parent)


def write_manifest(
    folder: Path, command: str, params: Mapping[str, Any], argv: Sequence[str] | None = None
) -> Manifest:
    """Write ``folder/manifest.json`` atomically and return it."""
    from sim import __version__

    manifest = Manifest(
        command=command,
        params=normalise(params),
        argv=[str(a) for a in (sys.argv if argv is None else argv)],
        version=__version__,
        source_digest=_source_digest(),
        created=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    )
    write_text_atomically(Path(folder) / MANIFEST, json.dumps(manifest.to_dict(), indent=2) + "\n")
    return manifest


def _clear(folder: Path) -> None:
    """Delete everything in ``folder`` (not the folder itself)."""
    for entry in folder.iterdir():
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()


def _describe(params: Mapping[str, Any], keys: Sequence[str], limit: int = 6) -> str:
    shown = [f"{key}={params.get(key, '(unset)')!r}" for key in keys[:limit]]
    more = f" and {len(keys) - limit} more" if len(keys) > limit else ""
    return ", ".join(shown) + more


@dataclass(frozen=True)
class Claim:
    """What :func:`claim` found: ``state`` is ``"new"`` (created or empty), ``"same"`` (a run of this
    command and identity, to continue), ``"adopted"`` (a pre-manifest folder of this command) or
    ``"overwritten"`` (the previous run deleted)."""

    folder: Path
    state: str
    manifest: Manifest


def preview(
    folder: str | Path,
    command: str,
    params: Mapping[str, Any],
    *,
    resume: bool = False,
    overwrite: bool = False,
    legacy: Sequence[str] = (),
    compare: Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]] | None = None,
    flag: str = "--out",
    resume_flag: str = "--resume",
    overwrite_flag: str = "--overwrite",
) -> str:
    """What :func:`claim` would find in ``folder`` (its ``state``: ``"new"``, ``"same"``, ``"adopted"`` or
    ``"overwritten"``), or the :class:`RunFolderError` it would raise; nothing is created or written.

    A command checks its folder with this before any work (and before it validates the files it would
    continue from), and claims it once everything is known to be in order."""
    folder = Path(folder)
    if resume and overwrite:
        raise RunFolderError(f"{resume_flag} and {overwrite_flag} exclude each other")
    if folder.exists() and not folder.is_dir():
        raise RunFolderError(f"{flag} {folder} exists and is not a folder")
    if not folder.exists():
        if resume:
            raise RunFolderError(f"{resume_flag}: {flag} {folder} holds no run to continue (no such folder)")
        check_writable_parent(folder, flag)
        return "new"
    try:
        entries = [entry.name for entry in folder.iterdir()]
    except OSError as exc:
        raise RunFolderError(f"{flag} {folder} cannot be used: {exc.strerror or exc}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise RunFolderError(f"{flag} {folder} is not writable")
    manifest = read_manifest(folder) if MANIFEST in entries else None
    if manifest is None and entries:
        owned = [name for name in legacy if (folder / name).exists()]
        if not owned:
            shown = ", ".join(sorted(entries)[:5]) + (", ..." if len(entries) > 5 else "")
            raise RunFolderError(
                f"{flag} {folder} is not empty ({shown}) and holds no {MANIFEST}, so no command owns it; "
                f"choose a new or empty folder ({overwrite_flag} never deletes a folder it did not make)"
            )
        return "overwritten" if overwrite else "adopted"
    if manifest is None:
        if resume:
            raise RunFolderError(f"{resume_flag}: {flag} {folder} holds no run to continue")
        return "new"
    if overwrite:
        return "overwritten"
    if manifest.command != command:
        raise RunFolderError(
            f"{flag} {folder} belongs to another command ({manifest.command!r}, made by "
            f"{' '.join(manifest.argv) or 'an unknown command line'}); choose another {flag}, or give "
            f"{overwrite_flag} to delete that run and start afresh"
        )
    keys = (compare or differing)(manifest.params, params)
    if keys:
        requested = normalise(params)
        raise RunFolderError(
            f"{flag} {folder} holds a run of {command} with other parameters: "
            f"{_describe(manifest.params, keys)} there, {_describe(requested, keys)} requested; choose "
            f"another {flag}, or give {overwrite_flag} to delete that run and start afresh"
        )
    return "same"


def claim(
    folder: str | Path,
    command: str,
    params: Mapping[str, Any],
    *,
    resume: bool = False,
    overwrite: bool = False,
    argv: Sequence[str] | None = None,
    legacy: Sequence[str] = (),
    compare: Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]] | None = None,
    flag: str = "--out",
    resume_flag: str = "--resume",
    overwrite_flag: str = "--overwrite",
) -> Claim:
    """Claim ``folder`` for ``command`` with identity ``params`` (module docstring), or raise
    :class:`RunFolderError` naming ``flag`` and the folder (then nothing is created or written).

    Args:
        legacy: files (or sub-folders) by which a folder this command wrote before manifests existed is
            recognised; such a folder is adopted.
        compare: ``compare(saved, requested)`` lists the identity keys that forbid continuing (default
            :func:`differing`); a command that may extend a run (a longer ``strain``) leaves that key out.
    """
    folder = Path(folder)
    state = preview(
        folder,
        command,
        params,
        resume=resume,
        overwrite=overwrite,
        legacy=legacy,
        compare=compare,
        flag=flag,
        resume_flag=resume_flag,
        overwrite_flag=overwrite_flag,
    )
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunFolderError(f"{flag} {folder} cannot be created: {exc.strerror or exc}") from None
    if state == "overwritten":
        _clear(folder)
    if state == "same":
        manifest = read_manifest(folder)
        assert manifest is not None
        if normalise(params) != manifest.params:  # an allowed change (e.g. a longer strain): record it
            manifest = write_manifest(folder, command, params, argv)
        return Claim(folder, state, manifest)
    return _new(folder, command, params, argv, state)


def _new(
    folder: Path, command: str, params: Mapping[str, Any], argv: Sequence[str] | None, state: str
) -> Claim:
    return Claim(folder, state, write_manifest(folder, command, params, argv))


def check_writable_parent(folder: str | Path, flag: str = "--out") -> None:
    """Refuse (``RunFolderError``) an output path whose nearest existing ancestor is not a writable
    folder, before any work starts (``/sys/...``, a path under a file)."""
    path = Path(folder).absolute()
    for ancestor in (path, *path.parents):
        if ancestor.exists():
            if not ancestor.is_dir():
                raise RunFolderError(f"{flag} {folder}: {ancestor} exists and is not a folder")
            if not os.access(ancestor, os.W_OK | os.X_OK):
                raise RunFolderError(f"{flag} {folder}: {ancestor} is not writable")
            return
