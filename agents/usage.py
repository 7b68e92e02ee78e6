"""Bad command-line input: one way for the ``agents`` commands to refuse it.

``usage_error(prog, message)`` prints ``prog: error: message`` on stderr and exits with status 2, as
argparse does for the arguments it checks itself; the message names the argument and what it accepts.
"""

from __future__ import annotations

import argparse
import json
import sys
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
