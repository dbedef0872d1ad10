"""Ports of the spatial beam: station sensors, deformed point sensors and point moments, and a PZT-pair
loop closed through ctmm.control equal to the same law written as a modal damping hook."""
from __future__ import annotations

import math

import numpy as np

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.flexible.beam import ModalForce
from ctmm.reference.beams import beta_roots, clamped_free_mode
from ctmm.spatial import Revolute, SpatialBeam, SpatialBody, SpatialModel, Weld
from ctmm.spatial.ports import SpatialPorts, sensor_jacobians, sensor_values


def _model(modal_forces=(), hinge=True):
    beam = SpatialBeam("b", length=1.2, mass_per_length=0.8, bending_stiffness_y=3.0, bending_stiffness_z=5.0,
                       n_modes_y=2, n_modes_z=3, n_torsion_modes=1, torsional_stiffness=2.0,
                       polar_inertia_per_length=0.004, stations={"p1": 0.1, "p2": 0.4}, modal_forces=modal_forces)
    return SpatialModel("m", [
        SpatialBody("hub", mass=1.5, inertia=np.diag([0.1, 0.1, 0.12]), points={"out": (0.1, 0.0, 0.0)}),
        Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1)) if hinge else
        Weld(name="hinge", parent=None, child="hub"), beam,
        Weld(name="mount", parent="hub", child="b", point="out")], gravity=(0.0, 0.0, -9.81))


def test_station_and_deformed_point_sensors_equal_the_mode_shapes():
    model = _model()
    rng = np.random.default_rng(5)
    q, v = rng.normal(size=7) * 0.2, rng.normal(size=7)
    angle, qy, qz, twist = q[0], q[1:3], q[3:6], q[6]
    L = 1.2
    shapes = [clamped_free_mode(b, 0.4 / L) for b in beta_roots("clamped-free", 3)]
    slopes = [clamped_free_mode(b, 0.4 / L, 1) / L for b in beta_roots("clamped-free", 3)]
    w_y, w_z = np.dot(shapes[:2], qy), np.dot(shapes, qz)
    expected = [w_y, w_z, np.dot(slopes[:2], qy), np.dot(slopes, qz), math.sqrt(2) * math.sin(math.pi * 0.4 / (2 * L)) * twist]
    names = [f"b.p2.{s}" for s in ("w_y", "w_z", "slope_y", "slope_z", "twist")]
    assert np.allclose(sensor_values(model, names, q, v), expected, rtol=0, atol=1e-13)
    c, s = math.cos(angle), math.sin(angle)
    position = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([0.1 + 0.4, w_y, w_z])
    assert np.allclose(sensor_values(model, ["b.p2.x", "b.p2.y", "b.p2.z"], q, v), position, rtol=0, atol=1e-13)
    units = SpatialPorts(model)
    assert units.sensors["b.qy1"].unit == "m" and units.sensors["b.twist1_rate"].unit == "rad/s"
    assert "b.com.x" not in units.sensors


def test_rate_sensors_are_the_time_derivatives_of_the_position_sensors():
    model = _model()
    rng = np.random.default_rng(6)
    q, v = rng.normal(size=7) * 0.2, rng.normal(size=7)
    positions = ["b.tip.x", "b.tip.y", "b.tip.z", "b.p1.w_z", "b.tip.twist", "b.p2.slope_y"]
    rates = ["b.tip.vx", "b.tip.vy", "b.tip.vz", "b.p1.w_z_rate", "b.tip.twist_rate", "b.p2.slope_y_rate"]
    dy_dx, _ = sensor_jacobians(model, positions, q, v)
    assert np.allclose(dy_dx @ v, sensor_values(model, rates, q, v), rtol=1e-8, atol=1e-10)


def test_a_pzt_pair_loop_on_station_moments_equals_the_modal_damping_hook():
    # the hook is the pair's virtual work linearised (theta_y's axis = the section's y axis); the port is exact.
    # They agree to round-off while the section's y axis does not turn: no hub rotation, no y-plane bending
    gain = 0.8
    plain = _model(hinge=False)
    beam = plain.bodies[1]
    weights = np.array(SpatialPorts(plain).sensors["b.tip.w_z_rate"].weights)
    delta = beam.moment_pair(0.1, 0.4, 1.0, axis="y").force(0.0)      # M (theta_y(x2) - theta_y(x1)) per unit M
    hooked = _model((ModalForce(damping=gain * np.outer(delta, weights), label="pzt"),), hinge=False)
    loops = [Feedback("pair2", "b.tip.w_z_rate", "b.p2.moment_y", gain=gain),      # u = -gain y: +M at p2
             Feedback("pair1", "b.tip.w_z_rate", "b.p1.moment_y", gain=-gain)]     # and -M at p1, about y
    x0 = {"b.qz1": 0.02}
    closed = ctmm.simulate(with_feedback(plain, loops), 0.2, 2e-3, method="rk4", x0=x0)
    reference = ctmm.simulate(hooked, 0.2, 2e-3, method="rk4", x0=x0)
    open_loop = ctmm.simulate(plain, 0.2, 2e-3, method="rk4", x0=x0)
    assert np.abs(closed["b.qz1"] - reference["b.qz1"]).max() <= 1e-13
    assert np.abs(open_loop["b.qz1"] - reference["b.qz1"]).max() > 1e-4
    # with the hub free to turn and both planes bending the port's exact moment and the hook differ slightly
    turning = [ctmm.simulate(model, 0.2, 2e-3, method="rk4", x0={"b.qz1": 0.02, "b.qy1": 0.01})["b.qz1"]
               for model in (with_feedback(_model(), loops), _model(hooked.bodies[1].modal_forces))]
    assert 1e-9 < np.abs(turning[0] - turning[1]).max() < 1e-4
