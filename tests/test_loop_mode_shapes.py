"""``ctmm.mode_shapes`` of planar and spatial kinematic loop models: the modes on the constraint manifold.

Independent references: the finite-element four-bar as a global Lagrange model closed by a multiplier
(:mod:`ctmm.reference.fem_loop_global`, sharing no code with ``ctmm.fem``, the tree sweep or the cut joints): the
generalised eigenproblem ``N^T K N phi = omega^2 N^T M N phi`` of its Lagrangian on the null space ``N`` of the
constraint Jacobian, the shapes ``N phi`` in the same coordinates as the tree's; and the Hooke pendulum's closed form
(two compound-pendulum swings about the cross axes, no translation of the pivot).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.scenarios.four_bar import mechanism as four_bar
from ctmm.scenarios.four_bar import start
from ctmm.spatial import closed_loop_linear as linear
from spatial_loop_helpers import hooke_pendulum
from test_fem_cut_joints import equilibrium, fe_four_bar, reference


def _unit_largest(shapes: np.ndarray) -> np.ndarray:
    return shapes / shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])]


def test_fe_four_bar_modes_match_the_constrained_global_model():
    """Seven modes (rigid swing, coupler bending and stretching) in the tree coordinates (angles [rad], nodal
    displacements [m] and rotations [rad]) against ``N phi`` of the global model: measured 2.7e-11 of the unit
    largest entry (the Richardson tangent's error over the modes' gaps)."""
    loop, ref = fe_four_bar(2), reference(2)
    q_eq, lam = equilibrium(loop, ref)
    point = (q_eq, np.zeros_like(q_eq))
    result = ctmm.mode_shapes(loop, n_modes=7, operating_point=point)
    zero = np.zeros(ref.n)
    M, _ = ref.mass_and_forces(q_eq, zero)
    _, J, _, _ = ref.constraints(q_eq, zero)
    N = scipy.linalg.null_space(J)
    Kr, Mr = N.T @ ref.stiffness(q_eq, lam) @ N, N.T @ M @ N
    squared, phi = scipy.linalg.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
    expected = _unit_largest(N @ phi)
    assert result.point_names == loop.tree.coordinates and result.components == ("amplitude",)
    assert result.shapes.shape == (7, loop.tree.n_coordinates, 1)
    np.testing.assert_allclose(result.natural_frequencies, ctmm.natural_frequencies(loop, operating_point=point),
                               rtol=1e-14)
    assert np.max(np.abs(result.natural_frequencies / np.sqrt(squared) - 1.0)) < 3e-10
    assert np.max(np.abs(result.shapes[:, :, 0] - expected.T)) < 1e-9
    assert np.max(np.abs(J @ result.shapes[:, :, 0].T)) < 1e-12      # on the cut joints to first order
    low = ctmm.mode_shapes(loop, omega_max=200.0, operating_point=point)
    assert low.shapes.shape[0] == 3 and np.array_equal(low.shapes, result.shapes[:3])


def test_hooke_pendulum_modes_are_the_two_swings_about_the_cross_axes():
    """A body on a free joint held by a universal cut at its origin: the modes are rotations about body y
    (``I_yy = 0.03``, the lower frequency) and world x, the pivot fixed -- unit tangent vectors of the free joint."""
    loop = hooke_pendulum()
    q, _ = loop.consistent_state({"free.qw": np.cos(0.15), "free.qx": np.sin(0.15), "free.x": 0.01},
                                 {"free.wx": 1.5})
    point = linear.equilibrium(loop, q)
    result = ctmm.mode_shapes(loop, n_modes=2, operating_point=point)
    mass, arm = 1.2, 0.3
    exact = np.sqrt(mass * 9.81 * arm / (np.array([0.03, 0.02]) + mass * arm ** 2))
    assert np.max(np.abs(result.natural_frequencies / exact - 1.0)) < 1e-11
    assert result.point_names == ("free.x", "free.y", "free.z", "free.rx", "free.ry", "free.rz")
    np.testing.assert_allclose(result.shapes[:, :, 0], [[0, 0, 0, 0, 1, 0], [0, 0, 0, 1, 0, 0]], atol=1e-9)


def test_mode_shapes_refuse_what_they_cannot_honour():
    loop = four_bar()
    controlled = with_feedback(loop, [Feedback("pd", sensor="h1.angle", actuator="h1.torque", gain=1.0)])
    with pytest.raises(ModelError, match="feedback loops"):
        ctmm.mode_shapes(controlled, n_modes=1)
    with pytest.raises(ModelError, match="exactly one of n_modes"):
        ctmm.mode_shapes(loop)
    with pytest.raises(ModelError, match="exactly one of n_modes"):
        ctmm.mode_shapes(hooke_pendulum(), n_modes=1, omega_max=10.0, operating_point=np.zeros(7))
    q0, _ = start(loop)
    with pytest.raises(ModelError, match="not an equilibrium"):
        ctmm.mode_shapes(loop, n_modes=1, operating_point=(q0, np.zeros(3)))
    with pytest.raises(ModelError, match="has 1 natural frequencies, n_modes=2"):
        ctmm.mode_shapes(loop, n_modes=2)


def test_a_floating_mechanism_without_springs_or_gravity_has_only_neutral_modes_as_its_open_tree():
    """A four-bar whose ground link floats (``FreeBase``), no gravity, no spring: nothing restores any of its four
    degrees of freedom (three rigid motions and the mechanism's), so every ``omega`` is 0 -- the open tree's
    ``natural_frequencies`` says so; the loop model refused "not a stable equilibrium" on the tangent's round-off
    (``omega^2 = -1.6e-10`` 1/s^2, the differences' estimated error 1.2e-10 of ``max |A|``)."""
    from ctmm.planar import FreeBase, PlanarModel, RigidBody, SmoothHinge
    from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
    base = RigidBody("b", mass=2.0, inertia=2.0 * 0.7 ** 2 / 12, center_of_mass=(0.35, 0.0),
                     outboard={"p0": (0.0, 0.0), "p1": (0.7, 0.0)})
    tree = PlanarModel("floating", [
        FreeBase("fb", child="b"), base,
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="b.p0", child="crank"),
        RigidBody.uniform_link("coupler", mass=1.0, length=0.6), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="b.p1", child="rocker")],
        gravity=(0.0, 0.0))
    loop = KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out")])
    q, _ = loop.consistent_state([0.0, 0.0, 0.0, 1.57, 0.5, 1.8], np.zeros(6), keep=["crank.theta"])
    rest = (q, np.zeros(6))
    assert np.array_equal(ctmm.natural_frequencies(tree, n_modes=6, operating_point=rest), np.zeros(6))
    assert np.array_equal(ctmm.natural_frequencies(loop, operating_point=rest), np.zeros(4))
    modes = ctmm.mode_shapes(loop, n_modes=4, operating_point=rest)
    assert np.array_equal(modes.natural_frequencies, np.zeros(4)) and modes.shapes.shape == (4, 6, 1)
