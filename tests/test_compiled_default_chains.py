"""``compiled=None`` on 1-D chains: the size limit by chain kind, the options the numpy path refuses, and the choice
for inputs and references given as signals or callables, with and without ``store_every`` (issue 13,
:mod:`ctmm.compiled_default`).

Reference: the numpy path (``compiled=False``) of the same call -- the contract of every generated path is the numpy
answer to round-off; where the default falls back, the numpy answer itself and the reason in ``info["compiled"]``.
The long-run threshold is lowered (``MINIMUM_STEPS``, read by :func:`~ctmm.compiled_default.default_refusal` at each
call) so that the runs are short; the choice does not otherwise depend on the step count.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.compiled_default as compiled_default
from ctmm.compiled_default import MAXIMUM_BANDED_CHAIN_POINTS, MAXIMUM_CHAIN_POINTS, default_refusal
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Inerter, Mass, PrescribedDisplacement, SpringDamper
from ctmm.errors import ModelError
from ctmm.signals import Harmonic, Ramp
from test_compiled_default import needs_compiler

LONG = dict(t_final=10.0, t0=0.0, dt=1e-3, controllers=(), fast=None, force_hook=None, solver="riccati")
DT = 1e-4


def masses(n: int, *, start=None, connector=None) -> ctmm.Chain:
    """``start - [k, c] - m_0 - ... - m_{n-1} - Free`` (2 n + 1 points); ``connector(i)`` replaces ``[k, c]`` i."""
    elements = [start or Fixed("wall")]
    for i in range(n):
        elements += [(connector(i) if connector else None) or SpringDamper(f"k{i}", 1.0e4, 1.0), Mass(f"m{i}", 1.0)]
    return ctmm.Chain(f"chain{n}", elements + [Free("end")])


def looped(n: int, delay: float = 0.0) -> ControlledChain:
    return ControlledChain(masses(n), [Feedback("tip", f"m{n - 1}.x", "m0", gain=500.0, delay=delay)])


def start_values(n: int) -> dict:
    return {f"m{i}": 0.01 * float(np.sin(np.pi * (i + 1) / (2 * n))) for i in range(n)}


@needs_compiler
def test_the_chain_size_limit_depends_on_the_chain_kind(monkeypatch):
    """Above the dense kinds' limit only a banded chain with feedback loops is generated; each dense part, or the
    missing loops, is named in the refusal; every kind stops at the banded limit (both limits lowered here: the
    rule, not the numbers; the generated run of a 2 003-point chain below is at the real ones)."""
    monkeypatch.setattr(compiled_default, "MAXIMUM_CHAIN_POINTS", 21)
    monkeypatch.setattr(compiled_default, "MAXIMUM_BANDED_CHAIN_POINTS", 41)

    def controlled(chain: ctmm.Chain) -> ControlledChain:
        return ControlledChain(chain, [Feedback("tip", "m10.x", "m0", gain=500.0)])

    n = 11                                          # 23 points
    for method in ("rk4", "newmark"):
        assert default_refusal(controlled(masses(n)), method, **LONG) is None
    assert default_refusal(masses(n), "newmark", **LONG) == (
        "a chain of 23 points without feedback loops (> 21: the numpy run of a plain banded chain is cheaper than the "
        "generated path's compile; give compiled=True)")
    massless = ctmm.Chain("massless", [Fixed("wall"), SpringDamper("ka", 1.0e4, 1.0)] + list(masses(n).elements[1:]))
    refusal = default_refusal(controlled(massless), "newmark", **LONG)
    assert refusal.startswith("a chain of 24 points with points without mass (") and "(> 21: its generated set-up is" \
        " dense; give compiled=True)" in refusal
    inerter = masses(n, connector=lambda i: Inerter(f"b{i}", 0.1, stiffness=1.0e4) if i == 7 else None)
    assert default_refusal(controlled(inerter), "rk4", **LONG) == (
        "a chain of 23 points with inerters (b7) (> 21: its generated set-up is dense; give compiled=True)")
    moving = masses(n, start=PrescribedDisplacement("shaker", Harmonic(1e-3, 10.0)))
    assert "with a prescribed motion (shaker)" in default_refusal(controlled(moving), "rk4", **LONG)
    for small in (massless, moving):                # the dense kinds up to their limit, as before
        trimmed = ctmm.Chain("small", list(small.elements[:19]) + [Free("end")])
        assert default_refusal(trimmed, "rk4", **LONG) is None
    refusal = default_refusal(looped(21), "rk4", **LONG)
    assert refusal == ("a chain of 43 points (> 41, the largest banded chain the default generates; give "
                       "compiled=True)")


def test_a_dense_chain_above_its_limit_runs_numpy_with_the_reason_in_info(monkeypatch):
    monkeypatch.setattr(compiled_default, "MAXIMUM_CHAIN_POINTS", 21)
    chain = masses(11, connector=lambda i: Inerter("b0", 0.1, stiffness=1.0e4) if i == 0 else None)
    result = ctmm.simulate(chain, 3 * DT, DT, x0={"m0": 0.01})
    assert result.info["compiled"].startswith("numpy (the default for this run: a chain of 23 points with inerters")
    reference = ctmm.simulate(chain, 3 * DT, DT, x0={"m0": 0.01}, compiled=False)
    np.testing.assert_array_equal(result["m0.x"], reference["m0.x"])


@needs_compiler
@pytest.mark.parametrize("method, delay", [("newmark", 0.0), ("rk4", 5 * DT)])
def test_a_banded_chain_above_the_dense_limit_is_generated_equal_to_numpy(monkeypatch, method, delay):
    """The round-off contract at a large size (the smallest chain the dense kinds' limit refuses, 2 003 points): the
    default's generated run against the numpy run, every position and velocity within 1e-12 of the largest of its
    kind (the tip's own velocity is tiny against the largest after a few steps: a bound on its own peak would ask
    for better than round-off of the chain's state).  10 steps: the loop acts from the first (the tip starts
    displaced) and the rk4 case's 5-step delay ring is read from step 6 on."""
    monkeypatch.setattr(compiled_default, "MINIMUM_STEPS", 10)
    n = MAXIMUM_CHAIN_POINTS // 2 + 1
    x0 = start_values(n)
    system = looped(n, delay)                       # one build of the 2 003 points for both runs
    result = ctmm.simulate(system, 10 * DT, DT, method=method, x0=x0)
    assert result.info["compiled"] == "generated (the default for this run)"
    reference = ctmm.simulate(system, 10 * DT, DT, method=method, x0=x0, compiled=False)
    for kind in ("x", "v"):
        expected = np.column_stack([reference[f"m{i}.{kind}"] for i in range(n)])
        found = np.column_stack([result[f"m{i}.{kind}"] for i in range(n)])
        scale = float(np.max(np.abs(expected)))
        assert scale > 0.0
        np.testing.assert_allclose(found, expected, rtol=0.0, atol=1e-12 * scale, err_msg=kind)


def test_options_the_numpy_path_refuses_stay_refused_at_any_length():
    """``store_every`` and ``outputs`` on a DT-TMM run of a chain, ``outputs`` on an RK4 run of a plain chain: the numpy
    path refuses them by name, so the default does for a long run too (it ran them on the generated path only)."""
    for method, options, name in (("newmark", dict(store_every=10), "store_every"),
                                  ("newmark", dict(outputs=("m0.x",)), "outputs"),
                                  ("rk4", dict(outputs=("m0.x",)), "outputs")):
        assert name in default_refusal(masses(2), method, **LONG, options=options)
        with pytest.raises(ModelError, match=name):
            ctmm.simulate(masses(2), compiled_default.MINIMUM_STEPS * 1e-3, 1e-3, method=method, **options)
    accepted = default_refusal(looped(2), "rk4", **LONG, options=dict(outputs=("m0.x",), store_every=10))
    assert accepted in (None, "no C compiler")


def signal_cases():
    """(system, method, options, generated?) with inputs / references as signals or callables, stored every step or
    every 7th."""
    harmonic, ramp, call = Harmonic(2.0, 30.0, 0.3), Ramp(5.0), (lambda t: 2.0 * np.sin(30.0 * t))
    cases = []
    for every in (1, 7):
        store = dict(store_every=every) if every != 1 else {}
        cases += [(masses(3), "rk4", dict(inputs={"m1": harmonic}, **store), True),
                  (masses(3), "rk4", dict(inputs={"m1": ramp}, **store), True),
                  (masses(3), "rk4", dict(inputs={"m1": call}, **store), False),
                  (looped(3), "rk4", dict(references={"tip": Harmonic(1e-3, 20.0)}, **store), True),
                  (looped(3), "rk4", dict(references={"tip": lambda t: 1e-3 * t}, **store), False)]
    cases += [(looped(3), "newmark", dict(references={"tip": Ramp(1e-2)}), True),
              (looped(3), "newmark", dict(references={"tip": lambda t: 1e-2 * t}), False)]
    return cases


@needs_compiler
@pytest.mark.parametrize("index", range(12))
def test_inputs_and_references_as_signals_or_callables(monkeypatch, index):
    """Each choice either runs generated, equal to numpy to round-off, or falls back to numpy with its reason."""
    monkeypatch.setattr(compiled_default, "MINIMUM_STEPS", 70)
    system, method, options, generated = signal_cases()[index]
    x0 = {"m0": 0.01, "m2": -0.005}
    result = ctmm.simulate(system, 70 * DT, DT, method=method, x0=x0, **options)
    reference = ctmm.simulate(system, 70 * DT, DT, method=method, x0=x0, compiled=False, **options)
    if generated:
        assert result.info["compiled"] == "generated (the default for this run)"
    else:
        assert result.info["compiled"].startswith("numpy (the default for this run; the generated path refused it")
        assert "Python callable" in result.info["compiled"]
    np.testing.assert_array_equal(result.time, reference.time)
    for name in ("m0.x", "m2.x", "m2.v"):
        scale = float(np.max(np.abs(reference[name])))
        np.testing.assert_allclose(result[name], reference[name], rtol=0.0, atol=1e-12 * scale, err_msg=name)
