"""Beam actuators in the beam's body axes (issues 14/15): ``"<beam>.<point>.force_body_x|y|z"`` and
``".moment_body_x|y|z"`` (turning with the floating frame) and the piezo pair built on them.

* 3-D: a two-link arm (yaw + shoulder, tilted mount, both bending planes, twist, axial, tip body, gravity off
  the axes) against the independent assumed-modes Lagrange model, whose generalised forces come from the
  virtual power of the forces and moments in the frame's axes (AD of the section frame);
* planar restriction: the piezo pair and the station force through ``with_feedback`` equal the planar
  ``ModalBeam``'s station ports (the planar PZT actuator) in both planes;
* every path: RK4, the implicit DT-TMM (second order on loops that act on beam stations), ``compiled=True``;
* the controlled linearisation's frequency response against the reference's linearisation closed by hand.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial import Revolute, SpatialBeam, SpatialBody, SpatialModel, Weld
from ctmm.spatial.beam_ports import patch_actuator, patch_sensor
from ctmm.spatial.dynamics import accelerations
from ctmm.spatial.ports import SpatialPorts
from test_spatial_beam import BEAM, HUB_INERTIA, MOUNT, TIP_INERTIA, rotation

BASE_INERTIA = np.array([[0.3, 0.0, 0.01], [0.0, 0.25, 0.0], [0.01, 0, 0.2]])
SHOULDER = (0.1, 0.05, 0.3)
#: (reference actuator, port name)
ACTUATORS = [((0.3, "force", 0), "b.p1.force_body_x"), ((0.3, "force", 1), "b.p1.force_body_y"),
             ((0.3, "force", 2), "b.p1.force_body_z"), ((0.3, "moment", 0), "b.p1.moment_body_x"),
             ((0.7, "moment", 1), "b.p2.moment_body_y"), ((0.7, "moment", 2), "b.p2.moment_body_z"),
             ((1.1, "moment", 2), "b.tip.moment_body_z"), ((1.1, "force", 1), "b.tip.force_body_y")]


def two_link(stiffening=True, gravity=(0.5, 0.2, -9.81), mount=MOUNT, damping=0.01, tip=True,
             actuators=tuple(a for a, _ in ACTUATORS)):
    """The two-link arm (yaw, shoulder, flexible forearm, tip body) and its Lagrange reference (with the
    body-axis ``actuators``)."""
    reference = SpatialBeamLagrange(HubBeam(
        **BEAM, hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02), axes=((0, 0, 1), (0, 1, 0)),
        mount=(0.2, 0.0, 0.05), mount_rotation=mount, geometric_stiffening=stiffening, damping_ratio=damping,
        tip_mass=0.3 if tip else 0.0, tip_inertia=TIP_INERTIA, tip_center=(0.03, 0.02, -0.01), gravity=gravity,
        shoulder=SHOULDER, base_mass=3.0, base_inertia=BASE_INERTIA, base_center=(0.02, 0.01, 0.15),
        actuators=actuators))
    elements = [
        SpatialBody("base", mass=3.0, inertia=BASE_INERTIA, center_of_mass=(0.02, 0.01, 0.15),
                    points={"shoulder": SHOULDER}),
        Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                    points={"out": (0.2, 0, 0.05)}),
        Revolute(name="shoulder", parent="base", point="shoulder", child="hub", axis=(0, 1, 0), actuated=True),
        SpatialBeam("b", **BEAM, geometric_stiffening=stiffening, damping_ratio=damping,
                    stations={"p1": 0.3, "p2": 0.7}),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=mount)]
    if tip:
        elements += [SpatialBody("tip", mass=0.3, inertia=TIP_INERTIA, center_of_mass=(0.03, 0.02, -0.01)),
                     Weld(name="m2", parent="b", child="tip", point="tip")]
    return SpatialModel("arm", elements, gravity=gravity), reference


@pytest.mark.parametrize("stiffening", [True, False])
def test_body_axis_actuators_equal_the_lagrange_generalised_forces(stiffening):
    model, reference = two_link(stiffening)
    ports = SpatialPorts(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, u = rng.normal(size=reference.n) * 0.3, rng.normal(size=reference.n) * 2
        free = reference.accelerations(q, u)
        assert np.abs(accelerations(model, q, u) - free).max() <= 1e-11 * np.abs(free).max()
        for k, (_, name) in enumerate(ACTUATORS):
            values = np.zeros(len(ACTUATORS))
            values[k] = 20.0
            expected = reference.accelerations(q, u, actuation=values)
            inputs = ports.inputs({name: 20.0})
            got = accelerations(model, q, u, 0.0, inputs.joint, inputs.wrenches)
            assert np.abs(expected - free).max() > 1e-5 * np.abs(free).max()       # the actuator acts
            assert np.abs(got - expected).max() <= 1e-11 * np.abs(expected).max(), name


def test_body_axes_turn_with_the_beam_and_world_axes_do_not():
    model, _ = two_link(gravity=(0.0, 0.0, 0.0))
    ports = SpatialPorts(model)
    q, u = np.zeros(model.n_positions), np.zeros(model.n_velocities)
    q[0] = 0.7                                            # yaw turned: body y is no longer world y
    body, world = (ports.inputs({f"b.tip.force{axes}_y": 1.0}) for axes in ("_body", ""))
    a_body = accelerations(model, q, u, 0.0, body.joint, body.wrenches)
    a_world = accelerations(model, q, u, 0.0, world.joint, world.wrenches)
    R = rotation((0, 0, 1), 0.7) @ MOUNT                   # the beam frame (shoulder at 0)
    turned = ports.inputs({"b.tip.force_x": R[0, 1], "b.tip.force_y": R[1, 1], "b.tip.force_z": R[2, 1]})
    a_turned = accelerations(model, q, u, 0.0, turned.joint, turned.wrenches)
    assert np.abs(a_body - a_turned).max() <= 1e-12 * np.abs(a_body).max()
    assert np.abs(a_body - a_world).max() > 1e-2 * np.abs(a_body).max()


# -- the planar restriction: the planar ModalBeam's station ports (its PZT actuator) ----------------------
def planar_arm():
    beam = ModalBeam("b", length=0.9, bending_stiffness=4.0, mass_per_length=0.5, n_modes=3, stiffness_damping=1e-3,
                     stations={"p1": 0.1, "p2": 0.35, "end": 0.9})
    return PlanarModel.chain("m", [Fixed("ground"), ActuatedHinge("motor"),
                                   RigidBody("hub", mass=1.0, inertia=0.2, center_of_mass=(0.0, 0.0), outboard=(0.05, 0.0)),
                                   FixedMounting("mount"), beam], gravity=(0.0, 0.0))


def spatial_arm(plane):
    axis = (0, 0, 1) if plane == "xy" else (0, -1, 0)
    modes = dict(n_modes_y=3, n_modes_z=0) if plane == "xy" else dict(n_modes_y=0, n_modes_z=3)
    inertia = np.diag([0.1, 0.1, 0.2]) if plane == "xy" else np.diag([0.1, 0.2, 0.1])
    return SpatialModel("s", [
        SpatialBody("hub", mass=1.0, inertia=inertia, points={"out": (0.05, 0, 0)}),
        Revolute(name="motor", parent=None, child="hub", axis=axis, actuated=True),
        SpatialBeam("b", length=0.9, bending_stiffness_y=4.0, bending_stiffness_z=4.0, mass_per_length=0.5, **modes,
                    stiffness_damping=1e-3, stations={"p1": 0.1, "p2": 0.35, "end": 0.9}),
        Weld(name="mount", parent="hub", child="b", point="out")], gravity=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("plane", ["xy", "xz"])
def test_the_piezo_pair_restricted_to_a_plane_is_the_planar_pzt_actuator(plane):
    planar, spatial = planar_arm(), spatial_arm(plane)
    beam = spatial.bodies[1]
    c, ka, kf = 0.01, 100.0, 3.0
    # planar: V = -ka (slope_rate(x2) - slope_rate(x1)), moments -c V at x1 and +c V at x2; a station force
    planar_loops = [Feedback("pd", [("motor.angle", 40.0), ("motor.rate", 6.0)], "motor.torque", gain=1.0),
                    Feedback("pzt", [("b.p2.slope_rate", ka), ("b.p1.slope_rate", -ka)],
                             [("b.p1.moment", -c), ("b.p2.moment", c)], gain=1.0),
                    Feedback("push", "b.end.w_dot", "b.p2.force", gain=kf)]
    # spatial: the planar slope is theta_z (x-y plane) or -theta_y (x-z plane, planar z = spatial -y)
    axis, sign, force = ("z", 1.0, "b.p2.force_body_y") if plane == "xy" else ("y", -1.0, "b.p2.force_body_z")
    deflection = "b.end.w_y_rate" if plane == "xy" else "b.end.w_z_rate"
    spatial_loops = [Feedback("pd", [("motor.angle", 40.0), ("motor.rate", 6.0)], "motor.torque", gain=1.0),
                     Feedback("pzt", patch_sensor(beam, "p1", "p2", axis=axis, gain=sign * ka),
                              patch_actuator(beam, "p1", "p2", axis=axis, coefficient=sign * c), gain=1.0),
                     Feedback("push", deflection, force, gain=kf)]
    x0, references = {"b.q1": 0.01}, {"pd": lambda t: 40.0 * min(t / 0.1, 1.0)}
    first = "b.qy1" if plane == "xy" else "b.qz1"
    planar_run = ctmm.simulate(with_feedback(planar, planar_loops), 0.2, 1e-3, method="rk4", x0=x0,
                               references=references)
    spatial_run = ctmm.simulate(with_feedback(spatial, spatial_loops), 0.2, 1e-3, method="rk4",
                                x0={first: 0.01}, references=references)
    names = [("hub.theta", "motor.angle")] + [(f"b.q{k}", f"{first[:-1]}{k}") for k in (1, 2, 3)] + \
        [("pzt.u", "pzt.u"), ("push.u", "push.u")]
    for planar_name, spatial_name in names:
        expected = planar_run[planar_name]
        assert np.abs(spatial_run[spatial_name] - expected).max() <= 1e-11 * np.abs(expected).max(), spatial_name
    open_run = ctmm.simulate(with_feedback(planar, [planar_loops[0], planar_loops[2]]), 0.2, 1e-3, method="rk4",
                             x0=x0, references=references)                  # without the piezo pair
    assert np.abs(open_run["b.q1"] - planar_run["b.q1"]).max() > 1e-3 * np.abs(planar_run["b.q1"]).max()


# -- every path ------------------------------------------------------------------------------------------
def controlled_arm(delay=0.0):
    model, _ = two_link(gravity=(0.0, 0.0, 0.0), damping=0.0, tip=False)          # tilted mount: both planes
    beam = model.bodies[2]
    loops = [Feedback("yaw_pd", [("yaw.angle", 30.0), ("yaw.rate", 4.0)], "yaw.torque", gain=1.0, delay=delay),
             Feedback("shoulder_pd", [("shoulder.angle", 40.0), ("shoulder.rate", 5.0)], "shoulder.torque", gain=1.0),
             Feedback("pzt_z", patch_sensor(beam, "p1", "p2", axis="z", gain=5.0),
                      patch_actuator(beam, "p1", "p2", axis="z", coefficient=1.0), gain=1.0),
             Feedback("pzt_y", patch_sensor(beam, "p1", "p2", axis="y", gain=5.0),
                      patch_actuator(beam, "p1", "p2", axis="y", coefficient=1.0), gain=1.0),
             Feedback("tip_push", "b.tip.w_z_rate", "b.tip.force_body_z", gain=0.5)]
    return with_feedback(model, loops)


MOVE = {"yaw_pd": lambda t: 30.0 * 0.5 * min(t / 0.1, 1.0), "shoulder_pd": lambda t: -40.0 * 0.3 * min(t / 0.1, 1.0)}


def test_dt_tmm_on_beam_actuator_loops_is_second_order_and_compiled_equals_numpy():
    # 0.05 s (half the reference ramp): measured Newmark 2.8e-6 / 7.1e-7 against the fine RK4, ratio 4.00, with
    # b.qz1 at -7.0e-3; the order needs the steps in the asymptotic range, not the whole move
    controlled = controlled_arm()
    fine = ctmm.simulate(controlled, 0.05, 2.5e-4, method="rk4", references=MOVE)
    errors = []
    for dt in (2e-3, 1e-3):
        run = ctmm.simulate(controlled, 0.05, dt, method="newmark", references=MOVE)
        errors.append(abs(run["b.qz1"][-1] - fine["b.qz1"][-1]))
    assert abs(fine["b.qz1"][-1]) > 1e-4
    assert 3.0 < errors[0] / errors[1] < 5.0                       # Newmark: second order
    numpy_run = ctmm.simulate(controlled, 0.05, 1e-3, method="rk4", references={"yaw_pd": 3.0, "shoulder_pd": -4.0})
    compiled = ctmm.simulate(controlled, 0.05, 1e-3, method="rk4", compiled=True,
                             references={"yaw_pd": 3.0, "shoulder_pd": -4.0})
    assert compiled.info["method"] == "rk4-generated"
    for name in ("b.qy1", "b.qz2", "b.twist1", "pzt_y.u", "tip_push.u"):
        assert np.abs(compiled[name] - numpy_run[name]).max() <= 1e-12 * np.abs(numpy_run[name]).max(), name


def test_compiled_loops_read_the_deformed_beam_points():
    # generated kernels state the beam's station and deformed-point sensors on symbols (a rigid-arm point
    # would miss Phi eta and Phi eta_dot)
    model, _ = two_link(gravity=(0.0, 0.0, 0.0), damping=0.0, tip=False)
    loops = [Feedback("tip_v", [("b.tip.vz", 1.0)], "b.tip.force_body_z", gain=2.0),
             Feedback("mid_y", [("b.p2.y", 1.0)], "yaw.torque", gain=5.0)]
    controlled = with_feedback(model, loops)
    x0 = {"b.qz1": 0.02, "b.qy1": -0.01}
    numpy_run = ctmm.simulate(controlled, 0.05, 1e-3, method="rk4", x0=x0, v0={"shoulder.angle_rate": 0.5})
    compiled = ctmm.simulate(controlled, 0.05, 1e-3, method="rk4", compiled=True, x0=x0,
                             v0={"shoulder.angle_rate": 0.5})
    assert compiled.info["method"] == "rk4-generated"
    for name in ("tip_v.u", "mid_y.u", "b.qz1", "yaw.angle"):
        assert np.abs(compiled[name] - numpy_run[name]).max() <= 1e-12 * np.abs(numpy_run[name]).max(), name


def test_controlled_frequency_response_equals_the_reference_linearisation_closed_by_hand():
    controlled = controlled_arm()
    pairs = ((0.3, "moment", 2), (0.7, "moment", 2), (0.3, "moment", 1), (0.7, "moment", 1), (1.1, "force", 2))
    _, reference = two_link(gravity=(0.0, 0.0, 0.0), damping=0.0, tip=False, actuators=pairs)
    n = reference.n
    A, B_force, B_act = reference.linearize(np.zeros(n))
    # the loops of controlled_arm on the reference's own rows, u = -gain (y - r), closed by hand
    closed = A.copy()
    for joint, (kp, kd) in ((0, (30.0, 4.0)), (1, (40.0, 5.0))):
        closed[:, joint] -= B_force[:, joint] * kp
        closed[:, n + joint] -= B_force[:, joint] * kd
    without = closed.copy()                                             # the joint loops alone
    for first, row in ((0, 2), (2, 1)):                                # pzt_z (theta_z), pzt_y (theta_y)
        sensed = 5.0 * (reference.section_rows(0.7)[row] - reference.section_rows(0.3)[row])   # of the rates
        closed[:, n:] -= np.outer(B_act[:, first + 1] - B_act[:, first], sensed)
    closed[:, n:] -= 0.5 * np.outer(B_act[:, 4], reference.deflection_rows(1.1)[2])
    omega = np.array([0.7, 3.0, 11.0, 40.0])
    frf = ctmm.frequency_response(controlled, omega, input="yaw_pd.reference", output=["b.tip.w_y", "b.tip.w_z"])
    tip = reference.deflection_rows(1.1)
    for k, w in enumerate(omega):
        response = np.linalg.solve(1j * w * np.eye(2 * n) - closed, B_force[:, 0])     # yaw torque = r
        expected = np.array([tip[1] @ response[:n], tip[2] @ response[:n]])
        got = np.array([frf("b.tip.w_y", "yaw_pd.reference")[k], frf("b.tip.w_z", "yaw_pd.reference")[k]])
        assert np.abs(got - expected).max() <= 1e-9 * np.abs(expected).max()
        assert abs(expected[1]) > 1e-2 * abs(expected[0])             # the yaw reference bends both planes
        joints_only = np.linalg.solve(1j * w * np.eye(2 * n) - without, B_force[:, 0])[:n]
        assert np.abs(tip[1:] @ joints_only - expected).max() > 1e-4 * np.abs(expected).max()   # the beam loops act


@pytest.mark.parametrize("first, second, axis, match", [
    ("p2", "p1", "z", "before"), ("p1", "nowhere", "z", "not a station"), ("p1", "p2", "w", "axis"),
    ("origin", "p2", "y", "not a station")])
def test_bad_patches_are_refused_with_the_parameter_named(first, second, axis, match):
    beam = spatial_arm("xy").bodies[1]
    with pytest.raises(ModelError, match=match):
        patch_actuator(beam, first, second, axis=axis)
    with pytest.raises(ModelError, match=match):
        patch_sensor(beam, first, second, axis=axis)
