"""Tests of the global-equation chain references (ctmm.reference.chain / delay_chain).

Every check compares against something independent of the code under test: published or
closed-form numbers (FORMULAS §2.1, §6.2, DESIGN §6 Hayes roots), hand-derived 1- and 2-DOF
algebra, scipy.special.lambertw, sympy's exact method of steps, or a separately written
fixed-step integrator.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.special import lambertw

from ctmm.errors import ModelError
from ctmm.reference.chain import (GlobalChain, assemble, assemble_banded, complex_eigenvalues,
                                  exact_response, frequency_response, frequency_response_banded,
                                  mode_shapes, natural_frequencies, newmark_global,
                                  solve_ivp_response, state_space, static_load,
                                  unstretched_positions)
from ctmm.reference.delay_chain import (GlobalLoop, closed_loop_characteristic,
                                        closed_loop_frequency_response, closed_loop_roots,
                                        method_of_steps)

# --------------------------------------------------------------------------------------------
# FORMULAS §2.1: 3-mass chain m = (1, 2, 1.5), k = (100, 200, 150, 120)
# --------------------------------------------------------------------------------------------
MASSES = [1.0, 2.0, 1.5]


def three_mass(start: str, end: str, damping=None) -> GlobalChain:
    k = np.array([100.0, 200.0, 150.0, 120.0])
    c = None if damping is None else np.array(damping, dtype=float)
    for index, side in ((0, start), (3, end)):
        if side == "free":
            k[index] = 0.0
            if c is not None:
                c[index] = 0.0
    return GlobalChain(MASSES, k, c, start=start, end=end)


@pytest.mark.parametrize("start, end, expected", [
    ("fixed", "free", [3.96143496, 12.62168899, 20.0]),
    ("fixed", "fixed", [6.5320391, 14.47052161, 20.0732775]),
    ("free", "free", [0.0, 11.43240802, 18.55532395]),
])
def test_three_mass_natural_frequencies_match_formulas(start, end, expected):
    omega = natural_frequencies(three_mass(start, end))
    np.testing.assert_allclose(omega, expected, rtol=0, atol=6e-8)
    if start == end == "free":
        assert omega[0] == 0.0                   # rigid mode kept as an exact zero


def test_three_mass_damped_roots_match_formulas():
    chain = three_mass("fixed", "free", damping=[0.5, 1.0, 0.8, 0.0])
    expected = np.array([-0.03942051 + 3.96123907j, -0.42003903 + 12.61471354j,
                         -1.00720712 + 19.97459599j])
    roots = complex_eigenvalues(chain)
    for part in (np.real, np.imag):                    # 8 printed decimals: half-unit 5e-9
        np.testing.assert_allclose(part(roots[1::2]), part(expected), rtol=0, atol=5.1e-9)
        np.testing.assert_allclose(part(roots[0::2]), part(expected.conj()), rtol=0, atol=5.1e-9)


@pytest.mark.parametrize("n", [1, 5, 20])
def test_uniform_fixed_free_closed_form_frequencies_and_shapes(n):
    # ω_j = 2√(k/m) sin((2j−1)π/(2(2n+1))), shape x_i ∝ sin(i θ_j), θ_j = (2j−1)π/(2n+1)
    k, m = 1000.0, 0.1
    chain = GlobalChain.uniform(n, m, k, start="fixed", end="free")
    j = np.arange(1, n + 1)
    expected = 2 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    omega, shapes = mode_shapes(chain)
    np.testing.assert_allclose(omega, expected, rtol=1e-12)
    theta = (2 * j - 1) * np.pi / (2 * n + 1)
    closed = np.sin(np.outer(np.arange(1, n + 1), theta))
    closed /= np.sqrt(np.sum(m * closed ** 2, axis=0))       # mass-normalised
    np.testing.assert_allclose(np.abs(shapes), np.abs(closed), atol=1e-10)
    if n == 5:                                                 # FORMULAS §2.1 numbers
        np.testing.assert_allclose(
            omega, [28.462968, 83.083003, 130.972147, 168.250707, 191.898595], atol=6e-7)


def test_static_load_equals_series_springs_in_absolute_coordinates():
    # absolute equilibrium K X = F e_tip + static_load; series springs: X_i = X0_i + F Σ_{j<=i} 1/k_j
    k = np.array([100.0, 200.0, 150.0, 0.0])
    length = np.array([0.3, 0.2, 0.5, 0.0])
    chain = GlobalChain(MASSES, k, free_length=length, start="fixed", end="free")
    _, _, K = assemble(chain)
    tip = 7.0
    X = np.linalg.solve(K, static_load(chain) + np.array([0, 0, tip]))
    np.testing.assert_allclose(X, np.cumsum(length[:3]) + tip * np.cumsum(1 / k[:3]), rtol=1e-13)
    fixed = GlobalChain(MASSES, [100.0, 200.0, 150.0, 120.0], free_length=[0.3, 0.2, 0.5, 0.4],
                        start="fixed", end="fixed")
    np.testing.assert_allclose(static_load(fixed), assemble(fixed)[2] @ unstretched_positions(fixed))
    # wall moved by d: one spring chain of total compliance, uniform tension d / Σ(1/k)
    d = 0.05
    X = np.linalg.solve(assemble(fixed)[2], static_load(fixed, end_position=1.4 + d))
    tension = d / np.sum(1 / fixed.stiffness)
    np.testing.assert_allclose(X - unstretched_positions(fixed),
                               tension * np.cumsum(1 / fixed.stiffness)[:3], rtol=1e-12)


# --------------------------------------------------------------------------------------------
# frequency response
# --------------------------------------------------------------------------------------------
def test_single_dof_frequency_response_closed_forms():
    m, k, c, kg = 2.0, 300.0, 1.5, 40.0
    chain = GlobalChain([m], [k, 0.0], [c, 0.0], ground_stiffness=[kg], start="fixed", end="free")
    w = np.linspace(0.0, 40.0, 81)
    H = 1.0 / (k + kg - m * w ** 2 + 1j * w * c)
    for function in (frequency_response, frequency_response_banded):
        np.testing.assert_allclose(function(chain, w, 0, 0, "displacement"), H, rtol=1e-13)
        np.testing.assert_allclose(function(chain, w, 0, 0, "velocity"), 1j * w * H, rtol=1e-13)
        np.testing.assert_allclose(function(chain, w, 0, 0, "acceleration"), -w ** 2 * H, rtol=1e-13)
        # connector 0: force by the wall on the mass = -(k + iωc)(X - 0); connector 1 absent
        np.testing.assert_allclose(function(chain, w, 0, 0, "force"), -(k + 1j * w * c) * H, rtol=1e-13)
        np.testing.assert_array_equal(function(chain, w, 0, 1, "force"), 0.0)
    assert frequency_response(chain, 3.0, 0, 0).shape == ()


def test_two_dof_frequency_response_hand_algebra():
    m1, m2, k1, k2, k3 = 1.0, 0.5, 100.0, 60.0, 30.0
    chain = GlobalChain([m1, m2], [k1, k2, k3], start="fixed", end="fixed")
    w = np.linspace(0.1, 30.0, 50)
    a, d, b = k1 + k2 - m1 * w ** 2, k2 + k3 - m2 * w ** 2, -k2
    det = a * d - b * b
    np.testing.assert_allclose(frequency_response(chain, w, 0, 0), d / det, rtol=1e-12)
    np.testing.assert_allclose(frequency_response(chain, w, 0, 1), -b / det, rtol=1e-12)
    # force in the end connector 2 (mass 1 on the wall): -k3 (0 - X_1)
    np.testing.assert_allclose(frequency_response(chain, w, 0, 2, "force"), k3 * (-b / det), rtol=1e-12)


def random_chain(n: int, seed: int) -> GlobalChain:
    rng = np.random.default_rng(seed)
    return GlobalChain(rng.uniform(0.5, 2.0, n), rng.uniform(50, 150, n + 1),
                       rng.uniform(0.0, 1.0, n + 1), ground_stiffness=rng.uniform(0, 10, n),
                       ground_damping=rng.uniform(0, 0.2, n), start="fixed", end="fixed")


@pytest.mark.parametrize("quantity, output", [("displacement", 7), ("velocity", 2),
                                              ("acceleration", 11), ("force", 5), ("force", 12)])
def test_dense_equals_banded_frequency_response(quantity, output):
    chain = random_chain(12, seed=3)
    w = np.linspace(0.0, 60.0, 200)
    dense = frequency_response(chain, w, 3, output, quantity)
    banded = frequency_response_banded(chain, w, 3, output, quantity)
    np.testing.assert_allclose(banded, dense, rtol=1e-10, atol=1e-14 * np.max(np.abs(dense)))


def test_banded_matrices_are_the_dense_bands():
    chain = random_chain(6, seed=1)
    for dense, band in zip(assemble(chain), assemble_banded(chain)):
        np.testing.assert_array_equal(np.diag(dense), band[1])
        np.testing.assert_array_equal(np.diag(dense, 1), band[0, 1:])
        np.testing.assert_array_equal(np.diag(dense, -1), band[2, :-1])


# --------------------------------------------------------------------------------------------
# time responses
# --------------------------------------------------------------------------------------------
def sdof_free_part(m, c, k, x0, v0, t):
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta ** 2)
    return np.exp(-zeta * wn * t) * (x0 * np.cos(wd * t) + (v0 + zeta * wn * x0) / wd * np.sin(wd * t))


def test_exact_response_matches_sdof_closed_forms():
    m, c, k = 1.5, 0.6, 90.0
    chain = GlobalChain([m], [k, 0.0], [c, 0.0], start="fixed", end="free")
    t = np.linspace(0.0, 5.0, 201)
    # constant force: x = F/k + free vibration from (x0 - F/k, v0)
    F, x0, v0 = 12.0, 0.02, -0.3
    result = exact_response(chain, t, [x0], [v0], [F], "constant")
    expected = F / k + sdof_free_part(m, c, k, x0 - F / k, v0, t)
    np.testing.assert_allclose(result.displacement[:, 0], expected, atol=1e-13)
    np.testing.assert_allclose(m * result.acceleration + c * result.velocity + k * result.displacement,
                               F, atol=1e-11)
    # harmonic sin(Ωt): particular Im(F e^{iΩt}/(k - mΩ² + icΩ)) + free part
    Om = 5.3
    Z = F / (k - m * Om ** 2 + 1j * c * Om)
    xp = np.imag(Z * np.exp(1j * Om * t))
    vp0 = np.imag(1j * Om * Z)
    result = exact_response(chain, t, [x0], [v0], [F], "sine", force_frequency=Om)
    expected = xp + sdof_free_part(m, c, k, x0 - np.imag(Z), v0 - vp0, t)
    np.testing.assert_allclose(result.displacement[:, 0], expected, atol=1e-13)
    cosine = exact_response(chain, t, [x0], [v0], [F], "cosine", force_frequency=Om)
    expected = np.real(Z * np.exp(1j * Om * t)) + sdof_free_part(
        m, c, k, x0 - np.real(Z), v0 - np.real(1j * Om * Z), t)
    np.testing.assert_allclose(cosine.displacement[:, 0], expected, atol=1e-13)


def test_exact_response_undamped_resonance():
    # x'' + w² x = (F/m) sin wt, x(0)=v(0)=0: x = F/(2 m w²)(sin wt - wt cos wt)
    m, k, F = 2.0, 50.0, 3.0
    w = np.sqrt(k / m)
    chain = GlobalChain([m], [k, 0.0], start="fixed", end="free")
    t = np.linspace(0.0, 20.0, 101)
    result = exact_response(chain, t, [0.0], [0.0], [F], "sine", force_frequency=w)
    expected = F / (2 * m * w ** 2) * (np.sin(w * t) - w * t * np.cos(w * t))
    np.testing.assert_allclose(result.displacement[:, 0], expected, atol=1e-12)


def test_newmark_is_second_order_and_banded_equals_dense():
    chain = three_mass("fixed", "free", damping=[0.5, 1.0, 0.8, 0.0])
    x0, v0, F, Om, T = [0.01, 0.0, -0.02], [0.0, 0.1, 0.0], np.array([0.0, 0.0, 5.0]), 7.0, 2.0
    exact = exact_response(chain, [T], x0, v0, F, "sine", force_frequency=Om)
    errors = []
    for dt in (4e-3, 2e-3, 1e-3):
        run = newmark_global(chain, T, dt, x0, v0, lambda t: F * np.sin(Om * t))
        errors.append(np.max(np.abs(run.displacement[-1] - exact.displacement[0])))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, 2.0, atol=0.05)
    dense = newmark_global(chain, T, 1e-3, x0, v0, lambda t: F * np.sin(Om * t))
    banded = newmark_global(chain, T, 1e-3, x0, v0, lambda t: F * np.sin(Om * t), banded=True)
    np.testing.assert_allclose(banded.displacement, dense.displacement, rtol=0, atol=1e-15)


def test_solve_ivp_response_matches_exact_response():
    chain = three_mass("fixed", "fixed", damping=[0.5, 1.0, 0.8, 0.3])
    t = np.linspace(0.0, 3.0, 61)
    x0, v0, F = [0.01, -0.01, 0.0], [0.0, 0.2, 0.0], np.array([1.0, 0.0, -2.0])
    exact = exact_response(chain, t, x0, v0, F, "cosine", force_frequency=4.0)
    ivp = solve_ivp_response(chain, t, x0, v0, lambda s: F * np.cos(4.0 * s))
    np.testing.assert_allclose(ivp.displacement, exact.displacement, atol=1e-11)
    np.testing.assert_allclose(ivp.acceleration, exact.acceleration, atol=1e-8)


def test_state_space_is_the_first_order_form():
    chain = random_chain(4, seed=5)
    A, B = state_space(chain)
    M, C, K = assemble(chain)
    x, v, f = np.arange(4.0), np.ones(4), np.array([1.0, -2.0, 0.5, 3.0])
    np.testing.assert_allclose((A @ np.r_[x, v] + B @ f)[4:], np.linalg.solve(M, f - C @ v - K @ x))


@pytest.mark.parametrize("kwargs, match", [
    (dict(masses=[1.0, 0.0], stiffness=[1, 1, 0]), r"masses\[1\] must be > 0"),
    (dict(masses=[1.0, 1.0], stiffness=[1, -1, 0]), r"stiffness\[1\] must be >= 0"),
    (dict(masses=[1.0, 1.0], stiffness=[1, 1]), r"stiffness must have shape \(3,\)"),
    (dict(masses=[1.0, np.nan], stiffness=[1, 1, 0]), "masses must contain only finite"),
    (dict(masses=[1.0, 1.0], stiffness=[1, 1, 5.0]), r"stiffness\[2\] must be 0 for a free end"),
    (dict(masses=[1.0], stiffness=[1, 0], damping=[0, 0.1]), r"damping\[1\] must be 0 for a free end"),
])
def test_invalid_chains_raise(kwargs, match):
    with pytest.raises(ModelError, match=match):
        GlobalChain(**kwargs, start="fixed", end="free")


def test_invalid_options_raise():
    chain = three_mass("fixed", "free")
    with pytest.raises(ModelError, match="start must be one of"):
        GlobalChain([1.0], [1.0, 0.0], start="clamped", end="free")
    with pytest.raises(ModelError, match="quantity must be one of"):
        frequency_response(chain, [1.0], 0, 0, "jerk")
    with pytest.raises(ModelError, match=r"output_mass must be a mass index in \[0, 2\], got 3"):
        frequency_response(chain, [1.0], 0, 3)
    with pytest.raises(ModelError, match="t_final/dt must be a positive integer"):
        newmark_global(chain, 1.0, 0.3, np.zeros(3), np.zeros(3))
    with pytest.raises(ModelError, match="force_frequency"):
        exact_response(chain, [0.0], np.zeros(3), np.zeros(3), np.ones(3), "sine")


# --------------------------------------------------------------------------------------------
# closed loop: characteristic roots (Lambert W), FRF (2x2 algebra), metamorphic identities
# --------------------------------------------------------------------------------------------
FREE_MASS = GlobalChain([1.0], [0.0, 0.0], start="free", end="free")


def test_delayed_velocity_feedback_roots_are_lambert_w():
    # m v' + c v = -g v(t - τ): s = -c/m + W_k(-(gτ/m) e^{cτ/m}) / τ
    m, c, g, tau = 1.3, 0.4, 2.0, 0.7
    chain = GlobalChain([m], [0.0, 0.0], ground_damping=[c], start="free", end="free")
    loops = [GlobalLoop(0, "velocity", 0, g, delay=tau)]
    branches = np.arange(-4, 5)
    roots = -c / m + lambertw(-(g * tau / m) * np.exp(c * tau / m), branches) / tau
    value = closed_loop_characteristic(chain, loops, roots)
    scale = np.abs(m * roots ** 2) + np.abs(g * roots * np.exp(-roots * tau))
    assert np.max(np.abs(value) / scale) < 1e-13
    # Hayes λ = -e^{-λ} (DESIGN §6): m = g = τ = 1, c = 0, rightmost pair -0.3181 ± 1.3372i
    hayes = [GlobalLoop(0, "velocity", 0, 1.0, delay=1.0)]
    s = np.array([-0.3181315052 + 1.3372357014j])
    assert abs(closed_loop_characteristic(FREE_MASS, hayes, s)[0]) < 1e-9


def test_delayed_position_feedback_on_free_mass_roots_are_lambert_w():
    # m s² + g e^{-sτ} = 0  <=>  s = (2/τ) W_k(± i τ √(g/m) / 2)
    m, g, tau = 0.8, 5.0, 0.3
    chain = GlobalChain([m], [0.0, 0.0], start="free", end="free")
    loops = [GlobalLoop(0, "displacement", 0, g, delay=tau)]
    branches = np.arange(-3, 4)
    roots = np.concatenate([2 / tau * lambertw(sign * 0.5j * tau * np.sqrt(g / m), branches)
                            for sign in (1, -1)])
    value = closed_loop_characteristic(chain, loops, roots)
    scale = np.abs(m * roots ** 2) + g * np.abs(np.exp(-roots * tau))
    assert np.max(np.abs(value) / scale) < 1e-13


def two_mass() -> GlobalChain:
    return GlobalChain([1.0, 0.5], [100.0, 60.0, 0.0], [0.4, 0.2, 0.0], start="fixed", end="free")


def test_closed_loop_frequency_response_two_mass_hand_algebra():
    # u = -g x_1(t - τ) on mass 0;  u2 = -h (v_1 - v_0)(t - τ2) on mass 1, -u2 on mass 0
    g, tau, h, tau2 = 30.0, 0.05, 2.0, 0.02
    loops = [GlobalLoop(1, "displacement", 0, g, delay=tau),
             GlobalLoop(1, "velocity", 1, h, delay=tau2, relative_to=0, reaction_mass=0)]
    w = np.linspace(0.0, 40.0, 120)
    e, e2, iw = np.exp(-1j * w * tau), np.exp(-1j * w * tau2), 1j * w
    k1, k2, c1, c2 = 100.0, 60.0, 0.4, 0.2
    D00 = k1 + k2 + iw * (c1 + c2) - w ** 2 * 1.0 + h * iw * e2
    D01 = -(k2 + iw * c2) + g * e - h * iw * e2
    D10 = -(k2 + iw * c2) - h * iw * e2
    D11 = k2 + iw * c2 - 0.5 * w ** 2 + h * iw * e2
    det = D00 * D11 - D01 * D10
    chain = two_mass()
    np.testing.assert_allclose(closed_loop_frequency_response(chain, loops, w, 0, 0), D11 / det, rtol=1e-12)
    np.testing.assert_allclose(closed_loop_frequency_response(chain, loops, w, 0, 1), -D10 / det, rtol=1e-12)
    np.testing.assert_allclose(closed_loop_frequency_response(chain, loops, w, 1, 0, "velocity"),
                               iw * -D01 / det, rtol=1e-12)
    np.testing.assert_allclose(closed_loop_characteristic(chain, loops, 1j * w), det, rtol=1e-12)


def test_loops_equal_passive_elements():
    chain = three_mass("fixed", "free", damping=[0.5, 1.0, 0.8, 0.0])
    w = np.linspace(0.0, 30.0, 90)
    # collocated velocity loop == ground damper; relative position across connector 2 == stiffer spring
    loops = [GlobalLoop(2, "velocity", 2, 3.0), GlobalLoop(2, "displacement", 2, 40.0, relative_to=1,
                                                           reaction_mass=1)]
    passive = GlobalChain(MASSES, [100.0, 200.0, 190.0, 0.0], [0.5, 1.0, 0.8, 0.0],
                          ground_damping=[0.0, 0.0, 3.0], start="fixed", end="free")
    np.testing.assert_allclose(closed_loop_frequency_response(chain, loops, w, 0, 2),
                               frequency_response(passive, w, 0, 2), rtol=1e-12)
    np.testing.assert_allclose(closed_loop_roots(chain, loops), complex_eigenvalues(passive), rtol=1e-10)
    np.testing.assert_allclose(closed_loop_frequency_response(chain, [], w, 1, 2, "force"),
                               frequency_response(chain, w, 1, 2, "force"), rtol=1e-13)


def test_closed_loop_roots_match_sympy_polynomial():
    # non-collocated delay-free loops: roots of det(s²M + sC + K + G(s)) expanded by sympy; with an acceleration
    # loop (M' not diagonal: the generalized eigenproblem) and without (M' divided out: the standard one)
    chain = three_mass("fixed", "free", damping=[0.5, 1.0, 0.8, 0.0])
    s = sp.symbols("s")
    M, C, K = (sp.Matrix(matrix.tolist()) for matrix in assemble(chain))
    for acceleration in (0.3, 0.0):
        loops = [GlobalLoop(2, "displacement", 0, 80.0), GlobalLoop(0, "velocity", 1, -1.5)]
        G = sp.zeros(3, 3)
        G[0, 2] += 80.0
        G[1, 0] += -1.5 * s
        if acceleration:
            loops.append(GlobalLoop(1, "acceleration", 2, acceleration))
            G[2, 1] += acceleration * s ** 2
        poly = sp.Poly(sp.expand((s ** 2 * M + s * C + K + G).det()), s)
        expected = np.roots([float(coefficient) for coefficient in poly.all_coeffs()])
        roots = closed_loop_roots(chain, loops)
        assert roots.size == 6
        distance = np.abs(roots[:, None] - expected[None, :])          # match each root to its twin
        assert np.all(np.sort(distance.min(axis=0)) < 1e-9 * np.abs(expected).max())
        assert sorted(np.argmin(distance, axis=0)) == list(range(6))
    with pytest.raises(ModelError, match="delay-free"):
        closed_loop_roots(chain, [GlobalLoop(0, "velocity", 0, 1.0, delay=0.1)])


def test_invalid_loops_raise():
    with pytest.raises(ModelError, match="quantity must be one of"):
        GlobalLoop(0, "jerk", 0, 1.0)
    with pytest.raises(ModelError, match="delay must be >= 0"):
        GlobalLoop(0, "velocity", 0, 1.0, delay=-0.1)
    with pytest.raises(ModelError, match="reaction_mass must differ"):
        GlobalLoop(0, "velocity", 1, 1.0, reaction_mass=1)
    with pytest.raises(ModelError, match=r"loops\[0\].sensor_mass must be a mass index"):
        closed_loop_characteristic(two_mass(), [GlobalLoop(5, "velocity", 0, 1.0)], [1j])


# --------------------------------------------------------------------------------------------
# method of steps
# --------------------------------------------------------------------------------------------
def sympy_method_of_steps(m, gains, tau, x0, v0, force, intervals):
    """Exact piecewise polynomials for m x'' = F - gx x(t-τ) - gv v(t-τ) - ga a(t-τ),
    history (x0, v0, 0) before 0: integrate the known right-hand side interval by interval."""
    t = sp.symbols("t")
    gx, gv, ga = gains
    X, V, A = sp.nsimplify(x0), sp.nsimplify(v0), sp.Integer(0)   # history (as functions of t)
    pieces = []
    x_start, v_start = sp.nsimplify(x0), sp.nsimplify(v0)
    for k in range(intervals):
        shift = {t: t - tau}
        a = (force - gx * X.subs(shift) - gv * V.subs(shift) - ga * A.subs(shift)) / m
        a = sp.expand(a)
        v = v_start + sp.integrate(a, (t, k * tau, t))
        x = x_start + sp.integrate(v, (t, k * tau, t))
        pieces.append((x, v, a))
        X, V, A = x, v, a
        x_start, v_start = x.subs(t, (k + 1) * tau), v.subs(t, (k + 1) * tau)
    return t, pieces


def test_method_of_steps_matches_exact_sympy_solution_neutral_free_mass():
    m, tau = sp.Rational(3, 2), sp.Rational(3, 10)
    gains = (sp.Integer(4), sp.Rational(1, 2), sp.Rational(3, 5))     # |ga/m| < 1: stable neutral
    x0, v0, force = sp.Rational(1, 10), sp.Rational(1, 5), sp.Integer(2)
    t, pieces = sympy_method_of_steps(m, gains, tau, x0, v0, force, intervals=4)
    chain = GlobalChain([1.5], [0.0, 0.0], start="free", end="free")
    loops = [GlobalLoop(0, quantity, 0, float(gain), delay=0.3)
             for quantity, gain in zip(("displacement", "velocity", "acceleration"), gains)]
    solution = method_of_steps(chain, loops, 1.2, [0.1], [0.2], force_fn=lambda time: [2.0],
                               rtol=1e-12, atol=1e-14)
    times = np.array([0.0, 0.1, 0.29, 0.3, 0.45, 0.6, 0.77, 0.9, 1.05, 1.19])
    result = solution.evaluate(times)
    for index, time in enumerate(times):
        k = min(int(np.floor(time / 0.3 + 1e-12)), 3)
        x, v, a = (float(expr.subs(t, sp.nsimplify(time))) for expr in pieces[k])
        assert result.displacement[index, 0] == pytest.approx(x, abs=1e-11)
        assert result.velocity[index, 0] == pytest.approx(v, abs=1e-11)
        assert result.acceleration[index, 0] == pytest.approx(a, abs=1e-9)


def heun_dde(chain, loops, t_final, h, x0, v0, force_fn):
    """Independent fixed-step Heun (explicit trapezoid) for the closed-loop DDE.

    Delays must be multiples of h (at least 2 h).  Accelerations are stored as the right limit at the start of
    each step and the left limit at its end, so jumps at multiples of τ (neutral case) keep
    second order.  History: x0, v0, a = 0 before t = 0.
    """
    M, C, K = assemble(chain)
    n, steps = chain.size, int(round(t_final / h))
    x, v = np.zeros((steps + 1, n)), np.zeros((steps + 1, n))
    a_start, a_end = np.zeros((steps, n)), np.zeros((steps, n))
    x[0], v[0] = x0, v0
    lags = [int(round(loop.delay / h)) for loop in loops]

    def delayed(loop, lag, i_time, end):
        j = i_time - lag                                      # grid index of t - τ
        if j < 0 or (j == 0 and end):                         # history (left limit at 0)
            values = {"displacement": x0, "velocity": v0, "acceleration": np.zeros(n)}
        else:
            values = {"displacement": x[j], "velocity": v[j],
                      "acceleration": a_end[j - 1] if end else a_start[j]}
        y = values[loop.quantity]
        sensed = y[loop.sensor_mass] - (y[loop.relative_to] if loop.relative_to is not None else 0.0)
        force = np.zeros(n)
        force[loop.actuator_mass] -= loop.gain * sensed
        if loop.reaction_mass is not None:
            force[loop.reaction_mass] += loop.gain * sensed
        return force

    def acceleration(i_time, xi, vi, end):
        load = force_fn(i_time * h) - C @ vi - K @ xi
        for loop, lag in zip(loops, lags):
            load = load + delayed(loop, lag, i_time, end)
        return np.linalg.solve(M, load)

    for i in range(steps):
        a_start[i] = acceleration(i, x[i], v[i], False)
        x_pred, v_pred = x[i] + h * v[i], v[i] + h * a_start[i]
        a_end[i] = acceleration(i + 1, x_pred, v_pred, True)
        x[i + 1] = x[i] + 0.5 * h * (v[i] + v_pred)
        v[i + 1] = v[i] + 0.5 * h * (a_start[i] + a_end[i])
    return x, v


def test_method_of_steps_matches_independent_heun_with_second_order_convergence():
    chain = two_mass()
    loops = [GlobalLoop(1, "displacement", 0, 15.0, delay=0.25),
             GlobalLoop(1, "acceleration", 1, 0.2, delay=0.25),
             GlobalLoop(1, "velocity", 1, 0.5, delay=0.4, relative_to=0, reaction_mass=0)]
    x0, v0, T = np.array([0.01, -0.02]), np.array([0.0, 0.3]), 1.2
    force = lambda time: np.array([0.0, np.sin(3.0 * time)])  # noqa: E731
    reference = method_of_steps(chain, loops, T, x0, v0, force_fn=force, rtol=1e-12, atol=1e-14)
    exact = reference.evaluate(np.array([T]))
    errors, finals = [], []
    for h in (0.005, 0.0025, 0.00125):
        x, v = heun_dde(chain, loops, T, h, x0, v0, force)
        finals.append(np.r_[x[-1], v[-1]])
        errors.append(np.max(np.abs(finals[-1] - np.r_[exact.displacement[0], exact.velocity[0]])))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, 2.0, atol=0.1)
    # Richardson extrapolation of the two finest Heun runs removes the h² term
    richardson = (4 * finals[2] - finals[1]) / 3
    assert np.max(np.abs(richardson - np.r_[exact.displacement[0], exact.velocity[0]])) < 0.02 * errors[-1]


def test_zero_delay_loops_fold_into_matrices():
    # collocated acceleration feedback g == mass m + g; velocity feedback == ground damper
    chain = three_mass("fixed", "free", damping=[0.5, 1.0, 0.8, 0.0])
    loops = [GlobalLoop(1, "acceleration", 1, 0.7), GlobalLoop(0, "velocity", 0, 2.0)]
    passive = GlobalChain([1.0, 2.7, 1.5], chain.stiffness, chain.damping,
                          ground_damping=[2.0, 0.0, 0.0], start="fixed", end="free")
    t = np.linspace(0.0, 2.0, 21)
    x0, v0 = [0.01, 0.0, -0.01], [0.0, 0.1, 0.0]
    solution = method_of_steps(chain, loops, 2.0, x0, v0, rtol=1e-12, atol=1e-14)
    assert len(solution.segments) == 1
    exact = exact_response(passive, t, x0, v0, np.zeros(3))
    result = solution.evaluate(t)
    np.testing.assert_allclose(result.displacement, exact.displacement, atol=1e-11)
    np.testing.assert_allclose(result.acceleration, exact.acceleration, atol=1e-8)


def test_method_of_steps_decays_with_the_rightmost_lambert_w_root():
    # m v' = -g v(t - τ) (Hayes with m = g = τ = 1): for large t, v ≈ Re(A e^{s0 t}),
    # s0 = W_0(-gτ/m)/τ = -0.3181 + 1.3372i; the next roots (Re ≈ -2.06) have died out by t = 8
    s0 = complex(lambertw(-1.0, 0))
    solution = method_of_steps(FREE_MASS, [GlobalLoop(0, "velocity", 0, 1.0, delay=1.0)], 12.0,
                               [0.0], [1.0], rtol=1e-12, atol=1e-14)
    t = np.linspace(8.0, 12.0, 41)
    v = solution.evaluate(t).velocity[:, 0]
    basis = np.exp(s0.real * t)[:, None] * np.c_[np.cos(s0.imag * t), np.sin(s0.imag * t)]
    coefficients, *_ = np.linalg.lstsq(basis, v, rcond=None)
    assert np.max(np.abs(basis @ coefficients - v)) < 1e-6 * np.max(np.abs(v))


def test_method_of_steps_uses_a_given_history_and_checks_forces():
    # history x(θ) = θ (v = 1) on a free mass with delayed position feedback: on [0, τ]
    # m x'' = -g (t - τ) -> x = v0 t - g (t³/6 - τ t²/2) / m
    m, g, tau = 2.0, 3.0, 0.5
    chain = GlobalChain([m], [0.0, 0.0], start="free", end="free")
    loops = [GlobalLoop(0, "displacement", 0, g, delay=tau)]
    history = lambda theta: (np.array([theta]), np.array([1.0]), np.array([0.0]))  # noqa: E731
    solution = method_of_steps(chain, loops, tau, [0.0], [1.0], history=history)
    t = np.linspace(0.0, tau, 6)
    expected = t - g * (t ** 3 / 6 - tau * t ** 2 / 2) / m
    np.testing.assert_allclose(solution.evaluate(t).displacement[:, 0], expected, atol=1e-12)
    with pytest.raises(ModelError, match=r"force_fn\(t\) must return shape \(1,\)"):
        method_of_steps(chain, loops, tau, [0.0], [1.0], force_fn=lambda time: [1.0, 2.0])
