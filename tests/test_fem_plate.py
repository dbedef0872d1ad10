"""A plane-stress plate (MembraneElement quads) welded to a rigid chain (seed 001 Example 9.2, scenario plate_chain)
against the global Lagrange model of ctmm.reference.mixed_global.MembranePlate (own interpolation and quadrature)."""
from __future__ import annotations

import json

import numpy as np
import pytest

import ctmm
from ctmm.planar.sweep import accelerations
from ctmm.scenarios import plate_chain


def test_accelerations_and_energy_equal_the_global_model_at_deformed_states():
    model, reference = plate_chain.model(), plate_chain.reference()
    order = plate_chain.reference_columns(model.coordinates)
    assert sorted(order) == list(range(model.n_coordinates)) and reference.n == model.n_coordinates
    rng = np.random.default_rng(5)
    for scale in (1e-4, 1e-2):                                   # plate node displacements [m]
        q, v = np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)
        q_ref, v_ref = rng.normal(size=reference.n), rng.normal(size=reference.n)
        q_ref[4:] *= scale
        q[order], v[order] = q_ref, v_ref
        a = accelerations(model, q, v, 0.0)
        a_ref = reference.accelerations(q_ref, v_ref)
        assert np.max(np.abs(a[order] - a_ref)) <= 1e-10 * np.max(np.abs(a_ref))
        assert model.energy(q, v) == pytest.approx(reference.energy(q_ref, v_ref), rel=1e-12)


def test_natural_frequencies_equal_eigh_of_the_global_linearisation():
    model, reference = plate_chain.model(), plate_chain.reference()
    q_rest = np.zeros(reference.n)
    q_rest[:4] = -np.pi / 2
    q_rest = reference.equilibrium(q_rest)
    expected = reference.natural_frequencies(q_rest)[:6]
    assert ctmm.natural_frequencies(model, n_modes=6) == pytest.approx(expected, rel=1e-9)


def test_plate_chain_scenario_quick(quick_scenario):
    summary, tmp_path = quick_scenario("plate_chain")
    json.dumps(summary)
    assert (tmp_path / "plate_chain.png").stat().st_size > 1000
    (figure,) = summary["accuracy"]
    assert figure["passed"] and figure["value"] < 1e-12
    assert summary["energy_drift_relative"] < 1e-8                 # undamped: RK4 error only (quick: 0.01 s)
    assert summary["energy_vs_global_model_relative"] < 1e-12
    assert 1e-5 < summary["largest_node_displacement_m"] < 0.05
