"""``ctmm.simulate`` on planar models with loops and co-simulated controllers (issue 12 Done-when).

References are independent of the transfer matrices: the Lagrange model
(:mod:`ctmm.reference.planar_lagrange`) integrated by DOP853 at tolerance 1e-12, with the control
written out here from the model's geometry (not through :mod:`ctmm.planar.ports`):

* a real-time loop is part of the reference's right-hand side;
* a delayed loop is integrated by the method of steps (segments of one delay, the control from
  the previous segment's dense output; before t = 0 the initial state held);
* a sampled controller is sampled at its sample times and its output held, the reference
  restarting at every sample (the measurement of a delayed controller is the reference state
  stored at the earlier sample time).
"""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.control import FMUController, Feedback, build_fmu
from ctmm.control.controlled_model import ControlledModel
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.ports import actuator_unit
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.results import SimulationResult

from _controllers_import import load_controllers

G = 9.81


def pendulum(hinge) -> PlanarModel:
    """Uniform rod (1 kg, 1 m) on a hinge at the origin: tip at ``(cos theta, sin theta)``."""
    return PlanarModel.chain("pendulum", [Fixed("ground"), hinge, RigidBody.uniform_link("rod", mass=1.0,
                                                                                          length=1.0)])


class Cell:
    """The hinge torque of a reference model: ``torque(t)`` returns whatever the driver set."""

    def __init__(self) -> None:
        self.value = 0.0

    def __call__(self, t: float) -> float:
        return self.value


def reference_rhs(model_with_cell, cell: Cell, control):
    """Lagrange right-hand side with the hinge torque ``control(t, y)`` set before each evaluation."""
    lagrange = PlanarLagrange(model_with_cell)
    n = lagrange.n

    def rhs(t, y):
        cell.value = control(t, y)
        return np.concatenate([y[n:], lagrange.accelerations(y[:n], y[n:], t)])

    return rhs


def dop853(rhs, t_span, y0, t_eval=None, dense=False):
    sol = scipy.integrate.solve_ivp(rhs, t_span, y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval,
                                    dense_output=dense)
    assert sol.success, sol.message
    return sol


# ------------------------------------------------------------------------------ embedded loops
KP, KD, TARGET = 30.0, 4.0, -1.2     # u = -(KP (theta - TARGET) + KD omega) [N m]


def test_real_time_feedback_on_a_pendulum_matches_lagrange():
    """A real-time PD ``Feedback`` (angle and rate sensors, hinge torque) with a reference: every RK4
    stage sees the current state, so the run converges at fourth order to the Lagrange closed loop."""
    loop = Feedback("pd", [("rod.theta", KP), ("rod.omega", KD)], "pivot.torque", gain=1.0)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    t_final, y0 = 1.5, np.array([-math.pi / 2, 0.0])
    errors = []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(system, t_final, dt, x0={"rod.theta": y0[0]}, references={"pd": KP * TARGET})
        cell = Cell()
        rhs = reference_rhs(pendulum(ActuatedHinge("pivot", torque=cell)), cell,
                            lambda t, y: -(KP * y[0] + KD * y[1] - KP * TARGET))
        ref = dop853(rhs, (0.0, t_final), y0, t_eval=result.time)
        errors.append(np.max(np.abs(result["rod.theta"] - ref.y[0])))
        u_ref = -(KP * ref.y[0] + KD * ref.y[1] - KP * TARGET)
        assert np.max(np.abs(result["pd.u"] - u_ref)) < 1e-5 * np.max(np.abs(u_ref))
        np.testing.assert_allclose(result["pd.y"], KP * ref.y[0] + KD * ref.y[1], atol=1e-5)
    assert errors[1] < 2e-9, errors
    assert errors[0] / errors[1] > 12.0, errors          # fourth order (16 asymptotically)
    assert result.unit("pd.u") == actuator_unit(system.plant, "pivot.torque") != ""
    assert result.unit("rod.theta") == "rad" and result.unit("pd.y") == ""   # rad and rad/s terms mixed
    assert result.info["loops"] == {"pd": "real-time"}


def test_lti_controller_states_are_integrated_with_the_plant():
    """``C(s) = K a / (s + a)`` (a first-order lag on the angle error): its state is integrated with
    the plant; the reference carries the lag state ``x' = a (e - x)``, ``u = -K x``."""
    control = pytest.importorskip("control")
    K, a = 25.0, 40.0
    loop = Feedback("lag", "rod.theta", "pivot.torque", gain=control.tf([K * a], [1.0, a]))
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    t_final, dt = 1.0, 1e-3
    result = ctmm.simulate(system, t_final, dt, x0=[-math.pi / 2], references={"lag": TARGET})
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=(cell := Cell()))))

    def rhs(t, y):
        e = y[0] - TARGET
        cell.value = -K * y[2]
        return np.array([y[1], lagrange.accelerations(y[:1], y[1:2], t)[0], a * (e - y[2])])

    ref = dop853(rhs, (0.0, t_final), [-math.pi / 2, 0.0, 0.0], t_eval=result.time)
    assert np.max(np.abs(result["rod.theta"] - ref.y[0])) < 1e-8
    assert np.max(np.abs(result["lag.u"] + K * ref.y[2])) < 1e-6


def test_delayed_feedback_on_a_pendulum_matches_the_method_of_steps():
    """``u(t) = -K (theta(t - tau) - r) - D omega(t - tau)`` read from the one delay history (cubic
    Hermite between steps) vs DOP853 by the method of steps."""
    K, D, tau, t_final, dt = 12.0, 1.5, 0.05, 1.0, 1e-3
    loop = Feedback("late", [("rod.theta", K), ("rod.omega", D)], "pivot.torque", gain=1.0, delay=tau)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    y0 = np.array([-math.pi / 2, 0.0])
    result = ctmm.simulate(system, t_final, dt, x0=y0[:1], references={"late": K * TARGET})
    cell = Cell()
    past = [lambda s: y0]                        # state history before the current segment
    law = lambda y: -(K * (y[0] - TARGET) + D * y[1])   # noqa: E731
    rhs = reference_rhs(pendulum(ActuatedHinge("pivot", torque=cell)), cell,
                        lambda t, y: law(past[-1](t - tau)))
    times, thetas, start, y = [], [], 0.0, y0
    while start < t_final - 1e-12:
        end = min(start + tau, t_final)
        sol = dop853(rhs, (start, end), y, dense=True)
        grid = result.time[(result.time >= start - 1e-12) & (result.time <= end + 1e-12)]
        times.append(grid)
        thetas.append(sol.sol(grid)[0])
        previous = sol.sol
        past.append(lambda s, f=previous, t0=start: f(s) if s >= t0 - 1e-12 else y0)
        start, y = end, sol.y[:, -1]
    theta_ref = np.interp(result.time, np.concatenate(times), np.concatenate(thetas))
    assert np.max(np.abs(result["rod.theta"] - theta_ref)) < 1e-10
    assert result.info["loops"] == {"late": "history"}
    # before tau the loop acts on the initial state held
    early = result.time < tau - 1e-12
    np.testing.assert_allclose(result["late.u"][early], law(y0), rtol=1e-12)


def test_loop_refusals():
    model = pendulum(SmoothHinge("pivot"))
    with pytest.raises(ModelError, match="delay = 0.0005 s is shorter than the step"):
        ctmm.simulate(ControlledModel(model, [Feedback("f", "rod.theta", "pivot.torque", 1.0, delay=5e-4)]),
                      0.01, 1e-3)
    with pytest.raises(ModelError, match="rod.thetaa"):
        ctmm.simulate(ControlledModel(model, [Feedback("f", "rod.thetaa", "pivot.torque", 1.0)]), 0.01, 1e-3)
    with pytest.raises(ModelError, match="shorter than 1.4 dt"):
        ctmm.simulate(ControlledModel(model, [Feedback("f", "rod.theta", "pivot.torque", 1.0, delay=1e-3)]), 0.01,
                      1e-3, method="wilson_theta")
    control = pytest.importorskip("control")
    with pytest.raises(ModelError, match="cannot be realised in time"):
        ctmm.simulate(ControlledModel(model, [Feedback("f", "rod.theta", "pivot.torque", control.tf([1, 2], [1]))]),
                      0.01, 1e-3)


def test_diverging_loop_stops_with_the_partial_result():
    """A destabilising positive feedback: SimulationError at the divergence bound, with the rows so far."""
    loop = Feedback("bad", "rod.theta", "pivot.torque", gain=-500.0)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(system, 5.0, 1e-3, x0=[-1.0], divergence_bound=50.0, stability_check="ignore")
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult)
    assert 0 < len(partial.time) < 5001 and "bad.u" in partial.signals()
    assert np.all(np.abs(partial["rod.theta"] + 1.0) <= 50.0)


# ---------------------------------------------------------------------------- controllers (FMU)
def hinge_arm(hub) -> PlanarModel:
    from ctmm.scenarios.hinge_spring_motor import arm

    return arm(hub)


def tip(y: np.ndarray) -> tuple[float, float]:
    """Tip height and vertical speed of the hinge_spring_motor arm (upper 0.6 m, fore tip at 0.5 m)."""
    th1, th2, w1, w2 = y
    return 0.6 * math.sin(th1) + 0.5 * math.sin(th2), 0.6 * math.cos(th1) * w1 + 0.5 * math.cos(th2) * w2


@pytest.fixture(scope="module")
def pd_fmu(tmp_path_factory):
    assert shutil.which("gcc"), "gcc is required to build the test FMU"
    controllers = load_controllers()
    return build_fmu(controllers.fmu_source("pd_controller"), tmp_path_factory.mktemp("fmu"), compiler="gcc")


def test_delayed_fmu_tip_controller_on_the_hinge_spring_motor_arm(pd_fmu):
    """Issue 12 Done-when: an FMU built by the project reads the tip height ``fore.out.y`` (and
    its rate) 20 ms late, writes ``motor.torque`` every 10 ms (held), on the hinge_spring_motor arm
    whose hub also has its PD motor tracking the quintic move; vs the Lagrange model restarted at
    every sample with the same held torques and the tip computed from the geometry."""
    from ctmm.scenarios.hinge_spring_motor import reference_angle, reference_rate

    kp, kd, target, h, delay, t_final, dt = 8.0, 0.8, -0.2, 0.01, 0.02, 1.0, 1e-3
    motor = dict(kp=200.0, kd=20.0, reference=reference_angle, reference_rate=reference_rate)
    fmu = FMUController(pd_fmu, inputs={"y": "fore.out.y", "ydot": "fore.out.vy"},
                        outputs={"u": "motor.torque"}, parameters={"kp": kp, "kd": kd, "reference": target},
                        sample_time=h)
    model = hinge_arm(ActuatedHinge("motor", **motor))
    y0 = np.array([-math.pi / 2, -math.pi / 2, 0.0, 0.0])
    result = ctmm.simulate(model, t_final, dt, x0=y0[:2], controllers=[DelayedController(fmu, delay)],
                           outputs=["fore.out.y"])
    np.testing.assert_allclose(result["fore.out.y"][0], tip(y0)[0], atol=1e-14)

    cell = Cell()
    lagrange = PlanarLagrange(hinge_arm(ActuatedHinge("motor", torque=cell, **motor)))
    rhs = lambda t, y: np.concatenate([y[2:], lagrange.accelerations(y[:2], y[2:], t)])  # noqa: E731
    n_samples = int(round(t_final / h))
    lag = int(round(delay / h))
    states, torques, y = [y0], [], y0
    for k in range(n_samples):
        measured = tip(states[max(k - lag, 0)])
        cell.value = kp * (target - measured[0]) - kd * measured[1]
        torques.append(cell.value)
        sol = dop853(rhs, (k * h, (k + 1) * h), y)
        y = sol.y[:, -1]
        states.append(y)
    states = np.array(states)
    rows = np.round(np.arange(n_samples + 1) * h / dt).astype(int)
    error = np.max(np.abs(np.column_stack([result["upper.theta"], result["fore.theta"]])[rows] - states[:, :2]))
    assert error < 1e-8, error
    samples = result["motor.torque@samples"]
    np.testing.assert_allclose(samples[:, 0], np.arange(n_samples + 1)[:len(samples)] * h, atol=1e-12)
    assert np.max(np.abs(samples[:n_samples, 1] - torques)) < 1e-8
    assert np.ptp(torques) > 0.5                     # the controller really acts
    assert result.info["controllers"][0]["sample_time"] == pytest.approx(h)


def test_python_controller_without_delay_and_scipy_method(pd_fmu):
    """The same sample-and-hold through a scipy method (restarted at every sample) agrees with RK4."""
    controllers = load_controllers()
    pd = controllers.SaturatedPD(("fore.out.y", "fore.out.vy"), ("motor.torque",), kp=8.0, kd=0.8,
                                 reference=-0.2, sample_time=0.01)
    model = hinge_arm(ActuatedHinge("motor", kp=200.0, kd=20.0, reference=-math.pi / 2))
    x0 = {"upper.theta": -1.2, "fore.theta": -1.2}
    a = ctmm.simulate(model, 0.3, 1e-3, x0=x0, controllers=[pd])
    b = ctmm.simulate(model, 0.3, 1e-3, method="DOP853", x0=x0, controllers=[pd], rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(a.time, b.time, atol=1e-12)
    assert np.max(np.abs(a["upper.theta"] - b["upper.theta"])) < 1e-8


def test_open_loop_inputs_and_unknown_names():
    """``inputs`` drive named actuators: a constant hinge torque equals an ActuatedHinge torque."""
    model = pendulum(SmoothHinge("pivot"))
    a = ctmm.simulate(model, 0.5, 1e-3, inputs={"pivot.torque": lambda t: 2.0 * math.sin(3 * t)})
    b = ctmm.simulate(pendulum(ActuatedHinge("pivot", torque=lambda t: 2.0 * math.sin(3 * t))), 0.5, 1e-3)
    np.testing.assert_allclose(a["rod.theta"], b["rod.theta"], rtol=0, atol=1e-13)
    with pytest.raises(ModelError, match="pivot.force"):
        ctmm.simulate(model, 0.5, 1e-3, inputs={"pivot.force": 1.0})
    with pytest.raises(ModelError, match="not both"):
        ctmm.simulate(model, 0.5, 1e-3, method="rk4", scheme="rk4")


def test_a_chain_refuses_a_delayed_controller():
    """The chain stepper has no measurement delay: a DelayedController there would be read on time
    (the co-simulation master refuses it for every stepper that does not apply the delay)."""
    controllers = load_controllers()
    from ctmm.elements import Fixed as Wall, Free, Mass, Spring

    chain = ctmm.Chain("sdof", [Wall("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("tip")])
    pd = controllers.SaturatedPD(("m.x", "m.v"), ("m.force",), kp=5.0, kd=0.5, sample_time=0.01)
    with pytest.raises(ModelError, match="measurement delay, which this stepper does not apply"):
        ctmm.simulate(chain, 0.1, 1e-3, controllers=[DelayedController(pd, 0.02)])
    with pytest.raises(ModelError, match="delay must be a finite measurement delay > 0"):
        DelayedController(pd, 0.0)


def test_manipulator_scene_with_delayed_loops_matches_the_lagrange_manipulator():
    """The seed manipulator as a scene (hub PD 2 ms late, slope-rate PZT loops 1 ms late, on a
    modal arm) run by ``ctmm.simulate`` vs the independent Lagrange manipulator with the same laws
    and delays (method of steps, DOP853 1e-11)."""
    from ctmm.manipulator import SEED_KD, SEED_KP, SEED_MOVE, HubPD, PZTFeedback, seed_manipulator
    from ctmm.manipulator.scene import manipulator_scene, scene_references
    from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

    gains = np.diag([300.0, 150.0, 80.0])
    seed = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD, delay=0.002), PZTFeedback(gains, delay=0.001)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    result = ctmm.simulate(scene, 0.25, 1e-3, references=scene_references(pd, SEED_MOVE))
    reference = ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)
    ref = reference.simulate(0.25, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pd_delay=0.002, pzt_gains=gains,
                             pzt_delay=0.001, t_eval=result.time)
    scale = scene.plant.bodies[scene.plant.body_index("arm")].data.tip_phi / reference.phi_tip
    eta = scale * np.column_stack([result[f"arm.q{k}"] for k in (1, 2, 3)])
    assert np.max(np.abs(result["hub.theta"] - ref.theta)) < 1e-9
    assert np.max(np.abs(eta - ref.eta)) < 1e-8 * np.max(np.abs(ref.eta))
    np.testing.assert_allclose(result["hub_pd.u"], ref.hub_torque, atol=1e-6 * np.max(np.abs(ref.hub_torque)))
    assert set(result.info["loops"].values()) == {"history"}


def test_failing_controller_init_gives_an_empty_partial_result():
    class Broken:
        inputs, outputs, sample_time, direct_feedthrough = ("rod.theta",), ("pivot.torque",), 0.01, False

        def init(self, t0):
            raise RuntimeError("no licence")

        def step(self, t, y, state):
            return [0.0], state

    with pytest.raises(SimulationError, match="no licence") as info:
        ctmm.simulate(pendulum(SmoothHinge("pivot")), 0.1, 1e-3, controllers=[Broken()])
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult) and len(partial.time) == 0 and len(partial["rod.theta"]) == 0


def test_embedded_pd_equals_a_sampled_pd_as_the_sample_time_goes_to_zero():
    """Metamorphic identity: the real-time PD ``Feedback`` and a co-simulated ``SaturatedPD`` (no
    limit) held over its sample time ``h`` differ by O(h) (first order); the loop reference given as
    the input ``"pd.reference"`` equals ``references``."""
    controllers = load_controllers()
    model = pendulum(SmoothHinge("pivot"))
    loop = Feedback("pd", [("rod.theta", KP), ("rod.omega", KD)], "pivot.torque", gain=1.0)
    # RK4 1 ms over 0.25 s: the gaps are those of 0.5 ms over 0.5 s to 1e-8 relative (3.3e-3, 1.6e-3, 8.2e-4 rad,
    # largest early in the swing)
    embedded = ctmm.simulate(ControlledModel(model, [loop]), 0.25, 1e-3, x0=[-math.pi / 2],
                             inputs={"pd.reference": KP * TARGET})
    same = ctmm.simulate(ControlledModel(model, [loop]), 0.25, 1e-3, x0=[-math.pi / 2],
                         references={"pd": KP * TARGET})
    np.testing.assert_array_equal(embedded["rod.theta"], same["rod.theta"])
    gaps = []
    for h in (4e-3, 2e-3, 1e-3):
        pd = controllers.SaturatedPD(("rod.theta", "rod.omega"), ("pivot.torque",), kp=KP, kd=KD, reference=TARGET,
                                     sample_time=h)
        sampled = ctmm.simulate(model, 0.25, 1e-3, x0=[-math.pi / 2], controllers=[pd])
        gaps.append(np.max(np.abs(sampled["rod.theta"] - embedded["rod.theta"])))
    assert 1.7 < gaps[0] / gaps[1] < 2.3 and 1.7 < gaps[1] / gaps[2] < 2.3, gaps
    with pytest.raises(ModelError, match="reference in both"):
        ctmm.simulate(ControlledModel(model, [loop]), 0.01, 1e-3, inputs={"pd.reference": 1.0},
                      references={"pd": 1.0})
