"""Generated kernels of planar scenes with hinges whose pins move in translational springs (bushings, issue 13):
the generated accelerations and RK4 against the independent Lagrange model and the numpy sweep."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.compiled_parameters import compile_refusal, structure_key
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring
from ctmm.planar import (ElasticHinge, Fixed, Load, NonlinearHinge, Pinned, PlanarModel, RigidBody, SpringDamperHinge,
                         simulate_rk4)
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.signals import Harmonic

pytest.importorskip("casadi")


def arm(translational_stiffness: float = 200.0) -> PlanarModel:
    """A two-link arm whose elbow pin sits in an isotropic spring-damper, a sinusoidal force at the tip."""
    elbow = SpringDamperHinge("elbow", stiffness=8.0, damping=0.05, rest_angle=0.3,
                              translational_stiffness=translational_stiffness, translational_damping=0.5)
    tip = RigidBody.uniform_link("b", mass=0.6, length=0.7, loads=[Load(point=(0.7, 0.0),
                                                                        force_y=Harmonic(3.0, 7.0, 0.2))])
    return PlanarModel.chain("arm", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0), elbow, tip])


Q0, V0 = np.array([0.2, 0.01, -0.02, 0.6]), np.array([0.3, -0.1, 0.2, -0.5])


def test_bushings_compile_and_equal_the_lagrange_model_and_the_numpy_rk4():
    from ctmm.compiled_scene import CompiledScene, simulate_rk4_generated

    model = arm()
    assert model.coordinates == ("a.theta", "b.dx", "b.dy", "b.theta") and compile_refusal(model) == ""
    scene = CompiledScene(model, store_every=10)
    for t in (0.0, 0.13):                          # the load's sine evaluated in the generated code
        expected = PlanarLagrange(model).accelerations(Q0, V0, t)
        got = np.asarray(scene._acceleration(Q0, V0, np.zeros(len(scene.actuators)), scene.parameters, t)).ravel()
        assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected))
    generated = simulate_rk4_generated(model, Q0, V0, t_final=0.2, dt=1e-3, store_every=10, scene=scene)
    numpy_run = simulate_rk4(model, Q0, V0, t_final=0.2, dt=1e-3, store_every=10)
    assert np.max(np.abs(generated.q - numpy_run.q)) < 1e-12
    assert np.max(np.abs(generated.qdot - numpy_run.qdot)) < 1e-11
    assert np.max(np.abs(generated.q[-1, 1:3] - Q0[1:3])) > 1e-3             # the offsets moved
    reference = PlanarLagrange(model).simulate(Q0, V0, 0.2, t_eval=[0.2]).y[:4, -1]
    assert np.max(np.abs(generated.q[-1] - reference)) < 1e-8                 # RK4 at dt = 1 ms


def test_a_nonlinear_radial_spring_compiles_and_equals_the_numpy_sweep():
    from ctmm.compiled_scene import CompiledScene
    from ctmm.planar.body_forms import PlanarScene

    model = PlanarModel("bushing", [Fixed("g"), RigidBody.uniform_link("l", mass=1.0, length=1.0),
                                    NonlinearHinge("h", parent="g", child="l", moment_law=CubicSpring(1.0, 3.0),
                                                   radial_law=CubicSpring(2000.0, 5e6))], gravity=(0.0, -9.81))
    assert compile_refusal(model) == ""
    q, v = np.array([0.003, -0.001, 0.4]), np.array([0.1, 0.05, -0.3])
    expected = PlanarScene(model).accelerations(q[None], v[None], 0.0)[0]
    assert np.max(np.abs(CompiledScene(model).accelerations(q, v) - expected)) <= 1e-12 * np.max(np.abs(expected))


def test_the_translational_springs_are_part_of_the_structure():
    """Their numbers are constants of the code: a model with another spring does not reuse a library."""
    from ctmm.compiled_scene import CompiledScene

    assert structure_key(arm(200.0)) != structure_key(arm(300.0))
    with pytest.raises(ModelError, match="another structure"):
        CompiledScene(arm(200.0)).with_model(arm(300.0))


def test_symbolic_points_follow_the_offsets():
    """The loops' sensor and cut kinematics on symbols (``SymbolicKinematics``) = ``PlanarModel.points``."""
    import casadi as ca

    from ctmm.compiled_planar_sensors import SymbolicKinematics

    model = PlanarModel.chain("arm", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                      ElasticHinge("elbow", stiffness=8.0, translational_stiffness=200.0),
                                      RigidBody.uniform_link("b", mass=0.6, length=0.7)])
    q, v = ca.SX.sym("q", 4), ca.SX.sym("v", 4)
    kinematics = SymbolicKinematics(model, q, v)
    (r, r_dot) = kinematics.point(1, "com")
    f = ca.Function("f", [q, v], [ca.vertcat(*r, *r_dot)])
    points = model.points(Q0, V0)
    got = np.asarray(f(Q0, V0)).ravel()
    assert np.max(np.abs(got - np.concatenate([points["com"][1], points["com_velocity"][1]]))) < 1e-14


def test_a_loop_on_a_point_of_the_offset_body_equals_the_numpy_path():
    """A real-time loop reading the tip link's centre of mass (it moves with the bushing offset) and driving
    the elbow torque: the generated RK4 with the loop in the step equals the numpy loop driver's RK4."""
    import ctmm
    from ctmm.control import Feedback, with_feedback

    controlled = with_feedback(arm(), [Feedback("tip", [("b.com.y", 3.0), ("b.com.vx", 0.2)], "elbow.torque",
                                                gain=0.5)])
    x0 = dict(zip(arm().coordinates, Q0))
    generated = ctmm.simulate(controlled, 0.1, 1e-3, method="rk4", compiled=True, x0=x0, store_every=10)
    plain = ctmm.simulate(controlled, 0.1, 1e-3, method="rk4", x0=x0, store_every=10)
    for name in arm().coordinates:
        np.testing.assert_allclose(generated[name], plain[name], rtol=0, atol=1e-12)
    assert np.ptp(generated["b.dy"]) > 1e-3


def test_the_generated_newmark_scheme_equals_the_numpy_scheme():
    """The generated DT-TMM Newmark (Newton on the generated accelerations' exact tangent) on the bushing arm."""
    import ctmm

    model = arm()
    x0 = dict(zip(model.coordinates, Q0))
    generated = ctmm.simulate(model, 0.1, 1e-3, method="newmark", compiled=True, x0=x0)
    plain = ctmm.simulate(model, 0.1, 1e-3, method="newmark", x0=x0)
    assert generated.info["method"] == "dt-tmm-generated/Newmark"
    for name in model.coordinates:
        np.testing.assert_allclose(generated[name], plain[name], rtol=0, atol=1e-11)


def test_a_kinematic_loop_closed_at_the_tip_of_the_offset_body_equals_the_numpy_path():
    """A link on a bushing whose tip is pinned to the ground by a cut joint: the generated RK4 with the cut forces
    and the projection in the step (its cut point moves with the offset) equals the numpy RK4 with projection."""
    import ctmm
    from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel

    tree = PlanarModel("p", [Fixed("g"), Fixed("anchor", position=(1.0, 0.0)),
                             RigidBody.uniform_link("l", mass=1.0, length=1.0),
                             ElasticHinge("h", parent="g", child="l", stiffness=3.0, translational_stiffness=1e3)],
                       gravity=(0.0, -9.81))
    loop = KinematicLoopModel(tree, [CutJoint("c", parent="anchor", child="l.out")])
    x0, v0 = {"l.dx": 0.0, "l.dy": 0.0, "l.theta": 0.0}, {"l.dx": 0.0, "l.dy": 0.1, "l.theta": -0.1}
    generated = ctmm.simulate(loop, 0.05, 1e-3, method="rk4", compiled=True, x0=x0, v0=v0)
    plain = ctmm.simulate(loop, 0.05, 1e-3, method="rk4", x0=x0, v0=v0)
    assert generated.scheme_name == "rk4-generated"
    for name in tree.coordinates:
        np.testing.assert_allclose(generated[name], plain[name], rtol=0, atol=1e-12)
    assert np.ptp(generated["l.dy"]) > 1e-3
