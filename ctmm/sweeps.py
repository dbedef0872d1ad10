"""Parameter sweeps: executors (threads, processes, dask.distributed) and progress bars.

Every sweep in ctmm takes ``executor=``: ``None`` (sequential, the default), ``"threads"`` or
``"processes"`` (a pool of ``os.cpu_count()`` workers created for the call and shut down after
it), or any object with the :class:`concurrent.futures.Executor` interface -- including
``distributed.Client(...).get_executor()`` of dask.distributed -- which is used as given and not
shut down.  Work is handed out as picklable callables and arguments (module-level functions),
results come back in input order.
"""
from __future__ import annotations

import os
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator

from .errors import ModelError
from .progress import progress_bar

__all__ = ["managed_executor", "executor_workers", "parallel_map"]


def _is_executor(value: Any) -> bool:
    return isinstance(value, Executor) or (callable(getattr(value, "submit", None))
                                           and callable(getattr(value, "map", None)))


@contextmanager
def managed_executor(executor: Any) -> Iterator[Any]:
    """Resolve an ``executor`` option; pools created here are shut down on exit."""
    if executor is None:
        yield None
    elif isinstance(executor, str):
        kinds = {"threads": ThreadPoolExecutor, "processes": ProcessPoolExecutor}
        if executor not in kinds:
            raise ModelError(f"executor must be None, 'threads', 'processes' or an Executor, got {executor!r}")
        with kinds[executor](max_workers=os.cpu_count() or 2) as pool:
            yield pool
    elif _is_executor(executor):
        yield executor
    else:
        raise ModelError(f"executor must be None, 'threads', 'processes' or an Executor, got {executor!r}")


def executor_workers(executor: Any) -> int:
    """Number of parallel workers of an executor (to split work into that many chunks)."""
    workers = getattr(executor, "_max_workers", None)
    if isinstance(workers, int) and workers > 0:
        return workers
    client = getattr(executor, "_client", None)
    if client is not None:                             # distributed.client.ClientExecutor
        try:
            return max(1, sum(client.nthreads().values()))
        except Exception:  # noqa: BLE001 - a closed client: fall back on the CPU count
            pass
    return os.cpu_count() or 2


def parallel_map(function: Callable[[Any], Any], items: Iterable[Any], *, executor: Any = None,
                 progress: bool | None = None, description: str = "sweep") -> list:
    """``[function(item) for item in items]``, sequentially or on ``executor``, in input order.

    Parameters
    ----------
    function : callable
        A picklable (module-level) function of one argument for process pools.
    items : iterable
        Arguments.
    executor : Executor, "threads", "processes" or None
        See the module docstring.
    progress : bool, optional
        Show a progress bar (default: on terminals for 50 items or more).
    description : str
        Label of the progress bar.
    """
    items = list(items)
    bar = progress_bar(len(items), description, enabled=progress, min_total=50)
    results = []
    try:
        with managed_executor(executor) as pool:
            if pool is None:
                for item in items:
                    results.append(function(item))
                    bar.update()
            else:
                futures = [pool.submit(function, item) for item in items]
                for future in futures:
                    results.append(future.result())
                    bar.update()
    finally:
        bar.close()
    return results
