"""Named stations of a modal beam and their ports (ctmm.flexible.stations, ctmm.planar.ports).

Independent checks: station sensors against the closed-form clamped-free mode shapes (written
out here) and against the beam's deformed end point; station actuators against the flexible
Lagrange model (ctmm.reference.flexible_lagrange) carrying the equivalent point load / moment
in global axes; the implicit DT-TMM with station inputs against an adaptive integration of the
explicit accelerations (whose station loads are the Lagrange-checked ones).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ctmm.errors import ModelError, UnknownNameError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, Load, PlanarModel, RigidBody, accelerations, ports
from ctmm.planar.elements import FixedMounting
from ctmm.planar.implicit import simulate_implicit
from ctmm.reference.flexible_lagrange import FlexibleLagrange

LENGTH, EI, RHOA = 1.0, 20.0, 0.5
STATIONS = {"root": 0.0, "a": 0.23, "b": 0.61, "tip": LENGTH}


def beam(**extra) -> ModalBeam:
    options = dict(length=LENGTH, bending_stiffness=EI, mass_per_length=RHOA, n_modes=3, stations=STATIONS)
    options.update(extra)
    return ModalBeam("arm", **options)


def model_with(arm: ModalBeam) -> PlanarModel:
    return PlanarModel.chain("hb", [Fixed("ground"), ActuatedHinge("motor"),
                                    RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
                                    FixedMounting("mount"), arm], gravity=(0.0, -9.81))


def clamped_free_shape(x: float, k: int, derivative: int) -> float:
    """Textbook clamped-free shape ``cosh - cos - sigma (sinh - sin)`` (tip value +-2) or its slope."""
    beta = brentq(lambda b: np.cos(b) * np.cosh(b) + 1.0, (k - 0.5) * np.pi - 0.6, (k - 0.5) * np.pi + 0.6)
    sigma = (np.cosh(beta) + np.cos(beta)) / (np.sinh(beta) + np.sin(beta))
    b = beta / LENGTH
    if derivative == 0:
        return np.cosh(b * x) - np.cos(b * x) - sigma * (np.sinh(b * x) - np.sin(b * x))
    return b * (np.sinh(b * x) + np.sin(b * x) - sigma * (np.cosh(b * x) - np.cos(b * x)))


def test_station_sensors_are_the_mode_shape_sums():
    model = model_with(beam())
    rng = np.random.default_rng(5)
    q, v = rng.normal(size=model.n_coordinates) * 0.02, rng.normal(size=model.n_coordinates) * 0.1
    eta, eta_dot = q[model.modal_index[1]], v[model.modal_index[1]]
    for name, x in STATIONS.items():
        phi = np.array([clamped_free_shape(x, k, 0) for k in (1, 2, 3)])
        dphi = np.array([clamped_free_shape(x, k, 1) for k in (1, 2, 3)])
        values = ports.sensor_values(model, [f"arm.{name}.{p}" for p in ("w", "slope", "w_dot", "slope_rate")], q, v)
        np.testing.assert_allclose(values, [phi @ eta, dphi @ eta, phi @ eta_dot, dphi @ eta_dot],
                                   rtol=1e-9, atol=1e-12)
    # the tip station is the deformed end seen in the beam frame (point kinematics, another path)
    theta = q[model.coordinate_index("hub.theta")]
    rotation = np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])
    end = ports.sensor_values(model, ["arm.out.x", "arm.out.y", "arm.inboard.x", "arm.inboard.y"], q, v)
    local = rotation @ (end[:2] - end[2:])
    assert ports.sensor_values(model, ["arm.tip.w"], q, v)[0] == pytest.approx(local[1], abs=1e-14)
    assert ports.sensor_unit(model, "arm.a.slope_rate") == "rad/s"
    assert ports.actuator_unit(model, "arm.a.moment") == "N m"


def test_station_jacobians_are_the_shape_rows():
    model = model_with(beam())
    q = np.zeros(model.n_coordinates)
    dy_dq, dy_dqdot = ports.sensor_jacobians(model, ["arm.b.w", "arm.b.slope_rate"], q, q)
    index = model.modal_index[1]
    np.testing.assert_allclose(dy_dq[0, index], model.beams[1].shapes([0.61], 0)[:, 0], rtol=1e-13)
    np.testing.assert_allclose(dy_dqdot[1, index], model.beams[1].shapes([0.61], 1)[:, 0], rtol=1e-13)
    assert not dy_dqdot[0].any() and not dy_dq[1].any()


@pytest.mark.parametrize("station", ["a", "b", "tip"])
def test_station_loads_equal_the_lagrange_model_with_the_same_point_load(station):
    model = model_with(beam())
    rng = np.random.default_rng(11)
    q, v = rng.normal(size=model.n_coordinates) * 0.02, rng.normal(size=model.n_coordinates) * 0.1
    q[model.coordinate_index("hub.theta")] = 0.7           # the force turns with the beam frame
    force, moment = 0.8, -0.3
    theta = q[model.coordinate_index("hub.theta")]
    x = STATIONS[station]
    load = Load(point=(x, 0.0), force_x=-np.sin(theta) * force, force_y=np.cos(theta) * force, moment=moment)
    reference = FlexibleLagrange(model_with(beam(loads=(load,)))).accelerations(q, v)
    inputs = ports.actuator_inputs(model, {f"arm.{station}.force": force, f"arm.{station}.moment": moment})
    np.testing.assert_allclose(accelerations(model, q, v, inputs=inputs), reference, rtol=1e-9, atol=1e-9)


def test_a_station_moment_pair_is_the_modal_moment_pair_hook():
    model = model_with(beam())
    q = np.random.default_rng(2).normal(size=model.n_coordinates) * 0.01
    v = np.zeros(model.n_coordinates)
    hook = model.beams[1].moment_pair(0.23, 0.61, 0.4)
    reference = accelerations(model_with(beam().with_modal_forces(hook)), q, v)
    inputs = ports.actuator_inputs(model, {"arm.a.moment": -0.4, "arm.b.moment": 0.4})
    np.testing.assert_allclose(accelerations(model, q, v, inputs=inputs), reference, rtol=1e-12, atol=1e-12)
    assert np.allclose(inputs.frame_wrench[1], 0.0, atol=1e-15)   # self-equilibrated: no frame load


def test_implicit_runs_with_station_inputs_converge_to_the_explicit_accelerations():
    model = model_with(beam())
    n = model.n_coordinates
    held = ports.PlanarPorts(model)

    def inputs(t, q, qdot):
        return held.inputs({"arm.b.force": 2.0 * np.sin(8.0 * t), "arm.a.moment": 0.5, "motor.torque": 0.3})

    q0 = np.zeros(n)
    run = simulate_implicit(model, q0, q0, t_final=0.2, dt=5e-4, scheme="newmark", inputs=inputs)

    def rhs(t, x):
        return np.concatenate([x[n:], accelerations(model, x[:n], x[n:], t, inputs=inputs(t, x[:n], x[n:]))])

    reference = solve_ivp(rhs, (0.0, 0.2), np.zeros(2 * n), method="DOP853", rtol=1e-11, atol=1e-13)
    final = reference.y[:n, -1]
    assert abs(final[0]) > 1e-2                                   # the hub really turned
    np.testing.assert_allclose(run.q[-1], final, rtol=0, atol=2e-5 * np.max(np.abs(final)))


def test_bad_stations_are_refused_with_the_parameter():
    with pytest.raises(ModelError, match=r"stations\['a'\].*must lie on the beam"):
        beam(stations={"a": 1.5})
    with pytest.raises(ModelError, match="station name 'q1' is taken"):
        beam(stations={"q1": 0.5})
    with pytest.raises(ModelError, match="station name 'out' is taken"):
        beam(stations={"out": 0.5})
    with pytest.raises(ModelError, match="stations must be a mapping"):
        beam(stations=[0.5])
    with pytest.raises(ModelError, match="finite"):
        beam(stations={"a": float("nan")})
    axial = model_with(beam(n_axial_modes=1, axial_stiffness=1e5))
    with pytest.raises(ModelError, match="axially rigid"):
        ports.actuator_inputs(axial, {"arm.a.force": 1.0})
    assert "arm.a.moment" in ports.actuator_names(axial)
    with pytest.raises(UnknownNameError, match="arm.a.w"):
        ports.sensor_values(model_with(beam()), ["arm.zz.w"], np.zeros(4), np.zeros(4))
