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


def test_controlled_chain_parameter_notes_match_the_chain():
    """The numbers in the controlled-chain parameter table (scenarios/controlled_chain_common.py) are those of
    the chain ground -[K,C]- m2 -[K,C]- m4 -[K,C]- m6 -free, computed here from its global M, C, K: first natural
    frequency, modal damping range (C = K / 10 gives zeta_k = omega_k / 20) and delay margin of u = -Ka x6(t - tau)
    on m2 (the crossover of |Ka G_62(i w)| = 1 with the smallest positive delay)."""
    import re

    import numpy as np

    from scenarios import controlled_chain_common as common      # the repository folder (ctmm.scenarios installed)

    m, k, c = common.MASS, common.STIFFNESS, common.DAMPING
    shape = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    mass, stiffness, damping = m * np.eye(3), k * shape, c * shape
    state = np.block([[np.zeros((3, 3)), np.eye(3)],
                      [-np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)]])
    roots = np.linalg.eigvals(state)
    roots = roots[roots.imag > 0]
    omega_n, zeta = np.abs(roots), -roots.real / np.abs(roots)
    doc = common.__doc__
    first = float(re.search(r"first natural frequency ([\d.]+) rad/s", doc).group(1))
    assert first == pytest.approx(omega_n.min(), abs=0.005)
    low, high = map(float, re.search(r"modal damping ([\d.]+)-([\d.]+) %", doc).groups())
    assert (low, high) == pytest.approx((100 * zeta.min(), 100 * zeta.max()), abs=0.05)

    def loop(w):
        return common.KA * np.linalg.solve(-w * w * mass + 1j * w * damping + stiffness, np.eye(3))[2, 0]

    grid = np.linspace(0.05, 20.0, 40001)
    magnitude = np.abs([loop(w) for w in grid]) - 1.0
    delays = []
    for i in np.nonzero(np.diff(np.sign(magnitude)))[0]:
        a, b = grid[i], grid[i + 1]
        for _ in range(60):                                  # bisection on |L(i w)| = 1
            mid = 0.5 * (a + b)
            a, b = (mid, b) if np.sign(abs(loop(mid)) - 1.0) == np.sign(magnitude[i]) else (a, mid)
        w = 0.5 * (a + b)
        delays.append(((np.angle(loop(w)) + np.pi) % (2 * np.pi)) / w)
    margin = float(re.search(r"half the delay margin \(([\d.]+) s\)", doc).group(1))
    assert margin == pytest.approx(min(delays), abs=5e-4)
    assert common.DELAY == pytest.approx(margin / 2, abs=5e-3)
