"""Spatial models with loops and controllers under the implicit DT-TMM schemes, against the independent
reference (ctmm.reference.spatial_tree, global Newton-Euler) with the control law written in the test.

The reference runs are converged (classical RK4 at 1 ms on ``[q, v, controller states]``, or the method
of steps by DOP853 for the delayed loop), so the scheme's error is its own discretisation error, and
halving ``dt`` must divide it by about 4 (second order: Newmark, generalized-alpha).  The plant is the
arm of ``tests/test_spatial_control_time.py`` (yaw revolute base, universal elbow, spherical wrist).
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import SimulationError

from _controllers_import import load_controllers
from spatial_control_helpers import quaternion_joint_state, random_model
from test_spatial_control_time import (KZ, LOOPS, REFERENCE_Z, V0, X0, Reference, _law, _max_state_error,
                                       _method_of_steps, arm, initial)

FINE = 1e-3


def _reference_rows(law, t_final, z0=np.zeros(0), on_step=None):
    model = arm()
    ref = Reference(model)
    q0, v0 = initial(model)
    return ref.rk4(q0, v0, z0, law(ref), t_final, FINE, on_step=on_step)


@functools.lru_cache(maxsize=1)
def _real_time_reference(t_final):
    """The reference run of :data:`LOOPS` (computed once for the tests that share it)."""
    return _reference_rows(_law, t_final)


def _errors(controlled, method, steps, t_final, q, v, reference_step=FINE, **options):
    """Largest state error of ``ctmm.simulate`` at each step of ``steps`` against reference rows
    ``q, v`` every ``reference_step`` [s]; and the last result."""
    out = []
    for dt in steps:
        every = int(round(dt / reference_step))
        result = ctmm.simulate(controlled, t_final, dt, method=method, x0=X0, v0=V0, **options)
        out.append(_max_state_error(controlled.plant, result, q[::every], v[::every]))
    return out, result


@pytest.mark.parametrize("method", ["newmark", "generalized_alpha"])
def test_real_time_loops_second_order(method):
    """Three real-time loops (joint PD, wrist damping on a world angular velocity, a saturated tip-height
    loop on a body force) closed at every iterate: error / 4 per halving of dt (measured 3.9-4.3)."""
    t_final = 0.2
    _, q, v, _ = _real_time_reference(t_final)
    controlled = with_feedback(arm(), LOOPS)
    errors, result = _errors(controlled, method, (0.02, 0.01), t_final, q, v,
                             references={"lift": KZ * REFERENCE_Z})
    assert 3.5 < errors[0] / errors[1] < 4.6 and errors[1] < 1e-2, errors     # measured 6.9e-3 at 10 ms
    assert result.info["loops"] == {"yaw_pd": "real-time", "damp": "real-time", "lift": "real-time"}
    assert result.info["method"].startswith("dt-tmm/")


@pytest.mark.parametrize("method, bound", [("wilson_theta", 0.03), ("houbolt", 0.04)])
def test_real_time_loops_other_schemes(method, bound):
    """Wilson-theta and Houbolt close the same loops (measured errors at dt = 10 ms: 0.025, 0.036 over 0.4 s)."""
    t_final = 0.2
    _, q, v, _ = _real_time_reference(t_final)
    errors, _ = _errors(with_feedback(arm(), LOOPS), method, (0.01,), t_final, q, v,
                        references={"lift": KZ * REFERENCE_Z})
    assert errors[0] < bound, errors


def test_stiff_cross_coupled_loops_converge_with_their_jacobian():
    """Two stiff real-time loops (omega dt about 1, one acting on a joint it does not sense) converge in a
    few iterations per step because their state dependence is in the iteration matrix; taken at the
    previous iterate instead (a fixed point on the inputs) the same step needs 24-37 sweeps or diverges."""
    kp, kd = 400.0, 10.0
    loops = [Feedback("cross", [("yaw.angle", kp), ("yaw.rate", kd), ("elbow.angle1", kp),
                                ("elbow.angle1_rate", kd)], "yaw.torque", gain=1.0),
             Feedback("elbow_pd", [("elbow.angle1", kp), ("elbow.angle1_rate", kd)], "elbow.torque1", gain=1.0)]
    result = ctmm.simulate(with_feedback(arm(), loops), 0.1, 0.01, method="newmark", x0=X0, v0=V0)
    assert result.info["newton_iterations_max"] <= 10, result.info


def test_delayed_loop_second_order_against_the_method_of_steps():
    """``u(t) = -(kp yaw(t - tau) + kd yaw_rate(t - tau))`` from the one delay history under Newmark."""
    model = arm()
    tau, t_final, gains = 0.04, 0.16, (8.0, 1.0)
    loop = Feedback("late", [("yaw.angle", gains[0]), ("yaw.rate", gains[1])], "yaw.torque", gain=1.0, delay=tau)
    q, v = _method_of_steps(model, tau, t_final, np.arange(41) * 4e-3, gains)
    errors, result = _errors(with_feedback(model, [loop]), "newmark", (8e-3, 4e-3), t_final, q, v,
                             reference_step=4e-3)
    assert 3.5 < errors[0] / errors[1] < 4.6 and errors[1] < 5e-3, errors      # measured 3.99, 3.2e-3
    assert result.info["loops"] == {"late": "history"}


def test_lti_loop_and_sampled_controller_second_order():
    """An LTI lag ``C(s) = K a / (s + a)`` on the yaw angle (its state by the trapezoidal rule inside the
    step) beside a Python PD sampled every 20 ms and held, on the elbow."""
    control = pytest.importorskip("control")
    K, a, kp, kd, h, t_final = 5.0, 30.0, 4.0, 0.5, 0.02, 0.2
    lag = Feedback("lag", "yaw.angle", "yaw.torque", gain=control.tf([K * a], [1.0, a]))
    ss = control.ss(control.tf([K * a], [1.0, a]))
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (ss.A, ss.B, ss.C, ss.D))
    held = [0.0]

    def law(ref):
        def rates(t, q, v, z):
            y, kin = ref.sensors(q, v)
            tau = ref.generalised(kin, float(-(C @ z)[0] - D[0, 0] * y[0]))
            tau[ref.slot["elbow"]] += held[0]
            return tau, A @ z + B[:, 0] * y[0]
        return rates

    every = int(round(h / FINE))
    model = arm()
    slot, qslot = Reference(model).slot["elbow"], Reference(model).qslot["elbow"]

    def on_step(k, t, y):
        if k % every == 0:
            angle, rate = y[qslot], y[Reference(model).tree.nq + slot]
            held[0] = float(np.clip(kp * (0.2 - angle) - kd * rate, -1.0, 1.0))

    _, q, v, _ = _reference_rows(law, t_final, z0=np.zeros(A.shape[0]), on_step=on_step)
    controllers = load_controllers()
    errors = []
    for dt in (0.01, 0.005):
        pd = controllers.SaturatedPD(("elbow.angle1", "elbow.angle1_rate"), ("elbow.torque1",), kp=kp, kd=kd,
                                     reference=0.2, limit=1.0, sample_time=h)
        result = ctmm.simulate(with_feedback(model, [lag]), t_final, dt, method="newmark", x0=X0, v0=V0,
                               controllers=[pd])
        errors.append(_max_state_error(model, result, q[::int(round(dt / FINE))], v[::int(round(dt / FINE))]))
    assert 3.3 < errors[0] / errors[1] < 4.8 and errors[1] < 5e-3, errors
    assert result["elbow.torque1@samples"].shape[0] == int(round(t_final / h)) + 1


def test_diverging_loop_under_a_scheme_stops_with_the_partial_result():
    wild = Feedback("wild", "yaw.angle", "yaw.torque", gain=-300.0)       # positive feedback
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(with_feedback(arm(), [wild]), 1.0, 5e-3, method="newmark", x0=X0, divergence_bound=50.0)
    partial = info.value.partial_result
    assert partial is not None and 0 < partial.time[-1] < 1.0 and "wild.u" in partial.signals()


@pytest.mark.parametrize("free_base", [False, True])
def test_input_response_is_the_difference_of_two_sweeps(free_base):
    """The input sweep of the iteration matrix (the changed joint forces and body loads alone through the
    iterate's articulated inertias) equals the difference of two full implicit sweeps, on random trees with
    every lawful joint kind, joint inputs, body forces at points and moments."""
    from ctmm.spatial.body_forms import SpatialScene
    from ctmm.spatial.implicit import implicit_rates, implicit_terms, input_response
    from ctmm.spatial.ports import SpatialPorts

    rng = np.random.default_rng(7 + free_base)
    model = random_model(rng, free_base=free_base)
    ports, scene = SpatialPorts(model), SpatialScene(model)
    q, v = quaternion_joint_state(rng, model)
    iterate = rng.normal(size=model.n_velocities)
    names = sorted(ports.actuators)

    def values():
        return ports.inputs({name: float(rng.normal()) for name in rng.choice(names, 8, replace=False)})

    before, after = values(), values()
    weights = (0.3e-4, 0.5e-2)
    terms = implicit_terms(scene, q, v, 0.1, before.joint, *weights, iterate, before.wrenches)
    change = input_response(scene, terms, before, after)
    full = [implicit_rates(scene, q, v, 0.1, u.joint, *weights, iterate, u.wrenches) for u in (before, after)]
    assert np.abs(change).max() > 1e-2
    np.testing.assert_allclose(change, full[1] - full[0], rtol=0, atol=1e-10 * np.abs(full).max())


def _driven_chain():
    """An actuated ball at the ground, a driven hinge, an actuated hinge: the prescribed joint in the bias pass."""
    import ctmm.spatial as sp
    return sp.SpatialModel("driven", [
        sp.SpatialBody("a", 1.0, (0.1, 0.12, 0.08), center_of_mass=(0.1, 0, 0.4), points={"tip": (0, 0, 1)}),
        sp.SpatialBody("b", 0.8, (0.05, 0.06, 0.07), center_of_mass=(0, 0.2, 0.3), points={"end": (0, 0.3, 0.6)}),
        sp.SpatialBody("c", 0.5, (0.02, 0.03, 0.04), center_of_mass=(0.1, 0.1, 0.2)),
        sp.Spherical(name="ball", parent=None, child="a", actuated=True),
        sp.Revolute(name="drive", parent="a", point="tip", child="b", axis=(1, 0, 0), position=lambda t: 0.3 * np.sin(2 * t),
                    rate=lambda t: 0.6 * np.cos(2 * t), acceleration=lambda t: -1.2 * np.sin(2 * t)),
        sp.Revolute(name="hinge", parent="b", point="end", child="c", axis=(0, 1, 0), actuated=True)])


@pytest.mark.parametrize("case", ["tree", "free base", "driven"])
def test_input_response_about_the_stored_elimination_is_the_full_input_sweep(case):
    """With the iterate's elimination at hand (``terms.inward``, as the Newton iteration passes it) the input
    sweep eliminates only the changed loads about the stored articulated inertias
    (:func:`ctmm.articulated.articulated_bias`): the same numbers, to the bit, as the sweep that forms them
    again, on random trees with every lawful joint kind and a chain with a driven joint."""
    from ctmm.articulated import articulated_bias, articulated_inward
    from ctmm.errors import ModelError
    from ctmm.ops import NUMPY
    from ctmm.spatial.body_forms import SpatialScene
    from ctmm.spatial.implicit import implicit_terms, input_response
    from ctmm.spatial.ports import SpatialPorts

    rng = np.random.default_rng(11 + len(case))
    model = _driven_chain() if case == "driven" else random_model(rng, free_base=case == "free base")
    assert all(layout is None for layout in model.modal)
    ports, scene = SpatialPorts(model), SpatialScene(model)
    for _ in range(3):
        q, v = quaternion_joint_state(rng, model)
        iterate = rng.normal(size=model.n_velocities)
        names = sorted(ports.actuators)
        before, after = (ports.inputs({name: float(rng.normal())
                                       for name in rng.choice(names, min(8, len(names)), replace=False)})
                         for _ in range(2))
        terms = implicit_terms(scene, q, v, 0.1, before.joint, 0.3e-4, 0.5e-2, iterate, before.wrenches)
        inward = articulated_inward(NUMPY, scene.tree, terms.bodies, terms.joints, terms.kappa)
        full = input_response(scene, terms, before, after)
        reused = input_response(scene, terms._replace(inward=inward), before, after)
        assert np.abs(full).max() > 1e-2
        assert reused.tobytes() == full.tobytes()
    with pytest.raises(ModelError, match="velocity term c"):      # the iterate's own terms carry c: refused
        articulated_bias(NUMPY, scene.tree, terms.bodies, terms.joints, inward)
