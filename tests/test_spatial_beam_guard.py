"""The deflection guard of the spatial beam: a diverging run of a SpatialModel with a SpatialBeam stops with a
SimulationError naming time and beam, keeping the partial result, on every time path (RK4, solve_ivp, DT-TMM,
generated RK4).

The model: a free hub (revolute about z) carrying a 10 m KRB beam spinning at 8 rad/s, above its first bending
frequency omega_1 = 3.80 rad/s.  Without geometric stiffening the centrifugal softening makes the in-plane
bending unstable (the deflection grows without bound); with it the deflection stays small.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import SimulationError

PATHS = [dict(method="rk4", dt=0.01), dict(method="RK45", dt=0.01), dict(method="newmark", dt=0.01),
         dict(method="rk4", dt=0.01, compiled=True)]


def spinner(stiffening: bool) -> sp.SpatialModel:
    beam = sp.SpatialBeam("arm", length=10.0, mass_per_length=1.2, bending_stiffness_y=1.4e4,
                          bending_stiffness_z=1.4e4, n_modes_y=2, n_modes_z=1, geometric_stiffening=stiffening)
    return sp.SpatialModel("spinner", [beam, sp.Revolute(name="hub", parent=None, child="arm",
                                                         axis=(0.0, 0.0, 1.0))])


def run(model: sp.SpatialModel, t_final: float, path: dict):
    return ctmm.simulate(model, t_final, x0={"arm.qy1": 0.01}, v0={"hub.angle_rate": 8.0}, **path)


@pytest.mark.parametrize("path", PATHS, ids=lambda p: p["method"] + ("-compiled" if p.get("compiled") else ""))
def test_diverging_spatial_beam_stops_with_time_beam_and_partial_result(path):
    with pytest.raises(SimulationError) as caught:
        run(spinner(False), 2.0, path)
    error = caught.value
    assert error.element == "arm"
    assert "arm" in str(error) and "exceeds its length 10 m" in str(error)
    assert 0.0 < error.time < 2.0
    partial = error.partial_result
    assert partial is not None and partial.time[-1] < error.time
    first = np.abs(np.asarray(partial["arm.qy1"]))
    assert first[-1] > 100 * first[0]          # the run really diverged before the guard stopped it


@pytest.mark.parametrize("path", PATHS[:1] + PATHS[2:3], ids=["rk4", "newmark"])
def test_stiffened_spinner_runs_through(path):
    result = run(spinner(True), 2.0, path)
    assert result.time[-1] == pytest.approx(2.0)
    assert np.max(np.abs(np.asarray(result["arm.qy1"]))) < 1.0
