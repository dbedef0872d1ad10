"""Shared pytest configuration: headless plotting and the repository root on sys.path."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def quick_scenario(tmp_path_factory):
    """``quick_scenario(name) -> (summary, folder)``: ``ctmm.scenario.run_scenario(name, folder, quick=True)`` run
    once per test session and name (several test files check the same quick run from different sides; running it
    once keeps the suite within its time budget).  The summary is a deep copy per call, the folder is the run's own."""
    import copy

    from ctmm import scenario

    done: dict = {}

    def run(name: str):
        if name not in done:
            folder = tmp_path_factory.mktemp(f"quick_{name}")
            done[name] = (scenario.run_scenario(name, folder, quick=True), folder)
        summary, folder = done[name]
        return copy.deepcopy(summary), folder

    return run
