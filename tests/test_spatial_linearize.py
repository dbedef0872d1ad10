"""``ctmm.linearize`` of spatial models against the independent global Newton-Euler reference
(``ctmm/reference/spatial_tree.py``: ``M``, ``C``, ``K`` by complex step of the global equations, sharing no
TMM code).  The conversion of a ``SpatialModel`` to the reference's plain description is test code
(``tests/spatial_linear_helpers.py``).

The two models state the same joint laws to first order about an undeflected joint; spherical and
elastic-hinge springs differ beyond that (ctmm ``2 w (x, y, z) = sin(angle) axis`` and ``R^T t``, the
reference the rotation vector and joint-axes forces), so spring-loaded rotations are tested where
they are not deflected at the equilibrium; 1- and 2-DOF springs are deflected by gravity.

Tolerance: 1e-10 relative to the largest entry (both sides exact to round-off).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.signals import Harmonic
from ctmm.errors import ModelError
from ctmm.ops import NUMPY
from ctmm.spatial_linearization import retract, static_equilibrium, tangent_names
from spatial_linear_helpers import elastic_hinge_body, random_spring_tree, reference_blocks

TOLERANCE = 1e-10


def assert_blocks_match(model: sp.SpatialModel, lin) -> None:
    n = model.n_velocities
    A = np.asarray(lin.state_space.A)
    Kq, Cv = reference_blocks(model, lin.operating_point.q)
    scale = max(np.max(np.abs(Kq)), np.max(np.abs(Cv)), 1e-300)
    np.testing.assert_array_equal(A[:n, :n], 0.0)
    np.testing.assert_array_equal(A[:n, n:], np.eye(n))
    assert np.max(np.abs(A[n:, :n] - Kq)) <= TOLERANCE * scale, np.max(np.abs(A[n:, :n] - Kq)) / scale
    assert np.max(np.abs(A[n:, n:] - Cv)) <= TOLERANCE * scale, np.max(np.abs(A[n:, n:] - Cv)) / scale


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_sprung_trees_about_their_equilibria_match_the_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = random_spring_tree(rng, 7, "revolute" if seed != 2 else "universal")
    lin = ctmm.linearize(model)
    op = lin.operating_point
    assert op.equilibrium and op.jacobian_error < 1e-8
    assert np.max(np.abs(sp.accelerations(model, op.q, op.qdot))) < 1e-9
    assert not np.allclose(op.q, model.neutral(), atol=1e-3)          # the springs are deflected
    assert_blocks_match(model, lin)
    names = tangent_names(model)
    assert list(lin.state_space.state_labels[:len(names)]) == [n.replace(".", "_") for n in names]


def test_hanging_spherical_pendulum_has_two_equal_pendulum_frequencies() -> None:
    length, mass = 0.8, 1.5
    inertia = np.diag([0.02, 0.03, 0.01])
    model = sp.SpatialModel("pendulum", [
        sp.SpatialBody("bob", mass, inertia, center_of_mass=(0.0, 0.0, -length)),
        sp.Spherical(name="ball", parent=None, child="bob", actuated=True)], gravity=(0, 0, -9.81))
    lin = ctmm.linearize(model)
    assert_blocks_match(model, lin)
    np.testing.assert_allclose(lin.operating_point.q, [1, 0, 0, 0], atol=1e-14)
    A = np.asarray(lin.state_space.A)
    omega2 = np.sort(-np.linalg.eigvals(A[3:, :3]).real)
    # by hand: about x and y, (I_xx + m l^2) theta'' + m g l theta = 0; about z, no restoring moment
    expected = sorted([0.0, mass * 9.81 * length / (0.02 + mass * length ** 2),
                       mass * 9.81 * length / (0.03 + mass * length ** 2)])
    np.testing.assert_allclose(omega2, expected, rtol=1e-12, atol=1e-12)
    # B: a unit torque about the child x axis accelerates r_x by 1 / (I_xx + m l^2)
    B = np.asarray(lin.state_space.B)
    assert list(lin.state_space.input_labels) == ["ball_torque_x", "ball_torque_y", "ball_torque_z"]
    np.testing.assert_allclose(B[3:, 0], [1.0 / (0.02 + mass * length ** 2), 0.0, 0.0], rtol=1e-13, atol=1e-15)


def test_elastic_hinge_body_matches_the_reference_and_sags_by_mg_over_k() -> None:
    model = elastic_hinge_body()
    lin = ctmm.linearize(model)
    np.testing.assert_allclose(lin.operating_point.q[:3], [0, 0, -4.0 * 9.81 / 2.0e4], rtol=1e-10, atol=1e-17)
    assert_blocks_match(model, lin)
    assert len(lin.state_space.input_labels) == 6


def test_given_operating_point_and_refusals() -> None:
    model = elastic_hinge_body(gravity=(0.0, 0.0, 0.0))
    lin = ctmm.linearize(model, (model.neutral(), np.zeros(6)), inputs=["hinge.wrench_mz"],
                         outputs=["hinge.rz", "hinge.wz"])
    assert_blocks_match(model, lin)
    assert lin.state_space.B.shape == (12, 1)
    with pytest.raises(ModelError, match="not an equilibrium"):
        ctmm.linearize(elastic_hinge_body(), (model.neutral(), np.zeros(6)))
    with pytest.raises(ModelError, match="unknown|Unknown"):
        ctmm.linearize(model, None, outputs=["hinge.nope"])
    falling = sp.SpatialModel("falling", [sp.SpatialBody("b", 1.0, (0.1, 0.1, 0.1)),
                                          sp.Free(name="base", parent=None, child="b")])
    with pytest.raises(ModelError, match="free joint.*gravity"):
        ctmm.linearize(falling)
    pushed = sp.SpatialModel("pushed", [sp.SpatialBody("b", 1.0, (0.1, 0.1, 0.1), points={"tip": (1, 0, 0)}),
                                        sp.Revolute(name="hinge", parent=None, child="b", axis=(0, 0, 1)),
                                        sp.Load("twist", "b", "tip", moment=(0.0, 0.0, 1.0))], gravity=(0, 0, 0))
    with pytest.raises(ModelError, match="no static equilibrium"):
        ctmm.linearize(pushed)
    shaken = sp.SpatialModel("shaken", [sp.SpatialBody("b", 1.0, (0.1, 0.1, 0.1), points={"tip": (1, 0, 0)}),
                                        sp.Revolute(name="hinge", parent=None, child="b", axis=(0, 0, 1), stiffness=5.0),
                                        sp.Load("shake", "b", "tip", force=(0.0, Harmonic(1.0, 3.0), 0.0))],
                            gravity=(0, 0, 0))
    with pytest.raises(ModelError, match="not an equilibrium"):         # at rest at t = 0 only
        ctmm.linearize(shaken, outputs=["hinge.angle", "hinge.angle_rate"])


def test_free_body_in_zero_gravity_is_a_double_integrator_in_its_own_axes() -> None:
    """About a turned pose, a force along the body's x axis moves the body along its x axis as
    1 / (m s^2): the sensed world position ``"base.x|y"`` (a port, not the tangent coordinate of that
    name) by the first column of the rotation ``R0``; a moment about a principal axis turns r_x as
    1 / (I_xx s^2)."""
    model = sp.SpatialModel("floating", [sp.SpatialBody("b", 3.0, (0.2, 0.3, 0.4)),
                                         sp.Free(name="base", parent=None, child="b", actuated=True)],
                            gravity=(0, 0, 0))
    turned = np.r_[0.3, -0.2, 1.0, np.cos(0.6), np.sin(0.6) * np.array([1.0, 2.0, 2.0]) / 3.0]
    omega = np.array([0.5, 2.0])
    frf = ctmm.frequency_response(model, omega, input=["base.wrench_fx", "base.wrench_mx"],
                                  output=["base.x", "base.y", "base.rx"], operating_point=(turned, np.zeros(6)))
    expected = np.zeros((3, 2, 2), dtype=complex)
    w, axis = turned[3], turned[4:]
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rotation = np.eye(3) + 2.0 * w * cross + 2.0 * cross @ cross            # R0 of the unit quaternion
    expected[0, 0] = -rotation[0, 0] / (3.0 * omega ** 2)
    expected[1, 0] = -rotation[1, 0] / (3.0 * omega ** 2)
    expected[2, 1] = -1.0 / (0.2 * omega ** 2)
    np.testing.assert_allclose(frf.response, expected, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(ctmm.natural_frequencies(model, n_modes=6), np.zeros(6))


def test_retraction_is_the_exponential_of_the_tangent() -> None:
    model = elastic_hinge_body()
    rng = np.random.default_rng(5)
    delta = rng.normal(size=6) * 0.7
    q = retract(model, model.neutral(), delta)[0]
    angle = np.linalg.norm(delta[3:])
    np.testing.assert_allclose(q[3:], np.r_[np.cos(angle / 2), np.sin(angle / 2) * delta[3:] / angle], rtol=1e-14)
    np.testing.assert_allclose(q[:3], delta[:3], rtol=1e-14)
    assert np.allclose(static_equilibrium(elastic_hinge_body(gravity=(0, 0, 0))), model.neutral())


def test_a_pendulum_starting_horizontal_falls_to_its_hanging_equilibrium() -> None:
    """Newton's Jacobian is singular at the horizontal start (the gravity moment is extremal there):
    the pseudo-transient steps fall to the hanging, stable equilibrium (not the upright one)."""
    model = sp.SpatialModel("arm", [
        sp.SpatialBody("base", 2.0, (0.02, 0.02, 0.01), center_of_mass=(0, 0, 0.1), points={"top": (0, 0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.01, 0.01, 0.002), center_of_mass=(0.25, 0, 0)),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.Spherical(name="ball", parent="base", point="top", child="link")], gravity=(0, 0, -9.81))
    lin = ctmm.linearize(model)
    q = lin.operating_point.q
    R = sp.SpatialScene(model).terms(NUMPY, q[None], np.zeros((1, 4)))[2][1].rotation[0]
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-9)     # the link's x axis hangs down
    assert_blocks_match(model, lin)
