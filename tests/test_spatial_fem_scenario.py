"""The spatial_fem_chain scenario (issue 16, docs/mixed.md §7) runs headless in quick mode and meets its bounds."""
from __future__ import annotations

import json


def test_spatial_fem_chain_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("spatial_fem_chain")
    json.dumps(summary)
    assert (tmp_path / "spatial_fem_chain.png").stat().st_size > 1000
    for figure in summary["accuracy"]:
        assert figure["passed"], figure
    assert summary["accuracy"][0]["value"] < 1e-12              # same integrator: the coupling to round-off
    assert summary["connected_point_error_m"] < 1e-12
    assert summary["largest_node_displacement_m"] > 1e-3         # the beam does deform
    assert summary["newmark_error_vs_reference_half_step"] < 1e-4
    for key in ("wall_time_s", "newmark_wall_time_s", "reference_rk4_wall_time_s"):
        assert summary[key] > 0
