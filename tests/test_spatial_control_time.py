"""Spatial models with embedded Feedback loops and co-simulated controllers in time, against the
independent reference (ctmm.reference.spatial_tree: global Newton-Euler) with the same control law
written here.

* Real-time loops, saturation, LTI controller states, sampled Python / FMU controllers: the reference
  is integrated by the same classical RK4 on the same state ``[q, v, controller states]`` (its
  ``q_dot = G(q) v`` and ``v_dot = M^-1 (tau - h)``), so the two runs are one discretisation of one ODE
  and agree to round-off amplified over the run: 1e-9 (measured ~1e-12).
* Delayed loops: the reference is the method of steps (DOP853, rtol 1e-12, on intervals of one delay,
  the delayed signal from the previous interval's dense output, the initial state held before t = 0);
  ctmm's RK4 with the cubic-Hermite history converges to it at fourth order (error ratio > 10 per
  halving of dt, measured 16.4) and is within 2e-6 at dt = 4 ms (measured 1.1e-6).
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import scipy.integrate

import ctmm
import ctmm.spatial as sp
from ctmm.control import FMUController, Feedback, build_fmu, with_feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError
from ctmm.reference.spatial_kinematics import kinematics, point_jacobian
from ctmm.reference.spatial_tree import configuration_rate, forward_dynamics
from tests.spatial_control_helpers import q_from_reference, q_to_reference, to_reference

from _controllers_import import load_controllers

KP, KD, KW, KZ = 6.0, 1.2, 0.1, 15.0


def arm() -> sp.SpatialModel:
    """Three bodies: a yaw revolute base (spring-damper), a universal elbow, a spherical wrist (all actuated)."""
    return sp.SpatialModel("arm", [
        sp.SpatialBody("base", 2.0, [[0.05, 0.001, 0.0], [0.001, 0.04, 0.002], [0.0, 0.002, 0.03]],
                       center_of_mass=(0.05, 0.0, 0.1), points={"top": (0.1, 0.0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.004, 0.03, 0.03), center_of_mass=(0.2, 0.01, 0.0),
                       points={"tip": (0.4, 0.0, 0.0)}),
        sp.SpatialBody("hand", 0.5, (0.01, 0.012, 0.015), center_of_mass=(0.05, 0.02, -0.03),
                       points={"tip": (0.12, 0.0, 0.0)}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), stiffness=2.0, damping=0.3, actuated=True),
        sp.Universal(name="elbow", parent="base", point="top", child="link", axis1=(0, 1, 0), axis2=(0, 0, 1),
                     stiffness=(3.0, 1.0), damping=(0.2, 0.1), actuated=True),
        sp.Spherical(name="wrist", parent="link", point="tip", child="hand", actuated=True),
    ], gravity=(0.0, 0.0, -9.81))


X0 = {"yaw.angle": 0.4, "elbow.angle1": -0.3, "elbow.angle2": 0.5, "wrist.qw": np.cos(0.3), "wrist.qx": np.sin(0.3)}
V0 = {"yaw.angle_rate": -0.5, "wrist.wy": 1.0, "wrist.wz": -0.7}


def initial(model):
    from ctmm.spatial.integrate import initial_state

    x = initial_state(model, X0, V0)
    return x[:model.n_positions], x[model.n_positions:]


class Reference:
    """The reference plant with the loops' sensors and actuators written out (no ctmm port code)."""

    def __init__(self, model: sp.SpatialModel) -> None:
        self.model = model
        self.tree = to_reference(model)
        self.slot = {j.name: layout.velocity.start for j, layout in zip(model.joints, model.layout)}
        self.qslot = {j.name: layout.position.start for j, layout in zip(model.joints, model.layout)}

    def sensors(self, q_ref, v):
        """``(yaw angle, yaw rate, hand omega_x world, hand tip z, hand tip vz)``."""
        kin = kinematics(self.tree, q_ref, v)
        tip = kin.origin[2] + kin.rotation[2] @ np.array([0.12, 0.0, 0.0])
        vz = (point_jacobian(kin, 2, tip) @ v)[2]
        return np.array([q_ref[self.qslot["yaw"]], v[self.slot["yaw"]], kin.omega[2][0], tip[2], vz]), kin

    def generalised(self, kin, yaw_torque=0.0, wrist_torque_x=0.0, link_force_z=0.0):
        tau = np.zeros(self.tree.nv)
        tau[self.slot["yaw"]] += yaw_torque
        tau[self.slot["wrist"]] += wrist_torque_x
        com = kin.origin[1] + kin.rotation[1] @ np.array([0.2, 0.01, 0.0])
        tau += point_jacobian(kin, 1, com).T @ np.array([0.0, 0.0, link_force_z])
        return tau

    def rk4(self, q0, v0, z0, law, t_final, dt, on_step=None):
        """Classical RK4 on ``[q_ref, v, z]``; ``law(t, q_ref, v, z) -> (tau, z_dot)``; ``on_step(k, t, y)``
        before step ``k`` (sampled controllers).  Returns the rows ``(time, q (ctmm order), v, z)``."""
        nq, nv = self.tree.nq, self.tree.nv

        def rate(t, y):
            q, v, z = y[:nq], y[nq:nq + nv], y[nq + nv:]
            tau, zdot = law(t, q, v, z)
            return np.concatenate([configuration_rate(self.tree, q, v), forward_dynamics(self.tree, q, v, tau, t),
                                   zdot])

        y = np.concatenate([q_to_reference(self.model, q0), v0, z0])
        n = int(round(t_final / dt))
        rows = [y]
        for k in range(n):
            t = k * dt
            if on_step is not None:
                on_step(k, t, y)
            k1 = rate(t, y)
            k2 = rate(t + dt / 2, y + dt / 2 * k1)
            k3 = rate(t + dt / 2, y + dt / 2 * k2)
            k4 = rate(t + dt, y + dt * k3)
            y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            rows.append(y)
        rows = np.array(rows)
        q = np.array([q_from_reference(self.model, r[:nq]) for r in rows])
        return np.arange(n + 1) * dt, q, rows[:, nq:nq + nv], rows[:, nq + nv:]


def _max_state_error(model, result, q, v):
    ours_q = np.column_stack([result[name] for name in model.coordinates])
    ours_v = np.column_stack([result[name] for name in model.velocities])
    return max(np.max(np.abs(ours_q - q)), np.max(np.abs(ours_v - v)))


LOOPS = [
    Feedback("yaw_pd", [("yaw.angle", KP), ("yaw.rate", KD)], "yaw.torque", gain=1.0),
    Feedback("damp", "hand.omega_x", "wrist.torque_x", gain=KW),
    Feedback("lift", [("hand.tip.z", KZ), ("hand.tip.vz", 2.0)], "link.force_z", gain=1.0, saturation=(-3.0, 3.0)),
]
REFERENCE_Z = 0.45


def _law(ref: Reference):
    def law(t, q, v, z):
        y, kin = ref.sensors(q, v)
        yaw = -(KP * y[0] + KD * y[1])
        wrist = -KW * y[2]
        lift = float(np.clip(-(KZ * (y[3] - REFERENCE_Z) + 2.0 * y[4]), -3.0, 3.0))
        return ref.generalised(kin, yaw, wrist, lift), np.zeros(0)
    return law


def test_real_time_loops_with_saturation_equal_the_reference_rk4():
    """Three real-time loops (joint PD, world angular-velocity damping on a spherical wrist, a saturated
    point-height loop on a body force) at every RK4 stage, no added lag."""
    model = arm()
    controlled = with_feedback(model, LOOPS)
    assert isinstance(controlled, ControlledModel) and controlled.plant is model
    t_final, dt = 0.6, 5e-3
    result = ctmm.simulate(controlled, t_final, dt, method="rk4", x0=X0, v0=V0,
                           references={"lift": KZ * REFERENCE_Z}, outputs=["hand.tip.z", "hand.tip.vz"])
    ref = Reference(model)
    q0, v0 = initial(model)
    _, q, v, _ = ref.rk4(q0, v0, np.zeros(0), _law(ref), t_final, dt)
    error = _max_state_error(model, result, q, v)
    assert error < 1e-9, error
    assert result.info["loops"] == {"yaw_pd": "real-time", "damp": "real-time", "lift": "real-time"}
    # the saturated loop did saturate, and "<loop>.u" is the clipped demand
    assert result["lift.saturated"].any() and not result["lift.saturated"].all()
    np.testing.assert_allclose(result["lift.u"], np.clip(result["lift.u_demand"], -3.0, 3.0), rtol=0, atol=1e-15)
    assert result.unit("lift.u") == "N" and result.unit("damp.y") == "rad/s" and result.unit("hand.tip.z") == "m"
    # the loop's signal is its weighted sensors: the stored output and the reference's tip height
    ref_tip = np.array([ref.sensors(q_to_reference(model, qk), vk)[0][3] for qk, vk in zip(q, v)])
    np.testing.assert_allclose(result["hand.tip.z"], ref_tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result["lift.y"], KZ * result["hand.tip.z"] + 2.0 * result["hand.tip.vz"],
                               rtol=0, atol=1e-12)


def test_scipy_method_with_loops_matches_the_reference():
    model = arm()
    t_final = 0.4
    result = ctmm.simulate(with_feedback(model, LOOPS), t_final, 0.05, method="DOP853", x0=X0, v0=V0,
                           references={"lift": KZ * REFERENCE_Z}, rtol=1e-11, atol=1e-12)
    ref = Reference(model)
    q0, v0 = initial(model)
    law = _law(ref)
    nq = ref.tree.nq

    def rhs(t, y):
        tau, _ = law(t, y[:nq], y[nq:], np.zeros(0))
        return np.concatenate([configuration_rate(ref.tree, y[:nq], y[nq:]),
                               forward_dynamics(ref.tree, y[:nq], y[nq:], tau, t)])

    sol = scipy.integrate.solve_ivp(rhs, (0.0, t_final), np.concatenate([q_to_reference(model, q0), v0]),
                                    method="DOP853", rtol=1e-12, atol=1e-13, t_eval=result.time)
    q = np.array([q_from_reference(model, r[:nq]) for r in sol.y.T])
    error = _max_state_error(model, result, q, sol.y.T[:, nq:])
    assert error < 1e-8, error


def test_lti_controller_states_are_integrated_with_the_plant():
    """``C(s) = K a / (s + a)`` on the yaw angle: its state ``x' = a (e - x)``, ``u = -K x``."""
    control = pytest.importorskip("control")
    K, a = 5.0, 30.0
    model = arm()
    loop = Feedback("lag", "yaw.angle", "yaw.torque", gain=control.tf([K * a], [1.0, a]))
    t_final, dt = 0.5, 5e-3
    result = ctmm.simulate(with_feedback(model, [loop]), t_final, dt, x0=X0, v0=V0)
    ref = Reference(model)
    q0, v0 = initial(model)
    ss = control.ss(control.tf([K * a], [1.0, a]))         # the realisation ctmm uses (one state)
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (ss.A, ss.B, ss.C, ss.D))

    def law(t, q, v, z):
        y, kin = ref.sensors(q, v)
        return ref.generalised(kin, float(-(C @ z)[0] - D[0, 0] * y[0])), A @ z + B[:, 0] * y[0]

    _, q, v, z = ref.rk4(q0, v0, np.zeros(1), law, t_final, dt)
    assert _max_state_error(model, result, q, v) < 1e-9
    np.testing.assert_allclose(result["lag.u"], -(z @ C[0]) - D[0, 0] * q[:, 0], rtol=0, atol=1e-9)


def _method_of_steps(model, tau, t_final, times, gains):
    """DOP853 on intervals of one delay; the loop reads the previous interval's dense output."""
    ref = Reference(model)
    tree = ref.tree
    nq = tree.nq
    q0, v0 = initial(model)
    y0 = np.concatenate([q_to_reference(model, q0), v0])
    kp, kd = gains
    past = [lambda s: y0]

    def rhs(t, y):
        yd = past[-1](t - tau)
        sensed, _ = ref.sensors(yd[:nq], yd[nq:])
        _, kin = ref.sensors(y[:nq], y[nq:])
        tau_gen = ref.generalised(kin, -(kp * sensed[0] + kd * sensed[1]))
        return np.concatenate([configuration_rate(tree, y[:nq], y[nq:]),
                               forward_dynamics(tree, y[:nq], y[nq:], tau_gen, t)])

    out = np.zeros((len(times), len(y0)))
    start, y = 0.0, y0
    while start < t_final - 1e-12:
        end = min(start + tau, t_final)
        sol = scipy.integrate.solve_ivp(rhs, (start, end), y, method="DOP853", rtol=1e-12, atol=1e-13,
                                        dense_output=True)
        inside = (times >= start - 1e-12) & (times <= end + 1e-12)
        out[inside] = sol.sol(times[inside]).T
        past.append(lambda s, f=sol.sol, t0=start: f(s) if s >= t0 - 1e-12 else past[0](s))
        start, y = end, sol.y[:, -1]
    q = np.array([q_from_reference(model, r[:nq]) for r in out])
    return q, out[:, nq:]


def test_delayed_loop_matches_the_method_of_steps_at_fourth_order():
    """``u(t) = -(kp yaw(t - tau) + kd yaw_rate(t - tau))`` from the one delay history; the wrist is free."""
    model = arm()
    tau, t_final, gains = 0.04, 0.16, (8.0, 1.0)
    loop = Feedback("late", [("yaw.angle", gains[0]), ("yaw.rate", gains[1])], "yaw.torque", gain=1.0, delay=tau)
    q_ref, v_ref = _method_of_steps(model, tau, t_final, np.arange(41) * 4e-3, gains)
    errors = []
    for dt, every in ((8e-3, 2), (4e-3, 1)):
        result = ctmm.simulate(with_feedback(model, [loop]), t_final, dt, x0=X0, v0=V0)
        errors.append(_max_state_error(model, result, q_ref[::every], v_ref[::every]))
        assert result.info["loops"] == {"late": "history"}
    assert errors[1] < 2e-6 and errors[0] / errors[1] > 10.0, errors
    # before tau the loop acts on the initial state held
    early = result.time < tau - 1e-12
    np.testing.assert_allclose(result["late.u"][early], -(gains[0] * X0["yaw.angle"] + gains[1] * V0["yaw.angle_rate"]),
                               rtol=1e-12)


def _sampled_reference(model, law_of_measured, h, dt, t_final, lag=0):
    """Reference RK4 with a sampled controller: every ``h`` the output is computed from the sensors
    ``lag`` samples ago and held."""
    ref = Reference(model)
    q0, v0 = initial(model)
    every = int(round(h / dt))
    held, measured = [0.0], []

    def on_step(k, t, y):
        if k % every == 0:
            nq = ref.tree.nq
            sensed, _ = ref.sensors(y[:nq], y[nq:])
            measured.append(sensed)
            held[0] = law_of_measured(measured[max(len(measured) - 1 - lag, 0)])

    def law(t, q, v, z):
        _, kin = ref.sensors(q, v)
        return ref.generalised(kin, held[0]), np.zeros(0)

    return ref.rk4(q0, v0, np.zeros(0), law, t_final, dt, on_step=on_step)


def test_python_controller_sampled_and_held_equals_the_reference():
    controllers = load_controllers()
    kp, kd, h, dt, t_final = 6.0, 1.0, 0.02, 5e-3, 0.4
    pd = controllers.SaturatedPD(("yaw.angle", "yaw.rate"), ("yaw.torque",), kp=kp, kd=kd, reference=0.1,
                                 limit=1.5, sample_time=h)
    model = arm()
    result = ctmm.simulate(model, t_final, dt, x0=X0, v0=V0, controllers=[pd])
    _, q, v, _ = _sampled_reference(model, lambda s: float(np.clip(kp * (0.1 - s[0]) - kd * s[1], -1.5, 1.5)),
                                    h, dt, t_final)
    assert _max_state_error(model, result, q, v) < 1e-9
    assert result["yaw.torque@samples"].shape[0] == int(round(t_final / h)) + 1


@pytest.fixture(scope="module")
def pd_fmu(tmp_path_factory):
    assert shutil.which("gcc"), "gcc is required to build the test FMU"
    return build_fmu(load_controllers().fmu_source("pd_controller"), tmp_path_factory.mktemp("fmu"), compiler="gcc")


def test_delayed_fmu_controller_on_a_point_height_equals_the_reference(pd_fmu):
    """An FMU built by the project reads the hand tip height and its rate two samples late and writes the
    link body force ``link.force_z`` (held), beside an embedded real-time yaw PD."""
    kp, kd, target, h, delay, dt, t_final = 20.0, 3.0, 0.4, 0.01, 0.02, 5e-3, 0.3
    fmu = FMUController(pd_fmu, inputs={"y": "hand.tip.z", "ydot": "hand.tip.vz"}, outputs={"u": "link.force_z"},
                        parameters={"kp": kp, "kd": kd, "reference": target}, sample_time=h)
    model = arm()
    yaw = Feedback("yaw_pd", [("yaw.angle", KP), ("yaw.rate", KD)], "yaw.torque", gain=1.0)
    result = ctmm.simulate(with_feedback(model, [yaw]), t_final, dt, x0=X0, v0=V0,
                           controllers=[DelayedController(fmu, delay)])
    ref = Reference(model)
    q0, v0 = initial(model)
    every, lag = int(round(h / dt)), int(round(delay / h))
    held, measured = [0.0], []

    def on_step(k, t, y):
        if k % every == 0:
            sensed, _ = ref.sensors(y[:ref.tree.nq], y[ref.tree.nq:])
            measured.append(sensed)
            s = measured[max(len(measured) - 1 - lag, 0)]
            held[0] = kp * (target - s[3]) - kd * s[4]

    def law(t, q, v, z):
        y, kin = ref.sensors(q, v)
        return ref.generalised(kin, -(KP * y[0] + KD * y[1]), 0.0, held[0]), np.zeros(0)

    _, q, v, _ = ref.rk4(q0, v0, np.zeros(0), law, t_final, dt, on_step=on_step)
    error = _max_state_error(model, result, q, v)
    assert error < 1e-8, error
    samples = result["link.force_z@samples"]
    assert np.ptp(samples[:, 1]) > 1.0                      # the controller really acts


def test_refusals():
    model = arm()
    with pytest.raises(ModelError, match="accelerations are not sensors"):
        with_feedback(model, [Feedback("a", "hand.alpha_x", "yaw.torque", gain=1.0)])
    with pytest.raises(ModelError, match="also an element"):
        with_feedback(model, [Feedback("yaw", "yaw.angle", "yaw.torque", gain=1.0)])
    with pytest.raises(ModelError, match="already has loops"):
        with_feedback(with_feedback(model, LOOPS[:1]), LOOPS[1:])
    with pytest.raises(ModelError, match="shorter than the step"):
        ctmm.simulate(with_feedback(model, [Feedback("d", "yaw.angle", "yaw.torque", gain=1.0, delay=1e-4)]),
                      0.1, 1e-3)
    unactuated = sp.SpatialModel("u", [sp.SpatialBody("b", 1.0, (1, 1, 1)),
                                       sp.Revolute(name="r", parent=None, child="b")])
    with pytest.raises(ModelError, match="actuated=True"):
        with_feedback(unactuated, [Feedback("pd", "r.angle", "r.torque", gain=1.0)])


def test_diverging_loop_stops_with_the_partial_result():
    model = arm()
    wild = Feedback("wild", "yaw.angle", "yaw.torque", gain=-300.0)       # positive feedback
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(with_feedback(model, [wild]), 1.0, 5e-3, x0=X0, divergence_bound=50.0)
    partial = info.value.partial_result
    assert partial is not None and 0 < partial.time[-1] < 1.0 and "wild.u" in partial.signals()


def test_open_loop_port_inputs_equal_model_inputs():
    """A body-force port input goes through the loop driver; a joint input with no loops equals the plain run."""
    model = arm()
    plain = ctmm.simulate(model, 0.1, 5e-3, x0=X0, inputs={"yaw.torque": 0.3})
    ported = ctmm.simulate(model, 0.1, 5e-3, x0=X0, inputs={"yaw.torque": 0.3, "hand.force_x": 0.0})
    for name in model.coordinates:
        np.testing.assert_allclose(ported[name], plain[name], rtol=0, atol=1e-13)
