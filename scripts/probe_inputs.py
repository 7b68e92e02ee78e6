"""Probe of bad and edge inputs, tried as a new user would (issue 45's acceptance).

Every case runs one command (``python -m sim ...``, ``python -m agents....``, ``python scripts/...``) or a
short Python snippet (the ``dipenv`` and ``sim`` APIs) in a subprocess, in a scratch folder of its own, and
classifies what happened:

* ``clean``: what was expected. ``refuse``: exit 2 with a one-line message (the line holding ``error:``,
  or for API cases the exception's message) that names the offending parameter (the case's ``needle``),
  no traceback; an API case raises an exception of a documented type (``ValueError`` unless the case says
  otherwise). ``ok``: exit 0 and the case's checks of the output pass (finite, plausible numbers; no stale
  files). ``either``: a clean refusal or a clean success.
* ``data loss``: a file that existed before the command (a folder another command made, a file given as
  ``--out``, the case's ``preserve`` list) was changed or deleted where it should not have been.
* ``silently wrong``: accepted what must be refused, wrote files into a folder it then refused, or left a
  NaN/inf/absurd number or a stale file in its output.
* ``escape``: a traceback, an exit status other than the expected one, a refusal whose message does not
  name the parameter, a valid input refused, or a hang past the case's timeout (default 120 s).

    python scripts/probe_inputs.py --out results/input_probe [--workers 1] [--only GROUP ...]
        [--cases ID ...] [--scratch DIR] [--timeout S] [--keep] [--list]

``OUT/probe.json`` holds one record per case (id, group, command, expectation, exit code, stderr tail,
class, detail, seconds) and is rewritten after every case: a rerun skips the cases already in it with the
same command, setup and expectation (``case_digest``), so the probe can run in chunks (``--only``,
``--cases``, or a killed run
continued). ``OUT/probe.md`` counts the classes per group and lists every case that is not clean with its
stderr tail. Folders that several cases start from (a finished ``sim run``, a flow curve, an open-loop
baseline, a controllers folder, a training run, an evaluation, a demo) are made once by real tiny
commands in ``SCRATCH/fixtures`` (default ``OUT/scratch``) and copied into each case's folder, so that no
case sees another's leftovers. Paths under the scratch folder are written as ``@WORK@`` in the records.

Tiny inputs only (N = 12 spheres, 0.02 strain, the ``Tiny`` environment ids, 64 training steps): a full run
is 20-40 minutes on two cores, most of it interpreter start-up.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
CLASSES = ("clean", "data loss", "silently wrong", "escape")
GROUPS = (
    "sim run",
    "sim sweep",
    "sim flow-curve",
    "sim API",
    "agents.train",
    "agents.open_loop",
    "agents.controllers",
    "agents.evaluate",
    "agents.demo",
    "dipenv API",
    "scripts",
)
DEFAULT_TIMEOUT = 120.0
STDERR_TAIL = 2000

# Exit codes of the snippet wrapper (API cases).
SNIPPET_REFUSED, SNIPPET_ABSURD, SNIPPET_ESCAPE, SNIPPET_LOST = 2, 3, 4, 5


@dataclass(frozen=True)
class Case:
    """One probe case.

    ``argv`` (after ``python``) or ``code`` (a snippet) may hold ``@WORK@`` (the case's scratch folder),
    ``@OUT@`` (``@WORK@/out``, not created) and ``@REPO@``. ``fixtures`` are copied to ``@WORK@/<name>``
    and ``files`` (path under ``@WORK@`` -> text, bytes, or one of the operations in :func:`prepare`) are
    applied after them. The files under ``preserve`` must be left as they were; without ``preserve``, every
    file set up this way for a ``refuse`` case. ``absent`` paths must not exist afterwards; ``checks`` are
    names in :data:`CHECKS` with an argument (``"name:arg"``).
    """

    id: str
    group: str
    expect: str  # refuse | ok | either
    argv: tuple[str, ...] | None = None
    code: str | None = None
    needle: str | tuple[str, ...] = ()
    fixtures: tuple[str, ...] = ()
    files: tuple[tuple[str, Any], ...] = ()
    preserve: tuple[str, ...] = ()
    absent: tuple[str, ...] = ()
    checks: tuple[str, ...] = ()
    exceptions: tuple[str, ...] = ("ValueError",)
    timeout: float = DEFAULT_TIMEOUT
    what: str = ""

    @property
    def command(self) -> str:
        if self.argv is not None:
            return "python " + " ".join(_quote(a) for a in self.argv)
        return "python -c " + (self.code or "").strip()

    @property
    def digest(self) -> str:
        """Everything that defines the case, the commands of its fixtures included (a recorded case is run
        again when it changes)."""
        data = {k: v for k, v in self.__dict__.items() if k not in ("timeout", "what")}
        data["fixture_recipes"] = {name: FIXTURES[name] for name in self.fixtures}
        text = json.dumps(
            data, sort_keys=True, default=lambda o: o.decode("latin-1") if isinstance(o, bytes) else repr(o)
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def needles(self) -> tuple[str, ...]:
        return (self.needle,) if isinstance(self.needle, str) else tuple(self.needle)


def _quote(argument: str) -> str:
    if argument == "" or re.search(r"[\s'\"{}\[\]$;|&*?<>]", argument):
        return "'" + argument.replace("'", "'\"'\"'") + "'"
    return argument


# -- fixtures ------------------------------------------------------------------------------------------------

TINY = "dipenv/ThickeningControlTiny-v0"
FM_TINY = "dipenv/FieldMagnitudeTiny-v0"
FV_TINY = "dipenv/FieldVectorTiny-v0"
SIM_RUN = ("-m", "sim", "run", "--n-particles", "12", "--strain", "0.02", "--quiet")
FIELD_RUN = (*SIM_RUN, "--near-field", "none", "--mason", "1")
SHORT_PPO = ("n_steps=32", "batch_size=32", "n_epochs=2", "eval_freq=64", "checkpoint_freq=32")
TRAIN = (
    "-m", "agents.train", "--env", FM_TINY, "--n-envs", "1", "--no-progress", "--algo", "ppo", "--seed", "0",
    "--timesteps", "64",
)  # fmt: skip
FLOW = (
    "-m", "sim", "flow-curve", "--n-particles", "12", "--rates", "0.1,1", "--strain-per-rate", "0.02",
    "--quiet",
    "--near-field", "none",
)  # fmt: skip
SWEEP = ("-m", "sim", "sweep", "--n-particles", "12", "--strain", "0.02", "--quiet", "--workers", "1")
OPEN_LOOP = ("-m", "agents.open_loop", "--env", TINY, "--mason", "off", "--episodes", "1")
CONTROLLERS = (
    "-m", "agents.controllers", "--env", TINY, "--controller", "feedforward", "--grid", "mason_star=1",
    "--tune-episodes", "1", "--episodes", "1",
)  # fmt: skip

FIXTURES: dict[str, list[tuple[str, ...]]] = {
    # name -> commands (argv after python) that make @F@ (the fixture's folder)
    "simrun": [(*SIM_RUN, "--seed", "1", "--out", "@F@")],
    "flow1": [(*FLOW, "--mason", "1", "--out", "@F@")],
    "flowinf": [(*FLOW, "--mason", "inf", "--out", "@F@")],
    "sweep": [(*SWEEP, "--out", "@F@")],
    "openloop": [(*OPEN_LOOP, "--out", "@F@")],
    "controllers": [(*CONTROLLERS, "--out", "@F@")],
    "baseline": [
        ("-m", "agents.open_loop", "--env", FM_TINY, "--mason", "off,1", "--episodes", "1", "--out", "@F@")
    ],
    "ppo": [(*TRAIN, "--hyperparams", *SHORT_PPO, "--out", "@F@")],
    "evaluation": [("-m", "agents.evaluate", "@FX@/ppo", "--baseline", "@FX@/baseline", "--out", "@F@")],
    "demo": [("-m", "agents.demo", "--out", "@F@", "--timesteps", "32", "--seeds", "0")],
    "loose": [],  # a folder of the user's own: no manifest
}
FIXTURE_ORDER = ["simrun", "flow1", "flowinf", "sweep", "openloop", "controllers", "baseline", "ppo",
                 "evaluation", "demo", "loose"]  # fmt: skip


def _set(argv: tuple[str, ...], flag: str, value: str) -> tuple[str, ...]:
    """``argv`` with ``flag``'s value replaced."""
    index = argv.index(flag)
    return (*argv[: index + 1], value, *argv[index + 2 :])


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["MPLBACKEND"] = "Agg"
    env["PYTHONUNBUFFERED"] = "1"
    env.pop("PYTHONWARNINGS", None)
    return env


def _substitute(text: str, work: Path, fixtures: Path | None = None) -> str:
    text = text.replace("@OUT@", str(work / "out")).replace("@WORK@", str(work)).replace("@REPO@", str(REPO))
    if fixtures is not None:
        text = text.replace("@FX@", str(fixtures))
    return text


def build_fixture(name: str, root: Path, log: Callable[[str], None]) -> Path:
    """Make the fixture ``name`` under ``root`` once (a ``.done`` marker holds the commands that made it; a
    fixture of other commands is made again)."""
    root.mkdir(parents=True, exist_ok=True)
    folder = root / name
    marker = root / f"{name}.done"
    recipe = json.dumps(FIXTURES[name])
    if marker.exists() and marker.read_text() == recipe:
        return folder
    marker.unlink(missing_ok=True)
    if folder.exists():
        shutil.rmtree(folder)
    if name == "loose":
        folder.mkdir(parents=True)
        (folder / "notes.txt").write_text("my own notes, not a run\n")
        (folder / "data.csv").write_text("x,y\n1,2\n")
    for argv in FIXTURES[name]:
        arguments = [a.replace("@F@", str(folder)).replace("@FX@", str(root)) for a in argv]
        log(f"fixture {name}: python {' '.join(arguments)}")
        started = time.monotonic()
        proc = subprocess.run(
            [PYTHON, *arguments], cwd=root, env=_environment(), capture_output=True, text=True, timeout=1800
        )
        if proc.returncode != 0:
            raise RuntimeError(f"fixture {name} failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
        log(f"fixture {name}: done in {time.monotonic() - started:.0f} s")
    marker.write_text(recipe)
    return folder


# -- setup operations ----------------------------------------------------------------------------------------


def prepare(work: Path, relative: str, content: Any) -> None:
    """Apply one ``files`` entry: text or bytes are written; ``("truncate", n)`` keeps the first n bytes
    (n < 1: that fraction); ``("dir",)`` replaces the path by an empty folder; ``("remove",)`` deletes it;
    ``("json", obj)`` writes ``obj`` as JSON (``allow_nan``); ``("copy", other)`` copies the folder ``other``
    (under the case's folder) there."""
    path = work / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, str):
        path.write_text(content)
    elif content[0] == "truncate":
        data = path.read_bytes()
        keep = content[1] if content[1] >= 1 else int(len(data) * content[1])
        path.write_bytes(data[: int(keep)])
    elif content[0] == "dir":
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
        path.mkdir()
    elif content[0] == "remove":
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
    elif content[0] == "json":
        path.write_text(json.dumps(content[1]))
    elif content[0] == "copy":
        shutil.copytree(work / content[1], path, symlinks=True)
    else:
        raise ValueError(f"unknown setup operation {content!r}")


def snapshot(root: Path, paths: Iterable[str]) -> dict[str, bytes | None]:
    """Every file under the given paths (relative to ``root``), with its bytes (None: a folder)."""
    files: dict[str, bytes | None] = {}
    for relative in paths:
        path = root / relative
        if path.is_file():
            files[relative] = path.read_bytes()
        elif path.is_dir():
            files[relative] = None
            for item in sorted(path.rglob("*")):
                key = str(item.relative_to(root))
                files[key] = item.read_bytes() if item.is_file() else None
    return files


def compare(before: dict[str, bytes | None], after: dict[str, bytes | None]) -> tuple[list[str], list[str]]:
    """(changed or deleted, added) paths."""
    lost = [k for k, v in before.items() if k not in after or after[k] != v]
    added = [k for k in after if k not in before and not k.endswith("__pycache__")]
    return lost, added


# -- checks of an accepted command's output ------------------------------------------------------------------


def _finite_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def check_json_line(work: Path, stdout: str, argument: str) -> str | None:
    """The last stdout line is JSON whose listed keys are finite numbers (``relative_viscosity`` also > 0
    and below 1e4)."""
    lines = [line for line in stdout.strip().splitlines() if line.strip()]
    if not lines:
        return "no JSON line on stdout"
    try:
        data = json.loads(lines[-1])
    except json.JSONDecodeError as error:
        return f"the last stdout line is not JSON ({error})"
    for key in argument.split(","):
        value = data.get(key)
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                return f"{key} = {value!r} is not a number"
        if not _finite_number(value):
            return f"{key} = {value!r} in the JSON line"
        if key == "relative_viscosity" and not 0.0 < value < 1e4:
            return f"relative_viscosity = {value!r}: absurd"
    return None


def check_result(work: Path, stdout: str, argument: str) -> str | None:
    """``argument`` = path (under @WORK@) of a result.json whose relative_viscosity is finite, in (0, 1e4)."""
    path = work / argument
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        return f"{argument} cannot be read ({error})"
    value = data.get("relative_viscosity")
    value = float(value) if isinstance(value, str) else value
    if not _finite_number(value) or not 0.0 < value < 1e4:
        return f"{argument}: relative_viscosity = {value!r}"
    return None


def check_csv(work: Path, stdout: str, argument: str) -> str | None:
    """``argument`` = ``path#column``: every row's column is a finite number in (0, 1e4)."""
    relative, column = argument.split("#")
    path = work / relative
    try:
        lines = path.read_text().splitlines()
    except OSError as error:
        return f"{relative} cannot be read ({error})"
    header = lines[0].split(",")
    if column not in header:
        return f"{relative} has no column {column}"
    index = header.index(column)
    for line in lines[1:]:
        value = float(line.split(",")[index])
        if not math.isfinite(value) or not 0.0 < value < 1e4:
            return f"{relative}: {column} = {value!r}"
    return None


def check_json_key(work: Path, stdout: str, argument: str) -> str | None:
    """``argument`` = ``key=JSON``: the last stdout line's ``key`` equals the JSON value."""
    key, _, value = argument.partition("=")
    lines = [line for line in stdout.strip().splitlines() if line.strip()]
    try:
        got = json.loads(lines[-1]).get(key) if lines else None
    except json.JSONDecodeError:
        return "the last stdout line is not JSON"
    return None if got == json.loads(value) else f"{key} = {got!r}, expected {value}"


def check_stdout_has(work: Path, stdout: str, argument: str) -> str | None:
    return None if argument in stdout else f"stdout lacks {argument!r}"


def check_stdout_lacks(work: Path, stdout: str, argument: str) -> str | None:
    """No match of the regular expression ``argument`` on stdout."""
    match = re.search(argument, stdout)
    return None if match is None else f"stdout has {match.group(0)!r}"


def check_stdout_plausible(work: Path, stdout: str, argument: str) -> str | None:
    """No nan/inf token on stdout and no percentage above ``argument`` (default 100) in absolute value."""
    if re.search(r"(?<![A-Za-z_])(nan|inf)(?![A-Za-z_])", stdout, re.IGNORECASE):
        return "a nan or inf on stdout"
    limit = float(argument or 100)
    for match in re.finditer(r"(-?[0-9.]+)\s*%", stdout):
        try:
            if abs(float(match.group(1))) > limit:
                return f"{match.group(0)} on stdout"
        except ValueError:
            continue
    return None


CHECKS: dict[str, Callable[[Path, str, str], str | None]] = {
    "json": check_json_line,
    "jsonkey": check_json_key,
    "result": check_result,
    "csv": check_csv,
    "stdout": check_stdout_has,
    "plausible": check_stdout_plausible,
    "lacks": check_stdout_lacks,
}


# -- the snippet wrapper -------------------------------------------------------------------------------------

WRAPPER = """\
import math, sys
import numpy as np

def absurd(message):
    print("ABSURD: " + str(message), file=sys.stderr)
    sys.exit({absurd})

def escape(message):
    print("ESCAPE: " + str(message), file=sys.stderr)
    sys.exit({escape})

def lost(message):
    print("LOST: " + str(message), file=sys.stderr)
    sys.exit({lost})

def finite(*values):
    for value in values:
        array = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(array)):
            absurd(f"non-finite value {{value!r}}")
    return values[0] if len(values) == 1 else values

REFUSALS = tuple(eval(name) for name in {exceptions!r})
try:
    exec(compile({code!r}, "<case>", "exec"), {{"__name__": "__case__", "absurd": absurd, "escape": escape,
         "lost": lost, "finite": finite, "np": np, "math": math, "sys": sys}})
except REFUSALS as error:
    message = " ".join(str(error).split())
    print(f"REFUSED {{type(error).__name__}}: {{message}}", file=sys.stderr)
    sys.exit({refused})
"""

_EXCEPTION_IMPORTS = {
    "gym.error.Error": "import gymnasium as gym",
}


def snippet(case: Case, work: Path) -> Path:
    imports = "\n".join(sorted({_EXCEPTION_IMPORTS[e] for e in case.exceptions if e in _EXCEPTION_IMPORTS}))
    text = (imports + "\n" if imports else "") + WRAPPER.format(
        absurd=SNIPPET_ABSURD,
        escape=SNIPPET_ESCAPE,
        lost=SNIPPET_LOST,
        refused=SNIPPET_REFUSED,
        exceptions=list(case.exceptions),
        code=_substitute(case.code or "", work),
    )
    path = work / "case.py"
    path.write_text(text)
    return path


# -- running and classifying ---------------------------------------------------------------------------------


@dataclass
class Outcome:
    exit_code: int | None
    stdout: str
    stderr: str
    seconds: float
    timed_out: bool
    lost: list[str] = field(default_factory=list)
    added: list[str] = field(default_factory=list)
    left_out: bool = False
    check_failures: list[str] = field(default_factory=list)
    stale: list[str] = field(default_factory=list)


def _error_lines(stderr: str, api: bool) -> list[str]:
    marker = "REFUSED " if api else "error:"
    return [line for line in stderr.splitlines() if marker in line]


def classify(case: Case, outcome: Outcome) -> tuple[str, str]:
    """(class, detail) of one outcome."""
    api = case.code is not None
    if outcome.timed_out:
        return "escape", f"no answer within {case.timeout:g} s (a hang)"
    if outcome.lost:
        return "data loss", "changed or deleted: " + ", ".join(outcome.lost[:8])
    code = outcome.exit_code
    traceback = "Traceback (most recent call last)" in outcome.stderr
    refused_expected = case.expect in ("refuse", "either")
    ok_expected = case.expect in ("ok", "either")
    if api and code == SNIPPET_ABSURD:
        return "silently wrong", _last_marker(outcome.stderr, "ABSURD: ")
    if api and code == SNIPPET_LOST:
        return "data loss", _last_marker(outcome.stderr, "LOST: ")
    if api and code == SNIPPET_ESCAPE:
        return "escape", _last_marker(outcome.stderr, "ESCAPE: ")
    if code == 0:
        if not ok_expected:
            return "silently wrong", "accepted (exit 0) what must be refused"
        if traceback:
            return "escape", "exit 0 but a traceback on stderr"
        if outcome.stale:
            return "silently wrong", "stale files left beside the new run: " + ", ".join(outcome.stale)
        if outcome.check_failures:
            return "silently wrong", "; ".join(outcome.check_failures)
        return "clean", "accepted"
    if code == 2 and refused_expected and not traceback:
        lines = _error_lines(outcome.stderr, api)
        if not lines:
            return "escape", "exit 2 without an error line"
        if case.needles and not any(all(n in line for n in case.needles) for line in lines):
            return "escape", f"wrong message: the error line does not name {' and '.join(case.needles)}"
        if outcome.added:
            return "silently wrong", "refused, but wrote into an existing folder: " + ", ".join(
                outcome.added[:6]
            )
        return "clean", "refused" + (" (left its new --out folder behind)" if outcome.left_out else "")
    if traceback:
        return "escape", f"traceback (exit {code})"
    if code == 2 and not refused_expected:
        lines = _error_lines(outcome.stderr, api)
        return "escape", "a valid input refused: " + (lines[-1].strip() if lines else "exit 2")
    return "escape", f"exit {code}"


def _last_marker(stderr: str, marker: str) -> str:
    lines = [line for line in stderr.splitlines() if line.startswith(marker)]
    return lines[-1][len(marker) :] if lines else marker.strip()


def _kill(proc: subprocess.Popen[str]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the case's own process group (start_new_session)
    except ProcessLookupError:
        pass


def run_case(case: Case, scratch: Path, keep: bool = False) -> dict[str, Any]:
    fixtures_root = scratch / "fixtures"
    work = scratch / "work" / re.sub(r"[^A-Za-z0-9_.-]", "_", case.id)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for name in case.fixtures:
        shutil.copytree(fixtures_root / name, work / name, symlinks=True)
    for relative, content in case.files:
        prepare(work, relative, content)
    setup = sorted({*case.fixtures, *(r for r, _ in case.files)})
    guarded = list(case.preserve) if case.preserve else setup if case.expect == "refuse" else []
    before = snapshot(work, guarded)
    out_existed = (work / "out").exists()
    if case.code is not None:
        arguments = [PYTHON, str(snippet(case, work))]
    else:
        assert case.argv is not None
        arguments = [PYTHON, *(_substitute(a, work, fixtures_root) for a in case.argv)]
    started = time.monotonic()
    proc = subprocess.Popen(
        arguments,
        cwd=work,
        env=_environment(),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
        start_new_session=True,
    )
    timed_out = False
    try:
        stdout, stderr = proc.communicate(timeout=case.timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        _kill(proc)
        stdout, stderr = proc.communicate()
    seconds = time.monotonic() - started
    after = snapshot(work, guarded)
    lost, added = compare(before, after)
    outcome = Outcome(
        proc.returncode if not timed_out else None, stdout, stderr, seconds, timed_out, lost, added
    )
    outcome.left_out = not out_existed and (work / "out").exists() and proc.returncode == 2
    outcome.stale = [a for a in case.absent if (work / a).exists()]
    if proc.returncode == 0 and not timed_out:
        for check in case.checks:
            name, _, argument = check.partition(":")
            problem = CHECKS[name](work, stdout, argument)
            if problem:
                outcome.check_failures.append(problem)
    klass, detail = classify(case, outcome)
    record = {
        "id": case.id,
        "group": case.group,
        "command": case.command,
        "case_digest": case.digest,
        "expect": case.expect,
        "needle": list(case.needles),
        "what": case.what,
        "exit_code": outcome.exit_code,
        "stderr_tail": _tidy(stderr, scratch)[-STDERR_TAIL:],
        "stdout_tail": _tidy(stdout, scratch)[-600:],
        "class": klass,
        "detail": _tidy(detail, scratch),
        "seconds": round(seconds, 1),
    }
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    return record


def _tidy(text: str, scratch: Path) -> str:
    text = text.replace(str(scratch / "work"), "@SCRATCH@/work").replace(str(scratch / "fixtures"), "@FX@")
    text = re.sub(r"@SCRATCH@/work/[A-Za-z0-9_.\-]+", "@WORK@", text)
    return text.replace(str(REPO), "@REPO@")


# -- the cases -----------------------------------------------------------------------------------------------


def _j(obj: Any) -> str:
    return json.dumps(obj)


def sim_run_cases() -> list[Case]:
    g = "sim run"
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(
        cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "", base=SIM_RUN
    ) -> None:
        cases.append(Case(cid, g, "refuse", argv=(*base, *flags, *out), needle=needle, what=what))

    for value in ("nan", "-0.1", "1e300"):
        bad(f"run-phi-{value or 'empty'}", ("--phi", value), "--phi")
    for value in ("0", "nan", "1e9"):
        bad(f"run-n-{value}", ("--n-particles", value), "--n-particles")
    for value in ("0", "nan", "1e-300"):
        bad(f"run-mason-{value}", ("--mason", value), "--mason", base=(*SIM_RUN, "--near-field", "none"))
    for value in ("nan", "0", "1e300"):
        bad(f"run-strain-{value}", ("--strain", value), "--strain")
    for value in ("-1", "1e-4", "1e-300", "1e300"):
        bad(f"run-rate-{value}", ("--shear-rate", value), "--shear-rate")
    bad("run-rate-0-nofield", ("--shear-rate", "0"), "--mason", "quiescent needs a field")
    for value in ("nan", "0", "1e-12"):
        bad(f"run-dt-{value}", ("--dt", value), "--dt")
    for value in ("-1",):
        bad(f"run-seed-{value}", ("--seed", value), "--seed")
    for value in ("0,0,0", "1,2", "nan,0,0"):
        bad(
            f"run-direction-{value or 'empty'}",
            ("--field-direction", value),
            "--field-direction",
            base=FIELD_RUN,
        )
    for value in ("5", "0.02"):
        bad(f"run-transient-{value}", ("--transient", value), "--transient")
    for value in ("0",):
        bad(f"run-maxdisp-{value}", ("--max-displacement", value), "--max-displacement")
    for value in ("nan",):
        bad(f"run-cutoff-{value}", ("--near-field-cutoff", value), "--near-field-cutoff")
    for value in ("0",):
        bad(f"run-ewald-{value}", ("--ewald-accuracy", value), "--ewald-accuracy")
    bad("run-mechanism-bogus", ("--mechanism", "bogus"), "--mechanism")
    bad("run-nearfield-bogus", ("--near-field", "approx"), "--near-field")
    bad("run-abbrev-mas", ("--mas", "1"), "--mas", "allow_abbrev off")
    bad("run-abbrev-over", ("--over",), "--over", "allow_abbrev off")
    bad("run-unknown-flag", ("--bogus", "1"), "--bogus")
    bad("run-resume-and-overwrite", ("--resume", "--overwrite"), "--overwrite")
    bad("run-resume-nothing", ("--resume",), "--resume")
    cases += [
        Case("run-out-missing", g, "refuse", argv=SIM_RUN, needle="--out"),
        Case("run-out-empty", g, "refuse", argv=(*SIM_RUN, "--out", ""), needle="--out"),
        Case("run-out-sys", g, "refuse", argv=(*SIM_RUN, "--out", "/sys/dipsim_probe/run"), needle="--out"),
        Case(
            "run-out-file",
            g,
            "refuse",
            argv=(*SIM_RUN, "--out", "@WORK@/notes.txt"),
            files=(("notes.txt", "keep me\n"),),
            needle="--out",
        ),
        Case(
            "run-out-under-file",
            g,
            "refuse",
            argv=(*SIM_RUN, "--out", "@WORK@/notes.txt/run"),
            files=(("notes.txt", "keep me\n"),),
            needle="--out",
            what="a parent of --out is a file",
        ),
        Case(
            "run-out-flowcurve",
            g,
            "refuse",
            argv=(*SIM_RUN, "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            needle="--out",
            what="another command's folder",
        ),
        Case(
            "run-out-openloop",
            g,
            "refuse",
            argv=(*SIM_RUN, "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            needle="--out",
        ),
        Case(
            "run-out-loose",
            g,
            "refuse",
            argv=(*SIM_RUN, "--out", "@WORK@/loose"),
            fixtures=("loose",),
            needle="--out",
            what="a non-empty folder without a manifest",
        ),
        Case(
            "run-overwrite-loose",
            g,
            "refuse",
            argv=(*SIM_RUN, "--overwrite", "--out", "@WORK@/loose"),
            fixtures=("loose",),
            needle="--out",
            what="--overwrite never deletes a folder without a manifest",
        ),
        Case(
            "run-out-other-seed",
            g,
            "refuse",
            argv=(*SIM_RUN, "--seed", "2", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
            what="the same command with other parameters",
        ),
        Case(
            "run-rerun-same",
            g,
            "ok",
            argv=(*SIM_RUN, "--seed", "1", "--json", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            checks=("json:relative_viscosity,n1,n2",),
            what="a rerun continues",
        ),
        Case(
            "run-resume-longer",
            g,
            "ok",
            argv=(
                *SIM_RUN[:-3],
                "--strain",
                "0.03",
                "--quiet",
                "--seed",
                "1",
                "--resume",
                "--json",
                "--out",
                "@WORK@/simrun",
            ),
            fixtures=("simrun",),
            checks=("json:relative_viscosity",),
        ),
        Case(
            "run-resume-shorter",
            g,
            "refuse",
            argv=(
                *SIM_RUN[:-3],
                "--strain",
                "0.01",
                "--quiet",
                "--seed",
                "1",
                "--resume",
                "--out",
                "@WORK@/simrun",
            ),
            fixtures=("simrun",),
            needle="--strain",
        ),
        Case(
            "run-overwrite-flowcurve",
            g,
            "ok",
            argv=(*SIM_RUN, "--overwrite", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            absent=("flowinf/flow_curve.csv", "flowinf/flow_curve.png"),
            checks=("result:flowinf/result.json",),
            what="--overwrite removes the whole previous run",
        ),
        Case(
            "run-checkpoint-truncated",
            g,
            "refuse",
            argv=(*SIM_RUN, "--seed", "1", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            files=(("simrun/checkpoint.npz", ("truncate", 0.5)),),
            needle="checkpoint.npz",
        ),
        Case(
            "run-checkpoint-garbage",
            g,
            "refuse",
            argv=(*SIM_RUN, "--seed", "1", "--resume", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            files=(("simrun/checkpoint.npz", "garbage\n"),),
            needle="checkpoint.npz",
        ),
        Case(
            "run-checkpoint-dir",
            g,
            "refuse",
            argv=(*SIM_RUN, "--seed", "1", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            files=(("simrun/checkpoint.npz", ("dir",)),),
            needle="checkpoint.npz",
        ),
        Case(
            "run-manifest-garbage",
            g,
            "refuse",
            argv=(*SIM_RUN, "--seed", "1", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            files=(("simrun/manifest.json", "{not json"),),
            needle="manifest.json",
        ),
        Case(
            "run-mason-huge",
            g,
            "ok",
            argv=(*FIELD_RUN[:-2], "--mason", "1e300", "--json", "--out", "@OUT@"),
            checks=("json:relative_viscosity,n1,n2",),
            what="a field too weak to matter",
        ),
        Case(
            "run-direction-huge",
            g,
            "either",
            argv=(*FIELD_RUN, "--field-direction", "1e300,0,0", "--json", "--out", "@OUT@"),
            needle="--field-direction",
            checks=("json:relative_viscosity", "jsonkey:field_direction=[1.0, 0.0, 0.0]"),
            what="normalising overflows",
        ),
        Case(
            "run-direction-subnormal",
            g,
            "either",
            argv=(*FIELD_RUN, "--field-direction", "1e-320,0,0", "--json", "--out", "@OUT@"),
            needle="--field-direction",
            checks=("json:relative_viscosity", "jsonkey:field_direction=[1.0, 0.0, 0.0]"),
            what="normalising underflows",
        ),
        Case(
            "run-quiescent",
            g,
            "ok",
            argv=(*FIELD_RUN, "--shear-rate", "0", "--json", "--out", "@OUT@"),
            checks=("json:u_rms_dip",),
            what="quiescent: eta_r is not defined, the rest must be finite",
        ),
        Case(
            "run-rate-max",
            g,
            "ok",
            argv=(*SIM_RUN, "--shear-rate", "1000", "--dt", "1e-6", "--json", "--out", "@OUT@"),
            checks=("json:relative_viscosity",),
            what="the top of the rate range",
        ),
        Case(
            "run-broken-pipe",
            g,
            "ok",
            code=(
                "import subprocess\n"
                "p = subprocess.Popen([sys.executable, '-m', 'sim', 'run', '--n-particles', '12', '--strain',"
                " '0.02', '--quiet', '--out', '@OUT@'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,"
                " text=True)\n"
                "p.stdout.close()\n"
                "err = p.stderr.read(); p.wait()\n"
                "if 'Traceback' in err: escape('sim run | true: ' + err.strip().splitlines()[-1])\n"
            ),
            what="stdout piped to a reader that has gone (| head, | true): the summary cannot be printed",
        ),
        Case(
            "run-sigint",
            g,
            "ok",
            code=(
                "import subprocess, time, pathlib, signal\n"
                "out = pathlib.Path('@OUT@')\n"
                "p = subprocess.Popen([sys.executable, '-m', 'sim', 'run', '--n-particles', '12',"
                " '--strain', '50',"
                " '--quiet', '--out', str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)\n"
                "deadline = time.time() + 60\n"
                "while not (out / 'params.json').exists() and p.poll() is None and time.time() < deadline:\n"
                "    time.sleep(0.1)\n"
                "time.sleep(2); p.send_signal(signal.SIGINT)\n"
                "_, err = p.communicate(timeout=60)\n"
                "if p.returncode != 130 or 'Traceback' in err:\n"
                "    escape(f'Ctrl-C: exit {p.returncode}: ' + (err.strip().splitlines() or [''])[-1])\n"
            ),
            what="Ctrl-C part way",
        ),
    ]
    return cases


def sweep_cases() -> list[Case]:
    g = "sim sweep"
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "") -> None:
        cases.append(Case(cid, g, "refuse", argv=(*SWEEP, *flags, *out), needle=needle, what=what))

    for value in ("", "0.3,0.3", "0.3,nan"):
        bad(f"sweep-phi-{value or 'empty'}", ("--phi", value), "--phi")
    for value in ("12,1",):
        bad(f"sweep-n-{value}", ("--n-particles", value), "--n-particles")
    for value in ("1,0", "inf,inf"):
        bad(f"sweep-mason-{value or 'empty'}", ("--mason", value), "--mason")
    bad("sweep-mechanism-bogus", ("--mechanism", "dip,bogus"), "--mechanism")
    for value in ("0", "3-1", "1,1", "1-100000000"):
        bad(f"sweep-seeds-{value or 'empty'}", ("--seeds", value), "--seeds")
    for value in ("0",):
        bad(f"sweep-workers-{value}", ("--workers", value), "--workers")
    bad("sweep-preset-bogus", ("--preset", "bogus"), "--preset")
    bad("sweep-abbrev", ("--see", "2"), "--see", "allow_abbrev off")
    cases += [
        Case(
            "sweep-spec-missing",
            g,
            "refuse",
            argv=(*SWEEP, "--spec", "@WORK@/nope.yml", *out),
            needle="--spec",
        ),
        Case(
            "sweep-spec-garbage",
            g,
            "refuse",
            argv=(*SWEEP, "--spec", "@WORK@/spec.yml", *out),
            files=(("spec.yml", "phi: [0.3\n"),),
            needle="--spec",
        ),
        Case(
            "sweep-spec-unknown-key",
            g,
            "refuse",
            argv=(*SWEEP, "--spec", "@WORK@/spec.yml", *out),
            files=(("spec.yml", "phi: 0.3\nbogus: 1\n"),),
            needle="bogus",
        ),
        Case(
            "sweep-spec-list",
            g,
            "refuse",
            argv=(*SWEEP, "--spec", "@WORK@/spec.yml", *out),
            files=(("spec.yml", "- 1\n- 2\n"),),
            needle="--spec",
        ),
        Case(
            "sweep-out-simrun",
            g,
            "refuse",
            argv=(*SWEEP, "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
        ),
        Case(
            "sweep-out-file",
            g,
            "refuse",
            argv=(*SWEEP, "--out", "@WORK@/notes.txt"),
            files=(("notes.txt", "keep\n"),),
            needle="--out",
        ),
        Case(
            "sweep-other-shared",
            g,
            "refuse",
            argv=(*SWEEP, "--dt", "0.001", "--out", "@WORK@/sweep"),
            fixtures=("sweep",),
            needle="--out",
            what="a shared option changed in a sweep folder",
        ),
        Case(
            "sweep-descending",
            g,
            "ok",
            argv=(*_set(SWEEP, "--n-particles", "16,12"), "--json", *out),
            what="a descending list is a set of points",
        ),
        Case(
            "sweep-rerun-adds-seed",
            g,
            "ok",
            argv=(*SWEEP, "--seeds", "1,2", "--out", "@WORK@/sweep"),
            fixtures=("sweep",),
            preserve=("sweep/phi0.4_n12_mninf_dip_seed1/result.json",),
            what="a rerun adds a point and keeps the finished one",
        ),
        Case(
            "figures-missing",
            g,
            "refuse",
            argv=("-m", "sim", "figures", "@WORK@/nope"),
            needle="nope",
        ),
        Case(
            "figures-simrun",
            g,
            "refuse",
            argv=("-m", "sim", "figures", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="simrun",
            what="a run folder is not a sweep",
        ),
        Case(
            "figures-empty",
            g,
            "refuse",
            argv=("-m", "sim", "figures", "@WORK@/empty"),
            files=(("empty/.keep", ""),),
            needle="empty",
        ),
    ]
    return cases


def flow_curve_cases() -> list[Case]:
    g = "sim flow-curve"
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(
        cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "", base=FLOW
    ) -> None:
        cases.append(Case(cid, g, "refuse", argv=(*base, *flags, *out), needle=needle, what=what))

    for value in ("1e20", "1e300", "nan", "", "1,0.1", "0.1,1e-4"):
        bad(f"flow-rates-{value or 'empty'}", ("--rates", value), "--rates")
    bad("flow-strain-not-a-flag", ("--strain", "5"), "--strain", "was read as --strain-per-rate")
    for value in ("1e-9", "0", "nan"):
        bad(f"flow-strain-per-rate-{value}", ("--strain-per-rate", value), "--strain-per-rate")
    for value in ("0", "1,1", ""):
        bad(f"flow-mason-{value or 'empty'}", ("--mason", value), "--mason")
    bad("flow-workers-0", ("--workers", "0"), "--workers")
    bad("flow-direction-zero", ("--field-direction", "0,0,0"), "--field-direction")
    cases += [
        Case(
            "flow-mason-1-inf-into-single",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "1,inf", "--out", "@WORK@/flow1"),
            fixtures=("flow1",),
            needle="--out",
            what="several curves into a single curve's folder",
        ),
        Case(
            "flow-mason-1-2-into-single",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "1,2", "--out", "@WORK@/flow1"),
            fixtures=("flow1",),
            needle="--out",
        ),
        Case(
            "flow-other-rates-into-curve",
            g,
            "refuse",
            argv=(*_set(FLOW, "--rates", "0.1,0.3"), "--mason", "1", "--out", "@WORK@/flow1"),
            fixtures=("flow1",),
            needle="--out",
        ),
        Case(
            "flow-into-simrun",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
        ),
        Case(
            "flow-into-loose",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/loose"),
            fixtures=("loose",),
            needle="--out",
        ),
        Case(
            "flow-resume-no-field",
            g,
            "ok",
            argv=(*FLOW, "--mason", "inf", "--resume", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            checks=("csv:flowinf/flow_curve.csv#relative_viscosity",),
            what="a no-field curve resumes (params.json stores inf)",
        ),
        Case(
            "flow-rerun-no-field",
            g,
            "ok",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            preserve=("flowinf/flow_curve.csv",),
        ),
        Case(
            "flow-checkpoint-truncated",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            files=(("flowinf/checkpoint.npz", ("truncate", 0.5)),),
            needle="checkpoint.npz",
            what="a rerun continues the curve: it must read the checkpoint",
        ),
        Case(
            "flow-checkpoint-garbage",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--resume", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            files=(("flowinf/checkpoint.npz", "garbage\n"),),
            needle="checkpoint.npz",
        ),
        Case(
            "flow-checkpoint-dir",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            files=(("flowinf/checkpoint.npz", ("dir",)),),
            needle="checkpoint.npz",
        ),
        Case(
            "flow-csv-dir",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            files=(("flowinf/flow_curve.csv", ("dir",)),),
            needle="flow_curve.csv",
        ),
        Case(
            "flow-csv-garbage",
            g,
            "refuse",
            argv=(*FLOW, "--mason", "inf", "--out", "@WORK@/flowinf"),
            fixtures=("flowinf",),
            files=(("flowinf/flow_curve.csv", "not,a\ncurve\n"),),
            needle="flow_curve.csv",
        ),
        Case(
            "flow-single-rate-down",
            g,
            "either",
            argv=(*_set(FLOW, "--rates", "1"), "--mason", "inf", "--down", *out),
            needle="--rates",
            checks=("csv:out/flow_curve.csv#relative_viscosity",),
        ),
        Case(
            "flow-help",
            g,
            "ok",
            argv=("-m", "sim", "flow-curve", "--help"),
            checks=(r"lacks:--strain(?![-\w])",),
            what="the help mentioned a --strain the command does not have",
        ),
        Case(
            "flow-sigint",
            g,
            "ok",
            code=(
                "import subprocess, time, pathlib, signal\n"
                "out = pathlib.Path('@OUT@')\n"
                "p = subprocess.Popen([sys.executable, '-m', 'sim', 'flow-curve', '--n-particles', '12',"
                " '--rates',"
                " '0.1,1', '--strain-per-rate', '30', '--mason', 'inf', '--quiet', '--out', str(out)],"
                " stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)\n"
                "deadline = time.time() + 60\n"
                "while not (out / 'params.json').exists() and p.poll() is None and time.time() < deadline:\n"
                "    time.sleep(0.1)\n"
                "time.sleep(2); p.send_signal(signal.SIGINT)\n"
                "std, err = p.communicate(timeout=60)\n"
                "if p.returncode != 130 or 'Traceback' in err:\n"
                "    escape(f'Ctrl-C: exit {p.returncode}: ' + (err.strip().splitlines() or [''])[-1])\n"
                "for word in (std + err).split():\n"
                "    if word.startswith(str(out)) and not pathlib.Path(word.rstrip('.,;:')).exists():\n"
                "        absurd(f'Ctrl-C: names {word}, which it did not write')\n"
            ),
            what="Ctrl-C during a hold",
        ),
    ]
    return cases


def sim_api_cases() -> list[Case]:
    g = "sim API"
    head = "import sim\n"

    def api(
        cid: str, expect: str, code: str, needle: str | tuple[str, ...] = (), what: str = "", **kw: Any
    ) -> Case:
        return Case(cid, g, expect, code=head + code, needle=needle, what=what, **kw)

    base = "config = sim.SimulationConfig(n_particles=12, volume_fraction=0.4, strain=0.02, seed=1)\n"
    return [
        api(
            "api-config-phi-nan",
            "refuse",
            "sim.SimulationConfig(n_particles=12, volume_fraction=float('nan'))",
            "volume_fraction",
        ),
        api(
            "api-config-n-bool",
            "refuse",
            "sim.SimulationConfig(n_particles=True, volume_fraction=0.4)",
            "n_particles",
        ),
        api(
            "api-config-mason-neg",
            "refuse",
            "sim.SimulationConfig(n_particles=12, volume_fraction=0.4, mason_number=-1.0)",
            "mason_number",
        ),
        api(
            "api-config-direction-zero",
            "refuse",
            "sim.SimulationConfig(n_particles=12, volume_fraction=0.4, mason_number=1.0,"
            " field_direction=(0, 0, 0))",
            "field_direction",
        ),
        api(
            "api-set-rate-tiny",
            "refuse",
            base + "s = sim.Simulation(config)\ns.set_shear_rate(1e-300)",
            "rate",
            "eta_r = Sigma/rate blew up (-9.7e288)",
        ),
        api(
            "api-set-rate-1e-9", "refuse", base + "s = sim.Simulation(config)\ns.set_shear_rate(1e-9)", "rate"
        ),
        api(
            "api-set-field-nan",
            "refuse",
            base + "s = sim.Simulation(config)\ns.set_field(float('nan'), (0, 1, 0))",
            ("mason",),
        ),
        api(
            "api-set-field-zero-dir",
            "refuse",
            base + "s = sim.Simulation(config)\ns.set_field(1.0, (0, 0, 0))",
            "direction",
        ),
        api(
            "api-piecewise-unsorted",
            "refuse",
            "sim.PiecewiseLinear((0.0, 2.0, 1.0), (1.0, 1.0, 1.0))",
            "times",
        ),
        api("api-piecewise-nan", "refuse", "sim.PiecewiseLinear((0.0, float('nan')), (1.0, 1.0))", "times"),
        api("api-piecewise-lengths", "refuse", "sim.PiecewiseLinear((0.0, 1.0), (1.0,))", "times"),
        api(
            "api-advance-inf",
            "refuse",
            base + "s = sim.Simulation(config)\ns.advance_to(float('inf'))",
            "time",
        ),
        api(
            "api-lattice-shift",
            "ok",
            base + "P = sim.Simulation(config).state.positions.copy()\n"
            "L = config.box_length\n"
            "a = sim.Simulation(config, state=sim.SimulationState.initial(P))\n"
            "b = sim.Simulation(config, state=sim.SimulationState.initial(P + np.array([L, -L, -L])))\n"
            "a.advance_to(0.01); b.advance_to(0.01)\n"
            "d = (b.state.positions - a.state.positions) / L\n"
            "d -= np.round(d)\n"
            "if np.max(np.abs(d)) * L > 1e-9:\n"
            "    absurd(f'a lattice shift changes the run by {np.max(np.abs(d)) * L:.3g} a')\n",
            what="a configuration shifted by a lattice vector runs as the original",
        ),
        api(
            "api-state-nan",
            "refuse",
            base + "P = sim.Simulation(config).state.positions.copy()\nP[3, 1] = np.nan\n"
            "sim.Simulation(config, state=sim.SimulationState.initial(P))",
            "positions",
        ),
    ]


def train_cases() -> list[Case]:
    g = "agents.train"
    out = ("--out", "@OUT@")
    short = ("--hyperparams", *SHORT_PPO)
    cases: list[Case] = []

    def bad(
        cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "", base=TRAIN
    ) -> None:
        cases.append(Case(cid, g, "refuse", argv=(*base, *flags, *out), needle=needle, what=what))

    no_env = tuple(a for a in TRAIN if a not in ("--env", FM_TINY))
    bad("train-env-unknown", ("--env", "dipenv/Bogus-v0"), "--env", base=no_env)
    for item, needle in (
        ("gamma=[0.9", "gamma"),
        ("policy_kwargs={net_arch: [-4]}", "--hyperparams"),
        ("ent_coef=-1", "ent_coef"),
        ("gamma=2", "gamma"),
        ("learning_rate=-1", "learning_rate"),
        ("n_steps=0", "n_steps"),
        ("bogus_key=1", "bogus_key"),
        ("=1", "--hyperparams"),
    ):
        bad(f"train-hp-{item}", ("--hyperparams", item), needle)
    cases.append(
        Case(
            "train-hp-batch_size=1000",
            g,
            "either",
            argv=(*TRAIN, "--hyperparams", "batch_size=1000", *out),
            needle="batch_size",
            what="above the rollout of n_steps * n_envs = 128: SB3 warns and truncates it",
        )
    )
    for value in ("0", "1e9"):
        bad(f"train-timesteps-{value}", ("--timesteps", value), "--timesteps", base=TRAIN[:-2])
    bad("train-n-envs-0", ("--n-envs", "0"), "--n-envs")
    bad("train-seeds-desc", ("--seeds", "3-1"), "--seeds", base=TRAIN[:9] + TRAIN[11:])
    bad("train-seed-and-seeds", ("--seeds", "0-1"), "--seeds")
    bad("train-abbrev-time", ("--time", "16"), "--time", "allow_abbrev off")
    for value, needle in (
        ("{bad json", "--env-kwargs"),
        ("[1, 2]", "--env-kwargs"),
        ('{"bogus": 1}', "bogus"),
        ('{"target_viscosity": NaN}', "target_viscosity"),
        ('{"mason_min": 30, "mason_max": 1}', "mason"),
    ):
        bad(f"train-env-kwargs-{value}", ("--env-kwargs", value), needle)
    cases += [
        Case(
            "train-out-sys",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "/sys/dipsim_probe/run"),
            needle="--out",
        ),
        Case(
            "train-out-file",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "@WORK@/notes.txt"),
            files=(("notes.txt", "keep\n"),),
            needle="--out",
        ),
        Case(
            "train-out-simrun",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
            what="was: replaced its result.json",
        ),
        Case(
            "train-out-openloop",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            needle="--out",
            what="was: overwrote command.txt",
        ),
        Case(
            "train-out-evaluation",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "@WORK@/evaluation"),
            fixtures=("evaluation",),
            needle="--out",
        ),
        Case(
            "train-out-loose",
            g,
            "refuse",
            argv=(*TRAIN, *short, "--out", "@WORK@/loose"),
            fixtures=("loose",),
            needle="--out",
        ),
        Case(
            "train-rerun-shorter",
            g,
            "refuse",
            argv=(*TRAIN[:-1], "32", *short, "--out", "@WORK@/ppo"),
            fixtures=("ppo",),
            needle="--out",
            what="a smaller --timesteps in a longer run's folder",
        ),
        Case(
            "train-rerun-other-hp",
            g,
            "refuse",
            argv=(*TRAIN, *short, "gamma=0.5", "--out", "@WORK@/ppo"),
            fixtures=("ppo",),
            needle="--out",
        ),
        Case(
            "train-eval-log-truncated",
            g,
            "refuse",
            argv=(*TRAIN[:-1], "128", *short, "--out", "@WORK@/ppo"),
            fixtures=("ppo",),
            files=(("ppo/eval/evaluations.npz", ("truncate", 60)), ("ppo/result.json", ("remove",))),
            needle="evaluations.npz",
            what="resuming from a run whose evaluation log is truncated",
        ),
        Case(
            "train-ok",
            g,
            "ok",
            argv=(*TRAIN, *short, *out),
            checks=(),
            what="the base command trains",
        ),
    ]
    return cases


def _schedule_files() -> dict[str, Any]:
    good = {"times": [0.0, 0.1, 0.2], "rates": [1.0, 2.0, 1.0]}
    return {
        "missing": None,
        "garbage": "this is not JSON\n",
        "empty": "[]",
        "object": _j(good),
        "unsorted": _j([{"times": [0.0, 0.2, 0.1], "rates": [1.0, 1.0, 1.0]}]),
        "rate-1e-9": _j([{"times": [0.0, 0.2], "rates": [1e-9, 1e-9]}]),
        "nested": _j([[[0.0, 1.0], [1.0, [2.0]]]]),
        "start-index": _j([{"schedule": good, "start_index": 99}]),
    }


def _schedule_cases(g: str, prefix: str, base: tuple[str, ...]) -> list[Case]:
    cases = []
    for name, content in _schedule_files().items():
        files = () if content is None else (("schedules.json", content),)
        cases.append(
            Case(
                f"{prefix}-schedules-{name}",
                g,
                "refuse",
                argv=(*base, "--schedules", "@WORK@/schedules.json", "--out", "@OUT@"),
                files=files,
                needle="--schedules",
            )
        )
    return cases


def open_loop_cases() -> list[Case]:
    g = "agents.open_loop"
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(
        cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "", base=OPEN_LOOP
    ) -> None:
        cases.append(Case(cid, g, "refuse", argv=(*base, *flags, *out), needle=needle, what=what))

    for value, needle in (
        ('{"eta_cap": -1}', "eta_cap"),
        ('{"eta_cap": 0}', "eta_cap"),
        ('{"eta_cap": NaN}', "eta_cap"),
        ('{"rate_range": [1e-9, 1]}', "rate_range"),
        ('{"rate_range": [2, 1]}', "rate_range"),
        ("{", "--env-kwargs"),
    ):
        bad(f"ol-env-kwargs-{value}", ("--env-kwargs", value), needle, base=OPEN_LOOP)
    no_mason = tuple(a for a in OPEN_LOOP if a not in ("--mason", "off"))
    for value in ("0", "", "1,1", "1e-300"):
        bad(f"ol-mason-{value or 'empty'}", ("--mason", value), "--mason", base=no_mason)
    bad("ol-split-bogus", ("--split", "bogus"), "--split")
    no_episodes = OPEN_LOOP[:-2]
    for value in ("100000",):
        bad(f"ol-episodes-{value}", ("--episodes", value), "--episodes", base=no_episodes)
    bad("ol-repeats-0", ("--repeats", "0"), "--repeats")
    bad("ol-env-unknown", ("--env", "dipenv/Nope-v0"), "--env", base=OPEN_LOOP[:2] + OPEN_LOOP[4:])
    bad("ol-directions-scalar-env", ("--directions", "x"), "--directions")
    bad(
        "ol-directions-bogus",
        ("--directions", "w"),
        "--directions",
        base=("-m", "agents.open_loop", "--env", FV_TINY, "--mason", "1", "--episodes", "1"),
    )
    bad(
        "ol-schedules-field-env",
        ("--schedules", "@WORK@/s.json"),
        "--schedules",
        base=("-m", "agents.open_loop", "--env", FM_TINY, "--mason", "off", "--episodes", "1"),
    )
    cases += _schedule_cases(g, "ol", OPEN_LOOP)
    cases += [
        Case("ol-out-sys", g, "refuse", argv=(*OPEN_LOOP, "--out", "/sys/dipsim_probe/run"), needle="--out"),
        Case(
            "ol-out-file",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--out", "@WORK@/notes.txt"),
            files=(("notes.txt", "keep\n"),),
            needle="--out",
        ),
        Case(
            "ol-out-simrun",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
        ),
        Case(
            "ol-out-controllers",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--out", "@WORK@/controllers"),
            fixtures=("controllers",),
            needle="--out",
        ),
        Case(
            "ol-out-ppo",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--out", "@WORK@/ppo"),
            fixtures=("ppo",),
            needle="--out",
        ),
        Case(
            "ol-other-env-kwargs",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--env-kwargs", '{"max_piece": 0.01}', "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            needle="--out",
            what="the same command with other parameters",
        ),
        Case(
            "ol-rerun-adds-point",
            g,
            "ok",
            argv=(*no_mason, "--mason", "off,1", "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            preserve=("openloop/points/off.json",),
            checks=("stdout:Mn1",),
            what="a rerun adds a point",
        ),
        Case(
            "ol-point-garbage",
            g,
            "refuse",
            argv=(*OPEN_LOOP, "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            files=(("openloop/points/off.json", "{truncated"),),
            needle="off.json",
            preserve=("openloop/points", "openloop/pareto.json", "openloop/best_constant.json"),
            what="a rerun over a damaged point file",
        ),
        Case(
            "ol-schedules-ok",
            g,
            "ok",
            argv=(*no_episodes, "--schedules", "@WORK@/s.json", *out),
            files=(
                (
                    "s.json",
                    _j(
                        [
                            {"times": [0.0, 0.1, 0.2], "rates": [0.5, 3.0, 1.0]},
                            {"times": [0.0, 0.2], "rates": [2.0, 0.7]},
                        ]
                    ),
                ),
            ),
            checks=("plausible:",),
            what="a schedule of one's own",
        ),
    ]
    return cases


def controllers_cases() -> list[Case]:
    g = "agents.controllers"
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(
        cid: str, flags: tuple[str, ...], needle: str | tuple[str, ...], what: str = "", base=CONTROLLERS
    ) -> None:
        cases.append(Case(cid, g, "refuse", argv=(*base, *flags, *out), needle=needle, what=what))

    no_grid = tuple(a for a in CONTROLLERS if a not in ("--grid", "mason_star=1"))
    bad("ctl-eta-cap-neg", ("--env-kwargs", '{"eta_cap": -1}'), "eta_cap")
    bad(
        "ctl-eta-cap-zero",
        ("--env-kwargs", '{"eta_cap": 0}'),
        "eta_cap",
        base=_set(no_grid, "--controller", "pi"),
    )
    bad("ctl-split-train", ("--split", "train"), "--split", "the help listed it (KeyError)")
    bad("ctl-tune-split-train", ("--tune-split", "train"), "--tune-split")
    for items, needle in (
        (("mason_star=1", "mason_star=2"), "mason_star"),
        (("mason_star=1,1",), "mason_star"),
        (("bogus=1",), "bogus"),
        (("mason_star=-1",), "mason_star"),
        (("mason_star=nan",), "mason_star"),
        (("mason_star",), "mason_star"),
    ):
        bad(f"ctl-grid-{' '.join(items)}", ("--grid", *items), needle, base=no_grid)
    bad(
        "ctl-grid-twice-options",
        ("--grid", "mason_star=1", "--grid", "mason_star=2"),
        "mason_star",
        base=no_grid,
    )
    bad("ctl-pi-grid-neg-gain", ("--grid", "kp=-1e300"), "kp", base=_set(no_grid, "--controller", "pi"))
    bad("ctl-controller-bogus", (), "--controller", base=_set(no_grid, "--controller", "bogus"))
    bad("ctl-field-env", (), "--env", base=(no_grid[0], no_grid[1], "--env", FM_TINY, *no_grid[4:]))
    for flag in ("--tune-episodes",):
        bad(f"ctl{flag}-0", (flag, "0"), flag, base=no_grid[:-4] if flag.endswith("episodes") else no_grid)
    cases += [
        c
        for c in _schedule_cases(g, "ctl", no_grid)
        if c.id.split("schedules-")[1] in ("missing", "empty", "unsorted")
    ]
    cases += [
        Case(
            "ctl-tune-schedules-empty",
            g,
            "refuse",
            argv=(*no_grid, "--tune-schedules", "@WORK@/s.json", *out),
            files=(("s.json", "[]"),),
            needle="--tune-schedules",
        ),
        Case(
            "ctl-out-openloop",
            g,
            "refuse",
            argv=(*CONTROLLERS, "--out", "@WORK@/openloop"),
            fixtures=("openloop",),
            needle="--out",
            what="was: dropped its point into the baseline's points/",
        ),
        Case(
            "ctl-other-grid",
            g,
            "refuse",
            argv=(*no_grid, "--grid", "mason_star=2", "--out", "@WORK@/controllers"),
            fixtures=("controllers",),
            needle="--out",
            what="was: replaced controller.json and tuning.csv",
        ),
        Case(
            "ctl-out-sys",
            g,
            "refuse",
            argv=(*CONTROLLERS, "--out", "/sys/dipsim_probe/run"),
            needle="--out",
        ),
        Case(
            "ctl-rerun-same",
            g,
            "ok",
            argv=(*CONTROLLERS, "--out", "@WORK@/controllers"),
            fixtures=("controllers",),
            preserve=("controllers/controller.json", "controllers/tuning.csv"),
            what="a rerun reuses everything",
        ),
    ]
    return cases


def evaluate_cases() -> list[Case]:
    g = "agents.evaluate"
    base = ("-m", "agents.evaluate", "@WORK@/ppo", "--baseline", "@WORK@/baseline")
    fx = ("ppo", "baseline")
    out = ("--out", "@OUT@")
    cases: list[Case] = []

    def bad(
        cid: str,
        flags: tuple[str, ...],
        needle: str | tuple[str, ...],
        what: str = "",
        files: tuple = (),
        fixtures: tuple[str, ...] = fx,
        argv: tuple[str, ...] = base,
    ) -> None:
        cases.append(
            Case(
                cid,
                g,
                "refuse",
                argv=(*argv, *flags, *out),
                needle=needle,
                what=what,
                files=files,
                fixtures=fixtures,
            )
        )

    bad(
        "ev-evaluations-truncated",
        ("--model", "best"),
        "evaluations.npz",
        files=(("ppo/eval/evaluations.npz", ("truncate", 100)),),
        what="was: BadZipFile",
    )
    bad(
        "ev-evaluations-truncated-final",
        (),
        "evaluations.npz",
        files=(("ppo/eval/evaluations.npz", ("truncate", 100)),),
        what="the learning curve reads it too",
    )
    bad("ev-model-truncated", (), "model.zip", files=(("ppo/model.zip", ("truncate", 0.5)),))
    bad("ev-vecnormalize-missing", (), "vecnormalize.pkl", files=(("ppo/vecnormalize.pkl", ("remove",)),))
    bad(
        "ev-baseline-missing",
        (),
        "--baseline",
        argv=("-m", "agents.evaluate", "@WORK@/ppo", "--baseline", "@WORK@/nope"),
    )
    bad(
        "ev-baseline-simrun",
        (),
        "--baseline",
        fixtures=("ppo", "simrun"),
        argv=("-m", "agents.evaluate", "@WORK@/ppo", "--baseline", "@WORK@/simrun"),
    )
    bad(
        "ev-baseline-controllers",
        (),
        "--baseline",
        fixtures=("ppo", "controllers"),
        argv=("-m", "agents.evaluate", "@WORK@/ppo", "--baseline", "@WORK@/controllers"),
    )
    bad(
        "ev-controllers-openloop",
        ("--controllers", "@WORK@/openloop"),
        "--controllers",
        fixtures=(*fx, "openloop"),
    )
    bad(
        "ev-baseline-other-env",
        (),
        ("--baseline",),
        fixtures=("ppo", "openloop"),
        argv=("-m", "agents.evaluate", "@WORK@/ppo", "--baseline", "@WORK@/openloop"),
        what="a thickening-control baseline for a field-magnitude policy",
    )
    bad(
        "ev-run-simrun",
        (),
        "simrun",
        fixtures=("simrun", "baseline"),
        argv=("-m", "agents.evaluate", "@WORK@/simrun", "--baseline", "@WORK@/baseline"),
    )
    bad("ev-split-bogus", ("--split", "bogus"), "--split")
    bad("ev-split-train", ("--split", "train"), "--split", what="a test-split baseline")
    for flag in ("--episodes", "--policy-repeats"):
        bad(f"ev{flag}-0", (flag, "0"), flag)
    bad("ev-repeats-more", ("--repeats", "3"), "--repeats", what="the baseline holds one realisation")
    bad("ev-episodes-more", ("--episodes", "5"), "--episodes", what="the baseline holds one state")
    bad("ev-play-kwargs-bad", ("--play-kwargs", "{bad"), "--play-kwargs")
    bad("ev-play-kwargs-unknown", ("--play-kwargs", '{"bogus": 1}'), "bogus")
    bad(
        "ev-schedules-field-env",
        ("--schedules", "@WORK@/s.json"),
        "--schedules",
        files=(("s.json", _j([{"times": [0.0], "rates": [1.0]}])),),
    )
    bad("ev-abbrev", ("--mod", "best"), "--mod", "allow_abbrev off")
    cases += [
        Case(
            "ev-out-openloop",
            g,
            "refuse",
            argv=(*base, "--out", "@WORK@/openloop"),
            fixtures=(*fx, "openloop"),
            needle="--out",
            preserve=("openloop",),
        ),
        Case(
            "ev-out-ppo",
            g,
            "refuse",
            argv=(*base, "--out", "@WORK@/ppo"),
            fixtures=fx,
            needle="--out",
            what="into the run it evaluates",
        ),
        Case(
            "ev-out-baseline",
            g,
            "refuse",
            argv=(*base, "--out", "@WORK@/baseline"),
            fixtures=fx,
            needle="--out",
        ),
        Case(
            "ev-out-file",
            g,
            "refuse",
            argv=(*base, "--out", "@WORK@/notes.txt"),
            fixtures=fx,
            files=(("notes.txt", "keep\n"),),
            needle="--out",
        ),
        Case(
            "ev-other-args-into-evaluation",
            g,
            "refuse",
            argv=(*base, "--model", "best", "--out", "@WORK@/evaluation"),
            fixtures=(*fx, "evaluation"),
            needle="--out",
        ),
        Case(
            "ev-ok",
            g,
            "ok",
            argv=(*base, *out),
            fixtures=fx,
            checks=("stdout:ppo",),
            what="the base evaluation",
        ),
    ]
    return cases


def demo_cases() -> list[Case]:
    g = "agents.demo"
    demo = ("-m", "agents.demo")
    return [
        Case(
            "demo-timesteps-16-into-demo",
            g,
            "refuse",
            argv=(*demo, "--out", "@WORK@/demo", "--timesteps", "16", "--seeds", "0"),
            fixtures=("demo",),
            needle="--out",
            what="was: announced 16 steps and reused the old runs",
        ),
        Case(
            "demo-seeds-other-into-demo",
            g,
            "refuse",
            argv=(*demo, "--out", "@WORK@/demo", "--timesteps", "32", "--seeds", "0-1"),
            fixtures=("demo",),
            needle="--out",
        ),
        Case(
            "demo-rerun-same",
            g,
            "ok",
            argv=(*demo, "--out", "@WORK@/demo", "--timesteps", "32", "--seeds", "0"),
            fixtures=("demo",),
            preserve=("demo/ppo/seed0/model.zip",),
            what="a rerun reuses the finished parts",
        ),
        Case(
            "demo-timesteps-0",
            g,
            "refuse",
            argv=(*demo, "--out", "@OUT@", "--timesteps", "0"),
            needle="--timesteps",
        ),
        Case(
            "demo-seeds-empty", g, "refuse", argv=(*demo, "--out", "@OUT@", "--seeds", ""), needle="--seeds"
        ),
        Case(
            "demo-seeds-desc", g, "refuse", argv=(*demo, "--out", "@OUT@", "--seeds", "3-1"), needle="--seeds"
        ),
        Case("demo-out-sys", g, "refuse", argv=(*demo, "--out", "/sys/dipsim_probe/demo"), needle="--out"),
        Case(
            "demo-out-file",
            g,
            "refuse",
            argv=(*demo, "--out", "@WORK@/notes.txt"),
            files=(("notes.txt", "keep\n"),),
            needle="--out",
        ),
        Case(
            "demo-out-simrun",
            g,
            "refuse",
            argv=(*demo, "--out", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="--out",
        ),
        Case(
            "demo-out-ppo",
            g,
            "refuse",
            argv=(*demo, "--out", "@WORK@/ppo"),
            fixtures=("ppo",),
            needle="--out",
        ),
        Case("demo-abbrev", g, "refuse", argv=(*demo, "--out", "@OUT@", "--time", "16"), needle="--time"),
    ]


def dipenv_cases() -> list[Case]:
    g = "dipenv API"
    head = "import gymnasium as gym\nimport dipenv\n"
    make = f"env = gym.make({TINY!r}, progress=False)\n"
    make_fm = f"env = gym.make({FM_TINY!r}, progress=False)\n"
    reset = "env.reset(seed=0, options={'split': 'test', 'index': 0})\n"
    step = (
        "obs, reward, terminated, truncated, info = env.step(np.array([0.0], dtype=np.float32))\n"
        "finite(obs, reward)\n"
    )

    def api(
        cid: str, expect: str, code: str, needle: str | tuple[str, ...] = (), what: str = "", **kw: Any
    ) -> Case:
        return Case(cid, g, expect, code=head + code, needle=needle, what=what, **kw)

    cases = []
    for kwargs, needle in (
        ("bogus=1", "bogus"),
        ("eta_cap=float('nan')", "eta_cap"),
        ("rate_range=(2.0, 1.0)", "rate_range"),
        ("hold_range=(-1.0, 1.0)", "hold_range"),
        ("hold_range=(0.0, 0.0)", "hold_range"),
        ("control_interval=float('inf')", "control_interval"),
        ("episode_steps=0", "episode_steps"),
        ("n_particles=2", "n_particles"),
        ("split_sizes={'test': -1}", "split"),
        ("simulation_overrides={'time_step': float('nan')}", "time_step"),
    ):
        cases.append(
            api(
                f"make-tc-{kwargs}",
                "refuse",
                f"gym.make({TINY!r}, progress=False, {kwargs})",
                needle,
                exceptions=("ValueError", "TypeError"),
            )
        )
    for kwargs, needle in (
        ("mason_min=30.0, mason_max=1.0", "mason"),
        ("off_band=2.0", "off_band"),
        ("energy_weight=float('inf')", "energy_weight"),
        ("actuator_substeps=0", "actuator_substeps"),
    ):
        cases.append(
            api(
                f"make-fm-{kwargs}",
                "refuse",
                f"gym.make({FM_TINY!r}, progress=False, {kwargs})",
                needle,
                exceptions=("ValueError", "TypeError"),
            )
        )
    cases.append(
        api(
            "make-unknown-id",
            "refuse",
            "gym.make('dipenv/Bogus-v0')",
            "Bogus",
            exceptions=("gym.error.Error",),
        )
    )
    cases.append(
        api(
            "make-library-root-sys",
            "refuse",
            f"env = gym.make({TINY!r}, progress=False, library_root='/sys/dipsim_probe')\n" + reset,
            "dipsim_probe",
            what="a start-state library that cannot be written",
            exceptions=("ValueError", "OSError"),
        )
    )
    bad_schedules = {
        "misspelled": (
            "{'schedules': {'times': [0.0], 'rates': [1.0]}}",
            ("'schedules'", "accepts: split, index, volume_fraction, realisation, schedule"),
        ),
        "fast": ("{'schedule': 'fast'}", "schedule"),
        "none": ("{'schedule': None}", "schedule"),
        "nested": ("{'schedule': [[0.0, 1.0], [1.0, [2.0]]]}", "rates"),
        "rate-1e-9": ("{'schedule': {'times': [0.0, 1.0], 'rates': [1e-9, 1e-9]}}", "rates"),
        "rate-1e-300": ("{'schedule': {'times': [0.0], 'rates': [1e-300]}}", "rates"),
        "rate-neg": ("{'schedule': {'times': [0.0, 1.0], 'rates': [1.0, -1.0]}}", "rates"),
        "times-unsorted": ("{'schedule': {'times': [0.0, 1.0, 0.5], 'rates': [1.0, 1.0, 1.0]}}", "times"),
        "over-cap": ("{'schedule': {'times': list(range(100001)), 'rates': [1.0] * 100001}}", "schedule"),
        "split-bogus": ("{'split': 'bogus'}", "split"),
        "index-neg": ("{'split': 'test', 'index': -1}", "index"),
        "index-huge": ("{'split': 'test', 'index': 10**9}", "index"),
        "index-bool": ("{'split': 'test', 'index': True}", "index"),
        "options-list": ("['split']", "options"),
    }
    for name, (options, needle) in bad_schedules.items():
        cases.append(api(f"reset-{name}", "refuse", make + f"env.reset(options={options})", needle))
    cases += [
        api(
            "reset-misspelled-fm",
            "refuse",
            make_fm + "env.reset(options={'splt': 'test'})",
            ("splt", "split"),
        ),
        api(
            "reset-schedule-100000",
            "ok",
            make + "import time\nn = 100000\nt0 = time.perf_counter()\n"
            "times = np.linspace(0.0, env.unwrapped.episode_duration, n)\n"
            "rates = 1.0 + 0.5 * np.sin(np.arange(n))\n"
            "env.reset(seed=0, options={'split': 'test', 'index': 0, 'schedule': {'times': times.tolist(),"
            " 'rates': rates.tolist()}})\n" + step + step + "elapsed = time.perf_counter() - t0\n"
            "if elapsed > 30: escape(f'a 100,000-knot schedule: reset and two steps took {elapsed:.0f} s')\n",
            what="must finish in seconds",
            timeout=90,
        ),
        api(
            "reset-schedule-ok-rates-finite",
            "ok",
            make + "env.reset(seed=0, options={'split': 'test', 'index': 0, 'schedule': {'times': [0.0, 0.1],"
            " 'rates': [1e-3, 1e-3]}})\n"
            + "obs, reward, terminated, truncated, info = env.step(np.array([-1.0], dtype=np.float32))\n"
            "finite(obs, reward)\n"
            "eta = info.get('eta_r', info.get('relative_viscosity'))\n"
            "if eta is None: escape(f'no eta_r in info: {sorted(info)}')\n"
            "if not (0 < eta < 1e4): absurd(f'eta_r = {eta} at the lowest rate, field off')\n",
            what="the lowest accepted rate, field off, gives a plausible eta_r",
        ),
        api(
            "step-before-reset",
            "refuse",
            make + step,
            "reset",
            exceptions=("ValueError", "RuntimeError", "gym.error.Error"),
        ),
        api("step-nan", "refuse", make + reset + "env.step(np.array([np.nan], dtype=np.float32))", "action"),
        api(
            "step-shape",
            "refuse",
            make + reset + "env.step(np.array([0.1, 0.2], dtype=np.float32))",
            "action",
        ),
        api("step-scalar", "refuse", make + reset + "env.step(0.5)", "action"),
        api(
            "step-out-of-space",
            "ok",
            make
            + reset
            + "obs, r, term, trunc, info = env.step(np.array([5.0], dtype=np.float32))\nfinite(obs, r)\n"
            "if not info.get('action_clipped'): absurd('an action of 5 was not reported as clipped')\n",
            what="clipped into [-1, 1] and reported",
        ),
        api(
            "step-vector-nan",
            "refuse",
            f"env = gym.make({FV_TINY!r}, progress=False)\n"
            + reset
            + "env.step(np.array([0.0, np.nan, 0.0], dtype=np.float32))",
            "action",
        ),
        api(
            "step-after-refused-reset",
            "ok",
            make + "try:\n    env.reset(options={'schedule': {'times': [0.0], 'rates': [1e-9]}})\n"
            "except ValueError:\n    pass\nelse:\n    absurd('rate 1e-9 accepted')\n" + reset + step,
            what="was: TypeError from the passive checker",
        ),
        api(
            "step-after-refused-reset-mid",
            "ok",
            make
            + reset
            + step
            + "try:\n    env.reset(options={'schedules': {}})\nexcept ValueError:\n    pass\n"
            + step,
            what="a refused reset mid-episode changes nothing",
        ),
        api(
            "reset-seed-neg",
            "refuse",
            make + "env.reset(seed=-1)",
            "Seed",
            exceptions=("ValueError", "gym.error.Error"),
        ),
        api(
            "step-after-end",
            "refuse",
            make + reset + "for _ in range(200):\n"
            "    obs, r, term, trunc, info = env.step(np.array([0.0], dtype=np.float32))\n"
            "    if term or trunc: break\nenv.step(np.array([0.0], dtype=np.float32))",
            "reset",
            exceptions=("ValueError", "RuntimeError"),
            what="a step after the episode ended",
        ),
    ]
    return cases


def scripts_cases() -> list[Case]:
    g = "scripts"
    paired = ("@REPO@/scripts/paired_rows.py",)

    def episodes(energy: Any = 1.0, excess: Any = 0.1, index: int = 0, ret: Any = -1.0) -> str:
        """Three states; the first carries the given values."""
        rows = [(index, energy, excess, ret), (index + 1, 0.5, 0.2, -2.0), (index + 2, 0.8, 0.3, -1.5)]
        return json.dumps(
            {
                "episodes": [
                    {
                        "split": "test",
                        "index": i,
                        "failed": False,
                        "return": r,
                        "excess_viscosity": x,
                        "energy_mean": e,
                    }
                    for i, e, x, r in rows
                ]
            }
        )

    def zero_energy(shift: float) -> str:
        return json.dumps(
            {
                "episodes": [
                    {
                        "split": "test",
                        "index": i,
                        "failed": False,
                        "return": -1.0 - i - shift,
                        "excess_viscosity": 0.1 * i,
                        "energy_mean": 0.0,
                    }
                    for i in range(3)
                ]
            }
        )

    good = ("good.json", episodes())
    cases = []
    for name, content in (
        ("negative-energy", episodes(energy=-0.5)),
        ("infinite-energy", episodes(energy=float("inf"))),
        ("nan-excess", episodes(excess=float("nan"))),
        ("negative-excess", episodes(excess=-1.0)),
        ("other-state", episodes(index=5)),
        ("no-episodes", json.dumps({"episodes": []})),
        ("garbage", "{not json"),
    ):
        cases.append(
            Case(
                f"paired-{name}",
                g,
                "refuse",
                argv=(*paired, "--a", "@WORK@/a.json", "--b", "@WORK@/good.json"),
                files=(("a.json", content), good),
                needle="different states" if name == "other-state" else "--a",
            )
        )
    cases += [
        Case(
            "paired-missing",
            g,
            "refuse",
            argv=(*paired, "--a", "@WORK@/nope.json", "--b", "@WORK@/good.json"),
            files=(good,),
            needle="nope.json",
        ),
        Case(
            "paired-ok",
            g,
            "ok",
            argv=(*paired, "--a", "@WORK@/good.json", "--b", "@WORK@/good.json"),
            files=(good,),
            checks=("plausible:",),
        ),
        Case(
            "paired-zero-energy",
            g,
            "ok",
            argv=(*paired, "--a", "@WORK@/a.json", "--b", "@WORK@/b.json"),
            files=(("a.json", zero_energy(0.0)), ("b.json", zero_energy(0.5))),
            checks=("plausible:",),
            what="no field in either row: no energy saving to divide",
        ),
        Case(
            "paired-split-bogus",
            g,
            "refuse",
            argv=(*paired, "--a", "@WORK@/good.json", "--b", "@WORK@/good.json", "--split", "bogus"),
            files=(good,),
            needle="bogus",
        ),
        Case(
            "paired-abbrev",
            g,
            "refuse",
            argv=(*paired, "--a", "@WORK@/good.json", "--b", "@WORK@/good.json", "--nam", "x,y"),
            files=(good,),
            needle="--nam",
        ),
        Case(
            "interval-noise-garbage",
            g,
            "refuse",
            argv=("@REPO@/scripts/interval_noise.py", "@WORK@/a.json"),
            files=(("a.json", "{not json"),),
            needle="a.json",
        ),
        Case(
            "rate-oracle-empty",
            g,
            "refuse",
            argv=("@REPO@/scripts/rate_oracle.py", "@WORK@/empty"),
            files=(("empty/.keep", ""),),
            needle="empty",
        ),
        Case(
            "thickening-summary-missing",
            g,
            "refuse",
            argv=("@REPO@/scripts/thickening_summary.py", "@WORK@/nope"),
            needle="nope",
        ),
        Case(
            "field-pulsing-garbage",
            g,
            "refuse",
            argv=("@REPO@/scripts/field_pulsing.py", "@WORK@/a.json"),
            files=(("a.json", "[]"),),
            needle="a.json",
        ),
        Case(
            "paper-grid-simrun",
            g,
            "refuse",
            argv=("@REPO@/scripts/paper_grid_compare.py", "@WORK@/simrun"),
            fixtures=("simrun",),
            needle="simrun",
            what="a run folder is not a sweep",
        ),
        Case(
            "collect-into-simrun",
            g,
            "refuse",
            argv=(
                "@REPO@/scripts/collect_training_runs.py",
                "@WORK@/study",
                "@WORK@/evaluation",
                "--out",
                "@WORK@/simrun",
            ),
            fixtures=("ppo", "evaluation", "simrun"),
            files=(("study/seed0", ("copy", "ppo")),),
            needle="--out",
        ),
        Case(
            "pulse-train-rate-tiny",
            g,
            "refuse",
            argv=("@REPO@/scripts/pulse_train.py", "--out", "@OUT@", "--env", TINY, "--rate", "1e-9"),
            needle="--rate",
        ),
        Case(
            "pulse-train-protocols-garbage",
            g,
            "refuse",
            argv=("@REPO@/scripts/pulse_train.py", "--out", "@OUT@", "--env", TINY, "--protocols", "bogus:x"),
            needle="--protocols",
        ),
        Case(
            "pulse-train-into-openloop",
            g,
            "refuse",
            argv=("@REPO@/scripts/pulse_train.py", "--out", "@WORK@/openloop", "--env", TINY),
            fixtures=("openloop",),
            needle="--out",
        ),
        Case(
            "direction-switch-zero",
            g,
            "refuse",
            argv=(
                "@REPO@/scripts/direction_switch.py",
                "--from",
                "@WORK@/simrun",
                "--direction",
                "0,0,0",
                "--out",
                "@OUT@",
            ),
            fixtures=("simrun",),
            needle="--direction",
        ),
        Case(
            "surrogate-data-seeds-bad",
            g,
            "refuse",
            argv=("@REPO@/scripts/surrogate_data.py", "--out", "@OUT@", "--seeds", "5-1"),
            needle="--seeds",
        ),
        Case(
            "thickening-energy-weight-neg",
            g,
            "refuse",
            argv=("@REPO@/scripts/thickening_energy_weight.py", "@WORK@/openloop/points", "--weights", "-1"),
            fixtures=("openloop",),
            needle="--weights",
        ),
    ]
    return cases


def all_cases() -> list[Case]:
    cases = [
        *sim_run_cases(), *sweep_cases(), *flow_curve_cases(), *sim_api_cases(), *train_cases(),
        *open_loop_cases(), *controllers_cases(), *evaluate_cases(), *demo_cases(), *dipenv_cases(),
        *scripts_cases(),
    ]  # fmt: skip
    ids = Counter(c.id for c in cases)
    duplicated = [i for i, n in ids.items() if n > 1]
    if duplicated:
        raise AssertionError(f"duplicate case ids: {duplicated}")
    return cases


# -- the report ----------------------------------------------------------------------------------------------


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    counts = Counter(r["class"] for r in records)
    total = len(records)
    return {
        "total": total,
        "counts": {k: counts.get(k, 0) for k in CLASSES},
        "clean_percent": round(100.0 * counts.get("clean", 0) / total, 1) if total else 0.0,
    }


def markdown(records: list[dict[str, Any]], command: str) -> str:
    summary = summarise(records)
    lines = [
        "# Input probe (issue 45)",
        "",
        f"Made by: `{command}`" if command else "",
        "",
        f"{summary['total']} cases: "
        + ", ".join(f"{n} {k}" for k, n in summary["counts"].items())
        + f"; {summary['clean_percent']}% clean.",
        "",
        "| group | cases | " + " | ".join(CLASSES) + " |",
        "|---|---|" + "---|" * len(CLASSES),
    ]
    groups = [g for g in GROUPS if any(r["group"] == g for r in records)]
    for group in groups:
        rows = [r for r in records if r["group"] == group]
        counts = Counter(r["class"] for r in rows)
        lines.append(
            f"| {group} | {len(rows)} | " + " | ".join(str(counts.get(k, 0)) for k in CLASSES) + " |"
        )
    bad = [r for r in records if r["class"] != "clean"]
    lines += ["", "## Cases that are not clean", ""]
    if not bad:
        lines.append("None.")
    for r in sorted(bad, key=lambda r: (CLASSES.index(r["class"]), GROUPS.index(r["group"]), r["id"])):
        lines += [
            f"### {r['id']} ({r['group']}): {r['class']}",
            "",
            f"expected `{r['expect']}`"
            + (f" naming {', '.join(repr(n) for n in r['needle'])}" if r["needle"] else "")
            + f"; exit {r['exit_code']}; {r['seconds']} s. {r['detail']}",
            "",
        ]
        if r["what"]:
            lines += [f"({r['what']})", ""]
        lines += ["```", r["command"][-1500:], "```", ""]
        tail = r["stderr_tail"].strip()[-800:]
        if tail:
            lines += ["stderr (tail):", "", "```", tail, "```", ""]
    return "\n".join(lines) + "\n"


def load(path: Path) -> tuple[list[dict[str, Any]], list[str]]:
    """(case records, the commands that made them) of a probe.json."""
    if not path.exists():
        return [], []
    data = json.loads(path.read_text())
    return list(data.get("cases", [])), list(data.get("commands", []))


def save(out: Path, records: list[dict[str, Any]], order: dict[str, int], commands: list[str]) -> None:
    records = sorted(records, key=lambda r: order.get(r["id"], len(order)))
    payload = {"commands": commands, "summary": summarise(records), "cases": records}
    text_md = markdown(records, "; ".join(commands))
    for name, text in (("probe.json", json.dumps(payload, indent=1) + "\n"), ("probe.md", text_md)):
        handle, temporary = tempfile.mkstemp(dir=out, prefix=f".{name}.")
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        os.chmod(temporary, 0o644)  # mkstemp's 0600 would keep the report from other readers
        os.replace(temporary, out / name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python scripts/probe_inputs.py",
        description="Probe bad and edge inputs of sim, dipenv, agents and scripts (issue 45).",
        allow_abbrev=False,
    )
    parser.add_argument("--out", required=True, type=Path, help="folder of probe.json and probe.md")
    parser.add_argument("--workers", type=int, default=1, help="cases at once, >= 1 (default 1)")
    parser.add_argument(
        "--only", nargs="+", choices=GROUPS, metavar="GROUP", help=f"groups: {', '.join(GROUPS)}"
    )
    parser.add_argument("--cases", nargs="+", metavar="ID", help="these case ids only")
    parser.add_argument(
        "--scratch", type=Path, help="folder of the fixtures and the cases' folders (default OUT/scratch)"
    )
    parser.add_argument(
        "--timeout", type=float, help=f"per-case timeout in s (default {DEFAULT_TIMEOUT:g}, or the case's)"
    )
    parser.add_argument("--rerun", action="store_true", help="run the selected cases again even if recorded")
    parser.add_argument("--keep", action="store_true", help="keep each case's scratch folder")
    parser.add_argument("--list", action="store_true", help="list the selected cases and exit")
    args = parser.parse_args(argv)
    if args.workers < 1:
        parser.error(f"argument --workers: must be an integer >= 1, got {args.workers}")
    if args.timeout is not None and not (math.isfinite(args.timeout) and args.timeout > 0):
        parser.error(f"argument --timeout: must be a number > 0, got {args.timeout}")

    cases = all_cases()
    known = {c.id for c in cases}
    if args.cases:
        unknown = [i for i in args.cases if i not in known]
        if unknown:
            parser.error(f"argument --cases: unknown ids {unknown}")
        cases = [c for c in cases if c.id in args.cases]
    if args.only:
        cases = [c for c in cases if c.group in args.only]
    if args.timeout is not None:
        cases = [Case(**{**c.__dict__, "timeout": args.timeout}) for c in cases]
    if args.list:
        for case in cases:
            print(f"{case.id}\t{case.group}\t{case.expect}\t{case.command}")
        return 0

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    scratch = (args.scratch or out / "scratch").resolve()
    scratch.mkdir(parents=True, exist_ok=True)
    command = "python scripts/probe_inputs.py " + " ".join(
        _quote(a) for a in (sys.argv[1:] if argv is None else argv)
    )
    order = {c.id: i for i, c in enumerate(all_cases())}
    loaded, commands = load(out / "probe.json")
    records = {r["id"]: r for r in loaded if r["id"] in known}
    current = {c.id: c for c in all_cases()}
    for rid, record in list(records.items()):  # a changed case is run again
        if record.get("case_digest") != current[rid].digest:
            del records[rid]
    todo = [c for c in cases if args.rerun or c.id not in records]
    lock = threading.Lock()

    def log(message: str) -> None:
        with lock:
            print(message, flush=True)

    needed = [name for name in FIXTURE_ORDER if any(name in c.fixtures for c in todo)]
    if any("evaluation" == n for n in needed):
        needed = sorted({*needed, "ppo", "baseline"}, key=FIXTURE_ORDER.index)
    for name in needed:
        build_fixture(name, scratch / "fixtures", log)
    log(f"{len(todo)} cases to run ({len(cases) - len(todo)} already recorded), {args.workers} at a time")

    done = 0
    if todo and command not in commands:
        commands = [*commands, command]

    def one(case: Case) -> None:
        nonlocal done
        record = run_case(case, scratch, keep=args.keep)
        with lock:
            records[case.id] = record
            done += 1
            save(out, list(records.values()), order, commands)
            print(
                f"[{done}/{len(todo)}] {case.id}: {record['class']} ({record['seconds']} s) "
                f"{record['detail']}",
                flush=True,
            )

    with ThreadPoolExecutor(max_workers=args.workers) as pool:
        list(pool.map(one, todo))
    save(out, list(records.values()), order, commands)
    summary = summarise(list(records.values()))
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
