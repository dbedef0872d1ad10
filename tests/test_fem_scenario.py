"""The fem_chain scenario (seed 001 §9.3) runs headless in quick mode and meets its bounds."""
from __future__ import annotations

import json


def test_fem_chain_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("fem_chain")
    json.dumps(summary)
    assert (tmp_path / "fem_chain.png").stat().st_size > 1000
    for figure in summary["accuracy"]:
        assert figure["passed"], figure
    assert summary["accuracy"][0]["value"] < 1e-12              # same integrator: the coupling to round-off
    assert summary["connected_point_error_m"] < 1e-12
    assert summary["rk4_angle_error_vs_dop853_rad"] < 1e-7
    assert summary["newmark_angle_error_vs_dop853_rad"] < 1e-5
    for key in ("wall_time_s", "newmark_wall_time_s", "reference_rk4_wall_time_s"):
        assert summary[key] > 0
