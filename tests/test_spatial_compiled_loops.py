"""Controlled spatial models with ``compiled=True``: loops closed inside the generated RK4 step
(``ctmm.compiled_spatial_loops``) against the independent reference (global Newton-Euler with the
control law written in the test) and against the Python RK4 of the same loops; refusals.

The generated step and the Python RK4 are one discretisation of one ODE (delayed loops: the same
cubic Hermite history at the half steps), so they agree to round-off (1e-10; measured 1e-15).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError, SimulationError
from ctmm.signals import Harmonic

from test_spatial_control_time import (KZ, LOOPS, REFERENCE_Z, V0, X0, Reference, _law, _max_state_error, arm,
                                       initial)

pytest.importorskip("casadi")


def test_real_time_loops_with_saturation_equal_the_reference_rk4():
    """Joint PD, wrist damping on a world angular velocity and a saturated tip-height loop on a body
    force at every stage of the generated RK4 = the reference RK4 with the law written here."""
    model = arm()
    t_final, dt = 0.3, 5e-3
    result = ctmm.simulate(with_feedback(model, LOOPS), t_final, dt, x0=X0, v0=V0, compiled=True,
                           references={"lift": KZ * REFERENCE_Z}, outputs=["hand.tip.z"])
    assert result.scheme_name == "rk4-generated" and result.info["compile_time_s"] > 0
    ref = Reference(model)
    q0, v0 = initial(model)
    _, q, v, _ = ref.rk4(q0, v0, np.zeros(0), _law(ref), t_final, dt)
    assert _max_state_error(model, result, q, v) < 1e-9
    assert result["lift.saturated"].any() and not result["lift.saturated"].all()
    np.testing.assert_allclose(result["lift.u"], np.clip(result["lift.u_demand"], -3.0, 3.0), rtol=0, atol=1e-15)
    assert result.info["time_saturated_s"]["lift"] > 0 and result.unit("lift.u") == "N"


def test_lti_delayed_loops_inputs_equal_the_python_rk4():
    """An LTI controller state, two delayed loops (m = 4 and 2 steps; tip height, x-y-z angle and a
    body-axes rate), a constant reference and a harmonic port input: every signal equal to the Python
    RK4 to 1e-10."""
    control = pytest.importorskip("control")
    model = arm()
    loops = [Feedback("lag", "yaw.angle", "yaw.torque", gain=control.tf([150.0], [1.0, 30.0])),
             Feedback("late", [("hand.tip.z", 20.0), ("hand.tip.vz", 2.0)], "link.force_z", gain=1.0, delay=0.02),
             Feedback("later", [("elbow.angle1", 5.0), ("hand.angle_x", 1.0), ("hand.omega_body_y", 0.3)],
                      "elbow.torque1", gain=1.0, delay=0.01)]
    arguments = dict(x0=X0, v0=V0, references={"late": 8.0}, inputs={"wrist.torque_y": Harmonic(0.2, 3.0)},
                     outputs=["hand.angle_x"], store_every=3)
    controlled = with_feedback(model, loops)
    generated = ctmm.simulate(controlled, 0.3, 5e-3, compiled=True, **arguments)
    python = ctmm.simulate(controlled, 0.3, 5e-3, **arguments)
    np.testing.assert_array_equal(generated.time, python.time)
    assert generated.info["loops"] == {"lag": "real-time", "late": "history", "later": "history"}
    names = list(model.coordinates) + list(model.velocities) + ["hand.angle_x"] + [
        f"{loop.name}.{part}" for loop in loops for part in ("y", "u")]
    for name in names:
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) < 1e-10 * scale, name


def test_rotation_vector_loops_equal_the_python_rk4():
    """Loops on the hand's rotation vector ``"hand.rotation_x|y|z"`` (``ctmm.compiled_spherical_cut_law.
    symbolic_rotation_vector`` in the generated step, numpy's quaternion logarithm in the Python RK4): real-time and
    delayed 3 steps (the ring's rates the forward derivative of the logarithm): equal to 1e-12."""
    model = arm()
    loops = [Feedback("rot", [("hand.rotation_x", 0.8), ("hand.rotation_y", 0.3)], "wrist.torque_x", gain=1.0),
             Feedback("late", [("hand.rotation_z", 0.5), ("hand.rotation_y", -0.2)], "wrist.torque_z", gain=1.0,
                      delay=0.015)]
    arguments = dict(x0=X0, v0=V0, outputs=["hand.rotation_x", "hand.rotation_y", "hand.rotation_z"])
    controlled = with_feedback(model, loops)
    generated = ctmm.simulate(controlled, 0.3, 5e-3, compiled=True, **arguments)
    python = ctmm.simulate(controlled, 0.3, 5e-3, **arguments)
    assert generated.scheme_name == "rk4-generated"
    assert np.ptp(python["rot.u"]) > 0.05 and np.ptp(python["late.u"]) > 0.05
    names = list(model.coordinates) + list(model.velocities) + arguments["outputs"] + [
        f"{loop.name}.{part}" for loop in loops for part in ("y", "u")]
    for name in names:
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-12, name

def test_refusals_and_divergence():
    model = arm()
    with pytest.raises(ModelError, match="not a whole multiple of dt"):
        ctmm.simulate(with_feedback(model, [Feedback("d", "yaw.angle", "yaw.torque", gain=1.0, delay=0.012)]),
                      0.1, 5e-3, compiled=True)
    wild = Feedback("wild", "yaw.angle", "yaw.torque", gain=-300.0)       # positive feedback
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(with_feedback(model, [wild]), 1.0, 5e-3, x0=X0, divergence_bound=50.0, compiled=True)
    partial = info.value.partial_result
    assert partial is not None and 0 < partial.time[-1] < 1.0 and "wild.u" in partial.signals()


def test_planar_saturated_loop_is_clipped_in_generated_code():
    """The loops of planar generated kernels (the same ``ClosedLoops``) clip a saturating loop too: the
    generated run equals the Python RK4 with ``u`` at its limits (before, the limits were dropped)."""
    from test_compiled_scene_loops import pendulum
    from ctmm.control.controlled_model import ControlledModel
    from ctmm.planar import SmoothHinge

    loop = Feedback("pd", [("rod.theta", 30.0), ("rod.omega", 4.0)], "pivot.torque", gain=1.0, saturation=(-5.0, 5.0))
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    generated = ctmm.simulate(system, 0.5, 4e-3, x0=[-1.5], references={"pd": -36.0}, compiled=True)
    python = ctmm.simulate(system, 0.5, 4e-3, x0=[-1.5], references={"pd": -36.0})
    assert np.max(np.abs(python["pd.u"])) == pytest.approx(5.0)        # the limit is reached
    for name in ("rod.theta", "pd.u", "pd.u_demand", "pd.saturated"):
        assert np.max(np.abs(generated[name] - python[name])) < 1e-10, name
    assert generated.info["time_saturated_s"]["pd"] == pytest.approx(python.info["time_saturated_s"]["pd"])
