"""Bad inputs of the spatial ports, loops and controlled runs are refused clearly.

Same rule as :mod:`test_api_fuzz` (:class:`Case`, :func:`check_refused`: a ``ModelError`` or ``TypeError``
naming the parameter and showing the value, within 5 s), on :class:`ctmm.spatial.ports.SpatialPorts`,
``sensor_values`` / ``sensor_jacobians``, ``with_feedback`` / ``ControlledModel`` on a spatial model and
``ctmm.simulate`` of controlled spatial models (loops, references, outputs, port inputs, controllers,
methods that do not apply).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ctmm
import ctmm.spatial as sp
from ctmm.control import ControlledModel, Feedback, with_feedback
from ctmm.spatial import ports

from test_api_fuzz import BAD, Case, Opaque, check_refused


def model() -> sp.SpatialModel:
    return sp.SpatialModel("top", [
        sp.SpatialBody("body", 1.0, (0.02, 0.02, 0.03), center_of_mass=(0, 0, 0.2), points={"tip": (0, 0, 0.4)}),
        sp.SpatialBody("arm", 0.5, (0.01, 0.01, 0.002), points={"end": (0.3, 0, 0)}),
        sp.Spherical(name="ball", parent=None, child="body", actuated=True),
        sp.Revolute(name="hinge", parent="body", point="tip", child="arm", axis=(0, 1, 0), damping=0.1),
    ])


def pd(delay: float = 0.0) -> Feedback:
    return Feedback("pd", [("body.angle_x", 5.0), ("body.omega_x", 0.5)], "ball.torque_x", gain=1.0, delay=delay)


def controlled() -> ControlledModel:
    return with_feedback(model(), [pd()])


Q0 = [1.0, 0.0, 0.0, 0.0, 0.1]
V0 = [0.0, 0.0, 0.0, 0.0]


class Sampler:
    """A do-nothing controller reading the body's x angle, writing the ball's x torque."""

    inputs, outputs, sample_time, direct_feedthrough = ("body.angle_x",), ("ball.torque_x",), 0.01, False

    def init(self, t0):
        return None

    def step(self, t, y, state):
        return [0.0], state


CASES: list[tuple[Case, list]] = [
    (Case("SpatialPorts", "model", "model", ports.SpatialPorts), [None, 3, "top", Opaque()]),
    (Case("SpatialPorts.inputs", "values", "mapping", lambda v: ports.SpatialPorts(model()).inputs(v)),
     [3, None, [("ball.torque_x", 1.0)], "ball.torque_x"]),
    (Case("SpatialPorts.inputs", "actuator", "mapping values", lambda v: ports.SpatialPorts(model()).inputs(v)),
     [{"nope": 1.0}, {"ball.torque_x": math.nan}, {"ball.torque_x": "1"}, {"ball.torque_x": True},
      {"ball.torque_x": np.array([1.0])}, {1: 1.0}, {"body.angle_x": 1.0}, {"hinge.torque": 1.0},
      {"ball.torque": [1.0, 0.0, 0.0]}]),
    (Case("sensor_values", "names", "names", lambda v: ports.sensor_values(model(), v, Q0, V0)),
     ["body.angle_x", 3, None, {"body.angle_x": 1}]),
    (Case("sensor_values", "sensor", "unknown names", lambda v: ports.sensor_values(model(), v, Q0, V0)),
     [["nope"], [3], [""], ["ball.torque_x"], ["body.alpha_x"], ["body.tip.ax"], ["body.omega_w"]]),
    (Case("sensor_values", "q", "coordinates", lambda v: ports.sensor_values(model(), ["body.angle_x"], v, V0)),
     [None, 3, [0.0], [math.nan] * 5, "a", [[0.0] * 5, [0.0] * 5], np.zeros(0), [0.0] * 5]),
    (Case("sensor_values", "v", "velocities", lambda v: ports.sensor_values(model(), ["body.angle_x"], Q0, v)),
     [None, [0.0], [math.inf] * 4, "a"]),
    (Case("sensor_values", "t", "time", lambda v: ports.sensor_values(model(), ["body.angle_x"], Q0, V0, v)),
     [math.nan, "a", None, [1.0]]),
    (Case("sensor_jacobians", "step", "positive",
          lambda v: ports.sensor_jacobians(model(), ["body.angle_x"], Q0, V0, step=v)), [0.0, -1.0, math.nan, "a"]),
    (Case("ControlledModel", "loops", "list of Feedback", lambda v: ControlledModel(model(), v)),
     [None, 3, "abc", {"a": 1}, [3], [pd(), 3], Opaque()]),
    (Case("with_feedback", "sensor", "spatial sensor names",
          lambda v: with_feedback(model(), [Feedback("f", v, "ball.torque_x", gain=1.0)])),
     ["nope", "body.theta", "body.alpha_y", "hinge.torque", "ball.angle"]),
    (Case("with_feedback", "actuator", "spatial actuator names",
          lambda v: with_feedback(model(), [Feedback("f", "body.angle_x", v, gain=1.0)])),
     ["nope", "hinge.torque", "ball.torque", "body.angle_x", "arm.end.force_w", "body.com.force_x"]),
    (Case("ctmm.simulate", "method", "spatial loops", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, method=v)),
     [None, 3, "nope", ""]),
    (Case("ctmm.simulate", "dt", "spatial loops", lambda v: ctmm.simulate(controlled(), 0.05, v)),
     [0, -1, math.nan, math.inf, "1", True, [0.1]]),
    (Case("ctmm.simulate", "x0", "spatial mapping", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, x0=v)),
     [{"nope": 1.0}, {"hinge.angle": math.nan}, {"hinge.angle": "a"}, {1: 0.0}, [0.0] * 5, [1.0, 0, 0]]),
    (Case("ctmm.simulate", "output", "spatial names", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, outputs=v)),
     ["body.angle_x", [3], ["nope"], [""], ["ball.torque_x"], ["body.tip.ax"]]),
    (Case("ctmm.simulate", "input", "spatial mapping", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, inputs=v)),
     [3, "ball.torque_x", [("ball.torque_x", 1.0)], {"nope": 1.0}, {"ball.torque_x": math.nan},
      {"ball.torque_x": "a"}, {"body.angle_x": 1.0}, {"hinge.torque": 1.0}]),
    (Case("ctmm.simulate", "reference", "spatial mapping",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, references=v)), [3, {"nope": 1.0}, {"pd": math.nan},
                                                                             {"pd": "a"}]),
    (Case("ctmm.simulate", "controllers", "spatial", lambda v: ctmm.simulate(model(), 0.02, 0.01, controllers=v)),
     [3, [3], "x", [Opaque()]]),
    (Case("ctmm.simulate", "compiled", "spatial", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, compiled=v)),
     [1, "yes"]),
    (Case("ctmm.simulate", "t0", "spatial", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, t0=v)), [1.0, -1.0]),
    (Case("ctmm.simulate", "delay", "shorter than the step",
          lambda v: ctmm.simulate(with_feedback(model(), [pd(v)]), 0.02, 0.01)), [1e-3, 5e-3]),
    (Case("ctmm.simulate", "stability_check", "option",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, stability_check=v)), ["nope", 3]),
]


@pytest.mark.parametrize("case, values", CASES, ids=[f"{c.api}-{c.parameter}-{c.kind}" for c, _ in CASES])
def test_spatial_bad_inputs_are_refused_clearly(case, values):
    for value in values:
        check_refused(case, value)


KIND_CASES: list[Case] = [
    Case("ControlledModel", "loops", "loops", lambda v: ControlledModel(model(), v)),
    Case("ctmm.simulate", "t_final", "positive", lambda v: ctmm.simulate(controlled(), v, 0.01)),
    Case("ctmm.simulate", "dt", "positive", lambda v: ctmm.simulate(controlled(), 0.02, v)),
    Case("ctmm.simulate", "controllers", "controllers", lambda v: ctmm.simulate(model(), 0.02, 0.01, controllers=v)),
    Case("ctmm.simulate", "reference", "mapping", lambda v: ctmm.simulate(controlled(), 0.02, 0.01, references=v)),
]


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_spatial_random_bad_values_are_refused_clearly(data):
    case = data.draw(st.sampled_from(KIND_CASES), label="case")
    check_refused(case, data.draw(BAD[case.kind], label="value"))


def test_a_controller_on_an_unknown_port_names_the_ports():
    class Wrong(Sampler):
        inputs = ("body.theta",)

    with pytest.raises(ctmm.ModelError, match="body.angle_x"):
        ctmm.simulate(model(), 0.02, 0.01, controllers=[Wrong()])
    ok = ctmm.simulate(model(), 0.02, 0.01, controllers=[Sampler()])
    assert ok["ball.torque_x@samples"].shape == (3, 2)
