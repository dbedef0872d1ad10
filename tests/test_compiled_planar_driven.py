"""Generated planar kernels with a moving driven hinge (issue 13): the drive's angle, rate and acceleration
(:mod:`ctmm.signals` Harmonic, Ramp) are symbolic functions of the stage time inside the generated RK4, with
feedback loops whose sensors move with the drive, over parameter sets, and in the generated DT-TMM schemes.

Independent references: the numpy RK4 / DT-TMM scheme of the same model (generated = numpy to round-off: the
contract of generated code) and, for the reaction torque of the drive, the Newton-Euler equation of a single rod
driven about its end, ``tau = (I_c + m a^2) theta'' + m g a cos(theta)``, evaluated on the expressions the
generated kernel compiles (the articulated sweep on the time symbol).  Signals without a symbolic form and the
paths that state the model at one time refuse by name.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError
from ctmm.planar import DrivenHinge, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge
from ctmm.planar import elements as planar_elements
from ctmm.signals import Harmonic, Ramp

ca = pytest.importorskip("casadi")

G = 9.81
A, W, PHASE = 0.4, 3.0, 0.2            # harmonic drive: A sin(W t + PHASE) [rad]


def harmonic_drive(name: str = "motor", **where) -> DrivenHinge:
    return DrivenHinge(name, angle=Harmonic(A, W, PHASE), rate=Harmonic(A * W, W, PHASE + math.pi / 2),
                       acceleration=Harmonic(-A * W * W, W, PHASE), **where)


def ramp_drive(name: str = "motor", **where) -> DrivenHinge:
    return DrivenHinge(name, angle=Ramp(4.0, 0.3), rate=4.0, **where)     # a crank at 4 rad/s from 0.3 rad


def double_pendulum(drive: DrivenHinge) -> PlanarModel:
    """A driven link carrying a free link on a smooth hinge, under gravity."""
    return PlanarModel.chain("driven_pendulum", [
        planar_elements.Fixed("g"), drive, RigidBody.uniform_link("l1", mass=1.0, length=0.5),
        SmoothHinge("h2"), RigidBody.uniform_link("l2", mass=0.7, length=0.4)], gravity=(0.0, -G))


def assert_round_off(value, expected, name, tolerance=1e-12):
    scale = max(1.0, float(np.max(np.abs(expected))))
    assert np.max(np.abs(np.asarray(value) - expected)) < tolerance * scale, name


@pytest.mark.parametrize("drive", [harmonic_drive, ramp_drive], ids=["harmonic", "ramp"])
def test_driven_double_pendulum_generated_equals_numpy_rk4(drive):
    model = double_pendulum(drive())
    options = dict(method="rk4", x0={"l2.theta": 0.3}, v0={"l2.theta": -0.5})
    generated = ctmm.simulate(model, 1.0, 1e-3, compiled=True, **options)
    python = ctmm.simulate(model, 1.0, 1e-3, compiled=False, **options)
    assert generated.info["method"] == "rk4-generated" and python.info["method"] == "rk4"
    assert np.ptp(python["l2.theta"]) > 0.5                 # the drive moves the free link
    for name in ("l2.theta", "l2.theta_dot"):
        assert_round_off(generated[name], python[name], name)


def test_a_crank_driving_modal_beams_generated_equals_numpy_rk4():
    """Crank at constant speed -> modal beam -> fixed mounting -> damped beam -> spring-damper hinge -> link: the
    drive's angle and rate enter the beams' kinematics on the time symbol (generated = numpy to round-off)."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar.elements import FixedMounting

    def beam(name, **options):
        return ModalBeam(name, length=0.8, bending_stiffness=4.0, mass_per_length=0.6, n_modes=2, **options)

    model = PlanarModel.chain("driven_beams", [
        planar_elements.Fixed("g"), DrivenHinge("motor", angle=Ramp(1.5, 0.1), rate=1.5), beam("b1"),
        FixedMounting("w", angle=0.2), beam("b2", damping_ratio=0.01),
        SpringDamperHinge("e", stiffness=3.0, damping=0.05, rest_angle=0.1),
        RigidBody.uniform_link("l", mass=0.3, length=0.4)], gravity=(0.0, -G))
    x0 = {"l.theta": 0.4}
    generated = ctmm.simulate(model, 0.3, 1e-3, method="rk4", compiled=True, x0=x0)
    python = ctmm.simulate(model, 0.3, 1e-3, method="rk4", compiled=False, x0=x0)
    assert generated.info["method"] == "rk4-generated" and np.ptp(python["b1.q1"]) > 1e-2
    for name in model.coordinates:
        assert_round_off(generated[name], python[name], name)


def test_a_welded_cantilever_and_a_beam_at_a_constant_drive_angle_generated_equal_numpy_rk4():
    """A beam whose angle is a number (Fixed + ModalBeam, the plain cantilever; a DrivenHinge with a constant
    angle) failed to compile with numpy's TypeError 'float ... has no callable cos method'."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar.elements import FixedMounting

    def beam(name):
        return ModalBeam(name, length=0.8, bending_stiffness=4.0, mass_per_length=0.6, n_modes=2, stations={"tip": 0.8})

    cantilever = PlanarModel.chain("cantilever", [planar_elements.Fixed("g"), beam("b")], gravity=(0.0, -G))
    held = PlanarModel.chain("held", [planar_elements.Fixed("g"), DrivenHinge("motor", angle=0.3),
                                      RigidBody("hub", mass=1.0, inertia=0.05, center_of_mass=(0.05, 0.0),
                                                outboard=(0.1, 0.0)), FixedMounting("m"), beam("b")], gravity=(0.0, -G))
    for model in (cantilever, held):
        options = dict(method="rk4", x0={"b.q1": 0.01}, inputs={"b.tip.force": 0.2})
        generated = ctmm.simulate(model, 0.2, 1e-3, compiled=True, **options)
        python = ctmm.simulate(model, 0.2, 1e-3, compiled=False, **options)
        assert generated.info["method"] == "rk4-generated" and np.ptp(python["b.q1"]) > 1e-3
        for name in model.coordinates:
            assert_round_off(generated[name], python[name], name)


def test_the_drive_numbers_are_inputs_of_one_library():
    """Two drives of one class with other numbers run on one compiled scene (their numbers are entries of ``p``),
    each equal to its own numpy run; a drive of another signal class is another structure."""
    from ctmm.compiled_parameters import parameter_vector, structure_key
    from ctmm.compiled_scene import CompiledScene

    model = double_pendulum(harmonic_drive())
    other = double_pendulum(DrivenHinge("motor", angle=Harmonic(0.7, 2.0, -0.4),
                                        rate=Harmonic(1.4, 2.0, -0.4 + math.pi / 2),
                                        acceleration=Harmonic(-2.8, 2.0, -0.4)))
    assert structure_key(model) == structure_key(other)
    assert parameter_vector(model).size == parameter_vector(other).size
    assert structure_key(double_pendulum(ramp_drive())) != structure_key(model)
    scene = CompiledScene(model).with_model(other)
    q0, v0 = np.array([0.3]), np.array([-0.5])
    states = scene.run(q0, v0, 1e-3, 500)
    python = ctmm.simulate(other, 0.5, 1e-3, method="rk4", compiled=False, x0={"l2.theta": 0.3},
                           v0={"l2.theta": -0.5})
    assert_round_off(states[-1, 0], python["l2.theta"][-1], "l2.theta")


def crank_system(gain: float = 3.0, stiffness: float = 2.0) -> ControlledModel:
    """A crank turning at constant speed carries an arm on a spring-damper hinge; a PD loop on the hinge's relative
    angle and rate (sensors that move with the drive) drives the hinge torque."""
    plant = PlanarModel.chain("crank", [
        planar_elements.Fixed("g"), ramp_drive(), RigidBody.uniform_link("crank", mass=0.5, length=0.2),
        SpringDamperHinge("h", stiffness=stiffness, damping=0.05), RigidBody.uniform_link("arm", mass=0.3, length=0.4)],
        gravity=(0.0, -G))
    return ControlledModel(plant, [Feedback("pd", [("h.angle", 1.0), ("h.rate", 0.2)], "h.torque", gain=gain)])


def test_driven_crank_with_a_feedback_loop_generated_equals_numpy():
    system = crank_system()
    options = dict(method="rk4", x0={"arm.theta": 0.5})
    generated = ctmm.simulate(system, 1.0, 1e-3, compiled=True, **options)
    python = ctmm.simulate(system, 1.0, 1e-3, compiled=False, **options)
    assert generated.info["method"] == "rk4-generated"
    assert np.ptp(python["pd.u"]) > 0.1
    for name in ("arm.theta", "arm.theta_dot", "pd.y", "pd.u"):
        assert_round_off(generated[name], python[name], name)


def test_driven_crank_sets_with_loops_equal_their_numpy_runs():
    """``simulate_batch`` over a loop gain and a hinge stiffness, the sets stepped together: the drive is the same
    in every set (its signals are not parameters: one motion, checked consistent when the hinge is built)."""
    from ctmm.parameter_sets import parameter_names

    assert not any("drive" in name for name in parameter_names(crank_system()))
    sets = [{"pd.gain": 3.0, "h.stiffness": 2.0}, {"pd.gain": 8.0, "h.stiffness": 5.0}]
    batch = ctmm.simulate_batch(crank_system(), sets, 0.3, 1e-3, x0={"arm.theta": 0.5})
    assert not batch.failures
    assert np.max(np.abs(batch.stacked("pd.u")[0] - batch.stacked("pd.u")[1])) > 1e-3
    for values, result in zip(sets, batch.results):
        python = ctmm.simulate(crank_system(values["pd.gain"], values["h.stiffness"]), 0.3, 1e-3, method="rk4",
                               compiled=False, x0={"arm.theta": 0.5})
        for name in ("arm.theta", "pd.u"):
            assert_round_off(result[name], python[name], name)


@pytest.mark.parametrize("method", ["newmark", "generalized_alpha"])
def test_driven_double_pendulum_generated_scheme_equals_numpy_scheme(method):
    model = double_pendulum(harmonic_drive())
    options = dict(method=method, x0={"l2.theta": 0.3})
    generated = ctmm.simulate(model, 0.5, 1e-3, compiled=True, **options)
    python = ctmm.simulate(model, 0.5, 1e-3, compiled=False, **options)
    assert "generated" in generated.info["method"]
    assert np.ptp(python["l2.theta"]) > 0.1
    for name in ("l2.theta", "l2.theta_dot"):
        assert_round_off(generated[name], python[name], name, 1e-10)


def test_driven_crank_scheme_with_loops_on_coordinates_and_moving_sensors_refused():
    """A generated Newmark step closes loops whose sensors are coordinates (= the numpy scheme to round-off); loop
    sensors that move with the drive are read at the state only there, so refused by name (the RK4 takes them)."""
    plant = crank_system().plant
    still = ControlledModel(plant, [Feedback("pd", [("arm.theta", 1.0), ("arm.omega", 0.2)], "h.torque", gain=3.0)])
    options = dict(method="newmark", x0={"arm.theta": 0.5})
    generated = ctmm.simulate(still, 0.3, 1e-3, compiled=True, **options)
    python = ctmm.simulate(still, 0.3, 1e-3, compiled=False, **options)
    assert "generated" in generated.info["method"] and np.ptp(python["pd.u"]) > 0.1
    for name in ("arm.theta", "pd.u"):
        assert_round_off(generated[name], python[name], name, 1e-10)
    with pytest.raises(ModelError, match=r"loop sensors move with the prescribed motion of driven joints"):
        ctmm.simulate(crank_system(), 0.1, 1e-3, compiled=True, **options)


def test_reaction_torque_of_a_driven_rod_against_newton_euler():
    """A uniform rod (m, L) driven about its end by a harmonic angle: the moment of the ground on the rod at the
    hinge is ``tau = (m L^2 / 3) theta'' + m g (L / 2) cos(theta)``; here from the articulated sweep on the time
    symbol (the expressions the generated kernel compiles, the drive's numbers as inputs ``p``)."""
    from ctmm.articulated import articulated_sweep
    from ctmm.compiled_parameters import parameter_vector, symbolic_numbers
    from ctmm.ops import CASADI
    from ctmm.planar.body_forms import PlanarScene

    m, length = 1.3, 0.8
    model = PlanarModel.chain("rod", [planar_elements.Fixed("g"), harmonic_drive(),
                                      RigidBody.uniform_link("rod", mass=m, length=length)], gravity=(0.0, -G))
    p0 = parameter_vector(model)
    t, p = ca.SX.sym("t"), ca.SX.sym("p", p0.size)
    none = ca.SX.sym("q", 0)
    bodies, joints = PlanarScene(model).terms(CASADI, none, none, 0.0, None, symbolic_numbers(model, p, t))
    solution = articulated_sweep(CASADI, PlanarScene(model).tree, bodies, joints)
    torque = ca.Function("torque", [p, t], [solution.force[0][2]])
    for time in (0.0, 0.21, 0.77, 1.9):
        theta = A * math.sin(W * time + PHASE)
        alpha = -A * W * W * math.sin(W * time + PHASE)
        expected = m * length ** 2 / 3 * alpha + m * G * length / 2 * math.cos(theta)
        assert float(torque(p0, time)) == pytest.approx(expected, rel=1e-13, abs=1e-13)


def test_signals_without_a_symbolic_form_and_one_time_paths_refuse_by_name(tmp_path):
    user = DrivenHinge("motor", angle=lambda t: 0.3 * math.sin(t), rate=lambda t: 0.3 * math.cos(t),
                       acceleration=lambda t: -0.3 * math.sin(t))
    with pytest.raises(ModelError, match=r"time-dependent signals without a symbolic form in 'motor'"):
        ctmm.simulate(double_pendulum(user), 0.1, 1e-3, method="rk4", compiled=True)
    from ctmm.compiled_parameters import compile_refusal

    model = double_pendulum(harmonic_drive())
    assert compile_refusal(model, driven_signals=True) == ""
    assert "driven hinges whose motion is not constant: 'motor'" in compile_refusal(model)
    with pytest.raises(ModelError, match=r"driven hinges whose motion is not constant: 'motor'"):
        ctmm.export_fmu(model, tmp_path / "driven.fmu", step=1e-3)
    with pytest.raises(ModelError, match=r"planar_simulation_sensitivity: .*motion is not constant: .motor."):
        ctmm.sensitivity.simulation_sensitivity(model, ["l2.mass"], t_final=0.1, dt=1e-3)


def test_a_kinematic_loop_tree_with_a_moving_drive_is_refused_by_name():
    """The generated kinematic-loop paths state the tree's kinematics at the state only: a four-bar whose crank is a
    moving driven hinge is refused by name (the numpy loop driver runs it)."""
    from ctmm.compiled_kinematic_loops import kinematic_loop_compile_refusal
    from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel

    tree = PlanarModel("driven_four_bar", [
        planar_elements.Fixed("g", position=(0.0, 0.0)), planar_elements.Fixed("g4", position=(0.6, 0.0)),
        RigidBody.uniform_link("crank", mass=0.3, length=0.2), ramp_drive(parent="g", child="crank"),
        RigidBody.uniform_link("coupler", mass=0.5, length=0.6), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.4, length=0.4), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -G))
    loop = KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out")])
    assert "driven hinges whose motion is not constant: 'motor'" in kinematic_loop_compile_refusal(loop)
