"""Every scenario runs headless in its quick form, writes PNG + JSON, and meets its accuracy bounds."""
from __future__ import annotations

import json
import math

import pytest

from ctmm import scenario

NAMES = sorted(scenario.available())


def test_no_scenario_module_is_broken():
    assert scenario.broken() == {}


@pytest.mark.parametrize("name", NAMES)
def test_scenario_quick_run(name, quick_scenario):
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
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
        assert (tmp_path / figure).stat().st_size > 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(data["figures"] + [f"{name}.json"])


def test_cli_list_and_run(tmp_path, capsys):
    from ctmm.cli import main

    assert main(["list"]) == 0
    assert "table7_1" in capsys.readouterr().out
    assert main(["run", "table7_1", "--quick", "--output", str(tmp_path)]) == 0
    line = capsys.readouterr().out
    assert line.startswith("table7_1 | linear MSTMM error vs exact: error ")
    assert "m (bound 1e-09)" in line
    assert main(["run", "nope", "--output", str(tmp_path)]) == 2
