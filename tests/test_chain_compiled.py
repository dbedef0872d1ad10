"""``compiled=True`` for 1-D lumped chains: the generated RK4 (:mod:`ctmm.compiled_chain`).

The generated path must equal the Python path (the chain's ODE, or the one loop driver with the loops)
to round-off, and both must converge to the independent references (``method_of_steps``, the exact
delay equation on the global ``M, C, K``; a global state-space ODE for the LTI controller).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.reference.delay_chain import method_of_steps
from ctmm.signals import Harmonic

from test_controlled_frequency import build

casadi = pytest.importorskip("casadi")

X0 = [-0.05, 0.0, 0.1]
V0 = [0.0, 0.3, 0.0]
CASES = {
    "no loops": [],
    "real-time": [(2, "displacement", 0, 5.0, 0.0, None, False), (1, "velocity", 1, 3.0, 0.0, 0, True)],
    "delayed": [(2, "displacement", 0, 5.0, 0.05, None, False), (0, "velocity", 2, 2.0, 0.03, None, False)],
}


def seed_setup(loops):
    return build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                 start="fixed", end="free", loops=loops)


def initial(values):
    return {f"m{i}": v for i, v in enumerate(values) if v != 0.0}


def both(system, t_final, dt, x0=None, v0=None, **options):
    kwargs = dict(method="rk4", x0=initial(X0) if x0 is None else x0, v0=initial(V0) if v0 is None else v0, **options)
    return ctmm.simulate(system, t_final, dt, compiled=True, **kwargs), ctmm.simulate(system, t_final, dt, **kwargs)


@pytest.mark.parametrize("case", list(CASES))
def test_generated_rk4_equals_the_python_path_and_the_exact_solution(case):
    setup = seed_setup(CASES[case])
    system = setup.system if CASES[case] else setup.plant
    generated, python = both(system, 0.6, 0.001)
    assert generated.scheme_name == "rk4-generated"
    for name in ("m0.x", "m1.x", "m2.x", "m2.v", "m1.a", "k1.f"):
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-10 * max(1.0, np.max(np.abs(python[name]))))
    for loop in setup.loops:
        for quantity in ("y", "u"):
            np.testing.assert_allclose(generated[f"{loop.name}.{quantity}"], python[f"{loop.name}.{quantity}"],
                                       rtol=0, atol=1e-12)
    exact = method_of_steps(setup.chain, setup.global_loops, 0.6, X0, V0, rtol=1e-12, atol=1e-14)
    x = np.column_stack([generated[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(x - exact.evaluate(generated.time).displacement)) < 1e-10


def test_lti_controller_references_and_load_signals_in_the_generated_loop():
    control = pytest.importorskip("control")
    plant = ctmm.Chain("c", [Fixed("s"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0, force=Harmonic(0.3, 9.0)),
                             SpringDamper("k1", 80.0, 0.3), Mass("m1", 1.5), Free("e")])
    system = ControlledChain(plant, [Feedback("lag", "m1.x", "m0", gain=control.tf([20.0], [0.05, 1.0])),
                                     Feedback("late", "k1.f", "m1", gain=0.01, delay=0.02)])
    options = dict(references={"lag": Harmonic(0.01, 3.0)}, inputs={"m1.force": 0.2}, store_every=5)
    generated, python = both(system, 0.5, 0.001, x0={"m1": 0.02}, v0={"m0": 0.1}, **options)
    assert len(generated.time) == len(python.time) == 101
    for name in ("m0.x", "m1.v", "lag.u", "late.u", "m1.a"):
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12)


def test_refusals_name_what_does_not_compile():
    setup = seed_setup(CASES["delayed"])
    with pytest.raises(ModelError, match="whole multiple"):
        ctmm.simulate(setup.system, 0.3, 0.004, method="rk4", compiled=True)
    with pytest.raises(ModelError, match="whole multiple"):          # the generated DT-TMM step too
        ctmm.simulate(setup.system, 0.3, 0.004, method="newmark", compiled=True)
    massless = ctmm.Chain("q", [Fixed("s"), Spring("k0", 100.0), Mass("m0", 1.0), Spring("k1", 50.0),
                                Spring("k2", 50.0), Mass("m1", 1.0), Free("e")])
    with pytest.raises(ModelError, match="'k1' acts on a point without inertia"):    # (loops sensing massless
        ctmm.simulate(ControlledChain(massless, [Feedback("l", "m1.x", "k1", gain=1.0)]), 0.1, 0.01, method="rk4",
                      compiled=True)                                  # nodes: test_chain_compiled_massless_loops)
    with pytest.raises(ModelError, match="Python callable"):
        ctmm.simulate(setup.plant, 0.1, 0.01, method="rk4", compiled=True, inputs={"m0.force": lambda t: t})


def test_a_reference_to_an_unknown_loop_is_refused_on_a_plain_chain():
    """A plain chain has no loop to take a reference: the generated RK4 refuses the name as the Python path does
    (it dropped it and ran the open chain)."""
    plant = seed_setup([]).plant
    for compiled in (False, True):
        with pytest.raises(ModelError, match="unknown .*loop.*'zz'"):
            ctmm.simulate(plant, 0.05, 0.001, method="rk4", compiled=compiled, x0={"m0": 0.01},
                          references={"zz": 1.0})
