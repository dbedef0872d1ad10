"""The one fixed-step RK4 (ctmm.ode) and the one real-axis root refiner (ctmm.roots1d) on analytic
problems: RK4's order and amplification polynomial, its imaginary-axis limit (ctmm.guard.RK4_LIMIT),
count bisection and sign-change refinement on known roots, clustered and repeated ones included."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.guard import RK4_LIMIT
from ctmm.ode import integrate_rk4, rk4_step, second_order_rate
from ctmm.roots1d import bisect_count, count_upper_bound, refine_sign_change


# ------------------------------------------------------------------------------------------- RK4
def test_rk4_is_fourth_order_on_a_time_dependent_ode():
    # y' = cos(t) y, y(0) = 1  ->  y = exp(sin t); two components with different rates
    rate = lambda t, y: np.cos(t) * y * np.array([1.0, -2.0])   # noqa: E731
    exact = np.array([math.exp(math.sin(2.0)), math.exp(-2.0 * math.sin(2.0))])
    errors = [np.max(np.abs(integrate_rk4(rate, [1.0, 1.0], h=2.0 / n, n_steps=n) - exact)) for n in (20, 40, 80)]
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((slopes > 3.8) & (slopes < 4.2)), slopes


def test_rk4_step_is_the_degree_four_taylor_polynomial_on_a_linear_ode():
    lam, h = -0.7 + 1.3j, 0.37
    z = lam * h
    y1 = rk4_step(lambda t, y: lam * y, 0.0, np.array([1.0 + 0j]), h)
    assert abs(y1[0] - (1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24)) < 1e-15


@pytest.mark.parametrize("factor, grows", [(0.999, False), (1.001, True)])
def test_rk4_limit_is_the_imaginary_axis_stability_boundary(factor, grows):
    h = factor * RK4_LIMIT              # omega = 1: y' = i y
    gain = abs(rk4_step(lambda t, y: 1j * y, 0.0, np.array([1.0 + 0j]), h)[0])
    assert (gain > 1.0) == grows


def test_second_order_rate_integrates_an_oscillator_and_the_callback_sees_every_step():
    omega, n, h = 3.0, 200, 0.01
    seen = []
    rate = second_order_rate(lambda q, v, t: -omega ** 2 * q, 1)
    y = integrate_rk4(rate, [1.0, 0.0], h=h, n_steps=n, t0=0.5,
                      after_step=lambda k, t, y: seen.append((k, t, y)))
    assert [k for k, _, _ in seen] == list(range(1, n + 1))
    assert seen[-1][1] == 0.5 + n * h and seen[-1][2] is y
    # RK4's phase error is theta^5 / 120 per step (theta = omega h = 0.03): 200 steps -> 4e-8 rad
    bound = n * (omega * h) ** 5 / 120
    assert abs(y[0] - math.cos(omega * n * h)) < bound and abs(y[1] + omega * math.sin(omega * n * h)) < omega * bound


def test_callback_stops_the_run_and_bad_steps_are_refused():
    class Stop(Exception):
        pass

    def stop(k, t, y):
        if k == 3:
            raise Stop

    with pytest.raises(Stop):
        integrate_rk4(lambda t, y: y, [1.0], h=0.1, n_steps=10, after_step=stop)
    for h in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ModelError, match="h must be"):
            integrate_rk4(lambda t, y: y, [1.0], h=h, n_steps=1)
    with pytest.raises(ModelError, match="n_steps"):
        integrate_rk4(lambda t, y: y, [1.0], h=0.1, n_steps=-1)


# ----------------------------------------------------------------------------------- root refiner
ROOTS = np.array([0.5, 1.0, 1.0 + 1e-12, 1.0 + 2e-12, 2.0, 2.0, 7.0])   # cluster and a double root


def _count(x):
    return np.sum(ROOTS[None, :] < np.asarray(x)[:, None], axis=1)


def test_count_bisection_finds_clustered_and_repeated_roots():
    k = np.arange(1, ROOTS.size + 1)
    lo, up = np.zeros(k.size), np.full(k.size, 8.0)
    c_lo, c_up = _count(lo), _count(up)
    bisect_count(_count, k, lo, up, c_lo, c_up, 1e-15)
    assert np.all(up - lo <= 1e-15 * up) and np.all(np.abs(0.5 * (lo + up) - ROOTS) <= 2e-15 * ROOTS)


def test_count_bisection_isolates_and_respects_the_iteration_bound():
    k = np.array([1, 2, 5, 7])
    lo, up = np.zeros(4), np.full(4, 8.0)
    c_lo, c_up = _count(lo), _count(up)
    bisect_count(_count, k, lo, up, c_lo, c_up, 1e-15, isolate=True)
    single = np.array([True, True, False, True])                                 # root 5 is double
    assert np.all(c_up[single] - c_lo[single] == 1) and np.all(up[single] - lo[single] > 1e-15 * up[single])
    assert c_up[2] - c_lo[2] == 2 and up[2] - lo[2] <= 1e-15 * up[2]           # repeated: down to rtol
    assert np.all((lo <= ROOTS[k - 1]) & (ROOTS[k - 1] < up))                    # count(x): roots below x
    lo, up = np.zeros(1), np.full(1, 8.0)                                       # a root at 0 never meets rtol
    calls = []
    bisect_count(lambda x: calls.append(x) or np.ones(x.size, dtype=int), np.array([1]), lo, up,
                 np.zeros(1, dtype=int), np.ones(1, dtype=int), 1e-15, max_iterations=30)
    assert len(calls) == 30 and up[0] == 8.0 * 2.0 ** -30
    with pytest.raises(ModelError, match="rtol"):
        bisect_count(_count, k, lo, up, c_lo, c_up, 0.0)


def test_sign_change_refinement_on_analytic_functions():
    roots = np.array([math.pi / 2, 2.0 ** (1 / 3), 1.0, 1.0 + 1e-9])
    scale = np.array([1.0, 1e-200, 1e200, -1.0])           # per-bracket data reaches the function

    def function(x, active):
        r = roots[active]
        base = np.where(np.isin(active, [0]), np.cos(x), (x - r) * (1.0 + (x - r) ** 2))
        return scale[active] * np.where(np.isin(active, [1]), x ** 3 - 2.0, base)

    lo = np.array([1.0, 1.0, 0.5, 1.0 + 0.5e-9])
    up = np.array([2.0, 2.0, 1.0 + 0.5e-9, 3.0])
    everyone = np.arange(4)
    calls = []
    counted = lambda x, active: calls.append(active.size) or function(x, active)   # noqa: E731
    good = refine_sign_change(counted, lo, up, function(lo, everyone), function(up, everyone), 1e-15)
    assert np.all(good) and len(calls) < 60
    assert np.all(np.abs(0.5 * (lo + up) - roots) <= 2e-15 * roots)


def test_sign_change_refinement_leaves_unbracketed_ends_and_stops_on_exact_zeros():
    lo, up = np.array([0.0, 1.0]), np.array([2.0, 2.0])
    f = lambda x, active: x - 1.0                                                   # noqa: E731
    good = refine_sign_change(f, lo, up, np.array([-1.0, 0.5]), np.array([1.0, 1.0]), 1e-15)
    assert good.tolist() == [True, False]
    assert lo[0] == up[0] == 1.0 and (lo[1], up[1]) == (1.0, 2.0)                  # secant hits 1 exactly


@pytest.mark.parametrize("function, lo, up, root, most", [
    (lambda x: x ** 3 - 2.0, 1.0, 2.0, 2.0 ** (1 / 3), 10),    # bisection alone: 50 evaluations
    (lambda x: np.exp(x) - 10.0, 0.1, 20.0, math.log(10.0), 26),  # strongly convex: Illinois halving
])
def test_sign_change_refinement_converges_superlinearly(function, lo, up, root, most):
    calls = []
    lo, up = np.array([lo]), np.array([up])
    refine_sign_change(lambda x, active: calls.append(1) or function(x), lo, up, function(lo), function(up), 1e-15)
    assert len(calls) <= most and abs(0.5 * (lo[0] + up[0]) - root) <= 2e-15 * root


def test_sign_change_refinement_carries_tracked_values_with_the_ends():
    roots = np.array([math.sqrt(2.0), 1.5, 3.0])
    lo, up = np.array([1.0, 1.0, 2.0]), np.array([2.0, 2.0, 4.0])
    p_lo, p_up = lo ** 3, up ** 3                                   # tracked: x^3 at each end
    everyone = np.arange(3)

    def function(x, active):
        return (x - roots[active]) * (1.0 + x), x ** 3

    f_lo, f_up = function(lo, everyone)[0], function(up, everyone)[0]
    good = refine_sign_change(function, lo, up, f_lo, f_up, 1e-15, tracked=(p_lo, p_up))
    assert np.all(good) and np.all(p_lo == lo ** 3) and np.all(p_up == up ** 3)
    assert np.all(np.abs(0.5 * (lo + up) - roots) <= 2e-15 * roots)
    assert lo[1] == up[1] == 1.5 and p_lo[1] == p_up[1] == 1.5 ** 3    # exact zero: both ends


def test_sign_change_refinement_stops_brackets_early_on_request():
    root, asked, evaluated = 2.0 ** (1 / 3), [], []
    lo, up = np.array([1.0, 1.0]), np.array([2.0, 2.0])

    def stop(active):
        asked.append(active.copy())
        return (active == 0) & (up[active] - lo[active] <= 1e-2)     # bracket 0 only, once narrow

    def function(x, active):
        evaluated.append(np.copy(active))
        return x ** 3 - 2.0

    everyone = np.arange(2)
    refine_sign_change(function, lo, up, lo ** 3 - 2.0, up ** 3 - 2.0, 1e-15, stop=stop)
    assert 1e-6 < up[0] - lo[0] <= 1e-2 and lo[0] < root < up[0]                 # stopped, not converged
    assert up[1] - lo[1] <= 1e-15 * up[1] and lo[1] <= root <= up[1]
    assert np.array_equal(evaluated[0], everyone) and not np.isin(0, evaluated[-1])
    assert all(np.isin(a, e).all() for a, e in zip(asked, evaluated))            # only brackets still going


def test_count_upper_bound_doubles_until_enough_roots_lie_below():
    # roots 0.5, 1, 1+1e-12, 1+2e-12, 2, 2, 7: below 2 lie four, below 4 six, below 8 all seven
    assert count_upper_bound(_count, 1, limit=100.0, what="x") == 1.0
    assert count_upper_bound(_count, 4, limit=100.0, what="x") == 2.0
    assert count_upper_bound(_count, 5, limit=100.0, what="x") == 4.0
    assert count_upper_bound(_count, 7, limit=100.0, what="x") == 8.0
    with pytest.raises(ModelError, match="chain 'c' has fewer than 8 natural frequencies"):
        count_upper_bound(_count, 8, limit=100.0, what="chain 'c'")
    with pytest.raises(ModelError, match="fewer than 7"):
        count_upper_bound(_count, 7, limit=7.0, what="x")          # 8 is beyond the limit
