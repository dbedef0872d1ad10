"""Shortcuts of the spatial linearisation's output rows and equilibrium check (issue 13 item 3).

* ``output_matrix`` steps only the position directions when every sensor asked for reads the configuration
  alone: its rows must equal the rows of the same sensors asked beside a velocity sensor (all ``2 nv``
  directions stepped), and a central difference of the sensors' real values along each tangent direction
  (:meth:`ctmm.spatial.ports.SpatialPorts.values`, no complex step);
* ``operating_point`` evaluates the later time probes only where the time enters the accelerations (driven
  joints, loads, flexible bodies): a driven joint that moves later is still refused.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.spatial.ports import SpatialPorts
from ctmm.spatial_linearization import operating_point, output_matrix, retract
from spatial_linear_helpers import random_spring_tree

CONFIGURATION = ("j0.angle", "b1.angle_x", "b2.rotation_y", "b3.origin.z", "b4.origin.x", "b5.angle_z",
                 "b6.rotation_x")


def test_configuration_sensor_rows_equal_the_full_step_and_a_difference_of_the_values() -> None:
    model = random_spring_tree(np.random.default_rng(1), 7, "revolute")
    point = operating_point(model)
    n = model.n_velocities
    names = list(CONFIGURATION)
    rows = output_matrix(model, names, point)
    full = output_matrix(model, names + ["b3.omega_x"], point)[:len(names)]
    np.testing.assert_array_equal(rows, full)
    np.testing.assert_array_equal(rows[:, n:], 0.0)
    for name in ("j0.rate", "b3.omega_x", "b3.omega_body_y", "b3.origin.vx"):     # velocity sensors: all steps
        assert np.any(output_matrix(model, [name], point)[0, n:] != 0.0), name
    ports = SpatialPorts(model)
    sensors = ports.resolve(names)
    step = 1e-6
    difference = np.zeros((len(names), n))
    for k in range(n):
        delta = np.zeros((2, n))
        delta[0, k], delta[1, k] = step, -step
        q = model.normalized(retract(model, point.q, delta))
        up, down = (ports.values(sensors, q[i], point.qdot, point.t) for i in (0, 1))
        difference[:, k] = (up - down) / (2.0 * step)
    assert np.max(np.abs(rows[:, :n] - difference)) <= 1e-7 * np.max(np.abs(rows))


def test_a_driven_joint_that_moves_later_is_not_an_equilibrium() -> None:
    model = sp.SpatialModel("shaken_base", [
        sp.SpatialBody("base", 1.0, (0.1, 0.1, 0.1), points={"tip": (1.0, 0.0, 0.0)}),
        sp.Revolute(name="drive", parent=None, child="base", axis=(0, 0, 1),
                    position=lambda t: t ** 3, rate=lambda t: 3.0 * t ** 2, acceleration=lambda t: 6.0 * t),
        sp.SpatialBody("arm", 1.0, (0.1, 0.1, 0.1), center_of_mass=(0.5, 0.0, 0.0)),
        sp.Revolute(name="hinge", parent="base", child="arm", point="tip", axis=(0, 0, 1), stiffness=5.0)],
        gravity=(0, 0, 0))
    q, v = model.neutral(), np.zeros(model.n_velocities)
    assert np.max(np.abs(sp.accelerations(model, q, v, 0.0))) == 0.0       # at rest at t = 0, moving later
    with pytest.raises(ModelError, match="not an equilibrium"):
        operating_point(model, (q, v))
    assert operating_point(model, (q, v), allow_nonequilibrium=True).equilibrium is False
