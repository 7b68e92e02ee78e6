"""Bad command-line input: one way for the ``agents`` commands to refuse it.

``usage_error(prog, message)`` prints ``prog: error: message`` on stderr and exits with status 2, as
argparse does for the arguments it checks itself; the message names the argument and what it accepts.
The other helpers are the checks the commands share, each ending in :func:`usage_error` (or argparse's
own error, for the argparse types): JSON objects, output folders, counts, scheduler addresses, the env
made once with its arguments, split sizes. Every command checks all its arguments before any work.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn


def usage_error(prog: str, message: str) -> NoReturn:
    """Exit with status 2 (argparse's code for bad arguments) and ``message`` on stderr."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def json_object(prog: str, option: str, text: str) -> dict[str, Any]:
    """``text`` parsed as a JSON object, or a usage error naming ``option``."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        usage_error(prog, f"{option} must be a JSON object, got {text!r} ({error})")
    if not isinstance(value, dict):
        usage_error(prog, f"{option} must be a JSON object, got {text!r}")
    return value


def directory(text: str) -> Path:
    """An argparse type for ``--out``: a folder's path; an empty one (``Path("")`` is the current folder)
    is refused with exit 2."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"must name a directory, got {text!r}")
    return Path(text)


def integer_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum`` (``--workers``, ``--n-envs``, ``--timesteps``: 1;
    ``--seed``: 0); anything else is refused with exit 2 naming the range."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def seed_list(text: str) -> list[int]:
    """An argparse type for ``--seeds``: ``0-4`` or ``0,2,5-7`` (non-negative, at most ``MAX_SEEDS``),
    as :func:`sim.tasks.parse_seeds` reads them; the sorted seeds."""
    from agents.tasks import parse_seeds

    try:
        return parse_seeds(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def scheduler_address(text: str) -> str:
    """An argparse type for ``--scheduler``: a Dask scheduler address, ``tcp://HOST:PORT`` (or another
    ``protocol://`` form)."""
    if not re.fullmatch(r"[a-z][a-z0-9+.-]*://\S+", text):
        raise argparse.ArgumentTypeError(
            f"must be a Dask scheduler address like tcp://HOST:8786, got {text!r}"
        )
    return text


def output_directory(prog: str, path: Path, option: str = "--out") -> Path:
    """``path`` if it is a folder, or can be created as one, and can be written; else a usage error naming
    ``option``. Nothing is created (the nearest existing folder above it must be a writable folder)."""
    if path.exists() and not path.is_dir():
        usage_error(prog, f"{option} {path} exists and is not a directory")
    existing = next((p for p in (path, *path.absolute().parents) if p.exists()), None)
    if existing is None or not existing.is_dir():
        usage_error(prog, f"{option} {path} cannot be created: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        usage_error(prog, f"{option} {path} cannot be written: {existing} is read-only")
    return path


def checked_env(prog: str, env_id: str, env_kwargs: dict[str, Any], **fixed: Any) -> Any:
    """The environment ``env_id`` made once with ``env_kwargs`` (and ``fixed``, e.g. ``progress=False``),
    or a usage error: ``--env`` when the id is not one of dipenv's, ``--env-kwargs`` when an argument is
    unknown or its value refused. Cheap (nothing is simulated), so every command calls it before any
    set-up."""
    import dipenv
    from agents.rollout import make_env

    if env_id not in dipenv.ENV_IDS:
        usage_error(prog, f"--env must be one of {', '.join(dipenv.ENV_IDS)}, got {env_id!r}")
    try:
        return make_env(env_id, {**env_kwargs, **fixed})
    except TypeError as error:  # an unknown keyword
        usage_error(prog, f"--env-kwargs {json.dumps(env_kwargs)}: {error}")
    except ValueError as error:
        usage_error(prog, f"--env-kwargs {json.dumps(env_kwargs)}: {error}")


def split_size(prog: str, unwrapped: Any, split: str, episodes: int | None, option: str = "--split") -> int:
    """The number of episodes to play on ``split`` of the env ``unwrapped`` (all its states when
    ``episodes`` is None), or a usage error naming ``option`` or ``--episodes`` with the valid range."""
    sizes = unwrapped.split_sizes
    if split not in sizes:
        usage_error(prog, f"{option} must be one of {', '.join(sizes)}, got {split!r}")
    n = sizes[split] if episodes is None else episodes
    if not 1 <= n <= sizes[split]:
        usage_error(prog, f"--episodes must be in [1, {sizes[split]}] for {option} {split}, got {n}")
    return int(n)
