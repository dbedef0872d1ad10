"""Every DT-TMM scheme of :mod:`ctmm.schemes` on planar models (rigid and with modal beams),
and actuator inputs closed around the plant in the implicit stepper.

Each scheme's nonlinear form (``Scheme.second_order_step``) drives the implicit planar stepper;
its order is measured on a step ladder against independent global references (the Lagrange
model of :mod:`ctmm.reference.planar_lagrange` / :mod:`ctmm.reference.flexible_lagrange`,
DOP853 at tight tolerance), and the pre-run stability check is compared with what the stepper
actually does on either side of the limit it reports.
"""
from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
import scipy.integrate

from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.guard import StabilityLimitWarning
from ctmm.planar import (ActuatedHinge, ElasticHinge, Load, Pinned, PlanarModel, RigidBody, SmoothHinge,
                         SpringDamperHinge, accelerations, simulate_implicit)
from ctmm.planar.actuated_newton import InputError
from ctmm.planar.elements import FixedMounting
from ctmm.planar.guards import check_scheme, linearised_omega_max
from ctmm.planar.ports import PlanarPorts
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import (SCHEMES, ForwardEuler, GeneralizedAlpha, Houbolt, Newmark, Scheme,
                          WilsonTheta, as_scheme)

# every registered name, and parameter variants that change the coefficients
VARIANTS = [*SCHEMES, WilsonTheta(1.0), GeneralizedAlpha(0.3), Newmark(beta=0.3, gamma=0.6)]
EXPECTED_ORDER = {"forward_euler": 1, "Newmark(beta=0.3, gamma=0.6)": 1}


def _label(scheme) -> str:
    return scheme if isinstance(scheme, str) else repr(scheme)


def _ladder(case, scheme, dts):
    """Final errors against the reference, local orders and the mean Newton sweeps per step."""
    model, q0, v0, T, ref = case
    runs = [simulate_implicit(model, q0, v0, t_final=T, dt=dt, scheme=scheme) for dt in dts]
    errors = np.array([np.max(np.abs(run.q[-1] - ref)) for run in runs])
    slopes = np.log(errors[:-1] / errors[1:]) / np.log(np.asarray(dts[:-1]) / dts[1:])
    return errors, slopes, max(run.iterations.mean() for run in runs)


@pytest.fixture(scope="module")
def double_pendulum():
    """Double pendulum with a spring-damper hinge and a time-varying tip load (the evaluation
    time of Wilson-theta matters), and its Lagrange reference at T."""
    model = PlanarModel.chain("dp", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
        SpringDamperHinge("h", stiffness=4.0, damping=0.3, rest_angle=0.2),
        RigidBody.uniform_link("b", mass=0.7, length=0.8,
                               loads=(Load(point=(0.8, 0.0), force_y=lambda t: 2.0 * math.sin(3.0 * t)),))])
    q0, v0, T = np.array([-0.6, -0.2]), np.array([0.5, -0.3]), 1.0
    ref = PlanarLagrange(model).simulate(q0, v0, T, t_eval=[T], rtol=1e-13, atol=1e-13).y[:2, -1]
    return model, q0, v0, T, ref


@pytest.mark.parametrize("scheme", VARIANTS, ids=_label)
def test_every_scheme_converges_at_its_order_on_a_double_pendulum(double_pendulum, scheme):
    order = EXPECTED_ORDER.get(_label(scheme), 2)
    assert as_scheme(scheme).order == order
    errors, slopes, iterations = _ladder(double_pendulum, scheme, [0.01, 0.005, 0.0025])
    assert np.all(np.abs(slopes - order) < 0.1), (slopes, errors)
    assert errors[-1] < (0.03 if order == 1 else 2e-3)
    assert iterations <= 3.5                           # Newton stays quadratic with every scheme


@pytest.fixture(scope="module")
def hub_beam():
    """Hub with a two-mode cantilever; global assumed-modes reference (no transfer matrices)."""
    beam = ModalBeam("b", length=1.0, bending_stiffness=1.0, mass_per_length=0.7, n_modes=2)
    model = PlanarModel.chain("hub-beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam])
    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    q0[:2], v0[0] = (0.3, 0.02), 2.0
    T = 0.2
    ref = FlexibleLagrange(model).simulate(q0, v0, T, t_eval=[T], rtol=1e-12, atol=1e-13).y[:n, -1]
    return model, q0, v0, T, ref


@pytest.mark.parametrize("scheme", list(SCHEMES), ids=_label)
def test_every_scheme_converges_at_its_order_on_a_hub_beam(hub_beam, scheme):
    order = EXPECTED_ORDER.get(scheme, 2)
    errors, slopes, iterations = _ladder(hub_beam, scheme, [4e-3, 2e-3, 1e-3])
    assert np.all(np.abs(slopes - order) < 0.1), (slopes, errors)
    assert iterations <= 3.5


@pytest.mark.parametrize("scheme", [ForwardEuler(), WilsonTheta(1.2), Houbolt(), Newmark(0.3, 0.6)], ids=repr)
def test_the_generic_nonlinear_form_is_the_schemes_own_linear_step(scheme):
    """On ``x'' = -w^2 x`` one nonlinear step (solved in closed form) equals one step of the
    chain core's linearisation (``coefficients`` / ``update``) of the same scheme."""
    w2, h = 9.0, 0.05
    history = scheme.start_history(np.array([0.3]), np.array([-0.2]), np.array([-w2 * 0.3]))
    for _ in range(4):                                  # through Houbolt's start-up
        plan = scheme.second_order_step(history, h)
        a = -w2 * plan.q_predictor / (1.0 + w2 * plan.position_weight)
        coefficients = scheme.coefficients(history, h)
        delta = -w2 * coefficients.x_pred / (coefficients.C + w2)
        linear = scheme.update(history, delta, h, coefficients)
        history = scheme.second_order_update(history, a, h, plan)
        for name in ("x", "v", "a"):
            assert np.allclose(getattr(history, name), getattr(linear, name), rtol=1e-13, atol=1e-15), name


def test_newmark_and_generalized_alpha_keep_the_arnold_bruls_form():
    """Newmark's own statement equals the generic derivation from its coefficients; the
    generalized-alpha step keeps the equations of motion at t_{n+1} with
    ``beta' = beta (1 - af)/(1 - am)``."""
    history = Newmark().start_history(np.array([0.3, -1.0]), np.array([0.5, 2.0]), np.array([-1.0, 4.0]))
    own, generic = Newmark(0.3, 0.6).second_order_step(history, 0.01), Scheme.second_order_step(
        Newmark(0.3, 0.6), history, 0.01)
    assert np.allclose(own.q_predictor, generic.q_predictor, rtol=1e-15, atol=1e-15)
    assert np.allclose(own.v_predictor, generic.v_predictor, rtol=1e-15, atol=1e-15)
    assert math.isclose(own.position_weight, generic.position_weight, rel_tol=1e-14)
    assert math.isclose(own.velocity_weight, generic.velocity_weight, rel_tol=1e-14)
    alpha = GeneralizedAlpha(0.6)
    plan = alpha.second_order_step(history, 0.01)
    factor = (1.0 - alpha.alpha_f) / (1.0 - alpha.alpha_m)
    assert plan.time_fraction == 1.0
    assert math.isclose(plan.position_weight, alpha.beta * factor * 1e-4, rel_tol=1e-14)
    assert math.isclose(plan.velocity_weight, alpha.gamma * factor * 1e-2, rel_tol=1e-14)


def test_scheme_names_and_errors(double_pendulum):
    model, q0, v0, _, _ = double_pendulum
    run = simulate_implicit(model, q0, v0, t_final=0.02, dt=0.01, scheme="houbolt")
    assert run.method == "dt-tmm/Houbolt"
    with pytest.raises(ModelError, match=r"unknown scheme 'rk45'; available: forward_euler, generalized_alpha, "
                                         r"houbolt, newmark, wilson_theta"):
        simulate_implicit(model, q0, v0, t_final=0.02, dt=0.01, scheme="rk45")


@pytest.fixture(scope="module")
def stiff_and_slow():
    """A slow pendulum carrying a stiff spring hinge (no damping): ``omega_max`` from the stiff
    mode, ``omega_min`` from the swing; small amplitude, so nearly linear."""
    model = PlanarModel.chain("stiff", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
        ElasticHinge("k", stiffness=400.0), RigidBody.uniform_link("b", mass=0.5, length=0.5)])
    q0, v0 = np.array([-math.pi / 2 + 0.05, -math.pi / 2 + 0.06]), np.zeros(2)
    omega_max, omega_min = linearised_omega_max(model, q0, v0, slowest=True)
    return model, q0, v0, omega_max, omega_min


def _stiff_mode_amplification(model, q0, v0, dt, scheme) -> float:
    """Largest relative angle over the last third of 150 steps (or of the steps before the run
    failed) / the initial one: late, after Wilson-theta's first-step overshoot (-32 x at
    ``omega h = 15``, ``theta = 1.4``, as in the linear recurrence) has decayed."""
    try:
        run = simulate_implicit(model, q0, v0, t_final=150 * dt, dt=dt, scheme=scheme, stability_check="ignore")
    except SimulationError as exc:                      # Newton lost on a growing solution
        run = exc.partial_result
    relative = np.abs(run.q[:, 1] - run.q[:, 0])
    return float(np.max(relative[2 * len(relative) // 3:]) / relative[0])


@pytest.mark.parametrize("scheme, limit", [
    (WilsonTheta(1.0), 2.0 * math.sqrt(3.0)), (Newmark(0.05, 0.5), 1.0 / math.sqrt(0.2)),
    (WilsonTheta(1.2), None)])
def test_conditionally_stable_schemes_are_checked_against_their_limit(stiff_and_slow, scheme, limit):
    model, q0, v0, omega_max, omega_min = stiff_and_slow
    limit = scheme.stability_limit() if limit is None else limit
    assert math.isclose(scheme.stability_limit(), limit, rel_tol=1e-8)
    below, above = 0.95 * limit / omega_max, 1.1 * limit / omega_max
    assert omega_min * above < math.pi                  # the slow swing is resolved: only stability speaks
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_scheme(model, q0, v0, below, scheme=scheme, policy="error") is None
    with pytest.warns(StabilityLimitWarning, match=re.escape(repr(scheme))):
        simulate_implicit(model, q0, v0, t_final=above, dt=above, scheme=scheme)
    with pytest.raises(ModelError, match="omega"):
        check_scheme(model, q0, v0, above, scheme=scheme, policy="error")
    # what the stepper does on either side of the reported limit
    assert _stiff_mode_amplification(model, q0, v0, below, scheme) < 1.5
    assert _stiff_mode_amplification(model, q0, v0, above, scheme) > 10.0


@pytest.mark.parametrize("scheme", ["forward_euler", "houbolt", "generalized_alpha", "newmark",
                                    WilsonTheta(1.4)], ids=_label)
def test_unconditionally_stable_schemes_only_ask_for_resolution(stiff_and_slow, scheme):
    model, q0, v0, omega_max, omega_min = stiff_and_slow
    scheme = as_scheme(scheme)
    assert scheme.stability_limit() == math.inf
    dt = 0.05                      # twice any finite limit, swing resolved (Newton from the last
    assert omega_max * dt > 7.0 and omega_min * dt < 0.1 * math.pi    # acceleration: dt <~ 0.1 s here)
    assert check_scheme(model, q0, v0, dt, scheme=scheme, policy="error") is None
    assert _stiff_mode_amplification(model, q0, v0, dt, scheme) < 1.5
    with pytest.raises(ModelError, match="no motion is resolved"):
        check_scheme(model, q0, v0, 1.1 * math.pi / omega_min, scheme=scheme, policy="error")


# ------------------------------------------------------------------------------------------
# actuator inputs closed around the plant (``simulate_implicit(..., inputs=)``)
# ------------------------------------------------------------------------------------------
def _two_links(second, body_loads=()) -> PlanarModel:
    return PlanarModel.chain("two", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0, loads=body_loads), second,
        RigidBody.uniform_link("b", mass=0.7, length=0.8)])


def _pd_inputs(model: PlanarModel, kp: float, kd: float, extra=None):
    """``inputs``: the PD law of ``ActuatedHinge("h", kp, kd, reference=0.3)`` on hinge ``h``
    (between coordinates 0 and 1) plus ``extra`` actuator values (numbers or functions of t)."""
    ports = PlanarPorts(model)

    def inputs(t, q, qdot):
        values = {"h.torque": -kp * (q[1] - q[0] - 0.3) - kd * (qdot[1] - qdot[0])}
        values.update({name: value(t) if callable(value) else value for name, value in (extra or {}).items()})
        return ports.inputs(values)

    return inputs


@pytest.mark.parametrize("scheme", list(SCHEMES))
@pytest.mark.parametrize("kp, kd", [(400.0, 20.0), (1e4, 200.0)], ids=["pd", "stiff-pd"])
def test_a_pd_torque_given_as_inputs_equals_the_same_pd_in_the_hinge(scheme, kp, kd):
    """The hinge law enters the tangent exactly (kappa); the same law as ``inputs`` through the
    finite-difference input tangent: same trajectory to round-off, same Newton iterations.
    A large force at the centre of mass of ``a`` (= a Load there) turns with the link: its
    moment's angle derivative is in the tangent too."""
    q0, v0 = np.array([-0.6, -0.28]), np.array([0.5, -0.3])     # 0.02 rad off the reference
    push = lambda t: 60.0 * math.cos(4.0 * t)  # noqa: E731
    hinge = _two_links(ActuatedHinge("h", kp=kp, kd=kd, reference=0.3),
                       body_loads=(Load(point=(0.5, 0.0), force_x=push, force_y=20.0),))
    plain = _two_links(SmoothHinge("h"))
    inputs = _pd_inputs(plain, kp, kd, {"a.force_x": push, "a.force_y": 20.0})

    embedded = simulate_implicit(hinge, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, tolerance=1e-12)
    closed = simulate_implicit(plain, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, tolerance=1e-12,
                               inputs=inputs)
    assert np.max(np.abs(closed.q - embedded.q)) < 1e-9
    assert np.max(np.abs(closed.qdot - embedded.qdot)) < 1e-8
    assert closed.iterations.mean() <= embedded.iterations.mean() + 0.05


def test_a_pd_torque_given_as_inputs_against_the_lagrange_model():
    kp, kd = 400.0, 20.0
    plain = _two_links(SmoothHinge("h"))
    q0, v0, T = np.array([-0.6, -0.2]), np.array([0.5, -0.3]), 1.0
    ref = PlanarLagrange(_two_links(ActuatedHinge("h", kp=kp, kd=kd, reference=0.3))).simulate(
        q0, v0, T, t_eval=[T], rtol=1e-13, atol=1e-13).y[:2, -1]

    inputs = _pd_inputs(plain, kp, kd)
    errors = [np.max(np.abs(simulate_implicit(plain, q0, v0, t_final=T, dt=dt, inputs=inputs).q[-1] - ref))
              for dt in (0.01, 0.005)]
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) < 0.1 and errors[1] < 1e-3, errors


@pytest.fixture(scope="module")
def cross_coupled():
    """A base torque fed back from both links (not a hinge law: non-collocated); reference: the
    Lagrange model with the torque as generalised force, ``M(q) qdd = ... + Q``."""
    model = _two_links(SmoothHinge("h"))
    kp, kd = 20.0, 2.0

    def law(t, q, qdot):
        return (-kp * (q[0] + 1.0 - 0.2 * math.sin(2.0 * t)) - kd * qdot[0] - 0.5 * kp * (q[1] - q[0])
                - 0.1 * kd * qdot[1])

    lagrange = PlanarLagrange(model)

    def rhs(t, y):
        q, qdot = y[:2], y[2:]
        forced = np.linalg.solve(lagrange.mass_matrix(q, t), [law(t, q, qdot), 0.0])
        return np.concatenate([qdot, lagrange.accelerations(q, qdot, t) + forced])

    q0, v0, T = np.array([-0.6, -0.2]), np.array([0.5, -0.3]), 1.0
    ref = scipy.integrate.solve_ivp(rhs, (0.0, T), np.concatenate([q0, v0]), method="DOP853", rtol=1e-13,
                                    atol=1e-13).y[:2, -1]
    ports = PlanarPorts(model)
    inputs = lambda t, q, qdot: ports.inputs({"o.torque": law(t, q, qdot)})  # noqa: E731
    return model, q0, v0, T, ref, inputs


@pytest.mark.parametrize("scheme", ["forward_euler", "newmark", "generalized_alpha"])
def test_non_collocated_feedback_through_inputs_keeps_the_order_and_newton(cross_coupled, scheme):
    model, q0, v0, T, ref, inputs = cross_coupled
    order = EXPECTED_ORDER.get(scheme, 2)
    # the second-order schemes are asymptotic from 10 ms (measured slopes 2.000 / 2.000 Newmark, 1.982 / 1.995
    # generalized-alpha with a third step of 2.5 ms); backward Euler (1.36 rad at 10 ms) needs the third step
    dts = [0.01, 0.005, 0.0025] if order == 1 else [0.01, 0.005]
    runs = [simulate_implicit(model, q0, v0, t_final=T, dt=dt, scheme=scheme, inputs=inputs) for dt in dts]
    errors = np.array([np.max(np.abs(run.q[-1] - ref)) for run in runs])
    slopes = np.log2(errors[:-1] / errors[1:])
    assert np.all(np.abs(slopes - order) < 0.1), (slopes, errors)
    assert max(run.iterations.mean() for run in runs) <= 3.5
    # rank-1 feedback: one sweep, two GMRES products, one sweep with the extrapolated inputs
    assert runs[-1].n_evaluations <= 4 * runs[-1].iterations.sum() + 1


def _hub_beam(hinge, hub_loads=()) -> PlanarModel:
    beam = ModalBeam("b", length=1.0, bending_stiffness=1.0, mass_per_length=0.7, n_modes=2)
    return PlanarModel.chain("hub-beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0),
                               loads=hub_loads), hinge, beam])


@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta"])
def test_inputs_on_a_flexible_model_equal_the_same_hinge_law_and_load(scheme):
    """Hinge torque (PD, state dependent) and a turning body force at the hub's centre of mass
    (time dependent) as inputs = an ActuatedHinge and a Load at the same point."""
    kp, kd = 300.0, 10.0
    push = lambda t: 3.0 * math.sin(5.0 * t)  # noqa: E731
    elements = _hub_beam(ActuatedHinge("h", kp=kp, kd=kd, reference=0.3),
                         hub_loads=(Load(point=(0.05, 0.02), force_x=push, moment=0.4),))
    plain = _hub_beam(SmoothHinge("h"))
    inputs = _pd_inputs(plain, kp, kd, {"hub.force_x": push, "hub.moment": 0.4})

    n = plain.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    q0[:2], v0[0] = (0.3, 0.5), 2.0
    embedded = simulate_implicit(elements, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme, tolerance=1e-12)
    closed = simulate_implicit(plain, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme, tolerance=1e-12, inputs=inputs)
    assert np.max(np.abs(closed.q - embedded.q)) < 1e-9
    assert closed.iterations.mean() <= embedded.iterations.mean() + 0.05


def test_modal_force_feedback_on_a_beam_converges_at_second_order():
    """A modal force fed back from the modal coordinate (no element does this): the implicit
    stepper converges at order 2 to the DOP853 solution of the explicit sweep with the same inputs."""
    model = _hub_beam(SmoothHinge("h"))
    ports = PlanarPorts(model)

    def inputs(t, q, qdot):
        return ports.inputs({"b.q1.force": -40.0 * q[2] - 0.5 * qdot[2], "hub.force_y": math.cos(t)})

    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    q0[:3], v0[0] = (0.3, 0.5, 0.02), 2.0
    T = 0.2

    def rhs(t, y):
        q, qdot = y[:n], y[n:]
        return np.concatenate([qdot, accelerations(model, q, qdot, t, inputs=inputs(t, q, qdot))])

    ref = scipy.integrate.solve_ivp(rhs, (0.0, T), np.concatenate([q0, v0]), method="DOP853", rtol=1e-12,
                                    atol=1e-13).y[:n, -1]
    runs = [simulate_implicit(model, q0, v0, t_final=T, dt=dt, inputs=inputs) for dt in (4e-3, 2e-3)]
    errors = [np.max(np.abs(run.q[-1] - ref)) for run in runs]
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) < 0.1, errors
    assert max(run.iterations.mean() for run in runs) <= 3.5


def test_the_stability_check_sees_the_feedback_closed_through_inputs():
    """A stiff proportional elbow torque as inputs raises omega_max like the same spring in the
    hinge: Wilson-theta(1) just above 2 sqrt 3 is flagged for both, not for the open plant."""
    kp = 1e4
    q0, v0 = np.array([-0.6, -0.29]), np.zeros(2)
    hinge, plain = _two_links(ActuatedHinge("h", kp=kp, reference=0.3)), _two_links(SmoothHinge("h"))
    dt = 1.1 * 2.0 * math.sqrt(3.0) / linearised_omega_max(hinge, q0, v0)
    for model, extra in ((hinge, {}), (plain, {"inputs": _pd_inputs(plain, kp, 0.0)})):
        with pytest.raises(ModelError, match=r"WilsonTheta\(theta=1.0\) .* only conditionally stable"):
            simulate_implicit(model, q0, v0, t_final=dt, dt=dt, scheme=WilsonTheta(1.0), stability_check="error",
                              **extra)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate_implicit(plain, q0, v0, t_final=dt, dt=dt, scheme=WilsonTheta(1.0), stability_check="error")


def test_inputs_errors_name_the_time_and_keep_the_partial_result():
    model = _two_links(SmoothHinge("h"))
    ports = PlanarPorts(model)
    q0, v0 = np.array([-0.6, -0.2]), np.zeros(2)
    with pytest.raises(ModelError, match="inputs must be a callable"):
        simulate_implicit(model, q0, v0, t_final=0.1, dt=0.01, inputs={"h.torque": 1.0})

    def failing(t, q, qdot):
        if t > 0.045:
            raise ValueError("sensor lost")
        return ports.inputs({"h.torque": 0.1})

    with pytest.raises(InputError, match=r"inputs\(t, q, qdot\) raised ValueError at t = 0.05 s: sensor lost") as info:
        simulate_implicit(model, q0, v0, t_final=0.1, dt=0.01, inputs=failing)
    assert info.value.time == pytest.approx(0.05) and isinstance(info.value, SimulationError)
    assert info.value.partial_result.t[-1] == pytest.approx(0.04)
    with pytest.raises(InputError, match="must return ctmm.planar.ports.ActuatorInputs or None"):
        simulate_implicit(model, q0, v0, t_final=0.1, dt=0.01, inputs=lambda t, q, qdot: {"h.torque": 1.0})
    none = simulate_implicit(model, q0, v0, t_final=0.1, dt=0.01, inputs=lambda t, q, qdot: None)
    assert np.array_equal(none.q, simulate_implicit(model, q0, v0, t_final=0.1, dt=0.01).q)
