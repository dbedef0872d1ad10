"""The C node loops of the generated DT-TMM step of chains (:mod:`ctmm.compiled_chain_kernel`, issue 13):
loads, real-time and delayed LTI loops and held inputs close as the Python DT-TMM step does."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_chain_kernel import tridiagonal_factors
from ctmm.compiled_chain_scheme_runs import simulate_chain_scheme_generated
from ctmm.compiled_chain_schemes import CompiledChainScheme
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.signals import Constant, Harmonic

NAMES = ["m0", "m1", "m2", "m3"]


def _loaded(force_on_m1=None) -> ctmm.Chain:
    elements = [Fixed("s")]
    for i, name in enumerate(NAMES):
        force = Harmonic(3.0, 40.0, 0.3) if i == 0 else (force_on_m1 if i == 1 else None)
        elements += [SpringDamper(f"k{i}", 2e3 + 300.0 * i, 0.5 + 0.1 * i),
                     Mass(name, 1.0 + 0.2 * i, **({"force": force} if force is not None else {}))]
    return ctmm.Chain("loaded", elements + [Free("e")])


def _positions(result) -> np.ndarray:
    return np.column_stack([result[f"{n}.x"] for n in NAMES])


def test_tridiagonal_factors_solve_as_numpy():
    rng = np.random.default_rng(4)
    matrix = np.diag(rng.uniform(5.0, 6.0, 6)) + np.diag(rng.uniform(-1.0, 1.0, 5), 1) + \
        np.diag(rng.uniform(-1.0, 1.0, 5), -1)
    factors, rhs = tridiagonal_factors(matrix), rng.standard_normal(6)
    partial = np.zeros(6)
    for i in range(6):
        partial[i] = rhs[i] - factors.factors[i] * (partial[i - 1] if i else 0.0)
    solution = np.zeros(6)
    for i in range(5, -1, -1):
        solution[i] = (partial[i] - (factors.upper[i] * solution[i + 1] if i < 5 else 0.0)) * factors.reciprocals[i]
    assert np.allclose(solution, np.linalg.solve(matrix, rhs), rtol=1e-13, atol=0.0)
    assert tridiagonal_factors(matrix + np.diag(np.ones(4), 2)) is None


@pytest.mark.parametrize("scheme", ["generalized_alpha", "wilson_theta"])
def test_node_loops_close_loads_and_lti_loops_as_the_python_dttmm_step(scheme):
    control = pytest.importorskip("control")
    loops = [Feedback("lag", [("m3.x", 1.0), ("m3.v", 0.05)], "m0", gain=control.tf([40.0, 200.0], [0.02, 1.0])),
             Feedback("late", "m2.v", "m1", gain=control.tf([3.0], [0.01, 1.0]), delay=0.004)]
    system = ControlledChain(_loaded(), loops)
    references, x0 = {"lag": Harmonic(0.01, 20.0), "late": 0.02}, {"m0": 0.01, "m3": -0.02}
    kernel = CompiledChainScheme(system, 1e-3, scheme, references=references, unrolled=False)
    assert kernel.unrolled is False
    generated = simulate_chain_scheme_generated(system, 0.2, 1e-3, scheme, x0=x0, references=references,
                                                compiled=kernel)
    python = ctmm.simulate(system, 0.2, 1e-3, method=scheme, x0=x0, references=references)
    assert np.max(np.abs(_positions(generated) - _positions(python))) < 1e-12 * 0.02
    for name in ("lag.u", "late.u"):
        assert np.max(np.abs(generated[name] - python[name])) < 1e-11 * np.max(np.abs(python[name])), name


def test_node_loops_take_held_inputs_as_a_constant_force():
    kernel = CompiledChainScheme(_loaded(), 1e-3, "newmark", actuators=("m1",), unrolled=False)
    first = kernel.start({"m2": 0.01}, None, held={"m1": 2.0})
    states = kernel.continue_run(first, np.array([2.0]), 100, 0)
    python = ctmm.simulate(_loaded(Constant(2.0)), 0.1, 1e-3, method="newmark", x0={"m2": 0.01})
    assert np.max(np.abs(states[:, :4] - _positions(python)[1:])) < 1e-13


def test_the_cache_key_holds_the_node_loops_numbers(tmp_path):
    """With an LTI controller the key is the serialized step (no description), which does not hold the C bodies:
    a chain differing only in a stiffness must not load the other's library."""
    control = pytest.importorskip("control")
    loops = [Feedback("lag", "m3.x", "m0", gain=control.tf([40.0, 200.0], [0.02, 1.0]))]
    x0 = {"m3": -0.02}
    for stiffness in (2e3, 5e3):
        chain = ctmm.Chain("keyed", [Fixed("s"), *[part for i, name in enumerate(NAMES) for part in (
            SpringDamper(f"k{i}", stiffness, 0.5), Mass(name, 1.0))], Free("e")])
        system = ControlledChain(chain, loops)
        kernel = CompiledChainScheme(system, 1e-3, "newmark", unrolled=False, cache_dir=tmp_path)
        generated = simulate_chain_scheme_generated(system, 0.1, 1e-3, "newmark", x0=x0, compiled=kernel)
        python = ctmm.simulate(system, 0.1, 1e-3, method="newmark", x0=x0)
        assert np.max(np.abs(_positions(generated) - _positions(python))) < 1e-14, stiffness
