"""Independent tasks on a local process pool or a Dask cluster: the one task engine of ``sim`` and ``agents``.

A task is ``function(payload)`` with a picklable module-level ``function`` and a picklable (JSON-like)
payload. Tasks that write their own result folder make a rerun skip finished work, so the backends are
interchangeable:

* ``workers <= 1`` and no scheduler: in this process, one after the other, in order;
* ``workers > 1``: a local ``ProcessPoolExecutor`` of spawned, non-daemonic processes (a task may start
  processes of its own, e.g. an SB3 ``SubprocVecEnv``);
* ``scheduler="tcp://host:8786"`` (any address ``distributed.Client`` accepts): an existing Dask cluster
  (``dask scheduler`` + ``dask worker tcp://host:8786``; ``pip install "dask[distributed]"``, imported only
  then). Dask workers are daemonic processes by default, so a task there cannot start processes.

Failure policy: ``on_error="raise"`` (the default) re-raises the first task exception, after the tasks
already running have finished; ``on_error="record"`` returns a :class:`TaskFailure` (exception type,
message and the traceback formatted where the task ran) in that task's place and lets the others go on.
A worker process that dies (a crash, the out-of-memory killer) fails its task the same way.
"""

from __future__ import annotations

import multiprocessing as mp
import sys
import traceback
from collections.abc import Callable, Generator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from typing import Any, Generic, Literal, TypeVar, overload

T = TypeVar("T")
R = TypeVar("R")

OnError = Literal["raise", "record"]


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised instead of returning.

    Attributes:
        index: position of the task's payload in the list given to :func:`run_tasks`.
        error: the exception's class name (``SimulationError``, ``BrokenProcessPool``, ...).
        message: ``str`` of the exception.
        traceback: the formatted traceback, taken in the process that ran the task (empty when the
            worker process died before it could report one).
    """

    index: int
    error: str
    message: str
    traceback: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return asdict(self)


MAX_SEEDS = 10_000
"""The most seeds one command takes (``--seeds``): each is a run or a training, so more is a typo."""


def parse_seeds(text: str, max_count: int = MAX_SEEDS) -> list[int]:
    """``"0-4"`` -> [0, 1, 2, 3, 4]; ``"0,3,7-8"`` -> [0, 3, 7, 8] (sorted, unique).

    The count is checked before any list is built, so ``0-99999999999`` is refused at once.

    Raises:
        ValueError: on anything but non-negative integers and ranges ``a-b`` with ``a <= b``, or on more
        than ``max_count`` seeds.
    """
    ranges: list[tuple[int, int]] = []
    for part in text.split(","):
        part = part.strip()
        try:
            low, high = (int(x) for x in part.split("-", 1)) if "-" in part else (int(part), int(part))
            if low < 0 or high < low:
                raise ValueError
        except ValueError:
            raise ValueError(f"seeds must look like 0-4 or 0,2,5-7 (non-negative), got {text!r}") from None
        ranges.append((low, high))
    count = sum(high - low + 1 for low, high in ranges)  # an upper bound (before duplicates are merged)
    if count > max_count:
        raise ValueError(f"at most {max_count} seeds are allowed, got {count} in {text!r}")
    seeds: set[int] = set()
    for low, high in ranges:
        seeds.update(range(low, high + 1))
    return sorted(seeds)


class _Recording(Generic[T, R]):
    """``function`` wrapped so that an exception comes back as a :class:`TaskFailure` (picklable)."""

    def __init__(self, function: Callable[[T], R]) -> None:
        self.function = function

    def __call__(self, item: tuple[int, T]) -> R | TaskFailure:
        index, payload = item
        try:
            return self.function(payload)
        except Exception as exc:
            return _failure(index, exc, traceback.format_exc())


def _failure(index: int, exc: BaseException, formatted: str = "") -> TaskFailure:
    """A :class:`TaskFailure` for ``exc`` (the traceback of a worker that died is unknown: empty)."""
    return TaskFailure(index=index, error=type(exc).__name__, message=str(exc), traceback=formatted)


@overload
def run_tasks(
    function: Callable[[T], R],
    payloads: Sequence[T],
    workers: int = 1,
    scheduler: str | None = None,
    *,
    on_error: Literal["raise"] = "raise",
    progress: bool = False,
    description: str = "tasks",
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]: ...


@overload
def run_tasks(
    function: Callable[[T], R],
    payloads: Sequence[T],
    workers: int = 1,
    scheduler: str | None = None,
    *,
    on_error: Literal["record"],
    progress: bool = False,
    description: str = "tasks",
    on_result: Callable[[int, R | TaskFailure], None] | None = None,
) -> list[R | TaskFailure]: ...


def run_tasks(
    function: Callable[[T], Any],
    payloads: Sequence[T],
    workers: int = 1,
    scheduler: str | None = None,
    *,
    on_error: OnError = "raise",
    progress: bool = False,
    description: str = "tasks",
    on_result: Callable[[int, Any], None] | None = None,
) -> list[Any]:
    """Run ``function`` on every payload; results in payload order.

    Args:
        function: a module-level (picklable) function of one payload.
        payloads: its arguments, one per task.
        workers: local worker processes, >= 1 (ignored with a scheduler).
        scheduler: address of a Dask scheduler (``tcp://host:port``), or None for the local pool.
        on_error: ``"raise"``: the first exception propagates (tasks not yet started are cancelled);
            ``"record"``: a failed task's place holds a :class:`TaskFailure` and the others go on.
        progress: show a tqdm bar over the tasks on stderr.
        description: the bar's label.
        on_result: called in this process as ``on_result(index, result)`` as each task finishes (in
            completion order), e.g. to keep a manifest file up to date.

    Raises:
        ValueError: ``workers < 1``; RuntimeError: a scheduler without Dask installed; OSError: the
        scheduler cannot be reached; any exception of a task with ``on_error="raise"``.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if on_error not in ("raise", "record"):
        raise ValueError(f"on_error must be 'raise' or 'record', got {on_error!r}")
    items = list(enumerate(payloads))
    task: Callable[[tuple[int, T]], Any] = _Recording(function) if on_error == "record" else _Direct(function)
    results: list[Any] = [None] * len(items)
    finished: Generator[tuple[int, Any], None, None]
    if scheduler is not None:
        finished = _dask(task, items, scheduler, on_error)
    elif workers == 1 or len(items) <= 1:
        finished = ((item[0], task(item)) for item in items)
    else:
        finished = _pool(task, items, workers, on_error)
    bar = _bar(len(items), description, progress)
    try:
        for index, result in finished:
            results[index] = result
            if bar is not None:
                bar.update(1)
                if isinstance(result, TaskFailure):
                    bar.set_postfix_str(f"{_count_failures(results)} failed", refresh=True)
            if on_result is not None:
                on_result(index, result)
    finally:
        finished.close()  # stops the pool or the Dask client after an error or an interrupt
        if bar is not None:
            bar.close()
    return results


class _Direct(Generic[T, R]):
    """``function`` applied to the payload of an ``(index, payload)`` item (picklable)."""

    def __init__(self, function: Callable[[T], R]) -> None:
        self.function = function

    def __call__(self, item: tuple[int, T]) -> R:
        return self.function(item[1])


def _count_failures(results: list[Any]) -> int:
    return sum(isinstance(r, TaskFailure) for r in results)


def _bar(total: int, description: str, progress: bool) -> Any:
    """A tqdm bar over ``total`` tasks on stderr, or None."""
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=description, unit="task", file=sys.stderr, dynamic_ncols=True)


def _outcome(future: Any, index: int, on_error: OnError) -> Any:
    """A finished future's result, or the :class:`TaskFailure` of task ``index`` when it raised.

    The exception is re-raised with ``on_error="raise"``: a task's own exception, or the pool's when its
    worker died (``BrokenProcessPool`` of a process pool, ``KilledWorker`` of Dask).
    """
    try:
        return future.result()
    except Exception as exc:
        if on_error == "raise":
            raise
        return _failure(index, exc)


def _pool(
    task: Callable[[tuple[int, T]], Any], items: list[tuple[int, T]], workers: int, on_error: OnError
) -> Generator[tuple[int, Any], None, None]:
    """(index, result) of every item as it finishes on a pool of spawned processes."""
    pool = ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=mp.get_context("spawn"))
    try:
        futures: dict[Future[Any], int] = {pool.submit(task, item): item[0] for item in items}
        for future in as_completed(futures):
            index = futures[future]
            yield index, _outcome(future, index, on_error)
    except (KeyboardInterrupt, GeneratorExit):  # interrupted, or the caller stopped reading: stop the workers
        for process in list((getattr(pool, "_processes", None) or {}).values()):
            process.terminate()
        raise
    finally:  # cancel what has not started; after a task's exception, wait for the tasks still running
        pool.shutdown(wait=True, cancel_futures=True)


def _dask(
    task: Callable[[tuple[int, T]], Any], items: list[tuple[int, T]], scheduler: str, on_error: OnError
) -> Generator[tuple[int, Any], None, None]:
    """(index, result) of every item as it finishes on the Dask cluster at ``scheduler``."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError as error:  # pragma: no cover - depends on the installation
        raise RuntimeError('a Dask scheduler needs Dask: pip install "dask[distributed]"') from error
    client: Any = Client(scheduler)
    futures: list[Any] = []
    try:
        futures = client.map(task, items, pure=False)
        indices = {future.key: index for future, (index, _) in zip(futures, items, strict=True)}
        for future in dask_completed(futures):
            index = indices[future.key]
            yield index, _outcome(future, index, on_error)
    except BaseException:  # a task's exception, an interrupt, or the caller stopped reading
        client.cancel(futures)
        raise
    finally:
        client.close()
