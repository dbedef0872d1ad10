"""The one statement of the spatial sensor maps (ctmm.spatial.sensor_maps): exact Jacobians by complex step
against the independent reference kinematics, beam station sensors in the rows of ``C``, and the rotation
maps against scipy's.

Tolerances: Jacobians of O(1) kinematics 1e-12 absolute (exact to round-off; the former 4th-order
difference reached 1e-8); rotation maps 1e-12.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.reference.beams import beta_roots, clamped_free_mode
from ctmm.reference.spatial_kinematics import kinematics, point_jacobian
from ctmm.spatial import ports
from ctmm.spatial.sensor_maps import rotation_vector, xyz_angles
from tests.spatial_control_helpers import q_to_reference, quaternion_joint_state, random_model, to_reference
from tests.test_spatial_beam_ports import _model as beam_model


@pytest.mark.parametrize("free_base", [False, True])
def test_sensor_jacobians_are_exact(free_base: bool) -> None:
    rng = np.random.default_rng(11)
    model = random_model(rng, free_base=free_base)
    q, v = quaternion_joint_state(rng, model, scale=0.6)
    kin = kinematics(to_reference(model), q_to_reference(model, q), v)
    for j, body in enumerate(model.bodies):
        point = next(iter(body.points))
        names = [f"{body.name}.{point}.{a}" for a in "xyz"] + [f"{body.name}.omega_{a}" for a in "xyz"]
        dy_dx, dy_dv = ports.sensor_jacobians(model, names, q, v)
        position = kin.origin[j] + kin.rotation[j] @ np.asarray(body.points[point], float)
        np.testing.assert_allclose(dy_dx[:3], point_jacobian(kin, j, position), rtol=0, atol=1e-12)
        np.testing.assert_allclose(dy_dv[3:], kin.jacobian_angular[j], rtol=0, atol=1e-12)
        assert not np.any(dy_dv[:3])


def test_sensor_jacobians_refuse_gimbal_lock() -> None:
    model = sp.SpatialModel("lock", [sp.SpatialBody("b", 1.0, (1, 1, 1)),
                                     sp.Revolute(name="r", parent=None, child="b", axis=(0, 1, 0))])
    with pytest.raises(ModelError, match=r"sensor_jacobians: sensor 'b\.angle_x' is at gimbal lock"):
        ports.sensor_jacobians(model, ["b.angle_x"], [math.pi / 2], [0.0])
    np.testing.assert_allclose(ports.sensor_values(model, ["b.angle_y"], [math.pi / 2], [0.0]), [math.pi / 2],
                               rtol=0, atol=1e-15)          # the value itself is defined


def test_linearize_reads_beam_station_sensors() -> None:
    """Rows of ``C`` of station and deformed-point sensors are the mode shapes at the station (before the
    one sensor map, the complex-step rows of linearize did not know beam sensors)."""
    model = beam_model()
    lin = ctmm.linearize(model, outputs=["b.p2.w_y", "b.tip.y", "b.tip.vy"], allow_nonequilibrium=True)
    C = np.asarray(lin.state_space.C)
    L = 1.2
    shapes = [clamped_free_mode(b, 0.4 / L) for b in beta_roots("clamped-free", 2)]
    tips = [clamped_free_mode(b, 1.0) for b in beta_roots("clamped-free", 2)]
    n = model.n_velocities
    np.testing.assert_allclose(C[0, 1:3], shapes, rtol=0, atol=1e-12)
    np.testing.assert_allclose(C[1, 1:3], tips, rtol=0, atol=1e-12)
    np.testing.assert_allclose(C[2, n + 1:n + 3], tips, rtol=0, atol=1e-12)
    assert C[1, 0] == pytest.approx(0.1 + L, abs=1e-12)     # the hub arm plus the beam, turned by the hinge


def test_rotation_maps_equal_scipy() -> None:
    rng = np.random.default_rng(3)
    rotations = Rotation.from_rotvec(np.vstack([
        rng.normal(size=(20, 3)), 1e-6 * rng.normal(size=(5, 3)), np.zeros((1, 3)),
        (math.pi - 1e-9) * np.array([[0.0, 0.6, 0.8], [1.0, 0.0, 0.0]])]))
    matrices = rotations.as_matrix()
    np.testing.assert_allclose(rotation_vector(matrices), rotations.as_rotvec(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rotation_vector(matrices[0]), rotations.as_rotvec()[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(xyz_angles(matrices), rotations.as_euler("XYZ"), rtol=0, atol=1e-12)
