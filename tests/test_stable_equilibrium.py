"""The planar static-equilibrium search with ``stable=True`` (and the default operating point of the
linear verbs) ends on a statically stable equilibrium even from guesses near balanced-upright ones.

Closed form (independent of the sweep): two uniform links (mass m, length L) on smooth hinges, the
first pinned, gravity g along -y.  Equilibria are each link straight down or up (absolute angles
-pi/2 or +pi/2); only both down is stable.  About it, in absolute angles, the linearised equations are
M theta'' + K theta = 0 with M = m L^2 [[4/3, 1/2], [1/2, 1/3]] and K = m g L [[3/2, 0], [0, 1/2]].
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.errors import ModelError
from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.equilibrium import static_equilibrium, unstable_directions

G, MASS, LENGTH = 9.81, 0.8, 0.6
DOWN = -np.pi / 2


def double_pendulum() -> PlanarModel:
    return PlanarModel.chain("double", [Pinned("o"), RigidBody.uniform_link("l1", mass=MASS, length=LENGTH),
                                        SmoothHinge("h"), RigidBody.uniform_link("l2", mass=MASS, length=LENGTH)],
                             gravity=(0.0, -G))


def closed_form_omega() -> np.ndarray:
    mass = MASS * LENGTH ** 2 * np.array([[4 / 3, 1 / 2], [1 / 2, 1 / 3]])
    stiffness = MASS * G * LENGTH * np.diag([3 / 2, 1 / 2])
    return np.sqrt(np.sort(scipy.linalg.eigh(stiffness, mass, eigvals_only=True)))


@pytest.mark.parametrize("guess", [(np.pi / 2 - 0.01, np.pi / 2 + 0.02), (DOWN + 0.02, np.pi / 2 - 0.03),
                                   (np.pi / 2 + 0.01, DOWN - 0.01), (0.0, 0.0)])
def test_stable_search_from_near_inverted_guesses_ends_hanging(guess):
    model = double_pendulum()
    nearest = static_equilibrium(model, guess)
    if np.max(np.abs(np.asarray(guess) - DOWN)) > 1.0:    # the plain search keeps the nearby unstable root
        assert unstable_directions(model, nearest)[0].size >= 1
    q = static_equilibrium(model, guess, stable=True)
    np.testing.assert_allclose(q, [DOWN, DOWN], atol=1e-9)
    assert unstable_directions(model, q)[0].size == 0


def test_unstable_directions_of_the_inverted_double_pendulum_are_the_closed_form():
    model = double_pendulum()
    values, vectors = unstable_directions(model, [np.pi / 2, np.pi / 2])
    # upright: K changes sign, so omega^2 = -(the hanging omega^2 with g -> -g): both directions unstable
    mass = MASS * LENGTH ** 2 * np.array([[4 / 3, 1 / 2], [1 / 2, 1 / 3]])
    stiffness = -MASS * G * LENGTH * np.diag([3 / 2, 1 / 2])
    expected = np.sort(scipy.linalg.eigh(stiffness, mass, eigvals_only=True))
    np.testing.assert_allclose(values, expected, rtol=1e-6)
    assert vectors.shape == (2, 2)


def test_default_operating_point_natural_frequencies_equal_the_closed_form():
    omega = ctmm.natural_frequencies(double_pendulum(), n_modes=2)
    np.testing.assert_allclose(omega, closed_form_omega(), rtol=1e-9)


def test_a_single_link_from_just_off_upright_ends_hanging_and_an_unfinished_search_is_refused(monkeypatch):
    model = PlanarModel.chain("one", [Pinned("o"), RigidBody.uniform_link("l", mass=MASS, length=LENGTH)],
                              gravity=(0.0, -G))
    np.testing.assert_allclose(static_equilibrium(model, [np.pi / 2 - 1e-3], stable=True), [DOWN], atol=1e-9)
    np.testing.assert_allclose(static_equilibrium(model, [np.pi / 2 - 1e-3]), [np.pi / 2], atol=1e-9)
    monkeypatch.setattr("ctmm.planar.equilibrium.STABLE_RESTARTS", 0)       # no descent allowed: refused, named
    with pytest.raises(ModelError, match=r"no statically stable equilibrium of 'one'.*omega\^2 = -24\.5.*l\.theta"):
        static_equilibrium(model, [np.pi / 2 - 1e-3], stable=True)
