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
import math
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
    as :func:`sim.runs.tasks.parse_seeds` reads them; the sorted seeds."""
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

    known = (*dipenv.ENV_IDS, *dipenv.SURROGATE_IDS, *dipenv.TRACKING_SURROGATE_IDS)
    if env_id not in known:
        usage_error(prog, f"--env must be one of {', '.join(known)}, got {env_id!r}")
    try:
        env = make_env(env_id, {**env_kwargs, **fixed})
    except TypeError as error:  # an unknown keyword
        usage_error(prog, f"--env-kwargs {json.dumps(env_kwargs)}: {error}")
    except ValueError as error:
        usage_error(prog, f"--env-kwargs {json.dumps(env_kwargs)}: {error}")
    problem = reward_problem(env.unwrapped)
    if problem is not None:
        env.close()
        usage_error(prog, f"--env-kwargs {json.dumps(env_kwargs)}: {problem}")
    return env


def reward_problem(unwrapped: Any) -> str | None:
    """Why the reward of the env ``unwrapped`` is meaningless, or None: its target ``eta_r`` (the
    thickening-control envs' cap ``eta_cap``) must be a relative viscosity, finite and > 0 (a suspension's
    ``eta_r`` is >= 1: a cap of -1 would count every interval as thickened). The env itself only asks for
    a finite value."""
    reward = getattr(unwrapped, "reward_function", None)
    target = getattr(reward, "target_viscosity", None)
    if target is None:
        return None
    name = "eta_cap" if hasattr(unwrapped, "explicit_cap") else "target_viscosity"
    if not (math.isfinite(float(target)) and float(target) > 0.0):
        return f"{name} must be a relative viscosity, finite and > 0, got {target!r}"
    return None


def compile_notice(scheduler: str | None = None) -> bool:
    """Print ``sim run``'s note ``compiling kernels (first run only, about a minute)...`` on stderr when the
    simulator's compiled kernels are not in numba's cache yet (the first episode then waits for them under
    a progress bar at 0%); returns whether it printed. Nothing for a Dask ``scheduler`` (the workers
    compile). Needs ``sim`` to export ``COMPILE_NOTICE`` and ``compiled_kernels_cached`` (``sim.runs.run``'s);
    without them it prints nothing."""
    import sim

    names = ("COMPILE_NOTICE", "compiled_kernels_cached")
    if scheduler is not None or not set(names) <= set(getattr(sim, "__all__", ())):
        return False
    notice, cached = (getattr(sim, name) for name in names)  # public names (sim.__all__)
    if cached():
        return False
    print(str(notice), file=sys.stderr, flush=True)
    return True


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
