"""Feedback loops inside the generated DT-TMM step of planar models (:mod:`ctmm.compiled_scheme_loops`).

(1) ``ctmm.simulate(ControlledModel(plant, loops), method=<scheme>, compiled=True)`` equals the Python DT-TMM path
(``compiled=None``: loops through the ``inputs`` hook of :func:`ctmm.planar.implicit.simulate_implicit`) to
round-off: real-time PD loops (saturating, a reference signal, an open-loop input) for every scheme, LTI controller
states, delayed loops (``delay = m dt``, the ring); (2) independent references: Newmark written here in its global
form on the Lagrange equations of :mod:`ctmm.reference.planar_lagrange` with the same PD laws (and a lag by the
trapezoidal rule on its own realisation) as generalised torques, solved by a finite-difference Newton; a delayed
PD against the method of steps (DOP853) at second order; (3) the stability check sees the loops; (4) what is not
compiled is refused by name; (5) a failed step keeps the loop signals in its partial result.
"""
from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.compiled_scheme_loops import CompiledSchemeLoops, simulate_scheme_loops_generated
from ctmm.control import ControlledModel, Feedback
from ctmm.errors import ConvergenceError, ModelError
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import SCHEMES, GeneralizedAlpha, Newmark
from ctmm.signals import Harmonic
from test_compiled_scene_schemes import DP_START, double_pendulum

KP, KD, KH, DH = 8.0, 1.5, 3.0, 0.4
START = DP_START


def pd_loops(limit: float | None = 0.5) -> list[Feedback]:
    """A PD on the pivot and a PD on the elbow hinge (saturating at ``limit`` [N m])."""
    return [Feedback("pd", [("a.theta", KP), ("a.omega", KD)], "o.torque", gain=1.0),
            Feedback("elbow", [("h.angle", KH), ("h.rate", DH)], "h.torque", gain=1.0,
                     saturation=None if limit is None else (-limit, limit))]


@pytest.fixture(scope="module")
def plant():
    return double_pendulum()


def _start(model):
    return dict(zip(model.coordinates, START[0])), dict(zip(model.coordinates, START[1]))


# ---------------------------------------------------------------- (1) the Python DT-TMM path
def both_paths(controlled, t_final, options):
    """``(generated, python)`` runs of ``controlled`` (dt = 10 ms), checked equal within 1e-10 on every signal."""
    generated = ctmm.simulate(controlled, t_final, 0.01, compiled=True, **options)
    python = ctmm.simulate(controlled, t_final, 0.01, **options)
    assert np.array_equal(generated.time, python.time)
    assert set(python.signals()) <= set(generated.signals())
    for name in python.signals():
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-10, name
    return generated, python


@pytest.mark.parametrize("scheme", [*SCHEMES, GeneralizedAlpha(0.3)], ids=str)
def test_generated_loops_equal_the_python_dt_tmm_path(plant, scheme):
    controlled = ControlledModel(plant, pd_loops())
    x0, v0 = _start(plant)
    options = dict(method=scheme, x0=x0, v0=v0, store_every=2, outputs=["b.out.y"],
                   references={"pd": Harmonic(0.2, 2.0)}, inputs={"b.moment": 0.3})
    generated, python = both_paths(controlled, 0.2, options)
    assert generated.info["method"].startswith("dt-tmm-generated/")
    assert np.any(python["elbow.saturated"] > 0.0) and np.any(python["elbow.saturated"] == 0.0)
    open_loop = ctmm.simulate(plant, 0.2, 0.01, method=scheme, x0=x0, v0=v0, store_every=2, compiled=True)
    assert np.max(np.abs(open_loop["a.theta"] - generated["a.theta"])) > 1e-3       # the loops act


def lti_loops() -> list[Feedback]:
    """A first-order lag on the pivot, a biproper second-order controller on the elbow (saturating), a rate loop."""
    return [Feedback("lag", "a.theta", "o.torque", gain=control.tf([LAG_GAIN * LAG_POLE], [1.0, LAG_POLE])),
            Feedback("lead", "h.angle", "h.torque", gain=control.tf([1.0, 2.0, 1.0], [1.0, 5.0, 4.0]),
                     saturation=(-0.25, 0.25)),
            Feedback("damp", [("b.omega", 0.3)], "h.torque", gain=1.0)]


LAG_GAIN, LAG_POLE = 6.0, 3.0


@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta", "generalized_alpha"])
def test_lti_controller_states_equal_the_python_dt_tmm_path(plant, scheme):
    """Controller states advanced by the trapezoidal rule from the step start to every Newton iterate, as the
    Python path (ctmm.control.implicit_loops.LoopSteps) does."""
    controlled = ControlledModel(plant, lti_loops())
    x0, v0 = _start(plant)
    options = dict(method=scheme, x0=x0, v0=v0, store_every=2, references={"lag": 0.1})
    _, python = both_paths(controlled, 0.3, options)
    assert np.ptp(python["lag.u"]) > 0.1 and 0.0 < np.mean(python["lead.saturated"]) < 1.0


# ---------------------------------------------------------------- (2) independent: Lagrange + global Newmark
def _newton_root(residual, guess):
    """Root of ``residual`` by Newton with a central-difference Jacobian, to round-off."""
    x = np.array(guess, dtype=float)
    for _ in range(50):
        jacobian = np.empty((x.size, x.size))
        for j in range(x.size):
            e = np.zeros(x.size)
            e[j] = 1e-6 * (1.0 + abs(x[j]))
            jacobian[:, j] = (residual(x + e) - residual(x - e)) / (2.0 * e[j])
        dx = np.linalg.solve(jacobian, -residual(x))
        x = x + dx
        if np.max(np.abs(dx)) <= 1e-15 * (1.0 + np.max(np.abs(x))):
            break
    return x


def test_generated_loops_equal_newmark_on_the_lagrange_equations_with_the_same_pd_laws(plant):
    lagrange = PlanarLagrange(plant)

    def closed(q, v, t):
        """Lagrange's accelerations with the pivot PD (on a.theta) and the elbow PD (on b.theta - a.theta, clipped
        at 0.5 N m) as generalised torques: the pivot torque on a; the elbow torque on b and its reaction on a."""
        pivot = -(KP * q[0] + KD * v[0])
        elbow = float(np.clip(-(KH * (q[1] - q[0]) + DH * (v[1] - v[0])), -0.5, 0.5))
        return lagrange.accelerations(q, v, t) + np.linalg.solve(lagrange.mass_matrix(q, t),
                                                                 np.array([pivot - elbow, elbow]))

    h, n_steps = 0.01, 30
    q, v = START[0].copy(), START[1].copy()
    a = closed(q, v, 0.0)
    qs = [q]
    for step in range(n_steps):                      # Newmark beta = 1/4, gamma = 1/2, equations at t_{n+1}
        def states(a1, q=q, v=v, a=a):
            return q + h * v + h * h * (0.25 * a + 0.25 * a1), v + 0.5 * h * (a + a1)

        a = _newton_root(lambda x: x - closed(*states(x), (step + 1) * h), a)
        q, v = states(a)
        qs.append(q)
    generated = simulate_scheme_loops_generated(ControlledModel(plant, pd_loops()), *START, t_final=n_steps * h,
                                                dt=h, scheme="newmark")
    assert np.max(np.abs(generated["a.theta"] - np.array(qs)[:, 0])) <= 1e-10
    assert np.max(np.abs(generated["b.theta"] - np.array(qs)[:, 1])) <= 1e-10


def test_a_lag_controller_equals_newmark_and_the_trapezoidal_rule_on_the_lagrange_equations(plant):
    """u = -C(s) theta_a with C(s) = k p / (s + p) written as z' = -p z + e, u = -k p z (another realisation than
    python-control's: the trapezoidal rule is invariant under it), solved with Newmark monolithically."""
    lagrange = PlanarLagrange(plant)
    h, n_steps, half = 0.01, 30, 0.005

    def lag_state(z, e, e_new):
        return ((1.0 - half * LAG_POLE) * z + half * (e + e_new)) / (1.0 + half * LAG_POLE)

    def closed(q, v, t, z):
        torque = -LAG_GAIN * LAG_POLE * z
        return lagrange.accelerations(q, v, t) + np.linalg.solve(lagrange.mass_matrix(q, t), np.array([torque, 0.0]))

    q, v, z = START[0].copy(), START[1].copy(), 0.0
    e = q[0]
    a = closed(q, v, 0.0, z)
    qs = [q]
    for step in range(n_steps):
        def states(a1, q=q, v=v, a=a, z=z, e=e):
            q1 = q + h * v + h * h * (0.25 * a + 0.25 * a1)
            return q1, v + 0.5 * h * (a + a1), lag_state(z, e, q1[0])

        a = _newton_root(lambda x: x - closed(*states(x)[:2], (step + 1) * h, states(x)[2]), a)
        q, v, z = states(a)
        e = q[0]
        qs.append(q)
    generated = simulate_scheme_loops_generated(ControlledModel(plant, lti_loops()[:1]), *START, t_final=n_steps * h,
                                                dt=h, scheme="newmark")
    assert np.max(np.abs(generated["a.theta"] - np.array(qs)[:, 0])) <= 1e-10
    assert np.max(np.abs(generated["b.theta"] - np.array(qs)[:, 1])) <= 1e-10


def delayed_loops() -> list[Feedback]:
    """A delayed PD (3 steps of 10 ms), a delayed lag with saturation (1 step) and a real-time rate loop."""
    return [Feedback("late", [("a.theta", 6.0), ("a.omega", 1.0)], "o.torque", gain=1.0, delay=0.03),
            Feedback("lag", "h.angle", "h.torque", gain=control.tf([2.0], [1.0, 3.0]), delay=0.01,
                     saturation=(-0.06, 0.06)),
            Feedback("damp", [("b.omega", 0.3)], "h.torque", gain=1.0)]


@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "generalized_alpha", "forward_euler"])
def test_delayed_loops_from_the_generated_ring_equal_the_python_dt_tmm_path(plant, scheme):
    """delay = m dt: the samples of the ring equal the Python path's delay history at its nodes."""
    controlled = ControlledModel(plant, delayed_loops())
    x0, v0 = _start(plant)
    options = dict(method=scheme, x0=x0, v0=v0, references={"late": 0.1})
    _, python = both_paths(controlled, 0.3, options)
    assert 0.0 < np.mean(python["lag.saturated"]) < 1.0


def method_of_steps(plant, kp: float, kd: float, tau: float, t_final: float) -> np.ndarray:
    """``[q, v]`` at ``t_final`` of the Lagrange equations with ``u(t) = -(kp theta_a(t - tau) + kd omega_a(t - tau))``
    on the pivot (the initial state :data:`START` held before t = 0), integrated interval by interval of length
    ``tau`` by DOP853 (rtol 1e-12) with the delayed signal from the previous interval's dense output."""
    lagrange, (q0, v0) = PlanarLagrange(plant), START

    def delayed_start(s):
        return q0[0], v0[0]

    past, y = delayed_start, np.concatenate([q0, v0])
    for k in range(round(t_final / tau)):
        def rhs(t, x, past=past):
            angle, rate = past(t - tau)
            torque = np.array([-(kp * angle + kd * rate), 0.0])
            return np.concatenate([x[2:], lagrange.accelerations(x[:2], x[2:], t)
                                   + np.linalg.solve(lagrange.mass_matrix(x[:2], t), torque)])

        piece = scipy.integrate.solve_ivp(rhs, (k * tau, (k + 1) * tau), y, method="DOP853", rtol=1e-12,
                                          atol=1e-12, dense_output=True)
        y = piece.y[:, -1]

        def past(s, piece=piece, before=past, start=k * tau):
            return (piece.sol(s)[0], piece.sol(s)[2]) if s >= start - 1e-12 else before(s)
    return y


def delayed_pd_errors(plant, kp: float, kd: float, tau: float, t_final: float, scheme: str) -> list[float]:
    """Largest angle error at ``t_final`` of the generated ``scheme`` with ``dt`` = 10 ms and 5 ms against
    :func:`method_of_steps`."""
    y = method_of_steps(plant, kp, kd, tau, t_final)
    controlled = ControlledModel(plant, [Feedback("late", [("a.theta", kp), ("a.omega", kd)], "o.torque", gain=1.0,
                                                  delay=tau)])
    errors = []
    for dt in (0.01, 0.005):
        run = simulate_scheme_loops_generated(controlled, *START, t_final=t_final, dt=dt, scheme=scheme)
        errors.append(max(abs(run["a.theta"][-1] - y[0]), abs(run["b.theta"][-1] - y[1])))
    return errors


def test_a_delayed_pd_converges_at_second_order_to_the_method_of_steps_on_the_lagrange_equations(plant):
    """u(t) = -(kp theta_a(t - tau) + kd omega_a(t - tau)), tau = 4 and 8 steps: generated Newmark errors at T
    against :func:`method_of_steps` fall 4x per halving of dt."""
    errors = delayed_pd_errors(plant, 6.0, 1.0, 0.04, 0.4, "newmark")
    assert errors[0] < 2e-4 and abs(np.log2(errors[0] / errors[1]) - 2.0) < 0.1, errors


# ---------------------------------------------------------------- (3) stability check with the loops
def test_the_stability_check_includes_the_loops(plant):
    stiff = [Feedback("stiff", [("a.theta", 2e5)], "o.torque", gain=1.0)]
    x0, v0 = _start(plant)
    scheme = Newmark(beta=0.1, gamma=0.5)           # conditionally stable: dt omega_max <= 1 / sqrt(0.15)
    ctmm.simulate(plant, 0.02, 0.01, method=scheme, x0=x0, v0=v0, compiled=True, stability_check="error")
    for compiled in (True, None):                    # the loop's 2e5 N m/rad sets omega_max on both paths
        with pytest.raises(ModelError, match="linearised about the initial state"):
            ctmm.simulate(ControlledModel(plant, stiff), 0.02, 0.01, method=scheme, x0=x0, v0=v0, compiled=compiled,
                          stability_check="error")


# ---------------------------------------------------------------- (4) refusals
@pytest.mark.parametrize("loop, scheme, match", [      # (delays: tests/test_compiled_scheme_delays.py)
    (Feedback("improper", "a.theta", "o.torque", gain=control.tf([1.0, 2.0], [1.0])), "newmark", "improper"),
])
def test_what_is_not_compiled_is_refused_by_name(plant, loop, scheme, match):
    with pytest.raises(ModelError, match=match):
        ctmm.simulate(ControlledModel(plant, [loop]), 0.1, 0.01, method=scheme, compiled=True)


def test_a_foreign_compiled_step_is_refused(plant):
    controlled = ControlledModel(plant, pd_loops())
    with pytest.raises(ModelError, match="CompiledSchemeLoops"):
        simulate_scheme_loops_generated(controlled, *START, t_final=0.1, dt=0.01, compiled="step")
    with pytest.raises(ModelError, match="ControlledModel of a PlanarModel"):
        CompiledSchemeLoops(plant)
    late = ControlledModel(plant, [Feedback("late", "a.theta", "o.torque", gain=2.0, delay=0.02)])
    with pytest.raises(ModelError, match="delay rings for dt = 0.01 s"):
        simulate_scheme_loops_generated(late, *START, t_final=0.1, dt=0.02,
                                        compiled=CompiledSchemeLoops(late, "newmark", dt=0.01))


# ---------------------------------------------------------------- (5) failures
def test_a_failed_step_keeps_the_loop_signals_in_its_partial_result(plant):
    with pytest.raises(ConvergenceError, match="did not converge") as info:
        simulate_scheme_loops_generated(ControlledModel(plant, pd_loops()), *START, t_final=0.5, dt=0.05,
                                        max_iterations=1)
    partial = info.value.partial_result
    assert partial.time.tolist() == [0.0]
    assert partial["pd.u"][0] == pytest.approx(-(KP * START[0][0] + KD * START[1][0]), rel=1e-12)
