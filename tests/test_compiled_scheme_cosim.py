"""Co-simulated controllers around the generated DT-TMM schemes of planar models (:mod:`ctmm.compiled_scheme_cosim`).

The same run on the Python path (:func:`ctmm.control.planar_time.simulate_closed_loop` through the implicit stepper
and its ``after_step`` hook) is the reference: the same sample instants, held outputs, restarts, records and
partial results; equal to the Newton tolerance for every scheme.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError

import ctmm.spatial as sp
from _controllers_import import load_controllers
from test_compiled_cosim import Failing
from test_compiled_scene_schemes import DP_START, double_pendulum

SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler")


def pid(sensor: str, actuator: str, sample_time: float, **gains: float):
    values = {"kp": 1.0, "ki": 0.0, "kd": 0.0, "derivative_filter_time": 0.0, **gains}
    return load_controllers().PID(sensor, actuator, sample_time=sample_time, **values)


def controllers():
    """A PID on the base hinge every 3 steps and a rate feedback on the elbow every 2 steps."""
    return [pid("a.theta", "o.torque", 0.03, kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01, reference=0.3),
            pid("b.omega", "h.torque", 0.02, kp=1.5)]


@pytest.fixture(scope="module")
def pendulum():
    model = double_pendulum()
    return model, dict(zip(model.coordinates, DP_START[0])), dict(zip(model.coordinates, DP_START[1]))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_sampled_controllers_equal_the_python_path(pendulum, scheme):
    model, x0, v0 = pendulum
    arguments = dict(method=scheme, x0=x0, v0=v0, outputs=["a.out.x"], store_every=2)
    generated = ctmm.simulate(model, 0.3, 0.01, compiled=True, controllers=controllers(), **arguments)
    python = ctmm.simulate(model, 0.3, 0.01, controllers=controllers(), **arguments)
    assert generated.scheme_name.startswith("dt-tmm-generated/") and generated.info["intervals"] == 20
    assert generated.info["controllers"] == python.info["controllers"]
    assert np.array_equal(generated.time, python.time) and generated.signals() == python.signals()
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name


@pytest.mark.parametrize("with_controllers", [False, True])
def test_numeric_inputs_are_held_with_or_without_controllers(pendulum, with_controllers):
    model, x0, v0 = pendulum
    arguments = dict(method="houbolt", x0=x0, v0=v0, inputs={"h.torque": 0.4, "o.torque": -0.2}, outputs=["a.out.y"])
    chosen = controllers if with_controllers else list
    generated = ctmm.simulate(model, 0.3, 0.01, compiled=True, controllers=chosen(), **arguments)
    python = ctmm.simulate(model, 0.3, 0.01, controllers=chosen(), **arguments)
    assert generated.info["intervals"] == (20 if with_controllers else 1)
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name


def spatial_double_pendulum() -> sp.SpatialModel:
    """An actuated revolute link carrying a link on an actuated ball joint."""
    return sp.SpatialModel("double", [
        sp.SpatialBody("upper", 1.0, (0.02, 0.03, 0.015), center_of_mass=(0, 0, -0.25), points={"tip": (0, 0, -0.5)}),
        sp.SpatialBody("lower", 0.7, (0.01, 0.012, 0.006), center_of_mass=(0.1, 0, -0.2)),
        sp.Revolute(name="hinge", parent=None, child="upper", axis=(1, 0, 0), actuated=True),
        sp.Spherical(name="ball", parent="upper", point="tip", child="lower", actuated=True)], gravity=(0, 0, -9.81))


@pytest.mark.parametrize("scheme", ["newmark", "houbolt"])
def test_sampled_controllers_on_a_spatial_model_equal_the_python_path(scheme):
    model = spatial_double_pendulum()
    arguments = dict(method=scheme, x0={"hinge.angle": 0.4}, v0={"hinge.angle_rate": 1.5, "ball.wy": -2.0},
                     store_every=2)
    make = lambda: [pid("hinge.angle", "hinge.torque", 0.03, kp=20.0, kd=2.0, reference=0.3)]  # noqa: E731
    generated = ctmm.simulate(model, 0.2, 0.01, compiled=True, controllers=make(), **arguments)
    python = ctmm.simulate(model, 0.2, 0.01, controllers=make(), **arguments)
    assert generated.info["controllers"] == python.info["controllers"] and generated.signals() == python.signals()
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name
    component = lambda: [pid("ball.wx", "ball.torque_x", 0.02, kp=0.5)]  # noqa: E731 -- a port actuator: the
    generated = ctmm.simulate(model, 0.2, 0.01, compiled=True, controllers=component(), **arguments)  # loops' step
    python = ctmm.simulate(model, 0.2, 0.01, controllers=component(), **arguments)
    assert np.ptp(python["ball.torque_x@samples"][:, 1]) > 0.1
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name


def test_a_failing_controller_stops_both_paths_with_the_same_partial_result(pendulum):
    model, x0, v0 = pendulum
    errors = []
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="controller broke") as info:
            ctmm.simulate(model, 0.1, 5e-3, method="newmark", x0=x0, v0=v0, compiled=compiled,
                          controllers=[Failing("a.theta", "o.torque")])
        errors.append(info.value)
    assert errors[0].time == errors[1].time
    np.testing.assert_allclose(errors[0].partial_result["a.theta"], errors[1].partial_result["a.theta"], rtol=0,
                               atol=1e-12)



class FailingAtOnce(Failing):
    """Raises in ``init`` (``where="init"``) or at its first sample, ``t = 0``."""

    def __init__(self, where: str) -> None:
        super().__init__("a.theta", "o.torque")
        self.where = where

    def init(self, t0: float) -> int:
        if self.where == "init":
            raise RuntimeError("controller broke")
        return 2                        # Failing raises at the sample with state 2


@pytest.mark.parametrize("where", ["init", "first sample"])
@pytest.mark.parametrize("looped", [False, True])
def test_a_controller_failing_before_the_first_step_gives_an_empty_partial_result(pendulum, where, looped):
    """docs/control.md §4a: a controller that fails in init or at t = 0 stops the run with a SimulationError at
    t = 0 and an empty partial result (the generated scheme raised ValueError / NameError building it)."""
    from ctmm.control import Feedback, with_feedback

    model, x0, v0 = pendulum
    system = with_feedback(model, [Feedback("pd", [("b.theta", 3.0)], "h.torque", gain=1.0)]) if looped else model
    for compiled in (True, False):
        with pytest.raises(SimulationError, match="controller broke") as info:
            ctmm.simulate(system, 0.1, 5e-3, method="newmark", x0=x0, v0=v0, compiled=compiled,
                          controllers=[FailingAtOnce(where)])
        assert info.value.time == 0.0
        partial = info.value.partial_result
        assert len(partial.time) == 0 and len(partial["a.theta"]) == 0


def test_what_the_generated_scheme_does_not_close_is_refused(pendulum):
    model, x0, v0 = pendulum
    with pytest.raises(ModelError, match="Python callable of time"):   # signals run on the step with loops
        ctmm.simulate(model, 0.1, 0.01, method="newmark", compiled=True, controllers=controllers(),
                      inputs={"h.torque": lambda t: 0.1 * t})
    with pytest.raises(ModelError, match="open-loop inputs as finite numbers"):
        ctmm.simulate(model, 0.1, 0.01, method="newmark", compiled=True, controllers=controllers(),
                      inputs={"h.torque": float("nan")})
    with pytest.raises(ModelError, match="measurement delay"):
        ctmm.simulate(model, 0.1, 0.01, method="newmark", compiled=True,
                      controllers=[DelayedController(pid("a.theta", "o.torque", 0.02), 0.02)])
    with pytest.raises(ModelError, match="dt is required"):
        ctmm.simulate(model, 0.1, None, method="newmark", compiled=True, controllers=controllers())


@pytest.mark.parametrize("spatial", [False, True])
def test_a_divergence_inside_an_interval_stops_both_paths_at_the_same_row(pendulum, spatial):
    """Rows screened as a block (``DivergenceGuard.passes``): a bound crossed inside a 10-step interval stops the
    generated path where the Python path stops, with its message and the rows stored before (every 2nd)."""
    if spatial:                 # the lower link spins up about x on its ball joint: 'ball.wx' leaves the bound
        model, dt, bound, watched = spatial_double_pendulum(), 0.002, 8.0, "hinge.angle"
        start = dict(x0={"hinge.angle": 0.4}, v0={"hinge.angle_rate": 1.5})
    else:                       # the PID drives the base far from the start: 'b.theta' leaves the bound
        (model, x0, v0), dt, bound, watched = pendulum, 0.01, 0.6, "a.theta"
        start = dict(x0=x0, v0=v0)
    sensor, actuator = ("hinge.angle", "hinge.torque") if spatial else ("a.theta", "o.torque")
    errors = []
    for compiled in (True, None):
        with pytest.raises(SimulationError) as info:
            ctmm.simulate(model, 1.0, dt, method="newmark", compiled=compiled, store_every=2, divergence_bound=bound,
                          controllers=[pid(sensor, actuator, 10 * dt, kp=50.0, reference=2.0)], **start)
        errors.append(info.value)
    step = round(errors[0].time / dt)
    assert errors[0].time == errors[1].time and step % 10 not in (0, 1)
    assert str(errors[0]).split(" at t =")[0] == str(errors[1]).split(" at t =")[0]
    generated, python = errors[0].partial_result, errors[1].partial_result
    np.testing.assert_array_equal(generated.time, python.time)
    assert len(generated.time) > 1
    np.testing.assert_allclose(generated[watched], python[watched], rtol=0, atol=1e-10)
