"""A single long BeamField in the frequency verbs of a chain, against the analytic cantilever.

Finding checked (issue: "no silent wrong answer"): the chain solver used one transfer matrix per
BeamField, whose entries grow like ``cosh beta``; the Riccati transfer then lost ``~ e^beta eps``
(tip receptance of a one-field cantilever: 5e-9 at beta = 17, 61 % at beta = 53, singular-matrix
crashes beyond).  ``frequency_response`` (and ``steady_state_response``, same solve) and ``characteristic_function``
now use the elements' ``subdivide`` hook (exact pieces of ``beta <= 4``); a controlled chain, whose
loop matrices are per element, refuses such an element naming it and the split that fixes it.
References: Bishop & Johnson's receptance and the clamped-free frequency equation
(ctmm.reference.beams), no code shared with the solver.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements.beams import BeamClamped, BeamField, BeamFree, BeamPointLoad
from ctmm.errors import ModelError
from ctmm.reference.beams import beta_roots, cantilever_tip_receptance, omega_from_beta

L, EI, RHOA = 2.0, 3.0, 1.5
OMEGA = np.array([10.0, 100.0, 300.0, 1e3, 2e3, 5e3, 3e4])        # beta = 5.3 ... 291


def _cantilever(*fields) -> ctmm.Chain:
    fields = fields or (BeamField("beam", length=L, bending_stiffness=EI, mass_per_length=RHOA),)
    return ctmm.Chain("cantilever", [BeamClamped("root"), *fields, BeamPointLoad("load"), BeamFree("tip")])


def test_one_long_field_keeps_the_tip_receptance_at_high_beta():
    frf = ctmm.frequency_response(_cantilever(), OMEGA, input="load.force", output=["load.w", "root.shear"])
    exact = cantilever_tip_receptance(OMEGA, L, EI, RHOA)
    np.testing.assert_allclose(frf("load.w", "load.force"), exact, rtol=1e-11)


def test_characteristic_function_changes_sign_at_high_cantilever_roots():
    beta = beta_roots("clamped-free", 40)[[19, 29, 39]]                # beta = 61 ... 124
    omega = omega_from_beta(beta, L, EI, RHOA)
    below = ctmm.frequency.characteristic_function(_cantilever(), 1j * omega * (1 - 1e-8))
    above = ctmm.frequency.characteristic_function(_cantilever(), 1j * omega * (1 + 1e-8))
    assert np.all(np.abs(below.imag) < 1e-9 * np.abs(below)) and np.all(np.sign(below.real) != np.sign(above.real))


def test_controlled_chain_refuses_a_long_field_and_takes_its_split():
    beam = BeamField("beam", length=L, bending_stiffness=EI, mass_per_length=RHOA)
    loop = [Feedback("p", [("load.w", 1.0)], "load", gain=1.0)]
    with pytest.raises(ModelError, match=r"element 'beam' of controlled chain .* \*beam\.split\(14\)"):
        ctmm.frequency_response(ControlledChain(_cantilever(beam), loop), [1e3], input="load.force",
                                output="load.w")
    split = ControlledChain(_cantilever(*beam.split(14)), loop)
    frf = ctmm.frequency_response(split, OMEGA[:4], input="load.force", output="load.w")("load.w", "load.force")
    open_loop = cantilever_tip_receptance(OMEGA[:4], L, EI, RHOA)
    np.testing.assert_allclose(frf, open_loop / (1 + open_loop), rtol=1e-11)
