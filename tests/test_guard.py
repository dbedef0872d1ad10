"""Run guards: Newmark / Wilson / RK4 stability limits against the amplification matrices, divergence and user code."""
import math
import warnings

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.guard import (RK4_LIMIT, DivergenceGuard, StabilityLimitWarning, UserFunction, call_user, check_step,
                        newmark_limit, user_output, wilson_limit)


def newmark_spectral_radius(beta: float, gamma: float, omega_h: float) -> float:
    """Spectral radius of Newmark's amplification matrix for x'' + w^2 x = 0 (textbook recurrence)."""
    w2 = omega_h ** 2
    # state (x, h v, h^2 a); a_{n+1} = -w2 x_{n+1}; x_{n+1} = x + hv + h^2((1/2 - beta) a + beta a_{n+1})
    d = 1.0 + beta * w2
    A = np.zeros((3, 3))
    A[0] = [1.0, 1.0, 0.5 - beta]
    A[0] /= d
    A[2] = -w2 * A[0]
    A[1] = [0.0, 1.0, 1.0 - gamma] + gamma * A[2]
    return float(np.max(np.abs(np.linalg.eigvals(A))))


@pytest.mark.parametrize("beta, gamma", [(0.0, 0.5), (1 / 12, 0.5), (1 / 6, 0.5), (0.01, 0.5), (0.1, 0.6)])
def test_newmark_limit_is_the_spectral_radius_boundary(beta, gamma):
    limit = newmark_limit(beta, gamma)
    assert math.isfinite(limit)
    assert newmark_spectral_radius(beta, gamma, 0.99 * limit) <= 1.0 + 1e-9
    assert newmark_spectral_radius(beta, gamma, 1.01 * limit) > 1.0 + 1e-6


def test_newmark_unconditional_and_never_stable():
    assert newmark_limit(0.25, 0.5) == math.inf
    assert newmark_limit(0.3025, 0.6) == math.inf
    assert newmark_limit(0.25, 0.0) == 0.0
    assert newmark_spectral_radius(0.25, 0.4, 0.1) > 1.0


def test_rk4_limit_on_the_imaginary_axis():
    def radius(z):
        return abs(1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24)
    assert radius(1j * 0.999 * RK4_LIMIT) <= 1.0 + 1e-12
    assert radius(1j * 1.001 * RK4_LIMIT) > 1.0


def test_check_step_policies():
    assert check_step("Newmark", 10.0, 0.01, 2.0) is None
    with pytest.warns(StabilityLimitWarning, match="dt <= 0.2 s"):
        check_step("Newmark(beta=0.01)", 10.0, 1.0, 2.0)
    with pytest.raises(ModelError, match="not stable at any step"):
        check_step("Newmark(gamma=0)", 10.0, 1.0, 0.0, policy="error")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_step("x", 10.0, 1.0, 2.0, policy="ignore")
    with pytest.raises(ModelError, match="stability_check must be"):
        check_step("x", 1.0, 1.0, 2.0, policy="loud")


def test_divergence_guard():
    guard = DivergenceGuard.from_start(["a", "b"], [0.0, 10.0], [0.5, 10.0])
    assert guard.bound == 1e6
    guard.check(0.1, [1.0, 11.0])
    with pytest.raises(SimulationError, match="'b' is 2e\\+06") as info:
        guard.check(0.2, [1.0, 2e6 + 10.0])
    assert info.value.time == 0.2 and info.value.element == "b"
    with pytest.raises(SimulationError, match="non-finite state at t = 0.3 s in 'a'"):
        guard.check(0.3, [np.nan, 0.0])
    off = DivergenceGuard.from_start(["a"], [0.0], [0.0], bound=math.inf)
    off.check(0.0, [1e300])
    with pytest.raises(ModelError, match="divergence_bound must be"):
        DivergenceGuard.from_start(["a"], [0.0], [0.0], bound=-1.0)


@pytest.mark.parametrize("bound", [2.5, math.inf])
def test_divergence_guard_passes_a_block_where_check_accepts_each_row(bound):
    """``passes`` on a block of rows is ``check`` row by row (NaN, infinities, values at and beyond the bound,
    differences that overflow to infinity)."""
    guard = DivergenceGuard.from_start(["a", "b", "c"], [0.0, 1.0, -1e308], [0.0, 1.0, -1e308], bound=bound)
    rng = np.random.default_rng(3)
    pool = np.array([0.0, 1.0, 2.5, -2.5, 3.5, -1.5, 1e308, -1e308, np.nan, np.inf, -np.inf, 2.5000000001])
    rows = rng.choice(pool, size=(400, 3))
    rows[:3] = [[2.5, 3.5, -1e308], [0.0, 1.0, 1e308], [2.5000000001, 1.0, -1e308]]
    accepted = []
    for row in rows:
        try:
            guard.check(0.0, row)
            accepted.append(True)
        except SimulationError:
            accepted.append(False)
    np.testing.assert_array_equal(guard.passes(rows), accepted)
    assert 0 < sum(accepted) < len(rows)
    assert accepted[:3] == ([True, True, True] if math.isinf(bound) else [True, False, False])


def test_user_code_is_named():
    def bad(t):
        raise KeyError("oops")
    with pytest.raises(SimulationError, match="force of 'm2' raised KeyError at t = 0.5 s") as info:
        call_user("force of 'm2'", bad, 0.5, time=0.5)
    assert isinstance(info.value.__cause__, KeyError)
    assert user_output("controller 'c'", 3.0, 1, time=0.0).tolist() == [3.0]
    with pytest.raises(SimulationError, match="returned 2 value"):
        user_output("controller 'c'", [1.0, 2.0], 1, time=0.0)
    with pytest.raises(SimulationError, match="non-finite"):
        user_output("controller 'c'", [np.nan], 1, time=0.0)
    with pytest.raises(SimulationError, match="expected 1 real"):
        user_output("controller 'c'", "abc", 1, time=0.0)
    with pytest.raises(SimulationError, match="expected 1 real"):     # no float holds it (was a raw OverflowError)
        user_output("controller 'c'", 10 ** 400, 1, time=0.25)


def test_wilson_limit():
    """theta = 1 is the linear-acceleration method: omega h <= 2 sqrt 3 (closed form); the limit grows
    without bound as theta approaches (1 + sqrt 3) / 2 = 1.366 and is infinite from 1.37."""
    assert wilson_limit(1.0) == pytest.approx(2.0 * math.sqrt(3.0), rel=1e-9)
    limits = [wilson_limit(theta) for theta in (1.0, 1.1, 1.2, 1.3, 1.35, 1.365)]
    assert np.all(np.diff(limits) > 0) and limits[-1] > 50.0
    assert wilson_limit(1.37) == math.inf and wilson_limit(1.4) == math.inf


def test_user_function_is_named():
    f = UserFunction("m2: force", lambda t: [t, t] if t > 1.0 else 2.0 * t)
    assert f(0.5) == 1.0
    with pytest.raises(SimulationError, match=r"user function 'm2: force' returned 2 value\(s\) at t = 2 s"):
        f(2.0)
