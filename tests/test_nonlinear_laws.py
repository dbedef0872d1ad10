"""Nonlinear spring and damper laws (ctmm.nonlinear_laws) and planar NonlinearHinge.

Independent checks: each law's tangents against central differences of its value; the potential
against the integral of the force; a single link on a cubic hinge (the undamped Duffing oscillator)
against the exact period from the energy quadrature ``T = 4 int_0^A dtheta / sqrt(2 (V(A) - V) / J)``
and its small-oscillation frequency ``sqrt(K1 / J)``; energy conservation of an undamped two-link
chain; the linearisation about a preloaded operating point against ``sqrt((K1 + 3 K2 theta0^2) / J)``;
every time method against a tight DOP853 run and against the global DAE reference
(:mod:`ctmm.reference.planar_dae`, which takes the law as a plain function).
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import ctmm
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import (CallableLaw, ClearanceSpring, CubicSpring, LinearLaw, ParallelLaw,
                                 PowerDamper)
from ctmm.planar import Fixed, NonlinearHinge, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar import accelerations

LAWS = [CubicSpring(10.0, 50.0), CubicSpring(10.0, -3.0), ClearanceSpring(20.0, clearance=0.05),
        ClearanceSpring(20.0, clearance=0.05, stop=0.3, stop_stiffness=200.0),
        PowerDamper(0.7, 2.0), PowerDamper(0.7, 0.5, regularization_rate=0.05), PowerDamper(0.7, 1.5),
        LinearLaw(3.0, 0.2), CubicSpring(4.0, 9.0) + PowerDamper(0.2, 1.7, regularization_rate=0.01),
        CallableLaw(lambda d, v: 3.0 * d + np.sinh(d) + 0.1 * v * abs(v),
                    stiffness=lambda d, v: 3.0 + np.cosh(d), damping=lambda d, v: 0.2 * abs(v), name="sinh")]
POINTS = [(-0.41, -0.9), (-0.02, 0.013), (0.17, 0.3), (0.6, -2.0)]


@pytest.mark.parametrize("law", LAWS, ids=repr)
def test_tangents_match_central_differences(law):
    h = 1e-6
    for d, v in POINTS:
        k, c = law.tangents(d, v)
        k_fd = (law.force(d + h, v) - law.force(d - h, v)) / (2 * h)
        c_fd = (law.force(d, v + h) - law.force(d, v - h)) / (2 * h)
        assert k == pytest.approx(k_fd, rel=1e-6, abs=1e-6)
        assert c == pytest.approx(c_fd, rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("law", [law for law in LAWS if not isinstance(law, CallableLaw)], ids=repr)
def test_potential_is_the_integral_of_the_static_force(law):
    for d in (-0.47, 0.033, 0.52):
        integral, _ = scipy.integrate.quad(lambda x: law.force(x, 0.0), 0.0, d, points=[-0.3, -0.05, 0.05, 0.3],
                                           epsabs=1e-13, epsrel=1e-12)
        assert law.potential(d) == pytest.approx(integral, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("law", LAWS, ids=repr)
def test_a_float_argument_gives_the_numbers_of_the_array_path(law):
    # the time loops call a law with Python floats (a shortcut past the symbol and complex checks): each value,
    # tangent and potential equals the element of one array evaluation, the clearance corners included, to the
    # last bit or one or two units in the last place where a power is taken: numpy's array power is vectorised
    # (SVML on processors with AVX-512) and may round differently from the C library's pow of the float path
    deltas = np.array([-0.61, -0.3, -0.05, -0.0, 0.0, 0.013, 0.05, 0.05 + 1e-12, 0.3, 0.47])
    rates = np.array([0.4, -1.3, 0.0, 2.0, -0.0, 0.02, -0.7, 1e-3, -2.5, 0.9])
    values, (stiffness, damping) = law.force(deltas, rates), law.tangents(deltas, rates)
    for k, (d, v) in enumerate(zip(deltas.tolist(), rates.tolist())):
        assert type(d) is float and type(v) is float
        np.testing.assert_array_max_ulp(float(law.force(d, v)), values[k], maxulp=2)
        np.testing.assert_array_max_ulp([float(x) for x in law.tangents(d, v)], [stiffness[k], damping[k]],
                                        maxulp=2)
        if not isinstance(law, CallableLaw):
            np.testing.assert_array_max_ulp(float(law.potential(d)), law.potential(deltas)[k], maxulp=2)


def test_law_values_of_the_seed_forms():
    assert CubicSpring(10.0, 50.0).force(0.2) == pytest.approx(10 * 0.2 + 50 * 0.008)
    clearance = ClearanceSpring(20.0, clearance=0.05, stop=0.3, stop_stiffness=200.0)
    assert clearance.force(0.04) == 0.0 and clearance.force(-0.04) == 0.0
    assert clearance.force(0.2) == pytest.approx(20 * 0.15)
    assert clearance.force(-0.4) == pytest.approx(-(20 * 0.35 + 200 * 0.1))
    damper = PowerDamper(0.7, 2.0)
    assert damper.force(0.0, -3.0) == pytest.approx(-0.7 * 9.0)
    regular = PowerDamper(0.7, 0.5, regularization_rate=0.01)
    assert regular.force(0.0, 2.0) == pytest.approx(0.7 * math.sqrt(2.0), rel=2e-5)      # |v| >> eps
    assert regular.tangents(0.0, 0.0)[1] == pytest.approx(0.7 * 0.01 ** -0.5)            # finite at rest


def test_complex_argument_gives_the_tangent_in_the_imaginary_part():
    law = ClearanceSpring(20.0, clearance=0.05) + PowerDamper(0.7, 2.0)
    value = law.force(0.2 + 1e-20j, -0.5 + 2e-20j)
    assert value.real == pytest.approx(law.force(0.2, -0.5))
    assert value.imag / 1e-20 == pytest.approx(20.0 + 2.0 * 0.7 * 0.5 * 2.0)


def test_bad_parameters_are_refused_by_name():
    with pytest.raises(ModelError, match="regularization_rate"):
        PowerDamper(1.0, 0.5)
    with pytest.raises(ModelError, match="stop"):
        ClearanceSpring(1.0, clearance=0.2, stop=0.1, stop_stiffness=3.0)
    with pytest.raises(ModelError, match="linear_stiffness"):
        CubicSpring(-1.0, 2.0)
    with pytest.raises(ModelError, match="stiffness at delta"):
        CallableLaw(lambda d, v: d ** 3, stiffness=lambda d, v: 2 * d, damping=lambda d, v: 0.0, name="wrong")
    with pytest.raises(ModelError, match="moment_law"):
        NonlinearHinge("h", parent="g", child="l", moment_law=3.0)
    with pytest.raises(ModelError, match="ParallelLaw"):
        ParallelLaw(CubicSpring(1.0, 1.0), "spring")


def test_casadi_automatic_differentiation_of_a_user_law():
    import casadi

    law = CallableLaw(lambda d, v: 3.0 * d + (casadi.sinh(d) if isinstance(d, casadi.SX) else np.sinh(d)),
                      name="ad")
    assert law.expressible
    assert law.tangents(0.5, 0.0)[0] == pytest.approx(3.0 + math.cosh(0.5), rel=1e-12)


# ------------------------------------------------------------------------------------------------
# planar hinge
# ------------------------------------------------------------------------------------------------
INERTIA = 1.0 / 3.0       # uniform unit link about its end [kg m^2]


def single_link(law, gravity=(0.0, 0.0), rest=0.0):
    return PlanarModel("duffing", [Fixed("g"), RigidBody.uniform_link("l", mass=1.0, length=1.0),
                                   NonlinearHinge("h", parent="g", child="l", moment_law=law, rest_angle=rest)],
                       gravity=gravity)


def exact_period(law, amplitude):
    """Period of ``J theta'' + f(theta) = 0`` from rest at ``amplitude``: energy quadrature, substituting
    ``theta = A sin(phi)`` (no endpoint singularity)."""
    V = law.potential
    integrand = lambda p: amplitude * math.cos(p) / math.sqrt(2.0 * (V(amplitude) - V(amplitude * math.sin(p))) / INERTIA)  # noqa: E731,E501
    value, _ = scipy.integrate.quad(integrand, 0.0, math.pi / 2, epsabs=1e-14, epsrel=1e-13, limit=200)
    return 4.0 * value


def crossing_period(result, name):
    t, x = result.time, result[name]
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    times = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    return float(np.mean(np.diff(times)))


@pytest.mark.parametrize("method, dt", [("rk4", 5e-4), ("DOP853", None), ("newmark", 5e-4)])
def test_duffing_period_matches_the_energy_quadrature(method, dt):
    law = CubicSpring(10.0, 60.0)
    amplitude = 0.6                      # K2 A^2 / K1 = 2.2: strongly hardening
    expected = exact_period(law, amplitude)
    assert expected < 2 * math.pi / math.sqrt(10.0 / INERTIA) * 0.8      # the law matters
    kwargs = dict(rtol=1e-11, atol=1e-12) if dt is None else {}
    result = ctmm.simulate(single_link(law), 3.0, dt, method=method, x0={"l.theta": amplitude}, **kwargs)
    tolerance = 1e-6 if method != "newmark" else 1e-5      # Newmark: period error ~ (w h)^2 / 12
    assert crossing_period(result, "l.theta") == pytest.approx(expected, rel=tolerance)


def test_small_oscillation_and_preloaded_linearisation():
    law = CubicSpring(10.0, 60.0)
    assert ctmm.natural_frequencies(single_link(law), n_modes=1)[0] == pytest.approx(math.sqrt(10.0 / INERTIA))
    # rest angle 0.3: about theta = 0 the tangent stiffness is K1 + 3 K2 0.09
    model = single_link(law, rest=0.3)
    point = {"l.theta": 0.0}
    expected = math.sqrt((10.0 + 3 * 60.0 * 0.09) / INERTIA)
    with pytest.raises(ModelError):          # not an equilibrium: refused unless asked
        ctmm.natural_frequencies(model, n_modes=1, operating_point=point)
    hanging = single_link(law, gravity=(0.0, -9.81), rest=0.0)
    theta0 = scipy.optimize.brentq(lambda th: law.force(th) + 9.81 * 0.5 * math.cos(th), -1.5, 0.0)
    omega = ctmm.natural_frequencies(hanging, n_modes=1, operating_point={"l.theta": theta0})[0]
    geometric = -9.81 * 0.5 * math.sin(theta0)           # gravity stiffness d/dtheta (m g l/2 cos)
    k_t = law.tangents(theta0)[0] + geometric
    assert omega == pytest.approx(math.sqrt(k_t / INERTIA), rel=1e-9)
    assert expected > 0


def two_link(law_1, law_2):
    return PlanarModel("two", [Fixed("g"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                               NonlinearHinge("h1", parent="g", child="a", moment_law=law_1),
                               RigidBody.uniform_link("b", mass=0.5, length=0.8),
                               NonlinearHinge("h2", parent="a", child="b", moment_law=law_2)],
                       gravity=(0.0, -9.81))


def test_undamped_two_link_conserves_energy():
    model = two_link(CubicSpring(10.0, 50.0), ClearanceSpring(8.0, clearance=0.05, stop=0.4, stop_stiffness=80.0))
    # 0.4 s: the relative angle already swings from -1.15 to +1.15 rad, past the stop (0.4) on both sides
    # (measured energy error 3.3e-10 relative; 1.2e-9 over 1 s)
    result = ctmm.simulate(model, 0.4, method="DOP853", x0={"a.theta": 0.5, "b.theta": -0.6}, rtol=1e-11,
                           atol=1e-12, max_step=1e-3)
    q = np.column_stack([result["a.theta"], result["b.theta"]])
    v = np.column_stack([result["a.theta_dot"], result["b.theta_dot"]])
    energy = np.array([model.energy(qi, vi) for qi, vi in zip(q, v)])
    assert np.ptp(q[:, 1] - q[:, 0]) > 0.8                 # the stop and the clearance both engage
    assert np.min(q[:, 1] - q[:, 0]) < -0.45 and np.max(q[:, 1] - q[:, 0]) > 0.45     # past the stop either way
    assert np.max(np.abs(energy - energy[0])) < 1e-7 * np.max(np.abs(energy))


def test_linear_law_keeps_the_numbers_of_the_linear_hinge():
    linear = PlanarModel("lin", [Fixed("g"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                 SpringDamperHinge("h1", parent="g", child="a", stiffness=7.0, damping=0.3)])
    wrapped = single_link(LinearLaw(7.0, 0.3), gravity=(0.0, -9.81))
    for q, v in ((0.3, -1.0), (-1.2, 0.4)):
        assert accelerations(wrapped, [q], [v])[0] == pytest.approx(accelerations(linear, [q], [v])[0], rel=1e-14)


@pytest.mark.parametrize("kwargs, tolerance", [(dict(method="rk4", dt=5e-4), 2e-6),
                                               (dict(method="rk4", dt=5e-4, compiled=True), 2e-6),
                                               (dict(method="RK45", rtol=1e-10, atol=1e-12), 1e-8),
                                               (dict(method="newmark", dt=5e-4), 5e-5),
                                               (dict(method="generalized_alpha", dt=5e-4), 5e-5)])
def test_every_time_method_against_the_dae_reference(kwargs, tolerance):
    law_1, law_2 = _two_link_laws()
    model = two_link(law_1, law_2)
    result = ctmm.simulate(model, 0.5, x0={"a.theta": 0.5, "b.theta": -0.3}, **kwargs)
    angle_a, angle_b, max_drift = _two_link_dae(result.time.tobytes())
    error = max(np.max(np.abs(result["a.theta"] - angle_a)), np.max(np.abs(result["b.theta"] - angle_b)))
    assert error < tolerance
    assert max_drift < 1e-9


def _two_link_laws() -> tuple:
    return (CubicSpring(10.0, 50.0) + PowerDamper(0.3, 2.0),
            ClearanceSpring(8.0, clearance=0.05) + PowerDamper(0.05, 0.5, regularization_rate=0.05))


@functools.lru_cache(maxsize=2)
def _two_link_dae(times: bytes) -> tuple[np.ndarray, np.ndarray, float]:
    """The independent DAE of :func:`test_every_time_method_against_the_dae_reference` at the times (float64 bytes):
    angles of ``a`` and ``b`` [rad] and the largest drift [m]; computed once per grid (the fixed-step methods share
    theirs)."""
    from ctmm.reference.planar_dae import PlanarDAE

    law_1, law_2 = _two_link_laws()
    dae = PlanarDAE(gravity=(0.0, -9.81))
    dae.add_body("a", mass=1.0, inertia=1 / 12, points={"in": (-0.5, 0.0), "out": (0.5, 0.0)})
    dae.add_body("b", mass=0.5, inertia=0.5 * 0.64 / 12, points={"in": (-0.4, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "a", "in", moment=lambda d, v: law_1.force(d, v))
    dae.add_revolute("a", "out", "b", "in", moment=lambda d, v: law_2.force(d, v))
    reference = dae.simulate(dae.assemble({"a": 0.5, "b": -0.3}, {"a": 0.0, "b": 0.0}), 0.5,
                             t_eval=np.frombuffer(times, dtype=float))
    return reference.angle("a"), reference.angle("b"), reference.max_drift


def test_generated_kernel_refuses_a_user_law_without_casadi_form():
    law = CallableLaw(lambda d, v: 3.0 * d + np.sinh(d), stiffness=lambda d, v: 3.0 + np.cosh(d),
                      damping=lambda d, v: 0.0, name="sinh spring")
    with pytest.raises(ModelError, match="sinh spring"):
        ctmm.simulate(single_link(law), 0.01, 1e-3, method="rk4", compiled=True, x0={"l.theta": 0.1})


def test_newton_uses_the_law_tangent():
    """Exact Newton: with the tangent ``kappa`` a strongly nonlinear step converges in <= 3 iterations (a
    chord iteration with the linear part only needs about 6 at this step)."""
    result = ctmm.simulate(single_link(CubicSpring(10.0, 60.0)), 1.0, 1e-2, method="newmark", x0={"l.theta": 0.8})
    assert result.info["newton_iterations_max"] <= 3


def test_linearisation_at_a_clearance_corner_is_refused():
    model = single_link(ClearanceSpring(20.0, clearance=0.05))
    with pytest.raises(ModelError, match="not smooth"):
        ctmm.natural_frequencies(model, n_modes=1, operating_point={"l.theta": 0.05})
    inside = ctmm.natural_frequencies(single_link(ClearanceSpring(20.0, clearance=0.05) + LinearLaw(1.0)), n_modes=1,
                                      operating_point={"l.theta": 0.0})
    assert inside[0] == pytest.approx(math.sqrt(1.0 / INERTIA))        # only the linear part inside the gap


# ------------------------------------------------------------------------------------------------
# spatial lawful joints
# ------------------------------------------------------------------------------------------------
def spatial_pendulum(law):
    import ctmm.spatial as sp

    return sp.SpatialModel("duffing3d", [sp.SpatialBody("b", 1.0, (0.1, 0.2, 0.3), (0.5, 0.0, 0.0)),
                                         sp.Revolute(name="h", parent=None, child="b", axis=(0, 0, 1), law=law)],
                           gravity=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("kwargs, tolerance", [(dict(method="rk4", dt=5e-4, compiled=True), 1e-8),
                                               (dict(method="DOP853", rtol=1e-11, atol=1e-12), 1e-6),
                                               (dict(method="newmark", dt=2e-3), 1e-4)])
def test_spatial_revolute_with_a_cubic_law_has_the_duffing_period(kwargs, tolerance):
    law = CubicSpring(10.0, 60.0)
    inertia = 0.3 + 1.0 * 0.5 ** 2            # about the joint axis [kg m^2]
    amplitude = 0.6
    V = law.potential
    integrand = lambda p: amplitude * math.cos(p) / math.sqrt(2.0 * (V(amplitude) - V(amplitude * math.sin(p))) / inertia)  # noqa: E731,E501
    expected = 4.0 * scipy.integrate.quad(integrand, 0.0, math.pi / 2, epsabs=1e-14, epsrel=1e-13)[0]
    result = ctmm.simulate(spatial_pendulum(law), 2.0, x0={"h.angle": amplitude}, **kwargs)
    assert crossing_period(result, "h.angle") == pytest.approx(expected, rel=tolerance)


def test_spatial_law_energy_and_linearisation():
    from ctmm.spatial.dynamics import energy

    law = CubicSpring(10.0, 60.0)
    model = spatial_pendulum(law)
    assert ctmm.natural_frequencies(model, n_modes=1)[0] == pytest.approx(math.sqrt(10.0 / 0.55), rel=1e-9)
    result = ctmm.simulate(model, 1.0, method="DOP853", x0={"h.angle": 0.6}, rtol=1e-11, atol=1e-12)
    values = energy(model, result["h.angle"][:, None], result["h.angle_rate"][:, None])
    assert values[0] == pytest.approx(law.potential(0.6), rel=1e-12)
    assert np.max(np.abs(values - values[0])) < 1e-8 * values[0]
    import ctmm.spatial as sp
    with pytest.raises(ModelError, match="law must be"):
        sp.Revolute(name="h", parent=None, child="b", law=lambda d, v: d)


def test_spatial_generated_kernel_refuses_a_user_law_by_joint_name():
    law = CallableLaw(lambda d, v: 3.0 * d + np.sinh(d), stiffness=lambda d, v: 3.0 + np.cosh(d),
                      damping=lambda d, v: 0.0, name="sinh spring")
    with pytest.raises(ModelError, match="'h' .*sinh spring"):
        ctmm.simulate(spatial_pendulum(law), 0.01, 1e-3, method="rk4", compiled=True, x0={"h.angle": 0.1})


def test_frequency_response_about_the_static_equilibrium_uses_the_tangent():
    """Hanging link on a cubic spring + linear damper: the FRF about the static equilibrium (found by
    the verb) is the 1-DOF ``1 / (k_t - J w^2 + i c w)`` with the tangent and gravity stiffness."""
    law = CubicSpring(10.0, 60.0) + PowerDamper(0.5, 1.0)
    model = single_link(law, gravity=(0.0, -9.81))
    theta0 = scipy.optimize.brentq(lambda th: law.force(th) + 9.81 * 0.5 * math.cos(th), -1.5, 0.0)
    omega = np.array([1.0, 5.0, 9.0])
    response = ctmm.frequency_response(model, omega, input="h.torque", output="l.theta").response[0, 0]
    k_t = law.tangents(theta0)[0] - 9.81 * 0.5 * math.sin(theta0)
    np.testing.assert_allclose(response, 1.0 / (k_t - INERTIA * omega ** 2 + 0.5j * omega), rtol=1e-8)


def test_modal_beam_path_carries_the_law():
    """Modal-beam models run the hinge law in their own kernels (explicit and DT-TMM Newton): a LinearLaw
    reproduces the ElasticHinge numbers exactly (wiring), and a cubic law changes the motion accordingly
    (Newmark converges to DOP853 at 1e-11 with order 2: over 0.1 s measured 2.0e-4 / 5.1e-5 rad, ratio 3.99; the
    cubic term moves the end angle by 0.10 rad)."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ElasticHinge

    def hub(hinge):
        beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2)
        return PlanarModel("hub", [Fixed("g"), beam, hinge], gravity=(0.0, 0.0))

    linear = hub(ElasticHinge("h", parent="g", child="b", stiffness=4.0))
    wrapped = hub(NonlinearHinge("h", parent="g", child="b", moment_law=LinearLaw(4.0)))
    q, v = np.array([0.5, 0.01, -0.002]), np.array([0.1, 0.2, 0.0])
    np.testing.assert_array_equal(accelerations(wrapped, q, v), accelerations(linear, q, v))
    x0 = {"b.theta": 0.5}
    for method in ("rk4", "newmark"):
        a = ctmm.simulate(linear, 0.05, 1e-3, method=method, x0=x0)
        b = ctmm.simulate(wrapped, 0.05, 1e-3, method=method, x0=x0)
        assert np.max(np.abs(a["b.q1"] - b["b.q1"])) < 1e-13
    cubic = hub(NonlinearHinge("h", parent="g", child="b", moment_law=CubicSpring(4.0, 40.0)))
    tight = ctmm.simulate(cubic, 0.1, method="DOP853", x0=x0, rtol=1e-11, atol=1e-12)
    errors = []
    for dt in (1e-3, 5e-4):
        newmark = ctmm.simulate(cubic, 0.1, dt, method="newmark", x0=x0)
        errors.append(abs(newmark["b.theta"][-1] - tight["b.theta"][-1]))
    assert errors[1] < 1e-4 and 3.0 < errors[0] / errors[1] < 5.0                # second order
    stiffer = ctmm.simulate(linear, 0.1, method="DOP853", x0=x0, rtol=1e-11, atol=1e-12)
    assert abs(stiffer["b.theta"][-1] - tight["b.theta"][-1]) > 1e-2           # the cubic term acts


# ------------------------------------------------------------------------------------------------
# radial (translational) springs of a planar hinge
# ------------------------------------------------------------------------------------------------
RADIAL = CubicSpring(2000.0, 5e6)
MOMENT = CubicSpring(1.0, 3.0)


def bushing_link(radial, moment=MOMENT):
    return PlanarModel("bushing", [Fixed("g"), RigidBody.uniform_link("l", mass=1.0, length=1.0),
                                   NonlinearHinge("h", parent="g", child="l", moment_law=moment, radial_law=radial)],
                       gravity=(0.0, -9.81))


@pytest.mark.parametrize("radial", [RADIAL, ClearanceSpring(3000.0, clearance=0.002)], ids=["cubic", "clearance"])
# bounds on the angle [rad] and the pin offsets [m], 3-6x the errors measured (cubic / clearance spring): DOP853
# 1.2e-11 / 1.1e-12 rad, 7.3e-12 / 6.7e-13 m; Newmark 2.8e-7 / 9.3e-7 rad, 1.8e-7 / 6.5e-7 m
@pytest.mark.parametrize("kwargs, angle_bound, offset_bound",
                         [(dict(method="DOP853", rtol=1e-11, atol=1e-13, max_step=1e-3), 6e-11, 4e-11),
                          (dict(method="newmark", dt=2e-4), 3e-6, 2e-6)])
def test_radial_spring_against_the_dae_reference(radial, kwargs, angle_bound, offset_bound):
    """A link on a hinge whose pin moves in a radial spring (a clearance: a pin in a hole), released
    sideways: ctmm's coordinates (offset d, angle) against the DAE with the same force element, 0.15 s (the pin
    crosses its hole: ``l.dy`` spans 3.3e-3 / 5.5e-3 m)."""
    from ctmm.reference.planar_dae import PlanarDAE

    model = bushing_link(radial)
    x0 = {"l.dx": 0.003, "l.dy": 0.0, "l.theta": 0.4}
    result = ctmm.simulate(model, 0.15, x0=x0, **kwargs)
    dae = PlanarDAE(gravity=(0.0, -9.81))
    dae.add_body("l", mass=1.0, inertia=1 / 12, points={"in": (-0.5, 0.0)})
    dae.add_bushing(None, (0.0, 0.0), "l", "in", radial=lambda r: float(radial.force(r)),
                    moment=lambda d, v: float(MOMENT.force(d, v)))
    state = dae.assemble({"l": 0.4}, {"l": 0.0}, offsets={"l": (0.003, 0.0)})
    reference = dae.simulate(state, 0.15, t_eval=result.time)
    inboard = reference.q[:, :2] + np.column_stack([-0.5 * np.cos(reference.angle("l")),
                                                    -0.5 * np.sin(reference.angle("l"))])
    assert np.max(np.abs(result["l.theta"] - reference.angle("l"))) < angle_bound
    assert np.max(np.abs(result["l.dx"] - inboard[:, 0])) < offset_bound
    assert np.max(np.abs(result["l.dy"] - inboard[:, 1])) < offset_bound
    assert np.ptp(result["l.dy"]) > 1e-3                                   # the pin moves in its hole


def test_radial_spring_energy_and_tangent():
    model = bushing_link(RADIAL, moment=CubicSpring(1.0, 3.0))
    # every accepted DOP853 step checked (max_step 2 ms: 154 rows, drift 9e-16; 0.5 ms: 601 rows, 2.6e-15, 5x the CPU)
    result = ctmm.simulate(model, 0.3, method="DOP853", x0={"l.dx": 0.003, "l.theta": 0.4}, rtol=1e-12,
                           atol=1e-14, max_step=2e-3)
    names = model.coordinates
    energy = np.array([model.energy(np.array([result[n][k] for n in names]),
                                    np.array([result[n + "_dot"][k] for n in names])) for k in range(len(result.time))])
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))
    from ctmm.planar.hinge_laws import radial_force
    hinge = model.nonlinear_hinges[0]
    for d in ([0.003, -0.001], [0.0, 0.0], [-2e-4, 5e-4]):
        _, slope = radial_force(hinge, np.array(d))
        for k in range(2):
            e = np.zeros(2)
            e[k] = 1e-9
            numeric = (radial_force(hinge, np.array(d) + e)[0] - radial_force(hinge, np.array(d) - e)[0]) / 2e-9
            np.testing.assert_allclose(slope[:, k], numeric, rtol=1e-5, atol=1e-3)
    with pytest.raises(ModelError, match="radial_law must be a spring"):
        NonlinearHinge("h", parent="g", child="l", radial_law=PowerDamper(1.0, 2.0))


def test_a_rate_independent_user_law_is_accepted_as_a_radial_spring():
    """A casadi-form CallableLaw whose force has no rate term was refused as "must be a spring (no rate
    dependence)".  Hand check: a link hanging free on its pin sinks by r with f(r) = m g (the root below)."""
    force = CallableLaw(lambda d, v: 2000.0 * d + 5e6 * d ** 3)
    model = PlanarModel("pin", [Fixed("g"), RigidBody.uniform_link("l", mass=1.0, length=1.0),
                                NonlinearHinge("h", parent="g", child="l", radial_law=force)], gravity=(0.0, -9.81))
    sag = scipy.optimize.brentq(lambda r: 2000.0 * r + 5e6 * r ** 3 - 9.81, 0.0, 1.0)
    from ctmm.planar.equilibrium import static_equilibrium
    q = static_equilibrium(model, [0.0, -0.001, -1.5])
    np.testing.assert_allclose(q, [0.0, -sag, -0.5 * math.pi], rtol=0, atol=1e-12)
    with pytest.raises(ModelError, match="radial_law must be a spring"):
        NonlinearHinge("h", radial_law=CallableLaw(lambda d, v: 2000.0 * d + 3.0 * v))


def test_generated_kernel_of_translational_and_radial_springs_equals_the_numpy_rk4():
    """Was refused by name; now compiled from the same terms (tests/test_compiled_bushings.py)."""
    for model in (bushing_link(RADIAL), bushing_link(ClearanceSpring(3000.0, clearance=0.002))):
        x0 = {"l.theta": 0.1, "l.dx": 0.003}
        generated = ctmm.simulate(model, 0.05, 1e-4, method="rk4", compiled=True, x0=x0, store_every=50)
        plain = ctmm.simulate(model, 0.05, 1e-4, method="rk4", x0=x0, store_every=50)
        for name in model.coordinates:
            np.testing.assert_allclose(generated[name], plain[name], rtol=0, atol=1e-12)
        assert np.ptp(generated["l.dx"]) > 1e-4


def test_linear_references_refuse_nonlinear_hinges():
    """The linear Lagrange references read the hinge-law arrays (0 for a nonlinear hinge): they refuse."""
    from ctmm.reference.planar_lagrange import PlanarLagrange, newton_euler_kkt

    model = single_link(CubicSpring(1.0, 2.0))
    with pytest.raises(ValueError, match="planar_dae"):
        PlanarLagrange(model)
    with pytest.raises(ValueError, match="planar_dae"):
        newton_euler_kkt(model, [0.1], [0.0])


def test_casadi_user_laws_with_one_name_are_told_apart_by_the_generated_kernels():
    """Two AD user laws named alike but different must not share a generated kernel (structure key)."""
    import casadi

    from ctmm.compiled_parameters import structure_key

    def law(k):
        return CallableLaw(lambda d, v: k * d + (casadi.sinh(d) if isinstance(d, casadi.SX) else np.sinh(d)), name="u")

    assert structure_key(single_link(law(3.0))) != structure_key(single_link(law(4.0)))
    assert structure_key(single_link(law(3.0))) == structure_key(single_link(law(3.0)))
