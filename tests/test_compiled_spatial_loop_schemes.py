"""Generated DT-TMM schemes of spatial kinematic loop models (ctmm.compiled_spatial_loop_schemes, issue 13):
``ctmm.simulate(loop_model, ..., method=<scheme>, compiled=True)``.

Checks: equal to the numpy scheme with projection (ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme) to
round-off; against the Newton-Euler DAE at order two with tests/test_loop_scheme_projection.py's bounds (the R-U-S-R
four-bar, spherical cut); failures and refusals by name.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_loop_scheme_projection import spatial_four_bar as four_bar  # noqa: F401 (a fixture)
from test_spatial_closed_loops import _dae_errors

import ctmm
from ctmm.errors import ModelError, SimulationError
from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme


def test_generated_scheme_equals_numpy_and_converges_to_the_dae(four_bar):
    """Newmark at 4 / 2 ms over 0.016 s (one kernel: the step is an input): = the numpy scheme with projection to
    1e-12 (coordinates, velocities, cut forces); rotations against the DAE at order two, the bounds of the numpy test
    (errors[1] < 3e-6, ratio in (3.3, 4.7)); drift at round-off after every step."""
    from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, simulate_spatial_loop_scheme_generated

    loop, q, v = four_bar
    method = "newmark"
    kernel = CompiledSpatialLoopScheme(loop, method)
    errors = []
    for dt in (4e-3, 2e-3):
        run, info = simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.016, dt=dt, scheme=method,
                                                           compiled=kernel)
        plain, _ = simulate_spatial_loop_scheme(loop, q, v, t_final=0.016, dt=dt, scheme=method)
        np.testing.assert_array_equal(run.t, plain.t)
        assert np.abs(run.q - plain.q).max() <= 1e-12 and np.abs(run.v - plain.v).max() <= 1e-12
        assert np.abs(run.cut_force - plain.cut_force).max() <= 1e-12 * max(1.0, np.abs(plain.cut_force).max())
        assert info["projection"] is True and info["max_drift_after_projection"] <= 1e-12
        assert run.drift.max() <= 1e-12 and run.method == f"dt-tmm-generated/{method}"
        errors.append(_dae_errors(loop, run)[0])
    assert errors[1] < 3e-6 and 3.3 < errors[0] / errors[1] < 4.7


@pytest.mark.parametrize("method", ["generalized_alpha", "houbolt"])
def test_simulate_routes_other_schemes_here(four_bar, method):
    """``ctmm.simulate(..., method=<scheme>, compiled=True)``: = the numpy scheme's result to 1e-12 (Houbolt with its
    earlier configurations from the projected states, as there)."""
    loop, q, v = four_bar
    result = ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method=method, compiled=True)
    plain = ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method=method)
    assert result.info["compiled"] is True
    for name in ("h1.angle", "s3.force_z", "drift"):
        assert np.abs(result[name] - plain[name]).max() <= 1e-12 * max(1.0, np.abs(plain[name]).max()), name


def test_failures_and_refusals_are_named(four_bar):
    """Ten times the rate at 20 ms: one Gauss-Newton step leaves the cut apart (the numpy test's case) -- stopped with
    the time, the cut and the partial result; joint inputs and divergence_bound are refused by name."""
    from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, simulate_spatial_loop_scheme_generated

    loop, q, v = four_bar
    one = CompiledSpatialLoopScheme(loop, "newmark", iterations=1)
    with pytest.raises(SimulationError, match="the projection onto the cut joints failed .* after 1 Gauss-Newton "
                                              "steps") as failure:
        simulate_spatial_loop_scheme_generated(loop, q, 10 * v, t_final=0.1, dt=0.02, scheme="newmark", compiled=one)
    assert failure.value.element == "s3" and failure.value.time == pytest.approx(0.02)
    assert failure.value.partial_result.t[-1] == 0.0
    with pytest.raises(ModelError, match="compiled must be a CompiledSpatialLoopScheme of this model with "
                                         "scheme=GeneralizedAlpha"):
        simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.1, dt=0.02, scheme="generalized_alpha",
                                               compiled=one)
    with pytest.raises(ModelError, match="compiled=True .* DT-TMM scheme .* not with joint inputs alone"):
        ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark", compiled=True, inputs={"h1.torque": 0.1})
    with pytest.raises(ModelError, match="divergence_bound"):
        ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark", compiled=True, divergence_bound=1.0)
