"""Generated DT-TMM schemes of spatial models with their loops closed inside the Newton step
(:mod:`ctmm.compiled_spatial_scheme_loops`, the loop part shared with planar schemes in
:mod:`ctmm.compiled_scheme_loop_terms`; issues 13 and 14).

(1) ``ctmm.simulate(ControlledModel(spatial_model, loops), method=<scheme>, compiled=True)`` with real-time loops
(joint PD with saturation, a body-rate loop on a ball joint, a point-height loop on a body force), an LTI controller
and a delayed PD 2.5 steps late (cubic Hermite between the ring's samples) equals the Python Lie-group DT-TMM path
(:func:`ctmm.spatial.implicit.simulate_spatial_implicit` through the loop driver) to round-off for every scheme;
(2) independent reference: a PD delayed by ``tau = 3.75 dt`` and ``7.5 dt`` on the hinge of a spatial double pendulum
against the method of steps (DOP853 on the global Newton-Euler equations of :mod:`ctmm.reference.spatial_tree`):
second order; (3) what does not compile is refused by name; (4) loops and co-simulated controllers together equal
the Python path.
"""
from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.compiled_scheme_loop_terms import BufferedCall
from ctmm.compiled_spatial_scheme_loops import CompiledSpatialSchemeLoops, simulate_spatial_scheme_loops_generated
from ctmm.control import ControlledModel, Feedback
from ctmm.errors import ModelError
from ctmm.reference.spatial_tree import configuration_rate, forward_dynamics
from ctmm.schemes import SCHEMES
from ctmm.signals import Harmonic
from ctmm.spatial.integrate import initial_state
from spatial_control_helpers import q_from_reference, q_to_reference, to_reference
from test_compiled_scheme_cosim import pid, spatial_double_pendulum
from test_compiled_scheme_delays import both_paths

X0 = {"hinge.angle": 0.4, "ball.qw": np.cos(0.2), "ball.qy": np.sin(0.2)}
V0 = {"hinge.angle_rate": 1.5, "ball.wy": -2.0, "ball.wz": 0.7}


@pytest.fixture(scope="module")
def plant():
    return spatial_double_pendulum()


def mixed_loops() -> list[Feedback]:
    """Real-time PD (saturated), ball damping on a world rate, a height loop on a body force, a lag, a PD 2.5 steps
    late (dt = 10 ms)."""
    return [Feedback("pd", [("hinge.angle", 8.0), ("hinge.rate", 1.0)], "hinge.torque", gain=1.0,
                     saturation=(-1.5, 1.5)),
            Feedback("damp", "lower.omega_x", "ball.torque_x", gain=0.05),
            Feedback("lift", [("upper.tip.z", 4.0), ("upper.tip.vz", 0.5)], "lower.origin.force_z", gain=1.0),
            Feedback("lag", "hinge.angle", "hinge.torque", gain=control.tf([2.0], [1.0, 3.0])),
            Feedback("late", [("hinge.angle", 3.0), ("hinge.rate", 0.5)], "hinge.torque", gain=1.0, delay=0.025)]


# ---------------------------------------------------------------- (1) equal to the Python path
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_generated_spatial_loops_equal_the_python_dt_tmm_path(plant, scheme):
    generated, python = both_paths(ControlledModel(plant, mixed_loops()), 0.2,
                                   dict(method=scheme, x0=X0, v0=V0, references={"lift": -2.0}, store_every=2,
                                        outputs=["lower.omega_body_y"]))
    assert python.info["method"].startswith("dt-tmm/") and generated.info["loops"] == python.info["loops"] == {
        "pd": "real-time", "damp": "real-time", "lift": "real-time", "lag": "real-time", "late": "history"}
    assert 0.0 < np.mean(python["pd.saturated"]) < 1.0             # the saturation is active part of the time
    assert np.ptp(python["lag.u"]) > 0.05 and np.ptp(python["late.u"]) > 0.1


def test_a_compiled_step_is_reused_and_a_foreign_one_refused(plant):
    controlled = ControlledModel(plant, mixed_loops()[:2])
    compiled = CompiledSpatialSchemeLoops(controlled, "newmark")
    first = simulate_spatial_scheme_loops_generated(controlled, 0.05, 0.01, x0=X0, v0=V0, compiled=compiled)
    again = simulate_spatial_scheme_loops_generated(controlled, 0.05, 0.005, x0=X0, v0=V0, compiled=compiled)
    assert first.time.size == 6 and again.time.size == 11 and np.isfinite(again["pd.u"]).all()
    with pytest.raises(ModelError, match="CompiledSpatialSchemeLoops of this controlled model"):
        simulate_spatial_scheme_loops_generated(ControlledModel(plant, mixed_loops()[:2]), 0.05, 0.01, x0=X0,
                                                compiled=compiled)
    delayed = ControlledModel(plant, mixed_loops()[4:])
    with pytest.raises(ModelError, match="delay rings for dt = 0.01 s"):
        simulate_spatial_scheme_loops_generated(delayed, 0.05, 0.005, x0=X0, v0=V0,
                                                compiled=CompiledSpatialSchemeLoops(delayed, dt=0.01))
    with pytest.raises(ModelError, match="needs the step dt"):
        CompiledSpatialSchemeLoops(delayed)


def test_the_restart_through_the_buffer_interface_equals_the_casadi_call(plant):
    """The restart between sample intervals (:class:`BufferedCall`) gives the numbers of the ordinary call; a function
    with a sparse output takes the ordinary call."""
    import casadi as ca

    compiled = CompiledSpatialSchemeLoops(ControlledModel(plant, mixed_loops()), "newmark", dt=0.01)
    state = compiled.initial_state(initial_state(plant, X0, V0))
    nq, n = plant.n_positions, plant.n_velocities
    arguments = (state[:nq], state[nq:nq + n], np.zeros(len(compiled.actuators)), np.zeros(0), 0.37,
                 state[compiled.status_index + 3:] + 0.01)
    direct = [np.asarray(out, float).reshape(-1) for out in compiled.state_functions[0](*arguments)]
    buffered = BufferedCall(compiled.state_functions[0])
    for _ in range(2):                                          # the buffer is reused
        for mine, theirs in zip(buffered(*arguments), direct):
            np.testing.assert_array_equal(mine, theirs)
    x = ca.SX.sym("x", 2)
    sparse = BufferedCall(ca.Function("f", [x], [ca.vertcat(x[0] * x[1], ca.SX(1, 1))]))
    assert sparse.buffer is None and sparse(np.array([2.0, 3.0]))[0].tolist() == [6.0, 0.0]


# ---------------------------------------------------------------- (2) independent: the method of steps
def method_of_steps(model, kp: float, kd: float, tau: float, t_final: float) -> tuple[np.ndarray, np.ndarray]:
    """``(q, v)`` at ``t_final`` of ``tau_hinge(t) = -(kp angle(t - tau) + kd rate(t - tau))`` (the initial state held
    before 0) by DOP853 on intervals of one delay on the Newton-Euler equations of the reference tree."""
    tree = to_reference(model)
    nq = tree.nq
    layout = dict(zip([joint.name for joint in model.joints], model.layout))["hinge"]
    qi, vi = layout.position.start, layout.velocity.start
    start = initial_state(model, X0, V0)
    y0 = np.concatenate([q_to_reference(model, start[:model.n_positions]), start[model.n_positions:]])
    past = [lambda s: y0]

    def rhs(t, y):
        delayed = past[-1](t - tau)
        torque = np.zeros(tree.nv)
        torque[vi] = -(kp * delayed[qi] + kd * delayed[nq + vi])
        return np.concatenate([configuration_rate(tree, y[:nq], y[nq:]),
                               forward_dynamics(tree, y[:nq], y[nq:], torque, t)])

    begin, y = 0.0, y0
    while begin < t_final - 1e-12:
        end = min(begin + tau, t_final)
        solution = scipy.integrate.solve_ivp(rhs, (begin, end), y, method="DOP853", rtol=1e-12, atol=1e-13,
                                             dense_output=True)
        past.append(lambda s, f=solution.sol, t0=begin, before=past[-1]: f(s) if s >= t0 - 1e-12 else before(s))
        begin, y = end, solution.y[:, -1]
    return q_from_reference(model, y[:nq]), y[nq:]


def test_a_delayed_pd_converges_at_second_order_to_the_method_of_steps_on_the_newton_euler_equations(plant):
    """tau = 3.75 dt and 7.5 dt (the ring interpolates between samples): the error at T falls 4x per halving."""
    kp, kd, tau, t_final = 6.0, 1.0, 0.0375, 0.3
    q_ref, v_ref = method_of_steps(plant, kp, kd, tau, t_final)
    loop = Feedback("late", [("hinge.angle", kp), ("hinge.rate", kd)], "hinge.torque", gain=1.0, delay=tau)
    errors = []
    for dt in (0.01, 0.005):
        result = ctmm.simulate(ControlledModel(plant, [loop]), t_final, dt, method="newmark", compiled=True,
                               x0=X0, v0=V0)
        q = np.array([result[name][-1] for name in plant.coordinates])
        v = np.array([result[name][-1] for name in plant.velocities])
        sign = np.sign(np.dot(q[1:5], q_ref[1:5]))             # the ball's quaternion: either sign
        errors.append(max(np.max(np.abs(q[:1] - q_ref[:1])), np.max(np.abs(q[1:5] - sign * q_ref[1:5])),
                          np.max(np.abs(v - v_ref))))
    assert errors[0] < 1e-2 and abs(np.log2(errors[0] / errors[1]) - 2.0) < 0.15, errors     # measured 8.0e-3, 1.97


@pytest.mark.parametrize("scheme", ["newmark", "wilson_theta"])
def test_rotation_vector_loops_equal_the_python_path(plant, scheme):
    """Loops on the lower body's rotation vector (``ctmm.compiled_spherical_cut_law.symbolic_rotation_vector``),
    real-time and delayed 2.5 steps (the ring's Hermite rates from its forward derivative), inside Newton: equal to
    the Python path to 1e-12."""
    loops = [Feedback("rot", [("lower.rotation_x", 0.4), ("lower.rotation_z", 0.1)], "ball.torque_x", gain=1.0),
             Feedback("late", [("lower.rotation_y", 0.3)], "ball.torque_y", gain=1.0, delay=0.025)]
    generated, python = both_paths(ControlledModel(plant, loops), 0.2,
                                   dict(method=scheme, x0=X0, v0=V0, outputs=["lower.rotation_y"]))
    assert np.ptp(python["rot.u"]) > 0.01 and np.ptp(python["late.u"]) > 0.01
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-12, name

# ---------------------------------------------------------------- (3) refusals
@pytest.mark.parametrize("loop, scheme, match", [
    (Feedback("late", "hinge.angle", "hinge.torque", gain=1.0, delay=0.005), "newmark", "shorter than the step dt"),
    (Feedback("late", "hinge.angle", "hinge.torque", gain=1.0, delay=0.012), "wilson_theta", "shorter than 1.4 dt"),
])
def test_what_is_not_compiled_is_refused_by_name(plant, loop, scheme, match):
    with pytest.raises(ModelError, match=match):
        ctmm.simulate(ControlledModel(plant, [loop]), 0.05, 0.01, method=scheme, compiled=True, x0=X0)


# ---------------------------------------------------------------- (4) loops and co-simulated controllers together
@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta"])
def test_loops_and_cosimulated_controllers_together_equal_the_python_path(plant, scheme):
    """A PID on the hinge every 3 steps and a rate loop on the ball every 2 steps sampled between calls into C, the
    loops inside Newton (the ring's newest rates and the accelerations solved again after each sample, Houbolt's
    start-up again), an open-loop harmonic body force compiled in."""
    controllers = [pid("hinge.angle", "hinge.torque", 0.03, kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01,
                       reference=0.3),
                   pid("lower.omega_y", "ball.torque_y", 0.02, kp=0.2)]
    options = dict(method=scheme, x0=X0, v0=V0, references={"lift": -2.0}, store_every=2,
                   inputs={"lower.origin.force_x": Harmonic(0.3, 4.0)}, outputs=["upper.tip.y"],
                   controllers=controllers)
    generated, python = both_paths(ControlledModel(plant, mixed_loops()), 0.3, options)
    assert generated.info["intervals"] == 20 and generated.info["controllers"] == python.info["controllers"]
    assert np.ptp(python["ball.torque_y@samples"]) > 0.01
