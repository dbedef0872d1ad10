"""Named sensors and actuators of planar models (ctmm.planar.ports) and ControlledModel.

Independent checks: sensor values against closed-form geometry of a two-link arm and the
beam's own mode shapes; actuator inputs against the Lagrange model (ctmm.reference.planar_lagrange)
of the same arm carrying the equivalent loads; Jacobians against central differences.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.control import ControlledChain, ControlledModel, Feedback, with_feedback
from ctmm.errors import ModelError, UnknownNameError
from ctmm.planar import (
    ActuatedHinge,
    DrivenHinge,
    Fixed,
    Load,
    PlanarModel,
    RigidBody,
    SpringDamperHinge,
    accelerations,
    ports,
    solve_instant,
)
from ctmm.planar.elements import FixedMounting
from ctmm.reference.planar_lagrange import PlanarLagrange

L1, L2, A2 = 0.6, 0.5, 0.35


def arm(loads=(), torque=0.0, hub=None) -> PlanarModel:
    upper = RigidBody.uniform_link("upper", mass=1.5, length=L1)
    fore = RigidBody("fore", mass=0.8, inertia=0.04, center_of_mass=(A2, 0.0), outboard=(L2, 0.0), loads=loads)
    elbow = SpringDamperHinge("elbow", stiffness=30.0, damping=0.2, rest_angle=0.0)
    hub = hub if hub is not None else ActuatedHinge("motor", torque=torque)
    return PlanarModel.chain("arm", [Fixed("ground"), hub, upper, elbow, fore])


STATE = (np.array([-1.2, -0.7]), np.array([0.3, -0.5]))


def test_sensor_values_match_closed_form_geometry():
    model = arm()
    (t1, t2), (w1, w2) = STATE
    names = ["fore.out.x", "fore.out.y", "fore.out.vx", "fore.out.vy", "fore.com.y", "elbow.angle",
             "elbow.rate", "motor.angle", "fore.theta", "fore.omega", "upper.theta_dot"]
    expected = [L1 * np.cos(t1) + L2 * np.cos(t2), L1 * np.sin(t1) + L2 * np.sin(t2),
                -L1 * np.sin(t1) * w1 - L2 * np.sin(t2) * w2, L1 * np.cos(t1) * w1 + L2 * np.cos(t2) * w2,
                L1 * np.sin(t1) + A2 * np.sin(t2), t2 - t1, w2 - w1, t1, t2, w2, w1]
    np.testing.assert_allclose(ports.sensor_values(model, names, *STATE), expected, rtol=0, atol=1e-14)
    assert ports.sensor_unit(model, "fore.out.vy") == "m/s" and ports.sensor_unit(model, "elbow.angle") == "rad"
    assert ports.actuator_unit(model, "motor.torque") == "N m"


def test_sensor_jacobians_match_central_differences():
    model = arm()
    names = ["fore.out.x", "fore.out.vy", "elbow.rate", "fore.com.x", "upper.theta"]
    q, v = STATE
    dq, dv = ports.sensor_jacobians(model, names, q, v)
    h = 1e-6
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd_q = (ports.sensor_values(model, names, q + e, v) - ports.sensor_values(model, names, q - e, v)) / (2 * h)
        fd_v = (ports.sensor_values(model, names, q, v + e) - ports.sensor_values(model, names, q, v - e)) / (2 * h)
        np.testing.assert_allclose(dq[:, k], fd_q, atol=1e-8)
        np.testing.assert_allclose(dv[:, k], fd_v, atol=1e-8)
    assert dq[1, 0] != 0.0 and dv[0].tolist() == [0.0, 0.0]     # position sensors do not read rates


def test_actuator_inputs_equal_the_lagrange_model_with_the_same_loads():
    q, v = STATE
    loaded = arm(loads=(Load(point=(A2, 0.0), force_x=1.1, force_y=-0.4, moment=0.3),), torque=0.7)
    reference = PlanarLagrange(loaded).accelerations(q, v)
    model = arm()
    inputs = ports.actuator_inputs(model, {"motor.torque": 0.7, "fore.force_x": 1.1, "fore.force_y": -0.4,
                                           "fore.moment": 0.3})
    np.testing.assert_allclose(accelerations(model, q, v, inputs=inputs), reference, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(solve_instant(model, q, v, inputs=inputs).qddot, reference, rtol=1e-12, atol=1e-12)
    # a torque across the elbow: +0.5 N m on the forearm, the reaction -0.5 N m on the upper link
    upper = RigidBody.uniform_link("upper", mass=1.5, length=L1, loads=(Load(moment=-0.5),))
    fore = RigidBody("fore", mass=0.8, inertia=0.04, center_of_mass=(A2, 0.0), outboard=(L2, 0.0),
                     loads=(Load(moment=0.5),))
    pair = PlanarModel.chain("arm", [Fixed("ground"), ActuatedHinge("motor"), upper,
                                     SpringDamperHinge("elbow", stiffness=30.0, damping=0.2), fore])
    np.testing.assert_allclose(accelerations(model, q, v, inputs=ports.actuator_inputs(model, {"elbow.torque": 0.5})),
                               PlanarLagrange(pair).accelerations(q, v), rtol=1e-12, atol=1e-12)


def test_modal_force_inputs_on_a_beam_equal_the_flexible_lagrange_model():
    from ctmm.flexible import ModalBeam
    from ctmm.flexible.beam import ModalForce
    from ctmm.reference.flexible_lagrange import FlexibleLagrange

    beam = dict(length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=3)

    def build(extra=(), torque=0.0):
        b = ModalBeam("beam", **beam)
        if extra:
            b = b.with_modal_forces(*extra)
        return PlanarModel.chain("hb", [Fixed("ground"), ActuatedHinge("motor", torque=torque),
                                        RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
                                        FixedMounting("mount"), b], gravity=(0.0, -9.81))

    model = build()
    rng = np.random.default_rng(3)
    q, v = rng.normal(size=model.n_coordinates) * 0.02, rng.normal(size=model.n_coordinates) * 0.1
    force = np.array([0.3, -0.2, 0.1])
    reference = FlexibleLagrange(build((ModalForce(force=lambda t: force),), torque=0.5)).accelerations(q, v)
    inputs = ports.actuator_inputs(model, {"motor.torque": 0.5, "beam.q1.force": 0.3, "beam.q2.force": -0.2,
                                           "beam.q3.force": 0.1})
    np.testing.assert_allclose(accelerations(model, q, v, inputs=inputs), reference, rtol=1e-9, atol=1e-9)
    # the deformed tip: rigid frame plus sum q_i phi_i(L) across it
    d = model.beams[1].data
    eta = q[model.modal_index[1]]
    theta = q[model.coordinate_index("hub.theta")]
    local = np.array([d.end_x[0] + eta[d.nq:] @ d.end_psi[0], eta[:d.nq] @ d.end_phi[0]])
    base = np.array([0.1 * np.cos(theta), 0.1 * np.sin(theta)])
    tip = base + np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]) @ local
    end = model.bodies[1].ends[0]
    np.testing.assert_allclose(ports.sensor_values(model, [f"beam.{end}.x", f"beam.{end}.y"], q, v), tip, atol=1e-14)


def test_bad_names_are_refused_with_the_available_names():
    model = arm()
    with pytest.raises(UnknownNameError, match="fore.out.y"):
        ports.sensor_values(model, ["fore.tip.y"], *STATE)
    with pytest.raises(ModelError, match="accelerations are not sensors"):
        ports.sensor_values(model, ["fore.out.ax"], *STATE)
    with pytest.raises(UnknownNameError, match="motor.torque"):
        ports.actuator_inputs(model, {"motor.force": 1.0})
    with pytest.raises(ModelError, match="not finite|finite"):
        ports.actuator_inputs(model, {"motor.torque": float("nan")})
    driven = arm(hub=DrivenHinge("motor", angle=lambda t: 0.0, rate=lambda t: 0.0, acceleration=lambda t: 0.0))
    with pytest.raises(ModelError, match="driven or welded"):
        ports.actuator_inputs(driven, {"motor.torque": 1.0})
    with pytest.raises(ModelError, match="sequence of sensor names"):
        ports.sensor_values(model, "fore.out.y", *STATE)


def test_one_ports_object_keeps_refusing_after_its_names_were_resolved():
    """A ports object resolves each actuator once (a time loop asks every stage): later calls still refuse
    non-finite values and unknown names, sum entries on one actuator and add body forces to the sweep."""
    model = arm()
    named = ports.PlanarPorts(model)
    first = named.inputs({"motor.torque": 0.5, "fore.force_y": 0.0})
    assert first.hinge_torque[0] == 0.5 and not first.body_force.any()
    for bad in (float("nan"), np.float64(np.inf), "1.0", np.array([1.0, 2.0]), True):
        with pytest.raises(ModelError, match="actuator 'motor.torque'"):
            named.inputs({"motor.torque": bad})
    with pytest.raises(UnknownNameError, match="motor.torque"):
        named.inputs({"motor.force": 1.0})
    np.testing.assert_array_equal(named.inputs({"motor.torque": np.float64(0.25)}).hinge_torque, [0.25, 0.0])
    pushed = named.inputs({"motor.torque": 0.5, "fore.force_y": -0.4})
    assert pushed.body_force[1, 1] == -0.4
    # a body force changes the accelerations (the torque-only path must not drop it); torque-only inputs equal the
    # model's own hinge torque
    q, v = STATE
    assert np.max(np.abs(accelerations(model, q, v, inputs=pushed) - accelerations(model, q, v, inputs=first))) > 0.1
    np.testing.assert_allclose(accelerations(model, q, v, inputs=first), accelerations(arm(torque=0.5), q, v),
                               rtol=1e-14, atol=1e-14)


def test_points_without_centres_are_the_inboard_ends_of_the_full_points():
    """``PlanarModel.points(..., centres=False)`` (what the cut points of kinematic loops read) holds the same
    inboard ends, velocities and angles as the full call, which adds the centres of mass."""
    model = arm()
    q, v = STATE
    full, ends = model.points(q, v, 0.0), model.points(q, v, 0.0, centres=False)
    assert set(full) - set(ends) == {"com", "com_velocity"}
    for key, value in ends.items():
        np.testing.assert_array_equal(value, full[key])
    np.testing.assert_allclose(ends["inboard"][1], [L1 * np.cos(q[0]), L1 * np.sin(q[0])], rtol=1e-15, atol=1e-15)


def test_controlled_model_validates_loops_and_with_feedback_dispatches():
    model = arm()
    pd = Feedback("pd", sensor=[("motor.angle", 20.0), ("motor.rate", 2.0)], actuator="motor.torque", delay=0.01,
                  gain=1.0)
    system = with_feedback(model, [pd])
    assert isinstance(system, ControlledModel) and system.loop("pd") is pd and system.plant is model
    assert system.signal_names()[-2:] == ["pd.y", "pd.u"] and system.input_names()[-1] == "pd.reference"
    assert system.sensed({"motor.angle": 0.1, "motor.rate": -1.0}) == {"pd": pytest.approx(0.0)}
    assert system.actuation({"pd": 2.0}) == {"motor.torque": 2.0}
    with pytest.raises(UnknownNameError, match="motor.angle"):
        ControlledModel(model, [Feedback("bad", sensor="motor.angel", actuator="motor.torque", gain=1.0)])
    with pytest.raises(UnknownNameError):
        ControlledModel(model, [Feedback("bad", sensor="motor.angle", actuator="motor.trq", gain=1.0)])
    with pytest.raises(ModelError, match="duplicate loop"):
        ControlledModel(model, [pd, pd])
    with pytest.raises(ModelError, match="also an element"):
        ControlledModel(model, [Feedback("elbow", sensor="motor.angle", actuator="motor.torque", gain=1.0)])
    with pytest.raises(ModelError, match="already has loops"):
        with_feedback(system, [pd])
    with pytest.raises(ModelError, match="ctmm.Chain, a ctmm.planar.PlanarModel or a ctmm.spatial.SpatialModel"):
        with_feedback("arm", [pd])
    assert isinstance(with_feedback(_chain(), [Feedback("v", sensor="m.v", actuator="m", gain=5.0)]), ControlledChain)


def _chain():
    import ctmm
    from ctmm.elements import Fixed as Wall
    from ctmm.elements import Free, Mass, SpringDamper

    return ctmm.Chain("c", [Wall("wall"), SpringDamper("k", 100.0, 0.1), Mass("m", 1.0), Free("end")])
