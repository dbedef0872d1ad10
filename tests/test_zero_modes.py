"""Rigid-body (zero) modes are decided by each mode's own round-off, never by a cut relative to the stiffest
mode: a soft mode beside a very stiff part (a stiff aluminium plate subsystem, a 1e12 spring) keeps its
frequency.  References: the global finite-element model of ctmm/reference/spatial_fe_global.py (own element
code) and analytic pendulum / spring frequencies."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.fem import SpatialFiniteElementModel, SpatialPlateElement
from ctmm.planar import Fixed, PlanarModel, RigidBody
from ctmm.planar.elements import ElasticHinge, SmoothHinge
from ctmm.reference.spatial_fe_global import FEFrame, FramePlate, Link, SpatialFEChain

NODES = {f"{i}_{j}": (0.25 * i, 0.24 * j, 0.18 * j) for i in range(3) for j in range(2)}
ALUMINIUM = dict(h=0.002, E=7e10, nu=0.33, rho=2700.0)
I1, I2 = np.diag([0.01, 0.02, 0.015]), np.diag([0.004, 0.003, 0.002])


def plate_chain(hinge_stiffness):
    """A free yaw link, a stiff 2 mm aluminium plate on a sprung pitch joint (omega_max ~ 7e4 rad/s) and a link on
    a soft hinge at the plate's corner, without gravity (rest is the equilibrium); and the global reference."""
    quads = [(f"{i}_0", f"{i + 1}_0", f"{i + 1}_1", f"{i}_1") for i in range(2)]
    plates = [SpatialPlateElement(f"p{i}", quad, ALUMINIUM["h"], ALUMINIUM["E"], ALUMINIUM["nu"], ALUMINIUM["rho"])
              for i, quad in enumerate(quads)]
    fe = SpatialFiniteElementModel("fe", NODES, plates)
    model = sp.SpatialModel("plate_chain", [
        sp.SpatialBody("link1", 1.2, I1, center_of_mass=(0.1, 0.0, 0.15), points={"tip": (0.2, 0.0, 0.3)}),
        sp.Revolute(name="yaw", parent=None, child="link1", axis=(0, 0, 1)),
        fe.subsystem("panel", boundary=("0_0", "2_1")),
        sp.Revolute(name="pitch", parent="link1", point="tip", child="panel", axis=(0, 1, 0), stiffness=200.0),
        sp.SpatialBody("link2", 0.3, I2, center_of_mass=(0.0, 0.05, -0.1)),
        sp.Revolute(name="hinge", parent="panel", point="2_1", child="link2", axis=(1, 0, 0),
                    stiffness=hinge_stiffness)], gravity=(0.0, 0.0, 0.0))
    reference = SpatialFEChain([Link(1.2, I1, (0.1, 0.0, 0.15), (0, 0, 1), (0, 0, 0)),
                                FEFrame(NODES, "0_0", [], [], axis=(0, 1, 0), point=(0.2, 0.0, 0.3),
                                        plates=[FramePlate(quad, **ALUMINIUM) for quad in quads]),
                                Link(0.3, I2, (0.0, 0.05, -0.1), (1, 0, 0), "2_1")],
                               gravity=(0.0, 0.0, 0.0), joint_springs={1: (200.0, 0.0), 2: (hinge_stiffness, 0.0)})
    return model, reference


def test_soft_mode_beside_a_stiff_plate_is_not_reported_rigid():
    model, reference = plate_chain(0.02)
    rest = (np.zeros(model.n_positions), np.zeros(model.n_velocities))
    omega = ctmm.natural_frequencies(model, n_modes=3, operating_point=rest)
    expected = reference.natural_frequencies(rest[0])
    assert expected[-1] > 7e4 and 1.0 < expected[1] < 1e-4 * expected[-1]      # below the old sqrt(1e-9) omega_max
    assert omega[0] == 0.0 and expected[0] < 1e-6                              # the free yaw
    np.testing.assert_allclose(omega[1:], expected[1:3], rtol=1e-8)
    assert ctmm.eigenvalue_count(model, [0.5 * expected[1], 1.5 * expected[1]], operating_point=rest).tolist() == [1, 2]


def test_a_mode_lost_in_round_off_is_refused_not_zeroed():
    model, _ = plate_chain(1e-4)                     # omega^2 ~ 0.015 rad^2/s^2 beside omega_max^2 ~ 5e9
    rest = (np.zeros(model.n_positions), np.zeros(model.n_velocities))
    with pytest.raises(ctmm.ModelError, match="cannot be told from rigid-body modes"):
        ctmm.natural_frequencies(model, n_modes=3, operating_point=rest)


def spatial_stiff_spring(stiffness):
    """A pendulum (bob 1 kg at 1 m), a block (inertia 2 kg m^2) on a torsion spring and a free wheel, side by side."""
    return sp.SpatialModel("side_by_side", [
        sp.SpatialBody("bob", 1.0, 1e-6 * np.eye(3), center_of_mass=(0, 0, -1.0)),
        sp.Revolute(name="swing", parent=None, child="bob", axis=(1, 0, 0)),
        sp.SpatialBody("block", 1.0, np.diag([1.0, 1.0, 2.0])),
        sp.Revolute(name="twist", parent=None, child="block", axis=(0, 0, 1), stiffness=stiffness, point=(3, 0, 0)),
        sp.SpatialBody("wheel", 1.0, np.diag([1.0, 1.0, 0.5])),
        sp.Revolute(name="spin", parent=None, child="wheel", axis=(0, 0, 1), point=(-3, 0, 0))])


def planar_stiff_spring(stiffness, gravity):
    """The planar pendulum beside a block on a rotary + translational spring."""
    return PlanarModel("side_by_side", [
        Fixed("g"), Fixed("g2"), RigidBody("bob", mass=1.0, inertia=1e-6, center_of_mass=(1.0, 0.0)),
        SmoothHinge("swing", parent="g", child="bob"),
        RigidBody("block", mass=1.0, inertia=2.0, center_of_mass=(0.0, 0.0)),
        ElasticHinge("twist", parent="g2", child="block", stiffness=stiffness, translational_stiffness=stiffness)],
        gravity=(0.0, -gravity))


@pytest.mark.parametrize("stiffness", [1e3, 1e12])
def test_pendulum_beside_a_stiff_spring_keeps_its_frequency(stiffness):
    pendulum, twist = np.sqrt(9.81 / (1.0 + 1e-6)), np.sqrt(stiffness / 2.0)
    omega = ctmm.natural_frequencies(spatial_stiff_spring(stiffness), n_modes=3)
    np.testing.assert_allclose(omega, [0.0, pendulum, twist], rtol=1e-9)
    omega = ctmm.natural_frequencies(planar_stiff_spring(stiffness, 9.81), n_modes=4)
    np.testing.assert_allclose(omega, [pendulum, twist, np.sqrt(stiffness), np.sqrt(stiffness)], rtol=1e-9)
    free = ctmm.mode_shapes(planar_stiff_spring(stiffness, 0.0), n_modes=2)
    np.testing.assert_allclose(free.natural_frequencies, [0.0, twist], rtol=1e-9)
    assert abs(free.shapes[0, 0, 0]) == pytest.approx(1.0)                   # the rigid mode is the bob's swing


def bare_beam(root, n_modes):
    beam = sp.SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=2.0,
                          n_modes_y=n_modes, n_modes_z=n_modes, polar_inertia_per_length=0.01)
    joint = (sp.Spherical(name="root", parent=None, child="b") if root == "spherical"
             else sp.Revolute(name="root", parent=None, child="b", axis=(0, 1, 0)))
    return sp.SpatialModel("beam", [beam, joint], gravity=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("root", ["spherical", "revolute"])
def test_a_bare_beam_with_many_modes_is_linearised_not_refused(root):
    """The Richardson cross-check of the Jacobians no longer refuses the smooth high modal coordinates: the
    assumed-modes frequencies converge from above to the exact-field ones (Wittrick-Williams on exact beam
    fields, independent of the modal form)."""
    exact = ctmm.natural_frequencies(bare_beam(root, 6), n_modes=5, fields="exact")
    few, many = (ctmm.natural_frequencies(bare_beam(root, n), n_modes=5) for n in (3, 6))
    elastic = exact > 0.0
    assert np.array_equal(few > 0.0, elastic) and np.array_equal(many > 0.0, elastic)
    assert np.all(many[elastic] >= exact[elastic] * (1.0 - 1e-12))                  # Rayleigh-Ritz: from above
    assert np.all(many[elastic] <= few[elastic] * (1.0 + 1e-12))
    np.testing.assert_allclose(many, exact, rtol=1e-5)


def test_a_kink_in_a_spatial_joint_law_is_still_refused():
    from ctmm.nonlinear_laws import ClearanceSpring

    model = sp.SpatialModel("gap", [
        sp.SpatialBody("arm", 1.0, np.diag([0.1, 0.1, 0.1]), center_of_mass=(0.5, 0.0, 0.0)),
        sp.Revolute(name="hinge", parent=None, child="arm", axis=(0, 0, 1), law=ClearanceSpring(20.0, clearance=0.05))],
        gravity=(0.0, 0.0, 0.0))
    corner = (np.array([0.05]), np.zeros(1))
    with pytest.raises(ctmm.ModelError, match="not smooth"):
        ctmm.natural_frequencies(model, n_modes=1, operating_point=corner)
