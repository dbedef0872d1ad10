"""Second-order (foreshortening) inertia of the modal spatial beam (``SpatialBeam(second_order_inertia=True)``,
:mod:`ctmm.spatial.beam_second_order`, ``docs/spatial_modal_beam.md`` §7).

Independent reference: :mod:`ctmm.reference.spatial_beam_lagrange` with ``second_order_inertia=True``, an
assumed-modes Lagrange model written from scratch (mass points on Gauss points moved by their shortening
``-1/2 int_0^x (w_y'^2 + w_z'^2)``, equations from the exact energy by automatic differentiation; no ctmm.spatial
or ctmm.flexible code).  The planar restriction is checked against ``ModalBeam(second_order_inertia=True)``.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.flexible.kernel import solve_flexible
from ctmm.planar import Pinned, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial.beam import SpatialBeam
from ctmm.spatial.dynamics import accelerations, energy
from ctmm.spatial.elements import Revolute, SpatialBody, Universal, Weld
from ctmm.spatial.model import SpatialModel


def rotation(axis, angle):
    a = np.asarray(axis, float)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


HUB_INERTIA = np.array([[0.12, 0.01, 0], [0.01, 0.1, 0.02], [0, 0.02, 0.15]])
TIP_INERTIA = np.array([[0.004, 0.0005, 0], [0.0005, 0.005, 0.0003], [0, 0.0003, 0.006]])
MOUNT = rotation((0, 1, 0), 0.2) @ rotation((1, 0, 0), 0.3)
BEAM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0, n_modes_y=2,
            n_modes_z=2, n_torsion_modes=1, torsional_stiffness=3.0, polar_inertia_per_length=0.002)
GRAVITY = (0.5, 0.2, -9.81)
POINTS = 12                     # Gauss points of both models (the same rule: they agree for any count)


def hub_beam(axes, second_order, tip_mass=0.3, reference=True, load=(0.0, 0.0, 0.0)):
    """Hub on a revolute / universal joint, the beam welded to it at an angle (uniform follower ``load`` [N/m]), a
    tip body; and the Lagrange model."""
    joint = (Revolute(name="hubj", parent=None, child="hub", axis=axes[0]) if len(axes) == 1 else
             Universal(name="hubj", parent=None, child="hub", axis1=axes[0], axis2=axes[1]))
    parts = [SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                         points={"out": (0.2, 0, 0.05)}), joint,
             SpatialBeam("b", **BEAM, second_order_inertia=second_order, quadrature=POINTS, distributed_load=load),
             Weld(name="mount", parent="hub", child="b", point="out", rotation=MOUNT)]
    if tip_mass:
        parts += [SpatialBody("tip", mass=tip_mass, inertia=TIP_INERTIA, center_of_mass=(0.03, 0.02, -0.01)),
                  Weld(name="m2", parent="b", child="tip", point="tip")]
    model = SpatialModel("s", parts, gravity=GRAVITY)
    if not reference:
        return model, None
    lagrange = SpatialBeamLagrange(HubBeam(
        **BEAM, hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02), axes=axes, mount=(0.2, 0.0, 0.05),
        mount_rotation=MOUNT, tip_mass=tip_mass, tip_inertia=TIP_INERTIA, tip_center=(0.03, 0.02, -0.01),
        gravity=GRAVITY, points=POINTS, second_order_inertia=second_order, distributed_load=load))
    return model, lagrange


# bent in both planes and twisted, the hub spinning about both axes, the modes vibrating
Q = np.r_[0.4, -0.3, 0.05, -0.02, 0.06, 0.01, 0.02]
U = np.r_[5.0, -3.0, 0.8, -0.5, 1.1, 0.4, -0.6]


def test_accelerations_at_a_bent_spinning_state_equal_the_lagrange_model():
    """Universal hub (3-D frame motion), both bending planes, twist and a tip body: the accelerations equal the
    Lagrange model's with the shortening in every mass point to 1e-10 of their size (and the energy its exact
    ``T + V``), and differ from the first-order (stiffened) beam's by more than 1 % of it (measured 17 %)."""
    axes = ((0, 0, 1), (0, 1, 0))
    model, lagrange = hub_beam(axes, True)
    expected = lagrange.accelerations(Q, U)
    got = accelerations(model, Q, U)
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()          # measured 9e-14
    assert energy(model, Q, U) == pytest.approx(lagrange.energy(Q, U), rel=1e-12)   # with the shortening's terms
    first_order, _ = hub_beam(axes, False, reference=False)
    assert np.abs(accelerations(first_order, Q, U) - expected).max() > 1e-2 * np.abs(expected).max()


@pytest.mark.parametrize("second_order", [True, False])
def test_a_follower_load_equals_its_virtual_power_in_the_lagrange_model(second_order):
    """A uniform follower load (all three frame components) on the hub beam: the second-order beam's moment of the
    shortened load line and the first-order beam's load stiffening both equal the Lagrange model's (the load's
    virtual power at its mass points), revolute hub."""
    load = (2.5, -1.5, 3.0)
    model, lagrange = hub_beam(((0, 0, 1),), second_order, tip_mass=0.0, load=load)
    q, u = np.r_[Q[0], Q[2:]], np.r_[U[0], U[2:]]
    expected = lagrange.accelerations(q, u)
    assert np.abs(accelerations(model, q, u) - expected).max() <= 1e-10 * np.abs(expected).max()
    unloaded, _ = hub_beam(((0, 0, 1),), second_order, tip_mass=0.0, reference=False)
    assert np.abs(accelerations(unloaded, q, u) - expected).max() > 1e-2 * np.abs(expected).max()


def test_energy_is_conserved_unlike_the_first_order_beams():
    """Undamped hub beam with a tip body (at the shortened tip, like every mass point): a short RK4 run conserves the
    energy to the integrator's error, while the first-order stiffened beam's energy drifts by the work of its
    non-conservative stiffening force."""
    axes = ((0, 0, 1), (0, 1, 0))
    q0, u0 = np.r_[0.2, -0.1, 0.04, 0, -0.03, 0, 0.0], np.r_[6.0, 2.0, 0, 0, 0, 0, 0]
    drift = {}
    for second_order in (True, False):
        model, _ = hub_beam(axes, second_order, reference=False)
        run = ctmm.simulate(model, 0.03, 1e-3, method="rk4", x0=q0, v0=u0)
        states = np.stack([run[name] for name in model.coordinates + model.velocities], axis=1)
        values = energy(model, states[:, :7], states[:, 7:])
        assert np.ptp(run["b.qz1"]) > 1e-2                                       # it bends: 0.016
        drift[second_order] = np.ptp(values) / np.abs(values).max()
    assert drift[True] < 1e-9 and drift[False] > 1e-4                    # measured 1.4e-11 (RK4) and 1.4e-3


def planar_pair(plane: str):
    """Hub, stiffened second-order beam and tip body moving in the ``x-y`` plane (hinge axis z) or the ``x-z``
    plane (hinge axis -y: planar ``y`` is spatial ``z``), planar and spatial."""
    beam = ModalBeam("b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, damping_ratio=0.02,
                     second_order_inertia=True)
    planar = PlanarModel.chain("m", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam, FixedMounting("m3"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))])
    if plane == "xy":
        axis, vector, modes = (0, 0, 1), (lambda a, b: (a, b, 0.0)), dict(n_modes_y=3, n_modes_z=0)
        inertia, small = np.diag([0.05, 0.06, 0.1]), np.diag([0.006, 0.005, 0.01])
    else:
        axis, vector, modes = (0, -1, 0), (lambda a, b: (a, 0.0, b)), dict(n_modes_y=0, n_modes_z=3)
        inertia, small = np.diag([0.05, 0.1, 0.06]), np.diag([0.006, 0.01, 0.005])
    spatial = SpatialModel("s", [
        SpatialBody("hub", mass=2.0, inertia=inertia, center_of_mass=vector(0.05, 0.02), points={"out": (0.2, 0, 0)}),
        Revolute(name="o", parent=None, child="hub", axis=axis),
        SpatialBeam("b", length=1.3, bending_stiffness_y=5.0, bending_stiffness_z=5.0, mass_per_length=0.7, **modes,
                    damping_ratio=0.02, second_order_inertia=True),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=rotation(axis, 0.3)),
        SpatialBody("tip", mass=0.2, inertia=small, center_of_mass=vector(0.03, 0.01)),
        Weld(name="m3", parent="b", child="tip", point="tip"),
    ], gravity=vector(0.0, -9.81))
    return planar, spatial


@pytest.mark.parametrize("plane", ["xy", "xz"])
def test_the_planar_restriction_is_the_planar_second_order_modal_beam(plane):
    planar, spatial = planar_pair(plane)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, qd = rng.normal(size=4) * 0.1, rng.normal(size=4) * 3
        expected = solve_flexible(planar, q, qd, 0.4).qddot
        assert np.abs(accelerations(spatial, q, qd, 0.4) - expected).max() <= 1e-12 * np.abs(expected).max()


V0 = {"hubj.angle_rate": 4.0, "b.qz1_rate": 0.5}


def test_generated_kernel_runs_the_same_terms():
    """The generated (casadi) kernel states the same accelerations as the numpy sweep: RK4 runs agree to round-off."""
    model, _ = hub_beam(((0, 0, 1),), True, reference=False)
    first = ctmm.simulate(model, 0.02, 1e-3, method="rk4", v0=V0)
    second = ctmm.simulate(model, 0.02, 1e-3, method="rk4", v0=V0, compiled=True)
    for name in model.coordinates:
        assert abs(second[name][-1] - first[name][-1]) <= 1e-12


def test_implicit_newmark_converges_at_second_order():
    """The implicit Newmark DT-TMM (same terms, its own Newton iteration) converges to a fine RK4 run at order 2."""
    model, _ = hub_beam(((0, 0, 1),), True, reference=False)
    fine = ctmm.simulate(model, 0.04, 1e-3, method="rk4", v0=V0)
    target = np.array([fine[name][-1] for name in model.coordinates])
    errors = []
    for dt in (4e-3, 2e-3):
        run = ctmm.simulate(model, 0.04, dt, method="newmark", v0=V0)
        errors.append(np.abs(np.array([run[name][-1] for name in model.coordinates]) - target).max())
    assert 1.7 < math.log2(errors[0] / errors[1]) < 2.3


def test_beam_numbers_as_kernel_inputs_scale_the_second_order_terms():
    """The generated loop kernel with the beam's numbers as inputs (``ctmm.compiled_spatial_beam_numbers``, used by
    ``ctmm.sensitivity``) at changed mass and polar inertia per length and gravity equals the numpy sweep of the
    model rebuilt with those numbers."""
    from ctmm.compiled_spatial_loops import loop_acceleration
    from ctmm.compiled_spatial_parameters import spatial_parameter_layout, spatial_parameter_vector
    from ctmm.spatial.ports import SpatialPorts

    axes = ((0, 0, 1), (0, 1, 0))
    base, _ = hub_beam(axes, True, reference=False)
    layout = spatial_parameter_layout(base)
    p = spatial_parameter_vector(base)
    scale = {"b.mass_per_length": 1.6, "b.polar_inertia_per_length": 1.4}
    for k, entry in enumerate(layout):
        p[k] *= scale.get(entry.name, 0.7 if entry.kind == "gravity" else 1.0)
    bodies = [dataclasses.replace(body, mass_per_length=0.9 * 1.6, polar_inertia_per_length=0.002 * 1.4)
              if isinstance(body, SpatialBeam) else body for body in base.bodies]
    rebuilt = SpatialModel("s", bodies + list(base.joints), gravity=0.7 * np.asarray(GRAVITY))
    parametrised = loop_acceleration(base, SpatialPorts(base), (), layout)
    got = np.asarray(parametrised(Q, U, [], p, 0.0)).ravel()
    expected = accelerations(rebuilt, Q, U)
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
    assert np.abs(expected - accelerations(base, Q, U)).max() > 0.02 * np.abs(expected).max()    # the numbers matter


@pytest.mark.parametrize("changes, message", [
    ({"second_order_inertia": 1}, "second_order_inertia must be True or False"),
    ({"second_order_inertia": True, "geometric_stiffening": False}, "geometric_stiffening = False"),
    ({"second_order_inertia": True, "n_axial_modes": 1, "axial_stiffness": 1e6}, "n_axial_modes = 1"),
])
def test_refused_combinations_name_the_parameter(changes, message):
    with pytest.raises(ModelError, match=message):
        SpatialBeam("b", **{**dict(length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0),
                            **changes})
