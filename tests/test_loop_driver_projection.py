"""Projection onto the cut joints in the loop driver's explicit runs (issue 16 item 2): RK4 after every step and
``solve_ivp`` at every controller sample (:mod:`ctmm.control.explicit_loops`, the one rule of
:class:`ctmm.loop_integration.StepProjection`), for planar and spatial kinematic loop models with feedback loops and
controllers; and the law sensors ``"<cut>.law_moment"`` / ``"<cut>.law_force"`` of spatial revolute and prismatic
cuts (:mod:`ctmm.spatial.closed_loop_ports`).  The spatial PD loop's RK4 run with projection is checked beside its
Newmark run in ``tests/test_loop_scheme_projection.py``.

Independent references: the planar four-bar as a global DAE in absolute coordinates (:mod:`ctmm.reference.planar_dae`
through ``ctmm.scenarios.four_bar.reference``, the PD law as a crank motor) and the spatial mechanisms as Newton-Euler
DAEs of free bodies (:mod:`ctmm.reference.spatial_loop_dae`, the laws written on the DAE's own state); neither shares
code with the tree sweep, the cut mechanism, the projection or the driver.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.scenarios.four_bar import BODIES, mechanism, reference, start
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from spatial_loop_helpers import poses
from test_spatial_cut_joint_laws import _actuation, _dae_law_loads, two_moving, two_moving_dae

KP, KD, TARGET = 8.0, 0.8, 1.2          # PD on the crank angle [N m/rad], [N m s/rad]; set point [rad]


def _pd(delay: float = 0.0) -> Feedback:
    return Feedback("pd", sensor=[("h1.angle", KP), ("h1.rate", KD)], actuator="h1.torque", gain=1.0, delay=delay)


@pytest.fixture(scope="module")
def four_bar():
    loop = mechanism()
    q0, v0 = start(loop)
    return loop, q0, v0, reference().assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_planar_pd_loop_rk4_projects_every_step_and_keeps_fourth_order(four_bar, delay):
    """The four-bar with a PD crank loop, RK4 in the loop driver at 5 / 2.5 ms over 0.1 s against the DAE with the
    law as a crank motor: every step projected (drift after it <= 1e-12 m), the angles converging at order four.
    Measured: 4.2e-8 / 2.5e-9 rad (ratio 16.7; delayed 16.4), drift 5.3e-9 / 1.7e-10 m before the projections and
    2e-16 m after."""
    loop, q0, v0, state = four_bar
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: -(KP * angle + KD * rate - KP * TARGET), delay=delay)
    errors = []
    for dt in (5e-3, 2.5e-3):
        run = ctmm.simulate(with_feedback(loop, [_pd(delay)]), 0.1, dt, x0=q0, v0=v0, references={"pd": KP * TARGET})
        assert run.info["projection"] is True and run.info["max_drift_after_projection"] <= 1e-12
        assert run.info["max_drift_before_projection"] > 1e-12             # the projection had work to do
        assert np.max(run["drift"]) <= 1e-12 and np.max(run["drift_rate"]) <= 1e-12
        dae_run = dae.simulate(state, 0.1, t_eval=run.time)
        errors.append(max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES))
    assert errors[1] < 1e-8 and 12.0 < errors[0] / errors[1] < 20.0


def test_planar_solve_ivp_projects_at_every_controller_sample(four_bar):
    """``solve_ivp`` restarts at every sample of a co-simulated controller and the state is projected there: the
    stored rows on the sample grid sit on the cut joints (<= 1e-12 m) and match the DAE (a zero-gain controller: the
    free four-bar; measured 4.7e-10 rad, drift 4.2e-10 m before the projections).  Without a controller the solver
    runs in one piece, Baumgarte alone (no projection report; measured drift 5.9e-11 m)."""
    from ctmm.control.static_gain import StaticGainController

    loop, q0, v0, state = four_bar
    controller = StaticGainController(["h1.angle", "h1.rate"], ["h1.torque"], [[0.0, 0.0]], sample_time=0.01)
    run = ctmm.simulate(loop, 0.1, 0.01, x0=q0, v0=v0, method="RK45", rtol=1e-6, atol=1e-8, controllers=[controller])
    assert run.info["projection"] is True and run.info["max_drift_after_projection"] <= 1e-12
    assert run.info["max_drift_before_projection"] > 1e-11 and np.max(run["drift"]) <= 1e-12
    dae_run = reference().simulate(state, 0.1, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES) < 5e-9
    alone = ctmm.simulate(with_feedback(loop, [_pd()]), 0.1, 0.01, x0=q0, v0=v0, method="RK45",
                          references={"pd": KP * TARGET})
    assert "projection" not in alone.info and np.max(alone["drift"]) > 1e-12


# -- law sensors of spatial revolute / prismatic cuts (the mechanisms of tests/test_spatial_cut_joint_laws.py) -------


@pytest.mark.parametrize("kind", ["revolute", "prismatic"])
def test_law_sensor_of_a_spatial_cut_matches_the_dae(kind):
    """``"c.law_moment"`` (revolute) / ``"c.law_force"`` (prismatic) over a 0.1 s RK4 run (2 ms, projected) against
    ``-law(s - rest, s')`` on the Newton-Euler DAE's own state with the law and actuation as its applied loads; the
    cut's ``"c.moment_x|y|z"`` (revolute) / ``"c.force_x|y|z"`` (prismatic) stay the constraint's: no component
    along the cut's direction ``a``.  Measured: 2.6e-8 (revolute, RK4's error at 2 ms) / 1.1e-10 (prismatic) relative
    to the law's largest load; along ``a`` 0 N m / 1e-12 N."""
    loop, cut, law, arm, other, q, v = two_moving(kind)
    name, load = ("c.law_moment", "moment") if kind == "revolute" else ("c.law_force", "force")
    run = ctmm.simulate(loop, 0.1, 2e-3, x0=q, v0=v, outputs=[name])
    assert run.units([name]) == {name: "N m" if kind == "revolute" else "N"}
    dae, points = two_moving_dae(loop, cut, arm, other)

    def loads(t, y):
        return _dae_law_loads(dae, y, cut, 0, 1, *points, law, t)

    _, Y = dae.simulate(dae.state(*poses(loop, q, v)), run.time, torques=loads)
    expected, along = [], []
    for k, (t, y) in enumerate(zip(run.time, Y)):
        R = dae.rotations(y)
        a = R[1] @ cut.axis if kind == "revolute" else R[0] @ cut.parent_axis     # the cut's direction
        on_child = loads(t, y)[1]
        # the DAE's load on the child along a is actuation(t) - law(s - rest, s') on its own state
        expected.append((on_child[3:] if kind == "revolute" else on_child[:3]) @ a - _actuation(t))
        along.append(np.array([run[f"c.{load}_{axis}"][k] for axis in "xyz"]) @ a)
    expected = np.array(expected)
    assert np.ptp(expected) > 0.1                                            # the law's load varies [N m, N]
    assert np.max(np.abs(run[name] - expected)) < 1e-7 * np.max(np.abs(expected))
    assert np.max(np.abs(along)) < 1e-9


def test_law_sensor_in_a_feedback_loop_and_its_refusals():
    """The law sensor is a state sensor: a loop reads it (its ``"<loop>.y"`` is the sensor's value); a cut without a
    law has none, and a revolute cut has no ``law_force`` (the unknown name listed with the sensors)."""
    loop, *_, q, v = two_moving("revolute")
    follow = Feedback("f", sensor="c.law_moment", actuator="c.torque", gain=0.5)
    run = ctmm.simulate(with_feedback(loop, [follow]), 0.02, 2e-3, x0=q, v0=v, outputs=["c.law_moment"])
    assert np.max(np.abs(run["f.y"] - run["c.law_moment"])) < 1e-12 and np.ptp(run["c.law_moment"]) > 0
    with pytest.raises(ModelError, match="c.law_force"):
        ctmm.simulate(loop, 0.01, 2e-3, x0=q, v0=v, outputs=["c.law_force"])
    bare = SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent="arm", point="tip", child="link",
                                                                 kind="revolute", axis=(1, 0, 0))])
    with pytest.raises(ModelError, match="c.law_moment"):
        ctmm.simulate(bare, 0.01, 2e-3, x0=q, v0=v, outputs=["c.law_moment"])
