"""``ctmm.interop.to_state_space`` on every model, not only chains (one set of verbs).

References are closed forms written here, sharing no ctmm code: a spatial revolute body on a torsion
spring-damper, ``theta / tau = 1 / (J s^2 + c s + k)``; the same body under a real-time PD loop on its
hinge, ``theta / M = 1 / (J s^2 + (c + kd) s + (k + kp))`` for a disturbance moment ``M``; a planar
uniform rod hanging on an actuated hinge, ``theta / tau = 1 / (m L^2 / 3 s^2 + m g L / 2)``.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm import interop
from ctmm.control import Feedback, with_feedback
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody

J, K, C = 0.3, 2.0, 0.05
KP, KD = 5.0, 0.6
OMEGA = np.array([0.3, 1.0, 2.58, 7.0, 40.0])


def spring_body() -> sp.SpatialModel:
    body = sp.SpatialBody("b", 1.5, (0.2, 0.25, J), center_of_mass=(0, 0, 0))
    return sp.SpatialModel("eh", [body, sp.Revolute(name="h", parent=None, child="b", axis=(0, 0, 1), stiffness=K,
                                                      damping=C, actuated=True)], gravity=(0, 0, -9.81))


def response(ss, omega: np.ndarray) -> np.ndarray:
    return np.array([np.squeeze(ss(1j * w)) for w in omega])


def test_spatial_model_is_linearised_about_its_equilibrium():
    ss = interop.to_state_space(spring_body(), inputs="h.torque", outputs="h.angle")
    exact = 1.0 / (J * (1j * OMEGA) ** 2 + C * 1j * OMEGA + K)
    assert np.max(np.abs(response(ss, OMEGA) - exact) / np.abs(exact)) < 1e-10
    assert ss.input_labels == ["h_torque"] and ss.output_labels == ["h_angle"]


def test_controlled_spatial_model_closes_its_real_time_loop():
    loop = Feedback("pd", [("h.angle", KP), ("h.rate", KD)], "h.torque", gain=1.0)
    ss = interop.to_state_space(with_feedback(spring_body(), [loop]), inputs="b.moment_z", outputs="h.angle")
    exact = 1.0 / (J * (1j * OMEGA) ** 2 + (C + KD) * 1j * OMEGA + K + KP)
    assert np.max(np.abs(response(ss, OMEGA) - exact) / np.abs(exact)) < 1e-10


def test_planar_pendulum_hangs_at_its_stable_equilibrium():
    mass, length, g = 1.0, 1.0, 9.81
    model = PlanarModel.chain("pendulum", [Fixed("ground"), ActuatedHinge("pivot", torque=0.0),
                                           RigidBody.uniform_link("rod", mass=mass, length=length)])
    ss = interop.to_state_space(model, inputs="pivot.torque")
    exact = 1.0 / (mass * length ** 2 / 3 * (1j * OMEGA) ** 2 + mass * g * length / 2)
    assert np.max(np.abs(response(ss, OMEGA) - exact) / np.abs(exact)) < 1e-8


def test_delayed_loops_are_refused_by_name():
    loop = Feedback("late_pd", [("h.angle", KP), ("h.rate", KD)], "h.torque", gain=1.0, delay=0.02)
    with pytest.raises(ctmm.ModelError, match=r"'late_pd' \(delay 0\.02 s\).*to_frd"):
        interop.to_state_space(with_feedback(spring_body(), [loop]))


def test_a_linearized_system_passes_through_and_keeps_its_ports():
    linear = ctmm.linearize(spring_body(), inputs=["h.torque"], outputs=["h.angle"])
    assert interop.to_state_space(linear) is linear.state_space
    with pytest.raises(ctmm.ModelError, match="takes no inputs/outputs"):
        interop.to_state_space(linear, inputs="h.torque")


def test_no_default_input_left_names_what_to_give_not_the_default():
    """The loop takes the one actuator: the default leaves no input, and the refusal says what to name
    (before: it also told the caller, who had left inputs=None, to 'leave inputs=None')."""
    loop = Feedback("pd", [("h.angle", KP), ("h.rate", KD)], "h.torque", gain=1.0)
    with pytest.raises(ctmm.ModelError, match=r"inputs=None leaves .*no input") as refused:
        interop.to_state_space(with_feedback(spring_body(), [loop]))
    assert "leave inputs=None" not in str(refused.value)
    assert "'<loop>.reference'" in str(refused.value)
    with pytest.raises(ctmm.ModelError, match=r"inputs=\[\] leaves .*or leave inputs=None"):
        ctmm.linearize(with_feedback(spring_body(), [loop]), inputs=[], outputs=["h.angle"])
