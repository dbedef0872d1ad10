"""Generated kinematics of points outboard of second-order beams and ``ctmm.fem`` subsystems
(:mod:`ctmm.symbolic_beam_points`, used by :class:`ctmm.compiled_planar_sensors.SymbolicKinematics` and
:class:`ctmm.compiled_spatial_loops.SpatialSymbols`).

Before it, a loop sensing a body on the tip of a ``ModalBeam(second_order_inertia=True)`` ran 0.45 N m (loop output)
and 2.3e-3 rad (hub) away from the numpy path in 0.1 s, silently (the generated tip ignored the foreshortening); the
spatial analogue (``SpatialBeam``) 0.36 N; a ``ctmm.fem`` subsystem carrying a body failed with an AttributeError.
Checked here: every point sensor as a casadi expression = the numpy sensor at a bent, spinning state to 1e-12 (and
the foreshortened tip against the integral ``-1/2 int_0^L w'^2 dx`` on a dense Gauss rule, independent of the
beam's ``G1`` matrices), and the generated closed-loop runs = the numpy runs to round-off.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_planar_sensors import SymbolicKinematics, sensor_expression
from ctmm.control import Feedback, with_feedback
from ctmm.fem import BeamElement, FiniteElementModel
from ctmm.planar import Pinned, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.planar.ports import PlanarPorts, sensor_values
from test_beam_points_second_order import LENGTH, MOUNT, Q, V, planar_arm

ca = pytest.importorskip("casadi")


def fe_arm() -> PlanarModel:
    """Hub on a pin, a two-element ctmm.fem subsystem welded to it at 0.3 rad, a rigid body welded at its far node."""
    nodes = {f"n{k}": (k * 0.4, 0.0) for k in range(3)}
    fe = FiniteElementModel("beam", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 30.0, 3000.0, 0.6)
                                            for k in range(2)])
    return PlanarModel("fe_arm", [
        Pinned("o", child="hub"),
        RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        fe.subsystem("b", boundary=("n0", "n2")), FixedMounting("mount", parent="hub", child="b", angle=0.3),
        FixedMounting("weld", parent="b.n2", child="tip"),
        RigidBody("tip", mass=0.4, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))],
        gravity=(0.5, -9.81))


def _state(model: PlanarModel) -> tuple[np.ndarray, np.ndarray]:
    n = model.n_coordinates
    if model.name == "arm":
        return Q, V
    return np.r_[0.4, 0.01 * np.sin(np.arange(1, n))], np.r_[5.0, 0.3 * np.cos(np.arange(1, n))]


@pytest.mark.parametrize("model", [planar_arm(True), planar_arm(False), planar_arm(True, station=0.7), fe_arm()],
                         ids=["second_order", "first_order", "station", "fem"])
def test_every_point_sensor_on_symbols_equals_the_numpy_sensor(model):
    ports = PlanarPorts(model)
    names = [name for name in ports.sensors if not name.endswith((".angle", ".rate"))]
    q, v = ca.SX.sym("q", model.n_coordinates), ca.SX.sym("v", model.n_coordinates)
    kinematics = SymbolicKinematics(model, q, v)
    function = ca.Function("sensors", [q, v], [ca.vertcat(*[sensor_expression(ports, n, kinematics) for n in names])])
    state = _state(model)
    got = np.asarray(function(*state), float).ravel()
    expected = sensor_values(model, names, *state)
    assert len(names) > 20 and np.max(np.abs(got - expected)) <= 1e-12


def test_the_foreshortened_tip_equals_the_shortening_integral():
    """Independent of the beam's ``G1`` matrices: the generated tip ``b.out.x|y`` = hub pin + hub arm + the
    rotated ``(L - 1/2 int_0^L w'(x)^2 dx, w(L))``, the integral on a 60-point Gauss rule."""
    model = planar_arm(True)
    beam = model.beams[model.body_names.index("b")]
    ports = PlanarPorts(model)
    q, v = ca.SX.sym("q", model.n_coordinates), ca.SX.sym("v", model.n_coordinates)
    kinematics = SymbolicKinematics(model, q, v)
    tip = ca.Function("tip", [q], [ca.vertcat(*[sensor_expression(ports, f"b.out.{a}", kinematics) for a in "xy"])])
    nodes, weights = np.polynomial.legendre.leggauss(60)
    x = 0.5 * LENGTH * (nodes + 1.0)
    slope = Q[1:] @ beam.shapes(x, 1)
    local = np.array([LENGTH - 0.25 * LENGTH * np.sum(weights * slope ** 2), Q[1:] @ beam.shapes([LENGTH])[:, 0]])
    angle = Q[0] + MOUNT
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    expected = 0.2 * np.array([np.cos(Q[0]), np.sin(Q[0])]) + rotation @ local
    assert np.max(np.abs(np.asarray(tip(Q), float).ravel() - expected)) <= 1e-12
    assert abs(local[0] - LENGTH) > 1e-4                                 # the shortening matters here


LOOPS = [Feedback("fast", [("tip.out.x", 3.0), ("tip.out.vx", 0.3), ("tip.theta", 2.0), ("tip.com.vy", 1.0)],
                  "o.torque", gain=1.0),
         Feedback("late", [("tip.com.y", 1.0), ("b.com.x", 0.5)], "o.torque", gain=0.5, delay=0.004)]


@pytest.mark.parametrize("plant", [planar_arm(True), fe_arm()], ids=["second_order", "fem"])
def test_generated_loops_on_a_body_outboard_equal_the_numpy_run(plant):
    model = with_feedback(plant, LOOPS)
    generated = ctmm.simulate(model, 0.05, 1e-3, compiled=True)
    python = ctmm.simulate(model, 0.05, 1e-3)
    assert generated.scheme_name == "rk4-generated"
    for name in list(plant.coordinates) + ["fast.u", "late.u"]:
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-12, name
    assert np.ptp(python["fast.u"]) > 1e-2


def test_spatial_loops_on_a_second_order_beam_point_equal_the_numpy_run():
    from test_spatial_beam_second_order import hub_beam

    plant, _ = hub_beam(((0, 0, 1),), True, reference=False)
    model = with_feedback(plant, [Feedback("l1", [("b.tip.x", 3.0), ("b.tip.vy", 0.3), ("tip.angle_z", 1.0)],
                                           "hub.out.force_y", gain=1.0)])
    arguments = dict(x0=[0.4, 0.05, -0.02, 0.06, 0.01, 0.02], v0=[5.0, 0.8, -0.5, 1.1, 0.4, -0.6])
    generated = ctmm.simulate(model, 0.03, 1e-3, compiled=True, **arguments)
    python = ctmm.simulate(model, 0.03, 1e-3, **arguments)
    assert generated.scheme_name == "rk4-generated"
    for name in list(plant.coordinates) + ["l1.u"]:
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-12, name
    assert np.ptp(python["l1.u"]) > 0.1


def _spatial_plants():
    from test_spatial_beam_second_order import Q as SPATIAL_Q, U as SPATIAL_U, hub_beam
    from test_spatial_cut_points import chain

    beam, _ = hub_beam(((0, 0, 1), (0, 1, 0)), True, reference=False)
    frame, _ = chain(child=False)                          # a yaw link carrying a ctmm.fem spatial L-frame
    rng = np.random.default_rng(3)
    q = rng.normal(size=frame.n_positions) * 0.6
    q[2:] *= 0.01
    return [(beam, SPATIAL_Q, SPATIAL_U), (frame, q, rng.normal(size=frame.n_velocities))]


@pytest.mark.parametrize("case", _spatial_plants(), ids=["second_order_beam", "fem_frame"])
def test_spatial_point_sensors_on_symbols_equal_the_numpy_sensors(case):
    """Point sensors of a second-order SpatialBeam (bent in both planes, twisted, universal hub) and of a ctmm.fem
    spatial subsystem's nodes (before: linear in the modes, and an AttributeError) = the numpy sensors to 1e-12."""
    from ctmm.compiled_spatial_loops import SpatialSymbols
    from ctmm.spatial.ports import SpatialPorts
    from ctmm.spatial.ports import sensor_values as spatial_sensor_values

    model, q0, v0 = case
    ports = SpatialPorts(model)
    names = [name for name in ports.sensors if ports.resolve([name])[0].kind in ("point", "point_v")]
    q, v = ca.SX.sym("q", model.n_positions), ca.SX.sym("v", model.n_velocities)
    symbols = SpatialSymbols(model, ports)
    function = ca.Function("sensors", [q, v], [ca.vertcat(*[symbols.sensor(name, q, v) for name in names])])
    got = np.asarray(function(q0, v0), float).ravel()
    assert len(names) > 20 and np.max(np.abs(got - spatial_sensor_values(model, names, q0, v0))) <= 1e-12
