"""The planar scenario reproducing FORMULAS c07 runs headless and meets its sourced numbers."""
from __future__ import annotations

import json

import numpy as np
import pytest


def test_pendulum_chain_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("pendulum_chain")
    json.dumps(summary)
    assert (tmp_path / "pendulum_chain.png").stat().st_size > 1000
    for key in ("accuracy", "wall_time_s", "reference_wall_time_s", "energy_drift"):
        assert key in summary
    (figure,) = summary["accuracy"]
    assert figure["unit"] == "rad" and figure["value"] <= figure["bound"] == 1e-6
    assert figure["value"] < 1e-7
    # FORMULAS 3.5 (check c07): Newmark errors 1.67e-3, 4.19e-4, 1.05e-4 rad at T = 1 s
    for entry in summary["newmark_ladder_at_1s"].values():
        assert entry["error_rad"] == pytest.approx(entry["published_rad"], rel=0.01)
        assert entry["newton_iterations_mean"] <= 3.0
    assert np.isfinite(summary["energy_drift"]["rk4_J"])
