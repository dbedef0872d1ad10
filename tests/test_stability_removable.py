"""Stability tools where the transfer-matrix sweep fails although ``Delta(s)`` is finite.

Two removable failures (:mod:`ctmm.entire_values`): a connector without spring (pure ``Damper``
``c s``) makes the sweep NaN at ``s = 0``, the start of every counting line (formerly a count of
-1); a substructure resonance (``m = 1`` on ``k = 100``: ``s = 10i``) made the Riccati pivot
singular (formerly a raw ``LinAlgError``).  References: the closed-form quasi-polynomial
``det(s^2 M + s C + K + e^(-s tau) (G + s H))`` and the verified roots of the delay equation
(:func:`ctmm.reference.dde_verified.verified_roots`: Chebyshev collocation, Newton, residual check).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import stability
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Damper, Fixed, Inerter, Mass, Spring
from ctmm.entire_values import circle_mean_logs, entire_logs
from ctmm.errors import SingularSystemError
from ctmm.reference import dde, dde_verified
from ctmm.reference import inerter_chain as ref
from ctmm.sweeps import LoopCharacteristic

# ------------------------------------------------------------------------------ pure damper
M1, M2, K1, K2, C12 = 1.0, 0.5, 100.0, 50.0, 0.5
MASS, DAMPING, STIFFNESS = np.diag([M1, M2]), C12 * np.array([[1.0, -1.0], [-1.0, 1.0]]), np.diag([K1, K2])
E12 = np.array([[0.0, 1.0], [0.0, 0.0]])       # force on m1 from x2 (u = -g x2(t - tau))


def damper_loop(gain: float, delay: float) -> ControlledChain:
    """Wall - k1 - m1 - c (no spring) - m2 - k2 - wall, u = -g x2(t - tau) on m1."""
    plant = ctmm.Chain("damper", [Fixed("g"), Spring("k1", K1), Mass("m1", M1), Damper("c", C12),
                                  Mass("m2", M2), Spring("k2", K2), Fixed("w")])
    return ControlledChain(plant, [Feedback("loop", "m2.x", "m1", gain=gain, delay=delay)])


def quasi_polynomial(s: np.ndarray, gain: float, delay: float) -> np.ndarray:
    """Closed form det([[m1 s^2 + c s + k1, -c s + g e^(-s tau)], [-c s, m2 s^2 + c s + k2]])."""
    s = np.asarray(s, dtype=complex)
    return (M1 * s**2 + C12 * s + K1) * (M2 * s**2 + C12 * s + K2) - (C12 * s) * (C12 * s - gain * np.exp(-s * delay))


def damper_roots(gain: float, delay: float, re_min: float = 0.0, im_max: float = 200.0) -> np.ndarray:
    """Verified roots of the delay equation, each also a zero of the closed-form quasi-polynomial."""
    A0, delayed = dde.second_order_system(MASS, DAMPING, STIFFNESS, [(gain * E12, np.zeros((2, 2)), delay)])
    roots = dde_verified.verified_roots(A0, delayed, 80, re_min=re_min, im_max=im_max)
    scale = np.abs(quasi_polynomial(np.abs(roots) * 1j, 0.0, 0.0)) + 1.0
    assert np.all(np.abs(quasi_polynomial(roots, gain, delay)) < 1e-9 * scale)
    return roots


def test_characteristic_function_is_finite_at_zero_with_a_pure_damper():
    """Delta(0) (NaN before: log(c s) = -inf plus a NaN sweep) against the closed form."""
    s = np.array([0.0, 1e-9j, 3.0j, 0.4 + 2.0j])
    got = ctmm.characteristic_function(damper_loop(30.0, 0.1), s)
    expected = quasi_polynomial(s, 30.0, 0.1)
    np.testing.assert_allclose(got / got[2], expected / expected[2], rtol=1e-9)


@pytest.mark.parametrize("delay", [0.02, 0.1, 0.3])
def test_unstable_root_count_with_a_pure_damper(delay):
    system = damper_loop(30.0, delay)
    counts = stability.unstable_root_count(system)
    expected = int(np.sum(damper_roots(30.0, delay).real > 0))
    assert int(counts[0]) == expected and counts.certificate.certified


def test_delay_margin_and_roots_with_a_pure_damper():
    """Zero-delay count from the polynomial's roots (numpy.roots of the closed form at tau = 0); the
    critical delay is a zero of the quasi-polynomial on the imaginary axis; roots equal the reference."""
    system = damper_loop(30.0, 0.1)
    margin = stability.delay_margin(system)
    # closed form at tau = 0: (m1 s^2 + c s + k1)(m2 s^2 + c s + k2) - c s (c s - g)
    polynomial = np.polymul([M1, C12, K1], [M2, C12, K2])
    polynomial[2:] -= [C12**2, -C12 * 30.0, 0.0]
    undelayed = np.roots(polynomial)
    assert margin.unstable_roots_at_zero_delay == int(np.sum(undelayed.real > 0))
    s = 1j * margin.critical_frequency
    assert abs(quasi_polynomial(s, 30.0, margin.critical_delay)) < 1e-9 * abs(quasi_polynomial(s, 0.0, 0.0))
    roots = stability.characteristic_roots(system, re_min=-2.0, im_max=30.0)
    np.testing.assert_allclose(np.sort_complex(roots.roots), np.sort_complex(damper_roots(30.0, 0.1, -2.0, 30.0)),
                               rtol=1e-9)


def test_stability_chart_with_a_pure_damper():
    gains, delays = np.array([10.0, 30.0, 60.0]), np.array([0.02, 0.1, 0.3])
    chart = stability.stability_chart(damper_loop(30.0, 0.1), ("gain", gains), ("delay", delays))
    expected = [[int(np.sum(damper_roots(g, d).real > 0)) for g in gains] for d in delays]
    np.testing.assert_array_equal(chart.unstable_roots, expected)


# ------------------------------------------------------------------------------ substructure resonance
def two_mass_loop(gain: float, delay: float) -> ControlledChain:
    """Wall - k 100 - m 1 - k12 - m2 - k2 - wall (m1 on k1 resonates at 10 rad/s), u = -g v2(t - tau)."""
    plant = ctmm.Chain("two", [Fixed("g"), Spring("k1", 100.0), Mass("m1", 1.0), Spring("k12", 40.0),
                               Mass("m2", 0.5), Spring("k2", 60.0), Fixed("w")])
    return ControlledChain(plant, [Feedback("loop", "m2.v", "m1", gain=gain, delay=delay)])


def two_mass_determinant(s: np.ndarray, gain: float, delay: float) -> np.ndarray:
    s = np.asarray(s, dtype=complex)
    return (s**2 + 140.0) * (0.5 * s**2 + 100.0) - (-40.0) * (-40.0 + gain * s * np.exp(-s * delay))


def test_characteristic_function_at_a_substructure_resonance():
    """s = 10i: LinAlgError before; now the certified circle mean, against the closed form."""
    system = two_mass_loop(2.0, 0.1)
    s = np.array([10.0j, 10.0j * (1 + 1e-6), 3.0j, 10.0 + 0j])
    got = ctmm.characteristic_function(system, s)
    expected = two_mass_determinant(s, 2.0, 0.1)
    np.testing.assert_allclose(got / got[2], expected / expected[2], rtol=1e-9)
    model = LoopCharacteristic(system)
    values = model.evaluate(s, gain=[2.0, 5.0, 0.0], delay=[0.1, 0.4, 0.0])   # scaled per s: compare rows
    exact = np.array([two_mass_determinant(s, g, tau) for g, tau in [(2.0, 0.1), (5.0, 0.4), (0.0, 0.0)]])
    np.testing.assert_allclose(values[:2] / values[2], exact[:2] / exact[2], rtol=1e-9)


def test_stability_chart_with_a_substructure_resonance_on_its_samples():
    """The inerter chain of tests/test_inerter.py with k1 = 100 (m1's clamped resonance 10 rad/s on
    the chart's samples: raw LinAlgError before) against the counts of the global delay equation."""
    masses, k12, k3, b12, b23, k23 = (1.0, 0.5, 0.8), 40.0, 60.0, 0.3, 0.2, 5.0
    plant = ctmm.Chain("inerters", [Fixed("g"), Spring("k1", 100.0), Mass("m1", masses[0]),
                                    Inerter("b12", b12, stiffness=k12, damping=0.7), Mass("m2", masses[1]),
                                    Inerter("b23", b23, stiffness=k23), Mass("m3", masses[2]), Spring("k3", k3),
                                    Fixed("wall")])
    system = ControlledChain(plant, [Feedback("loop", "m3.v", "b12", gain=5.0, delay=0.0)])
    M, C, K = ref.assemble(ref.InerterChain(masses, [100.0, k12, k23, k3], damping=[0.0, 0.7, 0.0, 0.0],
                                            inertance=[0.0, b12, b23, 0.0], start="fixed", end="fixed"))
    loop = np.outer([-1.0, 1.0, 0.0], [0.0, 0.0, 1.0])
    gains, delays = np.array([2.0, 5.0, 8.0]), np.array([0.05, 0.2, 0.35])
    chart = stability.stability_chart(system, ("gain", gains), ("delay", delays))
    expected = []
    for d in delays:
        row = []
        for g in gains:
            A0, delayed = dde.second_order_system(M, C, K, [(np.zeros((3, 3)), g * loop, d)])
            row.append(int(np.sum(dde_verified.verified_roots(A0, delayed, 60, re_min=0.0, im_max=100.0).real > 0)))
        expected.append(row)
    np.testing.assert_array_equal(chart.unstable_roots, expected)
    assert 0 < np.sum(chart.stable) < chart.stable.size


# ------------------------------------------------------------------------------ the circle mean itself
def test_circle_mean_of_entire_functions_and_its_refusal():
    """exp(s) / s - 1/s is entire with value 1 at 0 (a removable NaN there); a true pole is refused."""
    def removable(s):
        with np.errstate(all="ignore"):
            return np.log((np.exp(s) - 1.0) / s)[None, :]

    logs = entire_logs(removable, np.array([0.0, 1.0 + 0j]))
    np.testing.assert_allclose(np.exp(logs[0]), [1.0, np.e - 1.0], rtol=1e-12)

    def raising(s):
        if np.any(s == 2.0):
            raise np.linalg.LinAlgError("Singular matrix")
        return np.log(s * s)[None, :]

    np.testing.assert_allclose(np.exp(entire_logs(raising, np.array([1.0, 2.0, 3.0]))[0]), [1.0, 4.0, 9.0],
                               rtol=1e-12)
    assert entire_logs(lambda s: np.log(s)[None, :], np.array([0j]))[0, 0].real == -np.inf   # a true zero
    with pytest.raises(SingularSystemError, match="cannot be evaluated at s = 0"):
        circle_mean_logs(lambda s: np.log(1.0 / s**3 + s)[None, :], 0.0)     # a pole, not removable


def test_undamped_inerter_with_a_spring_at_its_connector_zero():
    """b s^2 + k = 0 at s = 20i (b = 0.25, k = 100): on the imaginary axis.  Delta there against the
    closed form det(s^2 M + K + g s e^(-s tau) E12) with M = [[m1 + b, -b], [-b, m2 + b]]; counts
    against the verified delay-equation roots (and the eigenvalues without delay)."""
    b, k, m1, m2, k1, k2, gain = 0.25, 100.0, 1.0, 0.5, 97.0, 50.0, 2.0
    plant = ctmm.Chain("undamped", [Fixed("g"), Spring("k1", k1), Mass("m1", m1), Inerter("b", b, stiffness=k),
                                    Mass("m2", m2), Spring("k2", k2), Fixed("w")])
    system = ControlledChain(plant, [Feedback("loop", "m2.v", "m1", gain=gain, delay=0.1)])
    M = np.array([[m1 + b, -b], [-b, m2 + b]])
    K = np.array([[k1 + k, -k], [-k, k + k2]])

    def closed_form(s, tau):
        return np.array([np.linalg.det(z * z * M + K + gain * z * np.exp(-z * tau) * E12) for z in s])

    s = np.array([20.0j, 3.0j])
    got = ctmm.characteristic_function(system, s)
    expected = closed_form(s, 0.1)
    assert got[0] / got[1] == pytest.approx(expected[0] / expected[1], rel=1e-9)
    delays = [0.0, 0.1, 0.5, 1.0]
    first_order = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, gain * E12)]])
    expected_counts = [int(np.sum(np.linalg.eigvals(first_order).real > 0))]
    for tau in delays[1:]:
        A0, delayed = dde.second_order_system(M, np.zeros((2, 2)), K, [(np.zeros((2, 2)), gain * E12, tau)])
        expected_counts.append(int(np.sum(dde_verified.verified_roots(A0, delayed, 100, re_min=0.0, im_max=200.0).real > 0)))
    assert expected_counts == [2, 2, 4, 2]
    np.testing.assert_array_equal(stability.unstable_root_count(system, delay=delays), expected_counts)
