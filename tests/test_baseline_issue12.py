"""The issue 12 baseline (``benchmarks/baseline_issue12.py``): its stored numbers and its comparison rule."""
from __future__ import annotations

import copy
import importlib
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def baseline_module():
    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))
    return importlib.import_module("baseline_issue12")


@pytest.fixture(scope="module")
def stored(baseline_module):
    return json.loads(baseline_module.RESULTS.read_text())


def test_stored_baseline_is_complete(stored):
    cases = stored["scenarios"]["cases"]
    assert cases and all(case["passed"] and case["accuracy"] for case in cases.values())
    for case in cases.values():
        for figure in case["accuracy"]:
            assert figure["passed"] and figure["value"] <= figure["bound"], figure
    timings = stored["timings"]["cases"]
    benchmarks = {path.name for path in (ROOT / "benchmarks").glob("*.py")} - {"baseline_issue12.py"}
    assert {Path(case["benchmark"]).name for case in timings.values()} == benchmarks
    for key, case in timings.items():
        assert 0 < case["cpu_s_per_unit"] and 0 < case["wall_s_per_unit"] and case["repeats"] == 5, key
    assert len(stored["scenarios"]["load_average_before"]) == 3


def _copy_with(stored, edit):
    data = copy.deepcopy(stored)
    edit(data)
    return data


def test_compare_accepts_the_baseline_itself_and_small_changes(baseline_module, stored):
    assert baseline_module.compare(stored, stored) == []

    def a_little_slower(data):
        for case in data["timings"]["cases"].values():
            case["cpu_s_per_unit"] *= 1.09
    assert baseline_module.compare(stored, _copy_with(stored, a_little_slower)) == []


def test_compare_names_every_broken_rule(baseline_module, stored):
    scenario = next(iter(stored["scenarios"]["cases"]))
    timing, other = list(stored["timings"]["cases"])[:2]
    figure = stored["scenarios"]["cases"][scenario]["accuracy"][0]["name"]

    def break_rules(data):
        bad = data["scenarios"]["cases"][scenario]["accuracy"][0]
        bad.update(value=2 * bad["bound"], passed=False)
        del data["scenarios"]["cases"][list(data["scenarios"]["cases"])[-1]]
        data["timings"]["cases"][timing]["cpu_s_per_unit"] *= 1.2
        del data["timings"]["cases"][other]
    problems = baseline_module.compare(stored, _copy_with(stored, break_rules))
    assert len(problems) == 4, problems
    assert any(scenario in p and figure in p and "exceeds its bound" in p for p in problems)
    assert any(p.endswith(": missing") and p.startswith("scenario ") for p in problems)
    assert any(timing in p and "+20 %" in p for p in problems)
    assert f"timing {other}: missing" in problems
