"""A particle-spring subsystem between two rigid bodies (seed 001 Figs. 9.8-9.9, scenario particle_chain): the
subsystem's outboard boundary particle carries the next body; against ctmm.reference.mixed_global (ParticleNet with
linear springs and an outboard particle)."""
from __future__ import annotations

import json

import numpy as np
import pytest

import ctmm
from ctmm.planar.sweep import accelerations
from ctmm.scenarios import particle_chain


def test_accelerations_and_energy_equal_the_global_model():
    model, reference = particle_chain.model(), particle_chain.reference()
    assert model.coordinates[0] == "body2.theta" and model.coordinates[-1] == "body6.theta"
    assert reference.n == model.n_coordinates
    rng = np.random.default_rng(3)
    for scale in (1e-3, 3e-2):
        q, v = rng.normal(size=model.n_coordinates), rng.normal(size=model.n_coordinates)
        q[1:-1] *= scale
        a, a_ref = accelerations(model, q, v, 0.0), reference.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) <= 1e-11 * np.max(np.abs(a_ref))
        assert model.energy(q, v) == pytest.approx(reference.energy(q, v), rel=1e-12)


def test_natural_frequencies_equal_eigh_of_the_global_linearisation():
    model, reference = particle_chain.model(), particle_chain.reference()
    q_rest = np.zeros(reference.n)
    q_rest[[0, -1]] = -np.pi / 2
    q_rest = reference.equilibrium(q_rest)
    hanging = (q_rest, np.zeros(reference.n))
    omega = ctmm.natural_frequencies(model, n_modes=6, operating_point=hanging)
    assert omega == pytest.approx(reference.natural_frequencies(q_rest)[:6], rel=1e-9)
    # the default operating point is the stable equilibrium (the plain root search finds body 6 inverted)
    assert ctmm.natural_frequencies(model, n_modes=6) == pytest.approx(omega, rel=1e-9)


def test_particle_chain_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("particle_chain")
    json.dumps(summary)
    assert (tmp_path / "particle_chain.png").stat().st_size > 1000
    (figure,) = summary["accuracy"]
    assert figure["passed"] and figure["value"] < 1e-12
    assert summary["energy_drift_relative"] < 1e-9
    assert summary["energy_vs_global_model_relative"] < 1e-12
    assert 1e-4 < summary["largest_particle_displacement_m"] < 0.05
