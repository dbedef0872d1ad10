"""parallel_map: fail fast on a task that raises; keep results when a worker process dies."""
from __future__ import annotations

import os
import time

import pytest

from ctmm.errors import ModelError
from ctmm.executors import WorkerLostError, managed_executor, parallel_map
from ctmm.sweeps import parallel_map as sweeps_parallel_map


def _square_or_fail(x: int) -> int:
    if x == 3:
        raise ZeroDivisionError("task 3 failed")
    time.sleep(0.05)
    return x * x


def _held_or_fail(argument: tuple[int, str]) -> int:
    """Task 0 waits until the test writes ``<folder>/release`` (at most 60 s) and then writes ``<folder>/done``;
    task 3 fails at once; the others return."""
    x, folder = argument
    if x == 3:
        raise ZeroDivisionError("task 3 failed")
    if x == 0:
        deadline = time.monotonic() + 60.0
        while not os.path.exists(os.path.join(folder, "release")) and time.monotonic() < deadline:
            time.sleep(0.01)
        open(os.path.join(folder, "done"), "w").close()
    return x * x


def _square(x: int) -> int:
    return x * x


def _die_once(argument: tuple[int, str]) -> int:
    """Kill the worker process the first time item 2 is computed (marker file), then succeed."""
    x, marker = argument
    if x == 2 and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(13)
    time.sleep(0.05)
    return x * x


def _always_die(x: int) -> int:
    if x == 2:
        os._exit(13)
    return x * x


def test_sweeps_reexports_the_executor_tools():
    assert sweeps_parallel_map is parallel_map


@pytest.mark.parametrize("executor", [None, "threads", "processes"])
def test_results_in_input_order(executor):
    assert parallel_map(_square, range(7), executor=executor) == [x * x for x in range(7)]


@pytest.mark.parametrize("executor", ["threads", "processes"])
def test_failing_task_is_reported_when_it_fails(executor, tmp_path):
    """Task 0 is held until the test releases it; task 3 fails at once.  The failure must reach the caller while
    task 0 is still held: waiting for the results in input order would report it only after task 0 (which then
    writes its ``done`` marker, after a 60 s hold).  Ordered by events, not timed."""
    with pytest.raises(ZeroDivisionError, match="task 3 failed") as info:
        parallel_map(_held_or_fail, [(x, str(tmp_path)) for x in range(8)], executor=executor,
                     description="test sweep")
    assert not (tmp_path / "done").exists(), "the failure was reported only after the held task 0 finished"
    (tmp_path / "release").touch()
    assert any("item 3 (" in note for note in info.value.__notes__)


def test_failing_task_sequential_names_the_item():
    with pytest.raises(ZeroDivisionError) as info:
        parallel_map(_square_or_fail, [3])
    assert "item 0 (3)" in info.value.__notes__[0]


def test_dead_worker_is_retried_in_a_fresh_pool(tmp_path):
    marker = str(tmp_path / "died")
    results = parallel_map(_die_once, [(x, marker) for x in range(8)], executor="processes")
    assert os.path.exists(marker)                 # the worker really died once
    assert results == [x * x for x in range(8)]


def test_dead_worker_keeps_finished_results_when_retries_run_out():
    with pytest.raises(WorkerLostError) as info:
        parallel_map(_always_die, range(6), executor="processes", retries=1)
    error = info.value
    assert 2 in error.lost_indices
    assert len(error.partial_result) == 6
    for index, value in enumerate(error.partial_result):
        assert value == (None if index in error.lost_indices else index * index)


def test_retries_and_executor_are_validated():
    with pytest.raises(ModelError, match="retries"):
        parallel_map(_square, [1], retries=-1)
    with pytest.raises(ModelError, match="executor"):
        with managed_executor("gpu"):
            pass
