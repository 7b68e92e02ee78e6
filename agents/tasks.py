"""Independent tasks (training seeds, open-loop points, evaluations) on a local pool or a Dask cluster.

The engine is the simulator's (:mod:`sim.runs.tasks`, exported by ``sim``), shared with
``python -m sim sweep``; this module keeps the names the agents import:

* ``workers <= 1`` and no scheduler: in this process, in order;
* ``workers > 1``: a local ``ProcessPoolExecutor`` (spawned, non-daemonic workers, so a task may start
  its own ``SubprocVecEnv``);
* ``scheduler="tcp://host:8786"`` (or any address ``distributed.Client`` accepts): a Dask cluster; needs
  ``pip install "dask[distributed]"`` (imported only then). Dask workers are daemonic processes by
  default, so training tasks there fall back to in-process environments (see
  :func:`agents.train.can_start_subprocesses`).

``run_tasks(..., on_error="record")`` returns a ``TaskFailure`` in a failed task's place instead of
raising, and ``progress=True`` shows a bar over the tasks.
"""

from __future__ import annotations

from sim import TaskFailure, parse_seeds, run_tasks

__all__ = ["TaskFailure", "parse_seeds", "run_tasks"]
