"""Controlled chains and the characteristic log-determinant on the compiled chain recursion (issue 13).

Independent references: the dense global closed loop of ``ctmm.reference.delay_chain`` (``s^2 M + s C + K`` plus
the delayed loop terms, solved and its determinant taken densely) and the dense global chain of
``ctmm.reference.chain``.  The numpy recursions (the extended chain of :func:`ctmm.assembly.riccati_solve`, the
scalar chain) are compared besides: equal to round-off, never instead.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import controlled_chain_frequency as closed
from ctmm.assembly import riccati_solve
from ctmm.chain_assembly import assemble, laplace_variables, solve
from ctmm.compiled_chain_frequency import compiled_library
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.reference import chain as reference
from ctmm.reference.delay_chain import closed_loop_characteristic, closed_loop_frequency_response
from _chain_convert import random_chain, to_global
from test_controlled_frequency import build, random_setup

pytestmark = pytest.mark.skipif(compiled_library() is None, reason="no C compiler: the numpy recursion answers")

OMEGA = np.linspace(0.3, 40.0, 61)


def _numpy_log_det(system, s):
    Us, us, start, end = assemble(system, s)
    return riccati_solve(Us, us, start, end, want_states=False).log_det


def _same_modulo_2pi(a, b, tolerance):
    """``exp(a) = exp(b)`` to ``tolerance`` relative (logs equal up to 2 pi i)."""
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    assert np.max(np.abs(np.expm1(a - b))) < tolerance


@pytest.mark.parametrize("seed", [0, 3, 7, 11])
def test_closed_loop_frf_compiled_equals_dense_reference_and_numpy(seed):
    """Random chains with 1-3 loops (delayed, relative, across a connector): the compiled closed loop equals the
    dense global closed loop and the extended numpy recursion, also for a reference input and the loop signals."""
    setup = random_setup(seed, n_loops=2 if seed % 2 else None)
    system, n = setup.system, setup.chain.size
    outputs = [f"m{i}.x" for i in range(n)] + ["loop0.y", "loop0.u"]
    frf = ctmm.frequency_response(system, OMEGA, input=["m0.force", "loop0.reference"], output=outputs)
    assert frf.info["kernel"] == "compiled"
    for i in range(n):
        ref = closed_loop_frequency_response(setup.chain, setup.global_loops, OMEGA, 0, i, "displacement")
        assert np.max(np.abs(frf(f"m{i}.x", "m0.force") - ref)) <= 1e-10 * np.max(np.abs(ref))
    s = laplace_variables(OMEGA)
    points = sorted({system.signal(o).point for o in outputs})
    for amplitudes in ({system.input("m0.force").position: {"force": 1.0}}, {"loop0": {"reference": 1.0}}):
        compiled = closed.closed_loop_solve(system, s, amplitudes, points)
        numpy = solve(system, s, amplitudes).states[points]
        scale = np.max(np.abs(numpy), axis=1, keepdims=True)
        assert np.all(np.abs(compiled.states - numpy) <= 1e-12 * scale + 1e-15)


def test_delayed_loop_signals_and_reference_transfer():
    """One delayed loop: ``y = T r`` with ``T = k P / (1 + k P)`` from the open plant (also compiled) and
    ``u = -k e^{-s tau} (y - r)``."""
    setup = build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                  start="fixed", end="free", loops=[(2, "displacement", 0, 5.0, 0.05, None, False)])
    frf = ctmm.frequency_response(setup.system, OMEGA, input="loop0.reference", output=["loop0.y", "loop0.u"])
    assert frf.info["kernel"] == "compiled"
    k = 5.0 * np.exp(-1j * OMEGA * 0.05)
    P = reference.frequency_response(setup.chain, OMEGA, 0, 2, "displacement")
    np.testing.assert_allclose(frf("loop0.y"), k * P / (1 + k * P), rtol=1e-11)
    np.testing.assert_allclose(frf("loop0.u"), k / (1 + k * P), rtol=1e-11)


def test_superposition_losing_digits_falls_back_to_circle_means():
    """A nearly undamped plant whose resonance the loop damps: the plant alone responds ~1e7 times more than the
    closed loop, the superposition would lose those digits; those frequencies are answered by certified circle
    means of the closed loop (kernel 'compiled/numpy') and the answer equals the dense reference."""
    setup = build([1.0, 1.0], [100.0, 100.0, 0.0], [1e-7, 1e-7, 0.0], [0.0, 0.0], start="fixed", end="free",
                  loops=[(1, "velocity", 1, 5.0, 0.01, None, False)])
    M, C, K = reference.assemble(setup.chain)
    omega_1 = float(np.sqrt(np.min(np.linalg.eigvals(np.linalg.solve(M, K)).real)))
    omega = np.array([0.5, omega_1, 30.0])
    frf = ctmm.frequency_response(setup.system, omega, input="m0.force", output="m1.x")
    assert frf.info["kernel"] == "compiled/numpy"
    ref = closed_loop_frequency_response(setup.chain, setup.global_loops, omega, 0, 1, "displacement")
    np.testing.assert_allclose(frf("m1.x")[[0, 2]], ref[[0, 2]], rtol=1e-10)
    # at the exact plant resonance: the extended numpy recursion is 1.6e-9 from the dense solve there, the
    # superposition 2.2e-8 (its amplification 5e7 times round-off), the circle means to round-off
    np.testing.assert_allclose(frf("m1.x")[1], ref[1], rtol=1e-12)


@pytest.mark.parametrize("n", [2, 5])
def test_closed_loop_at_the_natural_frequencies_of_an_undamped_plant(n):
    """Undamped plants closed by a delayed rate loop and a position loop, evaluated exactly at the plant's natural
    frequencies (the Riccati pivots of the plant vanish there, the closed loop is regular): equal to the dense global
    closed loop (before: the extended numpy recursion answered, 0.2-20 % off)."""
    rng = np.random.default_rng(5)
    masses, stiffness = rng.uniform(0.5, 2.0, n), np.append(rng.uniform(100.0, 1000.0, n), 0.0)
    setup = build(masses, stiffness, np.zeros(n + 1), np.zeros(n), start="fixed", end="free",
                  loops=[(n - 1, "velocity", 0, 3.0, 0.01, None, False), (n // 2, "displacement", n - 1, 20.0, 0.0,
                                                                            None, False)])
    M, _, K = reference.assemble(setup.chain)
    omega = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    frf = ctmm.frequency_response(setup.system, omega, input="m0.force", output=f"m{n - 1}.x")
    ref = closed_loop_frequency_response(setup.chain, setup.global_loops, omega, 0, n - 1, "displacement")
    np.testing.assert_allclose(frf(f"m{n - 1}.x"), ref, rtol=1e-10)


@pytest.mark.parametrize("start, end", [("fixed", "free"), ("free", "fixed"), ("elastic", "free"),
                                        ("fixed", "fixed")])
def test_log_det_compiled_equals_numpy_and_dense_determinant(start, end):
    """Lumped chains: the compiled log-determinant equals the numpy recursion's (modulo 2 pi i) and
    ``characteristic_function`` is a constant times ``det(s^2 M + s C + K)`` of the dense global model."""
    chain = random_chain(np.random.default_rng(2), 7, start=start, end=end, damped=True, grounded=True)
    rng = np.random.default_rng(4)
    s = rng.uniform(-3, 1, 21) + 1j * rng.uniform(-40, 40, 21)
    compiled = solve(chain, s, points=(), want_log_det=True, certify=False)
    assert compiled.kernel == "compiled"
    _same_modulo_2pi(compiled.log_det, _numpy_log_det(chain, s), 1e-12)
    M, C, K = reference.assemble(to_global(chain))
    dense = np.array([np.linalg.det(z * z * M + z * C + K) for z in s])
    ratio = ctmm.characteristic_function(chain, s) / dense
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-10)


def test_log_det_of_a_long_chain_does_not_overflow():
    """500 masses at high frequency: the product of the pivots leaves the double range (|log det| ~ 1e4), the
    compiled mantissa-exponent product keeps it, equal to the numpy sum of logarithms."""
    elements = [Fixed("wall")]
    for i in range(500):
        elements += [SpringDamper(f"k{i}", 1e4, 0.1), Mass(f"m{i}", 1e-3)]
    chain = ctmm.Chain("long", elements + [Free("end")])
    s = np.array([1.0 + 1e4j, 0.5 + 2e4j, 1e-3 + 0.1j, 3.0 + 7e3j])
    compiled = solve(chain, s, points=(), want_log_det=True, certify=False).log_det
    numpy = _numpy_log_det(chain, s)
    assert np.max(np.abs(numpy.real)) > 1000.0
    assert np.max(np.abs(compiled.real - numpy.real)) < 1e-9 * np.max(np.abs(numpy.real))
    assert np.max(np.abs(np.exp(1j * (compiled.imag - numpy.imag)) - 1)) < 1e-9


@pytest.mark.parametrize("seed", [1, 5, 8])
def test_controlled_log_det_equals_numpy_and_dense_characteristic(seed):
    """Controlled chains with delays: the determinant lemma on the compiled plant equals the extended numpy
    recursion's log-determinant (modulo 2 pi i), and the characteristic function is a constant times the dense
    closed-loop quasi-polynomial."""
    setup = random_setup(seed)
    rng = np.random.default_rng(seed)
    s = rng.uniform(-3, 1, 12) + 1j * rng.uniform(-30, 30, 12)
    assert closed.applies(setup.system)
    _same_modulo_2pi(closed.log_determinant(setup.system, s), _numpy_log_det(setup.system, s), 1e-10)
    ratio = ctmm.characteristic_function(setup.system, s) / closed_loop_characteristic(setup.chain,
                                                                                       setup.global_loops, s)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)


def test_controlled_log_det_where_the_plant_is_singular():
    """A free plant at s = 0 (a rigid-body mode: the plant solve is singular) closed by a position loop: that
    entry is answered by the extended numpy recursion, finite and equal to it."""
    plant = ctmm.Chain("free", [Free("a"), Mass("m0", 1.0), SpringDamper("k1", 50.0, 0.2), Mass("m1", 2.0),
                                Free("b")])
    system = ControlledChain(plant, [Feedback("p", "m1.x", "m0", gain=20.0, delay=0.02)])
    s = np.array([0.0 + 0j, 0.3 + 2j])
    _same_modulo_2pi(closed.log_determinant(system, s), _numpy_log_det(system, s), 1e-11)


def test_without_a_compiler_the_extended_numpy_recursion_answers(monkeypatch):
    from ctmm import compiled_chain_frequency as kernel

    setup = random_setup(3)
    monkeypatch.setattr(kernel, "compiled_library", lambda: None)
    assert not closed.applies(setup.system)
    frf = ctmm.frequency_response(setup.system, OMEGA[:5], input="m0.force", output="m1.x")
    assert frf.info["kernel"] == "numpy"


def test_steady_state_response_compiled_equals_dense_solve():
    """``steady_state_response`` at the outputs' points only (compiled): a harmonic load on one mass of a random
    chain, plain and closed by a delayed loop, against the dense global solves."""
    from ctmm.signals import Harmonic

    setup = build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                  start="fixed", end="free", loops=[(2, "displacement", 0, 5.0, 0.05, None, False)])
    elements = list(setup.plant.elements)
    position = setup.plant.position("m1")
    load = Harmonic(2.0, 7.0, phase=0.3)
    elements[position] = Mass("m1", elements[position].mass, force=load)
    plant = ctmm.Chain("loaded", elements)
    phasor = -1j * 2.0 * np.exp(0.3j)                      # 2 sin(7 t + 0.3) = Re(phasor e^{7 i t})
    outputs = ["m0.x", "m2.x"]
    for system, closed_loop in ((plant, False), (ControlledChain(plant, setup.loops), True)):
        result = ctmm.steady_state_response(system, 7.0, outputs=outputs)
        for name, mass in zip(outputs, (0, 2)):
            ref = (closed_loop_frequency_response(setup.chain, setup.global_loops, np.array([7.0]), 1, mass)
                   if closed_loop else reference.frequency_response(setup.chain, np.array([7.0]), 1, mass,
                                                                    "displacement"))
            np.testing.assert_allclose(result[name], phasor * ref[0], rtol=1e-12)


def test_closed_loop_memory_is_independent_of_the_elements_times_frequencies():
    """500 masses x 512 frequencies, a delayed loop on the tip, two outputs: the closed loop on the compiled plant
    solves allocates O(N + points x B) (below 1 MB); the extended numpy recursion holds (B, 4, 4) matrices of
    every element (measured: 0.35 MB against 297 MB)."""
    import tracemalloc

    elements = [Fixed("wall")] + [e for i in range(500) for e in (SpringDamper(f"k{i}", 1000.0, 0.2),
                                                                 Mass(f"m{i}", 0.1))] + [Free("end")]
    system = ControlledChain(ctmm.Chain("long", elements), [Feedback("pd", [("m499.x", 20.0), ("m499.v", 5.0)],
                                                                     "m499", gain=1.0, delay=0.01)])
    s = laplace_variables(np.linspace(1.0, 190.0, 512))
    amplitudes = {system.input("m0.force").position: {"force": 1.0}}
    points = [system.signal("m0.x").point, system.signal("m499.x").point]
    closed.closed_loop_solve(system, s, amplitudes, points)
    tracemalloc.start()
    try:
        solution = closed.closed_loop_solve(system, s, amplitudes, points)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert solution.kernel == "compiled"
    assert peak < 1_000_000
