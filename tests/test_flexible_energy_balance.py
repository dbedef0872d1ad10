"""Energy of a modal beam on a linear elastic hinge against the independent Lagrange reference.

Finding checked (issue: "no silent wrong answer"): a ``ModalBeam`` hung on an ``ElasticHinge`` does
not conserve ``model.energy`` with the default ``geometric_stiffening=True``.  The reference's own
energy (mass points, modal strain, hinge spring) equals ``model.energy`` along the run, and the
change of energy equals the work of the first-order stiffening force ``-G(N) q`` computed by the
reference (``docs/flexible.md`` §1.3: the force acts on the modal equations only, its reaction on
the reference motion is neglected, so it is not conservative).  Without stiffening the energy is
conserved to the integrator's tolerance.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.flexible import ModalBeam
from ctmm.planar import ElasticHinge, Fixed, PlanarModel
from ctmm.reference.flexible_lagrange import FlexibleLagrange


def _model(stiffening: bool) -> PlanarModel:
    beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2,
                     geometric_stiffening=stiffening)
    return PlanarModel.chain("hung", [Fixed("g"), ElasticHinge("e", stiffness=4.0, rest_angle=0.1), beam])


def _run(model: PlanarModel):
    q0, v0 = np.array([-1.2, 0.01, -0.002]), np.array([1.0, 0.0, 0.0])
    # 0.05 s: the stiffening already changes the energy by 0.34 J (measured: work - drift 1.6e-8 J with
    # stiffening, drift 1.3e-12 J without); the fine output grid is Simpson's (at twice it: 1.5e-6 J)
    run = ctmm.simulate(model, 0.05, 6.25e-5, method="DOP853", x0=q0, v0=v0, rtol=1e-12, atol=1e-13)
    q = np.column_stack([run[n] for n in model.coordinates])
    v = np.column_stack([run[f"{n}_dot"] for n in model.coordinates])
    return run.time, q, v


@pytest.mark.parametrize("stiffening", [False, True])
def test_energy_changes_by_the_work_of_the_stiffening_force_only(stiffening):
    model = _model(stiffening)
    reference = FlexibleLagrange(model)
    t, q, v = _run(model)
    energy = np.array([model.energy(a, b) for a, b in zip(q, v)])
    independent = np.array([reference.energy(a, b) for a, b in zip(q, v)])
    np.testing.assert_allclose(energy, independent, rtol=0, atol=1e-11 * np.abs(independent).max())
    power = np.array([b @ reference.stiffening_force(a, b) for a, b in zip(q, v)])
    work = scipy.integrate.cumulative_simpson(power, x=t, initial=0.0)
    drift = energy - energy[0]
    np.testing.assert_allclose(drift, work, rtol=0, atol=1e-6)   # Simpson, order 4
    if stiffening:        # the finding: a visible drift, all of it the stiffening work
        assert np.abs(drift).max() > 1e-2
    else:
        assert np.abs(drift).max() < 1e-9
