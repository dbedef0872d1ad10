"""One rule for ``(i omega I - A)^-1 B`` at or next to an undamped pole (planar and spatial frequency
responses; ``ctmm.controlled_linearization.resolvent``), and margins of a loop whose plant has one.

Closed forms (independent of the linearisation): a uniform link (mass m, length L) hanging from a motor
has ``J theta'' + m g (L/2) theta = tau``, ``J = m L^2 / 3``, pole ``omega_n = sqrt(m g L / (2 J))``; with
the PD ``u = -(kp theta + kd theta') e^{-s tau}`` the loop is ``L(s) = (kp + kd s) e^{-s tau} / (J s^2 + m g L/2)``.
A body (mass 1 kg, inertia 0.01 kg m^2 about every axis) on an isotropic elastic hinge (900 N/m, 4 N m/rad)
without gravity answers ``1 / (k - m omega^2)`` per axis, poles 30 and 20 rad/s.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import ctmm
import ctmm.spatial_linearization as spatial_linearization
from ctmm.control import margins
from ctmm.controlled_linearization import RESOLVENT_CONDITION, FrequencyAtPoleError
from ctmm.errors import ModelError

from test_planar_control_tools import INERTIA, KD, KP, LENGTH, MASS, G, exact_loop, system
from test_spatial_linear_frequency import isotropic_hinge_body

POLE = np.sqrt(MASS * G * LENGTH / 2.0 / INERTIA)


def plant_response(w):
    return 1.0 / (MASS * G * LENGTH / 2.0 - INERTIA * np.asarray(w) ** 2)


@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-10])
def test_planar_response_at_an_undamped_pole_is_refused_naming_frequency_and_pole(offset):
    w = float(POLE * (1.0 + offset))
    with pytest.raises(FrequencyAtPoleError, match=rf"'pendulum' is singular at omega = {w!r} rad/s.*"
                                                    rf"nearest pole is 0\+{POLE:.9g}j") as caught:
        ctmm.frequency_response(system().plant, [1.0, w], input="motor.torque", output="motor.angle")
    assert isinstance(caught.value, ModelError)


@pytest.mark.parametrize("offset", [1e-6, -1e-5, 1e-3])
def test_planar_response_next_to_the_pole_is_answered_and_correct(offset):
    w = POLE * (1.0 + offset)
    frf = ctmm.frequency_response(system().plant, [w], input="motor.torque", output="motor.angle")
    np.testing.assert_allclose(frf.response[0, 0], plant_response(w), rtol=1e-8)


def test_spatial_response_uses_the_same_rule():
    model = isotropic_hinge_body()
    outputs, inputs = spatial_linearization.tangent_names(model), spatial_linearization.input_names(model)
    with pytest.raises(FrequencyAtPoleError, match=r"'ball' is singular at omega = 20.0 rad/s.*nearest pole is 0\+20j"):
        ctmm.frequency_response(model, [20.0], input=inputs[3], output=outputs[3])
    w = 20.0 * (1.0 + 1e-6)
    frf = ctmm.frequency_response(model, [w, 30.0 * (1 - 1e-6)], input=[inputs[3], inputs[0]],
                                  output=[outputs[3], outputs[0]])
    np.testing.assert_allclose(frf.response[0, 0, 0], 1.0 / (4.0 - 0.01 * w ** 2), rtol=1e-8)
    np.testing.assert_allclose(frf.response[1, 1, 1], 1.0 / (900.0 - (30.0 * (1 - 1e-6)) ** 2), rtol=1e-8)
    assert RESOLVENT_CONDITION == pytest.approx(6.7108864e7)


@pytest.mark.parametrize("grid", [np.linspace(0.05, 60.0, 3000), np.linspace(0.05, 3 * POLE, 7)])
def test_margins_of_a_loop_around_an_undamped_pole_equal_the_closed_form(grid):
    # L changes sign through infinity at the plant's pole: no crossover there, and no evaluation at it
    result = margins(system(), "pd", grid)
    w_gc = brentq(lambda w: abs(exact_loop(w)) - 1.0, 1.0, 60.0)
    assert result.gain_crossovers == pytest.approx([w_gc], rel=1e-9)
    assert result.phase_margin == pytest.approx(np.degrees(np.pi + np.angle(exact_loop(w_gc))), rel=1e-8)
    w_pc = brentq(lambda w: exact_loop(w).imag, 20.0, 30.0)                   # the first phase crossover
    assert result.phase_crossovers[0] == pytest.approx(w_pc, rel=1e-9)
    assert result.gain_margin == pytest.approx(1.0 / abs(exact_loop(w_pc)), rel=1e-8)
    assert all(abs(w - POLE) > 1e-3 for w in result.phase_crossovers)
    undelayed = margins(system(0.0), "pd", grid)                            # Im L = kd w / (K - J w^2) != 0
    assert undelayed.phase_crossovers == () and undelayed.gain_margin == np.inf
    assert KP > 0 and KD > 0


def test_closed_loop_at_a_pole_of_the_plant_equals_the_lagrange_closed_loop():
    """Two links on motor and elbow, two delayed loops (elbow angle -> motor, motor rate -> elbow), at the natural
    frequencies of the plant (eig of the Lagrange K, M): the plant's resolvent refuses them, but the loops move those
    poles and the closed loop is regular there -- it equals the closed loop assembled from PlanarLagrange's M, C, K
    (before: FrequencyAtPoleError claiming the response unbounded)."""
    import scipy.linalg

    from ctmm.control import Feedback, with_feedback
    from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
    from ctmm.reference.planar_lagrange import PlanarLagrange

    plant = PlanarModel.chain("pendulum", [Fixed("ground"), ActuatedHinge("motor"),
                                           RigidBody.uniform_link("l0", mass=1.0, length=0.8), ActuatedHinge("h1"),
                                           RigidBody.uniform_link("l1", mass=0.8, length=0.7)])
    M, C, K = PlanarLagrange(plant).linearize(np.array([-np.pi / 2, -np.pi / 2]))
    omega = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    hinge = np.array([[1.0, 0.0], [-1.0, 1.0]])                 # hinge angles of the absolute angles
    torque = np.array([[1.0, -1.0], [0.0, 1.0]])                # generalised forces of the motor and elbow torques
    kp, kd, tau_a, tau_b = 6.0, 0.5, 0.05, 0.02
    loops = [Feedback("a", [("h1.angle", kp)], "motor.torque", gain=1.0, delay=tau_a),
             Feedback("b", [("motor.rate", kd)], "h1.torque", gain=1.0, delay=tau_b)]
    reference = []
    for s in 1j * omega:
        Z = (M * s * s + C * s + K).astype(complex)
        Z += np.outer(torque[:, 0], kp * np.exp(-s * tau_a) * hinge[1])
        Z += np.outer(torque[:, 1], kd * s * np.exp(-s * tau_b) * hinge[0])
        reference.append(hinge @ np.linalg.solve(Z, torque[:, 0]))
    with pytest.raises(FrequencyAtPoleError):
        ctmm.frequency_response(plant, omega, input="motor.torque", output="motor.angle")
    frf = ctmm.frequency_response(with_feedback(plant, loops), omega, input="motor.torque",
                                  output=["motor.angle", "h1.angle"])
    np.testing.assert_allclose(frf.response[:, 0, :], np.array(reference).T, rtol=1e-10)
