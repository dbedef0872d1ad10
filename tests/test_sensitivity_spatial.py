"""Exact sensitivities of spatial models, controlled or not (ctmm.sensitivity_spatial,
ctmm.sensitivity_time_spatial): against closed forms of a body on a revolute joint closed by a PD loop
(root, frequency response and free-response derivatives, delay included) and against
Richardson-extrapolated central differences of the library's verbs (ctmm.frequency_response,
ctmm.stability.spectral_abscissa, ctmm.control.margins, ctmm.linearize, ctmm.simulate) on rebuilt models:
the elastic-hinge body of scenarios/spatial_elastic_hinge_control (quaternion tangent coordinates, an
equilibrium that sags with the mass and gravity) and a two-body arm under gravity (a sensor that moves
with the equilibrium)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm import sensitivity as S
from ctmm.control import Constraint, Feedback, Quantity, margins, tune, with_feedback
from ctmm.errors import ModelError
from scenarios import spatial_elastic_hinge_control as hinge
from ctmm.state_space_characteristic import characteristic_of
from tests.test_sensitivity import central_difference, relative

def richardson(f, system, name: str) -> np.ndarray:
    """Central difference extrapolated over h, h/2 (error O(h^4)), ``h = 1e-3 |value|`` (inertias of 0.05 kg m^2)."""
    v = S.parameter_values(system, [name])[name]
    h = 1e-3 * abs(v)

    def central(step):
        return (np.asarray(f(S.with_parameters(system, {name: v + step})))
                - np.asarray(f(S.with_parameters(system, {name: v - step})))) / (2 * step)

    return (4 * central(h / 2) - central(h)) / 3


def refined_abscissa(system, **region) -> float:
    """The rightmost root of ctmm.stability.spectral_abscissa (accurate to its reported error, ~1e-15 here)
    refined by Newton on the library's characteristic function (ctmm.state_space_characteristic) to round-off."""
    root = ctmm.stability.spectral_abscissa(system, **region).root
    f = characteristic_of(system)
    for _ in range(20):
        d = 1e-6 * (1.0 + abs(root))
        value, up, down = f(np.array([root, root + d, root - d]))
        step = value / ((up - down) / (2 * d))
        root -= step
        if abs(step) < 1e-15 * abs(root):
            break
    return float(root.real)


MASS, INERTIA, ARM, K, C, KP, KD = 2.0, 0.3, 0.4, 5.0, 0.2, 10.0, 1.0
ROTOR_NAMES = ["link.mass", "link.inertia.zz", "j.stiffness", "j.damping", "pd.gain", "pd.j.angle", "pd.j.rate"]


def rotor(delay: float = 0.0):
    """A body on a revolute joint about the vertical (gravity along the axis) with a PD loop on the joint:
    ``I s^2 + c s + k + (kp + kd s) e^{-s tau} = 0``, ``I = I_zz + m d^2``."""
    model = sp.SpatialModel("rotor", [
        sp.SpatialBody("link", MASS, np.diag([0.1, 0.2, INERTIA]), center_of_mass=(ARM, 0.0, 0.0)),
        sp.Revolute(name="j", parent=None, child="link", axis=(0, 0, 1), stiffness=K, damping=C, actuated=True)])
    return with_feedback(model, [Feedback("pd", [("j.angle", KP), ("j.rate", KD)], "j.torque", gain=1.0,
                                          delay=delay)])


def rotor_terms(s, delay=0.0):
    """``P(s)``, ``dP/ds`` and ``dP/dp`` (``ROTOR_NAMES`` order) of the characteristic function."""
    inertia = INERTIA + MASS * ARM ** 2
    e = np.exp(-s * delay)
    P = inertia * s ** 2 + C * s + K + (KP + KD * s) * e
    P_s = 2 * inertia * s + C + KD * e - delay * (KP + KD * s) * e
    P_p = [ARM ** 2 * s ** 2, s ** 2, 1.0, s, (KP + KD * s) * e, e, s * e]
    return P, P_s, P_p, -s * (KP + KD * s) * e


def test_revolute_pd_root_and_response_derivatives_match_the_closed_form():
    found = S.spectral_abscissa_sensitivity(rotor(), ROTOR_NAMES)
    inertia, c, k = INERTIA + MASS * ARM ** 2, C + KD, K + KP
    root = (-c + np.sqrt(complex(c * c - 4 * inertia * k))) / (2 * inertia)
    assert abs(found.root - root) < 1e-12
    _, P_s, P_p, _ = rotor_terms(root)
    for name, dP in zip(ROTOR_NAMES, P_p):
        assert abs(found.root_gradient[name] - (-dP / P_s)) < 1e-10, name
    omega = np.array([0.5, 4.0, 11.0])
    response = S.frequency_response_sensitivity(rotor(), ROTOR_NAMES, omega, input="j.torque", output="j.angle")
    s = 1j * omega
    P, _, P_p, _ = rotor_terms(s)
    assert relative(response.response, 1.0 / P) < 1e-12
    for i, name in enumerate(ROTOR_NAMES):
        assert relative(response.derivative[i], -np.asarray(P_p[i]) / P ** 2) < 1e-10, name


def test_delayed_revolute_pd_root_derivative_matches_the_closed_form():
    delay = 0.05
    found = S.spectral_abscissa_sensitivity(rotor(delay), ROTOR_NAMES + ["pd.delay"], re_min=-5.0, im_max=30.0)
    assert found.method == "characteristic roots"
    P, P_s, P_p, P_tau = rotor_terms(found.root, delay)
    assert abs(P) < 1e-9 * abs(P_s)
    for name, dP in zip(ROTOR_NAMES + ["pd.delay"], P_p + [P_tau]):
        assert abs(found.root_gradient[name] - (-dP / P_s)) < 1e-9, name


def test_spatial_terms_are_built_once_per_structure_and_evaluated_with_each_models_numbers():
    # ctmm.sensitivity_spatial_terms: the rotor with other numbers (a stiffness, a mass, a loop gain) is served by the
    # one build of its structure and evaluated with its own numbers -- equal to a fresh build and to the closed form;
    # another geometry (the centre of mass) or a number set to zero (a constant of the expression) is another build
    from ctmm.sensitivity_spatial_terms import SpatialTerms, spatial_terms, structure_description
    from ctmm.spatial.ports import SpatialPorts
    from ctmm.spatial_linearization import operating_point
    from ctmm.compiled_spatial_parameters import spatial_parameter_vector
    from ctmm.sensitivity_spatial import spatial_parameter_index

    names = ["j.stiffness", "link.mass", "pd.gain"]

    def closed_form(system, arm_length):
        k, mass, gain = (S.parameter_values(system, names)[n] for n in names)
        inertia, c, stiffness = INERTIA + mass * arm_length ** 2, C + gain * KD, k + gain * KP
        root = (-c + np.sqrt(complex(c * c - 4 * inertia * stiffness))) / (2 * inertia)
        P_s = 2 * inertia * root + c
        return root, {n: -dP / P_s for n, dP in zip(names, [1.0, arm_length ** 2 * root ** 2,
                                                              KP + KD * root])}

    def terms_of(system):
        plant = system.plant
        ports = SpatialPorts(plant)
        indices = [-1 if n.startswith("pd.") else spatial_parameter_index(plant, n) for n in names]
        return plant, ports, tuple(ports.actuators), indices

    base = rotor()
    changed = S.with_parameters(base, {"j.stiffness": 7.5, "link.mass": 2.6, "pd.gain": 1.4})
    moved = with_feedback(sp.SpatialModel("rotor", [
        sp.SpatialBody("link", MASS, np.diag([0.1, 0.2, INERTIA]), center_of_mass=(0.5, 0.0, 0.0)),
        sp.Revolute(name="j", parent=None, child="link", axis=(0, 0, 1), stiffness=K, damping=C, actuated=True)]),
        list(base.loops))
    undamped = S.with_parameters(base, {"j.damping": 0.0})
    assert structure_description(base.plant) == structure_description(changed.plant)
    assert structure_description(moved.plant) != structure_description(base.plant)
    assert structure_description(undamped.plant) != structure_description(base.plant)
    shared = spatial_terms(*terms_of(base))
    assert spatial_terms(*terms_of(changed)) is shared and spatial_terms(*terms_of(moved)) is not shared
    plant = changed.plant
    point = operating_point(plant, None)
    served = shared.linearisation(point.q, spatial_parameter_vector(plant), point.t)
    fresh = SpatialTerms(*terms_of(changed)).linearisation(point.q, spatial_parameter_vector(plant), point.t)
    nominal = shared.linearisation(point.q, spatial_parameter_vector(base.plant), point.t)
    for a, b, c in zip(served, fresh, nominal):
        assert np.max(np.abs(a - b), initial=0.0) <= 1e-14 * max(np.max(np.abs(b), initial=0.0), 1.0)
    assert np.max(np.abs(served[0] - nominal[0])) > 0.1 * np.max(np.abs(nominal[0]))      # the numbers are honoured
    omega = np.array([0.5, 4.0, 11.0])
    for system, arm_length in ((base, ARM), (changed, ARM), (moved, 0.5), (base, ARM)):
        found = S.spectral_abscissa_sensitivity(system, names)
        root, gradient = closed_form(system, arm_length)
        assert abs(found.root - root) < 1e-12 * abs(root)
        for n in names:
            assert abs(found.root_gradient[n] - gradient[n]) < 1e-10 * max(1.0, abs(gradient[n])), n
        # a point sensor row (the centre of mass across the arm: y = d sin(theta)), served from the memo per record
        k, mass, gain = (S.parameter_values(system, names)[n] for n in names)
        s = 1j * omega
        P = (INERTIA + mass * arm_length ** 2) * s ** 2 + C * s + k + gain * (KP + KD * s)
        response = S.frequency_response_sensitivity(system, names, omega, input="j.torque", output="link.com.y")
        assert relative(response.response, arm_length / P) < 1e-12
        for i, dP in enumerate([1.0, arm_length ** 2 * s ** 2, KP + KD * s]):
            assert relative(response.derivative[i], -arm_length * dP / P ** 2) < 1e-10, names[i]


def test_revolute_pd_free_response_derivatives_match_the_closed_form():
    # I theta'' + (c + kd) theta' + (k + kp) theta = 0 from theta0: RK4 at 1 ms against the exact solution and
    # its exact derivatives (complex step of the closed form); they differ by the RK4 error only
    theta0, T, dt = 0.3, 1.0, 1e-3
    found = S.simulation_sensitivity(rotor(), ["pd.j.angle", "pd.j.rate", "link.inertia.zz", "j.stiffness"],
                                     t_final=T, dt=dt, x0={"j.angle": theta0}, outputs=["j.angle"])

    def exact(kp, kd, izz, k):
        inertia, c, stiffness = izz + MASS * ARM ** 2, C + kd, k + kp
        sigma = -c / (2 * inertia)
        w = np.sqrt(stiffness / inertia - sigma ** 2)
        return theta0 * np.exp(sigma * found.time) * (np.cos(w * found.time) - sigma / w * np.sin(w * found.time))

    base = [KP, KD, INERTIA, K]
    peak = np.max(np.abs(exact(*base)))
    assert np.max(np.abs(found.values[0] - exact(*base))) < 1e-9 * peak
    for i in range(4):
        shifted = [complex(x) for x in base]
        shifted[i] += 1e-30j
        slope = exact(*shifted).imag / 1e-30
        assert relative(found.derivative[i, 0], slope) < 1e-7, i


ELASTIC_NAMES = ["body.mass", "body.inertia.zz", "body.inertia.xx", "gravity.z", "yaw_pd.body.angle_z",
                 "yaw_pd.body.omega_z", "yaw_pd.gain"]


def test_elastic_hinge_response_derivatives_match_differences_of_the_verb():
    system = with_feedback(hinge.model(), [hinge.loop(0.004)])
    omega = np.array([5.0, 20.0, 40.0])
    names = ELASTIC_NAMES + ["yaw_pd.delay"]
    for input_name, output_name in (("body.force_x", "body.angle_y"), ("body.moment_y", "body.com.x")):
        found = S.frequency_response_sensitivity(system, names, omega, input=input_name, output=output_name)

        def H(s):
            return ctmm.frequency_response(s, omega, input=input_name, output=output_name)(output_name)

        assert relative(found.response, H(system)) < 1e-10
        for i, name in enumerate(names):          # one central difference: measured <= 3.5e-8 (yaw_pd.delay)
            assert relative(found.derivative[i], central_difference(H, system, name)) < 1e-6, (output_name, name)


def test_elastic_hinge_abscissa_is_polished_to_round_off_against_the_closed_loop_eigenvalues():
    """Without delay the closed loop is the linearisation's A: its rightmost eigenvalue (dense eigvals) is the
    abscissa.  The root search's Newton steps take Cauchy integrals of a Delta that each evaluation divides by a
    positive (not holomorphic) scale; unless the scale is multiplied back on each circle, Newton crawled (2 s a
    search) and the reported error stayed at 7.6e-6."""
    system = with_feedback(hinge.model(), [hinge.loop(0.0)])
    found = ctmm.stability.spectral_abscissa(system, re_min=-3.0, im_max=100.0)
    expected = np.max(np.linalg.eigvals(np.asarray(ctmm.linearize(system, inputs=[]).state_space.A)).real)
    assert found.error < 1e-12
    assert abs(found.value - expected) < 1e-12


@pytest.mark.slow
def test_elastic_hinge_abscissa_and_delay_margin_match_differences_of_the_verbs():
    # one central difference of each verb per number (its root search is the cost): measured errors <= 8e-10
    # (bound 1e-6; Richardson over 1e-3, 5e-4 gave <= 1e-12)
    system = with_feedback(hinge.model(), [hinge.loop(0.004)])
    region = dict(re_min=-3.0, im_max=100.0)
    names = ["body.mass", "yaw_pd.body.omega_z"]
    root = S.spectral_abscissa_sensitivity(system, names, **region)
    for name in names:
        fd = central_difference(lambda s: refined_abscissa(s, **region), system, name)
        assert abs(root.gradient[name] - fd) < 1e-6 * max(1.0, abs(fd)), name
    w = np.linspace(2.0, 120.0, 400)
    found = S.margin_sensitivity(system, "yaw_pd", ["body.inertia.zz", "yaw_pd.delay"], w)
    assert abs(found.margins.delay_margin - margins(system, "yaw_pd", w).delay_margin) < 1e-12
    for name in ("body.inertia.zz", "yaw_pd.delay"):
        fd = central_difference(lambda s: margins(s, "yaw_pd", w).delay_margin, system, name)
        assert abs(found.delay_margin[name] - fd) < 1e-6 * max(1.0, abs(fd)), name


def arm() -> sp.SpatialModel:
    """Two bodies under gravity: a shoulder about the horizontal y axis with a spring and a rest angle, a
    universal elbow with springs; the equilibrium sags with every number."""
    return sp.SpatialModel("arm", [
        sp.SpatialBody("upper", 1.5, np.diag([0.02, 0.05, 0.04]), center_of_mass=(0.2, 0.0, 0.0),
                       points={"elbow": (0.4, 0.0, 0.0)}),
        sp.Revolute(name="shoulder", parent=None, child="upper", axis=(0, 1, 0), stiffness=40.0, damping=0.3,
                    reference=0.2, actuated=True),
        sp.SpatialBody("lower", 0.8, [[0.01, 0.002, 0.0], [0.002, 0.02, 0.0], [0.0, 0.0, 0.025]],
                       center_of_mass=(0.15, 0.0, 0.01), points={"tip": (0.3, 0.0, 0.0)}),
        sp.Universal(name="elbow", parent="upper", child="lower", point="elbow", axis1=(0, 1, 0), axis2=(0, 0, 1),
                     stiffness=(12.0, 8.0), damping=(0.1, 0.05), reference=(-0.1, 0.05))])


ARM_NAMES = ["upper.mass", "lower.inertia.xy", "shoulder.stiffness", "shoulder.reference", "elbow.stiffness[0]",
             "elbow.damping[1]", "gravity.z"]


def test_arm_response_and_abscissa_match_differences_with_a_moving_sensor():
    model = arm()
    omega = np.array([1.0, 7.0, 25.0])

    def H(s):
        return ctmm.frequency_response(s, omega, input="shoulder.torque", output="lower.tip.z")("lower.tip.z")

    found = S.frequency_response_sensitivity(model, ARM_NAMES, omega, input="shoulder.torque", output="lower.tip.z")
    assert relative(found.response, H(model)) < 1e-10
    for i, name in enumerate(ARM_NAMES):          # one central difference: measured <= 6.9e-8 (elbow.damping[1])
        assert relative(found.derivative[i], central_difference(H, model, name)) < 1e-6, name
    root = S.spectral_abscissa_sensitivity(model, ARM_NAMES)

    def abscissa(s):
        return np.max(np.linalg.eigvals(np.asarray(ctmm.linearize(s, inputs=[]).state_space.A)).real)

    assert abs(root.value - abscissa(model)) < 1e-10
    for name in ARM_NAMES:                        # measured <= 1.3e-8 (lower.inertia.xy)
        assert abs(root.gradient[name] - central_difference(abscissa, model, name)) < 1e-6, name


def test_spatial_histories_match_differences_of_the_simulation():
    # the arm alone (a point sensor as output) and the elastic-hinge body with a delayed PD (loop numbers)
    # (the derivative of the same discrete RK4 run is compared: 40 steps of 5 ms for the arm, 30 steps of 2 ms for
    # the hinge, whose 4 ms delay is two steps; one central difference per number: measured relative error
    # <= 4.9e-8, bound 1e-6, in gravity.z, where the Richardson extrapolation over 1e-3, 5e-4 gave 1.2e-8)
    cases = [(arm(), ARM_NAMES[1:4], {"shoulder.angle": 0.4, "elbow.angle1": -0.3}, {},
              ["lower.tip.z", "elbow.q2_rate"], 0.2, 5e-3)]
    q0, v0 = hinge.initial_state()
    plant = hinge.model()
    cases.append((with_feedback(plant, [hinge.loop(0.004)]), ["body.mass", "gravity.z", "yaw_pd.body.angle_z",
                                                              "yaw_pd.gain"],
                  dict(zip(plant.coordinates, q0)), dict(zip(plant.velocities, v0)), ["body.angle_z", "hinge.wz"],
                  0.06, 2e-3))
    for system, names, x0, v0d, outputs, T, dt in cases:
        found = S.simulation_sensitivity(system, names, t_final=T, dt=dt, x0=x0, v0=v0d, outputs=outputs)

        def history(s):
            run = ctmm.simulate(s, T, dt, x0=x0, v0=v0d, outputs=outputs, method="rk4")
            return np.array([run[name] for name in outputs])

        assert np.max(np.abs(found.values - history(system))) < 1e-12
        for i, name in enumerate(names):
            assert relative(found.derivative[i], central_difference(history, system, name)) < 1e-6, name


def spherical_pendulum() -> sp.SpatialModel:
    return sp.SpatialModel("ball", [
        sp.SpatialBody("bob", 0.7, [[0.02, 0.001, 0.0], [0.001, 0.03, 0.0], [0.0, 0.0, 0.015]],
                       center_of_mass=(0.05, 0.02, -0.3)),
        sp.Spherical(name="ball", parent=None, child="bob", actuated=True)], gravity=(0.0, 0.0, -9.81))


def test_spherical_pendulum_with_a_neutral_yaw_matches_differences_or_is_refused():
    # hanging from a ball joint the body may turn freely about the vertical (a neutral direction): what does not
    # depend on that turn (child-axes rates and torques) is differentiated; a world position is refused
    model = spherical_pendulum()
    names = ["bob.mass", "bob.inertia.xy", "bob.inertia.zz", "gravity.z"]
    omega = np.array([1.0, 4.0, 13.0])

    def H(s):
        return ctmm.frequency_response(s, omega, input="ball.torque_y", output="bob.omega_body_y")("bob.omega_body_y")

    found = S.frequency_response_sensitivity(model, names, omega, input="ball.torque_y", output="bob.omega_body_y")
    for i, name in enumerate(names):
        assert relative(found.derivative[i], richardson(H, model, name)) < 1e-6, name
    for output, input_name in (("bob.com.x", "ball.torque_y"), ("bob.omega_body_y", "bob.moment_x")):
        with pytest.raises(ModelError, match="neutral in 1 direction"):
            S.frequency_response_sensitivity(model, ["bob.mass"], omega, input=input_name, output=output)
    assert S.frequency_response_sensitivity(model, [], omega, input="bob.moment_x", output="bob.com.x").response.size


def test_spatial_refusals_name_what_is_allowed():
    with pytest.raises(ModelError, match="whole number of steps"):
        S.simulation_sensitivity(rotor(0.01), ["pd.delay"], t_final=0.02, dt=0.01)
    with pytest.raises(ModelError, match="constant of the generated expression"):
        S.frequency_response_sensitivity(arm(), ["lower.inertia.yz"], [1.0], input="shoulder.torque",
                                         output="lower.tip.z")
    with pytest.raises(ModelError, match="rotation-vector"):
        S.frequency_response_sensitivity(arm(), ["upper.mass"], [1.0], input="shoulder.torque",
                                         output="lower.rotation_x")
    # beams: tests/test_sensitivity_spatial_beam.py


@pytest.mark.slow
def test_tune_the_elastic_hinge_yaw_pd_for_the_smallest_resonance_under_a_delay_margin():
    # the yaw PD of scenarios/spatial_elastic_hinge_control: the smallest peak of |theta_z / m_z| with a delay
    # margin of at least 35 ms (the scenario's gains have 39.8 ms and a peak of 0.066 rad/(N m))
    system = with_feedback(hinge.model(), [hinge.loop(0.0)])
    names = ["yaw_pd.body.angle_z", "yaw_pd.body.omega_z"]
    w = np.linspace(2.0, 120.0, 400)
    peak = Quantity("response_peak", input="body.moment_z", output="body.angle_z", omega=w)
    result = tune(system, names, peak, [Constraint(Quantity("delay_margin", loop="yaw_pd", omega=w), lower=0.035)],
                  bounds={names[0]: (0.0, 60.0), names[1]: (0.0, 6.0)})
    assert result.success and result.feasible
    tuned = S.with_parameters(system, result.parameters)
    assert abs(margins(tuned, "yaw_pd", w).delay_margin - 0.035) < 1e-6           # the constraint is active
    response = ctmm.frequency_response(tuned, np.linspace(2.0, 120.0, 4000), input="body.moment_z",
                                       output="body.angle_z")("body.angle_z")
    assert abs(result.objective - np.max(np.abs(response))) < 1e-6 * result.objective
    assert result.objective < 0.4 * 0.066
    # first-order optimality: the objective's gradient is parallel to the active constraint's
    g_peak = np.array([S.peak_sensitivity(tuned, names, w, input="body.moment_z",
                                          output="body.angle_z").gradient[n] for n in names])
    g_margin = np.array([S.margin_sensitivity(tuned, "yaw_pd", names, w).delay_margin[n] for n in names])
    assert abs(g_peak[0] * g_margin[1] - g_peak[1] * g_margin[0]) < 1e-3 * np.linalg.norm(g_peak) * \
        np.linalg.norm(g_margin)
