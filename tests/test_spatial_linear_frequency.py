"""Natural frequencies, mode shapes, eigenvalue counts and FRFs of spatial models against the
independent global reference (``ctmm/reference/spatial_tree.py``: ``M``, ``C``, ``K`` of the global
Newton-Euler equations), including repeated frequencies of symmetric bodies.

Tolerances: squared frequencies 1e-9 relative to the largest (eigenvalues of matrices equal to ~1e-12);
FRFs 1e-9 relative to the largest entry.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from spatial_linear_helpers import elastic_hinge_body, random_spring_tree, reference_matrices


def reference_squares(model: sp.SpatialModel, q0: np.ndarray) -> np.ndarray:
    """``omega^2`` [rad^2/s^2] ascending: ``eig(K, M)`` of the reference."""
    mass, _, stiffness = reference_matrices(model, q0)
    return scipy.linalg.eigh(0.5 * (stiffness + stiffness.T), mass, eigvals_only=True)


def reference_frequencies(model: sp.SpatialModel, q0: np.ndarray) -> np.ndarray:
    """Natural frequencies [rad/s] of the reference, rigid-body modes (``|omega^2|`` at round-off) as 0."""
    squares = reference_squares(model, q0)
    return np.sqrt(np.where(squares <= 1e-12 * squares[-1], 0.0, squares))


def symmetric_pendulum() -> sp.SpatialModel:
    """A body symmetric about its hanging axis on a smooth ball joint: two equal pendulum frequencies
    and a free yaw (0 rad/s)."""
    return sp.SpatialModel("pendulum", [
        sp.SpatialBody("bob", 2.0, (0.04, 0.04, 0.01), center_of_mass=(0.0, 0.0, -0.6)),
        sp.Spherical(name="ball", parent=None, child="bob", actuated=True)], gravity=(0, 0, -9.81))


def isotropic_hinge_body() -> sp.SpatialModel:
    """A sphere-like body on an isotropic 6-DOF elastic hinge in zero gravity: a triple translational
    and a triple rotational frequency."""
    stiffness = np.diag([900.0] * 3 + [4.0] * 3)
    return sp.SpatialModel("ball", [
        sp.SpatialBody("body", 1.0, (0.01, 0.01, 0.01)),
        sp.Elastic6(name="hinge", parent=None, child="body", stiffness=stiffness, actuated=True)], gravity=(0, 0, 0))


@pytest.mark.parametrize("seed", [4, 6])
def test_random_undamped_trees_have_the_reference_frequencies(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = random_spring_tree(rng, 6, "revolute", damped=False)         # ball joints: a free yaw (0 rad/s)
    lin = ctmm.linearize(model)
    squares = reference_squares(model, lin.operating_point.q)
    expected = np.sqrt(np.maximum(squares, 0.0))
    omega = ctmm.natural_frequencies(model, n_modes=model.n_velocities)
    assert np.max(np.abs(omega ** 2 - squares)) <= 1e-9 * squares[-1]     # (a zero's square root amplifies round-off)
    below = ctmm.natural_frequencies(model, omega_max=0.5 * (expected[2] + expected[3]))
    np.testing.assert_allclose(below, omega[:3], rtol=0, atol=1e-12 * expected[-1])
    # shapes: K phi = omega^2 M phi of the reference
    mass, _, stiffness = reference_matrices(model, lin.operating_point.q)
    modes = ctmm.mode_shapes(model, n_modes=model.n_velocities)
    for w, shape in zip(modes.natural_frequencies, modes.shapes[:, :, 0]):
        residual = stiffness @ shape - w * w * (mass @ shape)
        assert np.max(np.abs(residual)) <= 1e-9 * np.max(np.abs(stiffness))
    assert modes.point_names == ctmm.spatial_linearization.tangent_names(model)


@pytest.mark.parametrize("build, multiplicities", [(symmetric_pendulum, (1, 2)), (isotropic_hinge_body, (3, 3))])
def test_repeated_frequencies_of_symmetric_bodies_are_counted(build, multiplicities) -> None:
    model = build()
    q0 = ctmm.linearize(model).operating_point.q
    squares = reference_squares(model, q0)
    expected = reference_frequencies(model, q0)
    omega = ctmm.natural_frequencies(model, n_modes=model.n_velocities)
    assert np.max(np.abs(omega ** 2 - squares)) <= 1e-9 * squares[-1]
    distinct = np.unique(np.round(expected / expected[-1], 9)) * expected[-1]
    assert tuple(int(np.sum(np.isclose(expected, w, rtol=1e-9))) for w in distinct) == multiplicities
    trial = np.sort(np.concatenate([distinct * (1 - 1e-7), distinct * (1 + 1e-7), [0.0, 2 * expected[-1]]]))
    counts = ctmm.eigenvalue_count(model, trial)
    np.testing.assert_array_equal(counts, np.sum(expected[None, :] < trial[:, None], axis=1))


def test_frequency_response_is_the_reference_dynamic_stiffness_inverse() -> None:
    rng = np.random.default_rng(11)
    model = random_spring_tree(rng, 5, "universal")
    lin = ctmm.linearize(model)
    mass, damping, stiffness = reference_matrices(model, lin.operating_point.q)
    names = ctmm.spatial_linearization.tangent_names(model)
    inputs = list(ctmm.spatial_linearization.input_names(model))
    assert inputs[:2] == ["j0.torque_1", "j0.torque_2"]
    omega = np.array([0.05, 0.7, 3.0, 12.0])
    frf = ctmm.frequency_response(model, omega, input=inputs, output=list(names))
    # an actuator input is the generalised force of its joint's velocities (components in order)
    rows = [layout.velocity.start + i for joint, layout in zip(model.joints, model.layout) if joint.inputs
            for i in range(joint.velocity_count)]
    forcing = np.zeros((model.n_velocities, len(inputs)))
    forcing[rows, np.arange(len(inputs))] = 1.0
    for j, w in enumerate(omega):
        expected = np.linalg.solve(stiffness + 1j * w * damping - w * w * mass, forcing)
        got = frf.response[:, :, j]
        assert np.max(np.abs(got - expected)) <= 1e-9 * np.max(np.abs(expected))
    with pytest.raises(ModelError, match="singular at omega = 0.0"):      # the free yaw of a ball joint
        ctmm.frequency_response(model, [0.0, 1.0], input=inputs[0], output=names[0])


def test_damped_unstable_and_wrong_options_are_refused() -> None:
    with pytest.raises(ModelError, match="undamped"):
        ctmm.natural_frequencies(elastic_hinge_body(), n_modes=2)
    inverted = sp.SpatialModel("inverted", [
        sp.SpatialBody("bob", 1.0, (0.01, 0.01, 0.01), center_of_mass=(0.0, 0.0, 0.5)),
        sp.Spherical(name="ball", parent=None, child="bob")], gravity=(0, 0, -9.81))
    with pytest.raises(ModelError, match="statically unstable"):     # upright, asked for explicitly
        ctmm.natural_frequencies(inverted, n_modes=1, operating_point=(inverted.neutral(), np.zeros(3)))
    hanging = ctmm.natural_frequencies(inverted, n_modes=3)           # the default: the stable (hanging) one
    swing = np.sqrt(9.81 * 0.5 / (0.25 + 0.01))                        # m g c / (m c^2 + I), and the free yaw
    assert np.allclose(hanging, [0.0, swing, swing], rtol=1e-9, atol=1e-9)
    with pytest.raises(ModelError, match="ball.rx' has no exact-field counterpart"):   # (hanging: gravity is taken)
        ctmm.frequency_response(symmetric_pendulum(), [1.0], input="ball.torque_x", output="ball.rx",
                                fields="exact")
    with pytest.raises(ModelError, match="n_modes"):
        ctmm.natural_frequencies(symmetric_pendulum(), n_modes=4)


def test_count_below_the_lowest_mode_is_the_rigid_body_modes() -> None:
    """The arm of docs/spatial.md §9 has two rigid-body modes (a free yaw, the hanging link's spin about the
    vertical) and the link's swing at 5.82 rad/s: nothing lies strictly below omega = 0 and exactly those two
    lie below any small omega > 0 (the planar and chain counts agree).  The Sylvester count read the sign of the
    round-off of K along them: 2 at omega = 0, 1 at 1e-9 rad/s."""
    arm = sp.SpatialModel("arm", [
        sp.SpatialBody("base", 2.0, (0.02, 0.02, 0.01), center_of_mass=(0, 0, 0.1), points={"top": (0, 0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.01, 0.01, 0.002), center_of_mass=(0.25, 0, 0), points={"tip": (0.5, 0, 0)}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.Spherical(name="ball", parent="base", point="top", child="link")], gravity=(0, 0, -9.81))
    swing = np.sqrt(1.0 * 9.81 * 0.25 / (0.01 + 1.0 * 0.25 ** 2))        # the link's swing, m g l / (I + m l^2)
    counts = ctmm.eigenvalue_count(arm, [0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1.0, 0.5 * swing])
    np.testing.assert_array_equal(counts, [0, 2, 2, 2, 2, 2, 2])
