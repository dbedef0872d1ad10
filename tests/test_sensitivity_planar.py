"""Exact sensitivities of planar models, controlled or not (ctmm.sensitivity_planar): against
Richardson-extrapolated central differences of the library's verbs (ctmm.frequency_response,
ctmm.linearize, ctmm.stability.spectral_abscissa, ctmm.control.margins) on rebuilt models, and
against the closed form of a link hanging from a spring-damper hinge with a rest angle (whose
equilibrium moves with the numbers: the implicit function theorem part)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import sensitivity as S
from ctmm.control import Constraint, Feedback, Quantity, margins, tune, with_feedback
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, DamperHinge, Fixed, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar.elements import FixedMounting
from tests.test_sensitivity import central_difference, relative, richardson

G, LENGTH = 9.81, 0.5


def link(k: float = 3.0, c: float = 0.2, mass: float = 1.0, rest: float = 0.4) -> PlanarModel:
    return PlanarModel.chain("arm", [Fixed("base"), SpringDamperHinge("motor", stiffness=k, damping=c, rest_angle=rest),
                                     RigidBody.uniform_link("link", mass=mass, length=LENGTH)])


def two_link() -> PlanarModel:
    return PlanarModel.chain("arm2", [Fixed("base"), SpringDamperHinge("motor", stiffness=2.0, damping=0.1,
                                                                       rest_angle=0.3),
                                      RigidBody.uniform_link("upper", mass=1.0, length=0.5),
                                      SpringDamperHinge("elbow", stiffness=4.0, damping=0.3),
                                      RigidBody.uniform_link("lower", mass=0.6, length=0.4)])


def pd_arm(delay: float = 0.03, kd: float = 1.5):
    pd = Feedback("pd", [("motor.angle", 8.0), ("motor.rate", kd)], "motor.torque", gain=1.0, delay=delay)
    return with_feedback(two_link(), [pd])


def check_response(system, names, omega, input_name, output_name):
    """The FRF and its derivatives against the verb and Richardson differences of it on rebuilt systems."""
    found = S.frequency_response_sensitivity(system, names, omega, input=input_name, output=output_name)

    def H(s):
        return ctmm.frequency_response(s, omega, input=input_name, output=output_name)(output_name)

    assert relative(found.response, H(system)) < 1e-10
    for i, name in enumerate(names):
        assert relative(found.derivative[i], richardson(H, system, name)) < 1e-6, name


def test_hanging_link_matches_its_closed_form_with_the_moving_equilibrium():
    k, c, m, rest = 3.0, 0.2, 1.0, 0.4
    model = link(k, c, m, rest)
    omega = np.array([0.5, 2.0, 5.0, 9.0])
    names = ["link.mass", "link.inertia", "motor.stiffness", "motor.damping"]
    found = S.frequency_response_sensitivity(model, names, omega, input="motor.torque", output="link.theta")
    lc, inertia = LENGTH / 2, m * LENGTH ** 2 / 12
    theta = ctmm.linearize(model).operating_point.q[0]
    assert abs(k * (theta - rest) + m * G * lc * np.cos(theta)) < 1e-10          # the equilibrium
    stiffness = k - m * G * lc * np.sin(theta)
    s = 1j * omega
    H = 1.0 / ((inertia + m * lc ** 2) * s ** 2 + c * s + stiffness)
    dtheta_dk = -(theta - rest) / stiffness
    dtheta_dm = -G * lc * np.cos(theta) / stiffness
    expected = [-H ** 2 * (lc ** 2 * s ** 2 - G * lc * np.sin(theta) - m * G * lc * np.cos(theta) * dtheta_dm),
                -H ** 2 * s ** 2,
                -H ** 2 * (1.0 - m * G * lc * np.cos(theta) * dtheta_dk),
                -H ** 2 * s]
    assert relative(found.response, H) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], expected[i]) < 1e-10, name


def test_planar_frequency_response_derivatives_match_differences_of_the_verb():
    model = two_link()
    omega = np.array([0.4, 1.7, 3.3, 8.0])
    names = ["upper.mass", "lower.inertia", "motor.stiffness", "elbow.damping"]
    check_response(model, names, omega, "elbow.torque", "lower.theta")


def test_hub_with_a_modal_beam_and_an_actuated_hinge_match_differences_of_the_verb():
    hub_beam = PlanarModel.chain("hub_beam", [
        Fixed("base"), SpringDamperHinge("motor", stiffness=20.0, damping=0.5, rest_angle=0.2),
        RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.0), outboard=(0.2, 0.0)),
        FixedMounting("mount"), ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2,
                                          damping_ratio=0.02)])
    omega = np.array([0.5, 3.0, 12.0])
    check_response(hub_beam, ["hub.mass", "hub.inertia", "motor.stiffness", "motor.damping"], omega,
                   "motor.torque", "b.q2")
    actuated = PlanarModel.chain("actuated", [Fixed("base"), ActuatedHinge("motor", kp=5.0, kd=0.3, reference=0.2),
                                              RigidBody.uniform_link("link", mass=1.0, length=LENGTH)])
    check_response(actuated, ["motor.stiffness", "motor.damping", "link.mass"], omega, "motor.torque",
                   "link.theta")


def test_controlled_planar_derivatives_match_differences_with_a_delayed_pd_loop():
    system = pd_arm()
    names = ["upper.mass", "elbow.stiffness", "pd.motor.angle", "pd.motor.rate", "pd.delay", "pd.gain"]
    omega = np.array([0.7, 2.5, 6.0])
    check_response(system, names, omega, "elbow.torque", "upper.theta")
    region = dict(re_min=-3.0, im_max=40.0)
    root = S.spectral_abscissa_sensitivity(system, names, **region)
    assert root.method == "characteristic roots"
    for name in names:
        fd = richardson(lambda s: ctmm.stability.spectral_abscissa(s, **region).value, system, name)
        assert abs(root.gradient[name] - fd) < 1e-6 * max(1.0, abs(fd)), name


def test_delay_free_planar_abscissa_and_margins_match_differences():
    system = pd_arm(delay=0.0)
    names = ["upper.mass", "lower.inertia", "motor.damping", "pd.motor.angle", "pd.motor.rate"]
    root = S.spectral_abscissa_sensitivity(system, names)
    assert root.method == "quadratic eigenvalues"

    def abscissa(s):
        return np.max(np.linalg.eigvals(np.asarray(ctmm.linearize(s, inputs=[]).state_space.A)).real)

    assert abs(root.value - abscissa(system)) < 1e-10
    for name in names:
        assert abs(root.gradient[name] - richardson(abscissa, system, name)) < 1e-6, name
    delayed = pd_arm(delay=0.02)
    w = np.linspace(0.05, 40.0, 600)
    margin_names = ["upper.mass", "pd.motor.rate", "pd.delay"]
    found = S.margin_sensitivity(delayed, "pd", margin_names, w)
    assert np.isfinite(found.margins.delay_margin)
    for name in margin_names:
        fd = richardson(lambda s: margins(s, "pd", w).delay_margin, delayed, name)
        assert abs(found.delay_margin[name] - fd) < 1e-6 * max(1.0, abs(fd)), name


def test_refusals_name_what_is_allowed():
    with pytest.raises(ModelError, match="lower.length|allowed"):
        S.frequency_response_sensitivity(two_link(), ["lower.length"], [1.0], input="elbow.torque",
                                         output="lower.theta")
    with pytest.raises(ModelError, match="0 in the model"):
        damped = PlanarModel.chain("damped", [Fixed("base"), DamperHinge("motor", damping=0.2),
                                              RigidBody.uniform_link("link", mass=1.0, length=LENGTH)])
        S.frequency_response_sensitivity(damped, ["motor.stiffness"], [1.0], input="motor.torque",
                                         output="link.theta")
    # a point position moves with the equilibrium: refused, not silently wrong
    with pytest.raises(ModelError, match="depends on the configuration"):
        S.frequency_response_sensitivity(link(), ["motor.stiffness"], [1.0], input="motor.torque",
                                         output="link.com.x")


def test_tune_a_planar_pd_arm_for_damping_under_a_delay_margin():
    # from kd = 0.5 (delay margin 0.083 s < 0.1 s: infeasible) to the most damped feasible rate gain
    system = pd_arm(delay=0.0, kd=0.5)
    w = np.linspace(0.05, 40.0, 400)
    assert margins(system, "pd", w).delay_margin < 0.1
    result = tune(system, ["pd.motor.rate"], Quantity("spectral_abscissa"),
                  [Constraint(Quantity("delay_margin", loop="pd", omega=w), lower=0.1)],
                  bounds={"pd.motor.rate": (0.0, 4.0)})
    assert result.success and result.feasible
    tuned = S.with_parameters(system, result.parameters)
    assert margins(tuned, "pd", w).delay_margin >= 0.1
    A = np.asarray(ctmm.linearize(tuned, inputs=[]).state_space.A)
    assert abs(result.objective - np.max(np.linalg.eigvals(A).real)) < 1e-10
    assert result.objective < -4.9                          # from -0.70 1/s at the start


@pytest.mark.parametrize("delay, lti", [(0.0, False), (0.02, False), (0.0, True)])
def test_controlled_planar_histories_match_differences_of_the_simulation(delay, lti):
    # loops inside the generated RK4: real-time, delayed (ring of samples), LTI controller (its states); one central
    # difference of the numpy RK4 per number (h = 1e-4 |p|; measured relative error <= 3.9e-9, bound 1e-6)
    import control

    gain = control.tf([1.0], [0.05, 1.0]) if lti else 1.0
    pd = Feedback("pd", [("motor.angle", 8.0), ("motor.rate", 1.5)], "motor.torque", gain=gain, delay=delay)
    system = with_feedback(two_link(), [pd])
    names = ["upper.mass", "elbow.stiffness", "pd.motor.rate", "pd.gain", "pd.motor.angle"]
    found = S.simulation_sensitivity(system, names, t_final=0.5, dt=0.01, q0=[0.5, -0.3],
                                     outputs=["lower.theta", "upper.theta_dot"])

    def history(s):
        sim = ctmm.simulate(s, t_final=0.5, dt=0.01, method="rk4", x0={"upper.theta": 0.5, "lower.theta": -0.3})
        return np.array([sim["lower.theta"], sim["upper.theta_dot"]])

    assert np.max(np.abs(found.values - history(system))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, system, name)) < 1e-6, name
    with pytest.raises(ModelError, match="whole number of steps"):
        S.simulation_sensitivity(system, ["pd.delay"], t_final=0.1, dt=0.01, q0=[0.5, -0.3])


def test_controller_realisation_entries_in_time_match_differences_of_the_simulation():
    # "<loop>.A[0,0]", "<loop>.C[0]" of an LTI controller given as a state-space system, alone and together with
    # a sensor weight (the loop then stated per sensor term: every term's controller moves)
    import control

    A, B, C, D = -20.0, 4.0, 5.0, 0.0

    def system(a=A, c=C):
        pd = Feedback("pd", [("motor.angle", 8.0), ("motor.rate", 1.5)], "motor.torque",
                      gain=control.ss([[a]], [[B]], [[c]], [[D]]), delay=0.02)
        return with_feedback(two_link(), [pd])

    def history(s):
        sim = ctmm.simulate(s, t_final=0.3, dt=0.01, method="rk4", x0={"upper.theta": 0.5, "lower.theta": -0.3})
        return sim["lower.theta"]

    for names in (["pd.A[0,0]", "pd.C[0]"], ["pd.A[0,0]", "pd.C[0]", "pd.motor.rate"]):
        found = S.simulation_sensitivity(system(), names, t_final=0.3, dt=0.01, q0=[0.5, -0.3], outputs="lower.theta")
        assert np.max(np.abs(found.values[0] - history(system()))) < 1e-12
        for i, (name, build) in enumerate((("pd.A[0,0]", lambda h: system(a=A + h)),
                                           ("pd.C[0]", lambda h: system(c=C + h)))):
            h = 1e-3 * 20.0

            def central(step):
                return (history(build(step)) - history(build(-step))) / (2 * step)

            assert relative(found.derivative[i, 0], (4 * central(h / 2) - central(h)) / 3) < 1e-6, (names, name)
