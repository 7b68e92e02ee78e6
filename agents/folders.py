"""Output folders of the agents commands: the run-folder protocol of :mod:`sim.runs`, and atomic writes.

Every command that writes a folder (``agents.train``, ``agents.open_loop``, ``agents.controllers``,
``agents.evaluate``, ``agents.demo``; the scripts through :func:`claim_for_script` and, for reports beside
a sweep, :func:`report_folder`) claims its ``--out`` with :func:`claim_out` after it has checked all
its arguments and before any work (pre-shearing start states, simulating, training): the claim writes
``manifest.json`` first, naming the command and its identity (the parameters that make the folder's results
what they are; not ``--workers`` and the like). The rules are :mod:`sim.runs`'s, the same for every
command: a rerun of the same command and identity continues (what these commands always did: finished work
is reused); ``--resume`` insists on that; ``--overwrite`` deletes the whole previous run; a folder of another
command, or of the same command with other parameters, or a non-empty folder without a manifest, is refused
with exit 2 naming the folder. A folder written before manifests existed is adopted when it holds the
command's own files (its ``legacy`` markers, :func:`legacy_markers`), never another command's.

Files are written atomically (:func:`write_text_atomic`, :func:`save_figure`): a file is either its old
or its new contents, never a half-written one. :func:`read_evaluation_log` reads a run's validation log
back, naming the file and what is wrong with a bad one; :func:`read_run_config` a run's ``config.yml``, and
:func:`run_folders` finds the runs an argument names (a run folder, or a folder of them).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from agents.usage import usage_error
from sim.runs import MANIFEST, Claim, RunFolderError, check_writable_parent, claim, read_manifest

__all__ = [
    "MANIFEST",
    "add_folder_options",
    "check_parent",
    "claim_for_script",
    "claim_out",
    "command_line",
    "compare_paths",
    "legacy_conflict",
    "legacy_markers",
    "normalise",
    "owner",
    "read_evaluation_log",
    "read_run_config",
    "run_folders",
    "report_folder",
    "save_figure",
    "write_command",
    "write_text_atomic",
]


def add_folder_options(parser: argparse.ArgumentParser, what: str = "--out") -> None:
    """``--resume`` and ``--overwrite``, with the protocol's meaning."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument(
        "--resume",
        action="store_true",
        help=f"continue the run in {what} (its manifest.json names this command and the same parameters); "
        "refuse anything else (a plain rerun continues too, and starts a new folder)",
    )
    group.add_argument(
        "--overwrite",
        action="store_true",
        help=f"delete the whole previous run in {what} (one made by an agents command or sim: it holds a "
        "manifest.json) and start afresh; a folder without a manifest is never deleted",
    )


def command_line(module: str, argv: Sequence[str] | None) -> list[str]:
    """The command line of ``python -m module`` with ``argv`` (``sys.argv[1:]`` when None)."""
    return [sys.executable, "-m", module, *(sys.argv[1:] if argv is None else argv)]


def claim_out(
    prog: str,
    folder: Path,
    command: str,
    params: Mapping[str, Any],
    *,
    argv: Sequence[str],
    resume: bool = False,
    overwrite: bool = False,
    legacy: Sequence[str] = (),
    compare: Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]] | None = None,
    flag: str = "--out",
) -> Claim:
    """:func:`sim.runs.claim`, its refusal an exit 2 (``usage_error``) naming the folder and why."""
    try:
        return claim(
            folder,
            command,
            params,
            resume=resume,
            overwrite=overwrite,
            argv=list(argv),
            legacy=legacy,
            compare=compare,
            flag=flag,
        )
    except RunFolderError as error:
        usage_error(prog, str(error))


def owner(prog: str, folder: Path, option: str) -> str | None:
    """The command named by ``folder``'s manifest, None without one; exit 2 naming ``option`` when the
    manifest cannot be read."""
    try:
        manifest = read_manifest(folder)
    except RunFolderError as error:
        usage_error(prog, f"{option}: {error}")
    return None if manifest is None else manifest.command


def _names_module(command_file: Path, module: str) -> bool:
    """Whether ``command_file`` (a ``command.txt``) records a ``python -m module`` command line."""
    try:
        words = command_file.read_text().split()
    except (OSError, UnicodeDecodeError):
        return False
    return any(a == "-m" and b == module for a, b in zip(words, words[1:], strict=False))


def _names_script(command_file: Path, script: str) -> bool:
    """Whether ``command_file`` (a ``command.txt``) records a command line that runs ``scripts/<script>``."""
    try:
        words = command_file.read_text().split()
    except (OSError, UnicodeDecodeError):
        return False
    return any(Path(word).name == script for word in words[:3])


def legacy_markers(
    folder: Path, files: Iterable[str], module: str | None = None, script: str | None = None
) -> list[str]:
    """The ``legacy`` markers of a command for :func:`claim_out`: ``files`` (the command's own output
    files, relative to ``folder``), and ``command.txt`` where it records ``python -m module`` (or, for a
    script, ``python scripts/<script>``): an interrupted pre-manifest run holds little else, and another
    command's ``command.txt`` is no marker."""
    markers = list(files)
    command_file = folder / "command.txt"
    if (module is not None and _names_module(command_file, module)) or (
        script is not None and _names_script(command_file, script)
    ):
        markers.append("command.txt")
    return markers


def claim_for_script(
    parser: argparse.ArgumentParser,
    folder: Path,
    script: str,
    params: Mapping[str, Any],
    *,
    argv: Sequence[str] | None,
    resume: bool = False,
    overwrite: bool = False,
    legacy: Sequence[str] = (),
    compare: Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]] | None = None,
    flag: str = "--out",
) -> Claim:
    """:func:`claim_out` for ``scripts/<script>`` (the command ``"scripts/<script>"``): a refusal is
    ``parser.error`` (exit 2). Also writes ``folder/command.txt`` atomically."""
    words = [sys.executable, f"scripts/{script}", *(sys.argv[1:] if argv is None else argv)]
    try:
        claimed = claim(
            folder,
            f"scripts/{script}",
            params,
            resume=resume,
            overwrite=overwrite,
            argv=words,
            legacy=legacy,
            compare=compare,
            flag=flag,
        )
    except RunFolderError as error:
        parser.error(str(error))
    write_text_atomic(Path(folder) / "command.txt", " ".join(words) + "\n")
    return claimed


def check_parent(parser: argparse.ArgumentParser, folder: Path, flag: str = "--out") -> None:
    """:func:`sim.runs.check_writable_parent` for a script: ``parser.error`` (exit 2) before any work when
    ``folder`` cannot be created or written."""
    try:
        check_writable_parent(folder, flag)
    except RunFolderError as error:
        parser.error(str(error))


RUN_CONTENT_FILES = ("model.zip", "vecnormalize.pkl", "best_model.zip")
"""The files that make a trained run what it is (:func:`run_content`): its final model, its normalisation
statistics and its best model (``eval/``); checkpoints and logs are not part of it."""


def run_content(folder: str | Path) -> str | None:
    """SHA-256 over a run folder's (or a folder of runs') :data:`RUN_CONTENT_FILES`, each with its path
    relative to ``folder`` (``checkpoints/`` left out), or None when ``folder`` holds none of them: two
    folders with the same digest hold the same policies, wherever they lie."""
    root = Path(folder)
    if not root.is_dir():
        return None
    digest = hashlib.sha256()
    found = False
    for path in sorted(root.rglob("*")):
        relative = path.relative_to(root)
        if path.name not in RUN_CONTENT_FILES or "checkpoints" in relative.parts or not path.is_file():
            continue
        found = True
        digest.update(relative.as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest() if found else None


def compare_paths(
    path_keys: Sequence[str], content_keys: Sequence[str] = ()
) -> Callable[[Mapping[str, Any], Mapping[str, Any]], list[str]]:
    """An identity comparison for :func:`claim_out` in which the values of ``path_keys`` (a path, a list of
    paths or None) are equal when they name the same files from the current folder (``runs/x`` and
    ``./runs/x/``, or a relative and an absolute spelling): a rerun from the repository root of another
    checkout is the same run. The values of ``content_keys`` (trained runs' folders) are also equal when
    the folders, wherever they lie, hold the same policies (:func:`run_content`): a run copied from a
    scratch folder into the repository is the same run."""

    def resolved(value: Any) -> Any:
        if isinstance(value, str):
            return str(Path(value).resolve())
        if isinstance(value, list):
            return [resolved(v) for v in value]
        return value

    def contents(value: Any) -> Any:
        if isinstance(value, str):
            return run_content(value) or str(Path(value).resolve())
        if isinstance(value, list):
            return [contents(v) for v in value]
        return value

    def same(key: str, a: Any, b: Any) -> bool:
        if key not in path_keys:
            return False
        if resolved(a) == resolved(b):
            return True
        return key in content_keys and contents(a) == contents(b)

    def compare(saved: Mapping[str, Any], requested: Mapping[str, Any]) -> list[str]:
        a, b = normalise(saved), normalise(requested)
        keys = sorted(key for key in set(a) | set(b) if a.get(key, _MISSING) != b.get(key, _MISSING))
        return [key for key in keys if not same(key, a.get(key), b.get(key))]

    return compare


_MISSING = object()


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, Mapping):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def normalise(params: Mapping[str, Any]) -> dict[str, Any]:
    """``params`` as the manifest stores them (JSON, non-finite floats as strings, paths as strings), so
    that an identity compares equal to its stored self."""
    result: dict[str, Any] = json.loads(json.dumps(_finite(dict(params)), default=str, sort_keys=True))
    return result


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a temporary file beside it, then renamed over it)."""
    path = Path(path)
    handle, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def save_atomic(save: Callable[[str], Any], path: Path) -> None:
    """``save(file)`` (SB3's ``model.save``, ``save_replay_buffer``, ``VecNormalize.save``) into a temporary
    file beside ``path``, :func:`temporary_name`, then renamed over ``path`` (``os.replace``): ``path`` is
    either absent, its previous content, or whole, never a truncated file of a process killed while
    writing. The temporary file is removed on an exception; one left by a killed process is hidden
    (``.`` first) and overwritten by the next save of ``path``."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        save(str(tmp))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def temporary_name(path: Path) -> Path:
    """The temporary file :func:`save_atomic` writes ``path`` to: ``.<stem>.tmp<suffix>`` beside it (the
    same suffix: SB3 appends ``.zip`` or ``.pkl`` to a name without it)."""
    path = Path(path)
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def write_command(folder: Path, module: str, argv: Sequence[str] | None) -> None:
    """``folder/command.txt``: the command line, atomically."""
    write_text_atomic(Path(folder) / "command.txt", " ".join(command_line(module, argv)) + "\n")


def save_figure(fig: Any, path: Path, **kwargs: Any) -> None:
    """``fig.savefig(path, **kwargs)`` atomically (the format from ``path``'s suffix)."""
    path = Path(path)
    handle, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(handle)
    try:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or None, **kwargs)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_evaluation_log(path: Path) -> dict[str, Any]:
    """An ``eval/evaluations.npz`` (SB3's ``EvalCallback`` log) as arrays ``timesteps`` (1-D, integers),
    ``results`` and ``ep_lengths`` (2-D, a row per evaluation); ``ValueError`` naming the file and what is
    wrong (unreadable or truncated, keys missing, shapes that disagree, non-finite returns)."""
    import zipfile

    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in ("timesteps", "results", "ep_lengths") if k not in data.files]
            if missing:
                raise ValueError(f"{path}: not an evaluation log (lacks {', '.join(missing)})")
            log = {k: np.asarray(data[k]) for k in ("timesteps", "results", "ep_lengths")}
    except ValueError as error:
        if str(error).startswith(str(path)):
            raise
        raise ValueError(f"{path} cannot be read as an evaluation log ({error})") from None
    except (OSError, EOFError, zipfile.BadZipFile, KeyError) as error:
        raise ValueError(
            f"{path} cannot be read as an evaluation log ({type(error).__name__}: {error}; truncated?)"
        ) from None
    steps, results, lengths = log["timesteps"], log["results"], log["ep_lengths"]
    shapes_agree = steps.ndim == 1 and results.ndim == 2 and results.shape[0] == steps.size
    if not shapes_agree or lengths.shape != results.shape:
        raise ValueError(
            f"{path}: timesteps {steps.shape}, results {results.shape} and ep_lengths {lengths.shape} do not "
            "match (one row of returns and lengths per evaluation)"
        )
    if not (np.issubdtype(steps.dtype, np.integer) and np.isfinite(results).all() and results.shape[1] > 0):
        raise ValueError(f"{path}: timesteps must be integers and every return finite")
    return log


def legacy_conflict(
    folder: Path, source: Path, recorded: Mapping[str, Any], requested: Mapping[str, Any], flag: str = "--out"
) -> str | None:
    """Why a folder made before manifests cannot be adopted for the identity ``requested``, or None:
    ``recorded`` (what its file ``source`` records of the same keys; a key it does not record is not
    compared) differs. The message names the folder, the file and the keys."""
    a, b = normalise(recorded), normalise(requested)
    keys = sorted(k for k in a if k in b and a[k] != b[k])
    if not keys:
        return None
    shown = "; ".join(f"{k}: {a[k]!r} there, {b[k]!r} requested" for k in keys[:4])
    return (
        f"{flag} {folder} holds a run made with other parameters ({source.name} records {shown}); choose "
        f"another {flag}, or give --overwrite to delete that run and start afresh"
    )


def report_folder(
    parser: argparse.ArgumentParser,
    source: Path,
    out: Path | None,
    script: str,
    files: Sequence[str],
    *,
    argv: Sequence[str] | None,
    resume: bool = False,
    overwrite: bool = False,
) -> Path:
    """Where a report script (``scripts/<script>``, which summarises the folder ``source`` into ``files``)
    writes: beside ``source``'s results when ``out`` is None or ``source`` itself (the reports are derived
    files of that run, rewritten every time; the folder stays its owner's: nothing is claimed), else the
    folder ``out``, claimed for the script with the identity ``source`` (:func:`claim_for_script`; a
    pre-manifest folder that holds ``files`` and is not a sweep is adopted)."""
    if out is None or out.resolve() == source.resolve():
        if overwrite:
            parser.error(
                f"--overwrite deletes a previous report folder; the reports beside {source} are rewritten "
                "anyway (give --out for a folder of their own)"
            )
        return source
    check_parent(parser, out)
    sweep = (out / "sweep.json").exists()  # a sweep's results are not a report's folder
    claim_for_script(
        parser,
        out,
        script,
        {"source": os.path.normpath(str(source))},
        argv=argv,
        resume=resume,
        overwrite=overwrite,
        legacy=[] if sweep else legacy_markers(out, files, script=script),
        compare=compare_paths(["source"]),
    )
    return out


TRAIN_CONFIG_KEYS = ("env_id", "env_kwargs", "algo", "seed")
"""The keys every ``agents.train`` ``config.yml`` holds that the commands reading runs rely on."""


def read_run_config(run: Path, option: str = "RUN_DIRS") -> dict[str, Any]:
    """Run folder ``run``'s ``config.yml`` (``agents.train``); ``ValueError`` naming ``option`` and the file
    when it is missing, corrupt or of another shape (the keys :data:`TRAIN_CONFIG_KEYS`, ``algo`` ppo or
    sac, ``env_kwargs`` a mapping)."""
    path = run / "config.yml"
    try:
        config = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        raise ValueError(f"{option}: {path} cannot be read ({type(error).__name__}: {error})") from None
    if not isinstance(config, dict) or any(k not in config for k in TRAIN_CONFIG_KEYS):
        needs = ", ".join(TRAIN_CONFIG_KEYS)
        raise ValueError(f"{option}: {path} is not an agents.train config.yml (needs {needs})")
    if config["algo"] not in ("ppo", "sac") or not isinstance(config["env_kwargs"], dict):
        raise ValueError(f"{option}: {path}: algo must be ppo or sac and env_kwargs a mapping")
    return config


def run_folders(path: Path, marker: str = "model.zip", option: str = "RUN_DIRS") -> tuple[Path, list[Path]]:
    """The run folders an argument names, and the folder that names them: ``path`` itself when it holds
    ``marker`` (``model.zip``: a finished run; ``eval/evaluations.npz``: a run with a validation, also one
    still training), keyed by its parent; otherwise its subfolders that hold it, keyed by ``path``.
    ``ValueError`` naming ``option`` when there is none."""
    if (path / marker).exists():
        return path.parent, [path]
    depth = len(Path(marker).parts)
    runs = sorted(p.parents[depth - 1] for p in path.glob(f"*/{marker}"))
    if not runs:
        raise ValueError(f"{option} {path}: no {marker} in it or in its subfolders (an agents.train run)")
    return path, runs
