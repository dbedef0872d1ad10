"""The planar static-equilibrium search without waste (:mod:`ctmm.planar.equilibrium`, issue 13).

* a guess that already is an equilibrium (to the search's own certificate, residual <= 1e-8) is returned
  without a root search, and its stability is decided by one stiffness (``2 n + 1`` evaluations in all, where
  ``hybr``'s difference Jacobian and the differences of the stability check took ``3 n + 6``);
* a guess just outside the certificate is still searched (no weaker acceptance);
* the stiffness of the stability check against the independent Lagrange references
  (:class:`ctmm.reference.planar_lagrange.PlanarLagrange` for rigid chains,
  :class:`ctmm.reference.flexible_lagrange.FlexibleLagrange` for modal beams, complex-step path): a standing
  chain has ``n`` directions of negative stiffness, ``omega^2 = eig(M^-1 K)``, and is refused or left;
* the complex-step Jacobian given to the root search finds the same equilibrium as ``hybr``'s differences;
* the root found is polished to round-off (``hybr`` stops on its step and left accelerations of 2e-11 at rest on
  one of these random trees, a linearisation about it off by 1.5e-12), checked with the Lagrange accelerations.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam, ModalForce
from ctmm.planar import ElasticHinge, Fixed, Pinned, PlanarModel, RigidBody, SmoothHinge, accelerations
from ctmm.planar import equilibrium
from ctmm.planar.elements import FixedMounting
from ctmm.planar.equilibrium import (complex_step_applies, hanging_configuration, position_jacobian,
                                     static_equilibrium, unstable_directions)
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from planar_helpers import random_tree

G = 9.81


def chain(n: int) -> PlanarModel:
    elements = [Pinned("o")]
    for k in range(n):
        if k:
            elements.append(SmoothHinge(f"h{k}"))
        elements.append(RigidBody.uniform_link(f"l{k}", mass=1.0 + 0.1 * k, length=0.5 + 0.05 * k))
    return PlanarModel.chain(f"chain{n}", elements, gravity=(0.0, -G))


def hub_beam() -> PlanarModel:
    return PlanarModel.chain("hub_beam", [
        Fixed("g"), ElasticHinge("k", stiffness=40.0),
        RigidBody("hub", mass=2.0, inertia=0.15, center_of_mass=(0.1, 0.02), outboard=(0.25, 0.0)),
        FixedMounting("m", angle=0.2),
        ModalBeam("b", length=1.2, bending_stiffness=8.0, mass_per_length=0.9, n_modes=3),
        ElasticHinge("e", stiffness=3.0), RigidBody.uniform_link("tip", mass=0.3, length=0.4)], gravity=(0.0, -G))


def counting(monkeypatch) -> list[int]:
    calls = [0]
    original = equilibrium.accelerations

    def counted(*args, **kwargs):
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(equilibrium, "accelerations", counted)
    return calls


def test_a_hanging_guess_that_is_the_equilibrium_is_kept_and_checked_with_one_stiffness(monkeypatch):
    model = chain(12)
    guess = hanging_configuration(model)
    calls = counting(monkeypatch)
    q = static_equilibrium(model, guess, stable=True)
    assert np.array_equal(q, guess)
    assert calls[0] == 2 * model.n_coordinates + 1           # the residual at the guess, the central differences


def test_a_guess_just_outside_the_certificate_is_searched():
    model = chain(3)
    guess = hanging_configuration(model) + np.array([0.0, 3e-9, 0.0])
    assert np.max(np.abs(accelerations(model, guess, np.zeros(3)))) > equilibrium.RESIDUAL_TOLERANCE
    q = static_equilibrium(model, guess)
    np.testing.assert_allclose(q, hanging_configuration(model), rtol=0.0, atol=1e-13)
    assert np.max(np.abs(accelerations(model, q, np.zeros(3)))) <= 1e-12


def _lagrange_squares(model: PlanarModel, q: np.ndarray) -> np.ndarray:
    M, _, K = PlanarLagrange(model).linearize(q)
    return np.sort(scipy.linalg.eigvals(K, M).real)


def test_a_standing_chain_has_the_lagrange_negative_stiffness_and_is_left_or_refused(monkeypatch):
    model = chain(4)
    standing = -hanging_configuration(model)                 # every link straight up: an equilibrium
    assert np.max(np.abs(accelerations(model, standing, np.zeros(4)))) <= 1e-12
    values, vectors = unstable_directions(model, standing)
    np.testing.assert_allclose(values, _lagrange_squares(model, standing), rtol=1e-7)
    assert vectors.shape == (4, 4)
    np.testing.assert_allclose(static_equilibrium(model, standing + 1e-3), standing, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(static_equilibrium(model, standing, stable=True), hanging_configuration(model),
                               rtol=0.0, atol=1e-9)
    monkeypatch.setattr(equilibrium, "STABLE_RESTARTS", 0)
    with pytest.raises(ModelError, match=r"no statically stable equilibrium of 'chain4'.*4 direction\(s\) of "
                                         r"negative stiffness"):
        static_equilibrium(model, standing, stable=True)


def test_the_stiffness_of_a_hanging_chain_is_the_lagrange_one():
    model = chain(6)
    q = hanging_configuration(model)
    M, _, K = PlanarLagrange(model).linearize(q)
    np.testing.assert_allclose(position_jacobian(model, q), -np.linalg.solve(M, K), rtol=0.0,
                               atol=1e-8 * np.max(np.abs(np.linalg.solve(M, K))))
    assert unstable_directions(model, q)[0].size == 0


def test_the_complex_step_stiffness_of_a_modal_beam_is_the_flexible_lagrange_one():
    model = hub_beam()
    assert complex_step_applies(model)
    q = static_equilibrium(model, np.zeros(model.n_coordinates))
    reference = FlexibleLagrange(model)
    n, zero = model.n_coordinates, np.zeros(model.n_coordinates)

    def reference_accelerations(x: np.ndarray) -> np.ndarray:
        mass, rhs, *_ = reference._system(x, zero, 0.0)
        return np.linalg.solve(mass, rhs)

    assert np.max(np.abs(reference_accelerations(q))) <= 1e-8
    h = 1e-5
    expected = np.array([(reference_accelerations(q + h * e) - reference_accelerations(q - h * e)) / (2 * h)
                         for e in np.eye(n)]).T
    jacobian = position_jacobian(model, q)
    assert np.array_equal(jacobian, equilibrium.complex_step_jacobian(model, q))      # the cross-check accepted it
    np.testing.assert_allclose(jacobian, expected, rtol=0.0, atol=1e-6 * np.max(np.abs(expected)))


def test_the_complex_step_search_finds_the_equilibrium_of_the_difference_search(monkeypatch):
    model = hub_beam()
    roots = []
    original = equilibrium.scipy.optimize.root

    def recorded(*args, **kwargs):
        roots.append(kwargs.get("jac"))
        return original(*args, **kwargs)

    monkeypatch.setattr(equilibrium.scipy.optimize, "root", recorded)
    with_complex_step = static_equilibrium(model, np.zeros(model.n_coordinates), stable=True)
    assert len(roots) == 1 and roots[0] is not None             # one search, with the complex-step Jacobian
    monkeypatch.setattr(equilibrium, "complex_step_applies", lambda _: False)
    with_differences = static_equilibrium(model, np.zeros(model.n_coordinates), stable=True)
    np.testing.assert_allclose(with_complex_step, with_differences, rtol=0.0, atol=1e-10)
    assert np.max(np.abs(accelerations(model, with_complex_step, np.zeros(model.n_coordinates)))) <= 1e-8


def test_rigid_chains_take_the_differences_and_complex_step_refuses_beam_laws():
    assert not complex_step_applies(chain(2))
    beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=1.0, n_modes=2,
                     modal_forces=[ModalForce(law=lambda t, eta, eta_dot: -0.5 * eta)])
    with_laws = PlanarModel.chain("laws", [Fixed("g"), ElasticHinge("k", stiffness=10.0), beam],
                                  gravity=(0.0, -G))
    assert not complex_step_applies(with_laws)
    with pytest.raises(ModelError, match="user state laws"):
        equilibrium.complex_step_jacobian(with_laws, np.zeros(with_laws.n_coordinates))


@pytest.mark.parametrize("seed", (0, 3, 5, 6, 8))
def test_the_root_found_is_polished_to_round_off(seed):
    model = random_tree(seed, 5, allow_translation=False, allow_driven=False, base="pinned")
    guess = hanging_configuration(model)
    assert np.max(np.abs(accelerations(model, guess, np.zeros(model.n_coordinates)))) > equilibrium.RESIDUAL_TOLERANCE
    q = static_equilibrium(model, guess)
    residual = PlanarLagrange(model).accelerations(q, np.zeros_like(q), 0.0)
    assert np.max(np.abs(residual)) <= 1e-13
