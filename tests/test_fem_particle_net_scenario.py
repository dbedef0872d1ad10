"""The particle_net scenario (seed 001 Example 9.1) runs headless in quick mode and meets its bound."""
from __future__ import annotations

import json


def test_particle_net_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("particle_net")
    json.dumps(summary)
    assert (tmp_path / "particle_net.png").stat().st_size > 1000
    (figure,) = summary["accuracy"]
    assert figure["passed"] and figure["value"] < 1e-12
    assert summary["energy_drift_relative"] < 1e-9                # undamped: RK4 error only
    assert summary["energy_vs_global_model_relative"] < 1e-12
    assert 1e-3 < summary["largest_particle_displacement_m"] < 0.05
