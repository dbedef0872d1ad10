"""Generated DT-TMM schemes of spatial kinematic loop models (ctmm.compiled_spatial_loop_schemes, issue 13):
``ctmm.simulate(loop_model, ..., method=<scheme>, compiled=True)``.

Checks: equal to the numpy scheme with projection (ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme) to
round-off; against the Newton-Euler DAE at order two with tests/test_loop_scheme_projection.py's bounds (the R-U-S-R
four-bar, spherical cut), with a held joint input too (the DAE with the torque); divergence_bound where the numpy path
stops; failures and refusals by name.
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
        assert run.cut_moment.shape == plain.cut_moment.shape and not np.any(run.cut_moment)     # spherical, no law
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
    the time, the cut and the partial result; the RK4 with joint inputs alone is refused by name."""
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
    with pytest.raises(ModelError, match="compiled=True .* not the RK4 with joint inputs alone"):
        ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="rk4", compiled=True, inputs={"h1.torque": 0.1})


def _dae_rotation_error(loop, run, torques) -> float:
    """Largest difference of the bodies' rotation matrices [rad] against the Newton-Euler DAE
    (:mod:`ctmm.reference.spatial_loop_dae`, no ctmm.spatial code) started from the run's first state, with the world
    moments ``torques`` ``{body index: (3,)}`` [N m] applied (a function ``torques(t, y)``: a control law)."""
    from spatial_loop_helpers import dae_of, poses

    dae = dae_of(loop, 10.0)
    t, Y = dae.simulate(dae.state(*poses(loop, run.q[0], run.v[0])), run.t, torques=torques)
    return max(max(np.abs(a - b).max() for a, b in zip(poses(loop, run.q[k], run.v[k])[1], dae.rotations(Y[k])))
               for k in range(len(t)))


def test_held_joint_input_equals_numpy_and_converges_to_the_dae(four_bar):
    """A held crank torque of 0.5 N m (``inputs={"h1.torque": 0.5}``; the crank's hinge axis is world x): Newmark at 4 /
    2 ms over 0.016 s = the numpy scheme with the same input to 1e-12 (coordinates, velocities, cut forces); rotations
    against the Newton-Euler DAE with the moment (0.5, 0, 0) N m on the crank at order two (the bounds of the run without
    input); the torque moves the run (not a no-op) and ``ctmm.simulate`` routes it here."""
    from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, simulate_spatial_loop_scheme_generated

    loop, q, v = four_bar
    inputs, torque = {"h1.torque": 0.5}, {0: np.array([0.5, 0.0, 0.0])}
    kernel = CompiledSpatialLoopScheme(loop, "newmark")
    errors = []
    for dt in (4e-3, 2e-3):
        run, _ = simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.016, dt=dt, scheme="newmark",
                                                        inputs=inputs, compiled=kernel)
        plain, _ = simulate_spatial_loop_scheme(loop, q, v, t_final=0.016, dt=dt, scheme="newmark", inputs=inputs)
        free, _ = simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.016, dt=dt, scheme="newmark",
                                                         compiled=kernel)
        assert np.abs(run.q - plain.q).max() <= 1e-12 and np.abs(run.v - plain.v).max() <= 1e-12
        assert np.abs(run.cut_force - plain.cut_force).max() <= 1e-12 * max(1.0, np.abs(plain.cut_force).max())
        assert np.abs(run.q - free.q).max() > 1e-4 and run.drift.max() <= 1e-12
        errors.append(_dae_rotation_error(loop, run, torque))
    assert errors[1] < 3e-6 and 3.3 < errors[0] / errors[1] < 4.7
    result = ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark", compiled=True, inputs=inputs)
    reference = ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark", inputs=inputs)
    assert result.info["compiled"] is True
    for name in ("h1.angle", "s3.force_z", "drift"):
        assert np.abs(result[name] - reference[name]).max() <= 1e-12 * max(1.0, np.abs(reference[name]).max()), name
    with pytest.raises(ModelError, match="input 'h1.torque' is a function of time"):
        ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark", compiled=True, inputs={"h1.torque": np.sin})
    with pytest.raises(ModelError, match="unknown spatial input 'h4.torque'"):
        simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.016, dt=4e-3, scheme="newmark",
                                               inputs={"h4.torque": 1.0}, compiled=kernel)


def test_divergence_bound_stops_where_the_numpy_path_stops(four_bar):
    """``divergence_bound=0.05``: the crank swings 0.1 rad past its start within 0.2 s; the generated run stops at
    the step the numpy scheme stops at (stored every 5th step: the failing interval is run again step by step), that
    is the first step of an unbounded run whose state moved beyond the bound (read off the run itself), with the
    states before it; a bound the run stays within changes nothing."""
    loop, q, v = four_bar
    options = dict(x0=q, v0=v, method="newmark", inputs={"h1.torque": 0.5})
    free = ctmm.simulate(loop, 0.2, 4e-3, compiled=True, **options)
    names = list(loop.tree.coordinates) + list(loop.tree.velocities)
    moved = np.max(np.abs(np.array([free[n] - free[n][0] for n in names])), axis=0)
    first = int(np.flatnonzero(moved > 0.05)[0])
    with pytest.raises(SimulationError, match="beyond divergence_bound = 0.05") as generated:
        ctmm.simulate(loop, 0.2, 4e-3, compiled=True, store_every=5, divergence_bound=0.05, **options)
    with pytest.raises(SimulationError, match="beyond divergence_bound = 0.05") as numpy_path:
        ctmm.simulate(loop, 0.2, 4e-3, store_every=5, divergence_bound=0.05, **options)
    assert generated.value.time == pytest.approx(numpy_path.value.time, abs=1e-12)
    assert generated.value.time == pytest.approx(free.time[first], abs=1e-12)
    assert generated.value.partial_result.time[-1] < generated.value.time
    bounded = ctmm.simulate(loop, 0.2, 4e-3, compiled=True, divergence_bound=100.0, **options)
    assert np.array_equal(bounded["h1.angle"], free["h1.angle"])
