"""Every scenario runs headless in its quick form, writes PNG + JSON, and reports its error."""
from __future__ import annotations

import json
import math

import pytest

from ctmm import scenario

NAMES = sorted(scenario.available())


def test_no_scenario_module_is_broken():
    assert scenario.broken() == {}


@pytest.mark.parametrize("name", NAMES)
def test_scenario_quick_run(name, tmp_path):
    summary = scenario.run_scenario(name, tmp_path, quick=True)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["scenario"] == name
    for key in ("max_error", "wall_time_s"):
        assert key in data, f"{name}: summary lacks {key!r}"
    assert isinstance(summary["max_error"], float) and math.isfinite(summary["max_error"])
    assert "error_definition" in data
    for figure in data.get("figures", []):
        assert (tmp_path / figure).stat().st_size > 1000


def test_cli_list_and_run(tmp_path, capsys):
    from ctmm.cli import main

    assert main(["list"]) == 0
    assert "table7_1" in capsys.readouterr().out
    assert main(["run", "table7_1", "--quick", "--output", str(tmp_path)]) == 0
    line = capsys.readouterr().out
    assert line.startswith("table7_1 | max error")
    assert main(["run", "nope", "--output", str(tmp_path)]) == 2
