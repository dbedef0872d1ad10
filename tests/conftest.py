"""Shared pytest configuration: headless plotting and the repository root on sys.path."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# Generated kernels are built at -O0 in the tests (ctmm.codegen.effective_flags): the same numbers, ~3x less gcc time
# on straight-line code, and each test runs its kernels briefly.  CI starts from a cold kernel cache, where gcc was
# ~10 of the suite's 42 CPU-minutes at the kernels' own -O1/-O2.  Set CTMM_OPTIMIZATION_LEVEL empty to test the
# kernels' own flags (tests/test_codegen.py builds one kernel both ways and compares the numbers).
os.environ.setdefault("CTMM_OPTIMIZATION_LEVEL", "0")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def check_quick_run(name: str, summary: dict, folder: Path) -> None:
    """The contract of every scenario's quick run: the JSON written names the scenario and its wall time, its
    accuracy figures (each with unit, definition and bound source) are finite and within their bounds, the run
    passed, and the folder holds exactly the figures it lists (each a real image) and the JSON."""
    import json
    import math

    data = json.loads((folder / f"{name}.json").read_text())
    assert data["scenario"] == name
    assert "wall_time_s" in data, f"{name}: summary lacks 'wall_time_s'"
    assert data["accuracy"] == summary["accuracy"] and len(data["accuracy"]) >= 1
    for figure in data["accuracy"]:
        label = f"{name}: {figure['name']}"
        assert figure["unit"] and figure["definition"] and figure["bound_source"], label
        assert math.isfinite(figure["value"]), label
        assert figure["value"] <= figure["bound"], \
            f"{label} = {figure['value']:.3g} {figure['unit']} exceeds its bound {figure['bound']:.3g}"
    assert data["passed"] is True
    assert data["figures"], f"{name}: no figure written"
    for figure in data["figures"]:
        assert (folder / figure).stat().st_size > 1000
    assert sorted(p.name for p in folder.iterdir()) == sorted(data["figures"] + [f"{name}.json"])


@pytest.fixture(scope="session")
def quick_scenario(tmp_path_factory):
    """``quick_scenario(name) -> (summary, folder)``: ``ctmm.scenario.run_scenario(name, folder, quick=True)`` run
    once per test session and name, checked against the contract of every quick run (:func:`check_quick_run`)
    on every call.  Several test files check the same quick run from different sides; as xdist runs files on
    different workers, a scenario's quick run belongs to one test (``tests/test_scenarios.py`` for those without a
    test of their own, ``QUICK_RUN_OWNERS`` there for the others) so that it runs once per suite.  The summary is a
    deep copy per call, the folder is the run's own."""
    import copy

    from ctmm import scenario

    done: dict = {}

    def run(name: str):
        if name not in done:
            folder = tmp_path_factory.mktemp(f"quick_{name}")
            done[name] = (scenario.run_scenario(name, folder, quick=True), folder)
        summary, folder = done[name]
        check_quick_run(name, summary, folder)
        return copy.deepcopy(summary), folder

    return run
