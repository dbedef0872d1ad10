"""Executors for sweeps: sequential, thread pool, process pool or any ``Executor``.

Every sweep in ctmm takes ``executor=``: ``None`` (sequential, the default), ``"threads"`` or
``"processes"`` (a pool of ``os.cpu_count()`` workers created for the call and shut down after
it), or any object with the :class:`concurrent.futures.Executor` interface -- including
``distributed.Client(...).get_executor()`` of dask.distributed -- which is used as given and not
shut down.  Work is handed out as picklable callables and arguments (module-level functions),
results come back in input order.

Failures (:func:`parallel_map`)
-------------------------------
* A task that raises is reported as soon as it fails, not when the sweep ends: the work not yet
  started is cancelled and the task's own exception is raised, with a note naming the index and
  value of the item that failed.  A pool created here is shut down without waiting for the tasks
  still running.
* A worker process that dies (``os._exit``, a crash in native code, the out-of-memory killer)
  breaks a process pool (:class:`~concurrent.futures.process.BrokenProcessPool`): every result
  finished before is kept, and the items lost with the pool are run again in a fresh process pool
  (at most ``retries`` times).  If they are still lost, :class:`WorkerLostError` is raised; it
  carries the finished results (``partial_result``) and the indices of the lost items.
"""
from __future__ import annotations

import os
import pickle
from concurrent.futures import (FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor,
                                ThreadPoolExecutor, wait)
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator

from . import validation
from .errors import ModelError, SimulationError
from .progress import progress_bar

__all__ = ["WorkerLostError", "is_executor", "managed_executor", "executor_workers", "parallel_map"]

_KINDS = {"threads": ThreadPoolExecutor, "processes": ProcessPoolExecutor}


class WorkerLostError(SimulationError):
    """Worker processes died and some items of a sweep could not be computed.

    Attributes
    ----------
    partial_result : list
        One entry per item in input order: the finished result, or ``None`` for a lost item.
    lost_indices : list of int
        Indices (into the items) of the results that are missing.
    """

    def __init__(self, message: str, *, partial_result: list, lost_indices: list[int]) -> None:
        super().__init__(message, partial_result=partial_result)
        self.lost_indices = lost_indices


def is_executor(value: Any) -> bool:
    """True for objects usable as an executor (a ``submit`` and a ``map`` method)."""
    return isinstance(value, Executor) or (callable(getattr(value, "submit", None))
                                           and callable(getattr(value, "map", None)))


def _bad_executor(executor: Any) -> ModelError:
    return ModelError(f"executor must be None, 'threads', 'processes' or an Executor, got {executor!r}")


@contextmanager
def managed_executor(executor: Any) -> Iterator[Any]:
    """Resolve an ``executor`` option; pools created here are shut down on exit.

    On normal exit a pool created here waits for its tasks; when the block raises, it is shut down
    at once (pending tasks cancelled, running ones not waited for) so the error reaches the caller
    without delay.
    """
    if executor is None:
        yield None
    elif isinstance(executor, str):
        if executor not in _KINDS:
            raise _bad_executor(executor)
        pool = _KINDS[executor](max_workers=os.cpu_count() or 2)
        try:
            yield pool
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    elif is_executor(executor):
        yield executor
    else:
        raise _bad_executor(executor)


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


def _describe(index: int, item: Any) -> str:
    text = repr(item)
    if len(text) > 200:
        text = text[:197] + "..."
    return f"while computing item {index} ({text})"


def _completion_order(futures: dict[Future, int]) -> Iterator[Future]:
    """Futures as they finish (standard futures) or in submission order (other future types)."""
    if not all(isinstance(f, Future) for f in futures):
        yield from futures
        return
    remaining = set(futures)
    while remaining:
        done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
        yield from sorted(done, key=futures.__getitem__)


def _run_round(pool: Any, function: Callable[[Any], Any], items: list, indices: list[int],
               results: dict[int, Any], bar: Any, description: str) -> list[int]:
    """Run ``items[indices]`` on ``pool`` into ``results``; return the indices lost to a broken pool."""
    futures: dict[Future, int] = {}
    lost = []
    try:
        for position, index in enumerate(indices):
            try:
                futures[pool.submit(function, items[index])] = index
            except BrokenProcessPool:
                lost.extend(indices[position:])
                break
        for future in _completion_order(futures):
            index = futures[future]
            try:
                results[index] = future.result()
            except BrokenProcessPool:
                lost.append(index)
                continue
            except Exception as exc:
                exc.add_note(f"{description}: {_describe(index, items[index])}")
                raise
            bar.update()
    finally:
        for future in futures:
            future.cancel()
    return sorted(lost)


def parallel_map(function: Callable[[Any], Any], items: Iterable[Any], *, executor: Any = None,
                 progress: bool | None = None, description: str = "sweep", retries: int = 2) -> list:
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
        Label of the progress bar and of error notes.
    retries : int
        How many times items lost with a dead worker process are run again in a fresh process
        pool (default 2; 0: never).

    Raises
    ------
    Exception
        The first exception raised by ``function``, as soon as it is raised, with a note naming
        the item.
    WorkerLostError
        Worker processes died and items were still lost after ``retries`` fresh pools; it carries
        every finished result.
    """
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise ModelError(f"retries must be an integer >= 0, got {retries!r}")
    if not callable(function):
        raise ModelError(f"function must be callable, got {function!r}")
    progress = validation.flag("progress", progress, optional=True)
    if not isinstance(description, str):
        raise ModelError(f"description must be a str, got {description!r}")
    if isinstance(items, (str, bytes)) or not hasattr(items, "__iter__"):
        raise ModelError(f"items must be an iterable of arguments, got {items!r}")
    if (isinstance(executor, str) and executor == "processes") or isinstance(executor, ProcessPoolExecutor):
        try:
            pickle.dumps(function)
        except Exception as exc:  # noqa: BLE001 - any pickling failure means the same
            raise ModelError(f"function {function!r} cannot be sent to worker processes ({exc}); use a "
                             "module-level function (lambdas and local functions are not picklable), or "
                             "executor='threads'") from None
    items = list(items)
    bar = progress_bar(len(items), description, enabled=progress, min_total=50)
    try:
        with managed_executor(executor) as pool:
            if pool is None:
                return _sequential(function, items, bar, description)
            results: dict[int, Any] = {}
            lost = _run_round(pool, function, items, list(range(len(items))), results, bar, description)
            workers = executor_workers(pool)
        for _ in range(retries):
            if not lost:
                break
            fresh = ProcessPoolExecutor(max_workers=workers)
            try:
                lost = _run_round(fresh, function, items, lost, results, bar, description)
            except BaseException:
                fresh.shutdown(wait=False, cancel_futures=True)
                raise
            fresh.shutdown(wait=not lost, cancel_futures=True)
    finally:
        bar.close()
    if lost:
        partial = [results.get(i) for i in range(len(items))]
        raise WorkerLostError(
            f"{description}: a worker process died (BrokenProcessPool) and {len(lost)} of {len(items)} "
            f"items were lost after {retries} retries in a fresh pool (indices {lost[:20]}"
            f"{' ...' if len(lost) > 20 else ''}); the {len(items) - len(lost)} finished results are "
            "in .partial_result (None where lost)", partial_result=partial, lost_indices=lost)
    return [results[i] for i in range(len(items))]


def _sequential(function: Callable[[Any], Any], items: list, bar: Any, description: str) -> list:
    results = []
    for index, item in enumerate(items):
        try:
            results.append(function(item))
        except Exception as exc:
            exc.add_note(f"{description}: {_describe(index, item)}")
            raise
        bar.update()
    return results
