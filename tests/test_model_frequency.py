"""Frequency responses of planar models with loops (ctmm.frequency_response), exact delays.

Independent references: the closed-form linearised pendulum with a delayed PD
(J s^2 + m g a + (kp + kd s) e^{-s tau}) and the Lagrange linearisation (M, C, K) of a two-link
arm (ctmm.reference.planar_lagrange) with its tip's geometric Jacobian.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.control import ControlledModel, Feedback
from ctmm import frequency_response, natural_frequencies
from ctmm.errors import ModelError
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.reference.planar_lagrange import PlanarLagrange

G, MASS, LENGTH = 9.81, 1.3, 0.7


def pendulum() -> PlanarModel:
    return PlanarModel.chain("pendulum", [Fixed("ground"), ActuatedHinge("motor"),
                                          RigidBody.uniform_link("link", mass=MASS, length=LENGTH)])


def test_delayed_pd_pendulum_equals_the_closed_form():
    kp, kd, tau = 4.0, 0.6, 0.08
    system = ControlledModel(pendulum(), [Feedback("pd", sensor=[("motor.angle", kp), ("motor.rate", kd)],
                                                   actuator="motor.torque", gain=1.0, delay=tau)])
    omega = np.linspace(0.1, 30.0, 301)
    frf = frequency_response(system, omega, input=["motor.torque", "pd.reference"],
                                   output=["motor.angle", "link.out.x", "pd.u"])
    s = 1j * omega
    inertia = MASS * LENGTH ** 2 / 3.0
    plant = 1.0 / (inertia * s ** 2 + MASS * G * LENGTH / 2.0)
    loop = (kp + kd * s) * np.exp(-s * tau)
    closed = plant / (1.0 + loop * plant)
    np.testing.assert_allclose(frf("motor.angle", "motor.torque"), closed, rtol=1e-8)
    # hanging straight down: the tip moves along x by L * dtheta
    np.testing.assert_allclose(frf("link.out.x", "motor.torque"), LENGTH * closed, rtol=1e-8)
    # u = -e^{-s tau} (y - r) with y = (kp + kd s) theta, theta = P u:  u / r = e^{-s tau} / (1 + loop P)
    np.testing.assert_allclose(frf("pd.u", "pd.reference"), np.exp(-s * tau) / (1.0 + loop * plant), rtol=1e-8)
    assert frf.unit("motor.angle") == "rad" and frf.unit("motor.torque") == "N m"


def test_two_link_arm_tip_response_equals_the_lagrange_linearisation():
    upper = RigidBody.uniform_link("upper", mass=1.5, length=0.6)
    fore = RigidBody("fore", mass=0.8, inertia=0.04, center_of_mass=(0.35, 0.0), outboard=(0.5, 0.0))
    model = PlanarModel.chain("arm", [Fixed("ground"), ActuatedHinge("motor"), upper,
                                      SpringDamperHinge("elbow", stiffness=30.0, damping=0.2), fore])
    omega = np.linspace(0.5, 40.0, 120)
    frf = frequency_response(model, omega, input="motor.torque", output=["fore.out.x", "elbow.angle"])
    q_eq = np.array([-np.pi / 2, -np.pi / 2])
    M, C, K = PlanarLagrange(model).linearize(q_eq)
    s = 1j * omega
    b = np.array([1.0, 0.0])                                   # motor torque: generalised force on theta1
    X = np.array([np.linalg.solve(sk ** 2 * M + sk * C + K, b) for sk in s])
    # tip x at the hanging pose: d x / d theta_i = -L_i sin(theta_i) = L_i
    np.testing.assert_allclose(frf("fore.out.x", "motor.torque"), X @ np.array([0.6, 0.5]), rtol=1e-7)
    np.testing.assert_allclose(frf("elbow.angle", "motor.torque"), X[:, 1] - X[:, 0], rtol=1e-7)


def test_bad_names_are_refused():
    system = ControlledModel(pendulum(), [Feedback("pd", sensor="motor.angle", actuator="motor.torque", gain=2.0)])
    with pytest.raises(ModelError, match="motor.torque"):
        frequency_response(system, [1.0], input="motor.force", output="motor.angle")
    with pytest.raises(ModelError):
        frequency_response(system, [1.0], input="motor.torque", output="motor.angel")
    with pytest.raises(ModelError):
        frequency_response("pendulum", [1.0], input="motor.torque", output="motor.angle")


def test_natural_frequencies_of_a_stiff_segment_chain_keep_full_precision_on_the_low_modes():
    """80 rigid segments joined by torsional springs (a finite-segment cantilever): omega spans five
    decades, so eig of the dense M^-1 K loses ~1e-5 on the lowest mode; the verb counts instead."""
    from scipy.linalg import eigh

    from ctmm.flexible.segments import finite_segment_beam
    n = 80
    parts = finite_segment_beam("s", n_segments=n, root_spring_factor=2.0, length=1.0, bending_stiffness=2.0,
                                mass_per_length=0.5)
    model = PlanarModel.chain("fs", [Fixed("ground")] + parts, gravity=(0.0, 0.0))
    omega = natural_frequencies(model, n_modes=3)
    M, _, K = PlanarLagrange(model).linearize(np.zeros(n))
    values = eigh(K, M, eigvals_only=True)
    bound = 50 * np.finfo(float).eps * values[-1] / values[:3]          # eigh's own error on each eigenvalue
    assert np.all(np.abs(omega ** 2 / values[:3] - 1.0) <= bound)
    # the clamped-free Euler-Bernoulli beam it discretises: within the O(1/N^2) discretisation error
    beta = np.array([1.875104068711961, 4.694091132974175, 7.854757438237613])
    assert np.all(np.abs(omega / (beta ** 2 * np.sqrt(2.0 / 0.5)) - 1.0) < 1e-3)


def test_loop_signals_of_a_planar_response_carry_units_when_their_weights_are_plain():
    system = ControlledModel(pendulum(), [
        Feedback("a", sensor="motor.angle", actuator="motor.torque", gain=3.0, delay=0.01),
        Feedback("b", sensor=[("motor.angle", 2.0), ("motor.rate", 0.1)], actuator="motor.torque", gain=1.0)])
    frf = frequency_response(system, [1.0], input=["a.reference", "motor.torque"], output=["a.u", "a.y", "b.y"])
    assert [frf.unit(name) for name in ("a.reference", "motor.torque", "a.u", "a.y", "b.y")] == \
        ["rad", "N m", "N m", "rad", ""]          # b.y = 2 angle + 0.1 rate: no single unit
