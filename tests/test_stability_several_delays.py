"""Defaults that left roots out: counts of one loop when another loop is delayed too (its open chain
has no realisation), the delay margin of a neutral loop whose crossings cannot be bookkept from the
count at zero delay, the gain margin's refusal of a loop max_factor makes neutral, and the right edge of
a root search.

The open chain of loop ``a`` (loop ``a`` removed, loop ``b`` closed with its delay) can be
unstable.  Its roots are poles of loop ``a``'s term, so ``|L_a|`` sampled on the imaginary axis
does not see them, and a contour height taken from it alone left them out (a count of 0 or 2
where the system has 2 or 4 roots in the right half plane).  Independent reference: Chebyshev
collocation of the two-delay equations assembled from M, C, K (``ctmm.reference.dde``), each
root polished by Newton on ``det(s^2 M + s C + K + Ka e^{-s ta} e1 e2^T + Kb s e^{-s tb} e2 e1^T)``.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.optimize

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.reference.dde import chebyshev_collocation_roots, newton_refine_root, second_order_system
from ctmm.errors import ModelError
from ctmm.stability import characteristic_roots, delay_margin, gain_margin, spectral_abscissa, unstable_root_count

M = np.diag([1.0, 0.5])
K = np.array([[3.0, -2.0], [-2.0, 2.0]])
C = np.array([[0.1, -0.05], [-0.05, 0.05]])


def two_loop_chain(ka, ta, kb, tb):
    plant = ctmm.Chain("pair", [Fixed("w"), SpringDamper("k1", 1.0, 0.05), Mass("m1", 1.0),
                                SpringDamper("k2", 2.0, 0.05), Mass("m2", 0.5), Free("e")])
    return ControlledChain(plant, [Feedback("a", "m2.x", "m1", gain=ka, delay=ta),
                                   Feedback("b", "m1.v", "m2", gain=kb, delay=tb)])


def reference_count(ka, ta, kb, tb):
    """Roots with Re s > 0 of M x'' + C x' + K x = -ka e1 x2(t - ta) - kb e2 x1'(t - tb)."""
    G, H = np.zeros((2, 2)), np.zeros((2, 2))
    G[0, 1], H[1, 0] = ka, kb
    A0, delayed = second_order_system(M, C, K, [(G, np.zeros((2, 2)), ta), (np.zeros((2, 2)), H, tb)])
    candidates = chebyshev_collocation_roots(A0, delayed, 80)
    roots = {complex(np.round(newton_refine_root(A0, delayed, z), 8))
             for z in candidates if z.real > -0.05 and abs(z) < 20}
    return sum(1 for z in roots if z.real > 0)


@pytest.mark.parametrize("ka, ta, kb, tb", [(0.47, 1.23, -0.77, 1.6), (-0.14, 2.65, 0.52, 0.4)])
@pytest.mark.parametrize("loop", ["a", "b"])
def test_count_holds_the_roots_of_the_delayed_open_chain(ka, ta, kb, tb, loop):
    expected = reference_count(ka, ta, kb, tb)
    assert expected > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        counts = unstable_root_count(two_loop_chain(ka, ta, kb, tb), loop=loop)
    assert int(counts[0]) == expected
    assert not counts.certificate.certified


def test_neutral_loop_delay_margin_claims_no_interval_holding_unstable_roots():
    """Acceleration feedback at the actuated mass, m s^2 + c s + k + g s^2 e^{-s tau} with g / m = 1.5 > 1:
    a neutral equation whose root chain Re s -> ln(g / m) / tau > 0 is unstable for every delay.  With
    im_max the crossings at 0.63 rad/s move pairs to the left from a count of 0, which the running count
    turned into a stable interval (0, 39 s).  Reference: Newton on the closed form from the asymptotic
    roots (ln(g / m) + 11 pi i) / tau, each verified with Re s > 0."""
    m, c, k, g = 1.0, 0.1, 1.0, 1.5
    plant = ctmm.Chain("o", [Fixed("w"), SpringDamper("k", k, c), Mass("m", m), Free("e")])
    system = ControlledChain(plant, [Feedback("acc", "m.a", "m", gain=g, delay=0.01)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        margin = delay_margin(system, im_max=50.0)
    assert not margin.certificate.certified
    for tau in np.linspace(0.5, margin.delay_max, 12):
        s = complex((np.log(g / m) + 11j * np.pi) / tau)
        for _ in range(60):
            e = np.exp(-s * tau)
            s -= ((m * s * s + c * s + k) + g * s * s * e) / (2 * m * s + c + g * e * (2 * s - tau * s * s))
        assert abs((m * s * s + c * s + k) + g * s * s * np.exp(-s * tau)) < 1e-9 * abs(s) ** 2
        assert s.real > 0
        assert not any(lo <= tau <= hi for lo, hi in margin.stable_intervals), (tau, s)
        assert margin.delay + margin.margin < tau


def test_gain_margin_names_the_max_factor_that_makes_the_loop_neutral():
    """u = -(0.3 a + x)(t - 0.2 s) on a unit mass: |L(inf)| = 0.3 k / m, so gain factors above
    1 / (2 * 0.3) = 1.6667 make the loop term's limit reach 1/2.  The default max_factor = 100 was refused
    with "its loop term tends to 30", without naming max_factor; a max_factor below the limit works and
    gives the crossings of the closed form f(omega) = -(1 - omega^2 + 0.1 i omega) e^{i omega tau} / (1 - 0.3 omega^2)."""
    tau = 0.2
    plant = ctmm.Chain("o", [Fixed("w"), SpringDamper("k", 1.0, 0.1), Mass("m", 1.0), Free("e")])
    system = ControlledChain(plant, [Feedback("acc", [("m.a", 0.3), ("m.x", 1.0)], "m", gain=1.0, delay=tau)])
    with pytest.raises(ModelError, match=r"max_factor = 100; max_factor < 1\.66667 "):
        gain_margin(system)
    margin = gain_margin(system, max_factor=1.6)

    def imaginary(omega):
        return (-(1 - omega ** 2 + 0.1j * omega) * np.exp(1j * omega * tau) / (1 - 0.3 * omega ** 2)).imag

    omega = np.linspace(1e-3, 400.0, 400_001)
    exact = [-1.0]                                   # s = 0: f = -k / k_p
    for i in np.flatnonzero(np.diff(np.sign(imaginary(omega))) != 0):
        root = scipy.optimize.brentq(imaginary, omega[i], omega[i + 1], xtol=1e-15)
        factor = (-(1 - root ** 2 + 0.1j * root) * np.exp(1j * root * tau) / (1 - 0.3 * root ** 2)).real
        if abs(factor) <= 1.6:
            exact.append(factor)
    assert len(exact) == 2
    assert margin.crossing_factors == pytest.approx(sorted(exact), rel=1e-9)


def test_root_search_right_edge_holds_a_root_far_to_the_right():
    """x' = 40 x + x(t - 0.5): the rightmost root is 40 + W_0(0.5 e^{-20}) / 0.5 (Lambert W, real).  The
    heuristic right edge (no root in a strip next to re_min) stopped at Re s = 5 and reported the
    system stable with no root; the proven height of the certificate bounds every root right of re_min."""
    import control
    from scipy.special import lambertw

    from ctmm.linearized import DelayedLoop, LinearizedSystem

    a, b, tau = 40.0, 1.0, 0.5
    state_space = control.ss([[a]], [[1.0]], [[1.0]], [[0.0]], inputs=["L_u"], outputs=["L_y"], states=["x"])
    system = LinearizedSystem(state_space, (DelayedLoop("L", -b, tau),), None)
    exact = a + lambertw(b * tau * np.exp(-a * tau), 0).real / tau
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        abscissa = spectral_abscissa(system, re_min=-5.0, im_max=10.0)
        roots = characteristic_roots(system, re_min=-5.0, im_max=10.0)
    assert not abscissa.stable
    assert abscissa.value == pytest.approx(exact, rel=1e-12)
    assert roots.count == 1 and roots.roots[0] == pytest.approx(exact, rel=1e-12)


def test_root_search_right_edge_with_a_delay_free_loop_beside_the_delayed_one():
    """u = -1601 x (no delay) and u = -x(t - 0.5) on a unit mass with k = 1: s^2 - 1600 + e^{-s/2} = 0 has a
    real root near 40 (brentq on the closed form).  Several loops got no certificate and the heuristic edge
    at Re s = 5: reported stable with no root."""
    plant = ctmm.Chain("o", [Fixed("w"), SpringDamper("k", 1.0, 0.0), Mass("m", 1.0), Free("e")])
    system = ControlledChain(plant, [Feedback("q", "m.x", "m", gain=-1601.0, delay=0.0),
                                     Feedback("p", "m.x", "m", gain=1.0, delay=0.5)])
    exact = scipy.optimize.brentq(lambda s: s * s - 1600.0 + np.exp(-0.5 * s), 39.0, 41.0, xtol=1e-14)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        abscissa = spectral_abscissa(system, re_min=-5.0, im_max=10.0)
    assert not abscissa.stable
    assert abscissa.value == pytest.approx(exact, rel=1e-10)
