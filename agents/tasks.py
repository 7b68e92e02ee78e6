"""Independent tasks (training seeds, open-loop points) on a local process pool or a Dask cluster.

Each task is ``function(payload)`` with a picklable module-level ``function`` and a JSON-like payload, and
writes its own result folder, so a rerun skips finished tasks and the backends are interchangeable:

* ``workers <= 1`` and no scheduler: in this process, in order;
* ``workers > 1``: a local ``ProcessPoolExecutor`` (spawned, non-daemonic workers, so a task may start
  its own ``SubprocVecEnv``);
* ``scheduler="tcp://host:8786"`` (or any address ``distributed.Client`` accepts): a Dask cluster; needs
  ``pip install "dask[distributed]"`` (imported only here). Dask workers are daemonic processes by
  default, so training tasks there fall back to in-process environments (see
  :func:`agents.train.can_start_subprocesses`).
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")


def parse_seeds(text: str) -> list[int]:
    """``"0-4"`` -> [0, 1, 2, 3, 4]; ``"0,3,7-8"`` -> [0, 3, 7, 8] (sorted, unique).

    Raises:
        ValueError: on anything but non-negative integers and ranges ``a-b`` with ``a <= b``.
    """
    seeds: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                low, high = (int(x) for x in part.split("-", 1))
                if low < 0 or high < low:
                    raise ValueError
                seeds.update(range(low, high + 1))
            else:
                value = int(part)
                if value < 0:
                    raise ValueError
                seeds.add(value)
        except ValueError:
            raise ValueError(f"seeds must look like 0-4 or 0,2,5-7 (non-negative), got {text!r}") from None
    return sorted(seeds)


def run_tasks(
    function: Callable[[T], R], payloads: Sequence[T], workers: int = 1, scheduler: str | None = None
) -> list[R]:
    """Run ``function`` on every payload; results in payload order.

    Args:
        function: a module-level (picklable) function.
        payloads: its arguments, one per task.
        workers: local worker processes (ignored with a scheduler).
        scheduler: address of a Dask scheduler, or None for the local pool.
    """
    if scheduler is not None:
        return _run_dask(function, payloads, scheduler)
    if workers <= 1 or len(payloads) <= 1:
        return [function(p) for p in payloads]
    with ProcessPoolExecutor(
        max_workers=min(workers, len(payloads)), mp_context=mp.get_context("spawn")
    ) as pool:
        return list(pool.map(function, payloads))


def _run_dask(function: Callable[[T], R], payloads: Sequence[T], scheduler: str) -> list[R]:
    try:
        from distributed import Client
    except ImportError as error:  # pragma: no cover - depends on the installation
        raise RuntimeError('--scheduler needs Dask: pip install "dask[distributed]"') from error
    client: Any = Client(scheduler)
    try:
        futures = client.map(function, list(payloads), pure=False)
        return list(client.gather(futures))
    finally:
        client.close()
