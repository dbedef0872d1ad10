"""Independent DDE references: Lambert W, Hayes region, D-curves, Chebyshev collocation.

Analytic anchors
----------------
* Hayes' equation lambda = -e^(-lambda) (x' = -x(t - 1)): rightmost roots W_0(-1) and its
  conjugate, -0.318131505204764 +/- 1.337235701430689i (the constant W_0(-1); 9-digit value
  -0.318131505 +/- 1.337235701i as quoted in the literature, e.g. Insperger & Stépán 2011).
* Hayes (1950) stability region of x' = a x + b x(t - tau), closed form.
* D-subdivision curves of the delayed PD oscillator, FORMULAS 6.2.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.reference.dde import (
    characteristic_function, chebyshev_collocation_roots,
    delayed_pd_oscillator_characteristic_function, delayed_pd_oscillator_dcurves, hayes_boundary,
    hayes_critical_b, hayes_critical_delay, hayes_is_stable, lambert_w_roots, newton_refine_root,
    scalar_characteristic_function, second_order_system)

HAYES = complex(-0.31813150520476413, 1.3372357014306895)      # W_0(-1)
HAYES_LITERATURE = complex(-0.318131505, 1.337235701)           # 9 digits


# ------------------------------------------------------------------------------ Lambert W
def test_hayes_equation_rightmost_roots_from_lambert_w():
    roots = lambert_w_roots(0.0, -1.0, 1.0, [0, -1])
    assert abs(roots[0] - HAYES) < 1e-10
    assert abs(roots[1] - HAYES.conjugate()) < 1e-10
    assert abs(roots[0] - HAYES_LITERATURE) < 1e-9


@pytest.mark.parametrize("a, b, tau", [(0.0, -1.0, 1.0), (0.5, -2.0, 1.3), (-1.0, 0.3, 2.0),
                                       (0.2, 0.1, 0.5), (-0.5, -3.0, 0.7), (1.0, -0.1, 3.0)])
def test_lambert_roots_solve_the_characteristic_equation(a, b, tau):
    """Checks the scaling s = a + W_k(b tau e^(-a tau))/tau for tau != 1 and a != 0."""
    branches = np.arange(-6, 7)
    roots = lambert_w_roots(a, b, tau, branches)
    residual = roots - a - b * np.exp(-roots * tau)
    assert np.all(np.abs(residual) <= 1e-12 * (1 + np.abs(roots)))
    assert np.unique(np.round(roots, 8)).size == branches.size          # one root per branch
    # principal branch is rightmost; conjugates pair k with -k (b > 0) or -k-1 (b < 0)
    assert roots[6].real >= roots.real.max() - 1e-12
    mirror = [-2, -3] if b > 0 else [-3, -4]
    assert np.allclose(lambert_w_roots(a, b, tau, [2, 3]),
                       np.conj(lambert_w_roots(a, b, tau, mirror)), atol=1e-13)


def test_scalar_characteristic_function_vanishes_at_lambert_roots():
    delta = scalar_characteristic_function(0.3, -1.7, 0.8)
    roots = lambert_w_roots(0.3, -1.7, 0.8, np.arange(-4, 4))
    assert np.max(np.abs(delta(roots))) < 1e-12 * np.max(np.abs(roots))
    assert delta(np.zeros((2, 3), complex)).shape == (2, 3)


# ------------------------------------------------------------------------------ Hayes region
def test_hayes_critical_delay_puts_the_rightmost_root_on_the_imaginary_axis():
    a, b = -0.5, -2.0
    tau_c = hayes_critical_delay(a, b)
    root = lambert_w_roots(a, b, tau_c, 0)
    assert abs(root.real) < 1e-12
    assert abs(root.imag - math.sqrt(b * b - a * a)) < 1e-12
    assert hayes_critical_delay(-2.0, 1.0) == math.inf                # |b| < |a|: any delay


@pytest.mark.parametrize("a, tau", [(0.5, 1.0), (0.0, 1.0), (-2.0, 0.5), (0.45, 2.0)])
def test_hayes_critical_b_is_a_crossing(a, tau):
    b = hayes_critical_b(a, tau)
    root = lambert_w_roots(a, b, tau, 0)
    assert abs(root.real) < 1e-10
    assert not hayes_is_stable(a, b * (1 + 1e-6), tau)
    assert hayes_is_stable(a, b * (1 - 1e-6), tau)


def test_hayes_region_agrees_with_the_principal_lambert_root():
    rng = np.random.default_rng(3)
    samples = zip(rng.uniform(-3, 1.5, 300), rng.uniform(-4, 2, 300), rng.uniform(0.1, 2, 300))
    for a, b, tau in samples:
        rightmost = lambert_w_roots(a, b, tau, 0).real
        if abs(rightmost) > 1e-6:
            assert hayes_is_stable(a, b, tau) == (rightmost < 0), (a, b, tau)


def test_hayes_boundary_points_have_an_imaginary_root():
    tau = 0.7
    omega = np.linspace(0.1, 0.99 * math.pi / tau, 7)
    a, b = hayes_boundary(tau, omega)
    for ai, bi, wi in zip(a, b, omega):
        delta = scalar_characteristic_function(ai, bi, tau)
        assert abs(delta(np.array(1j * wi))) < 1e-12 * (1 + abs(bi))
    with pytest.raises(ModelError, match=r"omega\*tau must lie in \(0, pi\)"):
        hayes_boundary(1.0, [4.0])


# ------------------------------------------------------------------------------ D-curves
def test_dcurve_points_satisfy_the_characteristic_equation():
    omega_n, zeta, tau = 2.0, 0.05, 0.3
    Omega = np.linspace(0.05, 40.0, 400)
    curves = delayed_pd_oscillator_dcurves(omega_n, zeta, tau, Omega)
    for W, kp, kd in zip(Omega, curves.proportional_gain, curves.derivative_gain):
        delta = delayed_pd_oscillator_characteristic_function(omega_n, zeta, tau, kp, kd)
        scale = W ** 2 + omega_n ** 2 + abs(kp) + abs(kd) * W
        assert abs(delta(np.array(1j * W))) <= 1e-12 * scale
    static = delayed_pd_oscillator_characteristic_function(
        omega_n, zeta, tau, curves.static_proportional_gain, 3.0)
    assert abs(static(np.array(0j))) == 0.0
    with pytest.raises(ModelError, match="Omega must be non-zero"):
        delayed_pd_oscillator_dcurves(omega_n, zeta, tau, [0.0, 1.0])


# ------------------------------------------------------------------------------ collocation
def test_collocation_gives_hayes_roots():
    roots = chebyshev_collocation_roots([[0.0]], [([[-1.0]], 1.0)], 30)
    assert abs(roots[0] - HAYES.conjugate()) < 1e-10
    assert abs(roots[1] - HAYES) < 1e-10
    refined = chebyshev_collocation_roots([[0.0]], [([[-1.0]], 1.0)], 12, refine=2)
    assert abs(refined[1] - HAYES) < 1e-13


def test_collocation_converges_spectrally_to_lambert_roots():
    a, b, tau = 0.4, -1.5, 1.2
    exact = lambert_w_roots(a, b, tau, np.arange(-3, 3))
    errors = []
    for n in (6, 12, 24, 48):
        approx = chebyshev_collocation_roots([[a]], [([[b]], tau)], n)
        errors.append(max(np.min(np.abs(approx - z)) for z in exact))
    assert errors[-1] < 1e-10
    assert errors[0] > 100 * errors[2]                                   # geometric decay
    newton = newton_refine_root([[a]], [([[b]], tau)], exact[0] + 1e-3)
    assert abs(newton - exact[0]) < 1e-13


def test_collocation_with_two_delays_matches_the_determinant():
    A0 = np.array([[0.0, 1.0], [-4.0, -0.2]])
    delayed = [(np.array([[0.0, 0.0], [-1.0, 0.0]]), 0.4),
               (np.array([[0.0, 0.0], [0.0, -0.6]]), 0.25)]
    delta = characteristic_function(A0, delayed)
    roots = chebyshev_collocation_roots(A0, delayed, 40)
    # eigenvalues of large modulus are spurious (here the true root chain runs far to the
    # left, Re s ~ -4 ln(|s|/0.6)); those of moderate modulus are roots
    head = roots[np.abs(roots) < 40]
    assert head.size >= 4
    scale = 1 + np.abs(head) ** 2
    assert np.all(np.abs(delta(head)) < 1e-10 * scale)


def test_no_delay_gives_matrix_eigenvalues():
    A0 = np.array([[0.0, 1.0], [-9.0, -0.6]])
    roots = chebyshev_collocation_roots(A0, [], 10)
    assert np.allclose(np.sort_complex(roots), np.sort_complex(np.linalg.eigvals(A0)))


def test_second_order_form_has_the_determinant_of_the_second_order_system():
    M = np.diag([1.0, 2.0])
    C = np.array([[0.2, -0.1], [-0.1, 0.3]])
    K = np.array([[30.0, -10.0], [-10.0, 20.0]])
    G, H = np.array([[5.0, 0.0], [0.0, 0.0]]), np.array([[0.0, 0.8], [0.0, 0.0]])
    A0, delayed = second_order_system(M, C, K, [(G, H, 0.2)])
    assert A0.shape == (4, 4) and delayed[0][0].shape == (4, 4) and delayed[0][1] == 0.2
    delta = characteristic_function(A0, delayed)
    s = np.array([0.3 + 2.0j, -1.0 + 7.5j, 2.0 - 1.0j])
    direct = np.array([np.linalg.det(z * z * M + z * C + K + (G + z * H) * np.exp(-0.2 * z))
                       for z in s])
    assert np.allclose(delta(s), direct / np.linalg.det(M), rtol=1e-12)


# ------------------------------------------------------------------------------ errors
def test_invalid_parameters_name_the_parameter():
    with pytest.raises(ModelError, match="tau must be > 0"):
        lambert_w_roots(0.0, -1.0, 0.0, 0)
    with pytest.raises(ModelError, match="b must be non-zero"):
        lambert_w_roots(0.0, 0.0, 1.0, 0)
    with pytest.raises(ModelError, match="branches must be an int"):
        lambert_w_roots(0.0, -1.0, 1.0, [0.5])
    with pytest.raises(ModelError, match=r"delayed\[0\] matrix must be \(2, 2\)"):
        chebyshev_collocation_roots(np.eye(2), [(np.eye(3), 1.0)], 10)
    with pytest.raises(ModelError, match=r"delayed\[0\] delay tau_k must be > 0"):
        chebyshev_collocation_roots(np.eye(2), [(np.eye(2), -1.0)], 10)
    with pytest.raises(ModelError, match="n_nodes must be an int >= 2"):
        chebyshev_collocation_roots(np.eye(2), [(np.eye(2), 1.0)], 1)
    with pytest.raises(ModelError, match="M must be invertible"):
        second_order_system(np.zeros((1, 1)), [[0.0]], [[1.0]], [])
    with pytest.raises(ModelError, match=r"delayed_terms\[0\] must be \(G_k, H_k, tau_k\)"):
        second_order_system([[1.0]], [[0.0]], [[1.0]], [([[1.0]], 0.1)])
    with pytest.raises(ModelError, match="a\\*tau must be < 1"):
        hayes_critical_b(2.0, 1.0)
