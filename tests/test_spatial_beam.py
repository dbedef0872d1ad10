"""The modal spatial beam (issue 15 items 1-2, 5): equal to the planar ModalBeam in a plane, equal to the
independent assumed-modes Lagrange model in 3-D, analytic frequencies with a tip body, energy, the
compiled and implicit paths, connections and bad input."""
from __future__ import annotations

import copy
import math
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import brentq

import ctmm
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.flexible.beam import ModalForce
from ctmm.flexible.kernel import solve_flexible
from ctmm.ops import CASADI, NUMPY
from ctmm.planar import Load as PlanarLoad
from ctmm.planar import Pinned, PlanarModel, RigidBody, simulate_rk4
from ctmm.planar.elements import FixedMounting
from ctmm.reference.beams import beta_roots
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial.beam import SpatialBeam
from ctmm.spatial.beam_terms import spatial_beam_terms
from ctmm.spatial.dynamics import accelerations, energy
from ctmm.spatial.elements import Free, Load, Revolute, Spherical, SpatialBody, Universal, Weld
from ctmm.spatial.model import SpatialModel


def rotation(axis, angle):
    a = np.asarray(axis, float)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# -- (a) the planar restriction ---------------------------------------------------------------------
def planar_pair(plane: str):
    """The planar hub-beam-beam-tip model and the spatial one moving in the ``x-y`` plane (hinge axis z)
    or in the ``x-z`` plane (hinge axis -y: planar ``y`` is spatial ``z``, bending in the beam's z plane)."""
    load = PlanarLoad(point=(0.7, 0.0), force_x=0.3, force_y=lambda t: math.sin(t), moment=0.2)
    beam = ModalBeam("b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, n_axial_modes=1,
                     axial_stiffness=300.0, damping_ratio=0.02, loads=(load,))
    second = ModalBeam("c", length=0.6, bending_stiffness=2.0, mass_per_length=0.4, n_modes=2)
    planar = PlanarModel.chain("m", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam, FixedMounting("m2", angle=-0.2), second, FixedMounting("m3"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))])
    if plane == "xy":
        axis, vector, modes = (0, 0, 1), (lambda a, b: (a, b, 0.0)), dict(n_modes_y=3, n_modes_z=0)
        inertia, small = np.diag([0.05, 0.06, 0.1]), np.diag([0.006, 0.005, 0.01])
        second_modes = dict(n_modes_y=2, n_modes_z=0)
    else:
        axis, vector, modes = (0, -1, 0), (lambda a, b: (a, 0.0, b)), dict(n_modes_y=0, n_modes_z=3)
        inertia, small = np.diag([0.05, 0.1, 0.06]), np.diag([0.006, 0.01, 0.005])
        second_modes = dict(n_modes_y=0, n_modes_z=2)
    moment = tuple(0.2 * np.asarray(axis, float))
    spatial = SpatialModel("s", [
        SpatialBody("hub", mass=2.0, inertia=inertia, center_of_mass=vector(0.05, 0.02), points={"out": (0.2, 0, 0)}),
        Revolute(name="o", parent=None, child="hub", axis=axis),
        SpatialBeam("b", length=1.3, bending_stiffness_y=5.0, bending_stiffness_z=5.0, mass_per_length=0.7, **modes,
                    n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.02, stations={"l": 0.7}),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=rotation(axis, 0.3)),
        SpatialBeam("c", length=0.6, bending_stiffness_y=2.0, bending_stiffness_z=2.0, mass_per_length=0.4,
                    **second_modes),
        Weld(name="m2", parent="b", child="c", point="tip", rotation=rotation(axis, -0.2)),
        SpatialBody("tip", mass=0.2, inertia=small, center_of_mass=vector(0.03, 0.01)),
        Weld(name="m3", parent="c", child="tip", point="tip"),
        Load("ld", body="b", point="l", force=vector(0.3, lambda t: math.sin(t)), moment=moment),
    ], gravity=vector(0.0, -9.81))
    return planar, spatial


@pytest.mark.parametrize("plane", ["xy", "xz"])
def test_the_spatial_beam_restricted_to_a_plane_is_the_planar_modal_beam(plane):
    planar, spatial = planar_pair(plane)
    assert [c.split(".")[1] for c in planar.coordinates[1:]] == ["q1", "q2", "q3", "u1", "q1", "q2"]
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, qd = rng.normal(size=7) * 0.1, rng.normal(size=7)
        expected = solve_flexible(planar, q, qd, 0.4).qddot
        assert np.abs(accelerations(spatial, q, qd, 0.4) - expected).max() <= 1e-12 * np.abs(expected).max()
    q0, v0 = np.r_[0.3, 0.02, 0, 0, 0, 0.01, 0], np.r_[2.0, 0, 0, 0, 0, 0, 0]
    run = simulate_rk4(planar, q0, v0, t_final=0.1, dt=2e-3)
    result = ctmm.simulate(spatial, 0.1, 2e-3, method="rk4", x0=q0, v0=v0)
    got = np.stack([result[name] for name in spatial.coordinates], axis=1)
    assert np.abs(got - run.q).max() <= 1e-10 * np.abs(run.q).max()


# -- (b) 3-D motion against the independent Lagrange model -------------------------------------------
HUB_INERTIA = np.array([[0.12, 0.01, 0], [0.01, 0.1, 0.02], [0, 0.02, 0.15]])
TIP_INERTIA = np.array([[0.004, 0.0005, 0], [0.0005, 0.005, 0.0003], [0, 0.0003, 0.006]])
MOUNT = rotation((0, 1, 0), 0.2) @ rotation((1, 0, 0), 0.3)
BEAM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0, n_modes_y=2,
            n_modes_z=2, n_torsion_modes=1, torsional_stiffness=3.0, polar_inertia_per_length=0.002, n_axial_modes=1,
            axial_stiffness=400.0)
GRAVITY = (0.5, 0.2, -9.81)


def hub_beam(axes, stiffening, damping=0.01, spring=1.0, hub_damping=0.1):
    reference = SpatialBeamLagrange(HubBeam(
        **BEAM, hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02), axes=axes,
        mount=(0.2, 0.0, 0.05), mount_rotation=MOUNT, geometric_stiffening=stiffening, damping_ratio=damping,
        tip_mass=0.3, tip_inertia=TIP_INERTIA, tip_center=(0.03, 0.02, -0.01), gravity=GRAVITY,
        joint_stiffness=[spring] * len(axes), joint_damping=[hub_damping] * len(axes)))
    law = dict(stiffness=spring, damping=hub_damping)
    joint = (Revolute(name="hubj", parent=None, child="hub", axis=axes[0], **law) if len(axes) == 1 else
             Universal(name="hubj", parent=None, child="hub", axis1=axes[0], axis2=axes[1], **law))
    model = SpatialModel("s", [
        SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                    points={"out": (0.2, 0, 0.05)}), joint,
        SpatialBeam("b", **BEAM, geometric_stiffening=stiffening, damping_ratio=damping),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=MOUNT),
        SpatialBody("tip", mass=0.3, inertia=TIP_INERTIA, center_of_mass=(0.03, 0.02, -0.01)),
        Weld(name="m2", parent="b", child="tip", point="tip")], gravity=GRAVITY)
    return model, reference


@pytest.mark.parametrize("axes", [((0, 0, 1),), ((0, 0, 1), (0, 1, 0))], ids=["revolute", "universal"])
@pytest.mark.parametrize("stiffening", [True, False])
def test_3d_accelerations_equal_the_lagrange_model(axes, stiffening):
    model, reference = hub_beam(axes, stiffening)
    rng = np.random.default_rng(2)
    for _ in range(4):
        q, u = rng.normal(size=reference.n) * 0.3, rng.normal(size=reference.n) * 2
        expected = reference.accelerations(q, u)
        assert np.abs(accelerations(model, q, u) - expected).max() <= 1e-11 * np.abs(expected).max()


def test_3d_rk4_run_equals_the_lagrange_model_with_the_same_integrator():
    model, reference = hub_beam(((0, 0, 1), (0, 1, 0)), True)
    q0 = np.r_[0.2, -0.1, 0.01, 0, -0.02, 0, 0.005, 0.001]
    u0 = np.r_[3.0, 0.5, 0, 0, 0, 0, 0, 0]
    dt, steps = 2e-3, 100
    expected = reference.rk4(q0, u0, dt, steps)[-1]
    result = ctmm.simulate(model, dt * steps, dt, method="rk4", x0=q0, v0=u0)
    got = np.array([result[name][-1] for name in model.coordinates + model.velocities])
    assert np.abs(got - expected).max() <= 1e-8
    assert np.abs(expected[2:8]).max() > 1e-3                         # the beam did deform, out of plane too


def test_energy_equals_the_lagrange_energy_and_is_conserved_undamped():
    model, reference = hub_beam(((0, 0, 1), (0, 1, 0)), False, damping=0.0, hub_damping=0.0)
    rng = np.random.default_rng(3)
    q, u = rng.normal(size=reference.n) * 0.3, rng.normal(size=reference.n)
    assert energy(model, q, u) == pytest.approx(reference.energy(q, u), rel=1e-12)
    q0, u0 = np.r_[0.2, -0.1, 0.01, 0, -0.02, 0, 0.005, 0.001], np.r_[3.0, 0.5, 0, 0, 0, 0, 0, 0]
    result = ctmm.simulate(model, 0.1, 5e-4, method="rk4", x0=q0, v0=u0)
    states = np.stack([result[name] for name in model.coordinates + model.velocities], axis=1)
    values = energy(model, states[:, :8], states[:, 8:])
    assert np.ptp(values) <= 1e-7 * np.abs(values).max()


def test_a_free_floating_beam_on_a_spherical_joint_chain_conserves_energy():
    # beam on a free joint (inboard point != root after translation) carrying a beam on a spherical joint
    model = SpatialModel("f", [
        SpatialBeam("a", length=0.8, mass_per_length=1.0, bending_stiffness_y=4.0, bending_stiffness_z=6.0,
                    n_modes_y=2, n_modes_z=2, n_torsion_modes=1, torsional_stiffness=2.0,
                    polar_inertia_per_length=0.003, geometric_stiffening=False, stations={"mid": 0.5}),
        Free(name="base", parent=None, child="a"),
        SpatialBeam("c", length=0.5, mass_per_length=0.5, bending_stiffness_y=3.0, bending_stiffness_z=3.0,
                    n_modes_y=1, n_modes_z=1, n_axial_modes=1, axial_stiffness=200.0, geometric_stiffening=False,
                    polar_inertia_per_length=0.002),             # a ball joint lets it spin about its axis
        Spherical(name="ball", parent="a", child="c", point="mid", rotation=rotation((0, 0, 1), 1.0))],
        gravity=(0, 0, -9.81))
    x0 = dict(zip(model.coordinates, model.neutral()))
    x0.update({"base.x": 0.3, "a.qz1": 0.01, "c.qy1": -0.01})
    v0 = {"base.vx": 0.2, "base.wz": 2.0, "base.wx": 0.5, "ball.wy": 1.0}
    drift = []
    for dt in (5e-4, 2.5e-4):                  # free-free modes near 100 rad/s: RK4's energy error, order 4
        result = ctmm.simulate(model, 0.05, dt, method="rk4", x0=x0, v0=v0)
        states = np.stack([result[name] for name in model.coordinates + model.velocities], axis=1)
        values = energy(model, states[:, :model.n_positions], states[:, model.n_positions:])
        drift.append(np.ptp(values) / np.abs(values).max())
    assert drift[1] < 1e-6 and drift[0] / drift[1] > 12


# -- (c) frequencies of a clamped-free beam with a tip body ----------------------------------------
def _rod_frequencies(ratio: float, count: int, speed: float) -> np.ndarray:
    """Clamped rod with a tip inertia: ``k L tan(k L) = ratio`` (beam over tip inertia), ``omega = k c``."""
    return np.array([brentq(lambda z: z * math.tan(z) - ratio, k * math.pi + 1e-12, k * math.pi + math.pi / 2 - 1e-12)
                     for k in range(count)]) * speed


def test_linearised_frequencies_with_a_tip_body_converge_to_the_analytic_frequency_equations():
    # L = rhoA = 1; bending EI_y = 1 (tip rotation about z), EI_z = 2 (about y); GJ = 0.5, j_p = 0.01; EA = 50
    analytic = np.sort(np.concatenate([
        beta_roots("tip-mass", 3, tip_mass_ratio=0.5, tip_inertia_ratio=0.04) ** 2,
        beta_roots("tip-mass", 3, tip_mass_ratio=0.5, tip_inertia_ratio=0.03) ** 2 * math.sqrt(2.0),
        _rod_frequencies(0.01 / 0.02, 3, math.sqrt(0.5 / 0.01)), _rod_frequencies(1.0 / 0.5, 3, math.sqrt(50.0))]))
    found = []
    for n in (8, 16):
        model = SpatialModel("c", [
            SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                        n_modes_y=n, n_modes_z=n, n_torsion_modes=n, torsional_stiffness=0.5,
                        polar_inertia_per_length=0.01, n_axial_modes=n, axial_stiffness=50.0),
            Weld(name="clamp", parent=None, child="b"),
            SpatialBody("tip", mass=0.5, inertia=np.diag([0.02, 0.03, 0.04])),
            Weld(name="w", parent="b", child="tip", point="tip")], gravity=(0, 0, 0))
        found.append(ctmm.natural_frequencies(model, n_modes=8))
    error = [f / analytic[:8] - 1 for f in found]
    assert np.all(error[0] > 0) and np.all(error[1] > 0)               # Rayleigh-Ritz: from above
    assert np.all(error[1] < 0.6 * error[0])                           # the assumed-modes O(1/n) rate
    assert np.abs(2 * found[1] / analytic[:8] - found[0] / analytic[:8] - 1).max() < 3e-3   # Richardson
    assert np.abs(error[1][:2]).max() < 3e-4                           # first bending pair, 16 modes


def test_static_shapes_give_the_tip_body_frequencies_to_1e_8_with_six_modes():
    analytic = np.sort(np.concatenate([
        beta_roots("tip-mass", 2, tip_mass_ratio=0.5, tip_inertia_ratio=0.04) ** 2,
        beta_roots("tip-mass", 2, tip_mass_ratio=0.5, tip_inertia_ratio=0.03) ** 2 * math.sqrt(2.0),
        _rod_frequencies(0.01 / 0.02, 2, math.sqrt(0.5 / 0.01)), _rod_frequencies(1.0 / 0.5, 2, math.sqrt(50.0))]))
    beam = SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                       n_modes_y=6, n_modes_z=6, n_torsion_modes=6, torsional_stiffness=0.5,
                       polar_inertia_per_length=0.01, n_axial_modes=6, axial_stiffness=50.0, static_shapes=True)
    assert beam.coordinate_suffixes[6:8] == ("qy_force", "qy_moment") and beam.n_eta == 30
    model = SpatialModel("c", [beam, Weld(name="clamp", parent=None, child="b"),
                               SpatialBody("tip", mass=0.5, inertia=np.diag([0.02, 0.03, 0.04])),
                               Weld(name="w", parent="b", child="tip", point="tip")], gravity=(0, 0, 0))
    error = ctmm.natural_frequencies(model, n_modes=6) / analytic[:6] - 1
    assert np.all(error > -1e-11) and np.all(error < 1e-8)
    with pytest.raises(ModelError, match="nearly linearly dependent"):
        SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0,
                    n_modes_y=8, n_modes_z=1, static_shapes=True)
    with pytest.raises(ModelError, match="stiffness_damping"):
        SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0,
                    static_shapes=True, damping_ratio=0.01)


def test_static_shapes_conserve_energy_on_a_spinning_hub():
    model = SpatialModel("h", [
        SpatialBody("hub", 2.0, (0.1, 0.1, 0.15), points={"out": (0.2, 0, 0)}),
        Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1)),
        SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=3.0, bending_stiffness_z=4.0,
                    n_modes_y=2, n_modes_z=2, n_torsion_modes=1, torsional_stiffness=1.0, polar_inertia_per_length=0.01,
                    geometric_stiffening=False, static_shapes=True),
        Weld(name="mount", parent="hub", child="b", point="out"),
        SpatialBody("tip", mass=0.2, inertia=np.diag([0.002, 0.003, 0.004]), center_of_mass=(0.02, 0.01, 0)),
        Weld(name="w", parent="b", child="tip", point="tip")], gravity=(0, 0, -9.81))
    result = ctmm.simulate(model, 0.05, 2.5e-4, method="rk4", v0={"hinge.angle_rate": 3.0}, x0={"b.qz_force": 0.01})
    states = np.stack([result[name] for name in model.coordinates + model.velocities], axis=1)
    values = energy(model, states[:, :model.n_positions], states[:, model.n_positions:])
    assert np.ptp(values) <= 1e-8 * np.abs(values).max()


# -- the rotation of a point frame: casadi AD of Rz Ry Rx --------------------------------------------
def test_point_frame_angular_velocity_and_acceleration_equal_automatic_differentiation():
    beam = SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                       n_modes_y=2, n_modes_z=2, n_torsion_modes=2, torsional_stiffness=1.0,
                       polar_inertia_per_length=0.01, geometric_stiffening=False, stations={"s": 0.7})
    rng = np.random.default_rng(4)
    eta, rate = rng.normal(size=6) * 0.4, rng.normal(size=6)
    terms, frames = spatial_beam_terms(NUMPY, beam, rotation=np.eye(3)[None], offset=None, omega=None,
                                       eta=eta[None, :, None], eta_dot=rate[None, :, None], t=0.0,
                                       gravity=np.zeros(3), points={"s": beam.points["s"]}, frames=("s",))
    Lam = beam.data.station(0.7)[1]
    tau = ca.SX.sym("tau")
    theta = ca.DM(Lam) @ ca.DM(eta + 0 * rate) + ca.DM(Lam @ rate) * tau     # eta'' = 0 along the path

    def rot(axis, angle):
        K = ca.DM(np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]], float))
        return ca.DM.eye(3) + K * ca.sin(angle) + K @ K * (1 - ca.cos(angle))

    E = rot((0, 0, 1), theta[2]) @ rot((0, 1, 0), theta[1]) @ rot((1, 0, 0), theta[0])
    W = ca.jacobian(ca.reshape(E, 9, 1), tau)
    W = ca.reshape(W, 3, 3) @ E.T
    omega = ca.vertcat(W[2, 1], W[0, 2], W[1, 0])
    alpha = ca.jacobian(omega, tau)
    f = ca.Function("f", [tau], [E, omega, alpha])
    E0, omega0, alpha0 = (np.asarray(v) for v in f(0.0))
    assert np.abs(frames["s"].rotation[0] - E0).max() < 1e-14
    assert np.abs(frames["s"].omega[0, :, 0] - omega0[:, 0]).max() < 1e-14
    assert np.abs(terms.c["s"][0, 3:, 0] - alpha0[:, 0]).max() < 1e-13


# -- the compiled and implicit paths -----------------------------------------------------------------
def test_compiled_rk4_equals_the_numpy_rk4():
    model, _ = hub_beam(((0, 0, 1),), True)
    v0 = {"hubj.angle_rate": 2.0}
    first = ctmm.simulate(model, 0.05, 1e-3, method="rk4", v0=v0)
    second = ctmm.simulate(model, 0.05, 1e-3, method="rk4", v0=v0, compiled=True)
    for name in model.coordinates:
        assert abs(second[name][-1] - first[name][-1]) <= 1e-13


def test_implicit_newmark_is_second_order_on_a_hub_beam():
    model, _ = hub_beam(((0, 0, 1),), True)
    v0 = {"hubj.angle_rate": 2.0}
    fine = ctmm.simulate(model, 0.08, 1e-3, method="rk4", v0=v0)
    target = np.array([fine[name][-1] for name in model.coordinates])
    errors = []
    for dt in (4e-3, 2e-3):
        run = ctmm.simulate(model, 0.08, dt, method="newmark", v0=v0)
        errors.append(np.abs(np.array([run[name][-1] for name in model.coordinates]) - target).max())
    assert 1.7 < math.log2(errors[0] / errors[1]) < 2.3


# -- hooks and bad input -----------------------------------------------------------------------------
def test_a_moment_pair_equals_two_opposite_station_moments():
    beam = SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.5,
                       n_modes_y=2, n_modes_z=2, stations={"p1": 0.2, "p2": 0.5})
    hooked = SpatialModel("h", [beam.with_modal_forces(beam.moment_pair(0.2, 0.5, 2.0, axis="y")),
                                Weld(name="w", parent=None, child="b")], gravity=(0, 0, 0))
    loaded = SpatialModel("l", [beam, Weld(name="w", parent=None, child="b"),
                                Load("m1", body="b", point="p1", moment=(0, -2.0, 0), axes="body"),
                                Load("m2", body="b", point="p2", moment=(0, 2.0, 0), axes="body")], gravity=(0, 0, 0))
    rates = accelerations(hooked, np.zeros(4), np.zeros(4))
    assert np.abs(rates[2:]).min() > 1e-3 and np.abs(rates[:2]).max() == 0.0     # z-plane modes only
    assert np.allclose(rates, accelerations(loaded, np.zeros(4), np.zeros(4)), rtol=1e-13, atol=1e-13)
    with pytest.raises(ModelError, match="compiled"):
        ctmm.simulate(hooked, 0.01, 1e-3, compiled=True)


@pytest.mark.parametrize("change, match", [
    (dict(n_modes_y=0, n_modes_z=0), "at least one mode"),
    (dict(n_torsion_modes=1), "torsional_stiffness"),
    (dict(n_torsion_modes=1, torsional_stiffness=1.0), "polar_inertia_per_length"),
    (dict(stations={"tip": 0.5}), "taken"),
    (dict(stations={"s": 1.5}), "must lie on the beam"),
    (dict(modal_forces=(ModalForce(law=lambda t, e, d: e),)), "law is not supported"),
    (dict(quadrature=9), "quadrature"),
    (dict(length=-1.0), "length"),
])
def test_bad_input_is_refused_with_the_parameter_named(change, match):
    base = dict(length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0)
    with pytest.raises(ModelError, match=match):
        SpatialBeam("b", **{**base, **change})


# -- a rotating hub-beam in 3-D: Kane, Ryan & Banerjee's spin-up ---------------------------------------
@pytest.mark.parametrize("stiffening", [True, False])
def test_driven_spin_up_equals_kane_ryan_banerjee(stiffening):
    from ctmm.reference.beams import clamped_free_mode, kane_spinup, spinup_angle

    law = [lambda t, k=k: float(spinup_angle(t)[k]) for k in range(3)]
    model = SpatialModel("spin", [
        SpatialBody("hub", 1.0, (1.0, 1.0, 1.0)),
        Revolute(name="h", parent=None, child="hub", axis=(0, 0, 1), position=law[0], rate=law[1], acceleration=law[2]),
        SpatialBeam("b", length=10.0, mass_per_length=1.2, bending_stiffness_y=1.4e4, bending_stiffness_z=1.4e4,
                    n_modes_y=3, n_modes_z=1, geometric_stiffening=stiffening),
        Weld(name="w", parent="hub", child="b")], gravity=(0, 0, 0))
    result = ctmm.simulate(model, 8.0, 0.02, method="rk4", store_every=10)
    reference = kane_spinup(n_modes=3, geometric_stiffening=stiffening, t_eval=result.time, t_final=8.0)
    tip = sum(result[f"b.qy{i + 1}"] * clamped_free_mode(b, 1.0) for i, b in enumerate(beta_roots("clamped-free", 3)))
    assert np.abs(tip - reference.tip_deflection).max() <= 1e-6 * np.abs(reference.tip_deflection).max()
    assert np.abs(result["b.qz1"]).max() == 0.0                   # nothing drives the out-of-plane mode


def test_linearize_names_the_modes_and_its_eigenvalues_are_the_natural_frequencies():
    model = SpatialModel("c", [
        SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                    n_modes_y=2, n_modes_z=2, n_torsion_modes=1, torsional_stiffness=0.5, polar_inertia_per_length=0.01),
        Weld(name="clamp", parent=None, child="b"),
        SpatialBody("tip", mass=0.5, inertia=np.diag([0.02, 0.03, 0.04])),
        Weld(name="w", parent="b", child="tip", point="tip")], gravity=(0, 0, 0))
    linear = ctmm.linearize(model)
    assert linear.state_space.nstates == 10
    poles = np.sort(np.abs(np.linalg.eigvals(linear.state_space.A).imag))[::2]
    assert np.allclose(poles, ctmm.natural_frequencies(model, n_modes=5), rtol=1e-9)


def test_natural_frequencies_refuse_the_one_directional_stiffening_about_a_sagged_equilibrium():
    def hanging(stiffening):
        return SpatialModel("sag", [
            SpatialBody("hub", 2.0, (0.1, 0.1, 0.15), points={"out": (0.2, 0, 0)}),
            Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1)),
            SpatialBeam("b", length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
                        n_modes_y=1, n_modes_z=2, n_axial_modes=1, axial_stiffness=400.0,
                        geometric_stiffening=stiffening),
            Weld(name="mount", parent="hub", child="b", point="out"),
            SpatialBody("payload", 0.3, (0.004, 0.005, 0.006)),
            Weld(name="grip", parent="b", child="payload", point="tip")], gravity=(0, 0, -9.81))
    with pytest.raises(ModelError, match="not symmetric"):
        ctmm.natural_frequencies(hanging(True), n_modes=3)
    assert np.all(ctmm.natural_frequencies(hanging(False), n_modes=3)[1:] > 0)


# -- the numpy path on stacked integrals equals the term-by-term path of the generated kernels ---------
def _term_values(beam, ops, state, symbols=None):
    """``spatial_beam_terms`` of ``beam`` at ``state`` as a flat dict of numpy arrays (casadi: evaluated)."""
    arguments = dict(state)
    if symbols is not None:                       # casadi: symbols in, then the function at the same numbers
        arguments.update({key: symbol for key, symbol in symbols.items() if key in state})
        arguments["loads"] = [(point, symbols[f"w{i}"]) for i, (point, _) in enumerate(state["loads"])]
    terms, frames = spatial_beam_terms(ops, beam, **arguments)
    values = {"M": terms.M, "h": terms.h, **{f"{kind}:{e}": value for kind in ("Kin", "c", "RF")
                                            for e, value in getattr(terms, kind).items()},
              **{f"{e}:{name}": getattr(frame, name) for e, frame in frames.items()
                 for name in ("arm", "velocity", "rotation", "omega")}}
    if symbols is None:
        return {key: np.asarray(value)[0] for key, value in values.items()}
    inputs = [symbols[key] for key in ("rotation", "offset", "omega", "eta", "eta_dot", "w0", "w1")]
    numbers = [state[key][0] for key in ("rotation", "offset", "omega", "eta", "eta_dot")] + \
        [wrench[0] for _, wrench in state["loads"]]
    function = ca.Function("terms", inputs, list(values.values()))
    return {key: np.asarray(value) for key, value in zip(values, function(*numbers))}


@pytest.mark.parametrize("variant", ["plain", "stiffening", "wagner", "second_order", "rotary", "static_shapes"])
def test_numpy_terms_equal_the_term_by_term_ops_path_to_round_off(variant):
    """The numpy path (stacked integrals, one product for all ``E[i][k] eta``) against the term-by-term formulas that
    build the generated kernels (casadi, evaluated at the same state): every option, offset, loads, points and
    frames, a real and a complex-step state."""
    options = {"plain": {}, "stiffening": dict(geometric_stiffening=True),
               "wagner": dict(geometric_stiffening=True, wagner_term=True),
               "second_order": dict(geometric_stiffening=True, second_order_inertia=True, n_axial_modes=0),
               "rotary": dict(rotary_inertia_per_length_y=0.002, rotary_inertia_per_length_z=0.003),
               "static_shapes": dict(static_shapes=True, damping_ratio=0.0)}[variant]
    beam = SpatialBeam("b", **{**dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=5.0, bending_stiffness_z=7.0,
                                      n_modes_y=2, n_modes_z=2, n_torsion_modes=1, n_axial_modes=1,
                                      torsional_stiffness=3.0, axial_stiffness=400.0, polar_inertia_per_length=0.01,
                                      stations={"s": 0.4, "u": 0.9}, damping_ratio=0.01,
                                      distributed_load=(0.3, math.sin, 0.2)), **options})
    n = beam.data.n
    beam = beam.with_modal_forces(ModalForce(force=lambda t: 0.1 * t * np.arange(1.0, n + 1), label="hook"))
    rng = np.random.default_rng(7)
    state = dict(rotation=np.linalg.qr(rng.normal(size=(1, 3, 3)))[0], offset=rng.normal(size=(1, 3, 1)),
                 omega=rng.normal(size=(1, 3, 1)), eta=0.1 * rng.normal(size=(1, n, 1)),
                 eta_dot=rng.normal(size=(1, n, 1)), t=0.3, gravity=np.array([0.1, -9.81, 0.4]),
                 loads=[(beam.points[name], rng.normal(size=(1, 6, 1))) for name in ("s", "tip")],
                 points={"tip": beam.points["tip"], "s": beam.points["s"]}, frames=("tip", "u"))
    symbols = {key: ca.SX.sym(key, *state[key].shape[1:]) for key in ("rotation", "offset", "omega", "eta", "eta_dot")}
    symbols.update(w0=ca.SX.sym("w0", 6, 1), w1=ca.SX.sym("w1", 6, 1))
    reference = _term_values(beam, CASADI, state, symbols)
    values = _term_values(beam, NUMPY, state)
    assert values.keys() == reference.keys()
    for key, value in values.items():
        assert np.abs(value - reference[key]).max() <= 1e-14 * max(1.0, np.abs(reference[key]).max()), key
    # a complex-step state (frequency sweeps, sensitivities): the real part the real terms, the imaginary part
    # their directional derivative (central differences of the real path)
    step, direction = 1e-30, rng.normal(size=(1, n, 1))
    complex_values = _term_values(beam, NUMPY, {**state, "eta": state["eta"] + 1j * step * direction})
    ahead, behind = (_term_values(beam, NUMPY, {**state, "eta": state["eta"] + sign * 1e-6 * direction})
                     for sign in (1.0, -1.0))
    for key, value in complex_values.items():
        assert np.abs(value.real - values[key]).max() <= 1e-14 * max(1.0, np.abs(values[key]).max()), key
        slope = (ahead[key] - behind[key]) / 2e-6             # central differences (truncation ~1e-8 relative)
        assert np.abs(value.imag / step - slope).max() <= 1e-6 * max(1.0, np.abs(slope).max()), key


def test_the_stacked_integrals_are_built_once_and_never_read_by_a_changed_copy():
    beam = SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                       n_modes_y=2, n_modes_z=1)
    state = dict(rotation=np.eye(3)[None], offset=None, omega=np.ones((1, 3, 1)), eta=np.full((1, 3, 1), 0.1),
                 eta_dot=np.ones((1, 3, 1)), t=0.0, gravity=np.array([0.0, 0.0, -9.81]))
    first = spatial_beam_terms(NUMPY, beam, **state)[0]
    built = dict(beam.data.memo)
    assert built and spatial_beam_terms(NUMPY, beam, **state)[0].M.tolist() == first.M.tolist()
    assert all(beam.data.memo[key] is value for key, value in built.items())      # not rebuilt by the second call
    heavier = copy.copy(beam.data)                 # as the scaled views of the parametrised kernels
    heavier.b, heavier.m = 2.0 * heavier.b, 2.0 * heavier.m
    assert heavier.memo == {}
    doubled = spatial_beam_terms(NUMPY, SimpleNamespace(data=heavier, points=beam.points,
                                                        distributed_load=beam.distributed_load), **state)[0]
    assert np.allclose(doubled.M[0, :3, 6:], 2.0 * first.M[0, :3, 6:], rtol=1e-15, atol=0.0)
