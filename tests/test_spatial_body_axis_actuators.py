"""Body-axis force and moment actuators of spatial rigid bodies (issue 14): ``"<body>.force_body_x|y|z"``
(at the centre of mass), ``"<body>.moment_body_x|y|z"`` and ``"<body>.<point>.force_body_x|y|z"``, whose
components turn with the body (a thruster, a reaction-wheel torque).

* accelerations of a five-body tree with every joint kind at random states against the independent
  reference tree (:mod:`ctmm.reference.spatial_tree`) loaded with the world wrench ``R(q) [f ; m]``;
* a spinning axisymmetric top under a constant body-axis torque against Euler's equations solved by
  hand (numpy RK4, the implicit DT-TMM), and body-axis rate loops on it in generated kernels (``compiled=True``)
  equal to the numpy path;
* the linearisation's ``B`` column against a central difference of the reference;
* the exact-field frequency response (``fields="exact"``) against its world-axis ports turned by hand.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.reference.spatial_kinematics import kinematics, point_jacobian
from ctmm.reference.spatial_tree import forward_dynamics
from ctmm.spatial.dynamics import accelerations
from ctmm.spatial.ports import SpatialPorts
from spatial_control_helpers import q_to_reference, quaternion_joint_state, random_model, to_reference

_AXES = "xyz"


def _reference_rates(tree, q_reference, v, body: int, point, force_body, moment_body, tau=None):
    """The reference's ``v_dot`` with a body-axes force at ``point`` (body axes) and moment on ``body``."""
    kin = kinematics(tree, q_reference, v)
    R = kin.rotation[body]
    world_point = kin.origin[body] + R @ np.asarray(point, float)
    generalised = point_jacobian(kin, body, world_point).T @ (R @ force_body) \
        + kin.jacobian_angular[body].T @ (R @ moment_body)
    return forward_dynamics(tree, q_reference, v, generalised if tau is None else tau + generalised)


def _actuators(model):
    """``(port name, body index, point (body axes), force (3,), moment (3,))`` of some body-axis actuators."""
    rows = []
    for j, body in enumerate(model.bodies):
        for c, a in enumerate(_AXES):
            unit = np.eye(3)[c]
            rows.append((f"{body.name}.moment_body_{a}", j, np.zeros(3), np.zeros(3), unit))
            rows.append((f"{body.name}.force_body_{a}", j, body.center_of_mass, unit, np.zeros(3)))
            rows.append((f"{body.name}.tip.force_body_{a}", j, body.points["tip"], unit, np.zeros(3)))
    return rows


def test_body_axis_actuators_of_a_tree_equal_the_reference_with_the_turned_wrench():
    rng = np.random.default_rng(14)
    model = random_model(rng, actuated=False)
    tree, ports = to_reference(model), SpatialPorts(model)
    for _ in range(1):
        q, v = quaternion_joint_state(rng, model)
        free = forward_dynamics(tree, q_to_reference(model, q), v)
        assert np.abs(accelerations(model, q, v) - free).max() <= 1e-10 * np.abs(free).max()
        for name, j, point, force, moment in _actuators(model):
            expected = _reference_rates(tree, q_to_reference(model, q), v, j, point, 3.0 * force, 3.0 * moment)
            inputs = ports.inputs({name: 3.0})
            got = accelerations(model, q, v, 0.0, inputs.joint, inputs.wrenches)
            assert np.abs(expected - free).max() > 1e-4 * np.abs(free).max(), name          # it acts
            assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max(), name
            world = ports.inputs({name.replace("_body", ""): 3.0})                          # world axes differ
            turned = accelerations(model, q, v, 0.0, world.joint, world.wrenches)
            assert np.abs(turned - expected).max() > 1e-3 * np.abs(expected - free).max(), name


def test_body_axis_ports_are_listed_with_their_units():
    model = random_model(np.random.default_rng(1), actuated=False)
    ports = SpatialPorts(model)
    assert ports.actuator_unit("b2.moment_body_z") == "N m"
    assert ports.actuator_unit("b2.side.force_body_x") == "N"
    assert ports.actuators["b3.force_body_y"].axes == "body"
    assert ports.actuators["b3.force_y"].axes == "world"


# -- a spinning top: Euler's equations -------------------------------------------------------------------
A_INERTIA, C_INERTIA, TORQUE, SPIN = 0.2, 0.35, 0.3, 5.0


def spinning_top() -> sp.SpatialModel:
    return sp.SpatialModel("top", [sp.SpatialBody("top", 1.5, (A_INERTIA, A_INERTIA, C_INERTIA)),
                                   sp.Spherical(name="ball", parent=None, child="top")], gravity=(0, 0, 0))


def euler_solution(t: np.ndarray) -> np.ndarray:
    """Body-axes angular velocity of an axisymmetric body spinning at ``SPIN`` about its axis ``z`` under a
    constant body-axis torque ``TORQUE`` about ``x`` from rest in ``x, y``: ``A w1' = M - (C - A) W w2``,
    ``A w2' = (C - A) W w1``, ``w3 = W``; with ``lam = (C - A) W / A``:
    ``w1 = M / (A lam) sin(lam t)``, ``w2 = M / (A lam) (1 - cos(lam t))``."""
    lam = (C_INERTIA - A_INERTIA) * SPIN / A_INERTIA
    scale = TORQUE / (A_INERTIA * lam)
    return np.array([scale * np.sin(lam * t), scale * (1.0 - np.cos(lam * t)), SPIN * np.ones_like(t)])


OMEGA = [f"top.omega_body_{a}" for a in _AXES]


def _spin(method: str, dt: float, **options):
    run = ctmm.simulate(spinning_top(), 0.5, dt, method=method, v0={"ball.wz": SPIN},
                        inputs={"top.moment_body_x": TORQUE}, outputs=OMEGA, **options)
    return run, np.array([run[name] for name in OMEGA]) - euler_solution(run.time)


def test_a_spinning_top_under_a_body_axis_torque_follows_euler_equations():
    run, error = _spin("rk4", 1e-2)
    assert np.abs(error).max() <= 1e-8 * SPIN                                   # RK4 at dt = 10 ms: 1.2e-8 measured
    errors = [np.abs(_spin("newmark", dt)[1]).max() for dt in (1e-2, 5e-3)]
    assert errors[0] <= 1e-4 * SPIN and 3.5 < errors[0] / errors[1] < 4.5        # the DT-TMM: second order
    world = ctmm.simulate(spinning_top(), 0.5, 1e-2, method="rk4", v0={"ball.wz": SPIN},
                          inputs={"top.moment_x": TORQUE}, outputs=OMEGA)
    assert np.abs(world["top.omega_body_y"] - run["top.omega_body_y"]).max() > 1e-2 * TORQUE / A_INERTIA * 0.5


def test_loops_on_body_axis_actuators_in_generated_kernels_equal_the_numpy_path():
    # a nutation damper: body-axis rate feedback on body-axis torques, the loops closed inside the C step
    loops = [Feedback(f"damp_{a}", f"top.omega_body_{a}", f"top.moment_body_{a}", gain=0.4) for a in "xy"]
    controlled = with_feedback(spinning_top(), loops)
    options = dict(method="rk4", v0={"ball.wz": SPIN, "ball.wx": 0.3}, inputs={"top.moment_body_x": TORQUE})
    numpy_run = ctmm.simulate(controlled, 0.3, 1e-2, **options)
    compiled = ctmm.simulate(controlled, 0.3, 1e-2, compiled=True, **options)
    assert compiled.info["method"] == "rk4-generated"
    for name in ("damp_x.u", "damp_y.u", "ball.wx"):
        assert np.abs(compiled[name] - numpy_run[name]).max() <= 1e-12 * np.abs(numpy_run[name]).max(), name
    free = ctmm.simulate(spinning_top(), 0.3, 1e-2, **options, outputs=OMEGA)
    assert np.abs(free["top.omega_body_x"] - numpy_run["damp_x.y"]).max() > 1e-3              # the loops act


def test_linearised_input_columns_equal_a_difference_of_the_reference():
    inertia = np.array([[0.3, 0.02, 0.0], [0.02, 0.25, 0.01], [0.0, 0.01, 0.2]])
    model = sp.SpatialModel("pair", [
        sp.SpatialBody("arm", 1.2, inertia, (0.1, 0.02, -0.03), {"tip": (0.4, 0.05, 0.0)}),
        sp.Universal(name="u", parent=None, child="arm", axis1=(0, 0, 1), axis2=(0, 1, 0), stiffness=(3.0, 2.0)),
        sp.SpatialBody("head", 0.7, 0.6 * inertia, (0.05, -0.02, 0.04), {"tip": (0.1, 0.2, -0.1)}),
        sp.Spherical(name="ball", parent="arm", point="tip", child="head")], gravity=(0.0, 0.0, 0.0))
    tree = to_reference(model)
    q, v = quaternion_joint_state(np.random.default_rng(7), model)
    v = np.zeros(model.n_velocities)
    names = ["arm.moment_body_x", "head.force_body_z", "head.tip.force_body_y", "arm.tip.force_body_x"]
    B = ctmm.linearize(model, (q, v), inputs=names, allow_nonequilibrium=True).state_space.B
    n = model.n_velocities
    rows = {row[0]: row for row in _actuators(model)}
    for k, name in enumerate(names):
        _, j, point, force, moment = rows[name]
        up, down = (_reference_rates(tree, q_to_reference(model, q), v, j, point, h * force, h * moment)
                    for h in (1e-3, -1e-3))
        expected = (up - down) / 2e-3
        assert np.abs(B[n:, k] - expected).max() <= 1e-9 * np.abs(expected).max(), name
        assert np.abs(B[:n, k]).max() == 0.0


def test_exact_field_body_axis_ports_are_the_world_ports_turned_by_the_rest_rotation():
    tilt = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])       # body x = world y
    beam = sp.SpatialBeam("arm", length=1.0, mass_per_length=0.8, bending_stiffness_y=5.0, bending_stiffness_z=7.0,
                          torsional_stiffness=2.0, polar_inertia_per_length=0.002, axial_stiffness=300.0,
                          n_modes_y=2, n_modes_z=2, n_torsion_modes=1, n_axial_modes=1)
    model = sp.SpatialModel("m", [
        sp.SpatialBody("hub", 2.0, (0.1, 0.12, 0.15), points={"out": (0.2, 0.0, 0.0)}),
        sp.Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1), stiffness=40.0),
        beam, sp.Weld(name="mount", parent="hub", child="arm", point="out"),
        sp.SpatialBody("payload", 0.3, (0.004, 0.005, 0.006), center_of_mass=(0.05, 0.01, 0.0),
                       points={"side": (0.0, 0.1, 0.02)}),
        sp.Weld(name="grip", parent="arm", child="payload", point="tip", rotation=tilt)], gravity=(0, 0, 0))
    omega = np.array([2.0, 9.0, 30.0])
    outputs = ["arm.tip.w_y", "payload.side.z", "payload.omega_body_x", "payload.omega_y", "hinge.angle"]
    world = [f"payload.side.force_{a}" for a in _AXES] + [f"payload.moment_{a}" for a in _AXES]
    body = ["payload.side.force_body_x", "payload.moment_body_y", "arm.tip.moment_body_z", "arm.tip.force_body_y"]
    frf = ctmm.frequency_response(model, omega, input=world + body + ["arm.tip.moment_z", "arm.tip.force_y"],
                                  output=outputs, fields="exact")
    for name, combination in (("payload.side.force_body_x", {"payload.side.force_y": 1.0}),
                              ("payload.moment_body_y", {"payload.moment_x": -1.0}),
                              ("arm.tip.moment_body_z", {"arm.tip.moment_z": 1.0}),
                              ("arm.tip.force_body_y", {"arm.tip.force_y": 1.0})):
        expected = sum(w * frf.response[:, frf.inputs.index(n), :] for n, w in combination.items())
        got = frf.response[:, frf.inputs.index(name), :]
        assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max(), name
        assert np.abs(expected).max() > 0.0
    body_rate = frf.response[outputs.index("payload.omega_body_x")]            # body x = world y at rest
    world_rate = frf.response[outputs.index("payload.omega_y")]
    assert np.abs(body_rate - world_rate).max() <= 1e-12 * np.abs(world_rate).max()
    assert np.abs(world_rate).max() > 0.0
