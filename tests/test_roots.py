"""Argument-principle root finder (ctmm.roots) against independent references.

References: Lambert W roots of scalar DDEs and Hayes' equation (ctmm.reference.dde, scipy
lambertw), Chebyshev collocation of the infinitesimal generator (Breda, Maset & Vermiglio 2005),
closed-form polynomials with known roots.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ctmm.errors import ModelError
from ctmm.reference.dde import (
    characteristic_function, chebyshev_collocation_roots,
    delayed_pd_oscillator_characteristic_function, delayed_pd_oscillator_dcurves, lambert_w_roots,
    scalar_characteristic_function, second_order_system)
from ctmm.roots import (ContourError, count_roots_in_rectangle, find_roots_in_rectangle,
                        rightmost_roots, spectral_abscissa)

HAYES = complex(-0.31813150520476413, 1.3372357014306895)      # W_0(-1), lambda = -e^(-lambda)


def hayes(s):
    return s + np.exp(-s)


def match(found: np.ndarray, reference: np.ndarray) -> float:
    """Largest distance in a one-to-one nearest matching (asserts equal sizes)."""
    assert found.size == reference.size, (found.size, reference.size)
    remaining = list(found)
    worst = 0.0
    for z in reference:
        k = int(np.argmin(np.abs(np.array(remaining) - z)))
        worst = max(worst, abs(remaining.pop(k) - z))
    return worst


# ------------------------------------------------------------------------------ Hayes
def test_hayes_rightmost_roots_from_the_root_finder():
    found = find_roots_in_rectangle(hayes, (-3.0, 2.0), (-10.0, 10.0))
    assert found.reliable and found.count == 4 and list(found.multiplicities) == [1, 1, 1, 1]
    assert abs(found.roots[0] - HAYES.conjugate()) < 1e-10
    assert abs(found.roots[1] - HAYES) < 1e-10
    assert np.all(found.error_estimates < 1e-10)
    assert abs(lambert_w_roots(0.0, -1.0, 1.0, 0) - found.roots[1]) < 1e-10


def test_hayes_spectral_abscissa_and_conjugate_symmetry():
    result = spectral_abscissa(hayes, im_max=10.0, re_min=-3.0, re_max=2.0,
                               conjugate_symmetric=True)
    assert abs(result.value - HAYES.real) < 1e-10 and result.error < 1e-10
    assert abs(result.root - HAYES) < 1e-10 and not result.below_re_min
    assert result.roots.roots[0] == np.conj(result.roots.roots[1])      # mirrored exactly
    assert result.stable
    empty = spectral_abscissa(hayes, im_max=10.0, re_min=0.0, re_max=2.0)
    assert empty.below_re_min and empty.value == 0.0 and empty.root is None and empty.stable
    unstable = spectral_abscissa(lambda s: s - 1.2 + np.exp(-s), im_max=10.0, re_min=-1.0,
                                 re_max=2.0, conjugate_symmetric=True)
    assert unstable.root.imag == 0.0 and unstable.value > 0 and not unstable.stable
    ax = result.roots.plot()
    assert ax.get_xlabel() == "Re s [1/s]"


def test_rightmost_roots_without_re_max_uses_a_noted_heuristic():
    found = rightmost_roots(hayes, im_max=5.0, re_min=-1.0)
    assert abs(found.roots[1] - HAYES) < 1e-10 and found.count == 2
    assert any("heuristic" in note for note in found.notes)


# ------------------------------------------------------------------------------ scalar DDEs
@pytest.mark.parametrize("a, b, tau", [(0.0, -1.0, 1.0), (0.5, -2.0, 1.3), (-1.0, 0.3, 2.0),
                                       (0.2, 0.1, 0.5), (-0.5, -3.0, 0.7), (1.0, -0.1, 3.0)])
def test_every_lambert_root_in_the_box_is_found_once(a, b, tau):
    box_re, box_im = (-4.0, 2.0), (-60.0, 60.0)
    reference = lambert_w_roots(a, b, tau, np.arange(-40, 40))
    inside = reference[(reference.real > box_re[0]) & (reference.real < box_re[1])
                       & (np.abs(reference.imag) < box_im[1])]
    found = find_roots_in_rectangle(scalar_characteristic_function(a, b, tau), box_re, box_im)
    assert found.reliable and found.count == inside.size
    assert np.all(found.multiplicities == 1)
    assert np.min(np.abs(np.subtract.outer(found.roots, found.roots))
                  + np.eye(found.roots.size)) > 1e-3                    # no duplicates
    assert match(found.roots, inside) < 1e-10                           # none missed


# ------------------------------------------------------------------------------ PD oscillator
def test_delayed_pd_oscillator_roots_collocation_vs_root_finder():
    omega_n, zeta, tau, kp, kd = 2.0, 0.05, 0.3, 1.5, 0.4
    delta = delayed_pd_oscillator_characteristic_function(omega_n, zeta, tau, kp, kd)
    found = rightmost_roots(delta, im_max=100.0, re_min=-25.0, re_max=5.0, conjugate_symmetric=True)
    assert found.reliable and found.count == 11
    A0, delayed = second_order_system([[1.0]], [[2 * zeta * omega_n]], [[omega_n ** 2]],
                                      [([[kp]], [[kd]], tau)])
    collocation = chebyshev_collocation_roots(A0, delayed, 60)
    collocation = collocation[(collocation.real > -25) & (np.abs(collocation.imag) < 100)]
    assert match(found.roots, collocation) < 1e-8
    full = rightmost_roots(delta, im_max=100.0, re_min=-25.0, re_max=5.0)
    assert match(full.roots, found.roots) < 1e-10
    assert found.roots[-1].real == found.roots[-2].real                  # mirrored pairs


def test_dcurve_point_gives_a_root_on_the_imaginary_axis():
    omega_n, zeta, tau, Omega = 2.0, 0.05, 0.3, 3.1
    curves = delayed_pd_oscillator_dcurves(omega_n, zeta, tau, [Omega])
    delta = delayed_pd_oscillator_characteristic_function(
        omega_n, zeta, tau, curves.proportional_gain[0], curves.derivative_gain[0])
    found = rightmost_roots(delta, im_max=20.0, re_min=-0.5, re_max=5.0, conjugate_symmetric=True)
    on_axis = found.roots[np.abs(found.roots.real) < 1e-9]
    assert np.min(np.abs(on_axis - 1j * Omega)) < 1e-10


# ------------------------------------------------------------------------------ multiple roots
def test_double_root_is_counted_twice_and_reported_once():
    r0 = 0.3 + 0.4j
    found = find_roots_in_rectangle(lambda s: (s - r0) ** 2 * (s + 1) * (s - 2j), (-3, 3), (-3, 3))
    assert count_roots_in_rectangle(lambda s: (s - r0) ** 2 * (s + 1), (-3, 3), (-3, 3)).count == 3
    assert found.count == 4 and found.reliable
    k = int(np.argmin(np.abs(found.roots - r0)))
    assert found.multiplicities[k] == 2 and abs(found.roots[k] - r0) < 1e-10
    assert match(found.expanded(), np.array([r0, r0, -1, 2j])) < 1e-10


def test_double_root_of_a_rounded_polynomial_is_within_its_error_estimate():
    coefficients = np.poly([0.7 - 0.2j, 0.7 - 0.2j, -1.5, 1j])        # rounding splits the pair
    found = find_roots_in_rectangle(lambda s: np.polyval(coefficients, s), (-2, 2), (-2, 2))
    assert found.count == 4 and int(found.multiplicities.sum()) == 4 and found.reliable
    k = int(np.argmin(np.abs(found.roots - (0.7 - 0.2j))))
    assert abs(found.roots[k] - (0.7 - 0.2j)) < max(1e-7, 2 * found.error_estimates[k])


def test_two_roots_a_micro_unit_apart_are_separated():
    roots = np.array([0.5, 0.5 + 1e-6, -1j])
    def delta(s):
        return np.prod(s[..., None] - roots, axis=-1)

    found = find_roots_in_rectangle(delta, (-3, 3), (-3, 3))
    assert found.count == 3 and np.all(found.multiplicities == 1) and found.reliable
    assert match(found.roots, roots) < 1e-12
    assert count_roots_in_rectangle(delta, (0.4, 0.6), (-0.1, 0.1)).count == 2


@settings(max_examples=15, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.9, 1.9), st.floats(-1.9, 1.9)), min_size=1, max_size=8),
       st.floats(0.0, 2.0))
def test_random_root_sets_are_found_exactly(points, delay):
    roots = np.array([complex(x, y) for x, y in points])
    distinct = np.min(np.abs(np.subtract.outer(roots, roots)) + np.eye(roots.size) * 9)
    found = find_roots_in_rectangle(
        lambda s: np.prod(s[..., None] - roots, axis=-1) * np.exp(-delay * s), (-2, 2), (-2, 2))
    assert found.count == roots.size and int(found.multiplicities.sum()) == roots.size
    if distinct > 1e-5:
        assert match(found.roots, roots) < 1e-9


# ------------------------------------------------------------------------------ errors
def test_count_raises_when_a_root_lies_on_the_contour():
    with pytest.raises(ContourError, match=r"vanishes on the contour .* s = 0-1j") as info:
        count_roots_in_rectangle(lambda s: s ** 2 + 1, (-1, 1), (-1, 1))
    assert info.value.location == -1j
    with pytest.raises(ContourError, match=r"zero \(or pole\) on or within .* near s = 1\+0\.3"):
        count_roots_in_rectangle(lambda s: s - (1 + 1e-13 + 0.3j), (-1, 1), (-1, 1))
    with pytest.raises(ContourError, match=r"not finite on the contour .* at s = 0\.5"):
        count_roots_in_rectangle(lambda s: np.where(s.real > 0.4, np.nan, s + 2),
                                 (-1, 0.5), (-1, 1))
    with pytest.raises(ContourError, match=r"zero \(or pole\) on or within"):
        count_roots_in_rectangle(lambda s: 1 / (s - 0.5), (-1, 0.5), (-1, 1))
    assert isinstance(ContourError("x", 0j), ModelError)


def test_invalid_arguments_are_reported():
    with pytest.raises(ModelError, match=r"re_range must satisfy low < high, got \(1.0, -1.0\)"):
        count_roots_in_rectangle(hayes, (1, -1), (-1, 1))
    with pytest.raises(ModelError, match="im_range must be a pair"):
        find_roots_in_rectangle(hayes, (-1, 1), 3.0)
    with pytest.raises(ModelError, match="same shape as s"):
        count_roots_in_rectangle(lambda s: np.sum(s), (-1, 1), (-1, 1))
    with pytest.raises(ModelError, match="char_fn must be a callable"):
        count_roots_in_rectangle("hayes", (-1, 1), (-1, 1))
    with pytest.raises(ModelError, match=r"max_log_step must be in \(0, 1.5\]"):
        count_roots_in_rectangle(hayes, (-1, 1), (-1, 1), max_log_step=3.0)
    with pytest.raises(ModelError, match="im_max must be > 0"):
        rightmost_roots(hayes, im_max=0.0, re_min=-1.0)
    with pytest.raises(ModelError, match="re_max must be > re_min"):
        rightmost_roots(hayes, im_max=1.0, re_min=1.0, re_max=0.0)


# ------------------------------------------------------------------------------ batching, options
def test_contour_is_evaluated_in_batched_calls():
    calls = []

    def recorded(s):
        calls.append(s.shape)
        return hayes(s)

    result = count_roots_in_rectangle(recorded, (-3, 2), (-10, 10))
    assert result.count == 4 and result.reliable and result.n_calls == len(calls) <= 10
    assert all(len(shape) == 1 and shape[0] >= 8 for shape in calls)
    assert abs(result.root_sum - sum(lambert_w_roots(0.0, -1.0, 1.0, [-2, -1, 0, 1]))) < 1e-2


def test_seeds_and_derivative_give_the_same_roots_for_less_work():
    delta = scalar_characteristic_function(0.1, -1.2, 2.5)
    plain = find_roots_in_rectangle(delta, (-3, 1), (-30, 30))
    seeded = find_roots_in_rectangle(delta, (-3, 1), (-30, 30), seeds=plain.roots * (1 + 1e-5))
    exact = find_roots_in_rectangle(delta, (-3, 1), (-30, 30),
                                    derivative=lambda s: 1 - 1.2 * 2.5 * np.exp(-2.5 * s))
    assert match(seeded.roots, plain.roots) < 1e-11 and match(exact.roots, plain.roots) < 1e-11
    assert seeded.n_calls < plain.n_calls and seeded.reliable and exact.reliable


def test_fast_oscillation_from_a_long_delay_is_not_aliased():
    """s^2 + 0.1 s + 1 + 0.5 e^(-10 s): e^(-10 s) turns 10 rad per unit of Im s."""
    delta = lambda s: s * s + 0.1 * s + 1 + 0.5 * np.exp(-10 * s)      # noqa: E731
    half = rightmost_roots(delta, im_max=40.0, re_min=-1.0, re_max=1.0, conjugate_symmetric=True)
    full = find_roots_in_rectangle(delta, (-1.0, 1.0), (-40.0, 40.0))
    assert half.reliable and full.reliable and half.count == full.count > 100
    assert match(full.roots, half.roots) < 1e-10
    residual = np.abs(delta(full.roots)) / (1 + np.abs(full.roots) ** 2)
    assert residual.max() < 1e-12


def test_real_roots_are_exact_with_conjugate_symmetry():
    delta = lambda s: (s + 1 - 0.5 * np.exp(-s)) * (s * s + 0.4 * s + 4)  # noqa: E731
    half = rightmost_roots(delta, im_max=20.0, re_min=-3.0, re_max=2.0, conjugate_symmetric=True)
    full = rightmost_roots(delta, im_max=20.0, re_min=-3.0, re_max=2.0)
    assert match(half.roots, full.roots) < 1e-10 and half.count == full.count
    real = half.roots[half.roots.imag == 0]
    assert real.size == 1 and abs(delta(real)[0]) < 1e-13


# ------------------------------------------------------------------------------ 2-DOF system
def test_two_dof_delayed_system_collocation_vs_argument_principle():
    M = np.diag([1.0, 2.0])
    C = np.array([[0.2, -0.1], [-0.1, 0.3]])
    K = np.array([[30.0, -10.0], [-10.0, 20.0]])
    G = np.array([[5.0, 0.0], [0.0, 0.0]])
    H = np.array([[0.0, 0.8], [0.0, 0.0]])
    A0, delayed = second_order_system(
        M, C, K, [(G, H, 0.2), (0.5 * np.eye(2), np.zeros((2, 2)), 0.35)])
    delta = characteristic_function(A0, delayed)
    found = rightmost_roots(delta, im_max=60.0, re_min=-6.0, re_max=5.0, conjugate_symmetric=True)
    assert found.reliable and found.count >= 4
    assert found.roots[0].real > 0                                      # this loop is unstable
    collocation = chebyshev_collocation_roots(A0, delayed, 60)
    collocation = collocation[(collocation.real > -6) & (np.abs(collocation.imag) < 60)]
    assert match(found.roots, collocation) < 1e-8
