"""Co-simulated controllers around generated kernels: ``ctmm.simulate(..., compiled=True, controllers=[...])``
(:mod:`ctmm.compiled_cosim`).

Independent checks:

* the exact sampled-data solution of a linear plant (``scipy.linalg.expm`` of the plant with the held
  input, the controller's law written here) -- the generated RK4 converges to it;
* the numpy path of the same model and controllers (``compiled`` off): the same RK4 of the same ODE
  with the same samples, so every signal and every sample record agree to round-off (1e-12), for a
  Python PID, the shipped PD FMU, a :class:`DelayedController`, loops inside the step, planar and spatial.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.control import Feedback, FMUController, build_fmu, with_feedback
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody
from ctmm.signals import Harmonic

from _controllers_import import load_controllers
from test_compiled_scene import hub_beam, rigid_tree
from test_compiled_scene_loops import station_beam

pytest.importorskip("casadi")

STIFFNESS, INERTIA = 40.0, 0.5


@pytest.fixture(autouse=True, scope="module")
def kernel_cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


@pytest.fixture(scope="module")
def pd_fmu(tmp_path_factory):
    assert shutil.which("gcc"), "gcc is required to build the test FMU"
    return build_fmu(load_controllers().fmu_source("pd_controller"), tmp_path_factory.mktemp("fmu"), compiler="gcc")


def assert_same(generated: ctmm.SimulationResult, python: ctmm.SimulationResult, names: list[str]) -> None:
    """Every named signal of the two runs equal to 1e-12 of its scale; the same sample records."""
    np.testing.assert_array_equal(generated.time, python.time)
    for name in names:
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) < 1e-12 * scale, name
    samples = [name for name in python.signals() if name.endswith("@samples")]
    assert samples and sorted(samples) == sorted(n for n in generated.signals() if n.endswith("@samples"))
    for name in samples:
        np.testing.assert_array_equal(generated[name][:, 0], python[name][:, 0])
        np.testing.assert_allclose(generated[name][:, 1], python[name][:, 1], rtol=0, atol=1e-12, err_msg=name)


def torsion() -> PlanarModel:
    """One body on an elastic hinge at its centre of mass, no gravity: I theta'' = -k theta + torque (linear)."""
    return PlanarModel.chain("torsion", [Fixed("g"), ElasticHinge("h", stiffness=STIFFNESS),
                                         RigidBody("b", mass=1.0, inertia=INERTIA, center_of_mass=(0.0, 0.0))],
                             gravity=(0.0, 0.0))


def sampled_p_loop(stiffness: float, inertia: float, kp: float, r: float, h: float, x0: float, n: int) -> np.ndarray:
    """Exact sampled-data positions ``x_j`` of ``inertia x'' = -stiffness x + u_j``, ``u_j = kp (r - x_j)`` held on
    ``[t_j, t_j + h)``, from ``x(0) = x0`` at rest: ``scipy.linalg.expm`` of the plant augmented with the held
    input, ``n`` samples."""
    a = np.array([[0.0, 1.0], [-stiffness / inertia, 0.0]])
    b = np.array([[0.0], [1.0 / inertia]])
    augmented = scipy.linalg.expm(np.block([[a, b], [np.zeros((1, 3))]]) * h)
    z, exact = np.array([x0, 0.0]), [x0]
    for _ in range(n):
        z = augmented[:2, :2] @ z + augmented[:2, 2] * kp * (r - z[0])
        exact.append(z[0])
    return np.array(exact)


def test_linear_plant_with_a_sampled_p_controller_equals_the_exact_zoh_solution():
    """theta'' = (-k theta + u_j) / I with u_j = kp (r - theta_j) held on [t_j, t_j + h): the generated RK4
    between the samples converges to the matrix-exponential solution (error ~ dt^4)."""
    kp, r, h, theta0 = 12.0, 0.2, 0.02, 0.1
    pid = load_controllers().PID("h.angle", "h.torque", kp=kp, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=h, reference=r)
    exact = sampled_p_loop(STIFFNESS, INERTIA, kp, r, h, theta0, 50)
    errors = []
    for dt in (h / 2, h / 4):
        run = ctmm.simulate(torsion(), 1.0, dt, x0=[theta0], controllers=[pid], compiled=True)
        assert run.scheme_name == "rk4-generated" and run.info["intervals"] == 50
        errors.append(np.max(np.abs(run["b.theta"][::round(h / dt)] - exact)))
    assert errors[0] < 1e-6
    assert errors[1] < errors[0] / 12.0            # fourth order: 16x per halving


def test_planar_pid_fmu_and_loops_equal_the_numpy_path(pd_fmu):
    """A PID (every 3 steps), the PD FMU reading 2 steps late (every 2 steps), a real-time and a delayed
    Feedback loop inside the generated step and a harmonic input, stored every 4th step: equal to the numpy
    path to round-off."""
    controllers = load_controllers()
    pid = controllers.PID("b.theta", "h1.torque", kp=2.0, ki=1.5, kd=0.2, derivative_filter_time=0.01,
                          sample_time=0.006, reference=0.3)
    fmu = FMUController(pd_fmu, inputs={"y": "c.theta", "ydot": "c.omega"}, outputs={"u": "h3.torque"},
                        parameters={"kp": 1.0, "kd": 0.1, "reference": -0.2}, sample_time=0.004)
    loops = [Feedback("rt", [("a.theta", 3.0), ("a.omega", 0.4)], "o.torque", gain=1.0),
             Feedback("late", "e.theta", "h4.torque", gain=0.5, delay=0.01)]
    model = with_feedback(rigid_tree(), loops)
    arguments = dict(x0=[0.1, -0.2, 0.3, 0.1, 0.2], controllers=[pid, DelayedController(fmu, 0.004)],
                     inputs={"h2.torque": Harmonic(0.2, 3.0)}, outputs=["a.tip.y"], store_every=4)
    generated = ctmm.simulate(model, 0.3, 2e-3, compiled=True, **arguments)
    python = ctmm.simulate(model, 0.3, 2e-3, **arguments)
    assert generated.scheme_name == "rk4-generated" and generated.info["controllers"] == python.info["controllers"]
    tree = rigid_tree()
    assert_same(generated, python, list(tree.coordinates) + [f"{c}_dot" for c in tree.coordinates] + [
        "a.tip.y", "rt.y", "rt.u", "late.y", "late.u"])


def test_flexible_hub_beam_with_two_pids_equals_the_numpy_path():
    """A modal hub-beam: one PID on the hub torque every 2 steps, one on the first modal force reading the tip
    every 5 steps (plain model, no loops): equal to the numpy path to round-off."""
    controllers = load_controllers()
    hub = controllers.PID("hub.theta", "o.torque", kp=5.0, ki=1.0, kd=0.5, derivative_filter_time=0.01,
                          sample_time=2e-3, reference=0.2)
    tip = controllers.PID("tip.com.y", "b.q1.force", kp=2.0, ki=0.0, kd=0.1, derivative_filter_time=0.005,
                          sample_time=5e-3)
    model = hub_beam()
    arguments = dict(controllers=[hub, tip], outputs=["tip.com.y"])
    generated = ctmm.simulate(model, 0.1, 1e-3, compiled=True, **arguments)
    python = ctmm.simulate(model, 0.1, 1e-3, **arguments)
    assert_same(generated, python, list(model.coordinates) + [f"{c}_dot" for c in model.coordinates] + ["tip.com.y"])
    station = dict(controllers=[controllers.PID("link.theta", "arm.s1.force", kp=1.0, ki=0.0, kd=0.0,
                                                derivative_filter_time=0.0, sample_time=1e-3)], outputs=["link.theta"])
    generated = ctmm.simulate(station_beam(), 0.01, 1e-3, compiled=True, **station)    # a beam station load
    python = ctmm.simulate(station_beam(), 0.01, 1e-3, **station)
    assert_same(generated, python, list(station_beam().coordinates) + ["link.theta"])


def test_spatial_pid_and_fmu_with_loops_equal_the_numpy_path(pd_fmu):
    """A spatial arm with a PID on the yaw joint, the PD FMU on the elbow and the real-time loops of
    ``test_spatial_control_time`` (one saturating) in the generated step: equal to the numpy path."""
    from test_spatial_control_time import LOOPS, V0, X0, arm

    controllers = load_controllers()
    pid = controllers.PID("yaw.angle", "yaw.torque", kp=4.0, ki=2.0, kd=0.3, derivative_filter_time=0.02,
                          sample_time=0.01, reference=0.1)
    fmu = FMUController(pd_fmu, inputs={"y": "elbow.angle1", "ydot": "elbow.angle1_rate"},
                        outputs={"u": "elbow.torque1"}, parameters={"kp": 3.0, "kd": 0.2, "reference": 0.0},
                        sample_time=0.005)
    model = arm()
    for plant, names in ((model, []), (with_feedback(model, LOOPS[1:]), ["damp.u", "lift.u", "lift.saturated"])):
        arguments = dict(x0=X0, v0=V0, controllers=[pid, fmu], outputs=["hand.tip.z"], store_every=2)
        generated = ctmm.simulate(plant, 0.2, 5e-3, compiled=True, **arguments)
        python = ctmm.simulate(plant, 0.2, 5e-3, **arguments)
        assert_same(generated, python, list(model.coordinates) + list(model.velocities) + ["hand.tip.z"] + names)


class Failing:
    """A controller (``-5 y`` every 10 ms from ``sensor`` to ``actuator``) that raises at its third sample."""

    sample_time, direct_feedthrough = 0.01, False

    def __init__(self, sensor: str = "h.angle", actuator: str = "h.torque") -> None:
        self.inputs, self.outputs = (sensor,), (actuator,)

    def init(self, t0: float) -> int:
        return 0

    def step(self, t: float, y: np.ndarray, state: int) -> tuple:
        if state == 2:
            raise RuntimeError("controller broke")
        return np.array([-5.0 * y[0]]), state + 1


def test_failing_controller_and_refusals_carry_what_the_numpy_path_does():
    model = torsion()
    with pytest.raises(SimulationError, match="controller broke") as generated:
        ctmm.simulate(model, 0.1, 5e-3, x0=[0.1], controllers=[Failing()], compiled=True)
    with pytest.raises(SimulationError, match="controller broke") as python:
        ctmm.simulate(model, 0.1, 5e-3, x0=[0.1], controllers=[Failing()])
    assert generated.value.time == pytest.approx(0.02)
    np.testing.assert_array_equal(generated.value.partial_result.time, python.value.partial_result.time)
    np.testing.assert_allclose(generated.value.partial_result["b.theta"], python.value.partial_result["b.theta"],
                               rtol=0, atol=1e-14)
    pid = load_controllers().PID("h.angle", "h.torque", kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=0.01)
    with pytest.raises(ModelError, match="not a whole multiple of dt"):
        ctmm.simulate(model, 0.1, 5e-3, controllers=[DelayedController(pid, 0.007)], compiled=True)
    with pytest.raises(ModelError, match="compiled=True runs the generated RK4"):
        ctmm.simulate(model, 0.1, 5e-3, controllers=[pid], compiled=True, method="RK45")
    wild = load_controllers().PID("h.angle", "h.torque", kp=-1e4, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=5e-3)
    with pytest.raises(SimulationError) as diverged:
        ctmm.simulate(model, 1.0, 5e-3, x0=[0.1], controllers=[wild], compiled=True, divergence_bound=10.0,
                      stability_check="ignore")
    assert diverged.value.partial_result is not None and 0 < diverged.value.time < 1.0


def test_planar_divergence_bound_is_the_numpy_paths():
    """The planar guard watches the coordinates from ``x0`` (not the rates), with the default bound
    ``1e6 max(1, .)`` when none is given: the generated path stops exactly where the numpy path stops."""
    idle = load_controllers().PID("h.angle", "h.torque", kp=0.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=5e-3)
    arguments = dict(x0=[0.1], controllers=[idle], divergence_bound=0.5)   # |theta - 0.1| <= 0.2, |omega| ~ 0.9
    generated = ctmm.simulate(torsion(), 0.5, 5e-3, compiled=True, **arguments)
    assert np.max(np.abs(generated["b.theta_dot"])) > 0.5
    np.testing.assert_array_equal(generated.time, ctmm.simulate(torsion(), 0.5, 5e-3, **arguments).time)
    wild = load_controllers().PID("h.angle", "h.torque", kp=-1e4, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=5e-3)
    stops = []
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="beyond the bound 1e\\+06") as diverged:
            ctmm.simulate(torsion(), 3.0, 5e-3, x0=[0.1], controllers=[wild], compiled=compiled,
                          stability_check="ignore")
        stops.append((diverged.value.time, len(diverged.value.partial_result.time)))
    assert stops[0] == stops[1]


def test_rows_of_long_and_one_step_intervals_are_the_numpy_paths():
    """The rows of an interval are checked, stored and handed to the delayed reads as a block: a controller read
    2 steps late every 3 steps and one every step, stored every 4th step of 19 (the last one too), equal to the
    numpy path; a divergence inside a 10-step interval stops both paths at the same step with the same message and
    partial result (the rows before it, every 3rd), the evaluations counted to the step before it."""
    pid = load_controllers().PID("h.angle", "h.torque", kp=6.0, ki=1.0, kd=0.1, derivative_filter_time=0.01,
                                 sample_time=0.015, reference=0.2)
    arguments = dict(x0=[0.1], controllers=[DelayedController(pid, 0.01)], store_every=4)
    generated = ctmm.simulate(torsion(), 0.095, 5e-3, compiled=True, **arguments)
    assert generated.info["intervals"] == 7 and generated.time[-1] == pytest.approx(0.095)
    assert_same(generated, ctmm.simulate(torsion(), 0.095, 5e-3, **arguments), ["b.theta", "b.theta_dot"])
    every_step = load_controllers().PID("h.angle", "h.torque", kp=6.0, ki=1.0, kd=0.1, derivative_filter_time=0.01,
                                        sample_time=5e-3, reference=0.2)
    arguments = dict(x0=[0.1], controllers=[every_step], store_every=4)
    generated = ctmm.simulate(torsion(), 0.095, 5e-3, compiled=True, **arguments)
    assert generated.info["intervals"] == 19
    assert_same(generated, ctmm.simulate(torsion(), 0.095, 5e-3, **arguments), ["b.theta", "b.theta_dot"])
    wild = load_controllers().PID("h.angle", "h.torque", kp=-2e3, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=0.05)
    stops = []
    for compiled in (True, None):
        with pytest.raises(SimulationError) as diverged:
            ctmm.simulate(torsion(), 3.0, 5e-3, x0=[0.1], controllers=[wild], compiled=compiled, store_every=3,
                          divergence_bound=50.0, stability_check="ignore")
        stops.append(diverged.value)
    step = round(stops[0].time / 5e-3)
    assert stops[0].time == stops[1].time and step % 10 not in (0, 1)      # inside an interval
    assert str(stops[0]).split(" at t =")[0] == str(stops[1]).split(" at t =")[0]
    partial, python = stops[0].partial_result, stops[1].partial_result
    np.testing.assert_array_equal(partial.time, python.time)
    np.testing.assert_allclose(partial["b.theta"], python["b.theta"], rtol=0, atol=1e-12 * np.max(np.abs(python["b.theta"])))
    assert partial.info["n_evaluations"] == 4 * (step - 1)
    with pytest.raises(SimulationError, match="controller broke") as failed:     # at its third sample, step 4
        ctmm.simulate(torsion(), 0.1, 5e-3, x0=[0.1], controllers=[Failing()], compiled=True)
    assert failed.value.partial_result.info["n_evaluations"] == 4 * 3
