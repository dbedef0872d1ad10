"""Every scenario runs headless in its quick form, writes PNG + JSON, and meets its accuracy bounds."""
from __future__ import annotations

from pathlib import Path

import pytest

from ctmm import scenario

#: Scenarios whose quick run a test of their own checks (through the ``quick_scenario`` fixture, which applies the
#: contract of every quick run, ``conftest.check_quick_run``): the quick run is not repeated here, as xdist may run
#: that file on another worker (each quick run once per suite).
QUICK_RUN_OWNERS: dict[str, str] = {
    "flexible_manipulator_3d": "test_flexible_manipulator_3d.py",
    "spatial_chain": "test_scenarios_spatial.py",
    "branch_system": "test_scenarios_spatial.py",
    "spatial_elastic_hinge_control": "test_scenarios_spatial.py",
    "spatial_robot_arm": "test_scenarios_spatial.py",
    "spatial_hub_beam": "test_scenarios_spatial.py",
    "spatial_hub_beam_tip_body": "test_scenarios_spatial.py",
    "spatial_spin_up": "test_scenarios_spatial.py",
    "pendulum_chain": "test_planar_scenarios.py",
    "finite_segments": "test_flexible_scenarios.py",
    "fem_chain": "test_fem_scenario.py",
    "spatial_fem_chain": "test_spatial_fem_scenario.py",
    "particle_chain": "test_fem_particle_chain.py",
    "particle_net": "test_fem_particle_net_scenario.py",
    "plate_chain": "test_fem_plate.py",
    "rotary_base_segments": "test_rotary_base_segments.py",
}
NAMES = sorted(set(scenario.available()) - set(QUICK_RUN_OWNERS))


def test_no_scenario_module_is_broken():
    assert scenario.broken() == {}


def test_quick_run_owners_run_their_scenario_through_the_checked_fixture():
    """Each scenario left out of the quick runs here is a real scenario whose owning test file runs it through
    ``quick_scenario`` (so the contract of every quick run still applies to it)."""
    assert set(QUICK_RUN_OWNERS) <= set(scenario.available())
    for name, file in QUICK_RUN_OWNERS.items():
        text = (Path(__file__).parent / file).read_text(encoding="utf-8")
        assert "quick_scenario(" in text and f'"{name}"' in text, (name, file)
        assert "run_scenario(" not in text and ".run(tmp_path" not in text, file   # no second quick run


@pytest.mark.parametrize("name", NAMES)
def test_scenario_quick_run(name, quick_scenario):
    quick_scenario(name)          # the fixture checks the contract of every quick run (conftest.check_quick_run)


def test_cli_list_and_run(tmp_path, capsys):
    from ctmm.cli import main

    assert main(["list"]) == 0
    assert "table7_1" in capsys.readouterr().out
    assert main(["run", "table7_1", "--quick", "--output", str(tmp_path)]) == 0
    line = capsys.readouterr().out
    assert line.startswith("table7_1 | linear MSTMM error vs exact: error ")
    assert "m (bound 1e-09)" in line
    assert main(["run", "nope", "--output", str(tmp_path)]) == 2
