"""The rules every integrator of a kinematic loop model applies (ctmm.loop_integration, issues 12/16).

* A step too large for the loop: the numpy RK4 with projection (planar and spatial) now checks its own projection
  as the generated RK4 does (``max |Phi| <= PROJECTION_TOLERANCE`` after it) and stops with the same
  SimulationError: same time, same cut joint, same message, partial result up to the last good state (which equals
  the generated path's to round-off).  Before, the numpy path kept integrating a state off the cut joints.
* An initial state off the cut joints: one check and one message (the cut furthest off, |Phi| and |Phi'|, the
  arguments named) from every entry point.
* compiled=True refuses cut joints with a moment law, a torque or a drive (planar) and with a law, an actuation or
  a drive (spatial): the generated steps have no row for their load (they ignored them: 0.44 rad off the numpy run
  after 0.1 s on the planar four-bar below, 0.04 rad on the spatial revolute-cut pendulum).
"""
from __future__ import annotations

import re

import numpy as np
import pytest

import ctmm
from ctmm.compiled_kinematic_loops import simulate_kinematic_loops_generated
from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
from ctmm.errors import ModelError, SimulationError
from ctmm.loop_integration import CONSISTENCY_TOLERANCE, PROJECTION_TOLERANCE
from ctmm.nonlinear_laws import LinearLaw
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.scenarios.four_bar import mechanism, start
from ctmm.spatial.closed_loop_time import simulate_spatial_loops

FAILED = re.escape("the projection onto the cut joints failed (|Phi| = ") + r"(\d\.\d+e[-+]\d+)" + \
    re.escape(f" after 3 Gauss-Newton steps; allowed <= {PROJECTION_TOLERANCE:g}")


def _spatial_four_bar():
    from spatial_loop_helpers import rusr

    loop = rusr()
    return loop, loop.consistent_state({"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0}, keep=["h1"])


def _both_fail(numpy_run, generated_run):
    """The two SimulationErrors, checked to state the same failure."""
    with pytest.raises(SimulationError) as numpy_failure:
        numpy_run()
    with pytest.raises(SimulationError) as generated_failure:
        generated_run()
    found = [re.search(FAILED, str(failure.value)) for failure in (numpy_failure, generated_failure)]
    assert all(found), (str(numpy_failure.value), str(generated_failure.value))
    assert numpy_failure.value.time == generated_failure.value.time
    assert numpy_failure.value.element == generated_failure.value.element
    residuals = [float(match.group(1)) for match in found]
    assert min(residuals) > 1e3 * PROJECTION_TOLERANCE
    return numpy_failure.value, generated_failure.value


def test_a_planar_step_too_large_is_refused_alike_by_the_numpy_and_the_generated_rk4():
    loop = mechanism()
    q0, v0 = start(loop)
    numpy_error, generated_error = _both_fail(
        lambda: simulate_kinematic_loops(loop, q0, 10 * v0, t_final=2.0, dt=0.05),
        lambda: simulate_kinematic_loops_generated(loop, q0, 10 * v0, t_final=2.0, dt=0.05))
    assert numpy_error.time == pytest.approx(0.5) and numpy_error.element == "h3"
    partial, generated = numpy_error.partial_result, generated_error.partial_result
    assert partial.t[-1] == pytest.approx(0.45) and partial.q.shape == generated.q.shape == (10, 3)
    assert np.max(np.abs(partial.q - generated.q)) <= 1e-10          # the same good states before it
    run = simulate_kinematic_loops(loop, q0, 3 * v0, t_final=1.0, dt=0.05, projection=False)  # no projection, no check
    assert run.t[-1] == pytest.approx(1.0) and np.max(run.drift) > 1e-3


def test_a_spatial_step_too_large_is_refused_alike_by_the_numpy_and_the_generated_rk4():
    loop, (q, v) = _spatial_four_bar()
    numpy_error, generated_error = _both_fail(
        lambda: simulate_spatial_loops(loop, q, 30 * v, t_final=1.0, dt=0.05),
        lambda: simulate_spatial_kinematic_loops_generated(loop, q, 30 * v, t_final=1.0, dt=0.05))
    assert numpy_error.time == pytest.approx(0.05) and numpy_error.element == "s3"
    assert numpy_error.partial_result.t.tolist() == generated_error.partial_result.t.tolist() == [0.0]
    with pytest.raises(SimulationError, match=FAILED):                   # the verb's default path
        ctmm.simulate(loop, 1.0, 0.05, x0=q, v0=30 * v)


def test_normal_runs_stay_within_the_projection_tolerance():
    loop = mechanism()
    q0, v0 = start(loop)
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.1, dt=1e-3)
    assert run.t[-1] == pytest.approx(0.1) and np.max(run.drift) < 1e-12
    spatial, (q, v) = _spatial_four_bar()
    assert np.max(simulate_spatial_loops(spatial, q, v, t_final=0.02, dt=1e-3).drift) < 1e-12


def _message(model, q, v, names):
    phi, phi_dot = model.constraints(q, v)
    return re.escape(f"the initial state ({names}) violates the cut joints (|Phi| = {np.max(np.abs(phi)):.3e} m or "
                     f"rad, |Phi'| = {np.max(np.abs(phi_dot)):.3e} m/s or rad/s, furthest off at the cut ")


def test_one_initial_state_check_with_one_message_from_every_entry_point():
    loop = mechanism()
    q0, v0 = start(loop)
    bad = q0 + 0.1
    tail = re.escape(f"'h3'; allowed <= {CONSISTENCY_TOLERANCE:g}): start from KinematicLoopModel.consistent_state")
    for names, run in [("q0, qdot0", lambda: simulate_kinematic_loops(loop, bad, v0, t_final=0.01, dt=1e-3)),
                       ("x0, v0", lambda: ctmm.simulate(loop, 0.01, 1e-3, x0=bad, v0=v0)),
                       ("q0, v0", lambda: simulate_kinematic_loops_generated(loop, bad, v0, t_final=0.01, dt=1e-3))]:
        with pytest.raises(ModelError, match=_message(loop, bad, v0, names) + tail):
            run()
    spatial, (q, v) = _spatial_four_bar()
    bad = q.copy()
    bad[0] += 0.1
    tail = re.escape(f"'s3'; allowed <= {CONSISTENCY_TOLERANCE:g}): start from "
                     "SpatialKinematicLoopModel.consistent_state")
    for names, run in [("q0, v0", lambda: simulate_spatial_loops(spatial, bad, v, t_final=0.01, dt=1e-3)),
                       ("x0, v0", lambda: ctmm.simulate(spatial, 0.01, 1e-3, x0=bad, v0=v, method="newmark")),
                       ("q0, v0", lambda: simulate_spatial_kinematic_loops_generated(spatial, bad, v, t_final=0.01,
                                                                                     dt=1e-3))]:
        with pytest.raises(ModelError, match=_message(spatial, bad, v, names) + tail):
            run()


def test_the_generated_rk4_carries_cut_joint_moments():
    """Once refused (the generated step ignored them: 0.44 rad off); now in the step (tests/test_compiled_kinematic_
    loop_laws.py): equal to the numpy path, and the load changes the motion."""
    loop = mechanism()
    cut = loop.cuts[0]
    for extra in ({"moment_law": LinearLaw(5.0, 0.1)}, {"torque": 2.0}):
        lawful = KinematicLoopModel(loop.tree, [CutJoint(cut.name, parent=cut.parent, child=cut.child, **extra)])
        q0, v0 = start(lawful)
        generated = ctmm.simulate(lawful, 0.02, 1e-3, x0=q0, v0=v0, compiled=True)
        numpy_run = simulate_kinematic_loops(lawful, q0, v0, t_final=0.02, dt=1e-3)
        assert np.max(np.abs(generated["crank.theta"] - numpy_run.q[:, 0])) <= 1e-12
        smooth = simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3)
        assert np.max(np.abs(numpy_run.q - smooth.q)) > 1e-6


def test_the_spatial_generated_rk4_carries_cut_joint_laws_and_actuations():
    """Once refused; now in the generated step (tests/test_compiled_kinematic_loop_laws.py): equal to the numpy
    path, and the load changes the motion."""
    import dataclasses

    from spatial_loop_helpers import hinged_pendulum
    from ctmm.spatial.closed_loops import SpatialKinematicLoopModel

    pendulum = hinged_pendulum()
    for extra in ({"law": LinearLaw(5.0, 0.1)}, {"actuation": 2.0}):
        loaded = SpatialKinematicLoopModel(pendulum.tree, [dataclasses.replace(pendulum.cuts[0], **extra)],
                                           baumgarte=pendulum.baumgarte)
        q, v = loaded.consistent_state({"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01},
                                       {"free.wy": 2.0}, keep=["free.wy"])
        generated = ctmm.simulate(loaded, 0.02, 1e-3, x0=q, v0=v, compiled=True)
        numpy_run = simulate_spatial_loops(loaded, q, v, t_final=0.02, dt=1e-3)
        index = list(loaded.tree.coordinates).index("free.qy")
        assert np.max(np.abs(generated["free.qy"] - numpy_run.q[:, index])) <= 1e-12
        free = simulate_spatial_loops(pendulum, q, v, t_final=0.02, dt=1e-3)
        assert np.max(np.abs(numpy_run.q - free.q)) > 1e-6


def test_one_loop_run_hook_turns_stored_and_failed_rows_into_the_models_run():
    """:func:`ctmm.loop_integration.integrate_loop_run` (the planar and spatial numpy loop runs through one hook): the
    stored rows go to ``history`` with the wall time, a failure's rows before it with wall time 0, and the error keeps
    its message, time and element."""
    from ctmm.loop_integration import integrate_loop_run

    calls = []

    def history(t, q, v, wall):
        calls.append((np.array(t), np.array(q), np.array(v), wall))
        return len(calls)

    def rate(t, y):             # q'' = -q until t = 0.0025 s, then a singular configuration
        if t >= 0.0025:
            raise SimulationError("singular at the rate", time=t, element="rate")
        return np.array([y[1], -y[0]])

    options = dict(t_final=0.01, dt=1e-3, method="rk4", finish=lambda y, t: y, rtol=1e-9, atol=1e-11, store_every=1,
                   t_eval=None, max_step=None, label="kinematic loop 'x'", element="cut", velocity_label="qdot")
    assert integrate_loop_run(history, lambda t, y: np.array([y[1], -y[0]]), np.array([1.0, 0.0]), 1,
                              **options) == 1
    t, q, v, wall = calls[0]
    np.testing.assert_allclose(t, np.linspace(0.0, 0.01, 11), rtol=0.0, atol=1e-15)
    assert q.shape == v.shape == (11, 1) and wall > 0.0
    assert abs(q[-1, 0] - np.cos(0.01)) < 1e-12 and abs(v[-1, 0] + np.sin(0.01)) < 1e-12       # q = cos t
    with pytest.raises(SimulationError, match="^singular at the rate$") as failure:
        integrate_loop_run(history, rate, np.array([1.0, 0.0]), 1, **options)
    assert failure.value.partial_result == 2 and failure.value.element == "cut"
    assert failure.value.time == pytest.approx(0.002)          # the step that started at t = 2 ms
    t, q, v, wall = calls[1]
    np.testing.assert_allclose(t, [0.0, 1e-3, 2e-3], rtol=0.0, atol=1e-15)
    assert q.shape == v.shape == (3, 1) and wall == 0.0
