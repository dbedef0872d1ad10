"""Sensors and actuators of spatial models (ctmm.spatial.ports) against the independent reference
forward kinematics (ctmm.reference.spatial_kinematics) and closed forms.

Tolerances: 1e-12 absolute on O(1) kinematics (both sides are a few dozen float operations);
Jacobians by a 4th-order difference 1e-8; accelerations with actuators against the reference's
global Newton-Euler equations 1e-10 relative.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError, UnknownNameError
from ctmm.reference.spatial_kinematics import kinematics, point_jacobian
from ctmm.reference.spatial_tree import forward_dynamics
from ctmm.spatial import ports
from tests.spatial_control_helpers import q_to_reference, quaternion_joint_state, random_model, to_reference


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("free_base", [False, True])
def test_sensors_equal_reference_kinematics(seed: int, free_base: bool) -> None:
    rng = np.random.default_rng(seed)
    model = random_model(rng, free_base=free_base)
    tree = to_reference(model)
    q, v = quaternion_joint_state(rng, model)
    kin = kinematics(tree, q_to_reference(model, q), v)
    names, expected = [], []
    for j, body in enumerate(model.bodies):
        rotation, omega = kin.rotation[j], kin.omega[j]
        for c, a in enumerate("xyz"):
            names += [f"{body.name}.omega_{a}", f"{body.name}.omega_body_{a}"]
            expected += [omega[c], (rotation.T @ omega)[c]]
        for point, r in {"com": body.center_of_mass, **body.points}.items():
            position = kin.origin[j] + rotation @ np.asarray(r, float)
            velocity = point_jacobian(kin, j, position) @ v
            for c, a in enumerate("xyz"):
                names += [f"{body.name}.{point}.{a}", f"{body.name}.{point}.v{a}"]
                expected += [position[c], velocity[c]]
        angles = ports.sensor_values(model, [f"{body.name}.angle_{a}" for a in "xyz"], q, v)
        np.testing.assert_allclose(_rot(0, angles[0]) @ _rot(1, angles[1]) @ _rot(2, angles[2]), rotation,
                                   rtol=0, atol=1e-12)
        phi = ports.sensor_values(model, [f"{body.name}.rotation_{a}" for a in "xyz"], q, v)
        assert np.linalg.norm(phi) <= np.pi + 1e-12
        angle = np.linalg.norm(phi)
        k = phi / angle
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        np.testing.assert_allclose(np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K, rotation,
                                   rtol=0, atol=1e-12)
    got = ports.sensor_values(model, names, q, v)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_joint_sensors_read_the_state() -> None:
    rng = np.random.default_rng(3)
    model = random_model(rng)
    q, v = quaternion_joint_state(rng, model)
    lay = {j.name: layout for j, layout in zip(model.joints, model.layout)}
    got = ports.sensor_values(model, ["j0.angle", "j0.rate", "j1.q1", "j1.q2", "j1.q1_rate", "j1.q2_rate",
                                      "j3.position", "j3.rate", "j2.qw", "j2.wy"], q, v)
    p, w = lambda n, k=0: q[lay[n].position.start + k], lambda n, k=0: v[lay[n].velocity.start + k]
    np.testing.assert_array_equal(got, [p("j0"), w("j0"), p("j1"), p("j1", 1), w("j1"), w("j1", 1), p("j3"),
                                        w("j3"), p("j2"), w("j2", 1)])
    units = [ports.SpatialPorts(model).sensor_unit(n) for n in ("j0.angle", "j0.rate", "j3.position", "j3.rate", "j2.qw",
                                                   "b1.omega_x", "b1.tip.vz", "b1.angle_y")]
    assert units == ["rad", "rad/s", "m", "m/s", "1", "rad/s", "m/s", "rad"]


def test_xyz_angles_closed_form_and_limits() -> None:
    for angles in ([0.3, -0.7, 2.9], [-3.0, 1.2, -0.1], [1e-9, -2e-9, 3e-9]):
        r = _rot(0, angles[0]) @ _rot(1, angles[1]) @ _rot(2, angles[2])
        np.testing.assert_allclose(ports.xyz_angles(r), angles, rtol=0, atol=1e-12)
    # small rotations: x-y-z angles = rotation vector to first order (the book's linearisation)
    phi = np.array([2e-4, -1e-4, 3e-4])
    r = _rot(0, phi[0]) @ _rot(1, phi[1]) @ _rot(2, phi[2])
    np.testing.assert_allclose(ports.rotation_vector(r), phi, rtol=0, atol=1e-7)
    # rotation vector through pi - epsilon: well conditioned (largest quaternion component first)
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    for angle in (np.pi - 1e-6, 1.0, 1e-8):
        r = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
        np.testing.assert_allclose(ports.rotation_vector(r), angle * axis, rtol=0, atol=1e-12)


def test_body_spin_about_z_closed_form() -> None:
    body = sp.SpatialBody("disk", 1.0, (0.1, 0.1, 0.2), points={"rim": (0.5, 0.0, 0.0)})
    model = sp.SpatialModel("spin", [body, sp.Revolute(name="hub", parent=None, child="disk", axis=(0, 0, 1))],
                            gravity=(0, 0, 0))
    angle, rate = 0.7, 3.0
    got = ports.sensor_values(model, ["disk.angle_z", "disk.omega_z", "disk.rim.x", "disk.rim.y", "disk.rim.vx",
                                      "disk.rim.vy", "disk.rotation_z", "disk.omega_body_z"], [angle], [rate])
    expected = [angle, rate, 0.5 * np.cos(angle), 0.5 * np.sin(angle), -1.5 * np.sin(angle), 1.5 * np.cos(angle),
                angle, rate]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)


def test_sensor_jacobians_tangent_coordinates() -> None:
    rng = np.random.default_rng(4)
    model = random_model(rng, free_base=True)
    q, v = quaternion_joint_state(rng, model, scale=0.4)
    names = ["b2.tip.x", "b2.tip.vz", "b4.omega_y", "b1.angle_x", "j1.q2", "j3.rate", "b2.omega_body_z"]
    dy_dx, dy_dv = ports.sensor_jacobians(model, names, q, v)
    # the time derivative along the motion: dy/dt = dy_dx v + dy_dv v_dot
    vdot = sp.accelerations(model, q, v)
    h = 1e-4
    qdot = model.position_rates(q[None], v[None])[0]
    ydot = [ports.sensor_values(model, names, q + s * h * qdot, v + s * h * vdot) for s in (-1, 1)]
    numeric = (ydot[1] - ydot[0]) / (2 * h)
    np.testing.assert_allclose(dy_dx @ v + dy_dv @ vdot, numeric, rtol=0, atol=1e-6)
    # position sensors: dy_dv is zero; the point velocity sensor's dy_dv is the point Jacobian
    assert not np.any(dy_dv[[0, 3, 4]])
    tree = to_reference(model)
    kin = kinematics(tree, q_to_reference(model, q), v)
    j = model.body_index("b2")
    position = kin.origin[j] + kin.rotation[j] @ np.asarray(model.bodies[j].points["tip"])
    np.testing.assert_allclose(dy_dv[1], point_jacobian(kin, j, position)[2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dy_dx[0], point_jacobian(kin, j, position)[0], rtol=0, atol=1e-8)


def test_actuators_equal_reference_generalised_forces() -> None:
    rng = np.random.default_rng(5)
    model = random_model(rng, free_base=True)
    tree = to_reference(model)
    q, v = quaternion_joint_state(rng, model, scale=0.5)
    p = ports.SpatialPorts(model)
    values = {name: rng.normal() for name in p.actuators}
    ours = p.accelerations(q, v, 0.0, p.inputs(values))
    # the same actuation as generalised forces of the reference: joint inputs in their velocity slots,
    # body forces through point Jacobians (world axes; body axes turned by the body's rotation), moments
    # through angular Jacobians
    qr = q_to_reference(model, q)
    kin = kinematics(tree, qr, v)
    tau = np.zeros(model.n_velocities)
    for joint, layout in zip(model.joints, model.layout):
        block = {"revolute": ["torque"], "prismatic": ["force"], "universal": ["torque1", "torque2"],
                 "spherical": ["torque_x", "torque_y", "torque_z"],
                 "free": ["force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z"]}[joint.kind]
        tau[layout.velocity] += [values[f"{joint.name}.{part}"] for part in block]
    for j, body in enumerate(model.bodies):
        for point, r in {"com": body.center_of_mass, **body.points}.items():
            label = f"{body.name}.force" if point == "com" else f"{body.name}.{point}.force"
            force = np.array([values[f"{label}_{a}"] for a in "xyz"])
            force += kin.rotation[j] @ np.array([values[f"{label}_body_{a}"] for a in "xyz"])
            tau += point_jacobian(kin, j, kin.origin[j] + kin.rotation[j] @ np.asarray(r, float)).T @ force
        moment = np.array([values[f"{body.name}.moment_{a}"] for a in "xyz"])
        moment += kin.rotation[j] @ np.array([values[f"{body.name}.moment_body_{a}"] for a in "xyz"])
        tau += kin.jacobian_angular[j].T @ moment
    theirs = forward_dynamics(tree, qr, v, tau)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10 * np.max(np.abs(theirs)))
    # a hand-built SpatialInputs of the same values (unchecked) takes the checked path: the same answer
    built = p.inputs(values)
    assert built.checked
    by_hand = ports.SpatialInputs(dict(built.joint), {j: list(w) for j, w in built.wrenches.items()})
    assert not by_hand.checked
    np.testing.assert_array_equal(p.accelerations(q, v, 0.0, by_hand), ours)
    units = {p.actuator_unit(n) for n in ("j0.force_x", "b1.force_y", "b1.tip.force_z")}
    assert units == {"N"} and p.actuator_unit("b2.moment_x") == p.actuator_unit("j2.torque_x") == "N m"


def test_refusals_name_what_is_allowed() -> None:
    rng = np.random.default_rng(6)
    model = random_model(rng, actuated=False)
    p = ports.SpatialPorts(model)
    with pytest.raises(ModelError, match="accelerations are not sensors"):
        p.check_sensor("b1.alpha_x")
    with pytest.raises(ModelError, match="actuated=True"):
        p.check_actuator("j0.torque")
    with pytest.raises(UnknownNameError, match="b1.omega_x"):
        p.check_sensor("b1.omega_q")
    with pytest.raises(ModelError, match="SpatialModel"):
        ports.SpatialPorts("model")
    with pytest.raises(ModelError, match="sequence of sensor names"):
        p.resolve("b1.omega_x")
    with pytest.raises(ModelError, match="finite"):
        p.inputs({"b1.force_x": float("nan")})
    # a hand-built SpatialInputs is checked: an unknown body index or a non-finite load named, not a numpy error
    q, v = quaternion_joint_state(rng, model)
    with pytest.raises(ModelError, match="body"):
        p.accelerations(q, v, 0.0, ports.SpatialInputs({}, {99: [(np.zeros(3), np.ones((1, 6, 1)))]}))
    with pytest.raises(ModelError, match="finite"):
        p.accelerations(q, v, 0.0, ports.SpatialInputs({}, {0: [(np.zeros(3), np.full((1, 6, 1), np.nan))]}))
    welded = sp.SpatialModel("w", [sp.SpatialBody("a", 1.0, (1, 1, 1)), sp.SpatialBody("b", 1.0, (1, 1, 1)),
                                   sp.Revolute(name="r", parent=None, child="a"),
                                   sp.Weld(name="w", parent="a", child="b")])
    with pytest.raises(ModelError, match="welded"):
        ports.SpatialPorts(welded).check_actuator("w.torque")


def test_misspelt_input_of_an_actuated_joint_is_not_called_unactuated() -> None:
    """A wrong component name on an actuated joint names the joint's actuators instead of telling the user to
    declare ``actuated=True``, which it already is."""
    model = sp.SpatialModel("m", [sp.SpatialBody("a", 1.0, (1, 1, 1)),
                                  sp.Revolute(name="yaw", parent=None, child="a", actuated=True)])
    with pytest.raises(ModelError, match=r"input 'yaw\.torq': joint 'yaw' has no actuator of that name; "
                                         r"the actuators of 'yaw' are \['yaw\.torque'\]") as caught:
        ctmm.simulate(model, 0.01, 1e-3, inputs={"yaw.torq": 1.0})
    assert "actuated=True" not in str(caught.value)
