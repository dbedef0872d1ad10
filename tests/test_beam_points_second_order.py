"""Points of a second-order beam (children, point loads) move with the shortening (``ctmm.flexible.point_terms``,
``ctmm.spatial.beam_terms``; ``docs/flexible.md`` §1.3.1, ``docs/spatial_modal_beam.md`` §2c).

Independent reference: :mod:`ctmm.reference.spatial_beam_lagrange` (assumed modes, Gauss mass points, equations from
the exact ``T + V`` by automatic differentiation; no ctmm.flexible or ctmm.spatial code), whose tip body (at the tip or
a station) and body-axis force points sit at ``[x + u(x), w_y(x), w_z(x)]`` with ``second_order_inertia=True``.  Its
planar restriction (one bending plane, hinge axis z) is compared with ``ModalBeam``; the spatial model with a tip body
is compared in ``tests/test_spatial_beam_second_order.py``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.compiled_parameters import parameter_vector
from ctmm.compiled_scene import symbolic_plant_accelerations
from ctmm.flexible import ModalBeam
from ctmm.flexible.kernel import solve_flexible
from ctmm.planar import Pinned, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting, Load
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial.beam import SpatialBeam
from ctmm.spatial.dynamics import accelerations, energy
from ctmm.spatial.elements import Revolute, SpatialBody, Spherical, Universal, Weld
from ctmm.spatial.model import SpatialModel
from ctmm.spatial.ports import SpatialPorts
from test_spatial_beam_second_order import BEAM as SPATIAL_BEAM
from test_spatial_beam_second_order import GRAVITY as SPATIAL_GRAVITY
from test_spatial_beam_second_order import HUB_INERTIA, MOUNT as SPATIAL_MOUNT, Q as SPATIAL_Q, TIP_INERTIA
from test_spatial_beam_second_order import U as SPATIAL_U

LENGTH, EI, RHO_A, MOUNT, GRAVITY = 1.3, 5.0, 0.7, 0.3, (0.5, -9.81)
POINTS = 16                                    # Gauss points of both models


def _rotation_z(angle: float) -> np.ndarray:
    return np.array([[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])


def planar_arm(second_order: bool, station: float | None = None, loads: tuple = ()) -> PlanarModel:
    """Hub on a pin, the beam welded at 0.3 rad, a rigid body welded at the tip or at ``station``."""
    outboard = {"out": LENGTH} if station is None else {"out": LENGTH, "mid": station}
    beam = ModalBeam("b", length=LENGTH, bending_stiffness=EI, mass_per_length=RHO_A, n_modes=3, quadrature=POINTS,
                     second_order_inertia=second_order, outboard=outboard, loads=loads)
    return PlanarModel("arm", [
        Pinned("o", child="hub"),
        RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", parent="hub", child="b", angle=MOUNT), beam,
        FixedMounting("weld", parent="b.out" if station is None else "b.mid", child="tip"),
        RigidBody("tip", mass=0.4, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))],
        gravity=GRAVITY)


def lagrange_arm(second_order: bool, station: float | None = None, actuators: tuple = ()) -> SpatialBeamLagrange:
    return SpatialBeamLagrange(HubBeam(
        length=LENGTH, mass_per_length=RHO_A, bending_stiffness_y=EI, bending_stiffness_z=EI, n_modes_y=3, n_modes_z=0,
        hub_mass=2.0, hub_inertia=np.diag([0.05, 0.06, 0.1]), hub_center=(0.05, 0.02, 0.0), axes=((0, 0, 1),),
        mount=(0.2, 0.0, 0.0), mount_rotation=_rotation_z(MOUNT), tip_mass=0.4,
        tip_inertia=np.diag([0.006, 0.005, 0.01]), tip_center=(0.03, 0.01, 0.0), gravity=(*GRAVITY, 0.0),
        points=POINTS, second_order_inertia=second_order, tip_station=station, actuators=actuators))


# bent, spinning, vibrating: [hub angle, q1, q2, q3] and rates
Q = np.array([0.4, 0.05, -0.02, 0.01])
V = np.array([5.0, 0.8, -0.5, 0.3])


@pytest.mark.parametrize("station", [None, 0.7])
@pytest.mark.parametrize("second_order", [True, False])
def test_a_child_at_a_beam_point_equals_the_lagrange_model(second_order, station):
    """Tip body at the tip or at a station: the accelerations equal the Lagrange model's to 1e-10 of their size
    (measured 6e-16 ... 6e-14) and so does the energy, for both forms; the two forms differ by more than 1 %.  The
    second-order beam with its child at the first-order point (before this change) was 0.11 (tip) and 5.3e-3
    (station) off."""
    model = planar_arm(second_order, station)
    reference = lagrange_arm(second_order, station)
    expected = reference.accelerations(Q, V)
    got = solve_flexible(model, Q, V, 0.0).qddot
    assert np.max(np.abs(got - expected)) < 1e-10 * np.max(np.abs(expected))
    assert model.energy(Q, V) == pytest.approx(reference.energy(Q, V), rel=1e-12)
    other = lagrange_arm(not second_order, station).accelerations(Q, V)
    assert np.max(np.abs(other - expected)) > 1e-2 * np.max(np.abs(expected))


def test_a_point_load_moves_with_the_shortening():
    """A force at a station (global axes in the library, frame axes in the reference: the same vector at this state)
    on the second-order beam: its moment about the root uses the shortened lever arm, its modal force the virtual
    work through ``Phi - e1 q^T G1`` -- equal to the reference's virtual power at the moved point."""
    f_frame = np.array([3.0, -2.0])
    angle = Q[0] + MOUNT
    c, s = math.cos(angle), math.sin(angle)
    f_global = (c * f_frame[0] - s * f_frame[1], s * f_frame[0] + c * f_frame[1])
    model = planar_arm(True, loads=(Load(point=(0.9, 0.0), force_x=f_global[0], force_y=f_global[1]),))
    reference = lagrange_arm(True, actuators=((0.9, "force", 0), (0.9, "force", 1)))
    expected = reference.accelerations(Q, V, actuation=f_frame)
    got = solve_flexible(model, Q, V, 0.0).qddot
    assert np.max(np.abs(got - expected)) < 1e-10 * np.max(np.abs(expected))
    unloaded = reference.accelerations(Q, V)
    assert np.max(np.abs(unloaded - expected)) > 1e-2 * np.max(np.abs(expected))


@pytest.mark.parametrize("station", [None, 0.7])
def test_energy_with_a_child_is_conserved(station):
    """Undamped hub + second-order beam + rigid child at the tip or a station, swinging in gravity and bending: a
    short RK4 run conserves ``T + V`` (children at their shortened positions) to the integrator's error; the
    first-order stiffened beam drifts by the work of its non-conservative stiffening.  Measured 9e-15 / 4e-15 (first
    order 4.7e-4 / 3.5e-4; the second-order beam with its child at the first-order point: 2.5e-4 / 8.2e-5)."""
    drift = {}
    for second_order in (True, False):
        model = planar_arm(second_order, station)
        run = ctmm.simulate(model, 0.03, 2e-4, x0=[0.4, 0.03, 0.0, 0.0], v0=[6.0, 0.0, 0.0, 0.0])
        q = np.column_stack([run[n] for n in model.coordinates])
        v = np.column_stack([run[f"{n}_dot"] for n in model.coordinates])
        energy = np.array([model.energy(a, b) for a, b in zip(q, v)])
        assert np.ptp(run["b.q1"]) > 5e-3                                            # it bends
        drift[second_order] = np.ptp(energy) / np.max(np.abs(energy))
    assert drift[True] < 1e-9 and drift[False] > 1e3 * drift[True]


def test_spatial_child_on_a_spherical_joint_at_a_station_conserves_energy():
    """The case that showed the missing point terms (energy drift 3e-4 in 0.05 s before): a body hanging from a
    spherical joint at a station of a second-order spatial beam on a spinning hub.  Undamped RK4: the energy stays
    to 1e-9 (measured 7e-13 over 0.05 s); the first-order stiffened beam drifts (2.6e-3)."""
    drift = {}
    for second_order in (True, False):
        model = SpatialModel("station_child", [
            SpatialBody("hub", mass=2.0, inertia=np.diag([0.12, 0.1, 0.15]), center_of_mass=(0.03, 0.01, 0.02),
                        points={"out": (0.2, 0.0, 0.05)}),
            Revolute(name="hub_joint", parent=None, child="hub", axis=(0, 0, 1)),
            SpatialBeam("b", length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
                        n_modes_y=2, n_modes_z=2, second_order_inertia=second_order, stations={"s": 0.6}),
            Weld(name="mount", parent="hub", child="b", point="out"),
            SpatialBody("p", mass=0.5, inertia=np.diag([0.004, 0.005, 0.006]), center_of_mass=(0.0, 0.0, -0.2)),
            Spherical(name="ball", parent="b", child="p", point="s")], gravity=(0.0, 0.0, -9.81))
        x0 = dict(zip(model.coordinates, np.zeros(len(model.coordinates))))
        x0.update({"ball.qw": 1.0, "b.qy1": 0.04, "b.qz1": -0.03})
        v0 = np.zeros(len(model.velocities))
        v0[0] = 6.0
        run = ctmm.simulate(model, 0.03, 5e-4, method="rk4", x0=list(x0.values()), v0=v0)
        n = len(model.coordinates)
        states = np.stack([run[name] for name in model.coordinates + model.velocities], axis=1)
        values = energy(model, states[:, :n], states[:, n:])
        drift[second_order] = np.ptp(values) / np.max(np.abs(values))
    assert drift[True] < 1e-9 and drift[False] > 1e-5


def test_generated_kernel_moves_the_child_too():
    """The generated (casadi) path runs the same point statements on symbols: equal to the numpy sweep with a station
    child on the second-order beam."""
    model = planar_arm(True, 0.7)
    function = symbolic_plant_accelerations(model)
    symbolic = np.asarray(function(Q, V, parameter_vector(model), 0.0)).reshape(-1)
    numeric = solve_flexible(model, Q, V, 0.0).qddot
    assert np.max(np.abs(symbolic - numeric)) < 1e-10 * np.max(np.abs(numeric))


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_spatial_body_axis_force_at_a_station_moves_with_the_shortening(axis):
    """A body-axis force at a station of a second-order spatial beam (universal hub, both planes, twist, tip body):
    equal to the reference's virtual power at the shortened point to 1e-10 (its axial component's ``-f_1 G1 eta``
    included), for each axis."""
    axes = ((0, 0, 1), (0, 1, 0))
    model = SpatialModel("s", [
        SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                    points={"out": (0.2, 0, 0.05)}),
        Universal(name="hubj", parent=None, child="hub", axis1=axes[0], axis2=axes[1]),
        SpatialBeam("b", **SPATIAL_BEAM, second_order_inertia=True, quadrature=12, stations={"p": 0.6}),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=SPATIAL_MOUNT),
        SpatialBody("tip", mass=0.3, inertia=TIP_INERTIA, center_of_mass=(0.03, 0.02, -0.01)),
        Weld(name="m2", parent="b", child="tip", point="tip")], gravity=SPATIAL_GRAVITY)
    reference = SpatialBeamLagrange(HubBeam(
        **SPATIAL_BEAM, hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02), axes=axes,
        mount=(0.2, 0.0, 0.05), mount_rotation=SPATIAL_MOUNT, tip_mass=0.3, tip_inertia=TIP_INERTIA,
        tip_center=(0.03, 0.02, -0.01), gravity=SPATIAL_GRAVITY, points=12, second_order_inertia=True,
        actuators=((0.6, "force", axis),)))
    inputs = SpatialPorts(model).inputs({f"b.p.force_body_{'xyz'[axis]}": 20.0})
    got = accelerations(model, SPATIAL_Q, SPATIAL_U, 0.0, inputs.joint, inputs.wrenches)
    expected = reference.accelerations(SPATIAL_Q, SPATIAL_U, actuation=np.array([20.0]))
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()
    free = reference.accelerations(SPATIAL_Q, SPATIAL_U)
    assert np.abs(free - expected).max() > 1e-4 * np.abs(expected).max()                  # it acts


def test_spatial_point_sensors_sit_where_the_children_are():
    """The spatial beam's point sensors (``"b.tip.x"``, ``"b.tip.vx"`` ...: ``deformed_point``) use the shortened point:
    equal to the centre of a body welded at the tip with its centre there (computed by the sweep's point
    kinematics, another path) to 1e-12, on a bent, spinning second-order beam; the first-order beam's sensor is
    ``|u(L)|`` away."""
    from ctmm.spatial.ports import sensor_values

    def arm(second_order: bool) -> SpatialModel:
        return SpatialModel("s", [
            SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                        points={"out": (0.2, 0, 0.05)}),
            Universal(name="hubj", parent=None, child="hub", axis1=(0, 0, 1), axis2=(0, 1, 0)),
            SpatialBeam("b", **SPATIAL_BEAM, second_order_inertia=second_order, quadrature=12),
            Weld(name="mount", parent="hub", child="b", point="out", rotation=SPATIAL_MOUNT),
            SpatialBody("tip", mass=0.3, inertia=TIP_INERTIA),
            Weld(name="m2", parent="b", child="tip", point="tip")], gravity=SPATIAL_GRAVITY)

    model = arm(True)
    names = [f"{body}.{point}.{part}{axis}" for part in ("", "v") for axis in "xyz"
             for body, point in (("b", "tip"), ("tip", "com"))]
    values = sensor_values(model, names, SPATIAL_Q, SPATIAL_U).reshape(2, 3, 2)      # (position | rate, axis, body)
    np.testing.assert_allclose(values[..., 0], values[..., 1], rtol=0, atol=1e-12 * np.abs(values).max())
    moved = values[0, :, 0] - sensor_values(arm(False), names[0:6:2], SPATIAL_Q, SPATIAL_U)
    eta = SPATIAL_Q[2:]
    beam = SpatialBeam("b", **SPATIAL_BEAM, second_order_inertia=True, quadrature=12)
    u = -0.5 * eta @ beam.data.station(SPATIAL_BEAM["length"])[2] @ eta
    assert np.linalg.norm(moved) == pytest.approx(abs(u), rel=1e-10) and abs(u) > 1e-4     # along the frame axis


def test_a_station_force_port_is_refused_on_a_second_order_beam():
    """The planar station force port applies a constant moment arm ``x`` (a state-independent input row); on a
    second-order beam the arm is ``x + u(x)``: refused by name (station moments and ``Load`` remain)."""
    from ctmm.errors import ModelError
    from ctmm.planar import ports

    beam = ModalBeam("b", length=LENGTH, bending_stiffness=EI, mass_per_length=RHO_A, n_modes=3,
                     second_order_inertia=True, stations={"s": 0.7})
    model = PlanarModel("arm", [Pinned("o", child="b"), beam], gravity=GRAVITY)
    with pytest.raises(ModelError, match="second_order_inertia = False"):
        ports.actuator_inputs(model, {"b.s.force": 1.0})
    assert "b.s.moment" in ports.actuator_names(model)
