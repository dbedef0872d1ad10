"""``ctmm.simulate`` with an implicit DT-TMM scheme on planar models with loops, inputs and controllers.

The loops enter :func:`ctmm.planar.implicit.simulate_implicit` through its Newton-iterate input
hook, the controllers and the delay history through its per-step callback.  References are
independent of the transfer matrices: the Lagrange model (:mod:`ctmm.reference.planar_lagrange`,
:mod:`ctmm.reference.manipulator_lagrange`) integrated by DOP853 at tight tolerance with the
control written out here from the geometry (a delayed loop by the method of steps, a sampled
controller by restarting the reference at every sample with the held output).  Each scheme must
converge to them at its order (2; backward Euler 1).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError
from ctmm.planar import ActuatedHinge, SmoothHinge
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.results import SimulationResult

from _controllers_import import load_controllers
from test_planar_control_time import Cell, dop853, pd_fmu, pendulum, reference_rhs  # noqa: F401 (fixture)

KP, KD, TARGET = 30.0, 4.0, -1.2          # u = -(KP (theta - TARGET) + KD omega) [N m]
THETA0 = -math.pi / 2
# (scheme, order, bound on the angle error [rad] at dt = 2 ms over 0.5 s: about twice the measured one; the largest
# errors are in the first swing, the same to all digits over 1 s)
SCHEMES = [("newmark", 2, 1.5e-5), ("generalized_alpha", 2, 1.5e-5), ("wilson_theta", 2, 5e-5), ("houbolt", 2, 1.2e-4),
           ("forward_euler", 1, 4e-3)]


def observed_order(errors: list[float]) -> float:
    """log2 of the error ratio of two runs whose steps differ by a factor 2."""
    return math.log2(errors[0] / errors[1])


def pd_system(delay: float = 0.0) -> ControlledModel:
    loop = Feedback("pd", [("rod.theta", KP), ("rod.omega", KD)], "pivot.torque", gain=1.0, delay=delay)
    return ControlledModel(pendulum(SmoothHinge("pivot")), [loop])


def law(y: np.ndarray) -> float:
    return -(KP * (y[0] - TARGET) + KD * y[1])


@pytest.mark.parametrize("method, order, bound", SCHEMES)
def test_real_time_pd_loop_converges_to_lagrange_at_the_scheme_order(method, order, bound):
    """The loop is evaluated at every Newton iterate (implicit in the step); its state dependence is
    in the Newton tangent, so Newton still converges in about two iterations."""
    t_final, errors = 0.5, []
    cell = Cell()
    rhs = reference_rhs(pendulum(ActuatedHinge("pivot", torque=cell)), cell, lambda t, y: law(y))
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(pd_system(), t_final, dt, method=method, x0=[THETA0], references={"pd": KP * TARGET})
        ref = dop853(rhs, (0.0, t_final), [THETA0, 0.0], t_eval=result.time)
        errors.append(float(np.max(np.abs(result["rod.theta"] - ref.y[0]))))
        u_ref = np.array([law(y) for y in ref.y.T])
        assert np.max(np.abs(result["pd.u"] - u_ref)) < 50.0 * (KP + KD) * errors[-1] + 1e-9
    assert abs(observed_order(errors) - order) < 0.2, errors
    assert errors[1] < bound, errors
    assert result.info["loops"] == {"pd": "real-time"}
    assert result.info["newton_iterations_max"] <= 3
    assert result.info["method"].startswith("dt-tmm/")


@pytest.mark.parametrize("method, bound", [("newmark", 1.5e-5), ("houbolt", 1.2e-4)])   # ~2x the measured error
def test_delayed_loop_converges_to_the_method_of_steps(method, bound):
    """``u(t) = -K (theta(t - tau) - r) - D omega(t - tau)`` from the one delay history (appended by
    the scheme's per-step callback) vs DOP853 by the method of steps (before 0: the initial state)."""
    tau, t_final = 0.05, 0.6
    y0 = np.array([THETA0, 0.0])
    cell = Cell()
    segments: list = []                         # dense solutions of the finished segments

    def past(s: float) -> np.ndarray:
        for start, solution in reversed(segments):
            if s >= start - 1e-12:
                return solution(s)
        return y0

    rhs = reference_rhs(pendulum(ActuatedHinge("pivot", torque=cell)), cell, lambda t, y: law(past(t - tau)))
    start, y = 0.0, y0
    while start < t_final - 1e-12:              # each segment of one delay reads the finished ones
        sol = dop853(rhs, (start, min(start + tau, t_final)), y, dense=True)
        segments.append((start, sol.sol))
        start, y = sol.t[-1], sol.y[:, -1]
    errors = []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(pd_system(delay=tau), t_final, dt, method=method, x0=[THETA0],
                               references={"pd": KP * TARGET})
        theta_ref = np.array([past(t)[0] for t in result.time])
        errors.append(float(np.max(np.abs(result["rod.theta"] - theta_ref))))
    assert abs(observed_order(errors) - 2.0) < 0.25, errors
    assert errors[1] < bound, errors
    assert result.info["loops"] == {"pd": "history"}
    early = result.time < tau - 1e-12
    np.testing.assert_allclose(result["pd.u"][early], law(y0), rtol=1e-12)


@pytest.mark.parametrize("delay", [0.0, 0.02])
def test_sampled_python_controller_with_newmark_converges_to_the_restarted_lagrange(delay):
    """A co-simulated PD sampled every 10 ms (held), optionally reading 20 ms late: Newmark with
    steps 2 and 1 ms vs the Lagrange model restarted at every sample with the same held torque.
    Second order only because the step after a sample starts from the acceleration with the new
    held torque (without that restart the error is first order)."""
    controllers = load_controllers()
    h, t_final = 0.01, 0.5
    pd = controllers.SaturatedPD(("rod.theta", "rod.omega"), ("pivot.torque",), kp=KP, kd=KD, reference=TARGET,
                                 sample_time=h)
    controller = DelayedController(pd, delay) if delay else pd
    cell = Cell()
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=cell)))
    n_samples, lag = int(round(t_final / h)), int(round(delay / h))
    states, torques, y = [np.array([THETA0, 0.0])], [], np.array([THETA0, 0.0])
    for k in range(n_samples):
        cell.value = law(states[max(k - lag, 0)])
        torques.append(cell.value)
        sol = dop853(lambda t, z: np.concatenate([z[1:], lagrange.accelerations(z[:1], z[1:], t)]),
                     (k * h, (k + 1) * h), y)
        y = sol.y[:, -1]
        states.append(y)
    states = np.array(states)
    errors = []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(pendulum(SmoothHinge("pivot")), t_final, dt, method="newmark", x0=[THETA0],
                               controllers=[controller])
        rows = np.round(np.arange(n_samples + 1) * h / dt).astype(int)
        errors.append(float(np.max(np.abs(result["rod.theta"][rows] - states[:, 0]))))
        samples = result["pivot.torque@samples"]
        np.testing.assert_allclose(samples[:, 0], np.arange(n_samples + 1) * h, atol=1e-12)
        assert np.max(np.abs(samples[:n_samples, 1] - torques)) < 1e3 * errors[-1]
    assert abs(observed_order(errors) - 2.0) < 0.25, errors
    assert errors[1] < 8e-7, errors                   # measured 3.1e-7 and 3.9e-7
    assert np.ptp(torques) > 10.0                      # the controller really acts


@pytest.mark.parametrize("pd_delay, pzt_delay", [(0.0, 0.0), (0.002, 0.001)])
def test_manipulator_scene_with_newmark_matches_the_lagrange_manipulator(pd_delay, pzt_delay):
    """The seed manipulator as a scene (hub PD and slope-rate PZT loops on a modal arm; real-time or
    late) with Newmark vs the independent Lagrange manipulator: second order in the hub angle and
    the modal coordinates."""
    from ctmm.manipulator import SEED_KD, SEED_KP, SEED_MOVE, HubPD, PZTFeedback, seed_manipulator
    from ctmm.manipulator.scene import manipulator_scene, scene_references
    from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

    gains = np.diag([300.0, 150.0, 80.0])
    seed = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD, delay=pd_delay), PZTFeedback(gains, delay=pzt_delay)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    reference = ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)
    t_final, grid = 0.2, np.linspace(0.0, 0.2, 21)
    ref = reference.simulate(t_final, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pd_delay=pd_delay,
                             pzt_gains=gains, pzt_delay=pzt_delay, t_eval=grid)
    scale = scene.plant.bodies[scene.plant.body_index("arm")].data.tip_phi / reference.phi_tip
    theta_errors, eta_errors = [], []
    for dt in (1e-3, 5e-4):
        result = ctmm.simulate(scene, t_final, dt, method="newmark", references=scene_references(pd, SEED_MOVE),
                               store_every=int(round(0.01 / dt)))
        np.testing.assert_allclose(result.time, grid, atol=1e-12)
        eta = scale * np.column_stack([result[f"arm.q{k}"] for k in (1, 2, 3)])
        theta_errors.append(float(np.max(np.abs(result["hub.theta"] - ref.theta))))
        eta_errors.append(float(np.max(np.abs(eta - ref.eta)) / np.max(np.abs(ref.eta))))
    assert abs(observed_order(theta_errors) - 2.0) < 0.3, theta_errors
    assert abs(observed_order(eta_errors) - 2.0) < 0.3, eta_errors
    assert theta_errors[1] < 2.5e-7 and eta_errors[1] < 1.5e-5, (theta_errors, eta_errors)   # measured 1.2e-7, 7e-6
    kind = "real-time" if pd_delay == 0.0 else "history"
    assert set(result.info["loops"].values()) == {kind}


@pytest.mark.parametrize("method", ["wilson_theta", "generalized_alpha"])
def test_open_loop_inputs_equal_the_same_torque_in_the_hinge(method):
    """Metamorphic identity: ``inputs={"pivot.torque": f}`` through the hook equals an ActuatedHinge
    with ``torque=f`` under the same scheme (Wilson-theta evaluates both at ``t_n + theta dt``)."""
    f = lambda t: 2.0 * math.sin(3.0 * t)                         # noqa: E731
    a = ctmm.simulate(pendulum(SmoothHinge("pivot")), 0.5, 2e-3, method=method, x0=[THETA0],
                      inputs={"pivot.torque": f})
    b = ctmm.simulate(pendulum(ActuatedHinge("pivot", torque=f)), 0.5, 2e-3, method=method, x0=[THETA0])
    np.testing.assert_allclose(a["rod.theta"], b["rod.theta"], rtol=0, atol=1e-12)


@pytest.mark.parametrize("method, bound", [("newmark", 4e-5), ("wilson_theta", 1.7e-4)])   # ~2x the measured
def test_lti_controller_states_advance_with_the_step_at_second_order(method, bound):
    """``C(s) = K a / (s + a)`` on the angle error: its state advances by the trapezoidal rule inside
    the implicit step (at every Newton iterate); the reference carries ``x' = a (e - x)``, ``u = -K x``."""
    control = pytest.importorskip("control")
    K, a, t_final = 25.0, 40.0, 0.6
    loop = Feedback("lag", "rod.theta", "pivot.torque", gain=control.tf([K * a], [1.0, a]))
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=(cell := Cell()))))

    def rhs(t, y):
        cell.value = -K * y[2]
        return np.array([y[1], lagrange.accelerations(y[:1], y[1:2], t)[0], a * (y[0] - TARGET - y[2])])

    theta_errors, u_errors = [], []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(ControlledModel(pendulum(SmoothHinge("pivot")), [loop]), t_final, dt, method=method,
                               x0=[THETA0], references={"lag": TARGET})
        ref = dop853(rhs, (0.0, t_final), [THETA0, 0.0, 0.0], t_eval=result.time)
        theta_errors.append(float(np.max(np.abs(result["rod.theta"] - ref.y[0]))))
        u_errors.append(float(np.max(np.abs(result["lag.u"] + K * ref.y[2]))))
    assert abs(observed_order(theta_errors) - 2.0) < 0.25, theta_errors
    assert abs(observed_order(u_errors) - 2.0) < 0.25, u_errors
    assert theta_errors[1] < bound, theta_errors


def test_refusals_with_a_scheme():
    with pytest.raises(ModelError, match="delay = 0.0012 s is shorter than 1.4 dt"):
        ctmm.simulate(pd_system(delay=1.2e-3), 0.01, 1e-3, method="wilson_theta")
    ctmm.simulate(pd_system(delay=1.2e-3), 0.01, 1e-3, method="newmark")      # one step late: fine
    with pytest.raises(ModelError, match="delay = 0.0005 s is shorter than the step"):
        ctmm.simulate(pd_system(delay=5e-4), 0.01, 1e-3, method="houbolt")
    with pytest.raises(ModelError, match="dt is required with method='newmark'"):
        ctmm.simulate(pd_system(), 0.01, method="newmark")


def test_failures_carry_the_rows_so_far():
    """A destabilising loop stops at the divergence bound, a controller that raises at 0.01 s stops
    there; both with a SimulationResult of the rows before."""
    bad = ControlledModel(pendulum(SmoothHinge("pivot")), [Feedback("bad", "rod.theta", "pivot.torque", -500.0)])
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(bad, 5.0, 1e-3, method="newmark", x0=[-1.0], divergence_bound=50.0, stability_check="ignore")
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult) and 0 < len(partial.time) < 5001 and "bad.u" in partial.signals()

    class Failing:
        inputs, outputs, sample_time, direct_feedthrough = ("rod.theta",), ("pivot.torque",), None, False

        def init(self, t0):
            return None

        def step(self, t, y, state):
            if t > 0.0095:
                raise RuntimeError("sensor lost")
            return [0.0], state

    with pytest.raises(SimulationError, match="sensor lost") as info:
        ctmm.simulate(pendulum(SmoothHinge("pivot")), 0.05, 1e-3, method="generalized_alpha", controllers=[Failing()])
    assert info.value.time == pytest.approx(0.01)
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult) and partial.time[-1] == pytest.approx(0.009)


def test_delayed_fmu_tip_controller_with_newmark_converges_to_the_rk4_path(pd_fmu):
    """The issue-12 case with Newmark: an FMU reads the tip height of the hinge_spring_motor arm
    (``fore.out.y`` and its rate) 20 ms late through the one delay history and writes the motor
    torque every 10 ms (held), the hub's own PD tracking the quintic move.  The RK4 path (checked
    against the restarted Lagrange model to 1e-8 rad in ``test_planar_control_time.py``) at 0.5 ms
    is the reference: Newmark converges to it at order 2."""
    from ctmm.control import FMUController
    from ctmm.scenarios.hinge_spring_motor import arm, reference_angle, reference_rate

    fmu = FMUController(pd_fmu, inputs={"y": "fore.out.y", "ydot": "fore.out.vy"}, outputs={"u": "motor.torque"},
                        parameters={"kp": 8.0, "kd": 0.8, "reference": -0.2}, sample_time=0.01)
    model = arm(ActuatedHinge("motor", kp=200.0, kd=20.0, reference=reference_angle, reference_rate=reference_rate))
    x0, t_final = {"upper.theta": -math.pi / 2, "fore.theta": -math.pi / 2}, 0.5
    controllers = [DelayedController(fmu, 0.02)]
    rk4 = ctmm.simulate(model, t_final, 5e-4, x0=x0, controllers=controllers, store_every=4)
    errors = []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(model, t_final, dt, method="newmark", x0=x0, controllers=controllers,
                               store_every=int(round(2e-3 / dt)))
        np.testing.assert_allclose(result.time, rk4.time, atol=1e-12)
        errors.append(float(np.max(np.abs(result["fore.theta"] - rk4["fore.theta"]))))
    assert abs(observed_order(errors) - 2.0) < 0.3, errors
    assert errors[1] < 3e-6, errors                                    # measured 1.4e-6 rad
    assert np.ptp(result["motor.torque@samples"][:, 1]) > 0.5          # the controller really acts
