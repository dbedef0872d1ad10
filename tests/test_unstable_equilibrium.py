"""natural_frequencies / mode_shapes / eigenvalue_count about an unstable equilibrium: refused with a ModelError
naming the unstable directions and their omega^2 < 0 (imaginary roots), advising a stable operating point.

Closed form: a uniform link (mass m, length L) pinned at one end and held upright under gravity g has the
linearised equation (m L^2 / 3) theta'' = (m g L / 2) theta, i.e. omega^2 = -3 g / (2 L)."""
from __future__ import annotations

import re

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.planar import Pinned, PlanarModel, RigidBody

G, LENGTH = 9.81, 2.0


def pendulum() -> PlanarModel:
    return PlanarModel.chain("pendulum", [Pinned("o"), RigidBody.uniform_link("link", mass=1.5, length=LENGTH)])


@pytest.mark.parametrize("verb", [ctmm.natural_frequencies, ctmm.mode_shapes])
def test_inverted_pendulum_is_refused_with_its_closed_form_negative_stiffness(verb):
    model = pendulum()
    upright = (np.array([np.pi / 2]), np.zeros(1))
    with pytest.raises(ModelError, match=r"statically unstable.*1 mode\(s\) with negative stiffness.*link\.theta.*operating_point") as caught:
        verb(model, n_modes=1, operating_point=upright)
    omega_squared = float(re.search(r"omega\^2 = (\S+) rad\^2/s\^2", str(caught.value)).group(1))
    assert omega_squared == pytest.approx(-3 * G / (2 * LENGTH), rel=1e-5)
    hanging = (np.array([-np.pi / 2]), np.zeros(1))       # the stable one: omega^2 = +3 g / (2 L)
    assert ctmm.natural_frequencies(model, n_modes=1, operating_point=hanging)[0] == pytest.approx(
        np.sqrt(3 * G / (2 * LENGTH)), rel=1e-12)


def test_particle_chain_from_rest_names_the_inverted_link():
    from ctmm.planar.equilibrium import hanging_configuration, static_equilibrium
    from ctmm.scenarios.particle_chain import model

    plant = model()
    upright = static_equilibrium(plant, hanging_configuration(plant))       # the plain search: body 6 upright
    with pytest.raises(ModelError, match=r"statically unstable.*along \(body6\.theta \+1"):
        ctmm.natural_frequencies(plant, n_modes=3, operating_point=(upright, np.zeros_like(upright)))
    # the default operating point is the stable equilibrium (static_equilibrium(..., stable=True)): body 6 hangs
    assert ctmm.linearize(plant).operating_point.q[-1] == pytest.approx(-np.pi / 2, abs=1e-9)
    assert np.all(ctmm.natural_frequencies(plant, n_modes=3) > 0.0)
