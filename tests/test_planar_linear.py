"""Linear planar MSTMM about an equilibrium vs the linearised Lagrange model."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.planar import Fixed, Pinned, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge
from ctmm.planar.linear import (characteristic_function, hanging_configuration, natural_frequencies,
                                static_equilibrium)
from ctmm.reference.planar_lagrange import PlanarLagrange

from planar_helpers import random_tree, uniform_chain
from planar_linear_elements import LinearRigidBody, linear_chain


def _offset_chain():
    """Hanging chain with offset centres of mass and bent links (non-trivial preload)."""
    return PlanarModel.chain("offset", [
        Pinned("o"),
        RigidBody("a", mass=1.0, inertia=0.08, center_of_mass=(0.5, 0.05), outboard=(1.0, 0.0)),
        SmoothHinge("h2"),
        RigidBody("b", mass=0.7, inertia=0.05, center_of_mass=(0.4, 0.0), outboard=(0.8, 0.1)),
        SmoothHinge("h3"),
        RigidBody("c", mass=0.5, inertia=0.03, center_of_mass=(0.35, -0.02), outboard=(0.6, 0.0))])


@pytest.mark.parametrize("make", [lambda: uniform_chain(4), _offset_chain, lambda: uniform_chain(12)],
                         ids=["uniform4", "offset3", "uniform12"])
def test_hanging_chain_frequencies_equal_linearised_lagrange(make):
    model = make()
    q_eq = static_equilibrium(model, np.full(model.n_coordinates, -1.5))
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    got = natural_frequencies(model, q_eq, n_modes=model.n_coordinates)
    np.testing.assert_allclose(got, expected, rtol=1e-10)
    # the lead's Chain with the planar linear elements: Delta vanishes at the same frequencies
    chain = linear_chain(model, q_eq)
    at_roots = np.abs(ctmm.frequency.characteristic_function(chain, 1j * expected))
    nearby = np.abs(ctmm.frequency.characteristic_function(chain, 1j * expected * 1.001))
    assert np.all(at_roots < 1e-7 * nearby)


def test_spring_held_tree_frequencies():
    """Tree held by hinge springs against gravity (bent equilibrium, preloads everywhere)."""
    from ctmm.planar.elements import ElasticHinge as EH
    from ctmm.planar import Fixed as Ground
    bodies = [RigidBody("trunk", mass=2.0, inertia=0.2, center_of_mass=(0.5, 0.1),
                        outboard={"left": (1.0, 0.2), "right": (0.9, -0.3)}),
              RigidBody("l1", mass=0.8, inertia=0.05, center_of_mass=(0.3, 0.0), outboard=(0.6, 0.0)),
              RigidBody("r1", mass=0.6, inertia=0.04, center_of_mass=(0.25, 0.05), outboard=(0.5, 0.0)),
              RigidBody("l2", mass=0.4, inertia=0.02, center_of_mass=(0.2, 0.0))]
    model = PlanarModel("tree", bodies + [
        Ground("g"), EH("k0", parent="g", child="trunk", stiffness=200.0, rest_angle=1.2),
        EH("k1", parent="trunk.left", child="l1", stiffness=40.0, rest_angle=0.5),
        EH("k2", parent="trunk.right", child="r1", stiffness=30.0, rest_angle=-0.6),
        EH("k3", parent="l1", child="l2", stiffness=10.0, rest_angle=0.3)])
    q_eq = static_equilibrium(model, [1.2, 1.7, 0.6, 2.0])
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    np.testing.assert_allclose(natural_frequencies(model, q_eq, n_modes=4), expected, rtol=1e-10)


def test_damped_frf_equals_lagrange():
    model = PlanarModel.chain("mixed", [
        Fixed("g"), SpringDamperHinge("k0", stiffness=60.0, damping=0.4, rest_angle=-1.2),
        RigidBody.uniform_link("a", mass=1.0, length=1.0),
        SpringDamperHinge("k1", stiffness=25.0, damping=0.2, rest_angle=0.3),
        RigidBody("b", mass=0.7, inertia=0.05, center_of_mass=(0.4, 0.05), outboard=(0.8, 0.0)),
        SmoothHinge("h2"), RigidBody.uniform_link("c", mass=0.5, length=0.6)])
    q_eq = static_equilibrium(model, [-1.3, -1.2, -1.5])
    chain = linear_chain(model, q_eq)
    omega = np.array([0.3, 2.0, 5.5, 11.0])
    frf = ctmm.frequency_response(chain, omega, input=["b.force_x", "k1.torque"],
                                  output=["a.theta", "b.theta", "c.theta"])
    lag = PlanarLagrange(model)
    M, C, K = lag.linearize(q_eq)
    kin = lag.kinematics(q_eq, np.zeros(3), 0.0)
    B_force = kin["j_c"][1][0]                       # x-force at b's centre of mass
    B_torque = np.array([-1.0, 1.0, 0.0])            # hinge torque on b, reaction on a
    for name, B in (("b.force_x", B_force), ("k1.torque", B_torque)):
        H = np.array([np.linalg.solve(K + 1j * w * C - w * w * M, B) for w in omega])
        for i, out in enumerate(["a.theta", "b.theta", "c.theta"]):
            np.testing.assert_allclose(frf(out, name), H[:, i], rtol=1e-10, atol=1e-14)


def test_geometric_stiffness_is_what_makes_a_pendulum_swing():
    """Without the static-preload terms a hanging pendulum has no restoring stiffness."""
    model = uniform_chain(1, length=2.0)
    q_eq = np.array([-np.pi / 2])
    expected = np.sqrt(3 * 9.81 / (2 * 2.0))          # compound pendulum sqrt(m g d / J_O)
    assert natural_frequencies(model, q_eq, n_modes=1)[0] == pytest.approx(expected, rel=1e-12)
    bare = LinearRigidBody("rod", mass=1.0, inertia=1 / 3, center_of_mass=(0, -1.0),
                           outboard=(0, -2.0))
    assert bare.geometric_stiffness == 0.0
    loaded = linear_chain(model, q_eq).element("link0").body
    # G = r_IC . f_I0 = (0, -1) . (0, m g): the preload term of the moment row
    assert loaded.geometric_stiffness == pytest.approx(-9.81 * 1.0, rel=1e-12)


def test_element_shapes_and_vectorisation():
    body = LinearRigidBody("b", mass=1.0, inertia=0.1, center_of_mass=(0.3, 0.1), outboard=(1, 0),
                           inboard_force=(0.0, 5.0), outboard_force=(0.0, 2.0))
    s = 1j * np.linspace(0.1, 10.0, 12).reshape(3, 4)
    U = body.transfer_matrix(s)
    assert U.shape == (3, 4, 6, 6)
    np.testing.assert_allclose(U[1, 2], body.transfer_matrix(s[1, 2]))
    assert body.transfer_matrix(0.5j).shape == (6, 6)


def test_linear_errors():
    model = uniform_chain(2)
    with pytest.raises(ModelError, match="not an equilibrium"):
        natural_frequencies(model, [0.0, 0.0], n_modes=1)
    with pytest.raises(ModelError, match="mass must be > 0"):
        LinearRigidBody("b", mass=0.0, inertia=1.0, center_of_mass=(0, 0), outboard=(1, 0))
    damped = random_tree(1, 3, chain=True, base="fixed", allow_driven=False,
                         allow_translation=False)
    if np.any(damped.damping > 0):
        with pytest.raises(ModelError, match="undamped"):
            natural_frequencies(damped, np.zeros(damped.n_coordinates), n_modes=1)


def test_tree_characteristic_function_vanishes_at_the_frequencies():
    model = uniform_chain(3)
    q_eq = np.full(3, -np.pi / 2)
    omega = natural_frequencies(model, q_eq, n_modes=3)
    at = np.abs(characteristic_function(model, q_eq, 1j * omega))
    near = np.abs(characteristic_function(model, q_eq, 1j * omega * 1.001))
    assert np.all(at < 1e-8 * near)


def test_a_hub_hangs_by_the_beam_it_carries():
    """A hub with its centre of mass on the pivot carrying a welded beam: the guess hangs the beam, and
    the equilibrium found from it is the hanging one (not the upright one)."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
    from ctmm.planar.elements import FixedMounting

    model = PlanarModel.chain("hub_beam", [
        Fixed("ground"), ActuatedHinge("motor"), RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
        FixedMounting("mount"), ModalBeam("beam", length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=2)])
    guess = hanging_configuration(model)
    assert guess[model.coordinate_index("hub.theta")] == pytest.approx(-0.5 * np.pi, abs=1e-15)
    q = static_equilibrium(model, guess)
    assert q[model.coordinate_index("hub.theta")] == pytest.approx(-0.5 * np.pi, abs=1e-12)
