"""The compiled Riccati recursion of 1-D lumped chains in the frequency domain (ctmm.compiled_chain_frequency).

Independent references: the dense global solve of ``ctmm.reference.chain`` / ``ctmm.reference.inerter_chain``
(assembled from element parameters, no transfer matrices).  The numpy recursion is compared besides (the same
recursion: equal to round-off), never instead.
"""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import ctmm
from ctmm.chain_assembly import laplace_variables, solve
from ctmm.compiled_chain_frequency import compiled_library
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.errors import ModelError, SingularSystemError
from ctmm.reference import chain as reference
from ctmm.reference import inerter_chain
from _chain_convert import inerter_chains, random_chain, to_global

pytestmark = pytest.mark.skipif(compiled_library() is None, reason="no C compiler: the numpy recursion answers")


def _states(chain, omega, position, key, points, compiled):
    return solve(chain, laplace_variables(omega), {position: {key: 1.0}}, points=points, compiled=compiled)


@pytest.mark.parametrize("start, end", [("fixed", "free"), ("free", "fixed"), ("elastic", "free"),
                                        ("fixed", "fixed"), ("free", "elastic")])
def test_compiled_equals_dense_and_numpy(start, end):
    """Random damped, grounded chains, both start partitions (a free start knows the force), 37 frequencies (not a
    whole number of blocks of 8), outputs at four masses: compiled = dense global solve, compiled = numpy."""
    chain = random_chain(np.random.default_rng(5), 9, start=start, end=end, damped=True, grounded=True)
    g = to_global(chain)
    omega = np.linspace(0.2, 70.0, 37)
    outputs = ["m0.x", "m3.v", "m8.x", "m5.a"]
    frf = ctmm.frequency_response(chain, omega, input="m2.force", output=outputs)
    assert frf.info["kernel"] == "compiled"
    for name, (mass, quantity) in zip(outputs, [(0, "displacement"), (3, "velocity"), (8, "displacement"),
                                                (5, "acceleration")]):
        np.testing.assert_allclose(frf(name, "m2.force"), reference.frequency_response(g, omega, 2, mass, quantity),
                                   rtol=1e-10, atol=0)
    source = chain.input("m2.force")
    points = sorted({chain.signal(o).point for o in outputs})
    compiled = _states(chain, omega, source.position, source.input, points, True)
    numpy = _states(chain, omega, source.position, source.input, points, False)
    assert compiled.points == numpy.points == tuple(points)
    scale = np.max(np.abs(numpy.states), axis=1, keepdims=True)
    # per point and component, relative to its largest value; 1e-14 N absolute (of the 1 N load) for a free end's
    # force: exactly 0, where both recursions leave the round-off of S e + P (numpy up to 1.2e-16 N here)
    assert np.all(np.abs(compiled.states - numpy.states) <= 1e-13 * scale + 1e-14)


@pytest.mark.parametrize("end", ["free", "fixed"])
def test_compiled_inerters_and_connector_force_input(end):
    """Connectors with inertance (``v = 1 / (b s^2 + c s + k)``) against the dense inerter reference, and a load
    on a connector (an actuator force pushing its two ends apart) against the dense chain solve."""
    masses = np.array([1.0, 0.5, 2.0])
    chain, ref = inerter_chains(masses, np.array([100.0, 200.0, 150.0, 80.0]), np.array([0.5, 0.2, 0.1, 0.3]),
                                np.array([0.0, 0.4, 0.0, 0.7]), end)
    omega = np.linspace(0.5, 40.0, 21)
    frf = ctmm.frequency_response(chain, omega, input="m1.force", output=["m0.x", "m2.x"])
    exact = inerter_chain.frequency_response(ref, omega, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(frf.response[:, 0].T, exact[:, [0, 2]], rtol=1e-11)

    springs = random_chain(np.random.default_rng(3), 6, start="fixed", end="free", damped=True)
    g = to_global(springs)
    frf = ctmm.frequency_response(springs, omega, input="k3.force", output=["m1.x", "m4.x"])
    for name, mass in (("m1.x", 1), ("m4.x", 4)):      # +F on mass 3 (outboard end), -F on mass 2 (inboard end)
        exact = (reference.frequency_response(g, omega, 3, mass) - reference.frequency_response(g, omega, 2, mass))
        np.testing.assert_allclose(frf(name, "k3.force"), exact, rtol=1e-10)


def test_certificate_refuses_a_frequency_at_a_natural_frequency():
    """Undamped single mass k = 4 N/m, m = 1 kg at omega = 2 rad/s exactly: the pivot ``G = 1 - m w^2 / k`` is 0;
    both recursions refuse that frequency by its index (the end unknown is not finite), neither answers."""
    chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 4.0), Mass("m", 1.0), Free("end")])
    source = chain.input("m.force")
    for compiled in (True, False):
        with pytest.raises(SingularSystemError, match=r"batch entries \[1\]"):
            _states(chain, np.array([1.0, 2.0, 3.0]), source.position, source.input, [2], compiled)
    with pytest.raises(SingularSystemError):
        ctmm.frequency_response(chain, [2.0], input="m.force", output="m.x")
    frf = ctmm.frequency_response(chain, [1.0, 3.0], input="m.force", output="m.x")
    np.testing.assert_allclose(frf("m.x", "m.force"), 1.0 / (4.0 - np.array([1.0, 9.0])), rtol=1e-15)


def test_compiled_memory_is_independent_of_the_elements_times_frequencies():
    """500 masses x 512 frequencies, two outputs: the compiled solve's peak allocation stays below 1 MB (its work
    is O(N) per block of frequencies); the numpy recursion keeps G_j, r_j of every mass (8.2 MB of them)."""
    chain = ctmm.Chain("long", [Fixed("wall")] + [e for i in range(500) for e in
                                                  (SpringDamper(f"k{i}", 1000.0, 0.2), Mass(f"m{i}", 0.1))]
                       + [Free("end")])
    omega = np.linspace(1.0, 190.0, 512)
    source = chain.input("m0.force")
    points = [chain.signal("m0.x").point, chain.signal("m499.x").point]
    peaks = {}
    for compiled in (True, False):
        _states(chain, omega, source.position, source.input, points, compiled)
        tracemalloc.start()
        try:
            _states(chain, omega, source.position, source.input, points, compiled)
            peaks[compiled] = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    assert peaks[True] < 1_000_000 and peaks[False] > 5_000_000      # measured: 0.3 MB and 8.6 MB


def test_compiled_flag_is_checked():
    chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 4.0), Mass("m", 1.0), Free("end")])
    with pytest.raises(ModelError, match="compiled must be True, False or None, got 'yes'"):
        solve(chain, laplace_variables([1.0]), {2: {"force": 1.0}}, points=[2], compiled="yes")


def test_without_a_compiler_numpy_answers_and_compiled_true_refuses(monkeypatch):
    """No library (no compiler): the default falls back to the numpy recursion (bit-identical to compiled=False);
    compiled=True refuses by name."""
    import ctmm.compiled_chain_frequency as kernel

    chain = random_chain(np.random.default_rng(1), 4, start="fixed", end="free", damped=True)
    omega = np.linspace(0.5, 30.0, 11)
    source = chain.input("m1.force")
    numpy = _states(chain, omega, source.position, source.input, [3], False)
    monkeypatch.setattr(kernel, "compiled_library", lambda: None)
    assert ctmm.frequency_response(chain, omega, input="m1.force", output="m2.x").info["kernel"] == "numpy"
    np.testing.assert_array_equal(_states(chain, omega, source.position, source.input, [3], None).states,
                                  numpy.states)
    with pytest.raises(ModelError, match="compiled=True: the compiled chain recursion needs a C compiler"):
        _states(chain, omega, source.position, source.input, [3], True)
