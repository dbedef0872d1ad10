"""Projection onto the cut joints after every DT-TMM step (issue 16 item 2, issue 14 item 3): planar and spatial
kinematic loop models under the implicit schemes, with the one projection rule of the RK4
(:class:`ctmm.loop_integration.StepProjection`), against independent DAEs.

References: the planar four-bar as a global DAE in absolute coordinates (:mod:`ctmm.reference.planar_dae`, through
``ctmm.scenarios.four_bar.reference``) and the spatial R-U-S-R four-bar as a Newton-Euler DAE of free bodies
(:mod:`ctmm.reference.spatial_loop_dae`); neither shares code with the tree sweep, the cut mechanism or the schemes.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.errors import SimulationError
from ctmm.loop_integration import PROJECTION_TOLERANCE, StepProjection
from ctmm.planar.implicit import simulate_implicit
from ctmm.planar.implicit_kinematic_loops import simulate_loop_scheme
from ctmm.scenarios.four_bar import SPRING, mechanism, reference as four_bar_dae, start
from ctmm.schemes import as_scheme
from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme
from spatial_loop_helpers import rusr
from test_spatial_closed_loops import _dae_errors

NAMES = ["crank", "coupler", "rocker"]


@pytest.fixture(scope="module")
def planar_four_bar():
    loop = mechanism(SPRING)
    q0, v0 = start(loop)
    dae = four_bar_dae(SPRING)
    reference = dae.simulate(dae.assemble(dict(zip(NAMES, q0)), dict(zip(NAMES, v0))), 0.08,
                             t_eval=np.linspace(0.0, 0.08, 41))
    return loop, q0, v0, reference


@pytest.fixture(scope="module")
def spatial_four_bar():
    loop = rusr()
    q, v = loop.consistent_state({"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0}, keep=["h1"])
    return loop, q, v


def test_planar_newmark_with_projection_holds_the_cuts_at_second_order(planar_four_bar):
    """The cubic-spring four-bar, Newmark at 4 / 2 ms over 0.08 s against the DAE: the crank angle converges at
    order two (measured 1.25e-5 / 3.1e-6 rad, ratio 4.0) with the drift at round-off after every step (before each
    projection 1.0e-7 / 1.3e-8 m), while the same runs with Baumgarte alone drift by O(dt^2) (1.4e-6 / 3.4e-7 m)."""
    loop, q0, v0, reference = planar_four_bar
    errors, drifts = [], []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(loop, 0.08, dt, x0=q0, v0=v0, method="newmark")
        every = int(round(dt / 2e-3))
        errors.append(np.max(np.abs(result["crank.theta"] - reference.angle("crank")[::every])))
        assert np.max(result["drift"]) <= 1e-10 and result.info["projection"] is True
        assert result.info["max_drift_after_projection"] <= 1e-10
        assert result.info["max_drift_before_projection"] > 1e-9        # the projection had work to do
        baumgarte, info = simulate_loop_scheme(loop, q0, v0, t_final=0.08, dt=dt, scheme=as_scheme("newmark"),
                                               projection=False)
        assert info["projection"] is False and "max_drift_before_projection" not in info
        drifts.append(np.max(baumgarte.drift))
        # the unprojected drift of a run is of the size the projection removes from each step
        assert drifts[-1] > 1e-9
    assert errors[1] < 2e-5 and 3.5 < errors[0] / errors[1] < 4.5
    assert 3.5 < drifts[0] / drifts[1] < 4.5                          # Baumgarte alone: drift O(dt^2)


@pytest.mark.parametrize("method", ["generalized_alpha", "houbolt"])
def test_planar_other_schemes_with_projection(planar_four_bar, method):
    loop, q0, v0, reference = planar_four_bar
    errors = []
    for dt in (4e-3, 2e-3):
        run, info = simulate_loop_scheme(loop, q0, v0, t_final=0.08, dt=dt, scheme=as_scheme(method))
        every = int(round(dt / 2e-3))
        errors.append(np.max(np.abs(run.coordinate("crank.theta") - reference.angle("crank")[::every])))
        assert np.max(run.drift) <= 1e-10 and info["max_drift_before_projection"] > 1e-10
    assert 3.3 < errors[0] / errors[1] < 4.7 and errors[1] < 5e-5


def test_a_failed_projection_stops_the_scheme_with_time_cut_and_partial_result():
    """Twenty times the four-bar's rate at 20 ms: the step's drift before projection is ~5e-2 m, which three
    Gauss-Newton steps remove (measured 3e-11 m after them); one step cannot, and the run stops with the rule's
    error at that step, the cut named, the rows so far kept."""
    loop = mechanism()
    q0, v0 = start(loop)
    projector = StepProjection(loop, f"kinematic loop {loop.name!r}", iterations=1)
    with pytest.raises(SimulationError, match=r"the projection onto the cut joints failed .* after 1 Gauss-Newton "
                                              r"steps; allowed <= 1e-08") as failure:
        simulate_implicit(loop.tree, q0, 20 * v0, t_final=1.0, dt=0.02, scheme="newmark", stability_check="ignore",
                          inputs=lambda t, q, v: loop.cut_inputs(q, v, t), project=projector)
    error = failure.value
    assert error.element in {cut.name for cut in loop.cuts} and error.time > 0.0
    partial = error.partial_result
    assert partial is not None and partial.t[-1] < error.time
    assert np.all(np.abs(loop.constraints(partial.q[-1], partial.qdot[-1])[0]) <= PROJECTION_TOLERANCE)
    assert len(projector.drift_before) == len(projector.drift_after) + 1       # the failed step is the last


def test_a_failed_spatial_projection_stops_the_scheme_with_time_cut_and_partial_result(spatial_four_bar):
    """Ten times the R-U-S-R four-bar's rate at 20 ms: one Gauss-Newton step leaves 1e-4 m on the spherical cut."""
    from ctmm.spatial.implicit import simulate_spatial_implicit

    loop, q, v = spatial_four_bar
    projector = StepProjection(loop, f"spatial kinematic loop {loop.name!r}", iterations=1)
    with pytest.raises(SimulationError, match=r"the projection onto the cut joints failed .* after 1 Gauss-Newton "
                                              r"steps; allowed <= 1e-08") as failure:
        simulate_spatial_implicit(loop.tree, 0.1, 0.02, scheme="newmark", x0=q, v0=10 * v,
                                  input_map=lambda t, q_at, v_at: loop.cut_inputs(q_at, v_at, t), project=projector)
    error = failure.value
    assert error.element == "s3" and error.time == pytest.approx(0.02)
    assert error.partial_result is not None and error.partial_result.time[-1] == 0.0


@pytest.mark.parametrize("method", ["newmark", "generalized_alpha", "houbolt"])
def test_spatial_schemes_with_projection_converge_to_the_dae_at_second_order(spatial_four_bar, method):
    """The R-U-S-R four-bar (spherical cut) at 4 / 2 ms over 0.016 s against the Newton-Euler DAE: rotations at
    order two (measured ratios 4.0 / 4.0 / 3.8), drift at round-off after every step (before projection 1e-7 m)."""
    loop, q, v = spatial_four_bar
    errors = []
    for dt in (4e-3, 2e-3):
        run, info = simulate_spatial_loop_scheme(loop, q, v, t_final=0.016, dt=dt, scheme=method)
        assert info["projection"] is True and run.drift.max() <= 1e-12 and run.drift_rate.max() <= 1e-12
        assert info["max_drift_before_projection"] > 1e-9
        errors.append(_dae_errors(loop, run)[0])
    assert errors[1] < 3e-6 and 3.3 < errors[0] / errors[1] < 4.7


def test_spatial_simulate_projects_and_baumgarte_only_stays_for_comparison(spatial_four_bar):
    """``ctmm.simulate`` with a scheme is the projected run (its report in ``info``); ``projection=False`` of the
    library function keeps Baumgarte alone, whose drift is the size the projection removes."""
    loop, q, v = spatial_four_bar
    result = ctmm.simulate(loop, 0.016, 4e-3, x0=q, v0=v, method="newmark")
    projected, _ = simulate_spatial_loop_scheme(loop, q, v, t_final=0.016, dt=4e-3, scheme="newmark")
    assert np.array_equal(projected.q[:, 0], result[loop.tree.coordinates[0]])
    assert np.array_equal(projected.drift, result["drift"]) and result.info["projection"] is True
    assert result.info["max_drift_after_projection"] <= 1e-12 < 1e-9 < result.info["max_drift_before_projection"]
    run, info = simulate_spatial_loop_scheme(loop, q, v, t_final=0.016, dt=4e-3, scheme="newmark", projection=False)
    assert info["projection"] is False and run.drift.max() > 1e-8       # measured 4.5e-7 m


@pytest.mark.parametrize("method, t_final, order", [("newmark", 0.016, 2), ("rk4", 0.04, 4)])
def test_spatial_feedback_loop_converges_to_the_dae_and_projects(spatial_four_bar, method, t_final, order):
    """``with_feedback(loop_model, [PD])`` in the loop-closing driver, every accepted step projected onto the cut before
    the loop reads it; against the DAE with ``u = -(8 theta + 0.8 theta' - 1.6)`` on the crank at 4 / 2 ms.  Newmark
    (the tree stepped with the cut loads solved under each iterate's loop torque), 0.016 s: measured 2.9e-5 / 7.4e-6
    rad, ratio 4.0; drift before each projection 1.3e-6 / 1.8e-7 m, after it 1e-14 m.  RK4
    (:mod:`ctmm.control.explicit_loops`), 0.04 s: 1.27e-8 / 7.1e-10 rad, ratio 17.8 (order 4); drift before the
    projections 2.6e-9 / 8.1e-11 m, after them 2e-16 m."""
    from ctmm.control import Feedback, with_feedback
    from spatial_loop_helpers import dae_of, poses

    loop, q, v = spatial_four_bar
    down = np.diag([1.0, -1.0, -1.0])
    dae = dae_of(loop)

    def law(t, y):
        crank = down.T @ dae.rotations(y)[0]                       # Rot_x(theta)
        theta, rate = np.arctan2(crank[2, 1], crank[1, 1]), dae.split(y)[3][0][0]
        return {0: np.array([-(8.0 * theta + 0.8 * rate - 1.6), 0.0, 0.0])}

    pd = Feedback("pd", sensor=[("h1.angle", 8.0), ("h1.rate", 0.8)], actuator="h1.torque", gain=1.0)
    errors = []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(with_feedback(loop, [pd]), t_final, dt, x0=q, v0=v, method=method,
                               references={"pd": 1.6})
        assert result.info["projection"] is True and result["drift"].max() < 1e-12
        assert result.info["max_drift_after_projection"] <= 1e-12
        assert result.info["max_drift_before_projection"] > (1e-8 if order == 2 else 1e-11)
        _, Y = dae.simulate(dae.state(*poses(loop, q, v)), result.time, torques=law)
        qs = np.array([result[name] for name in loop.tree.coordinates]).T
        vs = np.array([result[name] for name in loop.tree.velocities]).T
        errors.append(max(max(np.abs(a - b).max() for a, b in zip(poses(loop, qs[k], vs[k])[1], dae.rotations(Y[k])))
                          for k in range(len(Y))))
        u = -(8.0 * result["h1.angle"] + 0.8 * result["h1.angle_rate"] - 1.6)
        assert np.max(np.abs(result["pd.u"] - u)) < 1e-12
    if order == 2:
        assert errors[1] < 1e-5 and 3.5 < errors[0] / errors[1] < 4.5
    else:
        assert errors[1] < 1e-8 and 12.0 < errors[0] / errors[1] < 20.0


def test_step_projection_equals_the_gauss_newton_written_out_and_its_residual(planar_four_bar, spatial_four_bar):
    """The projection of a step (:class:`StepProjection`, evaluating each constraint row once) equals, bit for bit,
    the Gauss-Newton of ``docs/closed_loops.md`` §2 written out here on the model's ``constraints`` and ``jacobian``
    (planar: ``Phi`` and ``J`` at every iterate, then ``qdot - J^+ Phi'`` at the last one; spatial: its
    ``project``), and its recorded drifts are ``max |Phi|`` of the state before and after it."""
    from ctmm.loop_integration import PROJECTION_SKIP

    def planar_gauss_newton(loop, q, v, t, iterations):
        for _ in range(iterations):
            phi, _ = loop.constraints(q, v, t)
            if np.max(np.abs(phi)) < PROJECTION_SKIP:
                break
            q = q - np.linalg.lstsq(loop.jacobian(q, t), phi, rcond=None)[0]
        return q, v - np.linalg.lstsq(loop.jacobian(q, t), loop.constraints(q, v, t)[1], rcond=None)[0]

    rng = np.random.default_rng(21)
    planar, q0, v0, _ = planar_four_bar
    spatial, sq, sv = spatial_four_bar
    for loop, q_on, v_on, written in ((planar, q0, v0, planar_gauss_newton),
                                      (spatial, sq, sv, lambda loop, q, v, t, k: loop.project(q, v, t, k))):
        for offset, iterations in ((1e-6, 3), (1e-4, 1), (1e-3, 3), (0.0, 3)):
            q = np.asarray(q_on, float) + offset * rng.normal(size=len(q_on))
            v = np.asarray(v_on, float) + 1e-2 * rng.normal(size=len(v_on))
            projector = StepProjection(loop, "loop", iterations=iterations)
            q_new, v_new = projector(0.05, q, v)
            q_ref, v_ref = written(loop, q.copy(), v.copy(), 0.05, iterations)
            assert np.array_equal(q_new, q_ref) and np.array_equal(v_new, v_ref)
            assert projector.drift_before == [float(np.max(np.abs(loop.constraints(q, v, 0.05)[0])))]
            assert projector.drift_after == [float(np.max(np.abs(loop.constraints(q_ref, v_ref, 0.05)[0])))]
