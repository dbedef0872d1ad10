"""The run guard of generated 1-D chain runs checks the stored rows in one pass and stops where the numpy path does.

The generated RK4 (:mod:`ctmm.compiled_chain`) and DT-TMM schemes (:mod:`ctmm.compiled_chain_scheme_runs`, with and
without massless nodes) return all their rows at once; the guard screens them together and hands the rows it refuses
to the numpy path's per-row check.  Reference: the numpy path of the same run (``compiled=False``), which checks every
step as it goes: the same error (message, time, element) and the same partial rows.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, PrescribedDisplacement, Spring, SpringDamper
from ctmm.errors import SimulationError
from ctmm.signals import Harmonic

pytest.importorskip("casadi")

RESONANCE = math.sqrt(200.0 / 1.0)          # [rad/s] of m0 on k0 alone (the base shakes it; m1 hangs on softly)


def chain(start, *, massless: bool = False) -> ctmm.Chain:
    middle = [Spring("k1a", 10.0), Spring("k1b", 10.0)] if massless else [SpringDamper("k1", 5.0, 0.01)]
    return ctmm.Chain("grows", [start, SpringDamper("k0", 200.0, 0.05), Mass("m0", 1.0), *middle, Mass("m1", 0.8),
                                Free("e")])


def unstable(start) -> ControlledChain:
    """Velocity feedback of the wrong sign: the run grows until the bound stops it."""
    return ControlledChain(chain(start), [Feedback("L", "m0.v", "m0", gain=-10.0)])


@pytest.mark.parametrize("method, system", [
    ("rk4", unstable(Fixed("w"))),
    ("rk4", unstable(PrescribedDisplacement("base", Harmonic(0.002, 7.0)))),
    ("rk4", chain(PrescribedDisplacement("base", Harmonic(0.3, 30.0)))),         # the support leaves the bound first
    ("newmark", unstable(Fixed("w"))),
    ("newmark", chain(PrescribedDisplacement("base", Harmonic(0.03, RESONANCE)), massless=True)),   # resonance
], ids=["rk4", "rk4-moving-base", "rk4-base-beyond", "newmark", "newmark-nodes"])
def test_a_diverging_generated_chain_run_stops_where_the_numpy_path_does(method, system):
    errors = {}
    for compiled in (False, True):
        with pytest.raises(SimulationError, match="diverged") as caught:
            ctmm.simulate(system, 3.0, 2e-3, method=method, x0={"m1": 0.01}, divergence_bound=0.2, compiled=compiled)
        errors[compiled] = caught.value
    python, generated = errors[False], errors[True]
    assert generated.partial_result.scheme_name.endswith("-generated")
    assert 0.01 < python.time < 3.0 and generated.time == pytest.approx(python.time, abs=1e-12)
    assert generated.element == python.element
    assert str(generated).split(" from its reference")[0] == str(python).split(" from its reference")[0]
    np.testing.assert_allclose(generated.partial_result.time, python.partial_result.time, rtol=0, atol=1e-12)
    for name in ("m0.x", "m1.x", "m1.v"):
        np.testing.assert_allclose(generated.partial_result[name], python.partial_result[name], rtol=0, atol=1e-9,
                                   err_msg=name)
