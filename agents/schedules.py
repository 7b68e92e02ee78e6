"""Your own schedules: ``--schedules FILE`` on ``agents.open_loop``, ``agents.controllers`` and
``agents.evaluate`` plays every row on shear-rate schedules of your own (issue 43).

The file is JSON, a list of entries (at least one, at most :data:`MAX_ENTRIES`); an entry is either a
schedule, ``{"times": [...], "rates": [...]}``, or ``{"schedule": {"times": [...], "rates": [...]}}``,
each optionally with ``"start_index": k`` (a start state of the command's ``--split``) and ``"name"`` (a
label for the reports). Entries are numbered from 0 in file order. Each schedule goes through
:func:`dipenv.schedules.validate_schedule`, the environments' one check (times from 0, increasing, two
equal times make a jump; rates in the simulator's range). The whole file is checked before a command
claims its ``--out``; a bad one exits 2 naming ``--schedules``, the entry and what is wrong.

Episode ``j`` of the file starts from state ``start_index`` (default ``j mod`` the split's size) of the
start-state split ``--split`` and follows schedule ``j``: ``reset(options={"split": split, "index":
start_index, "schedule": schedule_j, "realisation": k})``. Its stored record numbers it by the entry
(``index`` is ``j``, so realisations, per-episode averages and the pairing of rows work as on a fixed
split, where ``index`` is the state that plays schedule ``index``) and carries ``start_index``, ``entry``
and the schedule's digest ``schedule_digest``; a stored episode is reused only for the same schedule
and start state. A schedule equal to a fixed split's schedule ``k``, played from state ``k``, is that
split's episode bit for bit (JSON keeps every float exactly).

The file's digest (:attr:`ScheduleSet.digest`, 16 hex digits of SHA-256) covers each entry's schedule
and resolved start state, in order, not the names or the file's layout; it joins the identity of every
folder made with the file, so a changed file is refused in the same ``--out`` and plays afresh elsewhere.
``agents.evaluate --schedules FILE`` checks that its ``--baseline`` and ``--controllers`` were made with
a file of the same digest. Every command writes the file it played, resolved (start states explicit), to
``OUT/schedules.json`` (``agents.controllers --tune-schedules``: ``OUT/tune_schedules.json``): a file of the
same digest.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sim
from agents.rollout import Policy, run_episode
from agents.usage import usage_error
from dipenv.schedules import MAX_SCHEDULE_KNOTS, schedule_to_dict, validate_schedule

MAX_ENTRIES = 1024
"""The most entries a schedules file may hold (the fresh split has 128 schedules)."""
MAX_TOTAL_KNOTS = 10 * MAX_SCHEDULE_KNOTS
"""The most knots of all the file's schedules together: every task of a command receives them all."""
MAX_FILE_BYTES = 64 * 2**20
"""The largest schedules file read (about 2.5 million knots written with 17 digits)."""

ENTRY_FORMS = (
    '{"times": [...], "rates": [...]} or {"schedule": {"times": [...], "rates": [...]}}, each optionally '
    'with "start_index" and "name"'
)
_FLAT_KEYS = {"times", "rates"}
_OPTIONAL_KEYS = {"start_index", "name"}


def schedule_digest(schedule: sim.PiecewiseLinear) -> str:
    """SHA-256 (16 hex digits) of one schedule's knots (:func:`dipenv.schedules.schedule_to_dict`)."""
    return hashlib.sha256(json.dumps(schedule_to_dict(schedule)).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Entry:
    """One entry of a schedules file as given (``start_index`` None: the default)."""

    entry: int
    schedule: sim.PiecewiseLinear
    start_index: int | None
    name: str | None


@dataclass(frozen=True)
class ScheduledEpisode:
    """Episode ``entry`` of a schedules file: its schedule from start state ``start_index``."""

    entry: int
    start_index: int
    schedule: sim.PiecewiseLinear
    digest: str
    name: str | None

    def describe(self) -> dict[str, Any]:
        """The entry without its knots: entry, name, start state and schedule digest."""
        return {
            "entry": self.entry,
            "name": self.name,
            "start_index": self.start_index,
            "schedule_digest": self.digest,
        }


@dataclass(frozen=True)
class ScheduleSet:
    """A schedules file resolved on a start-state split: episode ``j`` is ``episodes[j]``."""

    path: str
    split: str
    episodes: tuple[ScheduledEpisode, ...]
    digest: str

    def __len__(self) -> int:
        return len(self.episodes)

    def summary(self) -> dict[str, Any]:
        """What a command's summary files record of the file (``pareto.json``, ``controller.json``,
        ``results.json``): its path, digest, start-state split and entries (without their knots)."""
        return {
            "file": self.path,
            "digest": self.digest,
            "split": self.split,
            "entries": [e.describe() for e in self.episodes],
        }

    def resolved(self) -> list[dict[str, Any]]:
        """The file with every start state explicit (``OUT/schedules.json``; the same digest)."""
        return [
            {
                **({"name": e.name} if e.name is not None else {}),
                "start_index": e.start_index,
                "schedule": schedule_to_dict(e.schedule),
            }
            for e in self.episodes
        ]

    def label(self) -> str:
        """``N schedules of FILE (digest D)``, for the printed tables."""
        count = len(self.episodes)
        return f"{count} schedule{'s' if count != 1 else ''} of {self.path} (digest {self.digest})"


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def read_entries(path: Path) -> list[Entry]:
    """The entries of the schedules file ``path``, each schedule checked by
    :func:`dipenv.schedules.validate_schedule`; ``ValueError`` naming the entry and what is wrong."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ValueError(f"is {size} bytes, more than the cap of {MAX_FILE_BYTES} (MAX_FILE_BYTES)")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"cannot be read ({type(error).__name__}: {error})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"is not JSON ({error})") from None
    if not isinstance(data, list):
        raise ValueError(f"must be a JSON list of schedules ({ENTRY_FORMS}), got {type(data).__name__}")
    if not data:
        raise ValueError("holds no schedule (give at least one entry)")
    if len(data) > MAX_ENTRIES:
        raise ValueError(f"holds {len(data)} entries, more than the cap of {MAX_ENTRIES} (MAX_ENTRIES)")
    entries: list[Entry] = []
    knots = 0
    for j, item in enumerate(data):
        where = f"entry {j}"
        if not isinstance(item, dict):
            raise ValueError(f"{where} must be {ENTRY_FORMS}, got {_short(item)}")
        keys = set(item)
        nested = "schedule" in keys
        allowed = ({"schedule"} if nested else _FLAT_KEYS) | _OPTIONAL_KEYS
        unknown = sorted(map(str, keys - allowed))
        if unknown or (not nested and not _FLAT_KEYS <= keys):
            what = f"unknown keys {unknown}" if unknown else f"keys {sorted(map(str, keys))}"
            raise ValueError(f"{where} must be {ENTRY_FORMS}, got {what}")
        raw = item["schedule"] if nested else {k: item[k] for k in ("times", "rates")}
        schedule = validate_schedule(raw, where)
        knots += len(schedule.times)
        if knots > MAX_TOTAL_KNOTS:
            raise ValueError(
                f"{where}: the schedules up to it hold {knots} knots, more than the cap of {MAX_TOTAL_KNOTS} "
                "for the whole file (MAX_TOTAL_KNOTS)"
            )
        start = item.get("start_index")
        if start is not None and (isinstance(start, bool) or not isinstance(start, int) or start < 0):
            raise ValueError(f"{where}: start_index must be an integer >= 0, got {_short(start)}")
        name = item.get("name")
        if name is not None and not (isinstance(name, str) and name.strip()):
            raise ValueError(f"{where}: name must be a non-empty string, got {_short(name)}")
        entries.append(Entry(j, schedule, start, name))
    return entries


def resolve(path: Path, entries: list[Entry], split: str, size: int) -> ScheduleSet:
    """``entries`` on the start-state split ``split`` of ``size`` states (``start_index`` default ``j mod
    size``); ``ValueError`` naming the entry whose start state is outside the split."""
    episodes = []
    for e in entries:
        start = e.entry % size if e.start_index is None else e.start_index
        if not 0 <= start < size:
            raise ValueError(
                f"entry {e.entry}: start_index {start} is outside the {size} start states of the {split} "
                f"split (0 to {size - 1})"
            )
        episodes.append(ScheduledEpisode(e.entry, start, e.schedule, schedule_digest(e.schedule), e.name))
    content = [{"schedule": e.digest, "start_index": e.start_index} for e in episodes]
    digest = hashlib.sha256(json.dumps(content).encode()).hexdigest()[:16]
    return ScheduleSet(str(path), split, tuple(episodes), digest)


def takes_schedules(unwrapped: Any) -> bool:
    """Whether the env ``unwrapped`` follows a shear-rate schedule (the thickening-control envs)."""
    return "schedule" in getattr(unwrapped, "reset_options", ())


def load_schedules(
    prog: str, path: Path, unwrapped: Any, env_id: str, split: str, option: str = "--schedules"
) -> ScheduleSet:
    """The schedules file ``path`` resolved on ``split`` of the env ``unwrapped``, or exit 2 naming
    ``option``: the env follows no schedule, the file is malformed (the entry and what is wrong), or a
    start state lies outside the split."""
    if not takes_schedules(unwrapped):
        usage_error(
            prog,
            f"{option} is for the thickening-control envs (their shear rate follows a schedule); --env "
            f"{env_id} has no schedule",
        )
    sizes = unwrapped.split_sizes
    if split not in sizes:
        usage_error(prog, f"--split must be one of {', '.join(sizes)}, got {split!r}")
    try:
        return resolve(path, read_entries(path), split, int(sizes[split]))
    except ValueError as error:
        usage_error(prog, f"{option} {path}: {error}")


def episode_count(prog: str, schedules: ScheduleSet, episodes: int | None) -> int:
    """The number of entries to play: all of them when ``episodes`` is None, else the first
    ``episodes``; exit 2 naming ``--episodes`` outside ``[1, entries]``."""
    n = len(schedules) if episodes is None else episodes
    if not 1 <= n <= len(schedules):
        usage_error(
            prog,
            f"--episodes must be in [1, {len(schedules)}] (the entries of --schedules {schedules.path}), "
            f"got {n}",
        )
    return int(n)


def prepare_states(unwrapped: Any, schedules: ScheduleSet, count: int | None = None) -> None:
    """Pre-shear the start states of the first ``count`` episodes (default all) that are not on disk yet,
    once, before the workers start (only those: a file on the fresh split needs few of its states)."""
    library = unwrapped.library()
    wanted = sorted({e.start_index for e in schedules.episodes[:count]})
    for index in wanted:
        library.load(schedules.split, index, progress=True)


def episodes_payload(schedules: ScheduleSet | None) -> list[dict[str, Any]] | None:
    """The episodes as plain data for a task's payload (picklable, JSON-ready), None without a file."""
    if schedules is None:
        return None
    return [{**e.describe(), **schedule_to_dict(e.schedule)} for e in schedules.episodes]


def matches(episode: dict[str, Any], scheduled: list[dict[str, Any]]) -> bool:
    """Whether the stored ``episode`` is that of entry ``episode["index"]`` of ``scheduled``
    (:func:`episodes_payload`): the same start state and schedule digest."""
    j = int(episode.get("index", -1))
    if not 0 <= j < len(scheduled):
        return False
    want = scheduled[j]
    return (
        episode.get("start_index") == want["start_index"]
        and episode.get("schedule_digest") == want["schedule_digest"]
    )


def play(
    env: Any, policy: Policy, split: str, scheduled: dict[str, Any], realisation: int = 0
) -> dict[str, Any]:
    """Episode ``scheduled`` (an item of :func:`episodes_payload`) with ``realisation``, as a stored
    record: the episode metrics (numbered by the entry), the trace, the start state and schedule digest."""
    schedule = {"times": scheduled["times"], "rates": scheduled["rates"]}
    trace = run_episode(
        env, policy, split, int(scheduled["start_index"]), realisation=realisation, schedule=schedule
    )
    tags = {
        "index": int(scheduled["entry"]),
        "entry": int(scheduled["entry"]),
        "start_index": int(scheduled["start_index"]),
        "schedule_digest": scheduled["schedule_digest"],
    }
    return {**trace.summary(), **tags, "trace": {**trace.to_dict(), **tags}}


def recorded(summary: dict[str, Any] | None) -> str:
    """How a folder's recorded schedules read in a message: ``FILE (digest D)``, or the split's own."""
    if not summary:
        return "its split's own schedules"
    return f"{summary.get('file')} (digest {summary.get('digest')})"


def mismatch(ours: ScheduleSet | None, theirs: dict[str, Any] | None) -> bool:
    """Whether a folder whose summary records the schedules ``theirs`` (None: the split's own) was played
    on other schedules than ``ours`` (None: the split's own)."""
    digest = None if not theirs else theirs.get("digest")
    return digest != (None if ours is None else ours.digest)


def mismatch_message(
    option: str, folder: Path, ours: ScheduleSet | None, theirs: dict[str, Any] | None, command: str
) -> str:
    """Why the folder ``folder`` (given as ``option``, made by ``command``) cannot join an evaluation on
    ``ours``: it names the schedules of both and the fix."""
    here = "the split's own schedules" if ours is None else f"--schedules {ours.path} (digest {ours.digest})"
    if ours is None:
        fix = f"give --schedules {(theirs or {}).get('file')} (a copy: {folder / 'schedules.json'})"
    elif not theirs:
        fix = f"make it again with {command} --schedules {ours.path}"
    else:
        fix = (
            f"make it again with {command} --schedules {ours.path}, or give --schedules {theirs.get('file')}"
        )
    return f"{option} {folder} was played on {recorded(theirs)}, this evaluation on {here}: {fix}"


__all__ = [
    "MAX_ENTRIES",
    "MAX_TOTAL_KNOTS",
    "Entry",
    "ScheduleSet",
    "ScheduledEpisode",
    "episode_count",
    "episodes_payload",
    "load_schedules",
    "matches",
    "mismatch",
    "mismatch_message",
    "play",
    "prepare_states",
    "read_entries",
    "resolve",
    "schedule_digest",
    "takes_schedules",
]
